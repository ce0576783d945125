// Training of the neural IK model from the analytic kinematics (what seed 000 did with the
// machine maker's kinematics software): sample joints within travel, forward kinematics gives the
// inputs, the joints are the targets. Two presets:
//   paper    - seed 000 §5 as far as the paper says: the 5^5 = 3125-point joint grid split
//              1042 / 1043 / 1040 (training / validation / test), Table 5 layer sizes,
//              gradient descent with Table 5's learning rate and momentum, C as an angle.
//   improved - more data (uniform random joints), Levenberg-Marquardt (seed 003), C as
//              (sin C, cos C), same layer sizes.
// Deterministic for a seed: one std::mt19937_64 drives data, split and initial weights in a fixed
// order; nothing depends on time or threads.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "gcpipe/kinematics.hpp"
#include "mlp.hpp"
#include "neural_ik.hpp"

namespace gcpipe::neural {

enum class Sampling : std::uint8_t {
  kGrid = 0,   //!< evenly spaced levels per joint, all combinations
  kRandom = 1  //!< uniform within the ranges
};

enum class Trainer : std::uint8_t { kGradientDescent = 0, kLevenbergMarquardt = 1 };

struct NeuralTrainingOptions {
  std::string preset = "custom";  //!< name written into the model file
  std::uint64_t seed = 1;
  Sampling sampling = Sampling::kRandom;
  // Position nets (X, Y, Z): joints X Y Z A C -> inputs (gauge point, A, C).
  int position_grid_levels = 5;   //!< grid: levels per joint (levels^5 points)
  int position_samples = 2500;    //!< random: number of points
  std::array<int, 2> position_split{1500, 500};  //!< training, validation; the rest is test
  // Rotary nets (A, C): A on the branch side, C over one turn -> tool axis.
  int rotary_grid_levels = 32;    //!< grid: levels of A and of C (levels^2 points)
  int rotary_samples = 2500;      //!< random: number of points
  std::array<int, 2> rotary_split{1500, 500};
  double min_tilt = 1.0;          //!< [deg] rotary data keep |A| >= this: C is undefined at A = 0
  COutput c_output = COutput::kSinCos;
  /// Hidden layers per net. Default: Table 5 for X Y Z A; the C net gets 12-12 instead of 6-12
  /// (Table 5's C net stalled at 0.2-0.3 deg RMS in our runs, 12-12 reaches ~0.05 deg).
  std::array<std::vector<int>, kNumAxes> hidden{{{25, 11}, {22, 11}, {18, 16}, {10, 14}, {12, 12}}};
  Trainer trainer = Trainer::kLevenbergMarquardt;
  /// 600 iterations: at a fixed CPU budget more iterations on fewer samples fitted better than
  /// fewer on more (README, "Neural IK"); validation and test errors stay equal, no overfitting.
  LevenbergMarquardtOptions levenberg_marquardt{.max_iterations = 600};
  /// Per net (X Y Z A C): Table 5's learning rate and momentum. The paper gives no epoch count;
  /// 20000 epochs with a patience of 500 failures (MATLAB's defaults are 1000 and 6) give
  /// gradient descent a fair chance and keep the paper preset under a minute.
  std::array<GradientDescentOptions, kNumAxes> gradient_descent{{{20000, 0.11, 0.30, 500},
                                                                 {20000, 0.71, 0.80, 500},
                                                                 {20000, 0.71, 0.10, 500},
                                                                 {20000, 0.61, 0.70, 500},
                                                                 {20000, 0.41, 0.90, 500}}};
};

/// The named presets: "paper" or "improved". Throws std::invalid_argument for anything else.
NeuralTrainingOptions preset_options(std::string_view preset);

/// Errors of one net. MSE values are on the normalised targets, as seed 000 Table 5.
struct AxisTrainingReport {
  int training_count = 0;
  int validation_count = 0;
  int test_count = 0;
  TrainingResult result;         //!< iterations, stop reason, training and validation MSE
  double test_mse = 0;           //!< normalised net outputs (C sin/cos: both outputs)
  /// C only: MSE of the C angle error, wrapped to [-180, 180) and normalised by 180 deg (the
  /// paper's scale for a C target spanning one turn); equals the plain MSE for an angle net
  /// except where the angle net's error crosses the wrap.
  double validation_mse_angle = 0;
  double test_mse_angle = 0;
  double validation_rms = 0;     //!< [mm | deg], net fed with exact inputs
  double test_rms = 0;           //!< [mm | deg]
  double test_max_abs = 0;       //!< [mm | deg]
  double seconds = 0;            //!< wall time of this net's training (not written to the model)
  double cpu_seconds = 0;        //!< process CPU time of the same
};

/// Errors of the assembled model on fresh random poses (rotary nets' A, C fed into the position
/// nets), per axis [mm | deg].
struct EndToEndReport {
  int count = 0;
  Axes rms{};
  Axes max_abs{};
};

struct NeuralTrainingReport {
  std::array<AxisTrainingReport, kNumAxes> axes;
  EndToEndReport end_to_end;
  /// The position nets alone on the same fresh poses, fed the exact A and C (predict_linear):
  /// how they generalise between the training points, free of rotary-net errors. X Y Z only.
  EndToEndReport position_only;
  double seconds = 0;            //!< total wall time
  double cpu_seconds = 0;        //!< total process CPU time (the figure a loaded machine keeps)
};

/// Called after every iteration (LM) or epoch (gradient descent) of net `axis`.
using NeuralProgressCallback = std::function<void(int axis, const TrainingProgress&)>;

/// Generates the data from the analytic model `m`, trains the five nets and assembles the model.
/// Throws std::invalid_argument for options that cannot work (split larger than the data, no
/// rotary range left after min_tilt, ...), naming the option and value.
NeuralIk train_neural_ik(const MachineKinematics& m, const std::string& machine_name,
                         const NeuralTrainingOptions& options, NeuralTrainingReport* report = nullptr,
                         const NeuralProgressCallback& progress = {});

/// Sign of A whose travel reaches further from zero (+1 on ties): the branch the rotary nets learn.
int training_branch_sign(const MachineKinematics& m);

}  // namespace gcpipe::neural
