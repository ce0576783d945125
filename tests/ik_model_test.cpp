// The neural IK model shipped with the MX-330 config (pipeline_configs/models/, `ik.model` in
// pipeline_configs/default.yaml): it loads through the config, was trained for the config's
// machine, and its per-axis errors against the analytic IK on seeded random poses stay under
// the bounds documented in stages/ik/README.md ("Shipped model"). The same measurement sets the
// config's neural_tolerance, so the test also checks that the tolerance flags outliers only.
// GCPIPE_IK_MODEL_POSES sets the number of random poses (default 20000).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <vector>

#include "gcpipe/config.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "ik.hpp"
#include "neural_ik.hpp"
#include "parse.hpp"

using namespace gcpipe;
namespace fs = std::filesystem;

namespace {

PipelineConfig default_config() {
  return load_pipeline_config(fs::path(GCPIPE_SOURCE_DIR) / "pipeline_configs" / "default.yaml");
}

// Top 53 bits of a draw: the same doubles on every standard library.
double uniform(std::mt19937_64& rng, double lo, double hi) {
  return lo + (hi - lo) * static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

// Per-axis |neural - analytic| samples and their order statistics.
struct ErrorStats {
  std::array<std::vector<double>, kNumAxes> abs;
  void add(const Axes& neural, const Axes& analytic) {
    for (int a = 0; a < kNumAxes; ++a) {
      double d = neural[static_cast<std::size_t>(a)] - analytic[static_cast<std::size_t>(a)];
      if (a == kC) d = neural::angle_difference(neural[kC], analytic[kC]);
      abs[static_cast<std::size_t>(a)].push_back(std::fabs(d));
    }
  }
  double quantile(int a, double q) {
    auto& v = abs[static_cast<std::size_t>(a)];
    std::sort(v.begin(), v.end());
    return v.empty() ? 0 : v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
  }
  double rms(int a) const {
    const auto& v = abs[static_cast<std::size_t>(a)];
    double s = 0;
    for (double x : v) s += x * x;
    return v.empty() ? 0 : std::sqrt(s / static_cast<double>(v.size()));
  }
  double max(int a) const {
    const auto& v = abs[static_cast<std::size_t>(a)];
    return v.empty() ? 0 : *std::max_element(v.begin(), v.end());
  }
  void print(const char* what) {
    std::printf("%s (%zu points): axis RMS / p50 / p99 / p99.9 / max [mm, deg]\n", what, abs[0].size());
    for (int a = 0; a < kNumAxes; ++a)
      std::printf("  %c  %.3g / %.3g / %.3g / %.3g / %.3g\n", kAxisLetters[a], rms(a), quantile(a, 0.5),
                  quantile(a, 0.99), quantile(a, 0.999), max(a));
  }
};

}  // namespace

TEST(ShippedIkModel, LoadsThroughTheConfigForItsMachine) {
  const PipelineConfig pc = default_config();
  const IkOptions o = load_ik_options(pc.root.section("ik"));
  ASSERT_FALSE(o.model.empty()) << "pipeline_configs/default.yaml names no ik.model";
  EXPECT_EQ(o.model.parent_path().filename(), "models");
  EXPECT_LT(fs::file_size(o.model), 100'000u) << "keep the shipped model small";
  const auto model = load_ik_model(o, pc.machine.name);
  ASSERT_TRUE(model.has_value());
  EXPECT_EQ(model->provenance().machine, "mx330");
  EXPECT_EQ(model->provenance().preset, "improved");
  EXPECT_EQ(model->provenance().seed, 1u);
  // Trained for mx330, refused for the LinuxCNC machine.
  EXPECT_THROW(load_ik_model(o, "linuxcnc_xyzac_trt"), ConfigError);
  // A missing file is a config error naming the key.
  const fs::path bad = fs::temp_directory_path() / "gcpipe_ik_model_test.yaml";
  {
    std::ofstream f(bad);
    f << "model: models/no_such.model\n";
  }
  try {
    load_ik_options(Config::load_file(bad));
    FAIL() << "a missing model file was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("model"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("no such file"), std::string::npos) << e.what();
  }
  fs::remove(bad);
}

// Random joint vectors inside the MX-330's travel (C over two turns), H1's 100 mm tool: the tool
// pose from FK, then the neural IK in both of the stage's uses (tool vector: all five nets;
// programmed A C: the X Y Z nets) against the analytic joints.
TEST(ShippedIkModel, MeasuredErrorsOnRandomPosesStayUnderTheDocumentedBounds) {
  const PipelineConfig pc = default_config();
  const MachineKinematics& m = pc.machine.kinematics;
  const IkOptions o = load_ik_options(pc.root.section("ik"));
  const auto model = load_ik_model(o, pc.machine.name);
  ASSERT_TRUE(model.has_value());
  const char* env = std::getenv("GCPIPE_IK_MODEL_POSES");
  const int count = env ? std::atoi(env) : 20000;
  const double tool = 100;
  std::mt19937_64 rng(2026);
  ErrorStats full, linear, off_pole;
  int diverged = 0, diverged_off_pole = 0, off_pole_count = 0;
  for (int i = 0; i < count; ++i) {
    Axes j;
    for (int a = 0; a < kNumAxes; ++a)
      j[static_cast<std::size_t>(a)] = uniform(rng, m.travel[static_cast<std::size_t>(a)].min,
                                               m.travel[static_cast<std::size_t>(a)].max);
    j[kC] = uniform(rng, -360, 360);
    const ToolPose pose = forward_kinematics(m, j, tool);
    const auto p = model->predict(pose, tool, j);
    const auto q = model->predict_linear(pose, tool, j[kA], j[kC]);
    ASSERT_TRUE(p.finite && q.finite);
    full.add(p.joints, j);
    linear.add(q.joints, j);
    bool over = false;
    for (int a = 0; a < kNumAxes; ++a) {
      double d = p.joints[static_cast<std::size_t>(a)] - j[static_cast<std::size_t>(a)];
      if (a == kC) d = neural::angle_difference(p.joints[kC], j[kC]);
      over = over || std::fabs(d) > o.neural_tolerance[static_cast<std::size_t>(a)];
    }
    diverged += over;
    if (std::fabs(j[kA]) >= 1) {
      off_pole.add(p.joints, j);
      ++off_pole_count;
      diverged_off_pole += over;
    }
  }
  full.print("tool vector (predict), A over its whole travel");
  off_pole.print("tool vector (predict), |A| >= 1 deg");
  linear.print("programmed A C (predict_linear)");
  std::printf("neural_tolerance exceeded: %d of %d poses (%.3f %%); with |A| >= 1 deg: %d of %d (%.3f %%)\n",
              diverged, count, 100.0 * diverged / count, diverged_off_pole, off_pole_count,
              100.0 * diverged_off_pole / off_pole_count);
  // Bounds documented in stages/ik/README.md ("Shipped model"): about 1.5x the measured values
  // (seed 2026, 20000 poses), so a retrained or damaged model that is clearly worse fails.
  const double max_rms[kNumAxes] = {0.55, 0.75, 0.3, 2.5e-5, 0.2};
  const double max_p999[kNumAxes] = {5, 5.5, 2.6, 2e-4, 1.8};
  const double max_linear_rms[kNumAxes] = {0.02, 0.53, 0.29, 0, 0};
  for (int a = 0; a < kNumAxes; ++a) {
    EXPECT_LT(full.rms(a), max_rms[a]) << kAxisLetters[a];
    EXPECT_LT(full.quantile(a, 0.999), max_p999[a]) << kAxisLetters[a];
    EXPECT_LE(linear.rms(a), max_linear_rms[a]) << kAxisLetters[a];
  }
  // The tolerance flags the tail (and real disagreements), not the bulk.
  EXPECT_LT(diverged, count / 200) << "neural_tolerance flags more than 0.5 % of random poses";
  EXPECT_GT(diverged, 0) << "neural_tolerance flags nothing: it is looser than the model's own tail";
}

// The shipped samples through the IK stage with the model from the config: the five-axis demo
// (G43.4, A C programmed: X Y Z nets) and the tool-vector demo (G43.5: all five nets).
TEST(ShippedIkModel, SamplesThroughTheStageWithTheConfiguredModel) {
  const PipelineConfig pc = default_config();
  const IkOptions o = load_ik_options(pc.root.section("ik"));
  const auto model = load_ik_model(o, pc.machine.name);
  ASSERT_TRUE(model.has_value());
  for (const char* name : {"five_axis_demo.nc", "tool_vector_demo.nc"}) {
    SCOPED_TRACE(name);
    const fs::path path = fs::path(GCPIPE_SOURCE_DIR) / "samples" / name;
    Parser parser(load_parse_options(pc.root.section("parse")), pc.machine, path.string());
    IkStage stage(pc.machine.kinematics, o, pc.machine.initial_position, &*model);
    std::ifstream in(path);
    LineOutput out;
    IkPoint p;
    ErrorStats stats;
    int diverged = 0, points = 0;
    for (std::string line; std::getline(in, line);) {
      parser.feed(line, out);
      if (out.blocks.size() != 1 || !stage.step(out.blocks[0], p)) continue;
      ++points;
      ASSERT_TRUE(p.has_neural);
      stats.add(p.neural_joints, p.joints);
      diverged += (p.flags & kIkNeuralDiverged) != 0;
    }
    stats.print(name);
    std::printf("  neural_diverged on %d of %d points\n", diverged, points);
    EXPECT_GE(points, 14);
    EXPECT_EQ(diverged, 0);
    EXPECT_EQ(stage.summary().failed, 0u);
  }
}

// Three-axis moves (machine axes, A = 0): the tool is along the C axis, every C is a right
// answer, so the stage compares the position nets at the program's A C instead of flagging the
// C net's arbitrary choice (which put X Y tens of mm elsewhere).
TEST(ShippedIkModel, ThreeAxisMovesAreNotFlaggedForTheArbitraryC) {
  const PipelineConfig pc = default_config();
  const IkOptions o = load_ik_options(pc.root.section("ik"));
  const auto model = load_ik_model(o, pc.machine.name);
  ASSERT_TRUE(model.has_value());
  IkStage stage(pc.machine.kinematics, o, pc.machine.initial_position, &*model);
  int points = 0;
  for (const Axes& j : {Axes{100, 50, 10, 0, 0}, Axes{-150, 120, -40, 0, 0}, Axes{80, -200, 60, 0, 30}}) {
    IkInput in;
    in.mode = IkInputMode::kMachineAxes;
    in.axes = j;
    in.tool_length = 100;
    const IkPoint p = stage.solve(in);
    ++points;
    ASSERT_TRUE(p.has_neural);
    EXPECT_EQ(p.flags & kIkNeuralDiverged, 0u) << ik_flags_to_string(p.flags);
    EXPECT_NE(p.flags & kIkNeuralOutsideEnvelope, 0u);
    EXPECT_EQ(p.neural_joints[kC], j[kC]);
    for (int a = 0; a < 3; ++a)
      EXPECT_LT(std::fabs(p.neural_joints[static_cast<std::size_t>(a)] - j[static_cast<std::size_t>(a)]),
                o.neural_tolerance[static_cast<std::size_t>(a)]);
  }
  EXPECT_EQ(points, 3);
  // The summary says these flags only inform, in its text and its count.
  EXPECT_EQ(stage.summary().envelope_flag_only, 3u);
  EXPECT_NE(format_summary(stage.summary(), true).find("3 of them ok: the tool is along C there"), std::string::npos)
      << format_summary(stage.summary(), true);
}
