// LinuxCNC's published xyzac-trt kinematics (forward and inverse, with rotary axis offsets and
// the tool offset), written out here independently from the equations in stages/ik/README.md §5
// and compared with gcpipe's forward_kinematics / inverse_kinematics_ac on the linuxcnc config.
//
// The equations are LinuxCNC's (docs/src/motion/5-axis-kinematics.adoc, "Transformations for a
// xyzac-trt machine with rotary axis offsets", eqs. 18-27, and their implementation in
// src/emc/kinematics/trtfuncs_math.h); the code below is ours, written from the mathematics.
// Their names: joints J (machine X Y Z A C), world point Q (what the G-code commands, with the
// tool-length offset Dt already added along world Z by LinuxCNC's motion controller),
// x/y/z-rot-point R (the C axis centre), y-offset Dy and z-offset Dz (the A axis relative to the
// C centre), tool-offset Dt, and conventional-directions (0: the table turns right-handed with
// positive A and C, which LinuxCNC calls unconventional; 1: ISO sense).
// GCPIPE_LINUXCNC_EQ_COUNT sets the number of random joint vectors per case (default 100000).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <random>

#include "gcpipe/kinematics.hpp"
#include "gcpipe/pipeline_config.hpp"

using namespace gcpipe;
namespace fs = std::filesystem;

namespace {

struct TrtParameters {
  Vec3 rot_point{};         //!< x/y/z-rot-point [mm]
  double y_offset = 0;      //!< Dy [mm]
  double z_offset = 0;      //!< Dz [mm]
  double tool_offset = 0;   //!< Dt [mm]
  bool conventional = false;//!< conventional-directions
};

struct World {
  Vec3 q{};     //!< Q [mm]
  double a = 0; //!< [deg], passed through
  double c = 0;
};

double rad(double deg) { return deg * std::numbers::pi / 180.0; }

// Forward: joints -> world. With e = +1 for conventional directions and -1 otherwise, and the
// joint vector taken relative to the A pivot, P = (Jx - Rx, Jy - Ry - Dy, Jz - Rz - Dz - Dt):
//   Qx = cosC Px - e sinC cosA Py + sinC sinA Pz - e sinC Dy + Rx
//   Qy = e sinC Px + cosC cosA Py - e cosC sinA Pz + cosC Dy + Ry
//   Qz = e sinA Py + cosA Pz + Dz + Dt + Rz
World linuxcnc_forward(const TrtParameters& k, const Axes& j) {
  const double e = k.conventional ? 1.0 : -1.0;
  const double sa = std::sin(rad(j[kA])), ca = std::cos(rad(j[kA]));
  const double sc = std::sin(rad(j[kC])), cc = std::cos(rad(j[kC]));
  const double dz = k.z_offset + k.tool_offset;
  const double px = j[kX] - k.rot_point[0];
  const double py = j[kY] - k.rot_point[1] - k.y_offset;
  const double pz = j[kZ] - k.rot_point[2] - dz;
  World w;
  w.q[0] = cc * px - e * sc * ca * py + sc * sa * pz - e * sc * k.y_offset + k.rot_point[0];
  w.q[1] = e * sc * px + cc * ca * py - e * cc * sa * pz + cc * k.y_offset + k.rot_point[1];
  w.q[2] = e * sa * py + ca * pz + dz + k.rot_point[2];
  w.a = j[kA];
  w.c = j[kC];
  return w;
}

// Inverse: world (Q, A, C) -> joints, the transpose of the rotation applied to Q - R plus the
// offsets carried back through the A rotation (D = (Dy, Dz + Dt) in the Y-Z plane):
//   Jx = cosC Ux + e sinC Uy + Rx
//   Jy = -e sinC cosA Ux + cosC cosA Uy + e sinA Uz - cosA Dy - e sinA (Dz + Dt) + Dy + Ry
//   Jz = sinC sinA Ux - e cosC sinA Uy + cosA Uz + e sinA Dy - cosA (Dz + Dt) + Dz + Dt + Rz
// with U = Q - R.
Axes linuxcnc_inverse(const TrtParameters& k, const World& w) {
  const double e = k.conventional ? 1.0 : -1.0;
  const double sa = std::sin(rad(w.a)), ca = std::cos(rad(w.a));
  const double sc = std::sin(rad(w.c)), cc = std::cos(rad(w.c));
  const double dy = k.y_offset, dz = k.z_offset + k.tool_offset;
  const double ux = w.q[0] - k.rot_point[0];
  const double uy = w.q[1] - k.rot_point[1];
  const double uz = w.q[2] - k.rot_point[2];
  Axes j;
  j[kX] = cc * ux + e * sc * uy + k.rot_point[0];
  j[kY] = -e * sc * ca * ux + cc * ca * uy + e * sa * uz - ca * dy - e * sa * dz + dy + k.rot_point[1];
  j[kZ] = sc * sa * ux - e * cc * sa * uy + ca * uz + e * sa * dy - ca * dz + dz + k.rot_point[2];
  j[kA] = w.a;
  j[kC] = w.c;
  return j;
}

double uniform(std::mt19937_64& rng, double lo, double hi) {
  return lo + (hi - lo) * static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

double distance(const Vec3& a, const Vec3& b) {
  return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

struct Worst {
  double forward = 0, inverse = 0, axis = 0, self = 0;
};

// Random joints within travel and a random tool offset; compares both directions and the tool
// axis (the third column of the forward map, which is affine in J).
Worst compare(const MachineKinematics& m, TrtParameters k, int count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  Worst w;
  for (int i = 0; i < count; ++i) {
    Axes j;
    for (int a = 0; a < kNumAxes; ++a)
      j[static_cast<std::size_t>(a)] = uniform(rng, m.travel[static_cast<std::size_t>(a)].min,
                                               m.travel[static_cast<std::size_t>(a)].max);
    k.tool_offset = uniform(rng, 0, 150);
    const World lw = linuxcnc_forward(k, j);
    // LinuxCNC's world point is the tip with Dt added along world Z.
    const Vec3 tip_lc = {lw.q[0], lw.q[1], lw.q[2] - k.tool_offset};
    const ToolPose ours = forward_kinematics(m, j, k.tool_offset);
    w.forward = std::max(w.forward, distance(ours.tip, tip_lc));
    Axes jz = j;
    jz[kZ] += 1;
    const World lw1 = linuxcnc_forward(k, jz);
    const Vec3 axis_lc = {lw1.q[0] - lw.q[0], lw1.q[1] - lw.q[1], lw1.q[2] - lw.q[2]};
    w.axis = std::max(w.axis, distance(ours.axis, axis_lc));
    // Inverse from a world point of its own (not the one just computed): a fresh random Q.
    World target;
    target.q = {uniform(rng, -200, 200), uniform(rng, -200, 200), uniform(rng, -150, 150)};
    target.a = j[kA];
    target.c = j[kC];
    const Axes jl = linuxcnc_inverse(k, target);
    const IkResult r = inverse_kinematics_ac(
        m, {target.q[0], target.q[1], target.q[2] - k.tool_offset}, target.a, target.c, k.tool_offset);
    for (int a = 0; a < kNumAxes; ++a)
      w.inverse = std::max(w.inverse, std::fabs(r.joints[static_cast<std::size_t>(a)] - jl[static_cast<std::size_t>(a)]));
    // The two LinuxCNC equations invert each other (a check of the transcription itself).
    const Axes back = linuxcnc_inverse(k, lw);
    for (int a = 0; a < kNumAxes; ++a)
      w.self = std::max(w.self, std::fabs(back[static_cast<std::size_t>(a)] - j[static_cast<std::size_t>(a)]));
  }
  return w;
}

int count_from_env() {
  const char* env = std::getenv("GCPIPE_LINUXCNC_EQ_COUNT");
  return env ? std::atoi(env) : 100000;
}

}  // namespace

// The linuxcnc_xyzac_trt config as shipped (rot point 0, y-offset 20, z-offset 10,
// conventional-directions 0), tool offset 0..150 mm, joints anywhere in travel (C to +-36000).
TEST(LinuxcncTrtEquations, ShippedConfigAgreesWithForwardAndInverse) {
  const PipelineConfig pc = load_pipeline_config(fs::path(GCPIPE_SOURCE_DIR) / "pipeline_configs" /
                                                 "linuxcnc_xyzac_trt.yaml");
  const MachineKinematics& m = pc.machine.kinematics;
  TrtParameters k;
  k.rot_point = m.c_centre;
  k.y_offset = m.a_offset_y;
  k.z_offset = m.a_offset_z;
  k.conventional = m.convention == RotaryConvention::kIso841;
  ASSERT_FALSE(k.conventional);  // the .ini leaves conventional-directions at 0
  ASSERT_EQ(k.y_offset, 20);
  ASSERT_EQ(k.z_offset, 10);
  const int count = count_from_env();
  const Worst w = compare(m, k, count, 1);
  std::printf("linuxcnc config, %d joint vectors: worst forward %.3g mm, inverse %.3g mm, axis %.3g, "
              "LinuxCNC self-inverse %.3g mm\n", count, w.forward, w.inverse, w.axis, w.self);
  EXPECT_LE(w.forward, 1e-9);
  EXPECT_LE(w.inverse, 1e-9);
  EXPECT_LE(w.axis, 1e-12);
  EXPECT_LE(w.self, 1e-9);
}

// Every parameter non-zero, and both direction conventions: conventional-directions 1 is our
// iso841, 0 our table_right_hand. Swapping them must break the agreement (the test can fail).
TEST(LinuxcncTrtEquations, OffsetRotPointAndBothDirectionConventions) {
  const PipelineConfig pc = load_pipeline_config(fs::path(GCPIPE_SOURCE_DIR) / "pipeline_configs" /
                                                 "linuxcnc_xyzac_trt.yaml");
  MachineKinematics m = pc.machine.kinematics;
  m.c_centre = {12.5, -31.25, 7.75};
  m.a_offset_y = -17.5;
  m.a_offset_z = 42.25;
  TrtParameters k;
  k.rot_point = m.c_centre;
  k.y_offset = m.a_offset_y;
  k.z_offset = m.a_offset_z;
  const int count = count_from_env();
  for (bool conventional : {false, true}) {
    SCOPED_TRACE(conventional ? "conventional-directions 1" : "conventional-directions 0");
    k.conventional = conventional;
    m.convention = conventional ? RotaryConvention::kIso841 : RotaryConvention::kTableRightHand;
    const Worst w = compare(m, k, count, conventional ? 3 : 2);
    std::printf("offsets and rot point, conventional-directions %d: worst forward %.3g mm, inverse %.3g mm, "
                "axis %.3g\n", conventional ? 1 : 0, w.forward, w.inverse, w.axis);
    EXPECT_LE(w.forward, 1e-9);
    EXPECT_LE(w.inverse, 1e-9);
    EXPECT_LE(w.axis, 1e-12);
    m.convention = conventional ? RotaryConvention::kTableRightHand : RotaryConvention::kIso841;
    const Worst wrong = compare(m, k, 1000, 4);
    EXPECT_GT(wrong.forward, 1.0) << "the direction convention made no difference";
  }
}
