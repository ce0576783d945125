// gcpipe calibrate end to end through its library entry point: a simulated trace written as the
// shared CSV, a config whose gains are 20 % off, OUTDIR with calibration.json (schema of issue
// #13), calibrated.yaml that loads as a pipeline config, report.txt and the PNG figures.
#include <gtest/gtest.h>

#include <filesystem>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <sys/wait.h>

#include "calibrate_test_util.hpp"
#include "gcpipe/pipeline_config.hpp"

namespace gcpipe::calibrate {
namespace {

namespace fs = std::filesystem;

TEST(CalibrateRun, CircleWithYBacklashWritesEveryOutput) {
  test::Scenario sc = test::circle_scenario();
  sc.machine.drives.axes[kY].effects.push_back(test::effect("backlash", {{"width", 0.012}}));
  const fs::path dir = test::scratch("run_backlash");
  test::write_csv(test::trace_of(sc, 3), dir / "trace.csv");
  const fs::path cfg = test::write_config(sc.config.drives, dir, "config");
  CalibrateRequest q{{(dir / "trace.csv").string()}, cfg.string(), (dir / "out").string(), std::nullopt, false, true, {}, 0};
  std::ostringstream out, err;
  ASSERT_EQ(run_calibrate(q, out, err), 0) << err.str();
  std::cout << out.str();

  const auto j = test::read_json(dir / "out" / "calibration.json");
  for (const char* k : {"trace", "rows", "period_s", "noise_um", "declared", "effects", "unidentified", "prediction_error", "config"})
    EXPECT_TRUE(j.contains(k)) << k;
  ASSERT_EQ(j["effects"].size(), 1u) << j["effects"].dump(1);
  EXPECT_EQ(j["effects"][0]["axis"], "Y");
  EXPECT_EQ(j["effects"][0]["name"], "backlash");
  EXPECT_NEAR(j["effects"][0]["parameters"]["width"]["value"].get<double>(), 0.012, 0.0012);
  EXPECT_GT(j["effects"][0]["parameters"]["width"]["sigma"].get<double>(), 0);
  EXPECT_LT(j["effects"][0]["criterion_after"].get<double>(), j["effects"][0]["criterion_before"].get<double>() - 10);
  const auto& pe = j["prediction_error"];
  for (const char* m : {"declared", "refit", "calibrated"})
    for (const char* k : {"rms_um", "max_um", "tip_rms_um", "tip_max_um"}) EXPECT_TRUE(pe[m].contains(k)) << m << "." << k;
  EXPECT_LE(pe["calibrated"]["rms_um"]["Y"].get<double>(), 2 * 0.2);
  EXPECT_LE(pe["calibrated"]["rms_um"]["X"].get<double>(), 2 * 0.2);
  EXPECT_GT(pe["declared"]["tip_rms_um"].get<double>(), 10 * pe["calibrated"]["tip_rms_um"].get<double>());
  EXPECT_TRUE(j["declared"]["X"]["Kpp"].contains("held"));

  // calibrated.yaml is a pipeline config that loads as is, with the effect under Y's effects.
  const auto model = compensate::load_model(load_pipeline_config(dir / "out" / "calibrated.yaml"));
  ASSERT_EQ(model.drives.axes[kY].effects.size(), 1u);
  EXPECT_EQ(model.drives.axes[kY].effects[0].type, "backlash");
  EXPECT_NEAR(model.drives.axes[kY].effects[0].get("width", 0), 0.012, 0.0012);
  EXPECT_NEAR(model.drives.axes[kX].Kpp, sc.machine.drives.axes[kX].Kpp, 0.1 * sc.machine.drives.axes[kX].Kpp);
  for (const char* f : {"report.txt", "calibrated_drives.yaml", "plots/criterion.png", "plots/residual_time_Y.png",
                        "plots/residual_velocity_X.png", "plots/residual_position_X.png", "plots/hysteresis_Y.png"})
    EXPECT_TRUE(fs::exists(dir / "out" / f)) << f;
  for (const auto& e : fs::recursive_directory_iterator(dir / "out"))
    EXPECT_EQ(e.path().string().find(".part"), std::string::npos) << e.path();

  // And the executable's main job takes it as is.
  std::ofstream(dir / "circle.nc") << test::circle_program();
  const std::string cmd = std::string(GCPIPE_EXE) + " batch " + (dir / "circle.nc").string() + " -o " + (dir / "batch").string() +
                          " --config " + (dir / "out" / "calibrated.yaml").string() + " > " + (dir / "batch.log").string() + " 2>&1";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
  EXPECT_TRUE(fs::exists(dir / "batch" / "compensated.nc"));
}

/// Runs a gcpipe command line; returns its exit status (WEXITSTATUS) and stdout+stderr.
int run_gcpipe(const std::string& args, std::string& output) {
  const std::string cmd = std::string(GCPIPE_EXE) + " " + args + " 2>&1";
  FILE* pipe = ::popen(cmd.c_str(), "r");
  if (pipe == nullptr) return -1;
  char buf[4096];
  for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, pipe)) > 0;) output.append(buf, n);
  const int status = ::pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(CalibrateRun, TheCommandRunsTheRegisteredStageThroughThePipeline) {
  std::string listed;
  ASSERT_EQ(run_gcpipe("stages", listed), 0);
  EXPECT_NE(listed.find("calibrate   -           program  -"), std::string::npos) << listed;

  // The command (pipeline runner + calibrate stage) and the library entry point agree.
  test::Scenario sc = test::circle_scenario();
  sc.machine.drives.axes[kY].effects.push_back(test::effect("backlash", {{"width", 0.010}}));
  const fs::path dir = test::scratch("run_stage");
  test::write_csv(test::trace_of(sc, 5), dir / "trace.csv");
  const fs::path cfg = test::write_config(sc.config.drives, dir, "config");
  CalibrateRequest q{{(dir / "trace.csv").string()}, cfg.string(), (dir / "library").string(), std::nullopt, false, false, {}, 0};
  std::ostringstream out, err;
  ASSERT_EQ(run_calibrate(q, out, err), 0) << err.str();
  std::string said;
  ASSERT_EQ(run_gcpipe("calibrate " + (dir / "trace.csv").string() + " --config " + cfg.string() + " -o " +
                           (dir / "command").string() + " --no-plots", said), 0) << said;
  const auto lib = test::read_json(dir / "library" / "calibration.json");
  const auto cmd = test::read_json(dir / "command" / "calibration.json");
  EXPECT_EQ(cmd["effects"], lib["effects"]);
  EXPECT_EQ(cmd["prediction_error"], lib["prediction_error"]);
  EXPECT_TRUE(fs::exists(dir / "command" / "calibrated.yaml"));

  // A rejected trace: the stage's failure, exit status 1, nothing written.
  std::ofstream(dir / "short.csv") << "t,X_cmd,Y_cmd,Z_cmd,A_cmd,C_cmd,X,Y,Z,A,C\n0,1,2\n";
  said.clear();
  EXPECT_EQ(run_gcpipe("calibrate " + (dir / "short.csv").string() + " --config " + cfg.string() + " -o " +
                           (dir / "rejected").string(), said), 1);
  EXPECT_NE(said.find("short.csv:2:6: error: row has 3 of 11 columns (truncated?)"), std::string::npos) << said;
  EXPECT_NE(said.find("gcpipe calibrate: "), std::string::npos) << said;
  EXPECT_FALSE(fs::exists(dir / "rejected" / "calibration.json"));
}

TEST(CalibrateRun, EvaluateRefusesATraceOfAnotherProgram) {
  // gcpipe evaluate with the circle's trace and the five-axis move as the program: exit status 1,
  // where they part and what to do, and no figures (issue 29 item 6: it printed max 10557.6 um).
  test::Scenario sc = test::circle_scenario();
  const fs::path dir = test::scratch("evaluate_other");
  test::write_csv(test::trace_of(sc, 3), dir / "circle_run.csv");
  std::ofstream(dir / "five_axis.nc") << test::five_axis_program();
  std::ofstream(dir / "circle.nc") << test::circle_program();
  const fs::path cfg = test::write_config(sc.machine.drives, dir, "machine");
  std::string said;
  EXPECT_EQ(run_gcpipe("evaluate --trace " + (dir / "circle_run.csv").string() + " --program " + (dir / "five_axis.nc").string() +
                           " --config " + cfg.string(), said), 1) << said;
  EXPECT_NE(said.find("gcpipe evaluate: " + (dir / "circle_run.csv").string() + ": the commanded positions are not a run of " +
                      (dir / "five_axis.nc").string() + ": axis Z moves in " + (dir / "five_axis.nc").string() + " (from line 3, at t = "),
            std::string::npos) << said;
  EXPECT_NE(said.find("Was the feed override at 100 %? Pass the program the trace ran"), std::string::npos) << said;
  EXPECT_EQ(said.find("max"), std::string::npos) << said;
  // The program it ran: measured.
  said.clear();
  EXPECT_EQ(run_gcpipe("evaluate --trace " + (dir / "circle_run.csv").string() + " --program " + (dir / "circle.nc").string() +
                           " --config " + cfg.string(), said), 0) << said;
  EXPECT_NE(said.find("cutting (G1 G2 G3): max "), std::string::npos) << said;
}

// Issue 29 item 5: batch warns when the model it compensates with is one whose prediction error
// the calibration knows to be large (calibrated_drives.yaml's prediction_warnings), on the
// console and in diagnostics.txt.
TEST(CalibrateRun, BatchWarnsWhenTheCalibratedModelPredictsBadly) {
  test::Scenario sc = test::circle_scenario();
  servo::DriveSet drives = sc.config.drives;
  drives.prediction_warnings = {"X: the calibrated model predicts the measured trace to 8.9 um rms (noise 0.2 um)"};
  const fs::path dir = test::scratch("run_prediction_warning");
  const fs::path cfg = test::write_config(drives, dir, "config");
  std::ofstream(dir / "circle.nc") << test::circle_program();
  std::string output;
  ASSERT_EQ(run_gcpipe("batch " + (dir / "circle.nc").string() + " -o " + (dir / "batch").string() + " --config " + cfg.string(), output), 0)
      << output;
  EXPECT_NE(output.find("warning: calibrated drives: X: the calibrated model predicts the measured trace to 8.9 um rms"), std::string::npos)
      << output;
  std::ifstream diag(dir / "batch" / "diagnostics.txt");
  const std::string text((std::istreambuf_iterator<char>(diag)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("calibrated drives: X:"), std::string::npos);
}

TEST(CalibrateRun, CircleWithXFrictionShowsTheQuadrantGlitches) {
  // The figures of stages/calibrate/README.md for friction come from this run.
  test::Scenario sc = test::circle_scenario();
  sc.machine.drives.axes[kX].effects.push_back(test::effect("coulomb_friction", {{"torque", 40}, {"velocity_band", 0.01}}));
  const fs::path dir = test::scratch("run_friction");
  test::write_csv(test::trace_of(sc, 8), dir / "trace.csv");
  const fs::path cfg = test::write_config(sc.config.drives, dir, "config");
  CalibrateRequest q{{(dir / "trace.csv").string()}, cfg.string(), (dir / "out").string(), std::nullopt, false, true, {}, 0};
  std::ostringstream out, err;
  ASSERT_EQ(run_calibrate(q, out, err), 0) << err.str();
  const auto j = test::read_json(dir / "out" / "calibration.json");
  ASSERT_EQ(j["effects"].size(), 1u) << j["effects"].dump(1);
  EXPECT_EQ(j["effects"][0]["name"], "coulomb_friction");
  // J is configured 20 % high: the torque comes back relative to it (README, "What a position
  // trace cannot see").
  EXPECT_NEAR(j["effects"][0]["parameters"]["torque"]["value"].get<double>(), 40 * 1.2, 4.8);
  EXPECT_TRUE(fs::exists(dir / "out" / "plots" / "residual_velocity_X.png"));
}

TEST(CalibrateRun, UsageAndBadConfigAreReported) {
  std::ostringstream out, err;
  EXPECT_EQ(run_calibrate(CalibrateRequest{}, out, err), 2);
  EXPECT_NE(err.str().find("usage: gcpipe calibrate"), std::string::npos);
  const fs::path dir = test::scratch("bad_config");
  std::ofstream(dir / "bad.yaml") << "machine: nowhere.yaml\n";
  std::ostringstream e2;
  CalibrateRequest q{{"x.csv"}, (dir / "bad.yaml").string(), (dir / "out").string(), std::nullopt, false, false, {}, 0};
  EXPECT_EQ(run_calibrate(q, out, e2), 1);
  EXPECT_FALSE(e2.str().empty());
}

}  // namespace
}  // namespace gcpipe::calibrate
