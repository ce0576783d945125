// Neural IK (stages/ik/neural_ik.hpp, neural_train.hpp): the gauge-point assumption against the
// analytic FK, the model file (round trip, rejection of bad files), prediction (branch, C turn,
// envelope, batching), determinism, the paper preset's data and split, and the accuracy of the
// default (improved) preset against thresholds set from measured values.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <optional>
#include <string>

#include "gcpipe/kinematics.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "neural_ik.hpp"
#include "neural_train.hpp"

using namespace gcpipe;
using namespace gcpipe::neural;

namespace {

const PipelineConfig& mx330_config() {
  static const PipelineConfig pc =
      load_pipeline_config(std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/default.yaml");
  return pc;
}

const MachineKinematics& mx330() {
  static const MachineKinematics m = load_kinematics(mx330_config().machine_section);
  return m;
}

/// A small, quickly trained model: enough to exercise every code path, not accurate.
NeuralTrainingOptions tiny_options(std::uint64_t seed = 3) {
  NeuralTrainingOptions o = preset_options("improved");
  o.seed = seed;
  o.position_samples = 300;
  o.position_split = {200, 50};
  o.rotary_samples = 200;
  o.rotary_split = {130, 35};
  o.levenberg_marquardt.max_iterations = 8;
  o.hidden = {{{6}, {6}, {6}, {5}, {5}}};
  return o;
}

const NeuralIk& tiny_model() {
  static const NeuralIk model = train_neural_ik(mx330(), "mx330", tiny_options());
  return model;
}

Axes random_joints(std::mt19937_64& rng, double min_tilt = 2.0) {
  Axes j;
  for (int a = 0; a < kNumAxes; ++a) j[a] = uniform(rng, mx330().travel[a].min, mx330().travel[a].max);
  j[kC] = uniform(rng, -180, 180);
  if (std::abs(j[kA]) < min_tilt) j[kA] = -min_tilt;
  return j;
}

std::string replace_line(const std::string& text, const std::string& prefix,
                         const std::string& replacement) {
  const std::size_t at = text.find(prefix);
  if (at == std::string::npos) return text;
  const std::size_t end = text.find('\n', at);
  return text.substr(0, at) + replacement + text.substr(end);
}

std::string parse_error(const std::string& text) {
  try {
    NeuralIk::parse(text, "m.model");
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(NeuralIk, GaugePointShiftIsExactInTheAnalyticModel) {
  // The nets take P = tip + L * axis; that removes the tool length only if FK with length L moves
  // the tip by exactly -L * axis.
  std::mt19937_64 rng(1);
  for (int i = 0; i < 1000; ++i) {
    const Axes j = random_joints(rng, 0.0);
    const double length = uniform(rng, 0, 250);
    const ToolPose with = forward_kinematics(mx330(), j, length);
    const ToolPose without = forward_kinematics(mx330(), j, 0.0);
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(with.tip[k] + length * with.axis[k], without.tip[k], 1e-9);
  }
}

TEST(NeuralIk, ModelFileRoundTripsBitForBit) {
  const NeuralIk& model = tiny_model();
  const std::string text = model.serialise();
  ASSERT_EQ(text.rfind("gcpipe-neural-ik v1\nmachine mx330\npreset improved\nseed 3\n", 0), 0u)
      << text.substr(0, 80);
  const NeuralIk loaded = NeuralIk::parse(text);
  EXPECT_EQ(loaded.serialise(), text);
  for (int a = 0; a < kNumAxes; ++a) {
    const auto& p = model.nets()[a].mlp.parameters();
    const auto& q = loaded.nets()[a].mlp.parameters();
    ASSERT_EQ(p.size(), q.size());
    for (Eigen::Index i = 0; i < p.size(); ++i) ASSERT_EQ(p[i], q[i]);
  }
  const std::filesystem::path path =
      std::filesystem::path(GCPIPE_BINARY_DIR) / "neural_ik_test_roundtrip.model";
  model.save(path);
  const NeuralIk from_file = NeuralIk::load(path);
  std::mt19937_64 rng(2);
  for (int i = 0; i < 100; ++i) {
    const Axes j = random_joints(rng);
    const ToolPose pose = forward_kinematics(mx330(), j, 0.0);
    const NeuralIkPrediction a = model.predict(pose, 0.0, j);
    const NeuralIkPrediction b = from_file.predict(pose, 0.0, j);
    for (int k = 0; k < kNumAxes; ++k) EXPECT_EQ(a.joints[k], b.joints[k]);
  }
  std::filesystem::remove(path);
}

TEST(NeuralIk, LoadingRejectsBadFilesWithAReason) {
  const std::string good = tiny_model().serialise();
  EXPECT_NE(parse_error(replace_line(good, "gcpipe-neural-ik", "gcpipe-neural-ik v2"))
                .find("m.model:1: unsupported model version 'v2'"),
            std::string::npos);
  EXPECT_NE(parse_error("hello\n").find("not a gcpipe neural IK model"), std::string::npos);
  EXPECT_NE(parse_error(replace_line(good, "layers 5 ", "layers 4 6 1")).find("net X maps 4 -> 1"),
            std::string::npos);
  EXPECT_NE(parse_error(replace_line(good, "c_output", "c_output degrees")).find("c_output"),
            std::string::npos);
  EXPECT_NE(parse_error(replace_line(good, "parameters", "parameters 3"))
                .find("3 parameters announced"),
            std::string::npos);
  EXPECT_NE(parse_error(replace_line(good, "input_min", "input_min nan 0 0 0 0")).find("finite"),
            std::string::npos);
  EXPECT_NE(parse_error(replace_line(good, "input_min", "input_min 1 2 3")).find("has 3 values"),
            std::string::npos);
  EXPECT_NE(parse_error(replace_line(good, "input_max", "input_max -1e9 -1e9 -1e9 -1e9 -1e9"))
                .find("range is empty"),
            std::string::npos);
  // A NaN weight: the first parameter line of net X.
  const std::size_t weights = good.find('\n', good.find("parameters ")) + 1;
  std::string nan_weight = good;
  nan_weight.replace(weights, good.find(' ', weights) - weights, "NaN");
  EXPECT_NE(parse_error(nan_weight).find("net X parameter[0]"), std::string::npos);
  // Cut after a whole line (a cut inside a line is caught by whatever that line then lacks).
  const std::string truncated = parse_error(good.substr(0, good.rfind('\n', good.size() / 2) + 1));
  EXPECT_NE(truncated.find("unexpected end of model file"), std::string::npos) << truncated;
  EXPECT_NE(parse_error(good + "net X\n").find("unexpected text after the last net"),
            std::string::npos);
  EXPECT_NE(parse_error(replace_line(good, "machine", "machine two words")).find("takes one value"),
            std::string::npos);
  EXPECT_THROW(NeuralIk({"two words", "custom", 1}, -1, COutput::kSinCos, tiny_model().nets()),
               std::invalid_argument);
  EXPECT_THROW(NeuralIk::load("/nonexistent/dir/x.model"), std::runtime_error);
}

TEST(NeuralIk, EnvelopeFlagsInputsOutsideTheTrainingRanges) {
  const NeuralIk& model = tiny_model();
  std::mt19937_64 rng(4);
  // Training-range interior: joints well inside travel and tilt.
  Axes inside{10, -20, 5, -60, 30};
  const ToolPose pose = forward_kinematics(mx330(), inside, 0.0);
  EXPECT_EQ(model.predict(pose, 0.0, inside).outside_envelope, 0);
  // Same pose with C given over several turns: the position nets see C modulo 360.
  Axes turned = inside;
  turned[kC] = 30 - 3 * 360;
  const NeuralIkPrediction p = model.predict(pose, 0.0, turned);
  EXPECT_EQ(p.outside_envelope, 0);
  EXPECT_NEAR(p.joints[kC], turned[kC], 180);  // on the caller's turn
  // A tip 2 m away: every position net is outside.
  ToolPose far = pose;
  far.tip[0] += 2000;
  EXPECT_EQ(model.predict(far, 0.0, inside).outside_envelope & 0b111, 0b111);
  // Nearly vertical tool (A = -0.1 deg, below min_tilt = 1 deg): C undefined -> A and C flagged.
  Axes flat = inside;
  flat[kA] = -0.1;
  const NeuralIkPrediction q = model.predict(forward_kinematics(mx330(), flat, 0.0), 0.0, flat);
  EXPECT_TRUE(q.outside_envelope & (1u << kA));
  EXPECT_TRUE(q.outside_envelope & (1u << kC));
  // predict_linear: only position bits.
  EXPECT_EQ(model.predict_linear(far, 0.0, inside[kA], inside[kC]).outside_envelope, 0b111);
  EXPECT_EQ(model.predict_linear(pose, 0.0, inside[kA], inside[kC]).outside_envelope, 0);
}

TEST(NeuralIk, ReferencePicksBranchAndTurnOfC) {
  const NeuralIk& model = tiny_model();
  ASSERT_EQ(model.branch_sign(), -1);  // mx330: A travel -125..+10
  const Axes joints{0, 0, 0, -40, 50};
  const ToolPose pose = forward_kinematics(mx330(), joints, 0.0);
  const NeuralIkPrediction same = model.predict(pose, 0.0, joints);
  // The other branch of the same orientation: (A, C) -> (-A, C + 180).
  const Axes other{0, 0, 0, 40, 230};
  const NeuralIkPrediction flipped = model.predict(pose, 0.0, other);
  EXPECT_DOUBLE_EQ(flipped.joints[kA], -same.joints[kA]);
  EXPECT_NEAR(flipped.joints[kC], same.joints[kC] + 180, 1e-9);
  // Two turns up.
  const Axes up{0, 0, 0, -40, 50 + 720};
  EXPECT_NEAR(model.predict(pose, 0.0, up).joints[kC], same.joints[kC] + 720, 1e-9);
}

TEST(NeuralIk, BatchedPredictEqualsSinglePredict) {
  const NeuralIk& model = tiny_model();
  std::mt19937_64 rng(5);
  std::vector<ToolPose> poses;
  std::vector<Axes> refs;
  for (int i = 0; i < 700; ++i) {  // spans several internal chunks
    refs.push_back(random_joints(rng));
    poses.push_back(forward_kinematics(mx330(), refs.back(), 50.0));
  }
  std::vector<NeuralIkPrediction> batch(poses.size());
  model.predict(poses, 50.0, refs, batch);
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const NeuralIkPrediction one = model.predict(poses[i], 50.0, refs[i]);
    for (int a = 0; a < kNumAxes; ++a) ASSERT_EQ(batch[i].joints[a], one.joints[a]) << i;
    ASSERT_EQ(batch[i].outside_envelope, one.outside_envelope);
  }
  std::vector<NeuralIkPrediction> wrong(3);
  EXPECT_THROW(model.predict(poses, 0.0, refs, wrong), std::invalid_argument);
}

TEST(NeuralIk, NonFiniteInputGivesNoAnswerAndNoThrow) {
  const NeuralIk& model = tiny_model();
  ToolPose bad;
  bad.tip = {std::nan(""), 0, 0};
  EXPECT_FALSE(model.predict(bad, 0.0, Axes{}).finite);
  ToolPose zero_axis;
  zero_axis.axis = {0, 0, 0};
  EXPECT_FALSE(model.predict(zero_axis, 0.0, Axes{}).finite);
  EXPECT_FALSE(model.predict_linear(ToolPose{}, 0.0, std::nan(""), 0).finite);
  EXPECT_TRUE(model.predict(ToolPose{{1, 2, 3}, {0.3, 0.1, 0.9}}, 10.0, Axes{}).finite);
}

TEST(NeuralIk, FloatInferenceMatchesTheDoubleNets) {
  // predict_linear evaluates the position nets in float; the double path built by hand from the
  // stored nets must agree far below the nets' own error.
  const NeuralIk& model = tiny_model();
  std::mt19937_64 rng(6);
  double worst = 0;
  for (int i = 0; i < 300; ++i) {
    const Axes j = random_joints(rng);
    const ToolPose pose = forward_kinematics(mx330(), j, 0.0);
    const NeuralIkPrediction p = model.predict_linear(pose, 0.0, j[kA], j[kC]);
    Eigen::VectorXd in(5);
    in << pose.tip[0], pose.tip[1], pose.tip[2], j[kA], j[kC];
    for (int a = kX; a <= kZ; ++a) {
      const AxisNet& net = model.nets()[a];
      const double exact =
          denormalise_outputs(net, net.mlp.forward(normalise_inputs(net, in)))(0, 0);
      worst = std::max(worst, std::abs(exact - p.joints[a]));
    }
  }
  EXPECT_LT(worst, 1e-3) << "mm; float rounding of a ~300 mm output is ~1e-5 mm";
}

TEST(NeuralIk, TrainingIsDeterministicForASeed) {
  const std::string a = train_neural_ik(mx330(), "mx330", tiny_options(9)).serialise();
  const std::string b = train_neural_ik(mx330(), "mx330", tiny_options(9)).serialise();
  const std::string c = train_neural_ik(mx330(), "mx330", tiny_options(10)).serialise();
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
}

TEST(NeuralIk, PaperPresetUsesTheGridSplitAndTable5Layers) {
  NeuralTrainingOptions o = preset_options("paper");
  for (auto& gd : o.gradient_descent) gd.max_epochs = 2;  // shapes only
  NeuralTrainingReport report;
  const NeuralIk model = train_neural_ik(mx330(), "mx330", o, &report);
  const int expected_layers[kNumAxes][4] = {
      {5, 25, 11, 1}, {5, 22, 11, 1}, {5, 18, 16, 1}, {2, 10, 14, 1}, {2, 6, 12, 1}};
  for (int a = 0; a < kNumAxes; ++a) {
    const auto& sizes = model.nets()[a].mlp.layer_sizes();
    ASSERT_EQ(sizes.size(), 4u);
    for (int l = 0; l < 4; ++l) EXPECT_EQ(sizes[l], expected_layers[a][l]) << "net " << a;
  }
  for (int a = kX; a <= kZ; ++a) {
    EXPECT_EQ(report.axes[a].training_count, 1042);
    EXPECT_EQ(report.axes[a].validation_count, 1043);
    EXPECT_EQ(report.axes[a].test_count, 1040);  // 3125 = 5^5 points
  }
  for (int a = kA; a <= kC; ++a) {
    EXPECT_EQ(report.axes[a].training_count, 341);
    EXPECT_EQ(report.axes[a].validation_count, 341);
    EXPECT_EQ(report.axes[a].test_count, 342);
  }
  EXPECT_EQ(model.c_output(), COutput::kAngle);
  EXPECT_THROW(preset_options("fast"), std::invalid_argument);
}

TEST(NeuralIk, TrainingRejectsImpossibleOptions) {
  NeuralTrainingOptions o = tiny_options();
  o.position_split = {300, 10};
  EXPECT_THROW(train_neural_ik(mx330(), "mx330", o), std::invalid_argument);
  o = tiny_options();
  o.min_tilt = 95;
  EXPECT_THROW(train_neural_ik(mx330(), "mx330", o), std::invalid_argument);
  o = tiny_options();
  o.hidden[kX] = {0};
  EXPECT_THROW(train_neural_ik(mx330(), "mx330", o), std::invalid_argument);
}
