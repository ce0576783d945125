// The compensation's reference: the nominal path planned with look-ahead as a modern control
// plans it, instead of re-timed with a stop at every corner. Derivation and sources:
// stages/compensate/README.md, "Reference".
#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <optional>
#include <type_traits>

#include "nominal_path.hpp"
#include "simulate.hpp"

namespace gcpipe::simulate {

namespace {

// The plan works in a joint-space path parameter sigma: each axis's travel divided by its speed
// limit, so that d(sigma)/dt = 1 is every moving axis at most at its limit. Unlike the tool-tip
// arc length it moves on rotary-only moves and stands still in dwells (whose time is kept).
struct RawPath {
  std::size_t first = 0;     //!< raw index of the path's sample 0 (a chunk of the program)
  bool ends_program = true;  //!< its last sample is the program's last
  std::vector<double> ds;    //!< sigma steps [s at speed limit]: step k from sample first + k
  /// Steps that do not move and where the path rests: a dwell, before the first and after the
  /// last move, a block's end in G61 / G61.1 (the control holds it until in position: the plan
  /// stops there too, and keeps the time). Other steps that do not move (a sample repeated where
  /// a block ends on a tick) neither stop the plan nor take time.
  std::vector<std::uint8_t> rest;
  std::vector<double> sigma;  //!< cumulative sigma at every sample, from the program's start
  /// Per sample: an exact stop of the look-ahead control (interpolate::Control::kLookahead): the
  /// last sample of a rapid or of a G61 / G61.1 / G09 block. The plan comes to rest there and
  /// stands still long enough for its smoothing to stand still too (PlanSettings::hold).
  std::vector<std::uint8_t> stop;
  // The unit directions of the steps are not kept (40 bytes a tick, the largest series of the
  // plan): step_speed_limits, their only user, recomputes them with step_direction().
  std::size_t samples() const { return sigma.size(); }
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

/// The first and the last raw step that moves (first > last when none does): where the program's
/// path begins and ends to rest.
struct MovingSteps {
  std::size_t first, last;
};

MovingSteps moving_steps(const Model& model, const Nominal& nom) {
  const std::size_t S = nom.raw.size() - 1;
  MovingSteps m{S, 0};
  for (std::size_t k = 0; k < S; ++k) {
    double len = 0;
    step_direction(model, nom, k, len);
    if (len > kStill) m.first = std::min(m.first, k), m.last = k;
  }
  return m;
}

/// Raw sample g ends a block after which the look-ahead control stops exactly: a rapid (LinuxCNC
/// and Fanuc position with G0 and check in-position before the next block) or a block in G61 /
/// G61.1 (G09 is resolved as one G61 block).
bool exact_stop_at(const Nominal& nom, std::size_t g) {
  if (g + 1 >= nom.raw.size() || nom.block[g] == nom.block[g + 1]) return false;
  const BlockBrief& b = nom.brief[nom.block[g]];
  return b.motion == Motion::kRapid || b.path_mode != PathMode::kBlend;
}

/// The path from raw sample `first` to `last` (inclusive), its sigma counted on from `sigma0`
/// (the sigma at `first`: the same sums in the same order as over the whole program).
RawPath raw_path(const Model& model, const Nominal& nom, std::size_t first,
                 std::size_t last, double sigma0, const MovingSteps& moving) {
  RawPath p;
  p.first = first;
  p.ends_program = last + 1 == nom.raw.size();
  const std::size_t n = last - first + 1;
  p.sigma.assign(n, 0.0);
  p.sigma[0] = sigma0;
  p.ds.reserve(n - 1);
  for (std::size_t k = 0; k + 1 < n; ++k) {
    double len = 0;
    step_direction(model, nom, first + k, len);
    p.ds.push_back(len);
    p.sigma[k + 1] = p.sigma[k] + len;
  }
  const std::size_t S = p.ds.size();
  p.rest.assign(S, 0);
  for (std::size_t k = 0; k < S; ++k) {
    if (p.ds[k] > kStill) continue;
    const std::size_t g = first + k;
    const BlockBrief& b = nom.brief[nom.block[g + 1]];
    p.rest[k] = g < moving.first || g > moving.last || b.motion == Motion::kDwell || b.stop != ProgramStop::kNone ||
                b.path_mode != PathMode::kBlend;
  }
  p.stop.assign(n, 0);
  if (model.interp.control == interpolate::Control::kLookahead)
    for (std::size_t k = 0; k < n; ++k) p.stop[k] = exact_stop_at(nom, first + k);
  return p;
}

/// The direction of the nearest raw step that moves, from step `from` on backwards (or
/// forwards); false when there is none.
bool moving_direction(const Model& model, const Nominal& nom, std::size_t from, bool backwards, Axes& dir) {
  const std::size_t S = nom.raw.size() - 1;
  auto moves = [&](std::size_t g) {
    double len = 0;
    dir = step_direction(model, nom, g, len);
    return len > kStill;
  };
  if (backwards) {
    for (std::size_t g = from; g-- > 0;)
      if (moves(g)) return true;
  } else {
    for (std::size_t g = from; g < S; ++g)
      if (moves(g)) return true;
  }
  return false;
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
  // then (the last moving step has no next jump). A chunk of the program measures its first jump
  // from the moving step before it and its last from the one after it: the same limits as over
  // the whole program.
  std::vector<double> w(S, 0.0);
  std::size_t prev = S;  // the previous moving step of the chunk
  Axes prev_dir{};
  bool have_prev = moving_direction(model, nom, p.first, true, prev_dir);
  double prev_jump = 0;  // the jump where the previous moving step began
  // The look-ahead control's plan is the machine's command: a rapid at an axis's velocity limit
  // would step by exactly v T, and the compact reference (float offsets, joint_series.hpp) rounds
  // a step by up to about 1e-5 of it, past the limit (C by 3.8e-6 on five_axis_demo). It plans
  // 1e-4 below the programmed speed: 0.01 % of the time.
  const double fastest = model.interp.control == interpolate::Control::kLookahead ? 1 - 1e-4 : 1.0;
  auto limit = [&](std::size_t k, double jump_begin, double jump_next) {
    const double j = std::max(jump_begin, jump_next);
    w[k] = fastest * p.ds[k] / T;
    if (j > 1e-12) w[k] = std::min(w[k], a_sigma * T1 / j);
  };
  for (std::size_t k = 0; k < S; ++k) {
    if (!(p.ds[k] > kStill)) continue;
    double len = 0;
    const Axes dir = step_direction(model, nom, p.first + k, len);
    const double jump = have_prev ? chord(prev_dir, dir) : 0.0;
    if (prev < S) limit(prev, prev_jump, jump);
    prev = k, prev_dir = dir, prev_jump = jump, have_prev = true;
  }
  Axes next_dir{};
  if (prev < S)
    limit(prev, prev_jump, moving_direction(model, nom, p.first + S, false, next_dir) ? chord(prev_dir, next_dir) : 0.0);
  return w;
}

/// Sigma-speed at every raw sample: zero where the path starts, stops or dwells and where a rapid
/// meets a feed move (controls check in-position there), at most the limits of the steps either
/// side, and reachable with acceleration `a` (a forward and a backward pass over the whole
/// program: the look-ahead of a planner with an unbounded block buffer).
std::vector<double> sample_speeds(const RawPath& p, const std::vector<double>& w, double a,
                                  const Nominal& nom, std::size_t from,
                                  double seed, std::size_t keep, double& forward_at_keep) {
  const std::size_t n = p.samples();
  std::vector<double> W(n, 0.0);
  for (std::size_t k = from + 1; k + 1 < n; ++k) {
    const std::size_t g = p.first + k;
    const bool rapid_a = nom.brief[nom.block[g - 1]].motion == Motion::kRapid;
    const bool rapid_b = nom.brief[nom.block[g + 1]].motion == Motion::kRapid;
    if (rapid_a != rapid_b) continue;
    if (p.rest[k - 1] || p.rest[k] || p.stop[k]) continue;
    const double inf = std::numeric_limits<double>::infinity();
    W[k] = std::min(p.ds[k - 1] > kStill ? w[k - 1] : inf, p.ds[k] > kStill ? w[k] : inf);
  }
  // A chunk is planned from sample `from` on, at the speed the forward pass of the chunk before
  // reached there (0: the program at rest), and ends, unless the program does, at its last
  // step's limit: its margin past what it commits is longer than a backward pass reaches back.
  W[from] = seed;
  if (!p.ends_program && n >= 2) W[n - 1] = p.ds[n - 2] > kStill ? w[n - 2] : 0.0;
  for (std::size_t k = from + 1; k < n; ++k) W[k] = std::min(W[k], std::sqrt(W[k - 1] * W[k - 1] + 2 * a * p.ds[k - 1]));
  forward_at_keep = W[std::min(keep, n - 1)];
  for (std::size_t k = n - 1; k-- > from;) W[k] = std::min(W[k], std::sqrt(W[k + 1] * W[k + 1] + 2 * a * p.ds[k]));
  return W;
}

/// Planned sigma at every tick, made tick by tick as the blend asks for it (held whole it was
/// 8 bytes a tick at the planner's peak). A moving step takes the time of a linear speed change
/// between its end speeds (never less than one tick: never faster than the program); a step that
/// does not move (a dwell) keeps its tick. The step times are summed in order, once for the total
/// and again as the ticks pass: the same sums, so the same ticks as a table of them. A chunk of
/// the program begins at the time `t_start` the chunk before reached its first step, with the
/// program's tick `first_tick`.
class PlannedSigma {
 public:
  PlannedSigma(const RawPath& p, std::vector<double> W, double T, double a, double hold, std::size_t from = 0,
               double t_start = 0, std::size_t first_tick = 0, std::size_t commit_step = SIZE_MAX)
      : p_(p), W_(std::move(W)), T_(T), a_(a), hold_(hold), j_(first_tick), k_(from), t0_(t_start) {
    const std::size_t S = p.ds.size();
    double t = t_start;
    commit_time_ = std::numeric_limits<double>::infinity();
    for (std::size_t k = from; k < S; ++k) {
      if (k == commit_step) commit_time_ = t;
      t = t + step_time(k);
    }
    end_ = t;
    t1_ = from < S ? t_start + step_time(from) : t_start;
    ticks_ = static_cast<std::size_t>(std::ceil(end_ / T - 1e-9)) + 1;
  }
  /// The plan would run past `max_ticks`.
  bool longer_than(double max_ticks) const { return end_ / T_ > max_ticks; }
  /// Ticks of the program's plan up to the path's end (next() gives each once): the whole
  /// plan's when the path ends the program.
  std::size_t size() const { return ticks_; }
  /// The program's tick next() gives next, and its time.
  std::size_t next_tick() const { return j_; }
  double next_time() const { return static_cast<double>(j_) * T_; }
  /// When the path's `commit_step` begins, and its last step ends [s].
  double commit_time() const { return commit_time_; }
  double end_time() const { return end_; }
  double next() {
    const std::size_t S = p_.ds.size();
    const double tj = std::min(static_cast<double>(j_++) * T_, end_);
    if (k_ >= S) return p_.sigma.empty() ? 0.0 : p_.sigma[std::min(k_, p_.sigma.size() - 1)];
    while (k_ + 1 < S && t1_ <= tj) {
      ++k_;
      t0_ = t1_;
      t1_ = t0_ + step_time(k_);
    }
    // An exact stop stands still for its hold at the start of the step that leaves it.
    const double h = p_.stop[k_] ? hold_ : 0.0;
    const double span = t1_ - t0_ - h;
    const double f = span > 0 ? std::clamp((tj - t0_ - h) / span, 0.0, 1.0) : 1.0;
    return p_.sigma[k_] + f * p_.ds[k_];
  }

 private:
  double step_time(std::size_t k) const {
    double dt = (p_.rest[k] ? T_ : 0.0) + (p_.stop[k] ? hold_ : 0.0);
    if (p_.ds[k] > kStill) {
      const double v = W_[k] + W_[k + 1];
      dt = std::max(T_, v > 1e-15 ? 2 * p_.ds[k] / v : 2 * std::sqrt(p_.ds[k] / a_)) + (p_.stop[k] ? hold_ : 0.0);
    }
    return dt;
  }

  const RawPath& p_;
  std::vector<double> W_;  // speed at every raw sample (sample_speeds)
  double T_, a_;
  double hold_;            // [s] an exact stop stands still this long (PlanSettings::hold)
  double end_ = 0;         // when the path's last step ends [s]
  double commit_time_ = 0;
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

/// Fractional raw index (of the program) of a sigma value (the first index where several share
/// it: a dwell's samples are one point); `k` carries the search (a sample of the path) from the
/// previous, never smaller, value.
double index_of_sigma(const RawPath& p, double s, std::size_t& k) {
  const std::size_t N = p.sigma.size();
  while (k + 1 < N && p.sigma[k + 1] <= s) ++k;
  const double g = static_cast<double>(p.first + k);  // (the program's index first: the same double as one plan's)
  if (k + 1 >= N || !(p.ds[k] > kStill)) return g;
  return g + std::clamp((s - p.sigma[k]) / p.ds[k], 0.0, 1.0);
}

/// Ticks where the reference leaves the nominal tool-tip path by more than `tolerance`, and by
/// how much, found with the contour metric itself (the polyline made as the reference reaches it,
/// not held whole: 28 bytes a tick at the planner's peak). Fed the reference tick by tick as the
/// blend makes it, in full precision: the plan's decisions (which ticks pass the tolerance) do not
/// depend on how the reference is then stored.
class Excursions {
 public:
  /// The polyline from raw tick `first_tick` on: a chunk of the plan measures from far enough
  /// back to hold the points its reference may still be near (ContourMeter's look-back).
  Excursions(const Model& model, const Nominal& nom, std::size_t h, double tolerance, std::size_t first_tick = 0)
      : model_(model), nom_(nom), path_(model, nom, search_, first_tick), h_(h),
        tolerance_(tolerance) {}

  /// Reference tick n (in order) is at joints r, with raw index k its progress.
  void add(const Axes& r, std::size_t k) {
    k = std::min(k, nom_.raw.size() - 1);
    if (model_.interp.control == interpolate::Control::kLookahead) check_acceleration(r, k);
    const double length = tool_length_of(model_, nom_.brief[nom_.block[k]]);
    // Where the tool length changes (G43 H, G49, a tool change) the nominal tool tip jumps by the
    // change while the joints move on smoothly: a reference blended across the change has no tip
    // on either side's path, and measuring it would slow the plan there without end (a 14 s
    // program planned to 2600 s). Those ticks are not measured; the joints stay the blend's.
    if (tool_length_changes_near(k, length)) return;
    const Vec3 tip = forward_kinematics(model_.kin, r, length).tip;
    const std::size_t limit = path_.index_of_tick(k + h_ + 2);
    path_.fill(std::max<std::size_t>(limit, 1) + 1);  // as the search over a whole polyline takes them
    Vec3 c;
    // The program's own G64 P where it has one, else the config's.
    const double given = nom_.brief[nom_.block[k]].path_tolerance;
    const double tolerance = given > 0 ? given : tolerance_;
    // Only the ticks beyond the tolerance matter, with their distance: most are found within it
    // near the previous match, without searching the whole window (the same ticks, the same
    // distances beyond it). A deviation is kept in units of the config's tolerance, which the
    // slow-down is reckoned in.
    const double e = search_.distance_beyond(tip, limit, tolerance, c);
    if (e > tolerance) over_.emplace_back(k, e * (tolerance_ / tolerance));
  }
  std::vector<std::pair<std::size_t, double>>& over() { return over_; }

  /// The look-ahead control's commands are its plan: no axis may accelerate beyond its limit. The
  /// corner speed rule bounds the blend's jump, but smoothing the speed profile fills the dip at a
  /// corner from both sides (a reversal at the end of a line into an arc asked X for 7237 mm/s^2,
  /// limit 5050). Such a tick is an excursion whose slow-down is sqrt(limit / acceleration) (on a
  /// fixed path the acceleration goes with the square of the speed), times slow_down's 0.9.
  void check_acceleration(const Axes& r, std::size_t k) {
    const double T = model_.interp.period;
    if (seen_ >= 2) {
      double ratio = 0;
      for (std::size_t i = 0; i < kNumAxes; ++i)
        if (model_.interp.max_acceleration[i] > 0)
          ratio = std::max(ratio, std::abs(r[i] - 2 * r1_[i] + r2_[i]) / (T * T) / model_.interp.max_acceleration[i]);
      if (ratio > 1.0) over_.emplace_back(k, tolerance_ * std::sqrt(ratio));
    }
    r2_ = r1_, r1_ = r, ++seen_;
  }

  // The tool length at raw samples k - h and k + h + 2 (the reach of the blend and the search
  // around the reference's progress) differs from `length`, the one at k.
  bool tool_length_changes_near(std::size_t k, double length) const {
    const std::size_t last = nom_.raw.size() - 1;
    for (const std::size_t j : {k > h_ ? k - h_ : 0, std::min(k + h_ + 2, last)})
      if (tool_length_of(model_, nom_.brief[nom_.block[j]]) != length) return true;
    return false;
  }

 private:
  const Model& model_;
  const Nominal& nom_;
  ContourSearch search_;
  NominalPolyline path_;
  std::size_t h_;
  double tolerance_;
  std::vector<std::pair<std::size_t, double>> over_;
  Axes r1_{}, r2_{};      // the two ticks before (check_acceleration)
  std::size_t seen_ = 0;  // ticks seen
};

/// The reference made from planned sigma, tick by tick: sigma smoothed by two moving averages
/// (ma, mb ticks: speed changes become jerk-limited, the path stays exact), the joints at that
/// sigma, then blended by two short moving averages (m1, m2: corners are rounded within the
/// tolerance, arcs shrink by v^2 (T1^2 + T2^2) / 24 R at most). Each stage streams into the next,
/// and the whole state is a few rings of values: a copy taken where a chunk of the plan ends is
/// where the next chunk goes on from, and where a round of the chunk's plan starts again.
class ReferenceBlend {
 public:
  ReferenceBlend(std::size_t ma, std::size_t mb, std::size_t m1, std::size_t m2)
      : speed_(ma, mb), joints_(m1, m2), delay_((m1 - 1) / 2 + (m2 - 1) / 2), tail_(ma - 1 + mb - 1) {}

  /// Where the made ticks go: the reference joints (each seen by `check` first, in full
  /// precision: the plan's decisions do not depend on how the reference is stored) and their
  /// progress (the whole raw index the blend centres on).
  struct Out {
    JointSeries& reference;
    ScratchArray<std::uint32_t>& progress;
    Excursions& check;
  };

  /// The next tick's planned sigma; `total_ticks`: the plan's tick count when `p` ends the program (its last smoothed sample is exactly the program's end).
  void push(double sigma, const RawPath& p, const Nominal& nom, std::size_t total_ticks, Out out) {
    speed_.push(sigma, [&](double s) { joints_at(s, p, nom, total_ticks, out); });
  }
  /// Runs the averages past the program's end.
  void finish(const RawPath& p, const Nominal& nom, std::size_t total_ticks, Out out) {
    speed_.finish([&](double s) { joints_at(s, p, nom, total_ticks, out); });
    joints_.finish([&](const Axes& q) { keep(q, nom, out); });
  }
  /// The raw index (whole) the reference has reached.
  std::size_t progress() const { return static_cast<std::size_t>(last_); }

 private:
  void joints_at(double s, const RawPath& p, const Nominal& nom, std::size_t total_ticks, Out& out) {
    const std::size_t N = nom.raw.size();
    std::size_t k = k_ > p.first ? k_ - p.first : 0;  // the search, as a sample of this path
    last_ = std::max(last_, index_of_sigma(p, std::max(s, 0.0), k));
    k_ = p.first + k;
    Axes q;
    double progress = last_;
    if (++j_ == total_ticks + tail_) {
      q = nom.raw.back();  // exactly where the program ends
      progress = static_cast<double>(N - 1);
    } else {
      const auto i0 = std::min(static_cast<std::size_t>(std::floor(last_)), N - 1);
      q = lerp(nom.raw[i0], nom.raw[std::min(i0 + 1, N - 1)], last_ - static_cast<double>(i0));
    }
    // The progress of reference tick n is the raw index of the joints the blend centres on at
    // n: `delay` ticks back. The reference's last ticks, made past the end of the plan, keep the
    // last progress.
    const auto whole = static_cast<std::uint32_t>(progress);
    if (!started_) ahead_.assign(delay_, whole), started_ = true;
    ahead_.push_back(whole);
    joints_.push(q, [&](const Axes& blended) { keep(blended, nom, out); });
  }

  void keep(const Axes& blended, const Nominal& nom, Out& out) {
    const Axes& r = made_ == 0 ? nom.raw.front() : blended;  // exactly at rest where the program starts
    if (!ahead_.empty()) last_progress_ = ahead_.front(), ahead_.pop_front();
    out.check.add(r, last_progress_);
    out.reference.push_back(r);
    out.progress.push_back(last_progress_);
    ++made_;
  }

  TwoAverages<double> speed_;
  TwoAverages<Axes> joints_;
  std::size_t delay_, tail_;
  std::size_t k_ = 0;        // raw index of index_of_sigma's search
  double last_ = 0;          // furthest fractional raw index reached
  std::size_t j_ = 0;        // smoothed sigma samples made
  std::size_t made_ = 0;     // reference ticks made
  bool started_ = false;
  std::deque<std::uint32_t> ahead_;  // progress of the joints pushed and not yet blended out
  std::uint32_t last_progress_ = 0;
};

/// Lowers the speed limits where the reference left the path: by 0.9 tolerance / deviation
/// (within [0.2, 0.9]), over the sigma the lowered speed covers in `half_span` seconds either
/// side, the reach of the speed smoothing, which averages the speed over that time.
void slow_down(const RawPath& p, const std::vector<std::pair<std::size_t, double>>& over, double tolerance,
               double half_span, std::size_t min_steps, std::vector<double>& w) {
  const std::size_t S = w.size();
  std::vector<double> factor(S, 1.0);
  for (const auto& [g, e] : over) {
    const std::size_t k = std::min(g > p.first ? g - p.first : 0, S - 1);
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

// The plan's constants from the model and the `compensate` section.
struct PlanSettings {
  double T, a_sigma, T1, half_span, tolerance;
  /// [s] an exact stop stands still in the planned sigma: the span of the speed smoothing and the
  /// blend, so that the reference itself stands still there for a few ticks (the look-ahead
  /// control's in-position check then holds it until the drives are there, simulate.cpp).
  double hold;
  std::size_t ma, mb, m1, m2, h, spread;
};

PlanSettings plan_settings(const Model& model, const ReferencePlan& plan, double T) {
  double Ts = 0, a_sigma = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < kNumAxes; ++i) {
    Ts = std::max(Ts, model.interp.smoothing_time[i]);
    const double v = model.interp.max_velocity[i] > 0 ? model.interp.max_velocity[i] : 1.0;
    if (model.interp.max_acceleration[i] > 0) a_sigma = std::min(a_sigma, model.interp.max_acceleration[i] / v);
  }
  PlanSettings s;
  s.T = T;
  s.a_sigma = a_sigma * plan.acceleration;
  // The look-ahead control blends within its own tolerance (interpolate.path_tolerance): its
  // plan is the reference. Under seed 002's control the reference is the compensation's own.
  s.tolerance = model.interp.control == interpolate::Control::kLookahead ? model.interp.path_tolerance : plan.tolerance;
  s.ma = ticks(plan.smoothing * Ts, T), s.mb = std::max<std::size_t>(1, s.ma / 2);
  s.m1 = ticks(plan.blend_time, T), s.m2 = std::max<std::size_t>(1, s.m1 / 2);
  s.T1 = static_cast<double>(s.m1) * T;
  s.h = (s.m1 + s.m2) / 2 + 1, s.spread = (s.ma + s.mb) / 2 + s.h;
  s.half_span = static_cast<double>(s.ma + s.mb) * T / 2;
  s.hold = static_cast<double>(s.ma + s.mb + s.m1 + s.m2 + 4) * T;
  return s;
}

/// The last raw sample a chunk committing samples up to `k1` plans to: at least `min_margin`
/// samples on, and far enough that a backward speed pass from past it could not reach `k1` nor a
/// slow-down in the margin's far part (where the cut look-ahead leaves speeds too high): twice
/// the braking distance 2 v^2 / (2 a_sigma) of the fastest the program moves in the margin.
std::size_t margin_end(const Model& model, const Nominal& nom, std::size_t k1, std::size_t min_margin, double a_sigma,
                       double T) {
  const std::size_t last = nom.raw.size() - 1;
  double sigma = 0, v_max = 0;
  std::size_t k = k1 > 0 ? k1 - 1 : 0;
  for (; k < last; ++k) {
    double len = 0;
    step_direction(model, nom, k, len);
    v_max = std::max(v_max, len / T);
    if (k >= k1) sigma += len;
    if (k >= k1 + min_margin && 2 * a_sigma * sigma > 2 * v_max * v_max) return k + 1;
  }
  return last;
}

/// The reference planned chunk by chunk (ReferencePlan::chunk_seconds of the program as the
/// control runs it, plus a margin): per chunk only its raw steps' sigma, limits and speeds are
/// held, not the program's. A chunk goes on from the state in which the one before left the
/// plan at the step it committed up to (the blend's rings, the time, the forward speed, the
/// slow-downs of the steps after it), so that without slow-downs the chunks plan what one plan of
/// the whole program would, tick for tick. The rounds that lower the speed where the blend leaves
/// the path by more than the tolerance run per chunk, over its margin too. One chunk a call
/// (next()): what a learning that asks for the reference as it goes would drive.
class ChunkedPlan {
 public:
  ChunkedPlan(const Model& model, const ReferencePlan& plan, double max_ticks, Nominal& nom)
      : model_(model), c_(plan_settings(model, plan, nom.period)), caps_(plan.caps), max_ticks_(max_ticks), nom_(nom),
        N_(nom.raw.size()), moving_(moving_steps(model, nom)), chunk_(ticks(plan.chunk_seconds, c_.T)),
        min_margin_(ticks(2.0, c_.T)), state_(c_.ma, c_.mb, c_.m1, c_.m2) {
    // The reference and its progress grow in scratch arrays (gcpipe/scratch.hpp), which never
    // copy to grow: no room is reserved (with a reservation for max_machine_time the one-hour
    // program peaked at 70 MB with that bound at 7300 s against 56 MB at 3600 s, twice each; the
    // spread between runs is up to 10 MB, so the cost is measured only roughly).
    nom.reference.release();
    nom.progress.release();
  }

  /// Plans the next chunk and commits its reference ticks; false once the program's end is
  /// planned (or the plan runs past max_ticks: Nominal::reference_too_long).
  bool next() {
    const std::size_t k1 = std::min(k0_ + chunk_, N_ - 1);
    const std::size_t k2 = k1 == N_ - 1 ? N_ - 1 : margin_end(model_, nom_, k1, min_margin_, c_.a_sigma, c_.T);
    const std::size_t first = lead_in_start();
    RawPath p = raw_path(model_, nom_, first, k2, k0_ == 0 ? 0.0 : prev_.sigma[first - prev_.first], moving_);
    Chunk ch{k0_ - first, k1 - first, p.ends_program && k1 == N_ - 1};
    std::vector<double> w = step_speed_limits(model_, nom_, p, c_.T, c_.T1, c_.a_sigma);
    apply_caps(p, w);
    std::copy_n(carried_w_.begin(), std::min(carried_w_.size(), w.size() - ch.from), w.begin() + static_cast<std::ptrdiff_t>(ch.from));
    const std::size_t made = nom_.reference.size();  // ticks the chunks before committed
    Round r;
    // Where the blend still leaves the path by more than the tolerance (a sharp corner taken
    // fast, a tight arc), the speed there is lowered and the chunk planned again: the deviation
    // of a blended corner grows with the speed, so a few rounds settle it.
    for (int round = 0; round < 8; ++round) {
      nom_.reference.truncate(made);  // a round writes over the round before
      nom_.progress.resize(made);
      if (!plan_round(p, ch, w, r)) return false;
      if (r.over.empty()) break;
      if (round < 7) slow_down(p, r.over, c_.tolerance, c_.half_span, c_.h, w);
    }
    nom_.reference.truncate(r.committed);  // the margin's ticks are the next chunk's to make
    nom_.progress.resize(r.committed);
    if (ch.last || !r.next) return false;
    go_on_from(r, std::move(p), std::move(w), ch.commit, k1);
    return true;
  }

 private:
  // The plan's own slow-downs (ReferencePlan::caps) on the chunk's steps; the steps carried from
  // the chunk before are overwritten by their limits there, which had them already.
  void apply_caps(const RawPath& p, std::vector<double>& w) const {
    for (const ReferencePlan::SpeedCap& c : caps_)
      for (std::size_t g = std::max(c.first, p.first); g <= c.last && g < p.first + w.size(); ++g) w[g - p.first] *= c.factor;
  }

  // The first raw sample of the next chunk's path: its first planned sample less the samples the
  // smoothed sigma may still be behind it (the speed smoothing's lag).
  std::size_t lead_in_start() const {
    const std::size_t lead = 2 * (c_.ma + c_.mb) + 64;
    return k0_ > lead ? k0_ - lead : 0;
  }
  static constexpr std::size_t kLookBack = ContourSearch::kLookBack + 500;  // the excursions' polyline

  struct Chunk {
    std::size_t from, commit;  // samples of the path: the chunk's first, and the one it commits up to
    bool last;                 // the chunk ends the program
  };
  // One round of a chunk: where the blend left the path, and (not the last chunk) the state at
  // the commit step, the reference ticks made before it and what the next chunk starts from.
  struct Round {
    std::vector<std::pair<std::size_t, double>> over;
    std::optional<ReferenceBlend> next;
    std::size_t committed = 0, next_tick = 0;
    double commit_time = 0, forward_at_commit = 0;
  };

  /// The chunk's reference with limits `w`, from the committed state; false when the plan runs
  /// past max_ticks.
  bool plan_round(const RawPath& p, const Chunk& ch, const std::vector<double>& w, Round& r) {
    PlannedSigma sig(p, sample_speeds(p, w, c_.a_sigma, nom_, ch.from, seed_, ch.commit, r.forward_at_commit),
                     c_.T, c_.a_sigma, c_.hold, ch.from, t0_, tick0_, ch.last ? SIZE_MAX : ch.commit);
    if (sig.longer_than(max_ticks_)) {
      nom_.reference.release();
      nom_.progress.release();
      nom_.reference_too_long = true;
      return false;
    }
    ReferenceBlend blend = state_;
    Excursions check(model_, nom_, c_.spread, c_.tolerance,
                     blend.progress() > kLookBack ? blend.progress() - kLookBack : 0);
    const ReferenceBlend::Out out{nom_.reference, nom_.progress, check};
    r.next.reset();
    if (ch.last) {
      const std::size_t total = sig.size();
      for (std::size_t n = total - std::min(tick0_, total); n > 0; --n) blend.push(sig.next(), p, nom_, total, out);
      blend.finish(p, nom_, total, out);
      r.committed = nom_.reference.size();
    } else {
      constexpr std::size_t kNotLast = SIZE_MAX / 4;  // the program's end is not in this chunk
      while (sig.next_time() < sig.end_time()) {
        if (!r.next && sig.next_time() >= sig.commit_time()) {
          r.next = blend, r.committed = nom_.reference.size(), r.next_tick = sig.next_tick();
          r.commit_time = sig.commit_time();
        }
        blend.push(sig.next(), p, nom_, kNotLast, out);
      }
    }
    r.over = std::move(check.over());
    return true;
  }

  /// The next chunk starts at raw sample k1 from the accepted round's state there.
  void go_on_from(Round& r, RawPath p, std::vector<double> w, std::size_t commit, std::size_t k1) {
    state_ = std::move(*r.next);
    tick0_ = r.next_tick;
    t0_ = r.commit_time;
    seed_ = r.forward_at_commit;
    carried_w_.assign(w.begin() + static_cast<std::ptrdiff_t>(commit), w.end());
    k0_ = k1;
    prev_ = std::move(p);
    // The raw samples the next chunks will not read again (its lead-in, its polyline's look-back
    // and some) are read compact from here on, as the learning reads them: the planner's peak is
    // not the program's exact samples beside its whole reference.
    const std::size_t reach = std::min(lead_in_start(), state_.progress());
    nom_.raw.compact_before(reach > kLookBack + 1000 ? reach - kLookBack - 1000 : 0);
  }

  const Model& model_;
  const PlanSettings c_;
  std::vector<ReferencePlan::SpeedCap> caps_;
  double max_ticks_;
  Nominal& nom_;
  std::size_t N_;
  MovingSteps moving_;
  std::size_t chunk_, min_margin_;
  // Where the next chunk goes on from.
  ReferenceBlend state_;
  std::size_t k0_ = 0, tick0_ = 0;  // its first raw sample, its first tick
  double t0_ = 0, seed_ = 0;        // the time its first step begins, the forward speed there
  RawPath prev_;                    // the chunk before (its sigma: where the next one's starts)
  std::vector<double> carried_w_;   // its limits of the steps from k0 on, slow-downs included
};

}  // namespace

void plan_reference(const Model& model, const ReferencePlan& plan, double max_ticks, Nominal& nom) {
  ChunkedPlan chunks(model, plan, max_ticks, nom);
  while (chunks.next()) {
  }
  // The plan was made on the exact raw samples; from here on (the learning, the contour metric,
  // the figures) they are read at the compact series' 0.5 nm, in half the memory.
  nom.raw.compact();
  give_back_freed_memory();
}

}  // namespace gcpipe::simulate
