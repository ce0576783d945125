#include "compensate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>
#include <stdexcept>

#include "chain_inverse.hpp"
#include "contour.hpp"
#include "gcpipe/config.hpp"

namespace gcpipe::compensate {


CompensateOptions load_compensate_options(const Config& s) {
  s.reject_unknown({"enabled", "node_period", "path_tolerance", "blend_time", "reference_acceleration", "reference_smoothing", "linearisation_tolerance", "max_iterations", "gain",
                    "max_machine_time", "max_blocks", "slowed_baseline", "slow_for_drive_limits", "work_frame"});
  CompensateOptions o;
  o.enabled = s.boolean("enabled", o.enabled);
  o.node_period = s.number("node_period", o.node_period, "s", 1e-4, 0.1);
  o.reference.tolerance = s.number("path_tolerance", o.reference.tolerance, "mm", 1e-5, 1.0);
  o.reference.blend_time = s.number("blend_time", o.reference.blend_time, "s", 0.002, 0.2);
  o.reference.acceleration = s.number("reference_acceleration", o.reference.acceleration, "", 0.05, 1.0);
  o.reference.smoothing = s.number("reference_smoothing", o.reference.smoothing, "x Ts", 0.5, 10.0);
  o.linearisation_tolerance = s.number("linearisation_tolerance", o.linearisation_tolerance, "mm", 1e-6, 1.0);
  o.max_iterations = static_cast<int>(s.integer("max_iterations", o.max_iterations, 0, 1000));
  o.gain = s.number("gain", o.gain, "", 0.01, 1.0);
  o.max_machine_time = s.number("max_machine_time", o.max_machine_time, "s", 1, 1e6);
  o.max_blocks = static_cast<std::uint64_t>(s.integer("max_blocks", static_cast<std::int64_t>(o.max_blocks), 1, 100000000));
  o.slowed_baseline = s.boolean("slowed_baseline", o.slowed_baseline);
  o.slow_for_drive_limits = s.boolean("slow_for_drive_limits", o.slow_for_drive_limits);
  o.work_frame = s.boolean("work_frame", o.work_frame);
  return o;
}

simulate::RunBounds run_bounds(const CompensateOptions& o) {
  simulate::RunBounds b;
  b.plan = o.reference;
  b.max_machine_time = o.max_machine_time;
  return b;
}

// ---------------------------------------------------------------------------------------------

namespace {

/// The block of a node program that moves from `from` to `to` in `ticks` periods: G93 G1 in
/// machine axes, with the modal state of the source block `src`.
void node_block(const ResolvedBlock& src, const Axes& from, const Axes& to, std::uint64_t ticks, double period,
                ResolvedBlock& b) {
  b = ResolvedBlock{};
  b.line = src.line;
  b.motion = Motion::kLinear;
  b.start = from;
  b.target = to;
  b.axis_words = 0x1F;
  b.feed_mode = FeedMode::kInverseTime;
  b.feed = 60.0 / (static_cast<double>(ticks) * period);
  b.spindle_speed = src.spindle_speed;
  b.spindle = src.spindle;
  b.tool = src.tool;
  b.tool_in_spindle = src.tool_in_spindle;
  b.coolant = src.coolant;
  b.work_offset = src.work_offset;
  b.work_origin = src.work_origin;
  b.source_units = src.source_units;
  b.plane = src.plane;
}

/// Forward projection onto the speed bound: a node that would need a faster axis than the bound
/// is pulled back along that axis, so the interpolator never lengthens a point (which would
/// shift every later point in time).
void project_step(const Axes& from, Axes& to, const Axes& vmax, double dt) {
  for (std::size_t i = 0; i < kNumAxes; ++i) {
    if (!(vmax[i] > 0)) continue;
    const double step = vmax[i] * dt * (1 - 1e-6);
    const double d = to[i] - from[i];
    if (std::abs(d) > step) to[i] = from[i] + std::copysign(step, d);
  }
}

// Where a tick of the planned reference is in the program, and its reference tool tip.
struct ReferenceClock {
  const Model& model;
  const Nominal& nom;
  std::uint32_t block_at(std::uint64_t tick) const {
    const std::size_t p = nom.progress[std::min<std::size_t>(tick, nom.progress.size() - 1)];
    return nom.block[std::min<std::size_t>(p, nom.block.size() - 1)];
  }
  Vec3 tip_at(const Axes& j, std::uint64_t tick) const {
    return forward_kinematics(model.kin, j, tool_length_of(model, nom.brief[block_at(tick)])).tip;
  }
};

// Node grid of reference ticks [from, to] (from a multiple of `m`, to a multiple of it or the
// reference's last tick): a node every `m` ticks, then kinematic linearisation: an interval is
// halved while joint-linear motion between its ends leaves the reference tool-tip path by more
// than the tolerance at its midpoint. The intervals are those of one grid over the whole
// reference, so windows that overlap make the same nodes where they overlap. Splits are counted
// in `res` for intervals that begin before `count_below` (a window counts the part it commits).
std::vector<std::uint64_t> linearised_grid(const ReferenceClock& clock, std::uint64_t m, double tolerance,
                                           std::uint64_t from, std::uint64_t to, std::uint64_t count_below, Result& res) {
  const Nominal& nom = clock.nom;
  std::vector<std::uint64_t> ticks;
  for (std::uint64_t k = from; k < to; k += m) ticks.push_back(k);
  ticks.push_back(to);
  std::vector<std::uint64_t> grid;
  grid.push_back(from);
  std::vector<std::pair<std::uint64_t, std::uint64_t>> stack;
  for (std::size_t k = 1; k < ticks.size(); ++k) {
    const bool counted = ticks[k - 1] < count_below;
    stack.clear();
    stack.emplace_back(ticks[k - 1], ticks[k]);
    std::vector<std::uint64_t> added;
    while (!stack.empty()) {
      auto [a, b] = stack.back();
      stack.pop_back();
      if (b - a >= 2) {
        const std::uint64_t c = (a + b) / 2;
        // Deviation of joint-linear motion from the path: the tip of the joint midpoint against
        // the reference tool-tip polyline between the two nodes (not against the time-matched
        // point: a speed change along a straight path is no deviation).
        const Vec3 mid = clock.tip_at(lerp(nom.reference[a], nom.reference[b], 0.5), c);
        double dev = std::numeric_limits<double>::infinity();
        Vec3 prev = clock.tip_at(nom.reference[a], a);
        for (std::uint64_t n = a + 1; n <= b; ++n) {
          const Vec3 cur = clock.tip_at(nom.reference[n], n);
          dev = std::min(dev, servo::segment_distance(prev, cur, mid));
          prev = cur;
        }
        if (dev > tolerance) {
          if (counted) ++res.linearisation_splits;
          stack.emplace_back(c, b);
          stack.emplace_back(a, c);
          continue;
        }
        if (counted) res.linearisation_max_deviation = std::max(res.linearisation_max_deviation, dev);
      }
      added.push_back(b);
    }
    std::sort(added.begin(), added.end());
    grid.insert(grid.end(), added.begin(), added.end());
  }
  return grid;
}

// What the source's own TCP blocks would do if run joint-linearly between their IK end points
// (a control without TCP): reported, since it is the error the node program removes.
void measure_source_joint_linear_deviation(const Model& model, std::span<const ResolvedBlock> program,
                                           const Nominal& nom, double tolerance, Result& res) {
  for (std::size_t i = 0; i < program.size(); ++i) {
    // The briefs are read first: a CAM program without TCP maps none of its blocks' pages here.
    if (!nom.brief[i].tcp || nom.brief[i].motion != Motion::kLinear) continue;
    const ResolvedBlock& b = program[i];
    const double L = tool_length_of(model, b);
    const IkResult s = inverse_kinematics_ac(model.kin, {b.start[kX], b.start[kY], b.start[kZ]}, b.start[kA], b.start[kC], L);
    const IkResult e = inverse_kinematics_ac(model.kin, {b.target[kX], b.target[kY], b.target[kZ]}, b.target[kA], b.target[kC], L);
    if (s.status == IkStatus::kFailed || e.status == IkStatus::kFailed) continue;
    double worst = 0;
    for (int k = 1; k < 8; ++k) {
      const double u = k / 8.0;
      const Vec3 tip = forward_kinematics(model.kin, lerp(s.joints, e.joints, u), L).tip;
      const Vec3 line{b.start[kX] + (b.target[kX] - b.start[kX]) * u, b.start[kY] + (b.target[kY] - b.start[kY]) * u,
                      b.start[kZ] + (b.target[kZ] - b.start[kZ]) * u};
      worst = std::max(worst, dist3(tip, line));
    }
    res.source_joint_linear_deviation = std::max(res.source_joint_linear_deviation, worst);
    if (worst > tolerance) ++res.source_blocks_needing_split;
  }
}

// A value per node (of the node's tick) averaged over the nodes within +-R ticks of each node,
// made node by node in order: the two ends of the span move forward, the sum adds a node as it
// enters and takes it off as it leaves, in the order a pass over a whole series of values would.
class WindowAverage {
 public:
  WindowAverage(const std::vector<std::uint64_t>& ticks, std::uint64_t R, std::function<double(std::uint64_t tick)> value)
      : ticks_(ticks), R_(R), value_(std::move(value)) {}

  /// The average at node k; k only grows between calls.
  double at(std::size_t k) {
    while (next_ <= k) step();
    return current_;
  }

 private:
  void step() {
    const std::size_t k = next_++;
    const std::size_t n = ticks_.size();
    while (hi_ < n && ticks_[hi_] <= ticks_[k] + R_) sum_ += value_(ticks_[hi_++]);
    while (ticks_[lo_] + R_ < ticks_[k]) sum_ -= value_(ticks_[lo_++]);
    current_ = sum_ / static_cast<double>(hi_ - lo_);
  }

  const std::vector<std::uint64_t>& ticks_;  // of the nodes
  std::uint64_t R_;
  std::function<double(std::uint64_t)> value_;
  std::size_t next_ = 0, lo_ = 0, hi_ = 0;
  double sum_ = 0, current_ = 0;
};

// One zero-phase [1 2 1]/4 pass over a window's series, the two end values kept.
void smooth_121(const std::vector<Axes>& in, std::vector<Axes>& out) {
  const std::size_t n = in.size();
  out.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    if (k == 0 || k + 1 >= n) {
      out[k] = in[k];
      continue;
    }
    for (std::size_t i = 0; i < kNumAxes; ++i) out[k][i] = 0.25 * in[k - 1][i] + 0.5 * in[k][i] + 0.25 * in[k + 1][i];
  }
}

// The joints of every node of the grid, as float offsets from the reference at the node's tick.
// A node is the reference plus its compensation, which is small (the lag of the chain: mm, a few
// degrees), so a float keeps it to a fraction of a nanometre, far below the 0.1 um the program is
// written with: 20 bytes a node instead of a Node's 56 (the tick and block are the grid's, the
// same for the current and the best nodes). `set` stores a value, `get` gives it back as stored.
class NodeJoints {
 public:
  NodeJoints(const simulate::JointSeries& reference, const std::vector<std::uint64_t>& grid)
      : reference_(&reference), grid_(&grid), offset_(grid.size()) {}

  std::size_t size() const { return offset_.size(); }
  /// The reference at node k's tick (the base of its offsets).
  Axes reference(std::size_t k) const { return (*reference_)[(*grid_)[k]]; }
  Axes get(std::size_t k) const { return get(k, reference(k)); }
  Axes get(std::size_t k, const Axes& r) const {
    Axes j;
    for (std::size_t i = 0; i < kNumAxes; ++i) j[i] = r[i] + static_cast<double>(offset_[k][i]);
    return j;
  }
  void set(std::size_t k, const Axes& joints) { set(k, reference(k), joints); }
  /// `r` must be reference(k).
  void set(std::size_t k, const Axes& r, const Axes& joints) {
    for (std::size_t i = 0; i < kNumAxes; ++i) offset_[k][i] = static_cast<float>(joints[i] - r[i]);
  }
  void release() { std::vector<AxesF>().swap(offset_); }
  /// Moves node k's offset on axis i by one float step towards `towards` [mm | deg].
  void nudge(std::size_t k, std::size_t i, double towards) {
    offset_[k][i] = std::nextafter(offset_[k][i], static_cast<float>(towards - reference(k)[i]));
  }

 private:
  const simulate::JointSeries* reference_;
  const std::vector<std::uint64_t>* grid_;
  std::vector<AxesF> offset_;
};

// The offsets are floats: a projected node read back can move past the bound by an ulp of its
// offset (5e-7 mm at a 4 mm lag), more than project_step's 1e-6 relative margin on a 0.25 mm step
// (F999 in/min at X's 250 mm/s bound: every point of arcspiral.ngc was refused as "slowed by the
// interpolator's speed bound"). Such an axis's offset is stepped back, float by float, towards
// the previous node until the step is within the bound again.
Axes keep_within_bound(NodeJoints& nodes, std::size_t k, const Axes& r, const Axes& from, const Axes& vmax, double dt) {
  Axes j = nodes.get(k, r);
  for (std::size_t i = 0; i < kNumAxes; ++i) {
    if (!(vmax[i] > 0)) continue;
    for (int n = 0; n < 64 && std::abs(j[i] - from[i]) > vmax[i] * dt * (1 - 1e-7); ++n) {
      nodes.nudge(k, i, from[i]);
      j = nodes.get(k, r);
    }
  }
  return j;
}

// Forward projection of every node onto the speed bound, in order (each against its projected
// predecessor as stored), as project_step does it for one node.
void project_speed(NodeJoints& nodes, const std::vector<std::uint64_t>& grid, const Axes& vmax, double period) {
  if (nodes.size() == 0) return;
  Axes before = nodes.get(0);
  for (std::size_t k = 1; k < nodes.size(); ++k) {
    const Axes r = nodes.reference(k);
    Axes j = nodes.get(k, r);
    const Axes unprojected = j;
    project_step(before, j, vmax, static_cast<double>(grid[k] - grid[k - 1]) * period);
    if (j != unprojected) {
      nodes.set(k, r, j);
      j = keep_within_bound(nodes, k, r, before, vmax, static_cast<double>(grid[k] - grid[k - 1]) * period);
    }
    before = j;
  }
}

// What one second of a node-program run did: the limits it met and its contour error.
struct WindowLimits {
  std::array<std::uint64_t, kNumAxes> saturated{};
  Axes peak_acceleration{};
  double max_contour = 0;
  std::size_t segment = 0;  // of the second's first tick, for the original's demand there
  bool seen = false;
};

// One learning iteration of one window as the report counts it: its run's contour error on the
// ticks the window commits, and its verdict.
struct WindowIteration {
  double max_contour = 0, sum_sq = 0;
  std::uint64_t count = 0;
  double gain = 0;
  bool accepted = true;
  std::string rejected_because;
};

// The learning of compensate(), in windows of the program: the reference clock is cut into
// windows of kWindowSeconds, and each is learned on its own, run from the machine state in which
// the nodes committed before it leave the machine (a copy of the MachineRun), with a margin of
// kMarginSeconds past its end, since the operator L reads the error up to 0.2 s ahead. The
// window's nodes are committed, the margin's nodes are the next window's start, and the
// window's series are dropped: memory and the replay are a window's, not the program's, and a
// window that has converged is not run again while another still learns.
//
// Inside a window the learning is local in time as well: the window is cut into seconds, and an
// iterate that breaks a limit or does worse in one second is dropped there only (its nodes keep
// their best values, its gain is halved) while the other seconds keep learning. Each iteration
// runs the window's node program (measure), judges every second (judge_seconds), keeps what
// improved blended over the seconds' boundaries (blend_into_best), and takes a learning step on
// each second's best error (learning_step).
class WindowedLearning {
 public:
  // Measured on the shipped samples, LinuxCNC's programs and generated CAM programs (README
  // beside this file, "Learning in windows"): 4 s windows with a 1 s margin lost up to 44 % of
  // the after figure at the joins; 16 s with 2 s keeps every row of the top README within 5 % of
  // the whole-program learning (one generated program of eight lost 46 %, at its first join).
  static constexpr double kWindowSeconds = 16;
  static constexpr double kMarginSeconds = 2;
  static constexpr double kTaperSeconds = 0.4;  // the update fades out over the margin's end
  static constexpr double kRampSeconds = 0.2;   // and in after the committed nodes

  WindowedLearning(const Model& model, const Nominal& nom, std::span<const ResolvedBlock> program, const Axes& start,
                   const Evaluation& before, const CompensateOptions& opt, Result& res, const NodeSink& sink)
      : model_(model), nom_(nom), program_(program), opt_(opt), res_(res), sink_(sink), T_(nom.period), E_(nom.reference.size()),
        clock_{model, nom}, m_(static_cast<std::uint64_t>(std::max(1L, std::lround(opt.node_period / T_)))),
        chain_inverse_(design_chain_inverse(model)), vbound_(interpolate::speed_bound(model.interp)),
        Wt_(static_cast<std::uint64_t>(std::max(1L, std::lround(1.0 / T_)))),
        window_ticks_(round_up(static_cast<std::uint64_t>(std::lround(kWindowSeconds / T_)), m_)),
        margin_ticks_(round_up(static_cast<std::uint64_t>(std::lround(kMarginSeconds / T_)), m_)),
        pre_ticks_(static_cast<std::uint64_t>(std::lround(0.25 / T_))),
        taper_ticks_(static_cast<std::uint64_t>(std::lround(kTaperSeconds / T_))),
        ramp_ticks_(std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::lround(kRampSeconds / T_)))),
        nseg_(std::max<std::size_t>(1, nom.segments.size())),
        R_(static_cast<std::uint64_t>(std::lround(0.1 / T_))), base_(before.demand),
        state_(model, start, clock_.block_at(0)), nodes_(nom.reference, grid_), best_(nom.reference, grid_),
        totals_(static_cast<std::size_t>(opt.max_iterations) + 1) {
    measure_source_joint_linear_deviation(model, program, nom, opt.linearisation_tolerance, res);
    last_committed_ = Node{0, start, clock_.block_at(0)};
    committed_.push_back(last_committed_);
    // The operator's design is freed: its pages go back before the windows.
    simulate::give_back_freed_memory();
  }

  void run(const Progress& progress) {
    for (std::uint64_t a = 0;;) {
      if (progress) progress("compensating (learning, window by window)", a, E_);
      const Window w = window_from(a);
      learn(w);
      commit(w);
      if (w.last) break;
      a = w.b;
    }
    finish();
  }

 private:
  // Reference ticks of a window: it learns [a, c] and commits [a, b] (b = c for the last).
  struct Window {
    std::uint64_t a = 0, b = 0, c = 0;
    bool last = false;
  };

  // How a run of node blocks went: a block the interpolator refused (the run stopped there), or
  // every block run with some slowed by the speed bound (an iterate that is rejected, while the
  // machine still ends where the nodes do).
  struct NodeRun {
    std::string refused;
    bool slowed = false;
    std::string why_rejected() const {
      return !refused.empty() ? refused : slowed ? "points slowed by the interpolator's speed bound" : std::string();
    }
  };

  static std::uint64_t round_up(std::uint64_t n, std::uint64_t m) { return (n + m - 1) / m * m; }

  Window window_from(std::uint64_t a) const {
    const std::uint64_t end = E_ - 1;
    if (a + window_ticks_ + margin_ticks_ >= end) return {a, end, end, true};
    return {a, a + window_ticks_, a + window_ticks_ + margin_ticks_, false};
  }

  // The window's grid, start iterate and learning state, before its first iteration.
  void open(const Window& w) {
    // Every run of the window is measured against the same stretch of the nominal path: it is
    // made once, on the first run, and searched again by the others.
    meter_ = std::make_unique<simulate::ContourMeter>(model_, nom_, true, w.a, true);
    grid_ = linearised_grid(clock_, m_, opt_.linearisation_tolerance, w.a, w.c, w.last ? w.c + 1 : w.b, res_);
    nodes_ = NodeJoints(nom_.reference, grid_);
    start_iterate();
    project_speed(nodes_, grid_, vbound_, T_);  // as stored (the start was projected in exact values)
    best_ = nodes_;
    nsub_ = static_cast<std::size_t>((w.c - w.a + Wt_ - 1) / Wt_) + (w.last ? 4 : 0);
    nsub_ = std::max<std::size_t>(nsub_, 1);
    sub_best_.assign(nsub_, std::numeric_limits<double>::infinity());
    sub_gain_.assign(nsub_, opt_.gain);
    sub_stalls_.assign(nsub_, 0);
    sub_learned_.assign(nsub_, false);
    // The seconds the previous window learned in its margin go on learning with the gain they
    // had; their best error is measured again (the committed nodes before them are a blend of
    // several iterations, so the run they now follow is new) and their stall count starts again.
    for (std::size_t s = 0; s < carry_seconds_.size() && s < nsub_; ++s) {
      sub_gain_[s] = carry_seconds_[s].gain;
      sub_learned_[s] = carry_seconds_[s].learned;
    }
    e0_ = w.a > pre_ticks_ ? w.a - pre_ticks_ : 0;
    best_error_.assign(w.c - e0_ + 1, AxesF{});
    for (std::size_t k = 0; k < carry_error_.size(); ++k) {
      const std::uint64_t n = w.a + k;
      if (n < e0_ + best_error_.size()) best_error_[n - e0_] = carry_error_[k];
    }
    // The committed run's error just before the window: the operator reads back into it.
    for (std::size_t k = 0; k < pre_error_.size(); ++k) {
      const std::uint64_t n = pre_first_ + k;
      if (n >= e0_ && n < w.a && n < e0_ + best_error_.size()) best_error_[n - e0_] = pre_error_[k];
    }
  }

  // The window's first iterate: node 0 where the committed nodes end, the nodes the previous
  // window learned in its margin, and beyond them the model-inverse start u0 = L r (the
  // program's end point at its end), each projected onto the speed bound against the one before.
  void start_iterate() {
    start_.assign(grid_.size(), Axes{});
    start_[0] = last_committed_.joints;
    std::size_t carried = 0;
    for (std::size_t k = 1; k < grid_.size(); ++k) {
      while (carried < carry_.size() && carry_[carried].first < grid_[k]) ++carried;
      Axes u;
      if (carried < carry_.size() && carry_[carried].first == grid_[k]) u = carry_[carried].second;
      else if (grid_[k] + 1 == E_) u = nom_.reference.back();
      else u = apply_inverse(chain_inverse_, nom_.reference, static_cast<std::int64_t>(grid_[k]));
      project_step(start_[k - 1], u, vbound_, static_cast<double>(grid_[k] - grid_[k - 1]) * T_);
      start_[k] = u;
      nodes_.set(k, u);
    }
    nodes_.set(0, start_[0]);
  }

  void learn(const Window& w) {
    win_ = w;
    open(w);
    if (stopped_) {  // the machine state is unknown past a failed commit: nothing is learned
      res_.windows.push_back({static_cast<double>(w.a) * T_, static_cast<double>(w.b) * T_, 0, false});
      return;
    }
    std::vector<WindowIteration> record;
    bool out_of_iterations = false;
    for (int it = 0; it <= opt_.max_iterations; ++it) {
      std::vector<WindowLimits> lim;
      WindowIteration rec = measure(w, lim);
      rec.gain = *std::max_element(sub_gain_.begin(), sub_gain_.end());
      if (!rec.rejected_because.empty()) {  // the run itself failed: nothing of it is learned from
        rec.accepted = false;
        record.push_back(rec);
        last_rejection_ = rec.rejected_because;
        break;
      }
      std::vector<bool> improved(nsub_, false);
      rec.rejected_because = judge_seconds(w, lim, improved);
      rec.accepted = rec.rejected_because.empty();
      record.push_back(rec);
      blend_into_best(improved);
      if (all_stalled(lim)) break;
      if (it == opt_.max_iterations) {
        out_of_iterations = true;
        break;
      }
      nodes_ = best_;
      project_speed(nodes_, grid_, vbound_, T_);
      learning_step();
      project_speed(nodes_, grid_, vbound_, T_);
    }
    add_to_totals(record);
    res_.windows.push_back({static_cast<double>(w.a) * T_, static_cast<double>(w.b) * T_, static_cast<int>(record.size()),
                            out_of_iterations});
  }

  // How much of the learning update a node takes: all of it, except over the first
  // kRampSeconds after the committed nodes, which cannot move with it, where it fades in from
  // none, and over the last kTaperSeconds of a margin, where it fades to none at the margin's
  // end. The end node stays at the window's start (the model-inverse start there), so the
  // learned nodes join it without a step, and the next window starts from nodes that join the
  // model-inverse start after them.
  double taper(std::uint64_t tick) const {
    double w = 1.0;
    const std::uint64_t a = win_.a, c = win_.c;
    if (!win_.last) w = std::clamp(static_cast<double>(c - std::min(tick, c)) / static_cast<double>(taper_ticks_), 0.0, 1.0);
    if (a > 0) w = std::min(w, std::clamp(static_cast<double>(std::max(tick, a) - a) / static_cast<double>(ramp_ticks_), 0.0, 1.0));
    return w;
  }

  std::size_t sub_of(std::uint64_t tick) const {
    return tick < win_.a ? 0 : std::min<std::size_t>(static_cast<std::size_t>((tick - win_.a) / Wt_), nsub_ - 1);
  }
  std::size_t segment_of_block(std::uint32_t b) const {
    return nom_.segment_of_block.empty() ? 0 : std::min<std::size_t>(nom_.segment_of_block[b], nseg_ - 1);
  }

  // The window's node program as it is now, block by block from node 0, into `run`; the last
  // window's run settles after the program's end. The ticks it simulates are counted for the
  // report.
  NodeRun run_nodes(simulate::MachineRun& run, std::size_t last_node, bool settle, const NodeJoints& nodes,
                    const simulate::TickFn& on_tick) {
    const std::uint64_t ticks_before = run.ticks();
    const std::uint64_t limited = run.interp_stats().velocity_limited_blocks;
    NodeRun out;
    out.refused = run_node_blocks(run, last_node, nodes, on_tick);
    if (out.refused.empty()) {
      if (settle) run.finish(on_tick);
      out.slowed = run.interp_stats().velocity_limited_blocks > limited;
    }
    res_.learning_ticks += run.ticks() - ticks_before;
    return out;
  }

  std::string run_node_blocks(simulate::MachineRun& run, std::size_t last_node, const NodeJoints& nodes,
                              const simulate::TickFn& on_tick) const {
    ResolvedBlock block;
    Axes from = start_[0];
    for (std::size_t i = 0; i < last_node; ++i) {
      const std::uint32_t src = clock_.block_at(grid_[i + 1]);
      node_block(program_[src], from, nodes.get(i + 1), grid_[i + 1] - grid_[i], T_, block);
      const auto r = run.add(block, src, on_tick);
      if (r.status != interpolate::InterpolateStatus::kOk) return r.message;
      from = block.target;
    }
    return {};
  }

  // Which limit a second's run broke, or empty: the torque-limited ticks and the smoothed
  // command's acceleration, against the original's own demand in the second's segment.
  std::string limit_broken(const WindowLimits& lw) const {
    const SegmentDemand& allowed = base_[std::min(lw.segment, base_.size() - 1)];
    std::string why;
    for (std::size_t i = 0; i < kNumAxes && why.empty(); ++i) {
      char msg[160];
      // The acceleration bound: the machine's limit, or the uncompensated program's own peak
      // in that segment where the control's acc/dec already reaches beyond it, plus 1 % of the
      // limit for the second difference of 1 ms samples (a sampling figure, not a motion).
      const double alim = std::max(model_.kin.max_acceleration[i], allowed.peak_acceleration[i]) +
                          0.01 * model_.kin.max_acceleration[i];
      if (lw.saturated[i] > allowed.saturated_ticks[i]) {
        std::snprintf(msg, sizeof msg, "axis %c torque-limited in %llu ticks (uncompensated segment: %llu)", kAxisLetters[i],
                      static_cast<unsigned long long>(lw.saturated[i]), static_cast<unsigned long long>(allowed.saturated_ticks[i]));
        why = msg;
      } else if (model_.kin.max_acceleration[i] > 0 && lw.peak_acceleration[i] > alim) {
        why = acceleration_over_limit(kAxisLetters[i], lw.peak_acceleration[i], alim);
      }
    }
    return why;
  }

  // A second that does better within the limits hands its error r - y to the learning. That is
  // known when its last tick has run, so the run keeps only the error of its current second and
  // copies it to best_error_ there.
  void keep_if_improved(std::size_t s, const WindowLimits& lw) {
    if (!lw.seen || !limit_broken(lw).empty() || !(lw.max_contour < sub_best_[s])) return;
    for (std::size_t k = 0; k < second_err_.size(); ++k) {
      const std::uint64_t n = second_first_ + k;
      if (n < e0_) continue;
      if (n - e0_ >= best_error_.size()) best_error_.resize(n - e0_ + 1, best_error_.back());
      for (std::size_t i = 0; i < kNumAxes; ++i) best_error_[n - e0_][i] = static_cast<float>(second_err_[k][i]);
    }
  }

  // One run of the window's nodes from the committed state: torque saturation, smoothed-command
  // acceleration and contour error per second, each second's error r - y to keep_if_improved as
  // the second ends, and the contour error on the ticks the window commits.
  WindowIteration measure(const Window& w, std::vector<WindowLimits>& lim) {
    lim.assign(nsub_, WindowLimits{});
    WindowIteration rec;
    simulate::MachineRun run = state_;
    simulate::ContourMeter& meter = *meter_;
    meter.rewind();
    Axes c1 = c1_, c2 = c2_;
    std::uint64_t seen = seen_;
    std::size_t current = 0;
    second_err_.clear();
    second_first_ = state_.ticks();
    const std::uint64_t counted_from = state_.ticks(), counted_to = w.last ? UINT64_MAX : w.b;
    auto on_tick = [&](const Tick& t) {
      const std::size_t s = sub_of(t.n);
      if (s != current) {
        keep_if_improved(current, lim[current]);
        second_err_.clear();
        second_first_ = t.n;
        current = s;
      }
      const ResolvedBlock& b = program_[std::min<std::size_t>(t.block, program_.size() - 1)];
      WindowLimits& L0 = lim[s];
      // The verdicts read the largest error of each second and of the committed ticks: a tick
      // that cannot raise either is measured only near its previous match (an upper bound of
      // its distance, usually the distance itself), not searched over the whole window.
      const bool cutting = simulate::is_cutting(b);
      const bool counted = t.n >= counted_from && t.n < counted_to;
      const double bound = !cutting ? std::numeric_limits<double>::infinity()
                                    : std::min(L0.max_contour, counted ? rec.max_contour : std::numeric_limits<double>::infinity());
      Vec3 tip, nearest;
      const double e = meter.distance_beyond(t, b, bound, tip, nearest);
      const double contour = cutting ? e : 0.0;
      if (!L0.seen) L0.segment = segment_of_block(t.block), L0.seen = true;
      L0.max_contour = std::max(L0.max_contour, contour);
      for (std::size_t i = 0; i < kNumAxes; ++i) {
        if (t.saturated & (1u << i)) ++L0.saturated[i];
        if (seen >= 2) {
          const double acc = std::abs(t.command[i] - 2 * c1[i] + c2[i]) / (T_ * T_);
          L0.peak_acceleration[i] = std::max(L0.peak_acceleration[i], acc);
        }
      }
      c2 = c1;
      c1 = t.command;
      ++seen;
      if (counted) {
        rec.max_contour = std::max(rec.max_contour, contour);
        rec.sum_sq += contour * contour;
        ++rec.count;
      }
      const Axes r = t.n < E_ ? nom_.reference[t.n] : nom_.reference.back();
      Axes err;
      for (std::size_t i = 0; i < kNumAxes; ++i) err[i] = r[i] - t.actual[i];
      second_err_.push_back(err);
    };
    rec.rejected_because = run_nodes(run, grid_.size() - 1, w.last, nodes_, on_tick).why_rejected();
    if (rec.rejected_because.empty()) keep_if_improved(current, lim[current]);
    return rec;
  }

  // Every second's verdict on the run just measured: improved within the limits (its error is
  // in best_error_ already, from measure), or its gain halved; a stall count per second. Returns
  // the first limit broken in this iteration, or empty.
  std::string judge_seconds(const Window& w, const std::vector<WindowLimits>& lim, std::vector<bool>& improved) {
    std::string why_iteration;
    for (std::size_t s = 0; s < nsub_; ++s) {
      if (!lim[s].seen) continue;
      const std::string why = limit_broken(lim[s]);
      const double emax = lim[s].max_contour;
      const double previous = sub_best_[s];
      if (why.empty() && emax < previous) {
        sub_best_[s] = emax;
        improved[s] = true;
        sub_learned_[s] = true;
      } else {
        sub_gain_[s] *= 0.5;
      }
      if (!why.empty()) {
        const double t0 = static_cast<double>(w.a + s * Wt_) * T_;
        char when[80];
        std::snprintf(when, sizeof when, " at t %.0f-%.0f s", t0, t0 + static_cast<double>(Wt_) * T_);
        last_rejection_ = why + when;
        // Keyed by the second of the program it begins in (the report looks up the seconds
        // around the largest error); the margin's second is the next window's to report.
        if (w.last || w.a + s * Wt_ < w.b) res_.window_limits[static_cast<std::size_t>(t0)] = last_rejection_;
        if (why_iteration.empty()) why_iteration = last_rejection_;
      }
      sub_stalls_[s] = why.empty() && emax < 0.99 * previous ? 0 : sub_stalls_[s] + 1;
    }
    return why_iteration;
  }

  // A per-second value at every node, moving-averaged over +-0.1 s of nodes, node by node in
  // order (WindowAverage).
  WindowAverage over_nodes(std::function<double(std::size_t)> value) const {
    return WindowAverage(grid_, R_, [value = std::move(value), this](std::uint64_t tick) { return value(sub_of(tick)); });
  }

  // Accepting some seconds and not others must not leave a step in the commands at a boundary
  // (the step itself would break the acceleration limit there): the per-second decisions are
  // blended over about 0.1 s of nodes on either side of each boundary.
  void blend_into_best(const std::vector<bool>& improved) {
    WindowAverage take = over_nodes([&](std::size_t s) { return improved[s] ? 1.0 : 0.0; });
    WindowAverage learned = over_nodes([&](std::size_t s) { return sub_learned_[s] ? 1.0 : 0.0; });
    WindowAverage blend = over_nodes([&](std::size_t s) { return sub_gain_[s]; });
    for (std::size_t k = 1; k < grid_.size(); ++k) {
      // Where nothing was accepted yet: the window's start blended back towards the reference
      // (the uncompensated motion, gentler than the program's own) by the gain.
      const Axes r = best_.reference(k);
      const Axes& u0 = start_[k];
      const double take_k = take.at(k), learned_k = learned.at(k), blend_k = blend.at(k);
      const Axes current = nodes_.get(k, r);
      Axes best = best_.get(k, r);
      for (std::size_t i = 0; i < kNumAxes; ++i) {
        const double fallback = r[i] + std::min(1.0, blend_k) * (u0[i] - r[i]);
        const double kept = learned_k * best[i] + (1 - learned_k) * fallback;
        best[i] = take_k * current[i] + (1 - take_k) * kept;
      }
      best_.set(k, r, best);
    }
  }

  bool all_stalled(const std::vector<WindowLimits>& lim) const {
    bool stalled = true;
    for (std::size_t s = 0; s < nsub_; ++s) stalled = stalled && (!lim[s].seen || sub_stalls_[s] >= 3);
    return stalled;
  }

  // Learning update on each second's best error, zero-phase smoothed over nodes ([1 2 1]/4
  // twice) so that the derivative term does not feed tick-scale roughness back. Node 0 is
  // committed and the last node is the program's end or the margin's far end: both stay.
  void learning_step() {
    WindowAverage gain_at = over_nodes([&](std::size_t s) { return sub_learned_[s] ? sub_gain_[s] : 0.0; });
    const std::size_t n = grid_.size();
    // A window's update is a few thousand nodes: held whole, it is smoothed in two plain passes
    // (the same sums in the same order as node by node, without a call per value).
    update_.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
      Axes du{};
      const double gain_k = k == 0 ? 0.0 : gain_at.at(k) * taper(grid_[k]);
      if (gain_k > 0) {
        du = apply_inverse(chain_inverse_, best_error_, static_cast<std::int64_t>(grid_[k] - e0_));
        for (std::size_t i = 0; i < kNumAxes; ++i) du[i] *= gain_k;
      }
      update_[k] = du;
    }
    smooth_121(update_, smoothed_);
    smooth_121(smoothed_, update_);
    for (std::size_t k = 1; k + 1 < n; ++k) {
      const Axes& du = update_[k];
      const Axes r = nodes_.reference(k);
      Axes j = nodes_.get(k, r);
      for (std::size_t i = 0; i < kNumAxes; ++i) {
        const auto& tr = model_.kin.travel[i];
        j[i] = std::clamp(j[i] + du[i], tr.min, tr.max);
      }
      nodes_.set(k, r, j);
    }
  }

  // The window's best nodes up to b go to the result; the margin's are the next window's start;
  // the machine state moves on to b by running the committed nodes once, which also gives the
  // error just before b (the next window's operator reads back into it).
  void commit(const Window& w) {
    std::size_t end = grid_.size() - 1;
    if (!w.last) end = static_cast<std::size_t>(std::find(grid_.begin(), grid_.end(), w.b) - grid_.begin());
    for (std::size_t k = 1; k <= end; ++k) committed_.push_back(Node{grid_[k], best_.get(k), clock_.block_at(grid_[k])});
    hand_on_committed();
    carry_.clear();
    for (std::size_t k = end + 1; k < grid_.size(); ++k) carry_.emplace_back(grid_[k], best_.get(k));
    carry_seconds_.clear();
    carry_error_.clear();
    if (w.last) return;
    // The margin's seconds and best error, when the next window's seconds are the same seconds.
    if ((w.b - w.a) % Wt_ == 0) {
      for (std::size_t s = (w.b - w.a) / Wt_; s < nsub_; ++s)
        carry_seconds_.push_back({sub_gain_[s], sub_learned_[s]});
      carry_error_.assign(best_error_.begin() + static_cast<std::ptrdiff_t>(w.b - e0_), best_error_.end());
    }
    pre_error_.clear();
    pre_first_ = w.b > pre_ticks_ ? w.b - pre_ticks_ : 0;
    auto on_tick = [&](const Tick& t) {
      c2_ = c1_;
      c1_ = t.command;
      ++seen_;
      if (t.n < pre_first_) return;
      const Axes r = nom_.reference[t.n];
      AxesF err;
      for (std::size_t i = 0; i < kNumAxes; ++i) err[i] = static_cast<float>(r[i] - t.actual[i]);
      if (pre_error_.empty()) pre_first_ = t.n;
      pre_error_.push_back(err);
    };
    if (stopped_) return;
    const NodeRun committed = run_nodes(state_, end, false, best_, on_tick);
    if (committed.slowed) last_rejection_ = committed.why_rejected();
    if (!committed.refused.empty()) {
      // The state the next window would start from is not where the committed nodes end: the
      // rest of the program keeps its model-inverse start, unlearned, and the note says why.
      stopped_ = true;
      char at[60];
      std::snprintf(at, sizeof at, " (t %.3f s)", static_cast<double>(w.b) * T_);
      last_rejection_ = "the committed nodes could not be run" + std::string(at) + ": " + committed.refused +
                        "; the program after that keeps the model-inverse start";
    }
  }

  // The window's nodes go to the sink (or the result), and only the last is kept: the program's
  // nodes are never all held where a sink takes them.
  void hand_on_committed() {
    for (bool learned : sub_learned_) any_learned_ = any_learned_ || learned;
    last_committed_ = committed_.back();
    handed_ += committed_.size();
    res_.points = handed_ - 1;  // node 0 is the start, not a point
    res_.end_tick = last_committed_.tick;
    if (sink_) sink_(committed_, any_learned_);
    else res_.nodes.insert(res_.nodes.end(), committed_.begin(), committed_.end());
    committed_.clear();
  }

  // A window's iterations added to the report's: iteration i of the program is each window at
  // its iteration i, or at its last where it stopped sooner.
  void add_to_totals(const std::vector<WindowIteration>& record) {
    if (record.empty()) return;
    iterations_run_ = std::max(iterations_run_, record.size());
    for (std::size_t i = 0; i < totals_.size(); ++i) {
      const WindowIteration& r = record[std::min(i, record.size() - 1)];
      WindowIteration& t = totals_[i];
      t.max_contour = std::max(t.max_contour, r.max_contour);
      t.sum_sq += r.sum_sq;
      t.count += r.count;
      t.gain = std::max(t.gain, r.gain);
      t.accepted = t.accepted && r.accepted;
      if (t.rejected_because.empty()) t.rejected_because = r.rejected_because;
    }
  }

  void finish() {
    for (std::size_t i = 0; i < iterations_run_; ++i) {
      const WindowIteration& t = totals_[i];
      Iteration rec;
      rec.index = static_cast<int>(i);
      rec.max_contour = t.max_contour;
      rec.rms_contour = t.count > 0 ? std::sqrt(t.sum_sq / static_cast<double>(t.count)) : 0.0;
      rec.gain = t.gain;
      rec.accepted = t.accepted;
      rec.rejected_because = t.rejected_because;
      res_.iterations.push_back(rec);
    }
    res_.compensated = any_learned_;
    if (!res_.compensated) res_.note = "no iterate stayed within the axis limits: " + last_rejection_;
    else if (!last_rejection_.empty()) res_.note = "learning held back where it would exceed a limit: " + last_rejection_;
  }

  const Model& model_;
  const Nominal& nom_;
  std::span<const ResolvedBlock> program_;
  const CompensateOptions& opt_;
  Result& res_;
  const NodeSink& sink_;
  std::vector<Node> committed_;  // the nodes of the window being committed (node 0 with the first)
  Node last_committed_;
  std::uint64_t handed_ = 0;     // nodes committed so far
  double T_;
  std::uint64_t E_;
  ReferenceClock clock_;
  std::uint64_t m_;             // ticks between nodes before linearisation
  ChainInverse chain_inverse_;  // the learning operator L, per axis
  Axes vbound_;
  std::uint64_t Wt_;            // ticks in a second (the unit of the accept/reject decisions)
  std::uint64_t window_ticks_, margin_ticks_, pre_ticks_, taper_ticks_, ramp_ticks_;
  std::size_t nseg_;
  std::uint64_t R_;             // ticks of the decisions' blend (0.1 s)
  const std::vector<SegmentDemand>& base_;
  // Across windows: the machine after the committed nodes, its last two commands, and the
  // error of the committed ticks just before the next window; the margin's nodes.
  simulate::MachineRun state_;
  Axes c1_{}, c2_{};
  std::uint64_t seen_ = 0;
  std::vector<AxesF> pre_error_;
  std::uint64_t pre_first_ = 0;
  std::vector<std::pair<std::uint64_t, Axes>> carry_;
  struct SecondState {
    double gain;
    bool learned;
  };
  std::vector<SecondState> carry_seconds_;
  std::vector<AxesF> carry_error_;  // best error from the next window's first tick on
  // The window being learned.
  Window win_;
  std::vector<std::uint64_t> grid_;
  std::vector<Axes> start_;     // its first iterate
  NodeJoints nodes_, best_;     // the current iterate and the best per second, on grid_
  std::size_t nsub_ = 1;
  std::vector<double> sub_best_, sub_gain_;
  std::vector<int> sub_stalls_;
  std::vector<bool> sub_learned_;
  std::uint64_t e0_ = 0;        // tick of best_error_[0]
  std::vector<AxesF> best_error_;  // r - y per tick, each second from its best run
  std::vector<Axes> update_, smoothed_;  // the learning update of the window's nodes, and a pass of its smoothing
  std::vector<Axes> second_err_;   // the current second's r - y, while a run is measured
  std::unique_ptr<simulate::ContourMeter> meter_;  // the window's contour metric, rewound for each run
  std::uint64_t second_first_ = 0;
  // The report.
  std::vector<WindowIteration> totals_;
  std::size_t iterations_run_ = 0;
  bool any_learned_ = false;
  bool stopped_ = false;  // a commit failed: later windows are not learned
  std::string last_rejection_;
};

}  // namespace

Result compensate(const Model& model, const Nominal& nom, std::span<const ResolvedBlock> program,
                  const Axes& start, const Evaluation& before, const CompensateOptions& opt,
                  const Progress& progress, const NodeSink& sink) {
  Result res;
  if (nom.reference_too_long) {
    // The plan stops at the bound, so its own length is unknown; the control's cycle is known.
    char msg[320];
    std::snprintf(msg, sizeof msg,
                  "not compensated: the planned reference would run longer than compensate.max_machine_time (%g s; "
                  "the control runs the program in %.1f s, and the plan slows its corners to the path tolerance): "
                  "raise compensate.max_machine_time in the pipeline config",
                  opt.max_machine_time, static_cast<double>(nom.stats.ticks) * nom.period);
    res.note = msg;
    return res;
  }
  if (nom.reference.empty() || program.empty()) {
    res.note = "nothing moves: no compensation needed";
    return res;
  }
  const double duration = static_cast<double>(nom.reference.size()) * nom.period;
  if (duration > opt.max_machine_time) {
    char msg[200];
    std::snprintf(msg, sizeof msg, "not compensated: the program runs %.0f s, compensate.max_machine_time is %.0f s", duration,
                  opt.max_machine_time);
    res.note = msg;
    return res;
  }
  WindowedLearning(model, nom, program, start, before, opt, res, sink).run(progress);
  simulate::give_back_freed_memory();  // the learning's series, before the program is written
  return res;
}

CompensatedBlocks::CompensatedBlocks(std::span<const ResolvedBlock> program, double period, Emit emit,
                                     CompensatedFrames frames)
    : program_(program), period_(period), emit_(std::move(emit)), frames_(std::move(frames)) {}

namespace {
// Tool length as compensated.nc states it. A tool-centre-point block's joints hold the tool length
// (inverse kinematics with it): G49. Any other block's joints are its targets, measured from the
// tool tip the control puts there with the source's own G43 H, so that length stays in force.
void tool_length_as_written(const ResolvedBlock& src, ResolvedBlock& c) {
  c.tcp = false;
  c.tool_vector_mode = false;
  c.tool_length_active = !src.tcp && src.tool_length_active;
  c.tool_length_offset = c.tool_length_active ? src.tool_length_offset : 0;
  c.tool_length = c.tool_length_active ? src.tool_length : 0;
}
}  // namespace

bool three_axis_program(std::span<const ResolvedBlock> program) {
  for (const ResolvedBlock& b : program) {
    if (b.motion == Motion::kNone) continue;
    if (b.tcp || b.tool_vector_mode) return false;
    if (b.target[kA] != b.start[kA] || b.target[kC] != b.start[kC]) return false;
  }
  return true;
}

namespace {
bool changes_origin(FrameCode c) {
  return c == FrameCode::kSetOrigin || c == FrameCode::kSetOriginHere || c == FrameCode::kShift ||
         c == FrameCode::kShiftClear || c == FrameCode::kShiftSuspend || c == FrameCode::kShiftRestore ||
         c == FrameCode::kLocalShift;
}
bool returns_home(FrameCode c) { return c == FrameCode::kHome || c == FrameCode::kHome2 || c == FrameCode::kMachine; }
}  // namespace

std::vector<bool> moves_written_as_source(std::span<const ResolvedBlock> program) {
  constexpr std::uint8_t kXyz = 0x07;
  std::vector<bool> as_source(program.size(), false);
  std::uint8_t known = 0;  // axes whose position in the work frame the control shares
  const ResolvedBlock* last = nullptr;
  for (std::size_t i = 0; i < program.size(); ++i) {
    const ResolvedBlock& b = program[i];
    if (last && (b.work_offset != last->work_offset || b.frame.origin != last->frame.origin)) known = 0;
    if (changes_origin(b.frame.code)) known = 0;
    if (last && (b.tool_length_active != last->tool_length_active || b.tool_length != last->tool_length))
      known &= static_cast<std::uint8_t>(~(1u << kZ));
    last = &b;
    if (b.motion == Motion::kNone) continue;
    if (returns_home(b.frame.code)) {
      as_source[i] = true;
      known &= static_cast<std::uint8_t>(b.frame.words ? ~b.frame.words : 0);
    } else if ((known & kXyz) != kXyz) {
      as_source[i] = true;
      if (!b.frame.incremental) known |= static_cast<std::uint8_t>(b.axis_words & kXyz);
    }
  }
  return as_source;
}

// A motion of the source is carried by the timed points that follow; the block stays as a note
// with its text so that the operator can find every source line.
void CompensatedBlocks::note_motion(const ResolvedBlock& b, ResolvedBlock& c) {
  noted_line_ = b.line;
  std::string text = b.text;
  std::replace(text.begin(), text.end(), '(', '[');
  std::replace(text.begin(), text.end(), ')', ']');
  c.motion = Motion::kNone;
  c.dwell = 0;
  c.axis_words = 0;
  c.frame.code = FrameCode::kNone;  // its G28 / G53 is in the points
  c.comment = (b.motion == Motion::kDwell ? "dwell, held by the timed points below: " : "source: ") + text;
  c.percent = false;
  c.program_number = -1;
}

void CompensatedBlocks::pass_block(std::size_t i) {
  const ResolvedBlock& b = program_[i];
  ResolvedBlock c = b;
  tool_length_as_written(b, c);
  // The timed points carry the program's stops and corner speeds (the plan followed G61 and
  // G64 P): the control runs them as timed, in its plain blending mode, not stopping at each.
  c.path_mode = PathMode::kBlend;
  c.path_tolerance = 0;
  if (b.tool_change) section_open_ = false;
  const bool as_source = frames_.work_frame && frames_.as_source[i];
  if (after_points_ && next_move_written_as_source(i)) settle_before(i);
  if (b.motion != Motion::kNone && !as_source && b.line == noted_line_ && b.motion != Motion::kDwell) return;
  if (b.motion != Motion::kNone && !as_source) note_motion(b, c);
  // Between timed points the inverse-time mode stays (no G94/G93 flip-flop in the output): a
  // rapid ignores F. Before the first point the block keeps its own feed mode.
  if (!as_source) c.start = c.target = last_target_;  // as the source wrote it: from its own start
  if (have_node_ && (c.motion == Motion::kNone || c.motion == Motion::kRapid)) {
    c.feed_mode = FeedMode::kInverseTime;
    c.feed = last_feed_;
  }
  if (as_source) last_target_ = c.target;
  emit_(c, i, last_node_.tick);
}

// The timed points of a move end near its end, not on it (the learning leads and corrects);
// a move written as the source wrote it keeps the axes it does not name where they are. So the
// points of the last move are closed by a rapid to its end: the next starts where the source's
// does, and every move that ends at a rapid's end ends there.
bool CompensatedBlocks::next_move_written_as_source(std::size_t i) const {
  if (!frames_.work_frame) return false;
  while (i < program_.size() && program_[i].motion == Motion::kNone) ++i;
  return i < program_.size() && frames_.as_source[i];
}

void CompensatedBlocks::settle_before(std::size_t i) {
  after_points_ = false;
  std::size_t k = i;
  while (k > 0 && program_[k - 1].motion == Motion::kNone) --k;
  if (k == 0 || frames_.as_source[k - 1]) return;
  const ResolvedBlock& prev = program_[k - 1];
  bool there = true;
  for (int a = 0; a < kA; ++a) there = there && std::abs(prev.target[a] - last_target_[a]) <= 1e-9;
  if (there) return;
  ResolvedBlock c = prev;
  tool_length_as_written(prev, c);
  c.motion = Motion::kRapid;
  c.frame.code = FrameCode::kNone;
  c.frame.incremental = false;
  c.frame.selects_work_offset = c.frame.sets_tool_length = false;
  c.start = last_target_;
  c.target[kA] = c.start[kA];
  c.target[kC] = c.start[kC];
  c.axis_words = 0x07;
  c.comment = "gcpipe: to the end of the source's move, before a move written as the source wrote it";
  c.text.clear();
  c.feed_mode = FeedMode::kInverseTime;
  c.feed = last_feed_;
  c.tool_change = false;
  c.stop = ProgramStop::kNone;
  c.program_number = -1;
  c.percent = false;
  emit_(c, k - 1, last_node_.tick);
  last_target_ = c.target;
}

void CompensatedBlocks::node(const Node& nd) {
  const ResolvedBlock& src = program_[nd.block];
  node_block(src, last_node_.joints, nd.joints, nd.tick - last_node_.tick, period_, block_);
  const std::uint64_t from_tick = last_node_.tick;
  const bool skip = frames_.work_frame && frames_.as_source[nd.block];
  last_node_ = nd;
  if (skip) return;  // the source's own move stands for its points
  if (!section_open_ && frames_.section_start) frames_.section_start(nd.block);
  section_open_ = true;
  tool_length_as_written(src, block_);
  block_.start = last_target_;
  if (frames_.work_frame) {
    // The points in the source's work coordinates: the writer subtracts the origin the source
    // has in force; A and C stay as they are (never written).
    block_.frame.origin = src.frame.origin;
    block_.target[kA] = block_.start[kA];
    block_.target[kC] = block_.start[kC];
    // The axes that move (a point in a dwell names X, so that it stays a move of its time).
    block_.axis_words = 0;
    for (int a = 0; a < kA; ++a)
      if (block_.target[a] != block_.start[a]) block_.axis_words |= static_cast<std::uint8_t>(1u << a);
    if (block_.axis_words == 0) block_.axis_words = 1u << kX;
  }
  emit_(block_, nd.block, from_tick);
  have_node_ = true;
  after_points_ = frames_.work_frame;
  last_feed_ = block_.feed;
  last_target_ = block_.target;
}

void CompensatedBlocks::add(std::span<const Node> nodes) {
  std::size_t k = 0;
  if (!started_ && !nodes.empty()) {
    started_ = true;
    last_node_ = nodes[0];
    last_target_ = nodes[0].joints;
    k = 1;
  }
  for (; k < nodes.size(); ++k) {
    // Program blocks up to this node's source block are passed in order (their M/S/T words and
    // comments), each source line's motion once as a note.
    while (next_ <= nodes[k].block && next_ < program_.size()) pass_block(next_++);
    node(nodes[k]);
  }
}

void CompensatedBlocks::finish() {
  if (!started_) return;
  if (frames_.work_frame && after_points_) settle_before(next_);
  while (next_ < program_.size()) pass_block(next_++);
}

std::vector<ResolvedBlock> compensated_blocks(std::span<const ResolvedBlock> program, const Result& result,
                                              double period) {
  std::vector<ResolvedBlock> out;
  CompensatedBlocks blocks(program, period, [&out](const ResolvedBlock& b, std::size_t, std::uint64_t) { out.push_back(b); });
  blocks.add(result.nodes);
  blocks.finish();
  return out;
}

std::string acceleration_over_limit(char axis, double peak, double limit) {
  int digits = 0;
  while (digits < 3 && std::llround(peak * std::pow(10.0, digits)) == std::llround(limit * std::pow(10.0, digits))) ++digits;
  char msg[120];
  std::snprintf(msg, sizeof msg, "axis %c acceleration %.*f > limit %.*f", axis, digits, peak, digits, limit);
  return msg;
}

}  // namespace gcpipe::compensate
