// Stage `ik`: resolved blocks to machine joints, analytic and (optionally) neural side by side.
//
// Reads: ResolvedBlock (one per source line, from `parse` or `trochoid`).
// Writes: IkPoint (one per block that ends somewhere: G0/G1/G2/G3 with a target), with the
//         analytic joints, the neural joints when a model is loaded, status band and IkFlag bits.
//
// Three input modes (README "Input modes"):
//   kTcpAngles   tool-centre-point mode (G43.4 / M428) with A C programmed: X Y Z is the tool tip
//                in the workpiece frame, A C are used as given; only X Y Z machine are solved.
//   kToolVector  tool tip plus a tool vector: the IK picks A and C (branch by travel, then by
//                continuity with the previous point; C unwrapped; C held at the pole).
//   kMachineAxes plain machine axes (no TCP): the joints are the program's, forward kinematics
//                gives the tool path in the workpiece frame.
// The tool-vector mode is reached three ways: a block in G43.5 mode (ResolvedBlock::tool_vector_mode,
// I J K programmed: always kToolVector with the block's vector); `IkOptions::resolve_orientation =
// kToolVector`, which turns the programmed A C of a G43.4/M428 block into its tool vector and lets
// the IK choose A and C itself (checks a CAM's branch choice against ours); or IkStage::solve()
// with an IkInput.
//
// Per point never throws; construction and option loading throw ConfigError.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include "gcpipe/block.hpp"
#include "gcpipe/kinematics.hpp"
#include "neural_ik.hpp"

namespace gcpipe {

class Config;

enum class IkInputMode : std::uint8_t { kTcpAngles = 0, kToolVector = 1, kMachineAxes = 2 };
const char* to_string(IkInputMode m);

/// Which solution the stage hands downstream.
enum class IkDownstream : std::uint8_t { kAnalytic = 0, kNeural = 1 };

/// Options of the `ik` section of a pipeline config (all optional; README lists them).
struct IkOptions {
  /// For G43.4/M428 blocks: kTcpAngles uses their programmed A C; kToolVector gives only their
  /// tool vector and the IK chooses A and C (checks a CAM's branch choice against ours). G43.5
  /// blocks always give their I J K vector, whatever this says.
  IkInputMode resolve_orientation = IkInputMode::kTcpAngles;
  /// Neural minus analytic joint difference above which kIkNeuralDiverged is set, per axis
  /// [mm, mm, mm, deg, deg].
  Axes neural_tolerance{0.05, 0.05, 0.05, 0.05, 0.05};
  IkDownstream downstream = IkDownstream::kAnalytic;
  /// Neural model file (`model:`, relative to the config file like `servo.drives`); empty = no
  /// neural solver. Loaded by load_ik_model().
  std::filesystem::path model;
};

/// Reads the `ik` section (unknown keys rejected); throws ConfigError (also when `model` names
/// a file that does not exist).
IkOptions load_ik_options(const Config& ik_section);

/// Loads `options.model` when set (std::nullopt when empty). Throws ConfigError when the file is
/// not a valid model or was trained for another machine than `machine_name` (a model learns one
/// machine's geometry; on another it would be confidently wrong). Typical use:
///   const IkOptions o = load_ik_options(pc.root.section("ik"));
///   const auto model = load_ik_model(o, pc.machine.name);
///   IkStage stage(pc.machine.kinematics, o, pc.machine.initial_position, model ? &*model : nullptr);
std::optional<neural::NeuralIk> load_ik_model(const IkOptions& options, const std::string& machine_name);

/// What the stage solves for one point.
struct IkInput {
  std::uint64_t line = 0;         //!< source line (1-based)
  IkInputMode mode = IkInputMode::kMachineAxes;
  Vec3 tip{};                     //!< kTcpAngles/kToolVector: tool tip, workpiece frame [mm]
  Vec3 tool_vector{0, 0, 1};      //!< kToolVector: tool axis tip -> spindle (any length > 0)
  Axes axes{};                    //!< kTcpAngles: A C used; kMachineAxes: all five [mm, deg]
  double tool_length = 0;         //!< [mm] (G43 H in force, else the machine default)
};

/// One resolved point.
struct IkPoint {
  std::uint64_t line = 0;
  IkInputMode mode = IkInputMode::kMachineAxes;
  ToolPose pose;                  //!< tool tip and axis in the workpiece frame (input or FK)
  Axes joints{};                  //!< analytic joints [mm, deg]
  IkStatus status = IkStatus::kOk;
  std::uint32_t flags = 0;        //!< IkFlag bits, analytic and neural
  bool has_neural = false;        //!< a neural model ran on this point
  Axes neural_joints{};           //!< [mm, deg], valid when has_neural
  /// The joints handed downstream: `joints`, or `neural_joints` when configured and usable.
  const Axes& downstream(IkDownstream d) const {
    return d == IkDownstream::kNeural && has_neural && (flags & kIkNeuralFailed) == 0
               ? neural_joints
               : joints;
  }
};

/// Counts for the batch summary.
struct IkSummary {
  std::uint64_t points = 0;
  std::uint64_t ok = 0, degraded = 0, failed = 0;
  std::uint64_t flag_counts[16] = {};  //!< per IkFlag bit
  std::uint64_t neural_points = 0;
  Axes neural_max_abs_diff{};          //!< max |neural - analytic| per axis [mm, deg]
  Axes neural_sum_sq_diff{};           //!< for the RMS [mm^2, deg^2]
  std::uint64_t first_failed_line = 0; //!< 0 when none failed
  /// Points flagged neural_outside_envelope and still ok: the tool along C, where every C is right
  /// and the neural C is not compared (the flag informs; a real excursion degrades the point).
  std::uint64_t envelope_flag_only = 0;
};

/// Readable multi-line summary (no trailing newline).
std::string format_summary(const IkSummary& s, bool with_neural);

/// The stage: holds the model, options, the optional neural model and the previous joints.
class IkStage {
 public:
  /// `neural` may be null (analytic only); it must outlive the stage.
  IkStage(const MachineKinematics& model, IkOptions options, Axes initial_joints,
          const neural::NeuralIk* neural = nullptr);

  /// Converts a block to its input; false when the block has no end point (no motion, dwell,
  /// unexpanded cycle).
  bool input_from_block(const ResolvedBlock& block, IkInput& in) const;
  /// Solves one point, updates the previous joints and the summary.
  IkPoint solve(const IkInput& in);
  /// input_from_block + solve; false when the block has no point.
  bool step(const ResolvedBlock& block, IkPoint& out);

  const IkSummary& summary() const { return summary_; }
  const IkOptions& options() const { return options_; }
  const MachineKinematics& model() const { return model_; }
  bool has_neural() const { return neural_ != nullptr; }

 private:
  void run_neural(IkPoint& p, double tool_length) const;
  void account(const IkPoint& p);

  MachineKinematics model_;
  IkOptions options_;
  const neural::NeuralIk* neural_;
  Axes previous_;
  IkSummary summary_;
};

}  // namespace gcpipe
