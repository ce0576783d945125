#include "compensate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <limits>
#include <memory>
#include <stdexcept>

#include "chain_inverse.hpp"
#include "contour.hpp"
#include "gcpipe/config.hpp"

namespace gcpipe::compensate {


CompensateOptions load_compensate_options(const Config& s) {
  s.reject_unknown({"enabled", "node_period", "path_tolerance", "blend_time", "reference_acceleration", "reference_smoothing", "linearisation_tolerance", "max_iterations", "gain",
                    "max_machine_time", "max_blocks", "slowed_baseline"});
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

/// A node program as the simulation reads it (no interleaved M words): block i is the move to
/// node i + 1 from node i (from `start` for the first: node 0 is the start, at tick 0). Made
/// block by block, not held (a block is 464 bytes, and a long program has a node every 4 ms).
/// `nodes` and `program` must outlive the source; the block it gives is valid until the next one
/// is asked for.
simulate::BlockSource node_program(std::span<const ResolvedBlock> program, const std::vector<Node>& nodes,
                                   const Axes& start, double period) {
  auto buffer = std::make_shared<ResolvedBlock>();
  return {nodes.empty() ? 0 : nodes.size() - 1, [program, &nodes, start, period, buffer](std::size_t i) -> const ResolvedBlock& {
            const Node& nd = nodes[i + 1];
            node_block(program[nd.block], i == 0 ? start : nodes[i].joints, nd.joints, nd.tick - nodes[i].tick, period,
                       *buffer);
            return *buffer;
          }};
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
  std::span<const ResolvedBlock> program;
  std::uint32_t block_at(std::uint64_t tick) const {
    const std::size_t p = nom.progress[std::min<std::size_t>(tick, nom.progress.size() - 1)];
    return nom.block[std::min<std::size_t>(p, nom.block.size() - 1)];
  }
  Vec3 tip_at(const Axes& j, std::uint64_t tick) const {
    return forward_kinematics(model.kin, j, tool_length_of(model, program[block_at(tick)])).tip;
  }
};

// Node grid every `m` ticks, then kinematic linearisation: an interval is halved while
// joint-linear motion between its ends leaves the reference tool-tip path by more than the
// tolerance at its midpoint.
std::vector<std::uint64_t> linearised_grid(const ReferenceClock& clock, std::uint64_t m, double tolerance, Result& res) {
  const Nominal& nom = clock.nom;
  const std::uint64_t E = nom.reference.size();
  std::vector<std::uint64_t> ticks;
  for (std::uint64_t k = 0; k < E; k += m) ticks.push_back(k);
  if (ticks.back() != E - 1) ticks.push_back(E - 1);
  std::vector<std::uint64_t> grid;
  grid.push_back(0);
  std::vector<std::pair<std::uint64_t, std::uint64_t>> stack;
  for (std::size_t k = 1; k < ticks.size(); ++k) {
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
          ++res.linearisation_splits;
          stack.emplace_back(c, b);
          stack.emplace_back(a, c);
          continue;
        }
        res.linearisation_max_deviation = std::max(res.linearisation_max_deviation, dev);
      }
      added.push_back(b);
    }
    std::sort(added.begin(), added.end());
    grid.insert(grid.end(), added.begin(), added.end());
  }
  grid.shrink_to_fit();  // grew node by node; held through the learning
  return grid;
}

// What the source's own TCP blocks would do if run joint-linearly between their IK end points
// (a control without TCP): reported, since it is the error the node program removes.
void measure_source_joint_linear_deviation(const Model& model, std::span<const ResolvedBlock> program, double tolerance,
                                           Result& res) {
  for (const ResolvedBlock& b : program) {
    if (!b.tcp || b.motion != Motion::kLinear) continue;
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

// A series made one value at a time, in order, of which only the last few are kept: the learning
// update and its two smoothing passes are chained through these instead of held as node series
// (the smoothing reads one node ahead, so a pass runs one node ahead of the next).
class InOrder {
 public:
  explicit InOrder(std::function<Axes(std::size_t)> make) : make_(std::move(make)) {}

  /// Value k; k may go back by at most kKept - 1 from the largest asked for.
  Axes at(std::size_t k) {
    while (first_ + kept_.size() <= k) kept_.push_back(make_(first_ + kept_.size()));
    while (first_ + kKept <= k) kept_.pop_front(), ++first_;
    if (k < first_) throw std::logic_error("InOrder: a value no longer kept");
    return kept_[k - first_];
  }

 private:
  static constexpr std::size_t kKept = 4;
  std::function<Axes(std::size_t)> make_;
  std::deque<Axes> kept_;
  std::size_t first_ = 0;  // index of kept_.front()
};

// One zero-phase [1 2 1]/4 pass at node k of n, the two end nodes kept.
Axes smoothed_121(InOrder& in, std::size_t k, std::size_t n) {
  if (k == 0 || k + 1 >= n) return in.at(k);
  const Axes before = in.at(k - 1), at = in.at(k), after = in.at(k + 1);
  Axes out;
  for (std::size_t i = 0; i < kNumAxes; ++i) out[i] = 0.25 * before[i] + 0.5 * at[i] + 0.25 * after[i];
  return out;
}

// The model-inverse start u0 = L r at every node of the grid, projected onto the speed bound,
// node by node in order; the first node is where the machine stands, the last the program's end
// point (the learning may move it, the end stays). It is the learning's first iterate, and the
// learning falls back on it where nothing was accepted yet: made again in each iteration instead
// of holding a third node series for the whole run.
class InverseStart {
 public:
  InverseStart(const Nominal& nom, const std::vector<std::uint64_t>& grid, const Axes& start, const ChainInverse& inverse,
               const Axes& vmax)
      : nom_(nom), grid_(grid), start_(start), inverse_(inverse), vmax_(vmax) {}

  /// Node k's joints; k only grows between calls until restart().
  const Axes& at(std::size_t k) {
    while (next_ <= k) step();
    return joints_;
  }
  void restart() { next_ = 0; }

 private:
  void step() {
    const std::size_t k = next_++;
    const Axes before = joints_;
    if (k + 1 == grid_.size()) joints_ = nom_.reference.back();
    else if (k == 0) joints_ = start_;
    else
      joints_ = apply_inverse(inverse_, nom_.reference, static_cast<std::int64_t>(grid_[k]));
    if (k > 0) project_step(before, joints_, vmax_, static_cast<double>(grid_[k] - grid_[k - 1]) * nom_.period);
  }

  const Nominal& nom_;
  const std::vector<std::uint64_t>& grid_;
  Axes start_;
  const ChainInverse& inverse_;
  Axes vmax_;
  std::size_t next_ = 0;
  Axes joints_{};  // node next_ - 1
};

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

 private:
  const simulate::JointSeries* reference_;
  const std::vector<std::uint64_t>* grid_;
  std::vector<AxesF> offset_;
};

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
      j = nodes.get(k, r);
    }
    before = j;
  }
}

// What one window's part of a node-program run did: the limits it met and its contour error.
struct WindowLimits {
  std::array<std::uint64_t, kNumAxes> saturated{};
  Axes peak_acceleration{};
  double max_contour = 0;
  std::size_t segment = 0;  // of the window's first tick, for the original's demand there
  bool seen = false;
};

// The learning of compensate(), local in time: the program is cut into windows of about a
// second, and an iterate that breaks a limit or does worse in one window is dropped there only
// (its nodes keep their best values, its gain is halved) while the other windows keep learning.
// Each iteration runs the node program (measure), judges every window (judge_windows), keeps
// what improved blended over window boundaries (blend_into_best), and takes a learning step on
// each window's best error (learning_step).
class WindowedLearning {
 public:
  WindowedLearning(const Model& model, const Nominal& nom, std::span<const ResolvedBlock> program, const Axes& start,
                   const Evaluation& before, const CompensateOptions& opt, Result& res)
      : model_(model), nom_(nom), program_(program), start_(start), opt_(opt), res_(res), T_(nom.period),
        E_(nom.reference.size()), clock_{model, nom, program},
        grid_(linearised_grid(clock_, static_cast<std::uint64_t>(std::max(1L, std::lround(opt.node_period / T_))),
                              opt.linearisation_tolerance, res)),
        chain_inverse_(design_chain_inverse(model)),
        vbound_(interpolate::speed_bound(model.interp)), Wt_(static_cast<std::uint64_t>(std::max(1L, std::lround(1.0 / T_)))),
        nwin_(static_cast<std::size_t>((E_ + 4 * Wt_) / Wt_) + 1), nseg_(std::max<std::size_t>(1, nom.segments.size())),
        R_(static_cast<std::uint64_t>(std::lround(0.1 / T_))), base_(before.demand),
        inverse_(nom, grid_, start, chain_inverse_, vbound_), win_best_(nwin_, std::numeric_limits<double>::infinity()),
        win_gain_(nwin_, opt.gain), win_stalls_(nwin_, 0), win_learned_(nwin_, false), nodes_(nom.reference, grid_),
        best_(nom.reference, grid_) {
    measure_source_joint_linear_deviation(model, program, opt.linearisation_tolerance, res);
    for (std::size_t k = 0; k < grid_.size(); ++k) nodes_.set(k, inverse_.at(k));  // the start u0 = L r
    project_speed(nodes_, grid_, vbound_, T_);  // as stored (InverseStart projected the exact values)
    best_error_.reserve(E_ + Wt_);  // the run settles a little past the reference's end
    best_ = nodes_;
    window_err_.reserve(Wt_);
    // The grid's making (its tick list, its growth) and the operator's design are freed: their
    // pages go back before the iterations, which are the peak.
    simulate::give_back_freed_memory();
  }

  void run(const Progress& progress) {
    // The node program is made block by block as it is simulated, from nodes_ as they are then.
    const simulate::BlockSource blocks = learning_program();
    auto node_source = [this](std::uint32_t i) { return clock_.block_at(grid_[std::min<std::size_t>(i + 1, grid_.size() - 1)]); };
    for (int it = 0; it <= opt_.max_iterations; ++it) {
      if (progress) progress("compensating (learning iterations)", static_cast<std::uint64_t>(it), static_cast<std::uint64_t>(opt_.max_iterations));
      std::vector<WindowLimits> lim;
      std::uint64_t ticks = 0;
      const Evaluation ev = measure(blocks, node_source, lim, ticks);
      Iteration rec;
      rec.index = it;
      rec.max_contour = ev.contour.max;
      rec.rms_contour = ev.contour.rms;
      rec.gain = *std::max_element(win_gain_.begin(), win_gain_.end());
      if (!ev.stats.ok || ev.stats.interp.velocity_limited_blocks > 0) {
        rec.accepted = false;
        rec.rejected_because = ev.stats.ok ? "points slowed by the interpolator's speed bound" : ev.stats.message;
        res_.iterations.push_back(rec);
        last_rejection_ = rec.rejected_because;
        break;
      }
      // The error series is as long as the longest run learned from (apply_inverse holds its ends).
      if (best_error_.size() < ticks) best_error_.resize(ticks, AxesF{});
      std::vector<bool> improved(nwin_, false);
      const std::string why_iteration = judge_windows(lim, improved);
      rec.accepted = why_iteration.empty();
      rec.rejected_because = why_iteration;
      res_.iterations.push_back(rec);
      blend_into_best(improved);
      if (all_stalled(lim) || it == opt_.max_iterations) break;
      nodes_ = best_;
      project_speed(nodes_, grid_, vbound_, T_);
      learning_step();
      project_speed(nodes_, grid_, vbound_, T_);
    }
    finish();
  }

 private:
  // The node program of nodes_ as they are when it is run, block by block (node_program's blocks
  // from the stored joints). The blocks are asked for in order, so the end of block i is kept as
  // the start of block i + 1 instead of being made again from the stored joints.
  simulate::BlockSource learning_program() {
    struct Buffer {
      ResolvedBlock block;
      std::size_t end_node = 0;  // the node block.target is (0: none yet)
    };
    auto buffer = std::make_shared<Buffer>();
    return {grid_.empty() ? 0 : grid_.size() - 1, [this, buffer](std::size_t i) -> const ResolvedBlock& {
              const Axes from = i == 0 ? start_ : buffer->end_node == i ? buffer->block.target : nodes_.get(i);
              node_block(program_[clock_.block_at(grid_[i + 1])], from, nodes_.get(i + 1), grid_[i + 1] - grid_[i], T_,
                         buffer->block);
              buffer->end_node = i + 1;
              return buffer->block;
            }};
  }

  std::size_t window_of(std::uint64_t tick) const {
    return std::min<std::size_t>(static_cast<std::size_t>(tick / Wt_), nwin_ - 1);
  }
  std::size_t segment_of_block(std::uint32_t b) const {
    return nom_.segment_of_block.empty() ? 0 : std::min<std::size_t>(nom_.segment_of_block[b], nseg_ - 1);
  }

  // Which limit a window's run broke, or empty: the torque-limited ticks and the smoothed
  // command's acceleration, against the original's own demand in the window's segment.
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
        std::snprintf(msg, sizeof msg, "axis %c acceleration %.0f > limit %.0f", kAxisLetters[i], lw.peak_acceleration[i], alim);
        why = msg;
      }
    }
    return why;
  }

  // A window that does better within the limits hands its error r - y to the learning. That is
  // known when its last tick has run, so the run keeps only the error of its current window (1 s)
  // and copies it to best_error_ there, instead of a whole-program series per iteration.
  void keep_if_improved(std::size_t w, const WindowLimits& lw) {
    if (!lw.seen || !limit_broken(lw).empty() || !(lw.max_contour < win_best_[w])) return;
    const std::size_t n0 = w * Wt_, n1 = n0 + window_err_.size();
    if (best_error_.size() < n1) best_error_.resize(n1, AxesF{});
    for (std::size_t n = n0; n < n1; ++n)
      for (std::size_t i = 0; i < kNumAxes; ++i) best_error_[n][i] = static_cast<float>(window_err_[n - n0][i]);
  }

  // Torque saturation, smoothed-command acceleration and contour error of one node-program run
  // per window; each window's error r - y per tick goes to keep_if_improved as the window ends.
  // Returns the run's evaluation and, in `ticks`, how many ticks it ran.
  Evaluation measure(const simulate::BlockSource& blocks, const std::function<std::uint32_t(std::uint32_t)>& source,
                     std::vector<WindowLimits>& lim, std::uint64_t& ticks) {
    lim.assign(nwin_, WindowLimits{});
    Axes c1{}, c2{};
    std::uint64_t seen = 0;
    std::size_t current = 0;  // the window being run
    window_err_.clear();
    Evaluation ev = evaluate(
        model_, nom_, program_, blocks, start_, source,
        [&](const Tick& t) {
          const std::size_t w = window_of(t.n);
          if (w != current) {
            keep_if_improved(current, lim[current]);
            window_err_.clear();
            current = w;
          }
          WindowLimits& L0 = lim[w];
          if (!L0.seen) L0.segment = segment_of_block(source(t.block)), L0.seen = true;
          L0.max_contour = std::max(L0.max_contour, t.contour);
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
          const std::size_t n = static_cast<std::size_t>(t.n);
          if (n >= (w + 1) * Wt_) return;  // past the last window's second: not learned from
          const Axes& r = n < nom_.reference.size() ? nom_.reference[n] : nom_.reference.back();
          Axes e;
          for (std::size_t i = 0; i < kNumAxes; ++i) e[i] = r[i] - t.actual[i];
          window_err_.push_back(e);
        },
        true);
    keep_if_improved(current, lim[current]);
    ticks = seen;
    return ev;
  }

  // Every window's verdict on the run just measured: improved within the limits (its error is
  // in best_error_ already, from measure), or its gain halved; a stall count per window. Returns
  // the first limit broken in this iteration, or empty.
  std::string judge_windows(const std::vector<WindowLimits>& lim, std::vector<bool>& improved) {
    std::string why_iteration;
    for (std::size_t w = 0; w < nwin_; ++w) {
      if (!lim[w].seen) continue;
      const std::string why = limit_broken(lim[w]);
      const double emax = lim[w].max_contour;
      const double previous = win_best_[w];
      if (why.empty() && emax < previous) {
        win_best_[w] = emax;
        improved[w] = true;
        win_learned_[w] = true;
      } else {
        win_gain_[w] *= 0.5;
      }
      if (!why.empty()) {
        char when[80];
        std::snprintf(when, sizeof when, " at t %.0f-%.0f s", static_cast<double>(w * Wt_) * T_, static_cast<double>((w + 1) * Wt_) * T_);
        last_rejection_ = why + when;
        res_.window_limits[w] = last_rejection_;
        if (why_iteration.empty()) why_iteration = last_rejection_;
      }
      win_stalls_[w] = why.empty() && emax < 0.99 * previous ? 0 : win_stalls_[w] + 1;
    }
    return why_iteration;
  }

  // A per-window value at every node, moving-averaged over +-0.1 s of nodes, node by node in
  // order (WindowAverage): four of these per iteration were a double a node each.
  WindowAverage over_nodes(std::function<double(std::size_t)> value) const {
    return WindowAverage(grid_, R_, [value = std::move(value), this](std::uint64_t tick) { return value(window_of(tick)); });
  }

  // Accepting some windows and not others must not leave a step in the commands at a window
  // boundary (the step itself would break the acceleration limit there): the per-window
  // decisions are blended over about 0.1 s of nodes on either side of each boundary.
  void blend_into_best(const std::vector<bool>& improved) {
    WindowAverage take = over_nodes([&](std::size_t w) { return improved[w] ? 1.0 : 0.0; });
    WindowAverage learned = over_nodes([&](std::size_t w) { return win_learned_[w] ? 1.0 : 0.0; });
    WindowAverage blend = over_nodes([&](std::size_t w) { return win_gain_[w]; });
    inverse_.restart();
    for (std::size_t k = 1; k < grid_.size(); ++k) {
      // Where nothing was accepted yet: the model-inverse start blended back towards the
      // reference (the uncompensated motion, gentler than the program's own) by the gain.
      const Axes r = best_.reference(k);
      const Axes& u0 = inverse_.at(k);
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
    for (std::size_t w = 0; w < nwin_; ++w) stalled = stalled && (!lim[w].seen || win_stalls_[w] >= 3);
    return stalled;
  }

  // Learning update on each window's best error, zero-phase smoothed over nodes ([1 2 1]/4
  // twice) so that the derivative term does not feed tick-scale roughness back.
  void learning_step() {
    WindowAverage gain_at = over_nodes([&](std::size_t w) { return win_learned_[w] ? win_gain_[w] : 0.0; });
    const std::size_t n = grid_.size();
    InOrder raw_update([&](std::size_t k) {
      Axes du{};
      const double gain_k = k == 0 ? 0.0 : gain_at.at(k);
      if (gain_k > 0) {
        du = apply_inverse(chain_inverse_, best_error_, static_cast<std::int64_t>(grid_[k]));
        for (std::size_t i = 0; i < kNumAxes; ++i) du[i] *= gain_k;
      }
      return du;
    });
    InOrder once([&](std::size_t k) { return smoothed_121(raw_update, k, n); });
    InOrder twice([&](std::size_t k) { return smoothed_121(once, k, n); });
    for (std::size_t k = 1; k + 1 < n; ++k) {
      const Axes du = twice.at(k);
      const Axes r = nodes_.reference(k);
      Axes j = nodes_.get(k, r);
      for (std::size_t i = 0; i < kNumAxes; ++i) {
        const auto& tr = model_.kin.travel[i];
        j[i] = std::clamp(j[i] + du[i], tr.min, tr.max);
      }
      nodes_.set(k, r, j);
    }
  }

  void finish() {
    bool any = false;
    for (std::size_t w = 0; w < nwin_; ++w) any = any || win_learned_[w];
    // The learning's series go before the result's nodes (56 bytes a node) are made.
    nodes_.release();
    std::vector<AxesF>().swap(best_error_);
    res_.nodes.resize(grid_.size());
    for (std::size_t k = 0; k < grid_.size(); ++k) {
      Node& nd = res_.nodes[k];
      nd.tick = grid_[k];
      nd.block = clock_.block_at(grid_[k]);
      nd.joints = best_.get(k);
    }
    best_.release();
    res_.compensated = any;
    if (!res_.compensated) res_.note = "no iterate stayed within the axis limits: " + last_rejection_;
    else if (!last_rejection_.empty()) res_.note = "learning held back where it would exceed a limit: " + last_rejection_;
  }

  const Model& model_;
  const Nominal& nom_;
  std::span<const ResolvedBlock> program_;
  Axes start_;
  const CompensateOptions& opt_;
  Result& res_;
  double T_;
  std::uint64_t E_;
  ReferenceClock clock_;
  std::vector<std::uint64_t> grid_;
  ChainInverse chain_inverse_;  // the learning operator L, per axis
  Axes vbound_;
  std::uint64_t Wt_;    // ticks in a window (1 s)
  std::size_t nwin_;
  std::size_t nseg_;
  std::uint64_t R_;     // ticks of the decisions' blend (0.1 s)
  const std::vector<SegmentDemand>& base_;
  InverseStart inverse_;  // the model-inverse start, node by node
  std::vector<double> win_best_, win_gain_;
  std::vector<int> win_stalls_;
  std::vector<bool> win_learned_;
  NodeJoints nodes_, best_;       // the current iterate and the best per window, on grid_
  std::vector<AxesF> best_error_;  // r - y per tick, each window from its best run
  std::vector<Axes> window_err_;  // the current window's r - y, while a run is measured
  std::string last_rejection_;
};

}  // namespace

Result compensate(const Model& model, const Nominal& nom, std::span<const ResolvedBlock> program,
                  const Axes& start, const Evaluation& before, const CompensateOptions& opt,
                  const Progress& progress) {
  Result res;
  if (nom.reference_too_long) {
    res.note = "not compensated: the planned reference would run longer than compensate.max_machine_time";
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
  WindowedLearning(model, nom, program, start, before, opt, res).run(progress);
  simulate::give_back_freed_memory();  // the learning's series, before the program is written
  return res;
}

void for_each_compensated_block(std::span<const ResolvedBlock> program, const Result& result, double period,
                                const std::function<void(const ResolvedBlock&)>& emit) {
  if (result.nodes.empty()) return;
  const Axes start = result.nodes.front().joints;
  const simulate::BlockSource nodes = node_program(program, result.nodes, start, period);
  std::size_t next = 0;  // next program block not yet passed
  std::uint64_t noted_line = 0;  // source line of the last motion note
  bool have_node = false;
  double last_feed = 0;
  Axes last_target = start;  // where the last block written leaves the machine
  auto pass_block = [&](std::size_t i) {
    const ResolvedBlock& b = program[i];
    ResolvedBlock c = b;
    c.tcp = false;
    c.tool_length_active = false;
    c.tool_length = 0;
    c.tool_length_offset = 0;
    if (b.motion != Motion::kNone && b.line == noted_line && b.motion != Motion::kDwell) return;
    if (b.motion != Motion::kNone) {
      noted_line = b.line;
      // A motion of the source is carried by the timed points that follow; the block stays as a
      // note with its text so that the operator can find every source line.
      std::string text = b.text;
      std::replace(text.begin(), text.end(), '(', '[');
      std::replace(text.begin(), text.end(), ')', ']');
      c.motion = Motion::kNone;
      c.dwell = 0;
      c.axis_words = 0;
      c.comment = (b.motion == Motion::kDwell ? "dwell, held by the timed points below: " : "source: ") + text;
      c.percent = false;
      c.program_number = -1;
    }
    // Between timed points the inverse-time mode stays (no G94/G93 flip-flop in the output);
    // before the first point the block keeps its own feed mode.
    c.start = c.target = last_target;
    if (have_node) {
      c.feed_mode = FeedMode::kInverseTime;
      c.feed = last_feed;
    }
    emit(c);
  };
  for (std::size_t k = 0; k < nodes.count; ++k) {
    const std::uint32_t src = result.nodes[k + 1].block;
    // Program blocks up to this node's source block are passed in order (their M/S/T words and
    // comments), each source line's motion once as a note.
    while (next <= src && next < program.size()) {
      pass_block(next++);
    }
    const ResolvedBlock& node = nodes.at(k);
    emit(node);
    have_node = true;
    last_feed = node.feed;
    last_target = node.target;
  }
  while (next < program.size()) pass_block(next++);
}

std::vector<ResolvedBlock> compensated_blocks(std::span<const ResolvedBlock> program, const Result& result,
                                              double period) {
  std::vector<ResolvedBlock> out;
  for_each_compensated_block(program, result, period, [&out](const ResolvedBlock& b) { out.push_back(b); });
  return out;
}

}  // namespace gcpipe::compensate
