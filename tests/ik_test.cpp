// The IK stage (stages/ik/ik.hpp): the three input modes, options, and LinuxCNC's own five-axis
// demo programs (impeller, boat) through parse -> ik with the linuxcnc_xyzac_trt config.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "gcpipe/config.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "ik.hpp"
#include "neural_ik.hpp"
#include "neural_train.hpp"
#include "parse.hpp"

using namespace gcpipe;
namespace fs = std::filesystem;

namespace {

PipelineConfig linuxcnc_config() {
  return load_pipeline_config(fs::path(GCPIPE_SOURCE_DIR) / "pipeline_configs" /
                              "linuxcnc_xyzac_trt.yaml");
}

double distance(const Vec3& a, const Vec3& b) {
  return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

// Parses `path` (or returns empty when absent) and runs every block through a fresh stage.
struct ProgramRun {
  std::vector<IkPoint> points;
  IkSummary summary;
  std::uint64_t rejected = 0;
};

ProgramRun run_program(const fs::path& path, IkOptions options) {
  ProgramRun run;
  const PipelineConfig pc = linuxcnc_config();
  Parser parser(load_parse_options(pc.root.section("parse")), pc.machine, path.string());
  IkStage stage(pc.machine.kinematics, options, pc.machine.initial_position);
  std::ifstream in(path);
  LineOutput out;
  IkPoint p;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    parser.feed(line, out);
    if (out.error() != nullptr) ++run.rejected;
    for (const ResolvedBlock& block : out.blocks)
      if (stage.step(block, p)) run.points.push_back(p);
  }
  run.summary = stage.summary();
  return run;
}

fs::path demo(const char* name) {
  return fs::path(GCPIPE_SHARED_DATA) / "gcode/linuxcnc/xyzac_trt" / name;
}

}  // namespace

TEST(IkStage, ThreeInputModes) {
  const PipelineConfig pc = linuxcnc_config();
  const MachineKinematics& m = pc.machine.kinematics;
  IkStage stage(m, IkOptions{}, Axes{});

  // Plain machine axes: joints pass through, FK gives the tool pose.
  IkInput machine;
  machine.line = 7;
  machine.mode = IkInputMode::kMachineAxes;
  machine.axes = {10, -20, 30, -45, 100};
  machine.tool_length = 12;
  const IkPoint a = stage.solve(machine);
  EXPECT_EQ(a.line, 7u);
  EXPECT_EQ(a.status, IkStatus::kOk);
  EXPECT_EQ(a.joints, machine.axes);
  const ToolPose fk = forward_kinematics(m, machine.axes, 12);
  EXPECT_LE(distance(a.pose.tip, fk.tip), 1e-12);

  // Tool-centre point with A C: back to the same joints.
  IkInput tcp;
  tcp.line = 8;
  tcp.mode = IkInputMode::kTcpAngles;
  tcp.tip = fk.tip;
  tcp.axes[kA] = -45;
  tcp.axes[kC] = 100;
  tcp.tool_length = 12;
  const IkPoint b = stage.solve(tcp);
  for (int i = 0; i < kNumAxes; ++i)
    EXPECT_NEAR(b.joints[static_cast<std::size_t>(i)], machine.axes[static_cast<std::size_t>(i)],
                1e-9);

  // Tool vector: the stage picks the branch next to the previous point (A = -45, C = 100).
  IkInput vec;
  vec.line = 9;
  vec.mode = IkInputMode::kToolVector;
  vec.tip = fk.tip;
  vec.tool_vector = {2 * fk.axis[0], 2 * fk.axis[1], 2 * fk.axis[2]};  // any length
  vec.tool_length = 12;
  const IkPoint c = stage.solve(vec);
  EXPECT_EQ(c.status, IkStatus::kOk);
  for (int i = 0; i < kNumAxes; ++i)
    EXPECT_NEAR(c.joints[static_cast<std::size_t>(i)], machine.axes[static_cast<std::size_t>(i)],
                1e-9);

  // Out of travel in machine-axes mode: failed, line reported in the summary.
  machine.line = 11;
  machine.axes[kA] = -120;
  const IkPoint d = stage.solve(machine);
  EXPECT_EQ(d.status, IkStatus::kFailed);
  EXPECT_EQ(d.flags, kIkTravelLimit);
  EXPECT_EQ(stage.summary().failed, 1u);
  EXPECT_EQ(stage.summary().first_failed_line, 11u);
  EXPECT_EQ(stage.summary().points, 4u);
  EXPECT_FALSE(a.has_neural);
}

TEST(IkStage, BlocksFromTheParser) {
  const PipelineConfig pc = linuxcnc_config();
  Parser parser(load_parse_options(pc.root.section("parse")), pc.machine, "inline");
  IkStage stage(pc.machine.kinematics, IkOptions{}, pc.machine.initial_position);
  LineOutput out;
  IkPoint p;
  std::vector<IkPoint> points;
  for (const char* line : {"G21 G90 G94", "G1 X10 Y0 Z5 A0 C0 F100", "M428",
                           "G1 X10 Y0 Z5 A-30 C90", "G4 P1", "M429", "G0 X0 Y0 Z0 A0 C0"}) {
    parser.feed(line, out);
    ASSERT_EQ(out.blocks.size(), 1u) << line;
    if (stage.step(out.blocks[0], p)) points.push_back(p);
  }
  ASSERT_EQ(points.size(), 3u);
  EXPECT_EQ(points[0].mode, IkInputMode::kMachineAxes);
  EXPECT_EQ(points[0].line, 2u);
  EXPECT_EQ(points[1].mode, IkInputMode::kTcpAngles);
  EXPECT_EQ(points[1].line, 4u);
  // TCP: the tip stays at (10, 0, 5) in the workpiece while the table turns.
  EXPECT_LE(distance(forward_kinematics(pc.machine.kinematics, points[1].joints, 0).tip,
                     {10, 0, 5}),
            1e-9);
  EXPECT_NE(points[1].joints[kX], 10);  // the machine had to move to keep it there
  EXPECT_EQ(points[2].mode, IkInputMode::kMachineAxes);
}

TEST(IkStage, OptionsLoadAndRejectUnknownKeys) {
  const IkOptions o = load_ik_options(Config::from_string(
      "resolve_orientation: tool_vector\nneural_tolerance: [0.1, 0.1, 0.2, 0.01, 0.02]\n"
      "downstream: neural\n"));
  EXPECT_EQ(o.resolve_orientation, IkInputMode::kToolVector);
  EXPECT_EQ(o.neural_tolerance[kZ], 0.2);
  EXPECT_EQ(o.downstream, IkDownstream::kNeural);
  EXPECT_THROW(load_ik_options(Config::from_string("tolerance: 1\n")), ConfigError);
  EXPECT_THROW(load_ik_options(Config::from_string("neural_tolerance: [1, 2]\n")), ConfigError);
  EXPECT_THROW(load_ik_options(Config::from_string("downstream: both\n")), ConfigError);
  // The shipped linuxcnc pipeline config has an ik section that loads.
  EXPECT_NO_THROW(load_ik_options(linuxcnc_config().root.section("ik")));
}

// LinuxCNC's impeller (4,510 lines, TCP with A C given, C down to -399.8 deg) and boat programs.
// Programmed mode: every point within travel, the joints' A C are the program's, FK(joints) is
// the programmed tip. Tool-vector mode (the IK chooses A and C from the tool axis alone): the
// same tip and tool axis, C never steps by 180 deg or more between points (no wrap jumps), and
// A, C equal the CAM's own choice modulo whole turns of C.
class LinuxcncDemo : public ::testing::TestWithParam<const char*> {};

double angle_between_deg(const Vec3& u, const Vec3& v) {
  const double c[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                       u[0] * v[1] - u[1] * v[0]};
  return std::atan2(std::hypot(c[0], c[1], c[2]), u[0] * v[0] + u[1] * v[1] + u[2] * v[2]) *
         180.0 / M_PI;
}

TEST_P(LinuxcncDemo, ThroughIkAndFk) {
  const fs::path file = demo(GetParam());
  if (!fs::exists(file)) GTEST_SKIP() << "third-party data absent: " << file;
  const MachineKinematics m = linuxcnc_config().machine.kinematics;
  const ProgramRun programmed = run_program(file, IkOptions{});
  EXPECT_EQ(programmed.rejected, 0u);
  ASSERT_GT(programmed.points.size(), 1000u);
  EXPECT_EQ(programmed.summary.failed, 0u) << "first failed line "
                                            << programmed.summary.first_failed_line;
  double worst_roundtrip = 0;
  std::uint64_t tcp_points = 0;
  for (const IkPoint& p : programmed.points) {
    EXPECT_EQ(joints_outside_travel(m, p.joints), 0) << "line " << p.line;
    worst_roundtrip =
        std::max(worst_roundtrip, distance(forward_kinematics(m, p.joints, 0).tip, p.pose.tip));
    if (p.mode == IkInputMode::kTcpAngles) ++tcp_points;
  }
  EXPECT_GT(tcp_points, programmed.points.size() / 2);
  EXPECT_LE(worst_roundtrip, 1e-9);

  IkOptions vector_mode;
  vector_mode.resolve_orientation = IkInputMode::kToolVector;
  const ProgramRun chosen = run_program(file, vector_mode);
  ASSERT_EQ(chosen.points.size(), programmed.points.size());
  EXPECT_EQ(chosen.summary.failed, 0u);
  EXPECT_EQ(chosen.summary.flag_counts[std::countr_zero(static_cast<unsigned>(kIkBranchSwitch))],
            0u);
  double worst_tip = 0, worst_axis = 0, worst_c_step = 0, worst_a = 0, worst_c_mod = 0;
  std::uint64_t compared = 0, other_turn = 0;
  for (std::size_t i = 0; i < chosen.points.size(); ++i) {
    const IkPoint& c = chosen.points[i];
    const IkPoint& p = programmed.points[i];
    const ToolPose back = forward_kinematics(m, c.joints, 0);
    worst_tip = std::max(worst_tip, distance(back.tip, p.pose.tip));
    worst_axis = std::max(worst_axis, angle_between_deg(back.axis, p.pose.axis));
    if (i > 0 && c.mode == IkInputMode::kToolVector &&
        chosen.points[i - 1].mode == IkInputMode::kToolVector)
      worst_c_step = std::max(worst_c_step, std::abs(c.joints[kC] - chosen.points[i - 1].joints[kC]));
    if (c.mode != IkInputMode::kToolVector || (c.flags & kIkCKeptAtSingularity)) continue;
    ++compared;
    worst_a = std::max(worst_a, std::abs(c.joints[kA] - p.joints[kA]));
    const double turns = (c.joints[kC] - p.joints[kC]) / 360.0;
    worst_c_mod = std::max(worst_c_mod, std::abs(turns - std::round(turns)) * 360.0);
    if (std::round(turns) != 0) ++other_turn;
  }
  EXPECT_GT(compared, 1000u);
  EXPECT_LE(worst_tip, 1e-9);
  EXPECT_LE(worst_axis, 1e-9);
  EXPECT_LT(worst_c_step, 180.0) << "a wrap jump in C";
  EXPECT_LE(worst_a, 1e-9);
  EXPECT_LE(worst_c_mod, 1e-9);
  RecordProperty("points", static_cast<int>(programmed.points.size()));
  RecordProperty("points_on_another_turn_of_c", static_cast<int>(other_turn));
}

INSTANTIATE_TEST_SUITE_P(Programs, LinuxcncDemo,
                         ::testing::Values("impeller-7bl-xyzac.ngc", "boat-xyzac.ngc"));

// The program unwinds C twice while retracted (lines 3401 and 4146: -345 -> -44, -352 -> -89 deg);
// the IK, which knows nothing of retracts, keeps turning the short way and so ends whole turns
// further down. Both are valid; the test pins what each does.
TEST(LinuxcncDemoFacts, ImpellerCTurns) {
  const fs::path file = demo("impeller-7bl-xyzac.ngc");
  if (!fs::exists(file)) GTEST_SKIP() << "third-party data absent: " << file;
  double min_programmed = 0, min_chosen = 0;
  for (const IkPoint& p : run_program(file, IkOptions{}).points)
    min_programmed = std::min(min_programmed, p.joints[kC]);
  IkOptions vector_mode;
  vector_mode.resolve_orientation = IkInputMode::kToolVector;
  for (const IkPoint& p : run_program(file, vector_mode).points)
    min_chosen = std::min(min_chosen, p.joints[kC]);
  EXPECT_NEAR(min_programmed, -399.805, 1e-9);
  EXPECT_LT(min_chosen, -1000.0);
  EXPECT_NEAR(std::remainder(min_chosen - min_programmed, 360.0), 0, 1e-9);
}

// The neural hook: a small model trained from the analytic IK runs beside it on every point; the
// divergence flag follows the configured tolerance and the summary collects the differences.
TEST(IkStage, NeuralSolverRunsBesideTheAnalyticOne) {
  const PipelineConfig pc = linuxcnc_config();
  const MachineKinematics& m = pc.machine.kinematics;
  neural::NeuralTrainingOptions t = neural::preset_options("improved");
  t.position_samples = 600;
  t.position_split = {400, 100};
  t.rotary_samples = 600;
  t.rotary_split = {400, 100};
  t.levenberg_marquardt.max_iterations = 15;
  const neural::NeuralIk model = neural::train_neural_ik(m, pc.machine.name, t);

  IkInput in;
  in.mode = IkInputMode::kToolVector;
  in.line = 3;
  const Axes q{20, -10, 15, -35, 60};
  const ToolPose p = forward_kinematics(m, q, 0);
  in.tip = p.tip;
  in.tool_vector = p.axis;

  IkOptions loose;
  loose.neural_tolerance = {1e3, 1e3, 1e3, 1e3, 1e3};
  IkStage a(m, loose, {0, 0, 0, -30, 50}, &model);
  const IkPoint pa = a.solve(in);
  ASSERT_TRUE(pa.has_neural);
  EXPECT_EQ(pa.flags & kIkNeuralDiverged, 0u);
  EXPECT_EQ(pa.flags & kIkNeuralFailed, 0u);
  EXPECT_EQ(a.summary().neural_points, 1u);
  for (int i = 0; i < kNumAxes; ++i)
    EXPECT_EQ(a.summary().neural_max_abs_diff[static_cast<std::size_t>(i)],
              std::abs(pa.neural_joints[static_cast<std::size_t>(i)] - pa.joints[static_cast<std::size_t>(i)]));
  // The analytic joints still go downstream by default; `neural` hands the other over.
  EXPECT_EQ(&pa.downstream(IkDownstream::kAnalytic), &pa.joints);
  EXPECT_EQ(&pa.downstream(IkDownstream::kNeural), &pa.neural_joints);

  IkOptions tight;
  tight.neural_tolerance = {1e-9, 1e-9, 1e-9, 1e-9, 1e-9};
  IkStage b(m, tight, {0, 0, 0, -30, 50}, &model);
  const IkPoint pb = b.solve(in);
  EXPECT_TRUE(pb.flags & kIkNeuralDiverged);  // a 15-iteration net is not exact to 1e-9
  EXPECT_EQ(pb.status, IkStatus::kDegraded);
  EXPECT_EQ(pb.joints, pa.joints);            // the analytic answer is untouched
}

// samples/tool_vector_demo.nc (MX-330, Fanuc G43.5): every move gives the tip and the tool vector;
// the IK chooses A and C. Checked: A on the side the travel allows, within travel, C unwrapped
// past -360 deg without a jump, the vertical tool handled at the pole, and FK(joints) giving the
// programmed tip and vector back.
TEST(IkStage, ToolVectorSampleThroughIkAndFk) {
  const PipelineConfig pc =
      load_pipeline_config(fs::path(GCPIPE_SOURCE_DIR) / "pipeline_configs" / "default.yaml");
  const MachineKinematics& m = pc.machine.kinematics;
  const fs::path path = fs::path(GCPIPE_SOURCE_DIR) / "samples" / "tool_vector_demo.nc";
  Parser parser(load_parse_options(pc.root.section("parse")), pc.machine, path.string());
  IkStage stage(m, load_ik_options(pc.root.section("ik")), pc.machine.initial_position);
  std::ifstream in(path);
  ASSERT_TRUE(in) << path;
  LineOutput out;
  IkPoint p;
  std::vector<IkPoint> points;
  std::vector<ResolvedBlock> blocks;
  for (std::string line; std::getline(in, line);) {
    parser.feed(line, out);
    ASSERT_EQ(out.error(), nullptr) << format(*out.error());
    if (out.blocks.size() != 1 || !stage.step(out.blocks[0], p)) continue;
    const ResolvedBlock& block = out.blocks[0];
    points.push_back(p);
    blocks.push_back(block);
  }
  ASSERT_EQ(points.size(), 30u);
  double min_c = 0, worst_tip = 0, worst_axis = 0;
  int kept = 0, near_singular = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const IkPoint& q = points[i];
    const ResolvedBlock& b = blocks[i];
    SCOPED_TRACE("line " + std::to_string(q.line) + ": " + b.text);
    ASSERT_TRUE(b.tool_vector_mode);
    EXPECT_EQ(q.mode, IkInputMode::kToolVector);
    EXPECT_NE(q.status, IkStatus::kFailed) << ik_flags_to_string(q.flags);
    EXPECT_EQ(joints_outside_travel(m, q.joints), 0) << q.joints[kA] << " " << q.joints[kC];
    const ToolPose fk = forward_kinematics(m, q.joints, b.tool_length);
    worst_tip = std::max(worst_tip, distance(fk.tip, {b.target[kX], b.target[kY], b.target[kZ]}));
    const double axis_err = angle_between_deg(fk.axis, b.tool_vector);
    // At the vertical tool C is held and A = 0 exactly, the axis is exact as well.
    worst_axis = std::max(worst_axis, axis_err);
    if (q.flags & kIkCKeptAtSingularity) ++kept;
    if (q.flags & kIkNearSingular) ++near_singular;
    // 20 deg of tilt is only reachable on the negative side (A travel -125..+10 deg).
    const double tilt = std::acos(std::clamp(b.tool_vector[2], -1.0, 1.0)) * 180 / M_PI;
    if (tilt > 10) EXPECT_NEAR(q.joints[kA], -tilt, 1e-9);
    if (i > 0) EXPECT_LT(std::fabs(q.joints[kC] - points[i - 1].joints[kC]), 180.0);
    min_c = std::min(min_c, q.joints[kC]);
  }
  EXPECT_LE(worst_tip, 1e-9);
  EXPECT_LE(worst_axis * M_PI / 180, 1e-9);  // [rad]: 1e-9 on the unit vector
  EXPECT_LT(min_c, -360.0);                  // the helix turns C past a full turn
  EXPECT_NEAR(min_c, -540.0, 1e-9);          // -90 - 450 deg, C = -90 - theta on the helix
  EXPECT_EQ(kept, 5);           // the three vertical moves at the start, the one on Y40, the retract
  EXPECT_GE(near_singular, 7);  // and the moves with 0.5 deg of tilt
  EXPECT_EQ(stage.summary().failed, 0u);
}
