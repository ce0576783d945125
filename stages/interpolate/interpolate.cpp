#include "interpolate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "gcpipe/config.hpp"

namespace gcpipe::interpolate {

namespace {
constexpr double kTwoPi = 2 * std::numbers::pi;
}

InterpolateOptions load_interpolate_options(const Config& s) {
  s.reject_unknown({"period", "control", "smoothing", "in_position", "path_tolerance"});
  InterpolateOptions o;
  o.period = s.number("period", o.period, "s", 1e-5, 0.1);
  o.in_position = s.number("in_position", o.in_position, "mm or deg", 1e-6, 1);
  const std::string c = s.choice("control", "after_interpolation", {"after_interpolation", "lookahead"});
  o.control = c == "lookahead" ? Control::kLookahead : Control::kAfterInterpolation;
  o.path_tolerance = s.number("path_tolerance", o.path_tolerance, "mm", 1e-5, 1.0);
  // The look-ahead control plans acc/dec before interpolation: a second acc/dec after it would
  // round every corner again by its lag, which is what the look-ahead exists to avoid.
  const std::string k = s.choice("smoothing", o.control == Control::kLookahead ? "none" : "exponential",
                                 {"none", "linear", "exponential"});
  if (o.control == Control::kLookahead && k != "none")
    throw s.error("smoothing", "must be none with control: lookahead (its acc/dec is before interpolation)");
  o.smoothing = k == "none" ? Smoothing::kNone : k == "linear" ? Smoothing::kLinear : Smoothing::kExponential;
  return o;
}

Axes speed_bound(const InterpolateOptions& o) {
  Axes v;
  for (std::size_t i = 0; i < kNumAxes; ++i) {
    v[i] = o.max_velocity[i];
    if (o.smoothing != Smoothing::kNone && o.smoothing_time[i] > 0)
      v[i] = std::min(v[i], o.max_acceleration[i] * o.smoothing_time[i]);
  }
  return v;
}

// ---------------------------------------------------------------------------------------------

AxisSmoother::AxisSmoother(Smoothing kind, double Ts, double period, double start)
    : kind_(Ts > 0 ? kind : Smoothing::kNone), y_(start) {
  if (kind_ == Smoothing::kLinear) {
    const auto n = static_cast<std::size_t>(std::max(1L, std::lround(Ts / period)));
    ring_.assign(n, start);
    sum_ = start * static_cast<double>(n);
    settle_ = n;
  } else if (kind_ == Smoothing::kExponential) {
    a_ = std::exp(-period / Ts);
    settle_ = static_cast<std::size_t>(std::ceil(50 * Ts / period));
  }
}

double AxisSmoother::filter(double x) {
  switch (kind_) {
    case Smoothing::kNone:
      y_ = x;
      break;
    case Smoothing::kLinear: {
      const std::size_t n = ring_.size();
      sum_ += x - ring_[head_];
      ring_[head_] = x;
      head_ = (head_ + 1) % n;
      // The running sum drifts by rounding; an exact re-sum every few thousand samples bounds it.
      if (++count_ % 4096 == 0) {
        sum_ = 0;
        for (double v : ring_) sum_ += v;
      }
      y_ = sum_ / static_cast<double>(n);
      break;
    }
    case Smoothing::kExponential:
      y_ = a_ * y_ + (1 - a_) * x;
      break;
  }
  return y_;
}

bool AxisSmoother::settled(double x, double tol) const { return std::abs(y_ - x) <= tol; }
std::size_t AxisSmoother::settle_samples() const { return settle_; }

std::complex<double> smoothing_response(Smoothing kind, double Ts, double period, double omega) {
  if (!(Ts > 0) || kind == Smoothing::kNone) return 1.0;
  const std::complex<double> z1 = std::exp(std::complex<double>(0, -omega * period));  // z^-1
  if (kind == Smoothing::kLinear) {
    const long n = std::max(1L, std::lround(Ts / period));
    std::complex<double> s = 0, zk = 1;
    for (long k = 0; k < n; ++k, zk *= z1) s += zk;
    return s / static_cast<double>(n);
  }
  const double a = std::exp(-period / Ts);
  return (1 - a) / (1.0 - a * z1);
}

// ---------------------------------------------------------------------------------------------

namespace {

struct Path {
  // Straight move, or arc in the plane (ia, ib) around (ca, cb) with the other axes linear. In
  // joint mode the coordinates are joints; in TCP mode X Y Z are the tool tip in the workpiece
  // frame and A C the programmed rotary positions.
  bool arc = false;
  int ia = 0, ib = 1, in = 2;
  double ca = 0, cb = 0, th0 = 0, dth = 0, r0 = 0, r1 = 0;
  Axes from{}, to{};

  Axes at(double s) const {
    Axes p;
    for (int i = 0; i < kNumAxes; ++i) p[static_cast<std::size_t>(i)] = from[static_cast<std::size_t>(i)] + s * (to[static_cast<std::size_t>(i)] - from[static_cast<std::size_t>(i)]);
    if (arc) {
      if (s >= 1) return to;  // land exactly on the programmed end point
      const double th = th0 + s * dth, r = r0 + s * (r1 - r0);
      p[static_cast<std::size_t>(ia)] = ca + r * std::cos(th);
      p[static_cast<std::size_t>(ib)] = cb + r * std::sin(th);
    }
    return p;
  }
};

std::string where(const ResolvedBlock& b) {
  return "line " + std::to_string(b.line) + " (" + b.text + ")";
}

double dot3(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double norm3(const Vec3& a) { return std::sqrt(dot3(a, a)); }
double dist3(const Vec3& a, const Vec3& b) { return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]); }
Vec3 tip_of(const Axes& p) { return {p[kX], p[kY], p[kZ]}; }
bool all_finite(const Axes& q) {
  for (double v : q)
    if (!std::isfinite(v)) return false;
  return true;
}

// Maps a point of a TCP path (tool tip + A C, at path parameter s) to joints.
struct TcpMap {
  const MachineKinematics* kin = nullptr;
  double tool_length = 0;
  bool vector_mode = false;  // G43.5: the tool vector is slerped, the IK chooses A and C
  Vec3 v0{}, v1{};           // unit tool vectors at s = 0 and s = 1
  double omega = 0;          // angle between them [rad]

  Vec3 vector_at(double s) const {
    if (omega < 1e-12) {
      Vec3 v{v0[0] + s * (v1[0] - v0[0]), v0[1] + s * (v1[1] - v0[1]), v0[2] + s * (v1[2] - v0[2])};
      const double n = norm3(v);
      return {v[0] / n, v[1] / n, v[2] / n};
    }
    const double so = std::sin(omega), w0 = std::sin((1 - s) * omega) / so, w1 = std::sin(s * omega) / so;
    return {w0 * v0[0] + w1 * v1[0], w0 * v0[1] + w1 * v1[1], w0 * v0[2] + w1 * v1[2]};
  }

  IkResult joints(const Axes& p, double s, const Axes& previous) const {
    if (!vector_mode) return inverse_kinematics_ac(*kin, tip_of(p), p[kA], p[kC], tool_length);
    return inverse_kinematics(*kin, ToolPose{tip_of(p), vector_at(s)}, previous, tool_length);
  }
};

// Largest |dq_i/ds| and |d2q_i/ds2| of a TCP block's joint path, from K + 1 sub-samples (chords
// and second differences), and the joints at s = 1 reached by continuity along the path.
struct JointSweep {
  Axes rate{};       // max |dq/ds| [mm, deg]
  Axes curvature{};  // max |d2q/ds2| [mm, deg]
  Axes end{};
  bool finite = true;
};

JointSweep sweep_joints(const Path& path, const TcpMap& map, const Axes& start, int K) {
  JointSweep w;
  Axes prev = start, prev2 = start;
  const double inv_ds = K, inv_ds2 = static_cast<double>(K) * K;
  for (int k = 1; k <= K; ++k) {
    const double s = static_cast<double>(k) / K;
    const IkResult r = map.joints(path.at(s), s, prev);
    if (!all_finite(r.joints)) {
      w.finite = false;
      return w;
    }
    for (std::size_t i = 0; i < kNumAxes; ++i) {
      w.rate[i] = std::max(w.rate[i], std::abs(r.joints[i] - prev[i]) * inv_ds);
      if (k >= 2) w.curvature[i] = std::max(w.curvature[i], std::abs(r.joints[i] - 2 * prev[i] + prev2[i]) * inv_ds2);
    }
    prev2 = prev;
    prev = r.joints;
  }
  w.end = prev;
  return w;
}

// Length of the tool-tip path [mm] of a joint-space path (line or arc) through forward
// kinematics: chord sums over 32 and 64 pieces, whose error is c/N^2 + O(N^-4) for a smooth
// curve, combined by Richardson extrapolation (4 L64 - L32) / 3.
double fk_tip_length(const MachineKinematics& kin, const Path& path, double tool_length) {
  auto chords = [&](int n) {
    double len = 0;
    Vec3 prev = forward_kinematics(kin, path.from, tool_length).tip;
    for (int k = 1; k <= n; ++k) {
      const Vec3 p = forward_kinematics(kin, path.at(static_cast<double>(k) / n), tool_length).tip;
      len += dist3(prev, p);
      prev = p;
    }
    return len;
  };
  const double l32 = chords(32), l64 = chords(64);
  return std::max(l64, (4 * l64 - l32) / 3);
}

}  // namespace

Interpolator::Interpolator(InterpolateOptions options, const Axes& start)
    : opt_(std::move(options)), raw_end_(start), prev_(start), prev2_(start) {
  if (!(opt_.period > 0) || !std::isfinite(opt_.period))
    throw ConfigError("interpolate: period " + std::to_string(opt_.period) + " s must be > 0");
  for (int i = 0; i < kNumAxes; ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (!(opt_.smoothing_time[k] >= 0))
      throw ConfigError(std::string("interpolate: smoothing time Ts of axis ") + kAxisLetters[i] + " must be >= 0");
    smooth_[k] = AxisSmoother(opt_.smoothing, opt_.smoothing_time[k], opt_.period, start[k]);
  }
}

void Interpolator::emit(const Axes& raw, SampleSink& sink) {
  Axes y;
  const double inv_T = 1 / opt_.period, inv_T2 = inv_T * inv_T;
  for (std::size_t i = 0; i < kNumAxes; ++i) {
    y[i] = smooth_[i].filter(raw[i]);
    // Joint limits are checked on every sample, so tool-centre-point and arc motion that leaves
    // the travel between programmed points is caught, not only the end points.
    if (y[i] < opt_.travel_min[i] || y[i] > opt_.travel_max[i]) {
      if (stats_.first_violation_line == 0) {
        stats_.first_violation_line = line_ ? line_ : 1;
        stats_.first_violation_axis = static_cast<int>(i);
        stats_.first_violation_position = y[i];
      }
      // The farthest the first axis to leave goes, so the message names the real excursion.
      if (static_cast<int>(i) == stats_.first_violation_axis &&
          std::max(y[i] - opt_.travel_max[i], opt_.travel_min[i] - y[i]) >
              std::max(stats_.first_violation_position - opt_.travel_max[i], opt_.travel_min[i] - stats_.first_violation_position))
        stats_.first_violation_position = y[i];
      ++stats_.travel_violations[i];
    }
    const double v = std::abs(y[i] - prev_[i]) * inv_T;
    const double a = std::abs(y[i] - 2 * prev_[i] + prev2_[i]) * inv_T2;
    stats_.peak_velocity[i] = std::max(stats_.peak_velocity[i], v);
    if (stats_.samples >= 1) stats_.peak_acceleration[i] = std::max(stats_.peak_acceleration[i], a);
  }
  prev2_ = prev_;
  prev_ = y;
  ++stats_.samples;
  sink.raw_sample(raw);
  sink.sample(y);
}

// One block's plan: what the steps of add() hand on.
struct Interpolator::BlockPlan {
  Path path;
  TcpMap map;
  bool moves = false, tcp = false;
  double tool_length = 0;
  double duration = 0;
  Axes travel{};    // largest speed-relevant excursion per axis (arc: radius x angle in plane)
  Axes tcp_end{};   // joints at the end of a TCP block
};

InterpolateResult Interpolator::add(const ResolvedBlock& b, SampleSink& sink) {
  InterpolateResult res;
  BlockPlan plan;
  if (auto early = plan_path(b, plan, sink)) return *early;
  if (auto early = plan_duration(b, plan, res)) return *early;
  if (auto early = account(b, plan, res)) return *early;
  sample(b, plan, sink);
  if (plan.moves && b.path_mode != PathMode::kBlend) res.duration += hold_until_in_position(sink);
  return res;
}

// G61 (exact stop) and G61.1 (exact path, which a control that smooths after interpolation can
// only keep by stopping): the end point is held until every axis's smoothed command is within
// in_position of it, as a control's in-position check holds the next block (here on the command:
// the drives come after the interpolator). The time held [s] belongs to the block.
double Interpolator::hold_until_in_position(SampleSink& sink) { return hold_end(sink, opt_.in_position); }

// Holds the raw end until every smoother is within `tolerance` of it (at most their settling
// time); the first sample completes the partial period so that the raw clock and the sample
// clock agree again. Returns the time held [s].
double Interpolator::hold_end(SampleSink& sink, double tolerance) {
  const double t0 = t_block_;
  std::size_t need = 0;
  for (const auto& s : smooth_) need = std::max(need, s.settle_samples());
  for (std::size_t i = 0; i < need + 1; ++i) {
    bool all = true;
    for (std::size_t a = 0; a < kNumAxes; ++a) all = all && smooth_[a].settled(raw_end_[a], tolerance);
    if (all && i > 0) break;
    ++n_;
    emit(raw_end_, sink);
  }
  t_block_ = static_cast<double>(n_) * opt_.period;
  return t_block_ - t0;
}

namespace {

InterpolateResult invalid_block(const ResolvedBlock& b, const std::string& why) {
  InterpolateResult res;
  res.status = InterpolateStatus::kInvalid;
  res.message = where(b) + ": " + why;
  return res;
}

/// The arc's geometry in its plane: centre, radii, start angle and signed sweep (turns
/// included), its length along the tool and the axes' excursions. Empty on success.
std::optional<InterpolateResult> arc_geometry(const ResolvedBlock& b, bool tcp, Path& path, Axes& travel, double& length_xyz) {
  path.arc = true;
  switch (b.plane) {
    case Plane::kXY: path.ia = kX; path.ib = kY; path.in = kZ; break;
    case Plane::kZX: path.ia = kZ; path.ib = kX; path.in = kY; break;
    case Plane::kYZ: path.ia = kY; path.ib = kZ; path.in = kX; break;
  }
  const auto ia = static_cast<std::size_t>(path.ia), ib = static_cast<std::size_t>(path.ib),
             in = static_cast<std::size_t>(path.in);
  path.ca = b.centre[ia];
  path.cb = b.centre[ib];
  const double sa = path.from[ia] - path.ca, sb = path.from[ib] - path.cb;
  const double ea = path.to[ia] - path.ca, eb = path.to[ib] - path.cb;
  path.r0 = std::hypot(sa, sb);
  path.r1 = std::hypot(ea, eb);
  if (!(path.r0 > 1e-9)) return invalid_block(b, "arc start lies on its centre");
  path.th0 = std::atan2(sb, sa);
  double d = std::atan2(eb, ea) - path.th0;
  const bool ccw = b.motion == Motion::kArcCCW;
  // TCP start points come through FK and match the programmed ones only to ~1e-13 mm.
  const bool full = std::hypot(ea - sa, eb - sb) < (tcp ? 1e-7 : 1e-9);
  if (ccw) {
    while (d <= 0) d += kTwoPi;
    if (full) d = kTwoPi;
  } else {
    while (d >= 0) d -= kTwoPi;
    if (full) d = -kTwoPi;
  }
  const double extra = kTwoPi * std::max(0, b.turns - 1);
  path.dth = ccw ? d + extra : d - extra;
  const double rmean = 0.5 * (path.r0 + path.r1);
  const double arc_len = rmean * std::abs(path.dth);
  const double dh = path.to[in] - path.from[in];
  length_xyz = std::hypot(arc_len, dh);
  for (std::size_t i = 0; i < kNumAxes; ++i) travel[i] = std::abs(path.to[i] - path.from[i]);
  travel[ia] = travel[ib] = std::max(path.r0, path.r1) * std::abs(path.dth);
  return std::nullopt;
}

}  // namespace

// Validates the target and sets the path's end points; in TCP mode the start becomes a tool tip
// and a G43.5 block leaving the pole first turns C there (a block of its own, run here).
std::optional<InterpolateResult> Interpolator::plan_path(const ResolvedBlock& b, BlockPlan& plan, SampleSink& sink) {
  Path& path = plan.path;
  path.from = raw_end_;
  path.to = b.target;
  for (double v : b.target)
    if (!std::isfinite(v)) return invalid_block(b, "non-finite target");

  plan.moves = b.motion == Motion::kRapid || b.motion == Motion::kLinear ||
               b.motion == Motion::kArcCW || b.motion == Motion::kArcCCW;
  plan.tcp = plan.moves && b.tcp;
  // Switching between joint and TCP mode: the parser's targets of the axes this block does not
  // program still hold values of the other space (tips vs joints); those axes keep their
  // current value in the block's own space instead (README, "Switching").
  const bool switching = plan.moves && plan.tcp != tcp_space_;
  auto kept = [&](int axis) { return switching && (b.axis_words & (1u << axis)) == 0; };
  const MachineKinematics* kin = opt_.kinematics;
  plan.tool_length = kin ? (b.tool_length_active ? b.tool_length : kin->tool_length) : 0.0;
  plan.tcp_end = raw_end_;

  if (!plan.tcp) {
    if (plan.moves && tcp_space_)
      for (int i = 0; i < kNumAxes; ++i)
        if (kept(i)) path.to[static_cast<std::size_t>(i)] = raw_end_[static_cast<std::size_t>(i)];
    return std::nullopt;
  }
  if (kin == nullptr) {
    InterpolateResult res;
    res.status = InterpolateStatus::kUnsupported;
    res.message = where(b) + ": tool-centre-point block needs the machine kinematics (InterpolateOptions::kinematics)";
    return res;
  }
  TcpMap& map = plan.map;
  map.kin = kin;
  map.tool_length = plan.tool_length;
  const ToolPose now = forward_kinematics(*kin, raw_end_, plan.tool_length);
  path.from = {now.tip[0], now.tip[1], now.tip[2], raw_end_[kA], raw_end_[kC]};
  for (int i = 0; i < kNumAxes; ++i)
    if (kept(i)) path.to[static_cast<std::size_t>(i)] = path.from[static_cast<std::size_t>(i)];
  if (!b.tool_vector_mode) return std::nullopt;
  map.vector_mode = true;
  const double n = norm3(b.tool_vector);
  if (!(n > 1e-12) || !std::isfinite(n)) return invalid_block(b, "tool vector I J K has zero length");
  map.v0 = now.axis;
  map.v1 = {b.tool_vector[0] / n, b.tool_vector[1] / n, b.tool_vector[2] / n};
  map.omega = std::acos(std::clamp(dot3(map.v0, map.v1), -1.0, 1.0));
  if (map.omega > std::numbers::pi - 1e-9)
    return invalid_block(b, "tool vector turns by 180 deg: the orientation path is undefined (split the move)");
  // Leaving the pole: at A = 0, C is free and was held; the first step off the pole needs the
  // C of the direction the slerp leaves in (a meridian: the azimuth of v1), which is a jump
  // in joints. As a control does, C turns first, at the pole, with the tip held and the
  // tool axis unchanged: a TCP move with A C given, fed at F deg/min (G94) or at the joint
  // limits (G93); then the block itself runs from there with C continuous.
  if (!pole_turn_ && std::abs(raw_end_[kA]) <= kin->c_hold_tilt && map.omega > 0) {
    const IkResult leave = inverse_kinematics(*kin, ToolPose{now.tip, map.v1}, raw_end_, plan.tool_length);
    if (all_finite(leave.joints) && std::abs(leave.joints[kC] - raw_end_[kC]) > 1e-9) {
      ResolvedBlock turn = b;
      turn.tool_vector_mode = false;
      turn.motion = b.feed_mode == FeedMode::kInverseTime ? Motion::kRapid : Motion::kLinear;
      turn.target = {now.tip[0], now.tip[1], now.tip[2], raw_end_[kA], leave.joints[kC]};
      turn.axis_words = 0x1f;
      pole_turn_ = true;
      InterpolateResult first = add(turn, sink);
      if (first.status == InterpolateStatus::kOk) {
        --stats_.blocks;  // one programmed block
        --stats_.tcp_blocks;
        InterpolateResult rest = add(b, sink);
        rest.duration += first.duration;
        rest.velocity_limited = rest.velocity_limited || first.velocity_limited;
        first = rest;
      }
      pole_turn_ = false;
      return first;
    }
  }
  // A and C follow from the IK; the path's own A C are placeholders at the current joints.
  path.to[kA] = raw_end_[kA];
  path.to[kC] = raw_end_[kC];
  return std::nullopt;
}

// A TCP block's duration: the joint path through IK, sub-sampled finer than the ticks and the
// rotation; its largest joint rates and curvatures set the shortest duration the joint limits
// allow.
std::optional<InterpolateResult> Interpolator::tcp_duration(const ResolvedBlock& b, BlockPlan& plan, InterpolateResult& res,
                                                           double length_xyz) const {
  const Path& path = plan.path;
  double& duration = plan.duration;
  const double T = opt_.period;
  const Axes vlim = speed_bound(opt_);
  const bool feed_move = b.motion != Motion::kRapid;
  // Joint path through IK, sub-sampled finer than the ticks and the rotation: its largest
  // joint rates and curvatures set the shortest duration the joint limits allow.
  const double angle_deg = std::abs(path.to[kA] - path.from[kA]) + std::abs(path.to[kC] - path.from[kC]) +
                           std::abs(path.dth) * 180 / std::numbers::pi + plan.map.omega * 180 / std::numbers::pi;
  const double feed_time = feed_move && b.feed > 0 ? std::max(length_xyz, 1.0) / (b.feed / 60.0) : 0.0;
  const int K = static_cast<int>(std::clamp(std::max(4 * angle_deg, 2 * std::max(duration, feed_time) / T), 256.0, 16384.0));
  const JointSweep w = sweep_joints(path, plan.map, raw_end_, K);
  if (!w.finite) return invalid_block(b, "no finite joints for the tool-tip path (inverse kinematics failed)");
  plan.tcp_end = w.end;
  if (feed_move && b.feed_mode == FeedMode::kUnitsPerMinute) {
    double length = length_xyz;  // along the tool tip in the workpiece frame
    if (!(length > 1e-9)) length = std::hypot(w.end[kA] - raw_end_[kA], w.end[kC] - raw_end_[kC]);
    duration = length / (b.feed / 60.0);
    res.feed_length = length;
  }
  res.axis_travel = w.rate;
  double need = 0;
  for (std::size_t i = 0; i < kNumAxes; ++i) {
    if (w.rate[i] == 0) continue;
    if (!(vlim[i] > 0)) return invalid_block(b, std::string("axis ") + kAxisLetters[i] + " has no velocity limit");
    need = std::max(need, w.rate[i] / vlim[i]);
    if (opt_.max_acceleration[i] > 0) need = std::max(need, std::sqrt(w.curvature[i] / opt_.max_acceleration[i]));
  }
  res.limit_duration = need;
  if (need > duration * (1 + 1e-12)) {
    res.velocity_limited = feed_move && duration > 0;
    if (res.velocity_limited) res.feed_factor = duration / need;
    duration = need;
  }
  return std::nullopt;
}

// The block's duration: from the feed (along the tool tip, or inverse time), raised to what the
// axes' velocity (and in TCP mode acceleration) limits allow.
std::optional<InterpolateResult> Interpolator::plan_duration(const ResolvedBlock& b, BlockPlan& plan, InterpolateResult& res) const {
  Path& path = plan.path;
  double& duration = plan.duration;
  Axes& travel = plan.travel;
  const Axes vlim = speed_bound(opt_);
  const MachineKinematics* kin = opt_.kinematics;
  switch (b.motion) {
    case Motion::kNone:
      return res;
    case Motion::kTrochoidSlot:
      res.status = InterpolateStatus::kUnsupported;
      res.message = where(b) + ": G275 trochoidal slot must be expanded by the trochoid stage first";
      return res;
    case Motion::kDwell:
      duration = b.dwell;
      if (!(duration >= 0)) return invalid_block(b, "negative dwell");
      path.to = raw_end_;
      return std::nullopt;
    case Motion::kRapid:
    case Motion::kLinear:
    case Motion::kArcCW:
    case Motion::kArcCCW:
      break;
  }
  double length_xyz = 0;
  if (b.motion == Motion::kArcCW || b.motion == Motion::kArcCCW) {
    if (auto bad = arc_geometry(b, plan.tcp, path, travel, length_xyz)) return bad;
  } else {
    for (std::size_t i = 0; i < kNumAxes; ++i) travel[i] = std::abs(path.to[i] - path.from[i]);
    length_xyz = std::sqrt(travel[kX] * travel[kX] + travel[kY] * travel[kY] + travel[kZ] * travel[kZ]);
  }
  const bool feed_move = b.motion != Motion::kRapid;
  if (feed_move && b.feed_mode == FeedMode::kInverseTime) {
    if (!(b.feed > 0)) return invalid_block(b, "inverse-time feed F must be > 0 (G93: F = 1/minutes)");
    duration = 60.0 / b.feed;
  } else if (feed_move && !(b.feed > 0)) {
    return invalid_block(b, "feed F must be > 0 for G1/G2/G3");
  }

  if (plan.tcp) return tcp_duration(b, plan, res, length_xyz);

  if (!feed_move) {
    for (std::size_t i = 0; i < kNumAxes; ++i) {
      if (travel[i] == 0) continue;
      if (!(vlim[i] > 0)) return invalid_block(b, std::string("axis ") + kAxisLetters[i] + " has no velocity limit for the rapid");
      duration = std::max(duration, travel[i] / vlim[i]);
    }
  } else if (b.feed_mode == FeedMode::kUnitsPerMinute) {
    double length = length_xyz;
    const bool rotary_moves = travel[kA] != 0 || travel[kC] != 0;
    double min_length = 1e-12;
    if (kin != nullptr && rotary_moves) {
      length = fk_tip_length(*kin, path, plan.tool_length);
      min_length = 1e-9;  // FK rounding of a tip that stays put
    } else if (kin == nullptr && opt_.tip_path_length && !path.arc) {
      length = opt_.tip_path_length(path.from, path.to);
    }
    if (!(length > min_length)) length = std::hypot(travel[kA], travel[kC]);  // deg at deg/min
    duration = length / (b.feed / 60.0);
    res.feed_length = length;
  }
  res.axis_travel = travel;
  for (std::size_t i = 0; i < kNumAxes; ++i) {
    if (travel[i] == 0 || !(vlim[i] > 0)) continue;
    const double need = travel[i] / vlim[i];
    res.limit_duration = std::max(res.limit_duration, need);
    if (need > duration * (1 + 1e-12)) {
      if (b.motion != Motion::kRapid) res.feed_factor = std::min(res.feed_factor, duration / need);
      duration = need;
      res.velocity_limited = b.motion != Motion::kRapid;
    }
  }
  return std::nullopt;
}

// A joint move past the machine's travel is usually a work offset gone wrong (G10 L2 X99999) and
// so long that the machine-time bound refuses it first: name the travel, the cause, not the time.
bool Interpolator::travel_message(const ResolvedBlock& b, double duration, InterpolateResult& res) const {
  for (int a = 0; a < kNumAxes; ++a) {
    const double q = b.target[a];
    if (q >= opt_.travel_min[a] && q <= opt_.travel_max[a]) continue;
    const char* unit = a >= kA ? "deg" : "mm";
    char msg[400];
    std::snprintf(msg, sizeof msg,
                  ": axis %c goes to %.3f %s, outside its travel [%g, %g] %s (the move would take %.6g s): the machine "
                  "cannot run this block; check the work offset (G10 L2/L20, G92, G52), the tool length and the "
                  "program's coordinates",
                  kAxisLetters[a], q, unit, opt_.travel_min[a], opt_.travel_max[a], unit, duration);
    res.status = InterpolateStatus::kInvalid;
    res.message = where(b) + msg;
    return true;
  }
  return false;
}

// A feed above an axis's speed bound runs at the bound, as a control clamps it (LinuxCNC limits
// a move's velocity to what its slowest axis allows; a Fanuc clamps to the axes' maximum cutting
// feed): counted, so the report can say where and by how much.
void Interpolator::count_clamped_feed(const ResolvedBlock& b, const InterpolateResult& res) {
  ++stats_.velocity_limited_blocks;
  if (stats_.first_clamped_line == 0) stats_.first_clamped_line = b.line;
  stats_.last_clamped_line = std::max<std::uint64_t>(stats_.last_clamped_line, b.line);
  if (res.feed_factor < stats_.most_clamped_factor) {
    stats_.most_clamped_factor = res.feed_factor;
    stats_.most_clamped_line = b.line;
    stats_.most_clamped_feed = b.feed;
    stats_.most_clamped_inverse_time = b.feed_mode == FeedMode::kInverseTime;
  }
}

// The block counts as run: statistics, mode, and the bound on machine time (a block ending past
// it is refused before its first tick).
std::optional<InterpolateResult> Interpolator::account(const ResolvedBlock& b, const BlockPlan& plan, InterpolateResult& res) {
  res.duration = plan.duration;
  line_ = b.line;
  ++stats_.blocks;
  if (plan.tcp) ++stats_.tcp_blocks;
  if (plan.moves) tcp_space_ = plan.tcp;
  if (res.velocity_limited) count_clamped_feed(b, res);
  const double t_end = t_block_ + plan.duration;
  if (t_end > opt_.max_time && !plan.tcp && travel_message(b, plan.duration, res)) return res;
  if (t_end > opt_.max_time) {
    char msg[200];
    std::snprintf(msg, sizeof msg, ": this block takes %.6g s and would end at %.6g s of machine time, past the bound of %.6g s",
                  plan.duration, t_end, opt_.max_time);
    res.status = InterpolateStatus::kTooLong;
    res.message = where(b) + msg;
    return res;
  }
  return std::nullopt;
}

// Samples at t = n T inside (t_block_, t_end]; the tolerance keeps a sample that rounding put a
// hair beyond the end.
void Interpolator::sample(const ResolvedBlock& b, const BlockPlan& plan, SampleSink& sink) {
  const Path& path = plan.path;
  const double T = opt_.period, duration = plan.duration;
  const double t_end = t_block_ + duration;
  // On an arc the angle grows by the same step every period, so cos and sin follow by rotation
  // (4 multiplies) instead of two libm calls per sample; an exact anchor every 64 samples keeps
  // the recurrence's rounding drift below 1e-13 of the radius.
  double cth = 0, sth = 0, cd = 1, sd = 0, th_step = 0;
  std::uint32_t since_anchor = 64;
  if (path.arc && duration > 0) {
    th_step = path.dth * T / duration;
    cd = std::cos(th_step);
    sd = std::sin(th_step);
  }
  Axes previous_joints = raw_end_;
  // TCP: the path point becomes joints before smoothing; a failed IK is counted with this
  // block's line, and a non-finite answer holds the previous joints.
  auto to_joints = [&](const Axes& p, double s) {
    // The end sample is the sweep's end (the joints the next block starts from).
    const IkResult r = s >= 1 ? plan.map.joints(path.to, 1.0, plan.tcp_end) : plan.map.joints(p, s, previous_joints);
    const bool finite = all_finite(r.joints);
    if (!finite || r.status == IkStatus::kFailed) {
      ++stats_.ik_failed_samples;
      if (!finite) ++stats_.ik_unreachable_samples;
      if (stats_.first_ik_failure_line == 0) stats_.first_ik_failure_line = b.line ? b.line : 1;
    }
    if (finite) previous_joints = r.joints;
    return previous_joints;
  };
  while (true) {
    const double t = static_cast<double>(n_ + 1) * T;
    if (t > t_end + 1e-9 * T) break;
    ++n_;
    const double s = duration > 0 ? std::clamp((t - t_block_) / duration, 0.0, 1.0) : 1.0;
    if (!path.arc || s >= 1) {
      if (plan.tcp) emit(to_joints(path.at(s), s), sink);
      else emit(path.at(s), sink);
      continue;
    }
    if (since_anchor >= 64) {
      const double th = path.th0 + s * path.dth;
      cth = std::cos(th);
      sth = std::sin(th);
      since_anchor = 0;
    } else {
      const double c = cth * cd - sth * sd;
      sth = sth * cd + cth * sd;
      cth = c;
    }
    ++since_anchor;
    Axes p;
    for (std::size_t i = 0; i < kNumAxes; ++i) p[i] = path.from[i] + s * (path.to[i] - path.from[i]);
    const double r = path.r0 + s * (path.r1 - path.r0);
    p[static_cast<std::size_t>(path.ia)] = path.ca + r * cth;
    p[static_cast<std::size_t>(path.ib)] = path.cb + r * sth;
    if (plan.tcp) emit(to_joints(p, s), sink);
    else emit(p, sink);
  }
  t_block_ = t_end;
  raw_end_ = plan.tcp ? plan.tcp_end : path.to;
}

void Interpolator::finish(SampleSink& sink) { hold_end(sink, 1e-9); }

}  // namespace gcpipe::interpolate
