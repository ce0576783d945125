// The spindle model of gcpipe train-spindle (stages/force/spindle_model.hpp, README sec. 8b): a
// model trained on the UMich runs and written to its file predicts, read back, the same series;
// a model whose channels the force stage cannot supply is named as such; the program's inputs on
// the interpolator's clock are the feed, spindle speed and cutting flag worked out by hand.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "gcpipe/config.hpp"
#include "spindle_inputs.hpp"
#include "spindle_model.hpp"

namespace gcpipe::force {
namespace {

const std::filesystem::path kUmich = std::filesystem::path(GCPIPE_SHARED_DATA) / "traces/umich_smart_cnc_mill";

std::vector<std::filesystem::path> runs(int first, int last) {
  std::vector<std::filesystem::path> out;
  for (int i = first; i <= last; ++i) out.push_back(kUmich / ("experiment_0" + std::to_string(i) + ".csv"));
  return out;
}

TEST(ForceSpindle, TrainedModelLoadsBackAndPredictsTheSameSeries) {
  if (!std::filesystem::exists(kUmich / "experiment_01.csv")) GTEST_SKIP() << "no UMich data at " << kUmich;
  for (const char* quantity : {"power", "current"}) {
    SpindleTrainingOptions o;
    o.quantity = quantity;
    const SpindleTraining t = train_spindle_model(runs(1, 3), runs(4, 6), o);
    // The structure kept is the lowest verification FPE of Table 1's five rows (not the ablation).
    ASSERT_EQ(t.table.size(), 6u);
    ASSERT_LT(t.chosen, 5u);
    for (std::size_t i = 0; i < 5; ++i) EXPECT_LE(t.table[t.chosen].verification_fpe, t.table[i].verification_fpe);
    EXPECT_EQ(t.model.verify_fpe, t.table[t.chosen].verification_fpe);

    const auto file = std::filesystem::temp_directory_path() / (std::string("gcpipe_spindle_") + quantity + ".yaml");
    std::ofstream(file) << spindle_model_yaml(t.model);
    const SpindleModel back = read_spindle_model(file);
    EXPECT_EQ(back.quantity, quantity);
    EXPECT_EQ(back.column, t.model.column);
    EXPECT_EQ(back.unit, t.model.unit);
    EXPECT_DOUBLE_EQ(back.period, 0.1);
    ASSERT_EQ(back.channels.size(), 3u);
    EXPECT_EQ(back.channels[0].name, "feed");
    EXPECT_EQ(back.channels[1].unit, "rev/s");
    EXPECT_EQ(back.nnoe.structure.text(), t.model.nnoe.structure.text());
    EXPECT_EQ(unsupplied_channels(back), "");

    // The verification runs through the trained model and through the one read back.
    const auto trained = predict_spindle(t.model, umich_channels(t.verify));
    const auto loaded = predict_spindle(back, umich_channels(t.verify));
    ASSERT_EQ(trained.size(), t.verify.power.size());
    ASSERT_EQ(loaded.size(), trained.size());
    double worst = 0;
    for (std::size_t i = 0; i < trained.size(); ++i) worst = std::max(worst, std::abs(trained[i] - loaded[i]));
    EXPECT_LE(worst, 1e-9) << quantity;
    // And the model is a model of the measurement: its FPE read back is what training reported.
    EXPECT_NEAR(back.verify_fpe, t.model.verify_fpe, 1e-9);
  }
}

/// A model file with a small net whose channels are given.
std::filesystem::path model_file(const std::string& channels, const std::string& units,
                                 const std::string& weights = "[0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7]") {
  // na 1, lags 1 1 1: 4 inputs, 1 tanh unit: 4 + 1 weights in, 1 + 1 out = 7 weights.
  const auto file = std::filesystem::temp_directory_path() / "gcpipe_spindle_channels.yaml";
  std::ofstream(file) << "format: \"gcpipe spindle NNOE 1\"\nquantity: power\ncolumn: P\nunit: kW\ndata: test\n"
                         "period: 0.1\nchannels: " << channels << "\nchannel_units: " << units
                      << "\nchannel_min: [0, 0, 0]\nchannel_max: [1, 1, 1]\noutput_range: [0, 1]\n"
                         "nnoe:\n  na: 1\n  hidden: 1\n  channel_lags: [1, 1, 1]\n  y_offset: 0\n  y_scale: 1\n"
                         "  u_offset: [0, 0, 0]\n  u_scale: [1, 1, 1]\n  weights: " << weights << "\n";
  return file;
}

TEST(ForceSpindle, ChannelsTheForceStageCannotSupplyAreNamed) {
  const SpindleModel depth = read_spindle_model(model_file("[feed, depth, cutting]", "[mm/s, mm, flag]"));
  const std::string why = unsupplied_channels(depth);
  EXPECT_NE(why.find("channel 'depth' in 'mm'"), std::string::npos) << why;
  const SpindleModel radians = read_spindle_model(model_file("[feed, spindle, cutting]", "[mm/min, rad/s, flag]"));
  EXPECT_NE(unsupplied_channels(radians).find("channel 'spindle' in 'rad/s'"), std::string::npos);
  // mm/min and rev/min convert: nothing to say.
  EXPECT_EQ(unsupplied_channels(read_spindle_model(model_file("[feed, spindle, cutting]", "[mm/min, rev/min, flag]"))), "");
}

TEST(ForceSpindle, ModelFileWithTheWrongNumberOfWeightsIsRefused) {
  const auto file = model_file("[feed, spindle, cutting]", "[mm/s, rev/s, flag]", "[0.1, 0.2, 0.3, 0.4, 0.5, 0.6]");
  try {
    (void)read_spindle_model(file);
    FAIL() << "a model with 6 weights for a net of 7 was read";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("'nnoe.weights': has 6 numbers"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("needs 7"), std::string::npos) << e.what();
  }
}

/// A block of the program, on the machine's axes.
ResolvedBlock block(Motion motion, double from, double x, double feed, Spindle spindle, double s) {
  ResolvedBlock b;
  b.motion = motion;
  b.start[kX] = from;
  b.target[kX] = x;
  b.axis_words = 1;
  b.feed = feed;
  b.spindle = spindle;
  b.spindle_speed = s;
  return b;
}

// G1 X100 F600 with the spindle stopped, then G1 X200 F1200 at S3000 M3: on a 1 ms clock without
// acc/dec the path speed is 10 then 20 mm/s, the spindle 0 then 3000 rev/min, cutting only in the
// second block; 10 + 5 s of program, one sample every 0.1 s.
TEST(ForceSpindle, ProgramInputsAreTheInterpolatorsFeedSpindleAndCuttingFlag) {
  interpolate::InterpolateOptions o;
  o.smoothing = interpolate::Smoothing::kNone;
  const std::vector<ResolvedBlock> blocks{block(Motion::kLinear, 0, 100, 600, Spindle::kOff, 3000),
                                          block(Motion::kLinear, 100, 200, 1200, Spindle::kCW, 3000)};
  const ProgramInputs in = sample_program_inputs(blocks, o, Axes{}, 0.1);
  ASSERT_EQ(in.failure, "");
  EXPECT_NEAR(in.period, 0.1, 1e-12);
  ASSERT_NEAR(static_cast<double>(in.feed.size()), 150, 1);
  for (std::size_t i = 0; i < in.feed.size(); ++i) {
    const double t = static_cast<double>(i + 1) * 0.1;  // the speed over the 1 ms tick ending at t
    if (std::abs(t - 10) < 0.05) continue;  // where the second block takes over
    EXPECT_NEAR(in.feed[i], t < 10 ? 10 : 20, 1e-6) << "t = " << t;
    EXPECT_EQ(in.spindle[i], t < 10 ? 0 : 3000) << "t = " << t;
    EXPECT_EQ(in.cutting[i], t < 10 ? 0 : 1) << "t = " << t;
  }
  // The force section's spindle_speed replaces the program's S where the spindle turns.
  const ProgramInputs at3200 = sample_program_inputs(blocks, o, Axes{}, 0.1, 3200);
  EXPECT_EQ(at3200.spindle.back(), 3200);
  EXPECT_EQ(at3200.spindle[50], 0);
}

}  // namespace
}  // namespace gcpipe::force
