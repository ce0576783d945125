#include "interpolate.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "gcpipe/config.hpp"

namespace gcpipe::interpolate {

namespace {
constexpr double kTwoPi = 2 * std::numbers::pi;
}

InterpolateOptions load_interpolate_options(const Config& s) {
  s.reject_unknown({"period", "smoothing"});
  InterpolateOptions o;
  o.period = s.number("period", o.period, "s", 1e-5, 0.1);
  const std::string k = s.choice("smoothing", "exponential", {"none", "linear", "exponential"});
  o.smoothing = k == "none" ? Smoothing::kNone : k == "linear" ? Smoothing::kLinear : Smoothing::kExponential;
  return o;
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
  // Straight joint move, or arc in the plane (ia, ib) around (ca, cb) with the other axes linear.
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
      if (stats_.first_violation_line == 0) stats_.first_violation_line = line_ ? line_ : 1;
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

InterpolateResult Interpolator::add(const ResolvedBlock& b, SampleSink& sink) {
  InterpolateResult res;
  Path path;
  path.from = raw_end_;
  path.to = b.target;
  double duration = 0;
  const double T = opt_.period;

  auto invalid = [&](const std::string& why) {
    res.status = InterpolateStatus::kInvalid;
    res.message = where(b) + ": " + why;
    return res;
  };
  for (double v : b.target)
    if (!std::isfinite(v)) return invalid("non-finite target");

  // Per-axis velocity bound: the axis limit, and the speed whose step the smoother turns into
  // exactly the acceleration limit (linear: dv/Ts; exponential: initial slope dv/Ts).
  Axes vlim;
  for (std::size_t i = 0; i < kNumAxes; ++i) {
    vlim[i] = opt_.max_velocity[i];
    if (opt_.smoothing != Smoothing::kNone && opt_.smoothing_time[i] > 0)
      vlim[i] = std::min(vlim[i], opt_.max_acceleration[i] * opt_.smoothing_time[i]);
  }
  Axes travel{};  // largest speed-relevant excursion per axis (arc: radius x angle in plane)

  switch (b.motion) {
    case Motion::kNone:
      return res;
    case Motion::kTrochoidSlot:
      res.status = InterpolateStatus::kUnsupported;
      res.message = where(b) + ": G275 trochoidal slot must be expanded by the trochoid stage first";
      return res;
    case Motion::kDwell:
      duration = b.dwell;
      if (!(duration >= 0)) return invalid("negative dwell");
      path.to = raw_end_;
      break;
    case Motion::kRapid:
    case Motion::kLinear:
    case Motion::kArcCW:
    case Motion::kArcCCW: {
      double length_xyz = 0;
      if (b.motion == Motion::kArcCW || b.motion == Motion::kArcCCW) {
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
        if (!(path.r0 > 1e-9)) return invalid("arc start lies on its centre");
        path.th0 = std::atan2(sb, sa);
        double d = std::atan2(eb, ea) - path.th0;
        const bool ccw = b.motion == Motion::kArcCCW;
        const bool full = std::hypot(ea - sa, eb - sb) < 1e-9;
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
      } else {
        for (std::size_t i = 0; i < kNumAxes; ++i) travel[i] = std::abs(path.to[i] - path.from[i]);
        length_xyz = std::sqrt(travel[kX] * travel[kX] + travel[kY] * travel[kY] + travel[kZ] * travel[kZ]);
      }
      if (b.motion == Motion::kRapid) {
        for (std::size_t i = 0; i < kNumAxes; ++i) {
          if (travel[i] == 0) continue;
          if (!(vlim[i] > 0)) return invalid(std::string("axis ") + kAxisLetters[i] + " has no velocity limit for the rapid");
          duration = std::max(duration, travel[i] / vlim[i]);
        }
      } else if (b.feed_mode == FeedMode::kInverseTime) {
        if (!(b.feed > 0)) return invalid("inverse-time feed F must be > 0 (G93: F = 1/minutes)");
        duration = 60.0 / b.feed;
      } else {
        if (!(b.feed > 0)) return invalid("feed F must be > 0 for G1/G2/G3");
        double length = length_xyz;
        if (opt_.tip_path_length && !path.arc) length = opt_.tip_path_length(path.from, path.to);
        if (!(length > 1e-12)) length = std::hypot(travel[kA], travel[kC]);  // deg at deg/min
        duration = length / (b.feed / 60.0);
      }
      for (std::size_t i = 0; i < kNumAxes; ++i) {
        if (travel[i] == 0 || !(vlim[i] > 0)) continue;
        const double need = travel[i] / vlim[i];
        if (need > duration * (1 + 1e-12)) {
          duration = need;
          res.velocity_limited = b.motion != Motion::kRapid;
        }
      }
      break;
    }
  }

  res.duration = duration;
  line_ = b.line;
  ++stats_.blocks;
  if (res.velocity_limited) ++stats_.velocity_limited_blocks;
  const double t_end = t_block_ + duration;
  // Samples at t = n T inside (t_block_, t_end]; the tolerance keeps a sample that rounding put
  // a hair beyond the end.
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
  while (true) {
    const double t = static_cast<double>(n_ + 1) * T;
    if (t > t_end + 1e-9 * T) break;
    ++n_;
    const double s = duration > 0 ? std::clamp((t - t_block_) / duration, 0.0, 1.0) : 1.0;
    if (!path.arc || s >= 1) {
      emit(path.at(s), sink);
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
    emit(p, sink);
  }
  t_block_ = t_end;
  raw_end_ = path.to;
  return res;
}

void Interpolator::finish(SampleSink& sink) {
  std::size_t need = 0;
  for (const auto& s : smooth_) need = std::max(need, s.settle_samples());
  // Complete the partial period first so the raw clock and the sample clock agree again.
  for (std::size_t i = 0; i < need + 1; ++i) {
    bool all = true;
    for (std::size_t a = 0; a < kNumAxes; ++a) all = all && smooth_[a].settled(raw_end_[a], 1e-9);
    if (all && i > 0) break;
    ++n_;
    emit(raw_end_, sink);
  }
  t_block_ = static_cast<double>(n_) * opt_.period;
}

}  // namespace gcpipe::interpolate
