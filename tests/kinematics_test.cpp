// Kinematics of the table-table XYZAC machine (stages/common/kinematics.cpp), proved four ways:
// round trip over random poses, an independent composition of homogeneous transforms (Eigen),
// seed 000's printed equations (3)/(5), and LinuxCNC's xyzac-trt chain checked on its own demo
// program. The round-trip count comes from GCPIPE_IK_ROUNDTRIP_COUNT (default 1,000,000).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <regex>
#include <string>
#include <vector>

#include "gcpipe/config.hpp"
#include "gcpipe/kinematics.hpp"
#include "gcpipe/pipeline_config.hpp"

using namespace gcpipe;
namespace fs = std::filesystem;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

MachineKinematics load_machine_kinematics(const std::string& pipeline_file) {
  return load_pipeline_config(fs::path(GCPIPE_SOURCE_DIR) / "pipeline_configs" / pipeline_file)
      .machine.kinematics;
}

// A deliberately asymmetric model: C centre off the origin, both offsets, ISO directions.
MachineKinematics odd_model() {
  MachineKinematics m;
  m.c_centre = {12.5, -31.25, -7.0};
  m.a_offset_y = -17.0;
  m.a_offset_z = 43.0;
  m.convention = RotaryConvention::kIso841;
  m.travel = {{{-300, 300}, {-250, 250}, {-400, 200}, {-120, 30}, {-720, 720}}};
  return m;
}

double angle_between_deg(const Vec3& u, const Vec3& v) {
  const Eigen::Vector3d a(u[0], u[1], u[2]), b(v[0], v[1], v[2]);
  return std::atan2(a.cross(b).norm(), a.dot(b)) / kDeg;
}

double distance(const Vec3& a, const Vec3& b) {
  return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

std::size_t roundtrip_count() {
  if (const char* env = std::getenv("GCPIPE_IK_ROUNDTRIP_COUNT")) return std::stoull(env);
  return 1'000'000;
}

// Joints drawn uniformly inside the travel envelope; C limited to +-720 deg so that several
// turns are covered without the huge configured C ranges dominating.
Axes random_joints(const MachineKinematics& m, std::mt19937_64& rng) {
  Axes j{};
  for (int a = 0; a < kNumAxes; ++a) {
    double lo = m.travel[static_cast<std::size_t>(a)].min;
    double hi = m.travel[static_cast<std::size_t>(a)].max;
    if (a == kC) lo = std::max(lo, -720.0), hi = std::min(hi, 720.0);
    j[static_cast<std::size_t>(a)] = std::uniform_real_distribution<double>(lo, hi)(rng);
  }
  return j;
}

// Second formulation: compose the chain as 4x4 homogeneous transforms.
//   kTr = T(a) Rx(theta_A) T(-a)   (cradle in carrier; a = pivot)
//   rTw = T(c) Rz(theta_C) T(-c)   (workpiece in cradle; c = C centre)
//   kTt = T(X, Y, Z) T(0, 0, -L)   (tool tip in carrier; spindle never turns)
//   wTt = (kTr rTw)^-1 kTt
Eigen::Isometry3d eigen_kTw(const MachineKinematics& m, double a_deg, double c_deg) {
  const double s = m.convention == RotaryConvention::kTableRightHand ? 1.0 : -1.0;
  const Eigen::Vector3d c(m.c_centre[0], m.c_centre[1], m.c_centre[2]);
  const Eigen::Vector3d a = c + Eigen::Vector3d(0, m.a_offset_y, m.a_offset_z);
  const Eigen::Isometry3d kTr = Eigen::Translation3d(a) *
                                Eigen::AngleAxisd(s * a_deg * kDeg, Eigen::Vector3d::UnitX()) *
                                Eigen::Translation3d(-a);
  const Eigen::Isometry3d rTw = Eigen::Translation3d(c) *
                                Eigen::AngleAxisd(s * c_deg * kDeg, Eigen::Vector3d::UnitZ()) *
                                Eigen::Translation3d(-c);
  return kTr * rTw;
}

Eigen::Isometry3d eigen_wTt(const MachineKinematics& m, const Axes& j, double tool_length) {
  const Eigen::Isometry3d kTt(Eigen::Translation3d(j[kX], j[kY], j[kZ] - tool_length));
  return eigen_kTw(m, j[kA], j[kC]).inverse() * kTt;
}

}  // namespace

TEST(Kinematics, ShippedMachinesLoad) {
  const auto lc = load_machine_kinematics("linuxcnc_xyzac_trt.yaml");
  EXPECT_EQ(lc.a_offset_y, 20);
  EXPECT_EQ(lc.a_offset_z, 10);
  EXPECT_EQ(lc.travel[kA].min, -100);
  EXPECT_EQ(lc.travel[kA].max, 50);
  EXPECT_EQ(lc.max_velocity[kX], 20);
  EXPECT_EQ(lc.max_acceleration[kC], 300);
  const auto mx = load_machine_kinematics("default.yaml");
  EXPECT_EQ(mx.travel[kA].min, -125);
  EXPECT_EQ(mx.travel[kA].max, 10);
  EXPECT_DOUBLE_EQ(mx.travel[kX].max - mx.travel[kX].min, 435);
  EXPECT_DOUBLE_EQ(mx.travel[kY].max - mx.travel[kY].min, 465);
  EXPECT_DOUBLE_EQ(mx.travel[kZ].max - mx.travel[kZ].min, 560);
}

TEST(Kinematics, BadConfigsAreRejectedWithKeyAndReason) {
  const std::string good_limits =
      "limits:\n"
      "  X: {min: -1, max: 1, velocity: 1, acceleration: 1}\n"
      "  Y: {min: -1, max: 1, velocity: 1, acceleration: 1}\n"
      "  Z: {min: -1, max: 1, velocity: 1, acceleration: 1}\n"
      "  A: {min: -90, max: 90, velocity: 1, acceleration: 1}\n"
      "  C: {min: -360, max: 360, velocity: 1, acceleration: 1}\n";
  const std::string good_kin =
      "kinematics:\n  chain: xyzac_trt\n  c_centre: [0, 0, 0]\n  a_offset_y: 0\n"
      "  a_offset_z: 0\n";
  EXPECT_NO_THROW(load_kinematics(Config::from_string(good_kin + good_limits)));
  auto expect_error = [](const std::string& yaml, const std::string& needle) {
    try {
      load_kinematics(Config::from_string(yaml, "m.yaml"));
      ADD_FAILURE() << "accepted: " << yaml;
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_error(good_limits, "kinematics");
  expect_error(good_kin, "limits");
  expect_error(good_kin + "  a_ofset_z: 3\n" + good_limits, "a_ofset_z");
  expect_error("kinematics:\n  chain: xyzbc_trt\n  c_centre: [0, 0, 0]\n  a_offset_y: 0\n"
               "  a_offset_z: 0\n" + good_limits, "xyzbc_trt");
  expect_error(good_kin + "  rotary_convention: clockwise\n" + good_limits, "clockwise");
  std::string swapped = good_kin + good_limits;
  swapped.replace(swapped.find("A: {min: -90, max: 90"), 21, "A: {min: 90, max: -90");
  expect_error(swapped, "limits.A.max");
  std::string no_c = good_kin + good_limits;
  no_c.erase(no_c.find("  C: {"));
  expect_error(no_c, "limits.C");
  std::string zero_v = good_kin + good_limits;
  zero_v.replace(zero_v.find("velocity: 1"), 11, "velocity: 0");
  expect_error(zero_v, "limits.X.velocity");
  // The machine file as a whole rejects unknown top-level keys.
  EXPECT_THROW(load_machine(Config::from_string(good_kin + good_limits + "spindle_power: 7\n")),
               ConfigError);
}

// FK(IK(p)) = p within 1e-9 mm and 1e-9 deg, and IK(FK(q)) = q when q is the previous point.
TEST(Kinematics, RoundTripOverRandomPosesInsideTheEnvelope) {
  const std::size_t n = roundtrip_count();
  std::vector<MachineKinematics> models = {load_machine_kinematics("default.yaml"),
                                           load_machine_kinematics("linuxcnc_xyzac_trt.yaml"),
                                           odd_model()};
  std::mt19937_64 rng(20260521);
  std::uniform_real_distribution<double> tool_length(0, 150);
  for (const auto& m : models) {
    double worst_tip = 0, worst_axis = 0, worst_joint = 0;
    std::size_t failed = 0, held = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const Axes q = random_joints(m, rng);
      const double L = tool_length(rng);
      const ToolPose p = forward_kinematics(m, q, L);
      // A previous point anywhere in the envelope: the solver may pick either branch.
      const Axes far = random_joints(m, rng);
      const IkResult r = inverse_kinematics(m, p, far, L);
      if (r.status == IkStatus::kFailed) ++failed;
      if (r.flags & kIkCKeptAtSingularity) ++held;
      const ToolPose back = forward_kinematics(m, r.joints, L);
      worst_tip = std::max(worst_tip, distance(back.tip, p.tip));
      worst_axis = std::max(worst_axis, angle_between_deg(back.axis, p.axis));
      // Continuity: with q itself as the previous point the same joints come back (every 4th
      // pose, to keep the default million within a few seconds).
      if (i % 4 != 0) continue;
      const IkResult same = inverse_kinematics(m, p, q, L);
      for (int a = 0; a < kNumAxes; ++a)
        worst_joint = std::max(worst_joint, std::abs(same.joints[static_cast<std::size_t>(a)] -
                                                     q[static_cast<std::size_t>(a)]));
    }
    EXPECT_EQ(failed, 0u);
    EXPECT_EQ(held, 0u) << "a random pose landed within c_hold_tilt of the pole";
    EXPECT_LE(worst_tip, 1e-9) << "mm";
    EXPECT_LE(worst_axis, 1e-9) << "deg";
    EXPECT_LE(worst_joint, 1e-9) << "mm/deg";
    std::printf("%zu poses: worst tip %.3g mm, axis %.3g deg, joints %.3g\n", n, worst_tip,
                worst_axis, worst_joint);
  }
}

TEST(Kinematics, AgreesWithComposedHomogeneousTransforms) {
  std::mt19937_64 rng(7);
  for (const auto& m : {load_machine_kinematics("default.yaml"),
                        load_machine_kinematics("linuxcnc_xyzac_trt.yaml"), odd_model()}) {
    for (int i = 0; i < 20000; ++i) {
      const Axes q = random_joints(m, rng);
      const double L = std::uniform_real_distribution<double>(0, 150)(rng);
      const Eigen::Isometry3d wTt = eigen_wTt(m, q, L);
      const ToolPose p = forward_kinematics(m, q, L);
      const Eigen::Vector3d z = wTt.linear().col(2);
      EXPECT_LE(distance(p.tip, {wTt.translation().x(), wTt.translation().y(),
                                 wTt.translation().z()}), 1e-9);
      EXPECT_LE(angle_between_deg(p.axis, {z.x(), z.y(), z.z()}), 1e-9);
      // Inverse through the same matrices: the tip in the carrier is kTw * w, and Z carries L.
      const IkResult r = inverse_kinematics_ac(m, p.tip, q[kA], q[kC], L);
      EXPECT_NE(r.status, IkStatus::kFailed);
      const Eigen::Vector3d tip_k = eigen_kTw(m, q[kA], q[kC]) *
                                    Eigen::Vector3d(p.tip[0], p.tip[1], p.tip[2]);
      EXPECT_NEAR(tip_k.x(), r.joints[kX], 1e-9);
      EXPECT_NEAR(tip_k.y(), r.joints[kY], 1e-9);
      EXPECT_NEAR(tip_k.z() + L, r.joints[kZ], 1e-9);
      for (int a = 0; a < 3; ++a)
        EXPECT_NEAR(r.joints[static_cast<std::size_t>(a)], q[static_cast<std::size_t>(a)], 1e-9);
    }
  }
}

// Seed 000 counts X and Y as table displacements (eq. 5: X = -Px cos C + Py sin C), we count the
// tool relative to the workpiece (ISO 841); Z and the angles agree. With X, Y negated the
// paper's inverse (5) and the position column of its matrix (3) are our IK and FK for
// c = 0, dy = 0, dz = -d.
TEST(Kinematics, MatchesSeed000Equations3And5UpToTheTableSignOfXY) {
  const double d = 50;
  MachineKinematics m;
  m.a_offset_z = -d;
  m.travel = {{{-1e4, 1e4}, {-1e4, 1e4}, {-1e4, 1e4}, {-180, 180}, {-1e4, 1e4}}};
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> lin(-200, 200), ang(-180, 180);
  int eq4_px_mismatch = 0;
  for (int i = 0; i < 10000; ++i) {
    const double Px = lin(rng), Py = lin(rng), Pz = lin(rng), Adeg = ang(rng), Cdeg = ang(rng);
    const double A = Adeg * kDeg, C = Cdeg * kDeg;
    // eq. (5)
    const double Xp = -Px * std::cos(C) + Py * std::sin(C);
    const double Yp = -Px * std::cos(A) * std::sin(C) - Py * std::cos(A) * std::cos(C) +
                      (Pz + d) * std::sin(A);
    const double Zp = Px * std::sin(A) * std::sin(C) + Py * std::sin(A) * std::cos(C) +
                      (Pz + d) * std::cos(A) - d;
    const IkResult r = inverse_kinematics_ac(m, {Px, Py, Pz}, Adeg, Cdeg, 0);
    EXPECT_NEAR(r.joints[kX], -Xp, 1e-9);
    EXPECT_NEAR(r.joints[kY], -Yp, 1e-9);
    EXPECT_NEAR(r.joints[kZ], Zp, 1e-9);
    // eq. (3), last column, and eq. (4)'s orientation.
    const double X = Xp, Y = Yp, Z = Zp;
    const double px3 = -X * std::cos(C) - Y * std::cos(A) * std::sin(C) +
                       (Z + d) * std::sin(A) * std::sin(C);
    const double py3 = X * std::sin(C) - Y * std::cos(A) * std::cos(C) +
                       (Z + d) * std::sin(A) * std::cos(C);
    const double pz3 = Y * std::sin(A) + (Z + d) * std::cos(A) - d;
    const ToolPose p = forward_kinematics(m, {-X, -Y, Z, Adeg, Cdeg}, 0);
    EXPECT_NEAR(p.tip[0], px3, 1e-9);
    EXPECT_NEAR(p.tip[1], py3, 1e-9);
    EXPECT_NEAR(p.tip[2], pz3, 1e-9);
    EXPECT_NEAR(p.axis[0], std::sin(A) * std::sin(C), 1e-12);
    EXPECT_NEAR(p.axis[1], std::sin(A) * std::cos(C), 1e-12);
    EXPECT_NEAR(p.axis[2], std::cos(A), 1e-12);
    // eq. (4)'s P_x (-X sin C ... + (Z+d) sin A cos C) is a misprint: it disagrees with (3).
    const double px4 = -X * std::sin(C) - Y * std::cos(A) * std::sin(C) +
                       (Z + d) * std::sin(A) * std::cos(C);
    if (std::abs(px4 - px3) > 1e-6) ++eq4_px_mismatch;
  }
  EXPECT_GT(eq4_px_mismatch, 9900);
}

// LinuxCNC's xyzac-trt: with conventional-directions 0 the table turns so that the tool axis in
// the workpiece is (sin A sin C, sin A cos C, cos A). Its own impeller demo (tool-centre-point
// mode, A -74.5..-40 deg, a 7-blade impeller around the C axis) proves the sense: with it the
// tool never reaches into the hub; with the opposite sense it would in hundreds of points.
TEST(Kinematics, LinuxcncImpellerToolStaysOutOfTheHub) {
  const fs::path file =
      fs::path(GCPIPE_SHARED_DATA) / "gcode/linuxcnc/xyzac_trt/impeller-7bl-xyzac.ngc";
  if (!fs::exists(file)) GTEST_SKIP() << "third-party data absent: " << file;
  std::ifstream in(file);
  const std::regex word(R"(([XYZAC])\s*(-?[0-9.]+))");
  std::vector<Axes> points;
  for (std::string line; std::getline(in, line);) {
    if (const auto semi = line.find(';'); semi != std::string::npos) line.resize(semi);
    Axes v{};
    int seen = 0;
    for (std::sregex_iterator it(line.begin(), line.end(), word), end; it != end; ++it) {
      const char letter = (*it)[1].str()[0];
      const int axis = letter == 'X' ? 0 : letter == 'Y' ? 1 : letter == 'Z' ? 2 : letter == 'A' ? 3 : 4;
      v[static_cast<std::size_t>(axis)] = std::stod((*it)[2].str());
      seen |= 1 << axis;
    }
    if (seen == 31) points.push_back(v);
  }
  ASSERT_GT(points.size(), 4000u);
  auto count_into_hub = [&](const MachineKinematics& m) {
    int n = 0;
    for (const Axes& p : points) {
      const Vec3 u = tool_axis(m, p[kA], p[kC]);
      double closest = 1e9;
      for (double t = 5; t <= 40; t += 1)
        closest = std::min(closest, std::hypot(p[kX] + t * u[0], p[kY] + t * u[1]));
      if (closest < 8) ++n;
    }
    return n;
  };
  MachineKinematics lc = load_machine_kinematics("linuxcnc_xyzac_trt.yaml");
  EXPECT_EQ(lc.convention, RotaryConvention::kTableRightHand);
  EXPECT_EQ(count_into_hub(lc), 0);
  lc.convention = RotaryConvention::kIso841;
  EXPECT_GT(count_into_hub(lc), 100);
}

// LinuxCNC's xyzac-trt.txt: y/z-offset are the A pivot relative to the C centre, x/y/z-rot-point
// the C centre relative to machine zero; at A = C = 0 the work coordinates equal the joints
// (switching M429 -> M428 at zero rotation moves nothing), whatever the offsets.
TEST(Kinematics, LinuxcncOffsetSemantics) {
  MachineKinematics m = load_machine_kinematics("linuxcnc_xyzac_trt.yaml");
  m.c_centre = {3, -4, 5};
  const ToolPose home = forward_kinematics(m, {11, 22, 33, 0, 0}, 0);
  EXPECT_NEAR(distance(home.tip, {11, 22, 33}), 0, 1e-12);
  // A point on the A axis (pivot = C centre + (0, dy, dz)) stays put whatever A is, at C = 0.
  const Vec3 pivot = {7, -4 + 20, 5 + 10};
  for (double a : {-100.0, -45.0, 30.0, 50.0})
    EXPECT_NEAR(distance(forward_kinematics(m, {7, pivot[1], pivot[2], a, 0}, 0).tip, pivot), 0,
                1e-12);
  // A point on the C axis stays put whatever C is, at A = 0.
  for (double c : {-399.8, 90.0, 1234.5})
    EXPECT_NEAR(distance(forward_kinematics(m, {3, -4, 17, 0, c}, 0).tip, {3, -4, 17}), 0, 1e-12);
  // Tool length: a longer tool needs the spindle higher by the same amount, along the tool.
  const Axes q{10, 20, 30, -40, 25};
  const ToolPose p0 = forward_kinematics(m, q, 0);
  const ToolPose p7 = forward_kinematics(m, {10, 20, 37, -40, 25}, 7);
  EXPECT_NEAR(distance(p0.tip, p7.tip), 0, 1e-12);
}

// ---- hard cases ------------------------------------------------------------------------------

TEST(KinematicsHardCases, BranchChosenByTravelThenContinuity) {
  const MachineKinematics mx = load_machine_kinematics("default.yaml");  // A -125..+10
  const ToolPose p = forward_kinematics(mx, {10, 20, 30, -30, 40}, 0);
  // The previous point prefers A = +30 (same tool axis, C + 180), but A = +30 is beyond +10.
  const IkResult r = inverse_kinematics(mx, p, {0, 0, 0, 30, 210}, 0);
  EXPECT_EQ(r.status, IkStatus::kDegraded);
  EXPECT_TRUE(r.flags & kIkBranchByLimit) << ik_flags_to_string(r.flags);
  EXPECT_NEAR(r.joints[kA], -30, 1e-9);
  EXPECT_NEAR(r.joints[kC], 40, 1e-9);

  const MachineKinematics lc = load_machine_kinematics("linuxcnc_xyzac_trt.yaml");  // -100..50
  const ToolPose t = forward_kinematics(lc, {1, 2, 3, 20, 10}, 0);
  const IkResult plus = inverse_kinematics(lc, t, {0, 0, 0, 19, 9}, 0);
  EXPECT_EQ(plus.status, IkStatus::kOk);
  EXPECT_NEAR(plus.joints[kA], 20, 1e-9);
  EXPECT_NEAR(plus.joints[kC], 10, 1e-9);
  const IkResult minus = inverse_kinematics(lc, t, {0, 0, 0, -19, 185}, 0);
  EXPECT_EQ(minus.status, IkStatus::kOk);
  EXPECT_NEAR(minus.joints[kA], -20, 1e-9);
  EXPECT_NEAR(minus.joints[kC], 190, 1e-9);
  for (const IkResult& r2 : {plus, minus})
    EXPECT_NEAR(distance(forward_kinematics(lc, r2.joints, 0).tip, t.tip), 0, 1e-9);
  // Crossing from one sign of A to the other is reported.
  const IkResult crossed = inverse_kinematics(lc, t, {0, 0, 0, -1, 10}, 0);
  EXPECT_NEAR(crossed.joints[kA], 20, 1e-9);
  EXPECT_TRUE(crossed.flags & kIkBranchSwitch);
}

TEST(KinematicsHardCases, AtThePoleThePreviousCIsKept) {
  const MachineKinematics lc = load_machine_kinematics("linuxcnc_xyzac_trt.yaml");
  const ToolPose pole{{5, -6, 7}, {0, 0, 1}};
  const IkResult r = inverse_kinematics(lc, pole, {0, 0, 0, -0.5, 123.4}, 0);
  EXPECT_EQ(r.status, IkStatus::kDegraded);
  EXPECT_TRUE(r.flags & kIkCKeptAtSingularity);
  EXPECT_TRUE(r.flags & kIkNearSingular);
  EXPECT_EQ(r.joints[kC], 123.4);
  EXPECT_EQ(r.joints[kA], 0);
  EXPECT_NEAR(distance(forward_kinematics(lc, r.joints, 0).tip, pole.tip), 0, 1e-9);
  // Slightly off the pole: C is defined again but flagged as ill-conditioned.
  const IkResult near = inverse_kinematics(lc, {{5, -6, 7}, tool_axis(lc, -0.5, 70)},
                                           {0, 0, 0, -0.5, 69}, 0);
  EXPECT_EQ(near.status, IkStatus::kDegraded);
  EXPECT_EQ(near.flags, kIkNearSingular);
  EXPECT_NEAR(near.joints[kC], 70, 1e-9);
}

TEST(KinematicsHardCases, CUnwrapsOverSeveralTurns) {
  const MachineKinematics lc = load_machine_kinematics("linuxcnc_xyzac_trt.yaml");
  // The tool axis circles the C axis three times, downwards in C like the impeller (-399.8).
  Axes prev{0, 0, 0, -60, 0};
  double max_step = 0;
  for (int i = 1; i <= 1080; ++i) {
    const double c = -static_cast<double>(i);
    const ToolPose p{{10, 5, 20}, tool_axis(lc, -60, c)};
    const IkResult r = inverse_kinematics(lc, p, prev, 0);
    ASSERT_EQ(r.status, IkStatus::kOk) << i;
    max_step = std::max(max_step, std::abs(r.joints[kC] - prev[kC]));
    prev = r.joints;
  }
  EXPECT_NEAR(prev[kC], -1080, 1e-9);
  EXPECT_NEAR(max_step, 1, 1e-9);
  // C travel wins over nearness: with C limited to [-10, 370] a previous C of 365 and a target
  // of 20 (mod 360) give 20, not 380 (A limited to negative values so only one branch exists).
  MachineKinematics limited = lc;
  limited.travel[kC] = {-10, 370};
  limited.travel[kA] = {-100, -1};  // only the negative branch exists
  const IkResult r = inverse_kinematics(limited, {{0, 0, 0}, tool_axis(limited, -30, 20)},
                                        {0, 0, 0, -30, 365}, 0);
  EXPECT_NE(r.status, IkStatus::kFailed);
  EXPECT_NEAR(r.joints[kC], 20, 1e-9);
}

TEST(KinematicsHardCases, UnreachableAndOutOfTravelAreReported) {
  const MachineKinematics lc = load_machine_kinematics("linuxcnc_xyzac_trt.yaml");
  const Axes prev{1, 2, 3, -10, 0};
  const IkResult zero = inverse_kinematics(lc, {{0, 0, 0}, {0, 0, 0}}, prev, 0);
  EXPECT_EQ(zero.status, IkStatus::kFailed);
  EXPECT_EQ(zero.flags, kIkUnreachable);
  EXPECT_EQ(zero.joints, prev);
  const IkResult nan = inverse_kinematics(lc, {{std::nan(""), 0, 0}, {0, 0, 1}}, prev, 0);
  EXPECT_EQ(nan.flags, kIkUnreachable);
  EXPECT_EQ(inverse_kinematics_ac(lc, {0, 0, 0}, std::nan(""), 0).flags, kIkUnreachable);
  // X travel is +-200 mm.
  const IkResult far = inverse_kinematics(lc, {{250, 0, 0}, {0, 0, 1}}, prev, 0);
  EXPECT_EQ(far.status, IkStatus::kFailed);
  EXPECT_TRUE(far.flags & kIkTravelLimit);
  EXPECT_NEAR(far.joints[kX], 250, 1e-9);
  EXPECT_EQ(joints_outside_travel(lc, far.joints), 1u << kX);
  // A tool axis that needs |A| = 120: beyond -100 and +50 on both branches.
  const IkResult tilt = inverse_kinematics(lc, {{0, 0, 0}, tool_axis(lc, 120, 0)}, prev, 0);
  EXPECT_EQ(tilt.status, IkStatus::kFailed);
  EXPECT_TRUE(tilt.flags & kIkTravelLimit);
  const IkResult tcp = inverse_kinematics_ac(lc, {0, 0, 0}, -101, 0, 0);
  EXPECT_EQ(tcp.status, IkStatus::kFailed);
  EXPECT_EQ(tcp.flags, kIkTravelLimit);
  EXPECT_EQ(ik_flags_to_string(kIkTravelLimit | kIkBranchSwitch), "branch_switch|travel_limit");
}

TEST(KinematicsHardCases, LeavingThePoleTakesTheWiderSideOfA) {
  MachineKinematics lc = load_machine_kinematics("linuxcnc_xyzac_trt.yaml");  // A -100..50
  const ToolPose p{{1, 2, 3}, tool_axis(lc, 46, -36)};
  const IkResult r = inverse_kinematics(lc, p, {0, 0, 0, 0, -30}, 0);
  EXPECT_EQ(r.status, IkStatus::kOk);
  EXPECT_NEAR(r.joints[kA], -46, 1e-9);
  EXPECT_NEAR(r.joints[kC], 144, 1e-9);
  // Away from the pole continuity rules: previous A = +40 keeps the positive side.
  const IkResult k = inverse_kinematics(lc, p, {0, 0, 0, 40, -36}, 0);
  EXPECT_NEAR(k.joints[kA], 46, 1e-9);
  EXPECT_NEAR(k.joints[kC], -36, 1e-9);
  lc.travel[kA] = {-10, 120};
  EXPECT_NEAR(inverse_kinematics(lc, p, {0, 0, 0, 0, -30}, 0).joints[kA], 46, 1e-9);
}
