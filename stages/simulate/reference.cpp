// The compensation's reference: the nominal path planned with look-ahead as a modern control
// plans it, instead of re-timed with a stop at every corner. Derivation and sources:
// stages/compensate/README.md, "Reference".
#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

#include "nominal_path.hpp"
#include "simulate.hpp"

namespace gcpipe::simulate {

namespace {

// The plan works in a joint-space path parameter sigma: each axis's travel divided by its speed
// limit, so that d(sigma)/dt = 1 is every moving axis at most at its limit. Unlike the tool-tip
// arc length it moves on rotary-only moves and stands still in dwells (whose time is kept).
struct RawPath {
  std::vector<double> ds;   //!< N - 1 sigma steps [s at speed limit]
  /// Steps that do not move and where the path rests: a dwell, before the first and after the
  /// last move. Other steps that do not move (a sample repeated where a block ends on a tick)
  /// neither stop the plan nor take time.
  std::vector<std::uint8_t> rest;
  std::vector<double> sigma;  //!< N cumulative sigma
  // The unit directions of the steps are not kept (40 bytes a tick, the largest series of the
  // plan): step_speed_limits, their only user, recomputes them with step_direction().
};

constexpr double kStill = 1e-12;  // a sigma step smaller than this does not move

/// Raw step k (sample k to k + 1) in the scaled joint space: its unit direction (zero when it
/// does not move) and its length, the sigma step.
Axes step_direction(const Model& model, const Nominal& nom, std::size_t k, double& len) {
  Axes d;
  len = 0;
  for (std::size_t i = 0; i < kNumAxes; ++i) {
    const double v = model.interp.max_velocity[i] > 0 ? model.interp.max_velocity[i] : 1.0;
    d[i] = (nom.raw[k + 1][i] - nom.raw[k][i]) / v;
    len += d[i] * d[i];
  }
  len = std::sqrt(len);
  for (std::size_t i = 0; i < kNumAxes; ++i) d[i] = len > kStill ? d[i] / len : 0.0;
  return d;
}

RawPath raw_path(const Model& model, std::span<const ResolvedBlock> program, const Nominal& nom) {
  RawPath p;
  const std::size_t N = nom.raw.size();
  p.sigma.assign(N, 0.0);
  p.ds.reserve(N);
  for (std::size_t k = 0; k + 1 < N; ++k) {
    double len = 0;
    step_direction(model, nom, k, len);
    p.ds.push_back(len);
    p.sigma[k + 1] = p.sigma[k] + len;
  }
  const std::size_t S = p.ds.size();
  p.rest.assign(S, 0);
  std::size_t first = S, last = 0;
  for (std::size_t k = 0; k < S; ++k)
    if (p.ds[k] > kStill) first = std::min(first, k), last = k;
  for (std::size_t k = 0; k < S; ++k) {
    if (p.ds[k] > kStill) continue;
    const ResolvedBlock& b = program[nom.block[k + 1]];
    p.rest[k] = k < first || k > last || b.motion == Motion::kDwell || b.stop != ProgramStop::kNone;
  }
  return p;
}

double chord(const Axes& u, const Axes& v) {
  double s = 0;
  for (std::size_t i = 0; i < kNumAxes; ++i) s += (u[i] - v[i]) * (u[i] - v[i]);
  return std::sqrt(s);
}

/// Sigma-speed limit of every raw step: the programmed speed (never faster than the program),
/// and the acceleration of direction changes. A change of direction of chord |u1 - u2| =
/// 2 sin(phi/2) passed at sigma-speed w jumps the scaled velocity by w |u1 - u2|; the blend's
/// first moving average spreads the jump over T1, so w |u1 - u2| / T1 is held to a_sigma at both
/// ends of the step. On a curve the steps turn a little each and the jumps add up to the
/// centripetal acceleration; at a corner the one jump is rounded within the tolerance, which
/// plan_reference then checks. (A jerk bound for corners, jump / (T1 T2) with the model
/// inverse's Ts, was tried and dropped: it slowed every vertex of a polygonised arc nearly to a
/// stop, the slot to 5.9x its cycle time; the compensation holds back where a limit is hit.)
std::vector<double> step_speed_limits(const Model& model, const Nominal& nom, const RawPath& p, double T, double T1,
                                      double a_sigma) {
  const std::size_t S = p.ds.size();
  // One pass, moving step by moving step: the jump where step k begins is known at k, the jump
  // where the next moving step begins only when that step is reached, so step k's limit is set
  // then (the last moving step has no next jump).
  std::vector<double> w(S, 0.0);
  std::size_t prev = S;  // the previous moving step
  Axes prev_dir{};
  double prev_jump = 0;  // the jump where the previous moving step began
  auto limit = [&](std::size_t k, double jump_begin, double jump_next) {
    const double j = std::max(jump_begin, jump_next);
    w[k] = p.ds[k] / T;
    if (j > 1e-12) w[k] = std::min(w[k], a_sigma * T1 / j);
  };
  for (std::size_t k = 0; k < S; ++k) {
    if (!(p.ds[k] > kStill)) continue;
    double len = 0;
    const Axes dir = step_direction(model, nom, k, len);
    const double jump = prev < S ? chord(prev_dir, dir) : 0.0;
    if (prev < S) limit(prev, prev_jump, jump);
    prev = k, prev_dir = dir, prev_jump = jump;
  }
  if (prev < S) limit(prev, prev_jump, 0.0);
  return w;
}

/// Sigma-speed at every raw sample: zero where the path starts, stops or dwells and where a rapid
/// meets a feed move (controls check in-position there), at most the limits of the steps either
/// side, and reachable with acceleration `a` (a forward and a backward pass over the whole
/// program: the look-ahead of a planner with an unbounded block buffer).
std::vector<double> sample_speeds(const RawPath& p, const std::vector<double>& w, double a,
                                  std::span<const ResolvedBlock> program, const Nominal& nom) {
  const std::size_t N = nom.raw.size();
  std::vector<double> W(N, 0.0);
  for (std::size_t k = 1; k + 1 < N; ++k) {
    const bool rapid_a = program[nom.block[k - 1]].motion == Motion::kRapid;
    const bool rapid_b = program[nom.block[k + 1]].motion == Motion::kRapid;
    if (rapid_a != rapid_b) continue;
    if (p.rest[k - 1] || p.rest[k]) continue;
    const double inf = std::numeric_limits<double>::infinity();
    W[k] = std::min(p.ds[k - 1] > kStill ? w[k - 1] : inf, p.ds[k] > kStill ? w[k] : inf);
  }
  for (std::size_t k = 1; k < N; ++k) W[k] = std::min(W[k], std::sqrt(W[k - 1] * W[k - 1] + 2 * a * p.ds[k - 1]));
  for (std::size_t k = N - 1; k-- > 0;) W[k] = std::min(W[k], std::sqrt(W[k + 1] * W[k + 1] + 2 * a * p.ds[k]));
  return W;
}

/// Planned sigma at every tick. A moving step takes the time of a linear speed change between
/// its end speeds (never less than one tick: never faster than the program); a step that does
/// not move (a dwell) keeps its tick. Empty when the plan would run past `max_ticks`.
std::vector<double> planned_sigma(const RawPath& p, const std::vector<double>& W, double T, double a,
                                  double max_ticks) {
  const std::size_t S = p.ds.size();
  std::vector<double> t(S + 1, 0.0);
  for (std::size_t k = 0; k < S; ++k) {
    double dt = p.rest[k] ? T : 0.0;
    if (p.ds[k] > kStill) {
      const double v = W[k] + W[k + 1];
      dt = std::max(T, v > 1e-15 ? 2 * p.ds[k] / v : 2 * std::sqrt(p.ds[k] / a));
    }
    t[k + 1] = t[k] + dt;
  }
  std::vector<double> sig;
  if (t[S] / T > max_ticks) return sig;
  const auto J = static_cast<std::size_t>(std::ceil(t[S] / T - 1e-9));
  sig.reserve(J + 1);
  std::size_t k = 0;
  for (std::size_t j = 0; j <= J; ++j) {
    const double tj = std::min(static_cast<double>(j) * T, t[S]);
    while (k + 1 < S && t[k + 1] <= tj) ++k;
    if (S == 0) {
      sig.push_back(0.0);
      continue;
    }
    const double span = t[k + 1] - t[k];
    const double f = span > 0 ? std::clamp((tj - t[k]) / span, 0.0, 1.0) : 1.0;
    sig.push_back(p.sigma[k] + f * p.ds[k]);
  }
  return sig;
}

/// Causal moving average of length m, fed one value at a time: held at the first value before
/// the start; push the last value m - 1 more times to run m - 1 ticks past the end. Streaming, so
/// that a chain of averages over a long series holds m values each, not the series between
/// stages (the blend's joint series alone was 40 bytes a tick, twice).
template <class V>
class MovingAverage {
 public:
  explicit MovingAverage(std::size_t m) : m_(m), inv_m_(1.0 / static_cast<double>(m)) {}
  V push(const V& x) {
    if (ring_.empty()) {
      ring_.assign(m_, x);  // before the start: the first value
      sum_ = zero();
      axpy(sum_, static_cast<double>(m_), x);
    }
    axpy(sum_, 1.0, x);
    axpy(sum_, -1.0, ring_[next_]);
    ring_[next_] = x;
    next_ = (next_ + 1) % m_;
    V v = zero();
    axpy(v, inv_m_, sum_);
    return v;
  }

 private:
  static V zero() {
    if constexpr (std::is_same_v<V, double>) return 0.0;
    else return V{};
  }
  static void axpy(V& y, double a, const V& x) {
    if constexpr (std::is_same_v<V, double>) y += a * x;
    else for (std::size_t i = 0; i < kNumAxes; ++i) y[i] += a * x[i];
  }
  std::size_t m_;
  double inv_m_;
  std::vector<V> ring_;  // the last m inputs; ring_[next_] is the oldest
  std::size_t next_ = 0;
  V sum_{};
};

/// Two moving averages in a row (lengths m1, m2) over a series that arrives value by value: each
/// output of the first is fed to the second, and finish() runs both past the end (m1 - 1 and
/// m2 - 1 ticks), as two whole-series averages of lengths in + m1 - 1 and that + m2 - 1 would.
template <class V>
class TwoAverages {
 public:
  TwoAverages(std::size_t m1, std::size_t m2) : a_(m1), b_(m2), m1_(m1), m2_(m2) {}
  template <class Out>
  void push(const V& x, Out&& out) {
    last_in_ = x;
    feed_second(a_.push(x), out);
  }
  template <class Out>
  void finish(Out&& out) {
    for (std::size_t j = 1; j < m1_; ++j) feed_second(a_.push(last_in_), out);
    for (std::size_t j = 1; j < m2_; ++j) out(b_.push(last_mid_));
  }

 private:
  template <class Out>
  void feed_second(const V& mid, Out& out) {
    last_mid_ = mid;
    out(b_.push(mid));
  }
  MovingAverage<V> a_, b_;
  std::size_t m1_, m2_;
  V last_in_{}, last_mid_{};
};

/// Fractional raw index of a sigma value (the first index where several share it: a dwell's
/// samples are one point); `k` carries the search from the previous, never smaller, value.
double index_of_sigma(const RawPath& p, double s, std::size_t& k) {
  const std::size_t N = p.sigma.size();
  while (k + 1 < N && p.sigma[k + 1] <= s) ++k;
  if (k + 1 >= N || !(p.ds[k] > kStill)) return static_cast<double>(k);
  return static_cast<double>(k) + std::clamp((s - p.sigma[k]) / p.ds[k], 0.0, 1.0);
}

/// The reference of one plan: sigma smoothed by two moving averages (ma, mb ticks: speed changes
/// become jerk-limited, the path stays exact), the joints at that sigma, then blended by two short
/// moving averages (m1, m2: corners are rounded within the tolerance, arcs shrink by
/// v^2 (T1^2 + T2^2) / 24 R at most). Each stage streams into the next: only the reference and
/// its progress are series.
void blend(const RawPath& p, const std::vector<double>& sig, std::size_t ma, std::size_t mb, std::size_t m1,
           std::size_t m2, Nominal& nom) {
  const std::size_t N = nom.raw.size();
  const std::size_t J = sig.size() + ma - 1 + mb - 1;  // samples of the smoothed sigma
  const std::size_t delay = (m1 - 1) / 2 + (m2 - 1) / 2;
  // The previous plan's series go first: a long program's reference is tens of MB.
  std::vector<Axes>().swap(nom.reference);
  std::vector<double>().swap(nom.progress);
  nom.reference.reserve(J + m1 - 1 + m2 - 1);
  nom.progress.reserve(J + m1 - 1 + m2 - 1);
  TwoAverages<Axes> joint_blend(m1, m2);
  auto keep_reference = [&nom](const Axes& r) { nom.reference.push_back(r); };
  std::size_t k = 0, j = 0;
  double last = 0;
  auto joints_at = [&](double s) {
    last = std::max(last, index_of_sigma(p, std::max(s, 0.0), k));
    Axes q;
    double progress = last;
    if (++j == J) {
      q = nom.raw.back();  // exactly where the program ends
      progress = static_cast<double>(N - 1);
    } else {
      const auto i0 = std::min(static_cast<std::size_t>(std::floor(last)), N - 1);
      q = lerp(nom.raw[i0], nom.raw[std::min(i0 + 1, N - 1)], last - static_cast<double>(i0));
    }
    // progress[n] is the raw index of the joints the blend centres on at n: delay ticks back.
    if (nom.progress.empty()) nom.progress.assign(delay, progress);
    nom.progress.push_back(progress);
    joint_blend.push(q, keep_reference);
  };
  TwoAverages<double> speed_smoothing(ma, mb);
  for (double s : sig) speed_smoothing.push(s, joints_at);
  speed_smoothing.finish(joints_at);
  joint_blend.finish(keep_reference);
  nom.progress.resize(nom.reference.size(), nom.progress.back());
  nom.reference.front() = nom.raw.front();  // exactly at rest where the program starts
}

/// Ticks where the reference leaves the nominal tool-tip path by more than `tolerance`, and by
/// how much, found with the contour metric itself (the polyline made as the reference reaches it,
/// not held whole: 28 bytes a tick at the planner's peak).
std::vector<std::pair<std::size_t, double>> excursions(const Model& model, std::span<const ResolvedBlock> program,
                                                       const Nominal& nom, std::size_t h, double tolerance) {
  std::vector<std::pair<std::size_t, double>> out;
  ContourSearch search;
  NominalPolyline path(model, nom, program, search);
  const std::size_t N = nom.raw.size();
  for (std::size_t n = 0; n < nom.reference.size(); ++n) {
    const auto k = std::min(static_cast<std::size_t>(nom.progress[n]), N - 1);
    const Vec3 tip = forward_kinematics(model.kin, nom.reference[n], tool_length_of(model, program[nom.block[k]])).tip;
    const std::size_t limit = path.index_of_tick(k + h + 2);
    path.fill(std::max<std::size_t>(limit, 1) + 1);  // as the search over a whole polyline takes them
    Vec3 c;
    const double e = search.distance(tip, limit, c);
    if (e > tolerance) out.emplace_back(k, e);
  }
  return out;
}

/// Lowers the speed limits where the reference left the path: by 0.9 tolerance / deviation
/// (within [0.2, 0.9]), over the sigma the lowered speed covers in `half_span` seconds either
/// side, the reach of the speed smoothing, which averages the speed over that time.
void slow_down(const RawPath& p, const std::vector<std::pair<std::size_t, double>>& over, double tolerance,
               double half_span, std::size_t min_steps, std::vector<double>& w) {
  const std::size_t S = w.size();
  std::vector<double> factor(S, 1.0);
  for (const auto& [k0, e] : over) {
    const std::size_t k = std::min(k0, S - 1);
    const double f = std::clamp(0.9 * tolerance / e, 0.2, 0.9);
    // At least the blend's own reach in raw steps: a deviation shows a few ticks off its cause.
    const double steps = p.sigma[std::min(k + min_steps, S)] - p.sigma[k >= min_steps ? k - min_steps : 0];
    const double reach = std::max(w[k] * f * half_span, steps / 2);
    for (std::size_t j = k; j < S && p.sigma[j] <= p.sigma[k] + reach; ++j) factor[j] = std::min(factor[j], f);
    for (std::size_t j = k; j-- > 0 && p.sigma[j + 1] >= p.sigma[k] - reach;) factor[j] = std::min(factor[j], f);
  }
  for (std::size_t j = 0; j < S; ++j) w[j] *= factor[j];
}

std::size_t ticks(double seconds, double T) {
  return static_cast<std::size_t>(std::max(1.0, std::round(seconds / T)));
}

}  // namespace

void plan_reference(const Model& model, std::span<const ResolvedBlock> program, const ReferencePlan& plan,
                    double max_ticks, Nominal& nom) {
  const double T = nom.period;
  double Ts = 0, a_sigma = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < kNumAxes; ++i) {
    Ts = std::max(Ts, model.interp.smoothing_time[i]);
    const double v = model.interp.max_velocity[i] > 0 ? model.interp.max_velocity[i] : 1.0;
    if (model.interp.max_acceleration[i] > 0) a_sigma = std::min(a_sigma, model.interp.max_acceleration[i] / v);
  }
  a_sigma *= plan.acceleration;
  const std::size_t ma = ticks(plan.smoothing * Ts, T), mb = std::max<std::size_t>(1, ma / 2);
  const std::size_t m1 = ticks(plan.blend_time, T), m2 = std::max<std::size_t>(1, m1 / 2);
  const double T1 = static_cast<double>(m1) * T;
  const std::size_t h = (m1 + m2) / 2 + 1, spread = (ma + mb) / 2 + h;
  const RawPath raw = raw_path(model, program, nom);
  std::vector<double> w = step_speed_limits(model, nom, raw, T, T1, a_sigma);
  // Where the blend still leaves the path by more than the tolerance (a sharp corner taken fast,
  // a tight arc), the speed there is lowered and the plan made again: the deviation of a blended
  // corner grows with the speed, so a few rounds settle it.
  for (int round = 0; round < 8; ++round) {
    const std::vector<double> sig = planned_sigma(raw, sample_speeds(raw, w, a_sigma, program, nom), T, a_sigma, max_ticks);
    if (sig.empty()) {
      nom.reference.clear();
      nom.progress.clear();
      nom.reference_too_long = true;
      return;
    }
    blend(raw, sig, ma, mb, m1, m2, nom);
    const auto over = excursions(model, program, nom, spread, plan.tolerance);
    if (over.empty()) return;
    slow_down(raw, over, plan.tolerance, static_cast<double>(ma + mb) * T / 2, h, w);
  }
}

}  // namespace gcpipe::simulate
