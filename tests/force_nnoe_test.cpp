// Seed 003's NNOE on the mechanistic force (stages/force/nnoe_force.hpp): Table 1's five regressor
// structures trained on one simulated run and verified on another; the FPE of the best structure
// on the held-out run below a stated bound.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <numbers>

#include <filesystem>
#include <fstream>

#include "force_nnoe_process.hpp"
#include "force_report.hpp"
#include "nnoe_fast.hpp"
#include "nnoe_force.hpp"
#include "umich_force.hpp"

namespace gcpipe::force {
namespace {

TEST(ForceNnoe, ProcessIsTheClosedFormSlotForceAtSteadyState) {
  // Held feed and depth: the force settles at the Altintas slot value.
  ForceProcess p;
  p.feed_min = p.feed_max = 200;
  p.depth_min = p.depth_max = 6;
  p.noise = 0;
  const ForceSeries s = simulate_force_process(p, 200, 1);
  const Cut cut{4, 200.0 / (4 * 1000), 6, 0, std::numbers::pi};
  EXPECT_NEAR(s.clean.back(), mean_force_closed_form(p.coefficients, cut).norm(), 1e-6);
  EXPECT_EQ(s.force, s.clean);
}

TEST(ForceNnoe, RegressorTextsOfTable1) {
  const auto st = table1_structures();
  ASSERT_EQ(st.size(), 5u);
  EXPECT_EQ(regressor_text(st[0]), "F(t-1) f(t-1) a(t-1)");
  EXPECT_EQ(regressor_text(st[4]), "F(t-1) F(t-2) f(t-1) f(t-2) a(t-1) a(t-2)");  // eq. (13)
  EXPECT_EQ(st[4].text(), "na=2 nb=[2,2] hidden=12");
}

TEST(ForceNnoe, Table1StructuresTrainAndVerify) {
  const ForceProcess p;
  const ForceSeries train = simulate_force_process(p, 3000, 11), verify = simulate_force_process(p, 3000, 12);
  calibrate::NnoeOptions o;
  o.max_iterations = 60;
  const auto scores = compare_structures(train, verify, table1_structures(12), o);
  std::printf("%-44s %10s %12s\n", "regressors", "train FPE%", "verify FPE%");
  double best = 1e9;
  for (const auto& s : scores) {
    std::printf("%-44s %10.2f %12.2f\n", s.regressors.c_str(), s.training_fpe, s.verification_fpe);
    best = std::min(best, s.verification_fpe);
  }
  // The stated bound on held-out data: the best structure's verification FPE under 10 % of the
  // force variance (seed 003's best: 9.4 %). Noise alone (2 % of the mean) is a floor of ~0.1 %.
  EXPECT_LT(best, 10.0);
  const auto& eq13 = scores[4];
  const auto predicted = calibrate::nnoe_simulate(eq13.model, calibrate::Channels{verify.feed, verify.depth}, verify.force.size());
  char note[160];
  std::snprintf(note, sizeof note, "eq. (13), 12 tanh units; verification run (seed 12): FPE %.2f %% (training %.2f %%)",
                eq13.verification_fpe, eq13.training_fpe);
  write_prediction_png(std::filesystem::path(GCPIPE_BINARY_DIR) / "force_nnoe_verification.png", verify.force, predicted,
                       p.period, "NNOE on the mechanistic slot force: verification run", note, "mean force [N]");
  // The float recurrence (the fast path, bench ParallelRunFloat) on the trained eq. (13) model
  // follows the double one over 100 000 steps: rounding does not accumulate in a stable model.
  const ForceSeries long_run = simulate_force_process(p, 100000, 13);
  const calibrate::Channels lu{long_run.feed, long_run.depth};
  const auto yd = calibrate::nnoe_simulate(eq13.model, lu, long_run.force.size());
  const auto yf = calibrate::nnoe_simulate_float(eq13.model, lu, long_run.force.size());
  double worst = 0, spread = 0;
  for (std::size_t t = 0; t < yd.size(); ++t) worst = std::max(worst, std::abs(yf[t] - yd[t])), spread = std::max(spread, std::abs(yd[t] - eq13.model.y_offset));
  std::printf("float vs double recurrence over %zu steps: max difference %.3g N (output spread %.1f N)\n", yd.size(), worst, spread);
  EXPECT_GT(spread, 10.0);
  EXPECT_LT(worst, 1e-4 * eq13.model.y_scale * 20);  // 1e-4 of the output's held range
  // The finding of README sec. 7, kept: the second-order structure of eq. (13) wins here too.
  EXPECT_EQ(scores[4].verification_fpe, best) << "eq. (13) no longer has the lowest verification FPE";
  for (const auto& s : scores) EXPECT_GT(s.training_fpe, 0.0);
}

// Real data: the UMich runs, read from ../shared (skipped when absent). Fit on experiments 1-3,
// verify on 4-6. The bound is what a model that has learnt anything must beat: the verification
// FPE of the best structure under 100 % (the variance of spindle power about the fit runs' mean).
TEST(ForceNnoe, UmichSpindlePowerTrainOnSomeVerifyOnOthers) {
  const std::filesystem::path dir = std::filesystem::path(GCPIPE_SHARED_DATA) / "traces/umich_smart_cnc_mill";
  if (!std::filesystem::exists(dir / "experiment_01.csv")) GTEST_SKIP() << "no UMich data at " << dir;
  std::vector<UmichRun> fit, verify;
  for (int i = 1; i <= 6; ++i)
    (i <= 3 ? fit : verify).push_back(read_umich_run(dir / ("experiment_0" + std::to_string(i) + ".csv")));
  const UmichRun f = concatenate(fit), v = concatenate(verify);
  calibrate::NnoeOptions o;
  o.max_iterations = 40;
  for (bool current : {false, true}) {
    const auto scores = compare_on_umich(f, v, current, o);
    std::printf("UMich spindle %s: fit %s (%zu samples), verify %s (%zu samples)\n", current ? "current" : "power",
                f.file.c_str(), f.power.size(), v.file.c_str(), v.power.size());
    double best = 1e9;
    for (const auto& s : scores) {
      std::printf("  %-50s %10.2f %12.2f\n", s.regressors.c_str(), s.training_fpe, s.verification_fpe);
      best = std::min(best, s.verification_fpe);
    }
    EXPECT_LT(best, 100.0);
    const auto& first = scores[0];
    // The first (stable) structure's FPEs as README sec. 8 records them, within half a point: the
    // force law's generalisation (issue 36) must leave this path unchanged. The second-order rows
    // that go unstable on the held-out runs (178-347 %) are not held to a value.
    const double recorded_fit = current ? 18.65 : 13.76, recorded_verify = current ? 27.94 : 17.48;
    EXPECT_NEAR(first.training_fpe, recorded_fit, 0.5);
    EXPECT_NEAR(first.verification_fpe, recorded_verify, 0.5);
    const auto predicted = calibrate::nnoe_simulate(first.model, calibrate::Channels{v.feed, v.spindle, v.cutting}, v.power.size());
    char note[160];
    std::snprintf(note, sizeof note, "%s: verification FPE %.1f %% (training %.1f %%)", first.regressors.c_str(),
                  first.verification_fpe, first.training_fpe);
    write_prediction_png(std::filesystem::path(GCPIPE_BINARY_DIR) / (current ? "force_nnoe_umich_current.png" : "force_nnoe_umich_power.png"),
                         current ? v.current : v.power, predicted, 0.1,
                         std::string("UMich experiments 4-6 (verification), spindle ") + (current ? "current" : "power"), note,
                         current ? "S1_CurrentFeedback [A]" : "S1_OutputPower");
  }
}

TEST(ForceNnoe, UmichReaderNamesTheMissingColumn) {
  const auto p = std::filesystem::temp_directory_path() / "gcpipe_force_not_umich.csv";
  std::ofstream(p) << "a,b\n1,2\n";
  try {
    (void)read_umich_run(p);
    FAIL() << "accepted a file without the UMich columns";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("X1_CommandVelocity"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("gcpipe_force_not_umich.csv"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace gcpipe::force
