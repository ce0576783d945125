// Neural inverse kinematics after seed 000 §4-5: one small MLP per machine axis.
//
//   X, Y, Z nets: (Px, Py, Pz, A, C) -> X | Y | Z      5 -> 25 -> 11 -> 1, 5 -> 22 -> 11 -> 1,
//                                                      5 -> 18 -> 16 -> 1   (Table 5)
//   A net:        (rho, Ok)          -> A              2 -> 10 -> 14 -> 1
//   C net:        (Oi, Oj)           -> C | (sin C, cos C)   2 -> 6 -> 12 -> 1 | 2
//
// P is the spindle gauge point in the workpiece frame, P = tip + L * axis (L = tool length):
// the machine's X, Y, Z depend on the tool only through that shift (forward kinematics with
// length L moves the tip by -L * axis exactly), so one model serves every G43 H value.
// (Oi, Oj, Ok) is the unit tool axis in the workpiece frame and rho = hypot(Oi, Oj) = |sin A|:
// the two inputs (rho, Ok) = (|sin A|, cos A) make A a smooth function of its inputs, where
// A = acos(Ok) alone has an infinite slope at A = 0. The rotary nets learn one IK branch (the
// sign of A with the larger travel, `branch_sign`); predict() maps to the other branch
// (A, C) -> (-A, C + 180) when the caller's reference lies there, and unwraps C to the turn
// nearest the reference. The derivation, data, split and errors are in stages/ik/README.md,
// section "Neural IK".
#pragma once

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>

#include "gcpipe/block.hpp"
#include "gcpipe/kinematics.hpp"
#include "mlp.hpp"

namespace gcpipe::neural {

/// First line of every model file; loading any other version is refused.
inline constexpr std::string_view kModelFormat = "gcpipe-neural-ik v1";

/// What the C net outputs.
enum class COutput : std::uint8_t {
  kAngle = 0,   //!< C [deg] in [-180, 180] (seed 000): jumps by 360 where the data wrap
  kSinCos = 1   //!< (sin C, cos C); C = atan2: no wrap in the targets
};

/// One per-axis network and the affine maps between physical values and the [-1, 1] range the
/// network sees (MATLAB mapminmax): v_n = 2 (v - min) / (max - min) - 1.
struct AxisNet {
  Mlp mlp;
  Eigen::VectorXd input_min;   //!< per input, physical units [mm, deg, 1]
  Eigen::VectorXd input_max;
  Eigen::VectorXd output_min;  //!< per output, physical units [mm, deg, 1]
  Eigen::VectorXd output_max;
};

/// Per-axis network order in the model: X Y Z A C (the Axis enum).
using AxisNets = std::array<AxisNet, kNumAxes>;

/// Bits of NeuralIkPrediction::outside_envelope: bit i (1 << Axis) set when an input of axis i's
/// net lies outside the range it was trained on (for C also: tilt below the trained minimum).
using EnvelopeBits = std::uint8_t;

/// One neural answer.
struct NeuralIkPrediction {
  Axes joints{};                 //!< X Y Z [mm], A C [deg]; C unwrapped near the reference
  EnvelopeBits outside_envelope = 0;
  bool finite = true;            //!< false when the input or an output was not finite
};

/// Where a model came from (stored in the file; no times, so files are reproducible).
struct ModelProvenance {
  std::string machine;           //!< machine name of the config it was trained for
  std::string preset;            //!< "paper", "improved", or "custom"
  std::uint64_t seed = 0;        //!< training seed
};

/// A trained neural IK model: five per-axis nets and their normalisation. Immutable once built;
/// predict() is const, safe to call from several threads, and evaluates the nets in single
/// precision (MlpInference; normalisation and everything around the nets stay double).
class NeuralIk {
 public:
  /// Checks shapes (X/Y/Z nets 5 -> ... -> 1, A net 2 -> ... -> 1, C net 2 -> ... -> 1 or 2 as
  /// `c_output` says), finite parameters, min < max for every range, and single-word machine and
  /// preset names; throws std::invalid_argument naming the net and the quantity otherwise.
  NeuralIk(ModelProvenance provenance, int branch_sign, COutput c_output, AxisNets nets);

  /// Reads a model file; throws std::runtime_error "file:line: reason" for a wrong version,
  /// shape, count, NaN or malformed number.
  static NeuralIk load(const std::filesystem::path& path);
  /// Parses model text; `source` names it in messages.
  static NeuralIk parse(std::string_view text, const std::string& source = "<model>");
  /// Model text: numbers in shortest round-trip form, so save -> load reproduces every bit.
  std::string serialise() const;
  /// Writes serialise() to `path`; throws std::runtime_error when it cannot.
  void save(const std::filesystem::path& path) const;

  const ModelProvenance& provenance() const { return provenance_; }
  int branch_sign() const { return branch_sign_; }  //!< +1 or -1: sign of A the rotary nets learnt
  COutput c_output() const { return c_output_; }
  const AxisNets& nets() const { return nets_; }

  /// Full neural IK: A and C from the rotary nets, then X, Y, Z from the position nets fed with
  /// the gauge point tip + tool_length * axis and those A, C. `reference` (the analytic answer
  /// or the previous point) picks the branch and the turn of C. Never throws.
  NeuralIkPrediction predict(const ToolPose& pose, double tool_length,
                             const Axes& reference) const;
  /// Batched predict; `references` has one entry per pose or a single entry for all.
  /// Throws std::invalid_argument on mismatched sizes (a programming error, not a data error).
  void predict(std::span<const ToolPose> poses, double tool_length,
               std::span<const Axes> references, std::span<NeuralIkPrediction> out) const;

  /// Seed 000's use of the position nets: X, Y, Z from the pose and given A, C [deg] (tool-centre
  /// point mode with rotary words; pose.axis must be the tool axis of those A, C, it only shifts
  /// the tip to the gauge point). joints[A], joints[C] are the given values; only the X, Y, Z
  /// envelope bits can be set. Never throws.
  NeuralIkPrediction predict_linear(const ToolPose& pose, double tool_length, double a_deg,
                                    double c_deg) const;

 private:
  void predict_block(std::span<const ToolPose> poses, double tool_length,
                     std::span<const Axes> references, std::span<NeuralIkPrediction> out) const;

  ModelProvenance provenance_;
  int branch_sign_ = -1;
  COutput c_output_ = COutput::kSinCos;
  AxisNets nets_;
  std::array<MlpInference, kNumAxes> inference_;  //!< float copies used by predict
};

/// Physical -> normalised inputs, column by column.
Eigen::MatrixXd normalise_inputs(const AxisNet& net, const Eigen::Ref<const Eigen::MatrixXd>& x);
/// Physical -> normalised targets.
Eigen::MatrixXd normalise_outputs(const AxisNet& net, const Eigen::Ref<const Eigen::MatrixXd>& y);
/// Normalised -> physical outputs.
Eigen::MatrixXd denormalise_outputs(const AxisNet& net,
                                    const Eigen::Ref<const Eigen::MatrixXd>& y_normalised);

/// `angle` shifted by whole turns to the value nearest `reference` [deg].
double unwrap_near(double angle, double reference);
/// Signed difference a - b wrapped to [-180, 180) [deg].
double angle_difference(double a, double b);

}  // namespace gcpipe::neural
