// gcpipe train-spindle and force.spindle_model end to end (issue 35 item 6, stages/force/README.md
// sec. 8b): a model trained by this test on the UMich runs (skipped, saying so, when they are
// absent) is run by gcpipe batch along the shipped seed 000 slot; the prediction is reported,
// finite and inside the range of the runs it was trained on; a model whose channels the force
// stage cannot supply stops the batch with a message naming the key and the channel.
#include <gtest/gtest.h>

#include <cmath>

#include "cli_helpers.hpp"

namespace {

const std::string kSource = GCPIPE_SOURCE_DIR;
const fs::path kUmich = fs::path(kSource) / ".." / "shared" / "data" / "traces" / "umich_smart_cnc_mill";

std::string run_file(int i) { return (kUmich / ("experiment_0" + std::to_string(i) + ".csv")).string(); }

/// A pipeline config beside the model: the mx330, no servo (batch --no-simulate), the Al7075 set.
/// The UMich runs turned the spindle at 53.3 rev/s (3200 rev/min) or not at all; spindle_speed
/// runs the slot at that speed, the one the model has seen (the sample's S4000 lies outside it).
fs::path write_config(const fs::path& dir, const std::string& model) {
  const fs::path cfg = dir / "spindle.yaml";
  std::ofstream(cfg) << "machine: " << kSource << "/pipeline_configs/machines/mx330.yaml\n"
                     << "force:\n  material: al7075\n  flutes: 3\n  spindle_speed: 3200\n  spindle_model: " << model << "\n";
  return cfg;
}

TEST(SpindleModelCli, TrainedModelPredictsTheSlotsSpindlePowerWithinItsTrainingRange) {
  if (!fs::exists(kUmich / "experiment_01.csv")) GTEST_SKIP() << "no UMich data at " << kUmich;
  const fs::path dir = tmpdir("spindle_model");
  Outcome t = gcpipe({"train-spindle", run_file(1), run_file(2), run_file(3), "--verify", run_file(4), run_file(5),
                      run_file(6), "-o", (dir / "power.yaml").string(), "--quiet"});
  ASSERT_EQ(t.status, 0) << t.err;
  EXPECT_NE(t.out.find("**chosen**"), std::string::npos) << t.out;
  EXPECT_NE(t.out.find("the lowest verification FPE"), std::string::npos) << t.out;
  EXPECT_TRUE(fs::exists(dir / "power_verification.png"));

  Outcome b = gcpipe({"batch", kSource + "/samples/trochoid_slot_seed000.nc", "--config",
                      write_config(dir, "power.yaml").string(), "-o", (dir / "out").string(), "--quiet", "--no-simulate"});
  ASSERT_EQ(b.status, 0) << b.err;
  const auto report = read_json(dir / "out" / "report.json");
  const auto& force = report.at("force");
  ASSERT_TRUE(force.contains("spindle_model")) << force.dump(2);
  const auto& s = force.at("spindle_model");
  EXPECT_EQ(s.at("quantity"), "power");
  const double lo = s.at("training_range")[0].get<double>(), hi = s.at("training_range")[1].get<double>();
  const double mean = s.at("mean_in_cutting").get<double>(), max = s.at("max_in_cutting").get<double>();
  EXPECT_TRUE(std::isfinite(mean) && std::isfinite(max));
  EXPECT_GE(mean, lo);
  EXPECT_LE(max, hi);
  EXPECT_LE(mean, max);
  EXPECT_TRUE(s.at("prediction_within_training_range").get<bool>());
  // One sample every 0.1 s of the program as the force stage's interpolator times it (its cycle
  // plus the acc/dec settling at the end: none here, there is no drives file), nearly all cutting.
  const double cycle = force.at("programmed").at("interpolated").at("cycle_time_s").get<double>();
  const double samples = s.at("samples").get<double>();
  EXPECT_NEAR(samples, cycle / 0.1, 2.0);
  EXPECT_GT(s.at("cutting_samples").get<double>(), 0.9 * samples);
  EXPECT_TRUE(fs::exists(dir / "out" / "plots" / "spindle_prediction.png"));
  EXPECT_NE(slurp(dir / "out" / "report.txt").find("spindle power (NNOE"), std::string::npos);
}

TEST(SpindleModelCli, ModelWithChannelsTheStageCannotSupplyIsRefused) {
  const fs::path dir = tmpdir("spindle_model_wrong");
  // A depth-of-cut channel, as seed 003's force model has: the force stage has no depth series.
  std::ofstream(dir / "depth.yaml")
      << "format: \"gcpipe spindle NNOE 1\"\nquantity: power\ncolumn: P\nunit: kW\ndata: test\nperiod: 0.1\n"
         "channels: [feed, depth, cutting]\nchannel_units: [mm/s, mm, flag]\nchannel_min: [0, 0, 0]\n"
         "channel_max: [1, 1, 1]\noutput_range: [0, 1]\nnnoe:\n  na: 1\n  hidden: 1\n  channel_lags: [1, 1, 1]\n"
         "  y_offset: 0\n  y_scale: 1\n  u_offset: [0, 0, 0]\n  u_scale: [1, 1, 1]\n"
         "  weights: [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7]\n";
  Outcome b = gcpipe({"batch", kSource + "/samples/trochoid_slot_seed000.nc", "--config",
                      write_config(dir, "depth.yaml").string(), "-o", (dir / "out").string(), "--quiet", "--no-simulate"});
  EXPECT_EQ(b.status, 1);
  EXPECT_NE(b.err.find("force.spindle_model"), std::string::npos) << b.err;
  EXPECT_NE(b.err.find("channel 'depth' in 'mm'"), std::string::npos) << b.err;
  EXPECT_NE(b.err.find("supplies only feed"), std::string::npos) << b.err;
}

}  // namespace
