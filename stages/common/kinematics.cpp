#include "gcpipe/kinematics.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>

#include "gcpipe/config.hpp"

namespace gcpipe {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;
constexpr double kRadToDeg = 180.0 / std::numbers::pi;

// Joint angle -> table rotation angle: theta = s * joint, s = +1 for the table right-hand
// convention, -1 for ISO 841 (the table turns against the tool's positive sense).
double rotation_sign(const MachineKinematics& m) {
  return m.convention == RotaryConvention::kTableRightHand ? 1.0 : -1.0;
}

bool finite3(const Vec3& v) {
  return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]);
}

// Linear joints for a tip w [mm] with the table rotations given as cos/sin of theta_A, theta_C.
// Inverse of the chain in forward_kinematics (README, "Inverse, position part"):
//   q = Rz(theta_C) (w - c),  r = q - (0, dy, dz),  p = Rx(theta_A) r,
//   X = p_x + c_x,  Y = p_y + c_y + dy,  Z = p_z + c_z + dz + L.
void solve_linear(const MachineKinematics& m, const Vec3& w, double ca, double sa, double cc,
                  double sc, double tool_length, Axes& j) {
  const double dx = w[0] - m.c_centre[0];
  const double dy = w[1] - m.c_centre[1];
  const double dz = w[2] - m.c_centre[2];
  const double qx = cc * dx - sc * dy;
  const double qy = sc * dx + cc * dy;
  const double ry = qy - m.a_offset_y;
  const double rz = dz - m.a_offset_z;
  j[kX] = qx + m.c_centre[0];
  j[kY] = ca * ry - sa * rz + m.c_centre[1] + m.a_offset_y;
  j[kZ] = sa * ry + ca * rz + m.c_centre[2] + m.a_offset_z + tool_length;
}

// Shifts c [deg] by whole turns to the value nearest `reference` that lies within `range`.
// Returns false (and the nearest turn regardless of travel) when no turn of c is within travel.
bool unwrap_c(double c, double reference, const AxisRange& range, double& out) {
  const double k_near = std::round((reference - c) / 360.0);
  const double k_min = std::ceil((range.min - c) / 360.0);
  const double k_max = std::floor((range.max - c) / 360.0);
  if (k_min > k_max) {
    out = c + 360.0 * k_near;
    return false;
  }
  out = c + 360.0 * std::clamp(k_near, k_min, k_max);
  return true;
}

struct Candidate {
  Axes joints{};
  bool in_travel = false;
  double cost = 0;  // squared rotary distance to the previous point [deg^2]
};

// Builds one IK candidate for table rotation theta_A [rad] and joint C (already unwrapped).
Candidate make_candidate(const MachineKinematics& m, const Vec3& tip, double theta_a,
                         double c_joint, bool c_in_travel, const Axes& previous,
                         double tool_length) {
  const double s = rotation_sign(m);
  Candidate k;
  const double theta_c = s * c_joint * kDegToRad;
  solve_linear(m, tip, std::cos(theta_a), std::sin(theta_a), std::cos(theta_c),
               std::sin(theta_c), tool_length, k.joints);
  k.joints[kA] = s * theta_a * kRadToDeg;
  k.joints[kC] = c_joint;
  k.in_travel = c_in_travel && joints_outside_travel(m, k.joints) == 0;
  const double da = k.joints[kA] - previous[kA];
  const double dc = k.joints[kC] - previous[kC];
  k.cost = da * da + dc * dc;
  return k;
}

IkResult failed_unreachable(const Axes& previous) {
  return IkResult{previous, IkStatus::kFailed, kIkUnreachable};
}

}  // namespace

Vec3 tool_axis(const MachineKinematics& m, double a_deg, double c_deg) {
  const double s = rotation_sign(m);
  const double ta = s * a_deg * kDegToRad;
  const double tc = s * c_deg * kDegToRad;
  const double sa = std::sin(ta);
  return {sa * std::sin(tc), sa * std::cos(tc), std::cos(ta)};
}

ToolPose forward_kinematics(const MachineKinematics& m, const Axes& j) {
  return forward_kinematics(m, j, m.tool_length);
}

// Chain (README, "Forward kinematics"): the tip in the carrier is (X, Y, Z - L). Relative to
// the A pivot a = c + (0, dy, dz) that is p; the cradle turned the table by Rx(theta_A) about a,
// so in the cradle the tip is a + Rx(-theta_A) p; the C table turned by Rz(theta_C) about c, so
// in the workpiece w = c + Rz(-theta_C) ((0, dy, dz) + Rx(-theta_A) p).
namespace {

// sin and cos of one rotary axis's angle, kept from the previous call on this thread: the rotary
// axes stand still for long stretches (a three-axis program never turns them), and glibc's sin
// and cos cost more than the rest of the kinematics (they switch the rounding mode on each call);
// the simulation calls this twice per tick. The same angle, bit for bit, gives the same values.
struct SinCos {
  double angle = 0, s = 0, c = 1;  // sin 0 and cos 0
  const SinCos& of(double a) {
    if (std::bit_cast<std::uint64_t>(a) != std::bit_cast<std::uint64_t>(angle)) *this = {a, std::sin(a), std::cos(a)};
    return *this;
  }
};

}  // namespace

ToolPose forward_kinematics(const MachineKinematics& m, const Axes& j, double tool_length) {
  const double s = rotation_sign(m);
  const double ta = s * j[kA] * kDegToRad;
  const double tc = s * j[kC] * kDegToRad;
  thread_local SinCos a_memo, c_memo;
  const SinCos& a = a_memo.of(ta);
  const SinCos& c = c_memo.of(tc);
  const double ca = a.c, sa = a.s;
  const double cc = c.c, sc = c.s;
  const double px = j[kX] - m.c_centre[0];
  const double py = j[kY] - m.c_centre[1] - m.a_offset_y;
  const double pz = j[kZ] - tool_length - m.c_centre[2] - m.a_offset_z;
  const double qx = px;
  const double qy = ca * py + sa * pz + m.a_offset_y;
  const double qz = -sa * py + ca * pz + m.a_offset_z;
  ToolPose out;
  out.tip = {cc * qx + sc * qy + m.c_centre[0], -sc * qx + cc * qy + m.c_centre[1],
             qz + m.c_centre[2]};
  out.axis = {sa * sc, sa * cc, ca};
  return out;
}

IkResult inverse_kinematics_ac(const MachineKinematics& m, const Vec3& tip, double a_deg,
                               double c_deg) {
  return inverse_kinematics_ac(m, tip, a_deg, c_deg, m.tool_length);
}

IkResult inverse_kinematics_ac(const MachineKinematics& m, const Vec3& tip, double a_deg,
                               double c_deg, double tool_length) {
  IkResult r;
  if (!finite3(tip) || !std::isfinite(a_deg) || !std::isfinite(c_deg) ||
      !std::isfinite(tool_length)) {
    r.status = IkStatus::kFailed;
    r.flags = kIkUnreachable;
    return r;
  }
  const double s = rotation_sign(m);
  const double ta = s * a_deg * kDegToRad;
  const double tc = s * c_deg * kDegToRad;
  solve_linear(m, tip, std::cos(ta), std::sin(ta), std::cos(tc), std::sin(tc), tool_length,
               r.joints);
  r.joints[kA] = a_deg;
  r.joints[kC] = c_deg;
  if (joints_outside_travel(m, r.joints) != 0) {
    r.status = IkStatus::kFailed;
    r.flags = kIkTravelLimit;
  }
  return r;
}

IkResult inverse_kinematics(const MachineKinematics& m, const ToolPose& pose,
                            const Axes& previous) {
  return inverse_kinematics(m, pose, previous, m.tool_length);
}

IkResult inverse_kinematics(const MachineKinematics& m, const ToolPose& pose,
                            const Axes& previous, double tool_length) {
  if (!finite3(pose.tip) || !finite3(pose.axis) || !std::isfinite(tool_length))
    return failed_unreachable(previous);
  const double len = std::sqrt(pose.axis[0] * pose.axis[0] + pose.axis[1] * pose.axis[1] +
                               pose.axis[2] * pose.axis[2]);
  if (!(len > 1e-12)) return failed_unreachable(previous);
  const double ux = pose.axis[0] / len, uy = pose.axis[1] / len, uz = pose.axis[2] / len;

  const double s = rotation_sign(m);
  // Tilt between tool axis and C axis, in [0, pi]. atan2 instead of acos(Ok): acos loses half
  // the digits near Ok = +-1, exactly where the singularity needs them.
  const double tilt = std::atan2(std::hypot(ux, uy), uz);
  const double tilt_deg = tilt * kRadToDeg;

  std::uint32_t flags = 0;
  Candidate cand[2];
  if (tilt_deg < m.c_hold_tilt) {
    // C undefined at the pole: every C gives the same tool axis (to within 2 * tilt), so keep
    // the previous C and solve the linear joints for it. Both signs of A remain.
    flags |= kIkCKeptAtSingularity | kIkNearSingular;
    const bool c_ok = m.travel[kC].contains(previous[kC]);
    cand[0] = make_candidate(m, pose.tip, tilt, previous[kC], c_ok, previous, tool_length);
    cand[1] = make_candidate(m, pose.tip, -tilt, previous[kC], c_ok, previous, tool_length);
  } else {
    if (tilt_deg < m.near_singular_tilt) flags |= kIkNearSingular;
    // Branch +: theta_A = tilt, theta_C = atan2(Oi, Oj). Branch -: theta_A = -tilt,
    // theta_C + pi (README, "Inverse, orientation part").
    const double theta_c = std::atan2(ux, uy);
    for (int b = 0; b < 2; ++b) {
      const double theta_a = b == 0 ? tilt : -tilt;
      const double c_raw = s * (theta_c + (b == 0 ? 0.0 : std::numbers::pi)) * kRadToDeg;
      double c_joint = 0;
      const bool c_ok = unwrap_c(c_raw, previous[kC], m.travel[kC], c_joint);
      cand[b] = make_candidate(m, pose.tip, theta_a, c_joint, c_ok, previous, tool_length);
    }
  }

  int nearest = cand[0].cost <= cand[1].cost ? 0 : 1;
  // Leaving the pole (previous A within c_hold_tilt of 0): only there can the branch change
  // without tilting the tool the wrong way on the way, so take the side of A with the wider
  // travel when it is reachable; continuity alone would keep the previous C and commit to
  // whichever side that happens to give, and pay with a forced 180-degree C flip later.
  if (std::abs(previous[kA]) <= m.c_hold_tilt && cand[0].in_travel && cand[1].in_travel &&
      !(flags & kIkCKeptAtSingularity)) {
    const double wide_side = -m.travel[kA].min > m.travel[kA].max ? -1.0 : 1.0;
    nearest = cand[0].joints[kA] * wide_side > 0 ? 0 : 1;
  }
  int chosen = nearest;
  if (!cand[nearest].in_travel && cand[1 - nearest].in_travel) {
    chosen = 1 - nearest;
    flags |= kIkBranchByLimit;
  }
  IkResult r;
  r.joints = cand[chosen].joints;
  const double h = m.c_hold_tilt;
  if ((r.joints[kA] > h && previous[kA] < -h) || (r.joints[kA] < -h && previous[kA] > h))
    flags |= kIkBranchSwitch;
  if (!cand[chosen].in_travel) flags |= kIkTravelLimit;
  r.flags = flags;
  if (flags & kIkTravelLimit)
    r.status = IkStatus::kFailed;
  else if (flags != 0)
    r.status = IkStatus::kDegraded;
  return r;
}

void inverse_kinematics_path(const MachineKinematics& m, std::span<const ToolPose> poses,
                             const Axes& previous, double tool_length, std::span<IkResult> out) {
  Axes prev = previous;
  const std::size_t n = std::min(poses.size(), out.size());
  for (std::size_t i = 0; i < n; ++i) {
    out[i] = inverse_kinematics(m, poses[i], prev, tool_length);
    prev = out[i].joints;
  }
}

std::uint8_t joints_outside_travel(const MachineKinematics& m, const Axes& j) {
  std::uint8_t bits = 0;
  for (int a = 0; a < kNumAxes; ++a)
    if (!m.travel[static_cast<std::size_t>(a)].contains(j[static_cast<std::size_t>(a)]))
      bits = static_cast<std::uint8_t>(bits | (1u << a));
  return bits;
}

std::string ik_flags_to_string(std::uint32_t flags) {
  static constexpr struct {
    std::uint32_t bit;
    const char* name;
  } kNames[] = {{kIkNearSingular, "near_singular"},
                {kIkCKeptAtSingularity, "c_kept"},
                {kIkBranchSwitch, "branch_switch"},
                {kIkBranchByLimit, "branch_by_limit"},
                {kIkTravelLimit, "travel_limit"},
                {kIkUnreachable, "unreachable"},
                {kIkNeuralDiverged, "neural_diverged"},
                {kIkNeuralOutsideEnvelope, "neural_outside_envelope"},
                {kIkNeuralFailed, "neural_failed"}};
  std::string out;
  for (const auto& n : kNames) {
    if ((flags & n.bit) == 0) continue;
    if (!out.empty()) out += '|';
    out += n.name;
  }
  return out;
}

const char* to_string(IkStatus s) {
  switch (s) {
    case IkStatus::kOk: return "ok";
    case IkStatus::kDegraded: return "degraded";
    case IkStatus::kFailed: return "failed";
  }
  return "?";
}

MachineKinematics load_kinematics(const Config& root) {
  MachineKinematics m;
  if (!root.has("kinematics"))
    throw root.error("kinematics", "missing: the machine file needs a 'kinematics' section");
  if (!root.has("limits"))
    throw root.error("limits", "missing: the machine file needs a 'limits' section");

  const Config k = root.section("kinematics");
  k.reject_unknown({"chain", "c_centre", "a_offset_y", "a_offset_z", "tool_length",
                    "rotary_convention", "c_hold_tilt", "near_singular_tilt"});
  // Only one chain exists; naming it makes a config for another machine type fail loudly.
  if (!k.has("chain")) throw k.error("chain", "missing: the kinematic chain, e.g. 'xyzac_trt'");
  k.choice("chain", "", {"xyzac_trt"});
  const auto c = k.numbers("c_centre", 3, "mm", -1e4, 1e4);
  m.c_centre = {c[0], c[1], c[2]};
  m.a_offset_y = k.number("a_offset_y", "mm", -1e4, 1e4);
  m.a_offset_z = k.number("a_offset_z", "mm", -1e4, 1e4);
  m.tool_length = k.number("tool_length", 0.0, "mm", 0, 1000);
  m.convention = k.choice("rotary_convention", "table_right_hand",
                          {"table_right_hand", "iso841"}) == "iso841"
                     ? RotaryConvention::kIso841
                     : RotaryConvention::kTableRightHand;
  m.c_hold_tilt = k.number("c_hold_tilt", 1e-7, "deg", 0, 1);
  m.near_singular_tilt = k.number("near_singular_tilt", 1.0, "deg", 0, 45);

  const Config lim = root.section("limits");
  lim.reject_unknown({"X", "Y", "Z", "A", "C"});
  for (int a = 0; a < kNumAxes; ++a) {
    const std::string key(1, kAxisLetters[a]);
    if (!lim.has(key)) throw lim.error(key, "missing: every axis X Y Z A C needs its limits");
    const Config ax = lim.section(key);
    ax.reject_unknown({"min", "max", "velocity", "acceleration"});
    const bool rotary = a >= kA;
    const char* pos_unit = rotary ? "deg" : "mm";
    // A is limited to one turn either way: the tool-vector IK produces A in [-180, 180].
    const double bound = a == kA ? 360.0 : (a == kC ? 1e6 : 1e4);
    auto& r = m.travel[static_cast<std::size_t>(a)];
    r.min = ax.number("min", pos_unit, -bound, bound);
    r.max = ax.number("max", pos_unit, -bound, bound);
    if (!(r.min < r.max))
      throw ax.error("max", "must be greater than min (" + std::to_string(r.min) + ") for axis " +
                                key);
    m.max_velocity[static_cast<std::size_t>(a)] =
        ax.number("velocity", rotary ? "deg/s" : "mm/s", 1e-6, 1e6);
    m.max_acceleration[static_cast<std::size_t>(a)] =
        ax.number("acceleration", rotary ? "deg/s^2" : "mm/s^2", 1e-6, 1e8);
  }
  return m;
}

}  // namespace gcpipe
