// Tool-centre-point interpolation (stages/interpolate, README "Tool-centre-point blocks"): the tool
// tip follows the programmed line or arc in the workpiece frame at the programmed feed, joints
// come from inverse kinematics every tick and respect the joint limits, TCP on/off switching does
// not jump, arcs that turn a rotary axis in joint mode are fed along the tool tip, and
// `gcpipe simulate` runs the five-axis demo with the kinematics.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "gcpipe/config.hpp"
#include "gcpipe/kinematics.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "interpolate.hpp"
#include "parse.hpp"

using namespace gcpipe;
using namespace gcpipe::interpolate;
namespace fs = std::filesystem;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180;

// Raw (unsmoothed) joints and smoothed commands, with the block each sample belongs to.
struct Collect : SampleSink {
  std::vector<Axes> raw, cmd;
  std::vector<std::size_t> block;
  std::size_t current = 0;
  void raw_sample(const Axes& r) override {
    raw.push_back(r);
    block.push_back(current);
  }
  void sample(const Axes& c) override { cmd.push_back(c); }
};

// A table-table machine with offsets everywhere, so that no joint equals a tip coordinate by
// accident: C centre off the origin, A pivot above/behind it.
MachineKinematics test_machine() {
  MachineKinematics m;
  m.c_centre = {12, -7, 3};
  m.a_offset_y = 4;
  m.a_offset_z = -60;
  m.tool_length = 100;
  m.max_velocity = {500, 500, 500, 100, 100};
  m.max_acceleration = {5000, 5000, 5000, 1000, 1000};
  return m;
}

InterpolateOptions tcp_options(const MachineKinematics& m) {
  InterpolateOptions o;
  o.smoothing = Smoothing::kNone;
  o.max_velocity = m.max_velocity;
  o.max_acceleration = m.max_acceleration;
  for (std::size_t i = 0; i < kNumAxes; ++i) {
    o.travel_min[i] = m.travel[i].min;
    o.travel_max[i] = m.travel[i].max;
  }
  o.kinematics = &m;
  return o;
}

ResolvedBlock tcp_block(Motion motion, const Axes& target, double feed, std::uint64_t line = 1) {
  ResolvedBlock b;
  b.motion = motion;
  b.target = target;
  b.feed = feed;
  b.line = line;
  b.tcp = true;
  b.tool_length_active = true;
  b.tool_length = 100;
  b.axis_words = 0x1f;
  return b;
}

Axes joints_for(const MachineKinematics& m, const Vec3& tip, double a, double c) {
  return inverse_kinematics_ac(m, tip, a, c, 100).joints;
}

Vec3 tip(const MachineKinematics& m, const Axes& q, double length = 100) {
  return forward_kinematics(m, q, length).tip;
}

double dist(const Vec3& a, const Vec3& b) { return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]); }

// Distance of p to the segment a-b, and the segment parameter of its foot point.
double segment_distance(const Vec3& a, const Vec3& b, const Vec3& p, double* u_out = nullptr) {
  const Vec3 d{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const Vec3 w{p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  const double u = dd > 0 ? std::clamp((w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) / dd, 0.0, 1.0) : 0.0;
  if (u_out) *u_out = u;
  return dist(p, Vec3{a[0] + u * d[0], a[1] + u * d[1], a[2] + u * d[2]});
}

// Largest per-tick joint step divided by the limit step v_i T (1 = exactly at the limit).
double worst_step_ratio(const std::vector<Axes>& q, const Axes& first, const Axes& vmax, double T) {
  double worst = 0;
  Axes prev = first;
  for (const Axes& p : q) {
    for (std::size_t i = 0; i < kNumAxes; ++i) worst = std::max(worst, std::abs(p[i] - prev[i]) / (vmax[i] * T));
    prev = p;
  }
  return worst;
}

}  // namespace

// TCP line: every raw sample's tool tip (FK of the joints) lies on the programmed line, A and C
// move linearly, the tip advances by F/60 * T per tick, and the joints are continuous.
TEST(TcpInterpolate, LineKeepsTheTipOnTheLineAtTheFeed) {
  const MachineKinematics m = test_machine();
  const Vec3 p0{5, -3, 2}, p1{45, 7, -3};
  const Axes start = joints_for(m, p0, 0, 0);
  Interpolator ip(tcp_options(m), start);
  Collect c;
  const double F = 600;  // 10 mm/s
  const auto r = ip.add(tcp_block(Motion::kLinear, {p1[0], p1[1], p1[2], -20, 30}, F), c);
  ASSERT_EQ(r.status, InterpolateStatus::kOk) << r.message;
  EXPECT_FALSE(r.velocity_limited);
  EXPECT_NEAR(r.duration, dist(p0, p1) / (F / 60), 1e-12);
  ASSERT_EQ(c.raw.size(), static_cast<std::size_t>(std::floor(r.duration / 0.001 + 1e-9)));
  double worst_off = 0, worst_speed = 0, worst_rotary = 0;
  Vec3 prev = p0;
  for (std::size_t n = 0; n < c.raw.size(); ++n) {
    const Vec3 t = tip(m, c.raw[n]);
    double u = 0;
    worst_off = std::max(worst_off, segment_distance(p0, p1, t, &u));
    // s = t / d: A and C linear in s, the tip at s along the line.
    const double s = (static_cast<double>(n) + 1) * 0.001 / r.duration;
    worst_rotary = std::max({worst_rotary, std::abs(c.raw[n][kA] - (-20 * s)), std::abs(c.raw[n][kC] - 30 * s)});
    worst_speed = std::max(worst_speed, std::abs(dist(prev, t) / 0.001 - F / 60));
    prev = t;
  }
  std::printf("TCP line: tip off the line <= %.3g mm, |tip speed - F/60| <= %.3g mm/s\n", worst_off, worst_speed);
  EXPECT_LT(worst_off, 1e-6);
  EXPECT_LT(worst_rotary, 1e-9);
  EXPECT_LT(worst_speed, 1e-6);  // mm/s: the feed measured on the samples' tool tips
  EXPECT_LT(dist(tip(m, ip.position()), p1), 1e-9);  // the block's end (between samples)
  // Joints: not a straight joint move (the tip would leave the line), yet continuous.
  EXPECT_LT(worst_step_ratio(c.raw, start, m.max_velocity, 0.001), 1.0);
  const Axes mid = c.raw[c.raw.size() / 2], lin_mid = [&] {
    Axes q;
    for (std::size_t i = 0; i < kNumAxes; ++i) q[i] = 0.5 * (start[i] + c.raw.back()[i]);
    return q;
  }();
  EXPECT_GT(std::abs(mid[kY] - lin_mid[kY]) + std::abs(mid[kZ] - lin_mid[kZ]), 0.1);
  EXPECT_EQ(ip.stats().tcp_blocks, 1u);
  EXPECT_EQ(ip.stats().ik_failed_samples, 0u);
}

// TCP arc (G17 G3 with a helix and C turning): the tip stays on the programmed helix.
TEST(TcpInterpolate, ArcKeepsTheTipOnTheProgrammedHelix) {
  const MachineKinematics m = test_machine();
  const Vec3 centre{20, 10, 0};
  const Axes start = joints_for(m, {30, 10, 0}, -10, 0);
  Interpolator ip(tcp_options(m), start);
  Collect c;
  ResolvedBlock b = tcp_block(Motion::kArcCCW, {20, 20, -4, -25, 45}, 1200);
  b.centre = centre;
  const auto r = ip.add(b, c);
  ASSERT_EQ(r.status, InterpolateStatus::kOk) << r.message;
  const double len = std::hypot(10 * kPi / 2, 4.0);
  EXPECT_NEAR(r.duration, len / 20, 1e-12);
  double worst_radius = 0, worst_z = 0;
  for (std::size_t n = 0; n < c.raw.size(); ++n) {
    const Vec3 t = tip(m, c.raw[n]);
    const double s = (static_cast<double>(n) + 1) * 0.001 / r.duration;
    worst_radius = std::max(worst_radius, std::abs(std::hypot(t[0] - centre[0], t[1] - centre[1]) - 10));
    worst_z = std::max(worst_z, std::abs(t[2] - (-4 * s)));
    // angle from the centre grows linearly from 0 to 90 deg
    EXPECT_NEAR(std::atan2(t[1] - centre[1], t[0] - centre[0]), s * kPi / 2, 1e-9) << n;
  }
  EXPECT_LT(worst_radius, 1e-6);
  EXPECT_LT(worst_z, 1e-6);
  EXPECT_LT(worst_step_ratio(c.raw, start, m.max_velocity, 0.001), 1.0);
}

// C swinging 180 deg while the tip crosses the C centre: the programmed feed would turn C at
// 900 deg/s; the block is lengthened until C runs at its 100 deg/s limit, and no sample exceeds it.
TEST(TcpInterpolate, JointVelocityLimitHoldsWhenCSwingsNearItsCentre) {
  MachineKinematics m = test_machine();
  const Vec3 cc = m.c_centre;
  const Vec3 p0{cc[0] - 1, cc[1] + 0.05, cc[2]}, p1{cc[0] + 1, cc[1] + 0.05, cc[2]};
  const Axes start = joints_for(m, p0, 0, 0);
  Interpolator ip(tcp_options(m), start);
  Collect c;
  const auto r = ip.add(tcp_block(Motion::kLinear, {p1[0], p1[1], p1[2], 0, 180}, 600), c);
  ASSERT_EQ(r.status, InterpolateStatus::kOk) << r.message;
  EXPECT_TRUE(r.velocity_limited);
  EXPECT_NEAR(r.duration, 1.8, 1e-9);  // 180 deg at 100 deg/s
  const double ratio = worst_step_ratio(c.raw, start, m.max_velocity, 0.001);
  EXPECT_LE(ratio, 1 + 1e-9);
  EXPECT_GT(ratio, 0.99);  // C really runs at its limit
  for (const Axes& q : c.raw) EXPECT_LT(segment_distance(p0, p1, tip(m, q)), 1e-6);
}

// Far from the C centre a C swing drives X and Y along a circle whose speed peaks inside the
// block; slow X/Y limits make the linear joints, not C, the limiting axes. Measured on the
// samples: no tick exceeds a velocity limit, the binding axis reaches it, and the interior
// accelerations (q'' of the joint path) stay within the acceleration limit.
TEST(TcpInterpolate, JointLimitsHoldWhenLinearAxesBindInsideTheBlock) {
  for (const bool accel_binds : {false, true}) {
    MachineKinematics m = test_machine();
    m.max_velocity = {50, 50, 500, 100, 100};
    m.max_acceleration = {accel_binds ? 10.0 : 5000.0, accel_binds ? 10.0 : 5000.0, 5000, 1000, 1000};
    const Vec3 p{m.c_centre[0] + 150, m.c_centre[1], -5};
    const Axes start = joints_for(m, p, 0, -30);
    Interpolator ip(tcp_options(m), start);
    Collect c;
    const auto r = ip.add(tcp_block(Motion::kLinear, {p[0], p[1] + 1, p[2], 0, 60}, 3000), c);
    ASSERT_EQ(r.status, InterpolateStatus::kOk) << r.message;
    EXPECT_TRUE(r.velocity_limited);
    const double T = 0.001;
    const double vratio = worst_step_ratio(c.raw, start, m.max_velocity, T);
    EXPECT_LE(vratio, 1 + 1e-4);
    double aratio = 0;
    for (std::size_t n = 2; n + 1 < c.raw.size(); ++n)  // interior ticks: the block's own curvature
      for (std::size_t i = 0; i < kNumAxes; ++i)
        aratio = std::max(aratio, std::abs(c.raw[n][i] - 2 * c.raw[n - 1][i] + c.raw[n - 2][i]) / (T * T) /
                                      m.max_acceleration[i]);
    EXPECT_LE(aratio, 1 + 1e-2);
    if (accel_binds) {
      EXPECT_GT(aratio, 0.98);
      EXPECT_LT(vratio, 0.99);
    } else {
      EXPECT_GT(vratio, 0.999);
    }
    // X speed at the 150 mm radius: 150 * omega * |sin C| peaks at C = 0, inside the block.
    EXPECT_LT(dist(tip(m, ip.position()), {p[0], p[1] + 1, p[2]}), 1e-9);
  }
}

// A TCP move whose middle leaves the X travel: counted with the block's line, commands finite.
TEST(TcpInterpolate, OutOfTravelTicksAreReportedWithTheLineAndStayFinite) {
  MachineKinematics m = test_machine();
  m.travel[kX] = {-1e4, 60};
  const Vec3 p{m.c_centre[0] + 50, m.c_centre[1], 0};
  const Axes start = joints_for(m, p, 0, -90);
  ASSERT_LT(start[kX], 60);
  Interpolator ip(tcp_options(m), start);
  Collect c;
  // C -90 -> 90: the X joint passes through c_x + 50 = 62 > 60 at C = 0.
  const auto r = ip.add(tcp_block(Motion::kLinear, {p[0], p[1], p[2], 0, 90}, 600, 42), c);
  ASSERT_EQ(r.status, InterpolateStatus::kOk);
  EXPECT_GT(ip.stats().ik_failed_samples, 0u);
  EXPECT_EQ(ip.stats().ik_unreachable_samples, 0u);
  EXPECT_EQ(ip.stats().first_ik_failure_line, 42u);
  EXPECT_GT(ip.stats().travel_violations[kX], 0u);
  EXPECT_EQ(ip.stats().first_violation_line, 42u);
  for (const Axes& q : c.cmd)
    for (double v : q) ASSERT_TRUE(std::isfinite(v));
}

// G43.5: the tool vector is slerped and the IK chooses A and C with continuity; the tip stays on
// the line and the tool axis of every sample is the slerp at that sample's s.
TEST(TcpInterpolate, ToolVectorModeSlerpsTheToolAxis) {
  const MachineKinematics m = test_machine();
  const Vec3 p0{10, 0, 0}, p1{30, 5, -2};
  const Axes start = joints_for(m, p0, -10, 20);
  const Vec3 v0 = tool_axis(m, -10, 20);
  const Vec3 v1{std::sin(35 * kDeg) * std::cos(10 * kDeg), std::sin(35 * kDeg) * std::sin(10 * kDeg), std::cos(35 * kDeg)};
  Interpolator ip(tcp_options(m), start);
  Collect c;
  ResolvedBlock b = tcp_block(Motion::kLinear, {p1[0], p1[1], p1[2], 0, 0}, 600);
  b.tool_vector_mode = true;
  b.tool_vector = {2 * v1[0], 2 * v1[1], 2 * v1[2]};  // any length: normalised
  const auto r = ip.add(b, c);
  ASSERT_EQ(r.status, InterpolateStatus::kOk) << r.message;
  const double omega = std::acos(v0[0] * v1[0] + v0[1] * v1[1] + v0[2] * v1[2]);
  double worst_axis = 0, worst_tip = 0;
  for (std::size_t n = 0; n < c.raw.size(); ++n) {
    const double s = std::min(1.0, (static_cast<double>(n) + 1) * 0.001 / r.duration);
    const ToolPose pose = forward_kinematics(m, c.raw[n], 100);
    const double ang0 = std::acos(std::clamp(pose.axis[0] * v0[0] + pose.axis[1] * v0[1] + pose.axis[2] * v0[2], -1.0, 1.0));
    const double ang1 = std::acos(std::clamp(pose.axis[0] * v1[0] + pose.axis[1] * v1[1] + pose.axis[2] * v1[2], -1.0, 1.0));
    worst_axis = std::max({worst_axis, std::abs(ang0 - s * omega), std::abs(ang1 - (1 - s) * omega)});
    worst_tip = std::max(worst_tip, segment_distance(p0, p1, pose.tip));
  }
  EXPECT_LT(worst_axis, 1e-7);
  EXPECT_LT(worst_tip, 1e-6);
  EXPECT_LT(worst_step_ratio(c.raw, start, m.max_velocity, 0.001), 1.0);
  // A zero tool vector is rejected before anything is emitted.
  const std::size_t before = c.raw.size();
  b.tool_vector = {0, 0, 0};
  EXPECT_EQ(ip.add(b, c).status, InterpolateStatus::kInvalid);
  EXPECT_EQ(c.raw.size(), before);
}

// G43.5 leaving the pole (tool along the C axis, C free and held): C first turns to the C of the
// direction the tool leaves in, at the pole with the tip held and the axis vertical, at F deg/min;
// then the slerp runs with C continuous. Without the turn, C would jump 120 deg in one tick.
TEST(TcpInterpolate, ToolVectorLeavingThePoleTurnsCFirst) {
  const MachineKinematics m = test_machine();
  const Vec3 p0{30, 0, 0}, p1{30, 10, 0};
  const Axes start = joints_for(m, p0, 0, 0);
  Interpolator ip(tcp_options(m), start);
  Collect c;
  ResolvedBlock b = tcp_block(Motion::kLinear, {p1[0], p1[1], p1[2], 0, 0}, 1500);  // 25 mm/s, 25 deg/s
  b.tool_vector_mode = true;
  b.tool_vector = {std::sin(20 * kDeg) * std::sin(60 * kDeg), std::sin(20 * kDeg) * std::cos(60 * kDeg), std::cos(20 * kDeg)};
  const auto r = ip.add(b, c);
  ASSERT_EQ(r.status, InterpolateStatus::kOk) << r.message;
  const IkResult end = inverse_kinematics(m, ToolPose{p1, b.tool_vector}, start, 100);
  const double turn = std::abs(end.joints[kC]);  // from C 0 to the leaving C
  ASSERT_GT(turn, 10.0);
  EXPECT_NEAR(r.duration, turn / 25 + 10.0 / 25, 1e-9);
  EXPECT_EQ(ip.stats().blocks, 1u);
  EXPECT_LE(worst_step_ratio(c.raw, start, m.max_velocity, 0.001), 1 + 1e-9);
  const std::size_t turn_ticks = static_cast<std::size_t>(turn / 25 / 0.001);
  for (std::size_t n = 0; n < c.raw.size(); ++n) {
    const ToolPose pose = forward_kinematics(m, c.raw[n], 100);
    EXPECT_LT(segment_distance(p0, p1, pose.tip), 1e-9) << n;
    if (n < turn_ticks) {  // turning at the pole: tip and tool axis still
      EXPECT_LT(dist(pose.tip, p0), 1e-9) << n;
      EXPECT_NEAR(pose.axis[2], 1.0, 1e-12) << n;
    }
  }
  EXPECT_NEAR(ip.position()[kC], end.joints[kC], 1e-9);
}

TEST(TcpInterpolate, TcpBlockWithoutKinematicsIsUnsupported) {
  InterpolateOptions o;
  Interpolator ip(o, Axes{});
  Collect c;
  const auto r = ip.add(tcp_block(Motion::kLinear, {1, 0, 0, 0, 0}, 600), c);
  EXPECT_EQ(r.status, InterpolateStatus::kUnsupported);
  EXPECT_NE(r.message.find("kinematics"), std::string::npos);
  EXPECT_TRUE(c.raw.empty());
}

// Joint-mode arc (G17 G2) while C turns 90 deg: G94 F is along the tool tip's path relative to
// the workpiece, measured here as the sum of FK tip chords of the 1 ms samples.
TEST(TcpInterpolate, JointArcWithRotaryIsFedAlongTheToolTip) {
  const MachineKinematics m = test_machine();
  InterpolateOptions o = tcp_options(m);
  const Axes start{m.c_centre[0] + 40, m.c_centre[1], 50, 0, 0};
  Interpolator ip(o, start);
  Collect c;
  ResolvedBlock b;
  b.motion = Motion::kArcCW;
  b.centre = {m.c_centre[0] + 30, m.c_centre[1], 50};
  b.target = {m.c_centre[0] + 20, m.c_centre[1], 50, 0, 90};
  b.feed = 1200;  // 20 mm/s
  b.line = 3;
  b.axis_words = 0x1f;
  const auto r = ip.add(b, c);
  ASSERT_EQ(r.status, InterpolateStatus::kOk) << r.message;
  double measured = 0;
  Vec3 prev = tip(m, start, 0);
  for (const Axes& q : c.raw) {
    const Vec3 t = tip(m, q, 0);
    measured += dist(prev, t);
    prev = t;
  }
  EXPECT_NEAR(measured / r.duration, 20.0, 20.0 * 1e-5);
  // The XYZ arc length alone (10 pi mm) would give a much shorter block: the rule matters here.
  EXPECT_GT(r.duration, 1.5 * (10 * kPi / 20));
  // Without a rotary axis moving, the tip path is the joint path (FK is a rigid motion).
  Interpolator ip2(o, start);
  b.target[kC] = 0;
  EXPECT_NEAR(ip2.add(b, c).duration, 10 * kPi / 20, 1e-12);
}

namespace {

PipelineConfig default_config() {
  return load_pipeline_config(fs::path(GCPIPE_SOURCE_DIR) / "pipeline_configs" / "default.yaml");
}

std::vector<std::string> demo_lines() {
  std::ifstream in(fs::path(GCPIPE_SOURCE_DIR) / "samples" / "five_axis_demo.nc");
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) {
    if (!l.empty() && l.back() == '\r') l.pop_back();
    lines.push_back(l);
  }
  return lines;
}

// Parses the lines and interpolates them as `gcpipe simulate` does (kinematics, limits, Ts-free
// raw path: smoothing off so the raw joints are what is checked), keeping the blocks.
struct DemoRun {
  std::vector<ResolvedBlock> blocks;  // blocks given to the interpolator, in order
  std::vector<Vec3> block_start_tip;  // FK tip (block's tool length) of the joints at its start
  std::vector<Axes> block_start_joints;
  Collect c;
  Axes start{};
  InterpolateStats stats;
};

DemoRun run_demo(const std::vector<std::string>& lines, const PipelineConfig& pc) {
  DemoRun run;
  const MachineKinematics& kin = pc.machine.kinematics;
  InterpolateOptions io = load_interpolate_options(pc.root.section("interpolate"));
  io.smoothing = Smoothing::kNone;
  io.max_velocity = kin.max_velocity;
  io.max_acceleration = kin.max_acceleration;
  for (std::size_t i = 0; i < kNumAxes; ++i) {
    io.travel_min[i] = kin.travel[i].min;
    io.travel_max[i] = kin.travel[i].max;
  }
  io.kinematics = &kin;
  Parser parser(load_parse_options(pc.root.section("parse")), pc.machine, "five_axis_demo.nc");
  std::optional<Interpolator> ip;
  LineOutput out;
  for (const std::string& line : lines) {
    parser.feed(line, out);
    if (out.blocks.size() != 1) continue;
    const ResolvedBlock& b = out.blocks[0];
    const double L = b.tool_length_active ? b.tool_length : kin.tool_length;
    if (!ip) {
      if (b.motion == Motion::kNone) continue;
      run.start = b.tcp ? inverse_kinematics_ac(kin, {b.start[kX], b.start[kY], b.start[kZ]}, b.start[kA], b.start[kC], L).joints
                        : b.start;
      ip.emplace(io, run.start);
    }
    run.block_start_joints.push_back(ip->position());
    run.block_start_tip.push_back(forward_kinematics(kin, ip->position(), L).tip);
    run.c.current = run.blocks.size();
    run.blocks.push_back(b);
    const auto r = ip->add(b, run.c);
    EXPECT_EQ(r.status, InterpolateStatus::kOk) << r.message;
  }
  ip->finish(run.c);
  run.stats = ip->stats();
  return run;
}

}  // namespace

// samples/five_axis_demo.nc as `gcpipe simulate` interpolates it: in the TCP section (G43.4 ...
// G49) the nominal tip path, FK of the raw joints, lies on the programmed lines and arcs.
TEST(TcpInterpolate, FiveAxisDemoNominalTipFollowsTheProgram) {
  const PipelineConfig pc = default_config();
  const MachineKinematics& kin = pc.machine.kinematics;
  const DemoRun run = run_demo(demo_lines(), pc);
  ASSERT_GT(run.stats.tcp_blocks, 10u);
  EXPECT_EQ(run.stats.ik_failed_samples, 0u);
  double worst = 0;
  std::size_t checked = 0;
  for (std::size_t n = 0; n < run.c.raw.size(); ++n) {
    const std::size_t k = run.c.block[n];
    if (k >= run.blocks.size()) continue;  // finish()
    const ResolvedBlock& b = run.blocks[k];
    if (!b.tcp || b.motion == Motion::kDwell || b.motion == Motion::kNone) continue;
    const Vec3 t = forward_kinematics(kin, run.c.raw[n], b.tool_length).tip;
    const Vec3 a = run.block_start_tip[k], e{b.target[kX], b.target[kY], b.target[kZ]};
    double off = 0;
    if (b.motion == Motion::kArcCW || b.motion == Motion::kArcCCW) {
      ASSERT_EQ(b.plane, Plane::kXY);
      off = std::max(std::abs(std::hypot(t[0] - b.centre[0], t[1] - b.centre[1]) - b.radius), std::abs(t[2] - e[2]));
    } else {
      off = segment_distance(a, e, t);
    }
    worst = std::max(worst, off);
    ++checked;
  }
  std::printf("five_axis_demo.nc: %zu TCP samples, nominal tip off the programmed path <= %.3g mm\n", checked, worst);
  EXPECT_GT(checked, 10000u);
  EXPECT_LT(worst, 1e-6);
  // The programmed tip path starts where the parser believes the tool is (tip 0 0 0).
  EXPECT_LT(dist(forward_kinematics(kin, run.start, 100).tip, {0, 0, 0}), 1e-9);
  EXPECT_LT(worst_step_ratio(run.c.raw, run.start, kin.max_velocity, 0.001), 1 + 1e-6);
}

// Switching (README "Switching"): the demo with a joint-mode move and a second TCP section
// inserted after the tilted sweep. G49 then `G1 Z150.`: only Z moves; X Y A C keep their joint
// values (the parser's X Y are tool-tip coordinates). `G43.4 H1` then `G1 X0.`: the tip starts
// where the joints put it, Y Z of the tip stay, A C stay. No tick jumps anywhere.
TEST(TcpInterpolate, FiveAxisDemoTcpOnOffSwitchingDoesNotJump) {
  const PipelineConfig pc = default_config();
  const MachineKinematics& kin = pc.machine.kinematics;
  std::vector<std::string> lines = demo_lines();
  std::size_t at = 0;
  for (std::size_t i = 0; i < lines.size(); ++i)
    if (lines[i].rfind("G1 X10. Y20. Z0. A-20. C60.", 0) == 0) at = i + 1;
  ASSERT_GT(at, 0u) << "five_axis_demo.nc changed: the tilted sweep's last block is gone";
  lines.insert(lines.begin() + static_cast<long>(at),
               {"G49", "G1 Z150. F1000.", "G43.4 H1", "G1 X0. F600."});
  const DemoRun run = run_demo(lines, pc);
  EXPECT_EQ(run.stats.ik_failed_samples, 0u);
  EXPECT_LT(worst_step_ratio(run.c.raw, run.start, kin.max_velocity, 0.001), 1 + 1e-6);

  std::size_t joint_block = 0, tcp_block_index = 0;
  for (std::size_t k = 0; k < run.blocks.size(); ++k) {
    if (run.blocks[k].text == "G1 Z150. F1000.") joint_block = k;
    if (run.blocks[k].text == "G1 X0. F600.") tcp_block_index = k;
  }
  ASSERT_GT(joint_block, 0u);
  ASSERT_GT(tcp_block_index, joint_block);
  ASSERT_FALSE(run.blocks[joint_block].tcp);
  ASSERT_TRUE(run.blocks[tcp_block_index].tcp);
  const Axes q0 = run.block_start_joints[joint_block];
  EXPECT_NEAR(q0[kA], -20, 1e-9);  // the switch happens tilted, where joints differ from tips
  std::size_t seen_joint = 0, seen_tcp = 0;
  const Vec3 tip0 = forward_kinematics(kin, run.block_start_joints[tcp_block_index], 100).tip;
  for (std::size_t n = 0; n < run.c.raw.size(); ++n) {
    const Axes& q = run.c.raw[n];
    if (run.c.block[n] == joint_block) {
      ++seen_joint;
      for (int a : {kX, kY, kA, kC}) EXPECT_EQ(q[static_cast<std::size_t>(a)], q0[static_cast<std::size_t>(a)]) << n;
    }
    if (run.c.block[n] == tcp_block_index) {
      ++seen_tcp;
      const Vec3 t = forward_kinematics(kin, q, 100).tip;
      EXPECT_NEAR(t[1], tip0[1], 1e-9);
      EXPECT_NEAR(t[2], tip0[2], 1e-9);
      EXPECT_NEAR(q[kA], -20, 1e-12);
      EXPECT_NEAR(q[kC], 60, 1e-12);
    }
  }
  EXPECT_GT(seen_joint, 100u);
  EXPECT_GT(seen_tcp, 100u);
  EXPECT_NEAR(run.block_start_joints[joint_block + 1][kZ], 150, 1e-12);
  EXPECT_NEAR(forward_kinematics(kin, run.block_start_joints[tcp_block_index + 1], 100).tip[0], 0, 1e-9);
}

#ifdef GCPIPE_EXE
// The command itself on the demo: exit 0, and every smoothed joint command moves by at most the
// axis velocity limit per tick (no jump at the G43.4 start or anywhere else).
TEST(TcpInterpolate, SimulateRunsTheFiveAxisDemo) {
  const fs::path out = fs::path(GCPIPE_BINARY_DIR) / "tcp_five_axis_demo_trace.csv";
  const std::string cmd = std::string("'") + GCPIPE_EXE + "' simulate '" + GCPIPE_SOURCE_DIR +
                          "/samples/five_axis_demo.nc' --config '" + GCPIPE_SOURCE_DIR +
                          "/pipeline_configs/default.yaml' -o '" + out.string() + "' 2>/dev/null";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  const PipelineConfig pc = default_config();
  std::ifstream in(out);
  std::string header;
  std::getline(in, header);
  ASSERT_EQ(header, "t,X_cmd,Y_cmd,Z_cmd,A_cmd,C_cmd,X,Y,Z,A,C");
  std::vector<Axes> cmd_rows;
  for (std::string row; std::getline(in, row);) {
    std::istringstream s(row);
    std::string f;
    std::getline(s, f, ',');
    Axes q;
    for (double& v : q) {
      std::getline(s, f, ',');
      v = std::stod(f);
    }
    cmd_rows.push_back(q);
  }
  ASSERT_GT(cmd_rows.size(), 10000u);
  EXPECT_LT(worst_step_ratio(cmd_rows, cmd_rows.front(), pc.machine.kinematics.max_velocity, 0.001), 1 + 1e-6);
}
#endif
