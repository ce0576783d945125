// Accuracy of the default (improved) neural IK preset for the mx330, trained here from scratch
// (about 45 s of CPU). Thresholds come from measurements (stages/ik/README.md, "Neural IK"):
// seeds 1, 2, 3 were trained, and each threshold is about twice the worst of the three, so a
// different compiler's rounding (which changes the LM trajectory) does not fail the test, while
// a real regression (a broken gradient, wrong normalisation, a lost branch) does by orders of
// magnitude. Seed 000 Table 5's errors are checked as well: the nets must beat them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "gcpipe/kinematics.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "neural_ik.hpp"
#include "neural_train.hpp"

using namespace gcpipe;
using namespace gcpipe::neural;

TEST(NeuralIkAccuracy, ImprovedPresetBeatsTable5AndMeetsMeasuredErrors) {
  const PipelineConfig pc =
      load_pipeline_config(std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/default.yaml");
  const MachineKinematics m = load_kinematics(pc.machine_section);
  NeuralTrainingOptions options = preset_options("improved");
  // Seed 1 by default; GCPIPE_NEURAL_SEED=2 or 3 reproduces the other measured seeds.
  if (const char* seed = std::getenv("GCPIPE_NEURAL_SEED")) options.seed = std::strtoull(seed, nullptr, 10);
  std::printf("seed %llu\n", static_cast<unsigned long long>(options.seed));
  NeuralTrainingReport report;
  const NeuralIk model = train_neural_ik(m, pc.machine.name, options, &report);

  // Seed 000 Table 5, MSE on normalised targets (test set).
  const double table5_test_mse[kNumAxes] = {0.0053, 0.0053, 0.0061, 1.236e-4, 0.982e-4};
  // Measured test RMS, seeds 1/2/3: X 0.0169/0.0092/0.0125 mm, Y 0.340/0.232/0.198 mm,
  // Z 0.181/0.162/0.220 mm, A 6.4e-6/2.7e-5/2.1e-5 deg, C 0.047/0.056/0.052 deg.
  const double max_test_rms[kNumAxes] = {0.035, 0.7, 0.45, 6e-5, 0.12};
  for (int a = 0; a < kNumAxes; ++a) {
    const AxisTrainingReport& r = report.axes[a];
    std::printf("net %c: test MSE %.3g (C: angle MSE %.3g), test RMS %.3g, validation RMS %.3g\n",
                kAxisLetters[a], r.test_mse, r.test_mse_angle, r.test_rms, r.validation_rms);
    const double mse = a == kC ? r.test_mse_angle : r.test_mse;
    EXPECT_LT(mse, table5_test_mse[a] / 100) << "net " << kAxisLetters[a];
    EXPECT_LT(r.test_rms, max_test_rms[a]) << "net " << kAxisLetters[a];
    // No overfitting: validation and test errors agree within a factor of 2 (measured <= 1.7,
    // the C net of seed 2).
    EXPECT_LT(r.test_rms, 2 * r.validation_rms) << "net " << kAxisLetters[a];
    EXPECT_LT(r.validation_rms, 2 * r.test_rms) << "net " << kAxisLetters[a];
  }

  // End to end through NeuralIk::predict (float inference, rotary nets feeding the position nets)
  // on fresh poses with a 100 mm tool, |A| >= 5 deg, C over two turns.
  // Measured RMS, seeds 1/2/3 (report.end_to_end, |A| >= 1 deg): X 0.22/0.50/0.46 mm,
  // Y 0.40/0.50/0.50 mm, Z 0.19/0.17/0.23 mm, A 1.1e-5/3.4e-5/2.9e-5 deg, C 0.09/0.21/0.20 deg.
  const double max_rms[kNumAxes] = {1.0, 1.0, 0.5, 7e-5, 0.45};
  for (int a = 0; a < kNumAxes; ++a)
    EXPECT_LT(report.end_to_end.rms[a], max_rms[a]) << "end to end, axis " << kAxisLetters[a];
  std::mt19937_64 rng(2024);
  const double tool = 100.0;
  Axes sum_sq{}, max_abs{};
  const int count = 4000;
  for (int i = 0; i < count; ++i) {
    Axes j;
    for (int a = 0; a < kNumAxes; ++a) j[a] = uniform(rng, m.travel[a].min, m.travel[a].max);
    j[kC] = uniform(rng, -360, 360);
    if (std::abs(j[kA]) < 5) j[kA] = -5;
    const NeuralIkPrediction p = model.predict(forward_kinematics(m, j, tool), tool, j);
    ASSERT_TRUE(p.finite);
    for (int a = 0; a < kNumAxes; ++a) {
      sum_sq[a] += (p.joints[a] - j[a]) * (p.joints[a] - j[a]);
      max_abs[a] = std::max(max_abs[a], std::abs(p.joints[a] - j[a]));
    }
  }
  // Measured RMS of this loop, seeds 1/2/3: X 0.154/0.158/0.141 mm, Y 0.407/0.259/0.225 mm,
  // Z 0.199/0.170/0.226 mm, A 9.6e-6/2.7e-5/2.6e-5 deg, C 0.064/0.067/0.056 deg.
  const double max_predict_rms[kNumAxes] = {0.35, 0.85, 0.5, 6e-5, 0.15};
  std::printf("predict RMS (tool 100 mm, |A| >= 5 deg, %d poses):", count);
  for (int a = 0; a < kNumAxes; ++a) {
    std::printf(" %c %.3g", kAxisLetters[a], std::sqrt(sum_sq[a] / count));
    EXPECT_LT(std::sqrt(sum_sq[a] / count), max_predict_rms[a])
        << "predict, axis " << kAxisLetters[a];
  }
  std::printf("; max");
  for (int a = 0; a < kNumAxes; ++a) std::printf(" %c %.3g", kAxisLetters[a], max_abs[a]);
  std::printf(" [mm, deg]\n");
}
