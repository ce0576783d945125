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

/// Planned sigma at every tick, made tick by tick as the blend asks for it (held whole it was
/// 8 bytes a tick at the planner's peak). A moving step takes the time of a linear speed change
/// between its end speeds (never less than one tick: never faster than the program); a step that
/// does not move (a dwell) keeps its tick. The step times are summed in order, once for the total
/// and again as the ticks pass: the same sums, so the same ticks as a table of them.
class PlannedSigma {
 public:
  PlannedSigma(const RawPath& p, std::vector<double> W, double T, double a) : p_(p), W_(std::move(W)), T_(T), a_(a) {
    const std::size_t S = p.ds.size();
    double t = 0;
    for (std::size_t k = 0; k < S; ++k) t = t + step_time(k);
    end_ = t;
    if (S > 0) t1_ = 0.0 + step_time(0);
    ticks_ = static_cast<std::size_t>(std::ceil(end_ / T - 1e-9)) + 1;
  }
  /// The plan would run past `max_ticks`.
  bool longer_than(double max_ticks) const { return end_ / T_ > max_ticks; }
  /// Ticks of the plan (next() gives each once).
  std::size_t size() const { return ticks_; }
  double next() {
    const std::size_t S = p_.ds.size();
    const double tj = std::min(static_cast<double>(j_++) * T_, end_);
    if (S == 0) return 0.0;
    while (k_ + 1 < S && t1_ <= tj) {
      ++k_;
      t0_ = t1_;
      t1_ = t0_ + step_time(k_);
    }
    const double span = t1_ - t0_;
    const double f = span > 0 ? std::clamp((tj - t0_) / span, 0.0, 1.0) : 1.0;
    return p_.sigma[k_] + f * p_.ds[k_];
  }

 private:
  double step_time(std::size_t k) const {
    double dt = p_.rest[k] ? T_ : 0.0;
    if (p_.ds[k] > kStill) {
      const double v = W_[k] + W_[k + 1];
      dt = std::max(T_, v > 1e-15 ? 2 * p_.ds[k] / v : 2 * std::sqrt(p_.ds[k] / a_));
    }
    return dt;
  }

  const RawPath& p_;
  std::vector<double> W_;  // speed at every raw sample (sample_speeds)
  double T_, a_;
  double end_ = 0;         // the plan's duration [s]
  std::size_t ticks_ = 0;
  std::size_t j_ = 0;      // next tick
  std::size_t k_ = 0;      // raw step of the last tick
  double t0_ = 0, t1_ = 0; // times at which step k_ begins and ends
};

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

/// Ticks where the reference leaves the nominal tool-tip path by more than `tolerance`, and by
/// how much, found with the contour metric itself (the polyline made as the reference reaches it,
/// not held whole: 28 bytes a tick at the planner's peak). Fed the reference tick by tick as the
/// blend makes it, in full precision: the plan's decisions (which ticks pass the tolerance) do not
/// depend on how the reference is then stored.
class Excursions {
 public:
  Excursions(const Model& model, std::span<const ResolvedBlock> program, const Nominal& nom, std::size_t h,
             double tolerance)
      : model_(model), program_(program), nom_(nom), path_(model, nom, program, search_), h_(h), tolerance_(tolerance) {}

  /// Reference tick n (in order) is at joints r, with raw index k its progress.
  void add(const Axes& r, std::size_t k) {
    k = std::min(k, nom_.raw.size() - 1);
    const double length = tool_length_of(model_, program_[nom_.block[k]]);
    // Where the tool length changes (G43 H, G49, a tool change) the nominal tool tip jumps by the
    // change while the joints move on smoothly: a reference blended across the change has no tip
    // on either side's path, and measuring it would slow the plan there without end (a 14 s
    // program planned to 2600 s). Those ticks are not measured; the joints stay the blend's.
    if (tool_length_changes_near(k, length)) return;
    const Vec3 tip = forward_kinematics(model_.kin, r, length).tip;
    const std::size_t limit = path_.index_of_tick(k + h_ + 2);
    path_.fill(std::max<std::size_t>(limit, 1) + 1);  // as the search over a whole polyline takes them
    Vec3 c;
    // Only the ticks beyond the tolerance matter, with their distance: most are found within it
    // near the previous match, without searching the whole window (the same ticks, the same
    // distances beyond it).
    const double e = search_.distance_beyond(tip, limit, tolerance_, c);
    if (e > tolerance_) over_.emplace_back(k, e);
  }
  std::vector<std::pair<std::size_t, double>>& over() { return over_; }

  // The tool length at raw samples k - h and k + h + 2 (the reach of the blend and the search
  // around the reference's progress) differs from `length`, the one at k.
  bool tool_length_changes_near(std::size_t k, double length) const {
    const std::size_t last = nom_.raw.size() - 1;
    for (const std::size_t j : {k > h_ ? k - h_ : 0, std::min(k + h_ + 2, last)})
      if (tool_length_of(model_, program_[nom_.block[j]]) != length) return true;
    return false;
  }

 private:
  const Model& model_;
  std::span<const ResolvedBlock> program_;
  const Nominal& nom_;
  ContourSearch search_;
  NominalPolyline path_;
  std::size_t h_;
  double tolerance_;
  std::vector<std::pair<std::size_t, double>> over_;
};

/// The reference of one plan: sigma smoothed by two moving averages (ma, mb ticks: speed changes
/// become jerk-limited, the path stays exact), the joints at that sigma, then blended by two short
/// moving averages (m1, m2: corners are rounded within the tolerance, arcs shrink by
/// v^2 (T1^2 + T2^2) / 24 R at most). Each stage streams into the next: only the reference and
/// its progress are series. Every reference tick goes to `check` before it is stored.
void blend(const RawPath& p, PlannedSigma& sig, std::size_t ma, std::size_t mb, std::size_t m1,
           std::size_t m2, Nominal& nom, Excursions& check) {
  const std::size_t N = nom.raw.size();
  const std::size_t J = sig.size() + ma - 1 + mb - 1;  // samples of the smoothed sigma
  const std::size_t delay = (m1 - 1) / 2 + (m2 - 1) / 2;
  // The previous plan's series go first (a long program's reference is tens of MB), or are
  // written over where they are long enough: the next round's plan is about as long, and memory
  // freed and taken again in another size leaves holes that stay resident.
  const std::size_t E = J + m1 - 1 + m2 - 1;
  nom.reference.clear_for(E);
  if (nom.progress.capacity() < E) std::vector<std::uint32_t>().swap(nom.progress);
  nom.progress.clear();
  nom.progress.reserve(E);
  TwoAverages<Axes> joint_blend(m1, m2);
  // progress runs `delay` ticks ahead of the reference (below); the reference's last ticks, made
  // past the end of the plan, keep the last progress.
  auto keep_reference = [&nom, &check](const Axes& blended) {
    const std::size_t n = nom.reference.size();
    const Axes& r = n == 0 ? nom.raw.front() : blended;  // exactly at rest where the program starts
    check.add(r, n < nom.progress.size() ? nom.progress[n] : nom.progress.back());
    nom.reference.push_back(r);
  };
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
    const auto whole = static_cast<std::uint32_t>(progress);
    if (nom.progress.empty()) nom.progress.assign(delay, whole);
    nom.progress.push_back(whole);
    joint_blend.push(q, keep_reference);
  };
  TwoAverages<double> speed_smoothing(ma, mb);
  for (std::size_t n = sig.size(); n > 0; --n) speed_smoothing.push(sig.next(), joints_at);
  speed_smoothing.finish(joints_at);
  joint_blend.finish(keep_reference);
  nom.progress.resize(nom.reference.size(), nom.progress.back());
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

namespace {

void plan_rounds(const Model& model, std::span<const ResolvedBlock> program, const ReferencePlan& plan,
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
    PlannedSigma sig(raw, sample_speeds(raw, w, a_sigma, program, nom), T, a_sigma);
    if (sig.longer_than(max_ticks)) {
      nom.reference.release();
      std::vector<std::uint32_t>().swap(nom.progress);
      nom.reference_too_long = true;
      return;
    }
    Excursions check(model, program, nom, spread, plan.tolerance);
    blend(raw, sig, ma, mb, m1, m2, nom, check);
    if (check.over().empty()) return;
    slow_down(raw, check.over(), plan.tolerance, static_cast<double>(ma + mb) * T / 2, h, w);
  }
}

}  // namespace

void plan_reference(const Model& model, std::span<const ResolvedBlock> program, const ReferencePlan& plan,
                    double max_ticks, Nominal& nom) {
  plan_rounds(model, program, plan, max_ticks, nom);
  // The plan was made on the exact raw samples; from here on (the learning, the contour metric,
  // the figures) they are read at the compact series' 0.5 nm, in half the memory.
  nom.raw.compact();
  give_back_freed_memory();
}

}  // namespace gcpipe::simulate
