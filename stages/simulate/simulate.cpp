#include "simulate.hpp"

#include <algorithm>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <limits>
#include <stdexcept>

#include "contour.hpp"
#include "nominal_path.hpp"
#include "gcpipe/chunked_worker.hpp"
#include "gcpipe/config.hpp"

namespace gcpipe::simulate {

namespace {


bool is_motion(Motion m) {
  return m == Motion::kRapid || m == Motion::kLinear || m == Motion::kArcCW || m == Motion::kArcCCW ||
         m == Motion::kTrochoidSlot;
}

}  // namespace

namespace {

void add_error(ErrorStats& s, double& sum_sq, std::uint64_t& count, double e, double t, std::uint64_t line) {
  if (e > s.max) {
    s.max = e;
    s.t_at_max = t;
    s.line_at_max = line;
  }
  sum_sq += e * e;
  ++count;
}

/// Circle through a segment's nominal tip points (Kasa's algebraic fit, in X Y), accepted when
/// every point lies within 1e-4 R of it, Z is constant and the points cover most of a turn. Two
/// passes over the points (the fit's sums, then each point against the fit), so that they are
/// made again from the recorded run rather than held (24 bytes a tick: 38 MB on an hour).
class CircleFit {
 public:
  void sum(const Vec3& p) {
    const double x = p[0], y = p[1], z = x * x + y * y;
    sx += x; sy += y; sxx += x * x; syy += y * y; sxy += x * y; sxz += x * z; syz += y * z; sz += z;
    zmin = std::min(zmin, p[2]);
    zmax = std::max(zmax, p[2]);
    ++n_;
  }
  /// After the sums: the circle they fit; false when there is none to check.
  bool solve() {
    if (n_ < 50) return false;
    const double n = static_cast<double>(n_);
    // Solve [sxx sxy sx; sxy syy sy; sx sy n] [a b c] = [sxz syz sz]; centre (a/2, b/2).
    double a[3][4] = {{sxx, sxy, sx, sxz}, {sxy, syy, sy, syz}, {sx, sy, n, sz}};
    for (int c = 0; c < 3; ++c) {
      int piv = c;
      for (int r = c + 1; r < 3; ++r)
        if (std::abs(a[r][c]) > std::abs(a[piv][c])) piv = r;
      if (std::abs(a[piv][c]) < 1e-300) return false;
      for (int j = 0; j < 4; ++j) std::swap(a[c][j], a[piv][j]);
      for (int r = 0; r < 3; ++r) {
        if (r == c) continue;
        const double f = a[r][c] / a[c][c];
        for (int j = c; j < 4; ++j) a[r][j] -= f * a[c][j];
      }
    }
    const double A = a[0][3] / a[0][0], B = a[1][3] / a[1][1], C = a[2][3] / a[2][2];
    cx_ = A / 2, cy_ = B / 2;
    const double r2 = C + cx_ * cx_ + cy_ * cy_;
    if (!(r2 > 0)) return false;
    R_ = std::sqrt(r2);
    return solved_ = true;
  }
  /// The second pass, point by point in the same order.
  void check(const Vec3& p) {
    if (!solved_) return;
    const double ang = std::atan2(p[1] - cy_, p[0] - cx_);
    if (checked_++ == 0) prev_ = ang;
    worst_ = std::max(worst_, std::abs(std::hypot(p[0] - cx_, p[1] - cy_) - R_));
    double d = ang - prev_;
    if (d > M_PI) d -= 2 * M_PI;
    if (d < -M_PI) d += 2 * M_PI;
    span_ += d;
    prev_ = ang;
  }
  void describe(Segment& seg) const {
    if (solved_ && worst_ <= 1e-4 * R_ && zmax - zmin <= 1e-6 && std::abs(span_) >= 1.5 * M_PI) {
      seg.circle = true;
      seg.circle_radius = R_;
      seg.circle_centre = {cx_, cy_};
    }
  }

 private:
  double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0, sxz = 0, syz = 0, sz = 0, zmin = 1e300, zmax = -1e300;
  std::size_t n_ = 0, checked_ = 0;
  bool solved_ = false;
  double cx_ = 0, cy_ = 0, R_ = 0, worst_ = 0, span_ = 0, prev_ = 0;
};

// The drives are built for the interpolation period; a period too short for a drive's delays
// (interpolate.period 0.00001 s against Tp = 0.0155 s) fails in the servo with its own words, which
// name neither key. Build them once here, where both keys are known, and say which to change.
void check_drives_at_period(const Model& m, const std::string& drives_file) {
  try {
    servo::ServoSimulator probe(m.drives, m.interp.period);
  } catch (const ConfigError& e) {
    char msg[200];
    std::snprintf(msg, sizeof msg, "interpolate.period = %g s does not fit the drives in %s: ", m.interp.period,
                  drives_file.c_str());
    throw ConfigError(msg + std::string(e.what()) +
                      "; raise interpolate.period (default 0.001 s) or lower the drive's Tp in the drives file");
  }
}

}  // namespace

Model load_model(const PipelineConfig& pc) {
  if (!pc.root.has("servo"))
    throw pc.root.error("servo", "missing: name the drives file, e.g. 'servo: {drives: drives/seed002.yaml}'");
  const Config servo_section = pc.root.section("servo");
  servo_section.reject_unknown({"drives"});
  if (!servo_section.has("drives"))
    throw servo_section.error("drives", "missing: the drives file, e.g. drives/seed002.yaml");
  Model m;
  m.kin = pc.machine.kinematics;
  m.start = pc.machine.start_position;
  m.drives = servo::load_drives(Config::load_file(servo_section.file_path("drives", "the drives file, e.g. drives/seed002.yaml")));
  m.interp = interpolate::load_interpolate_options(pc.root.section("interpolate"));
  m.interp.max_velocity = m.kin.max_velocity;
  m.interp.max_acceleration = m.kin.max_acceleration;
  for (std::size_t i = 0; i < kNumAxes; ++i) {
    m.interp.travel_min[i] = m.kin.travel[i].min;
    m.interp.travel_max[i] = m.kin.travel[i].max;
    m.interp.smoothing_time[i] = m.drives.axes[i].Ts;
  }
  check_drives_at_period(m, servo_section.file_path("drives", "the drives file").string());
  return m;
}

Axes machine_start(const MachineKinematics& kin, const ResolvedBlock& b, double tool_length) {
  if (!b.tcp) return b.start;
  const Vec3 tip{b.start[kX], b.start[kY], b.start[kZ]};
  return b.tool_vector_mode ? inverse_kinematics(kin, ToolPose{tip, b.tool_vector}, b.start, tool_length).joints
                            : inverse_kinematics_ac(kin, tip, b.start[kA], b.start[kC], tool_length).joints;
}

double tool_length_of(const Model& model, const ResolvedBlock& b) {
  return b.tool_length_active ? b.tool_length : model.kin.tool_length;
}

double tool_length_of(const Model& model, const BlockBrief& b) {
  return b.tool_length_active ? b.tool_length : model.kin.tool_length;
}

namespace {
interpolate::InterpolateOptions run_options(const Model& model, std::uint64_t max_ticks) {
  interpolate::InterpolateOptions io = model.interp;
  io.kinematics = &model.kin;  // TCP blocks: inverse kinematics per tick, feed along the tool tip
  // The bound holds inside blocks too: one block past it is refused before its first tick.
  if (max_ticks != UINT64_MAX) io.max_time = static_cast<double>(max_ticks) * model.interp.period;
  return io;
}
}  // namespace

MachineRun::MachineRun(const Model& model, const Axes& start, std::uint32_t first_block, std::uint64_t max_ticks)
    : interp_(run_options(model, max_ticks), start), sink_(model) {
  sink_.max_ticks = max_ticks;
  sink_.block = first_block;
  sink_.raw.emplace_back(start, first_block);
  first_ = sink_.sim.reset(start, 0.0);
}

void MachineRun::Sink::sample(const Axes& c) {
  servo::ServoSample s;
  if (sim.push(c, s)) emit(s);
}

void MachineRun::Sink::emit(const servo::ServoSample& s) {
  Tick t;
  t.n = n++;
  t.raw = raw.front().first;
  t.block = raw.front().second;
  raw.pop_front();
  t.command = s.command;
  t.actual = s.actual;
  t.torque = s.torque;
  t.saturated = s.saturated;
  for (std::size_t i = 0; i < kNumAxes; ++i) {
    if (s.saturated & (1u << i)) ++saturated[i];
  }
  if (t.n >= max_ticks) {
    over = true;
    return;
  }
  (*on_tick)(t);
}

void MachineRun::emit_first() {
  if (!sink_.first_pending) return;
  sink_.first_pending = false;
  sink_.emit(first_);
}

interpolate::InterpolateResult MachineRun::add(const ResolvedBlock& b, std::uint32_t source, const TickFn& on_tick) {
  sink_.on_tick = &on_tick;
  emit_first();
  // Samples belong to the block that moves (or dwells): a block without motion emits none,
  // and the settling after the last move belongs to that move.
  if (b.motion != Motion::kNone) sink_.block = source;
  return interp_.add(b, sink_);
}

void MachineRun::finish(const TickFn& on_tick) {
  sink_.on_tick = &on_tick;
  emit_first();
  interp_.finish(sink_);
  servo::ServoSample s;
  while (sink_.sim.flush(s)) sink_.emit(s);
}

ProgramRunner::ProgramRunner(const Model& model, const Axes& start, std::uint32_t first_block, std::uint64_t max_ticks)
    : period_(model.interp.period), max_ticks_(max_ticks), run_(model, start, first_block, max_ticks) {}

bool ProgramRunner::add(const ResolvedBlock& b, std::uint32_t i, const TickFn& on_tick) {
  if (stopped_) return false;
  const auto r = run_.add(b, i, on_tick);
  if (r.status != interpolate::InterpolateStatus::kOk) {
    stats_.ok = false;
    stats_.message = r.message;
    if (r.status == interpolate::InterpolateStatus::kTooLong) stats_.message += " (compensate.max_machine_time)";
    stats_.failed_line = b.line;
    stopped_ = true;
    return false;
  }
  if (run_.over()) {
    char msg[160];
    std::snprintf(msg, sizeof msg, "the program runs longer than %.0f s of machine time (compensate.max_machine_time)",
                  static_cast<double>(max_ticks_) * period_);
    stats_.ok = false;
    stats_.message = msg;
    stats_.failed_line = b.line;
    stopped_ = over_ = true;
    return false;
  }
  return true;
}

RunStats ProgramRunner::finish(const TickFn& on_tick) {
  // A run past max_ticks is cut off there; one stopped at a block it cannot run settles where
  // it stopped.
  if (!over_) run_.finish(on_tick);
  stats_.ticks = run_.ticks();
  stats_.saturated_ticks = run_.saturated_ticks();
  stats_.interp = run_.interp_stats();
  return stats_;
}

RunStats run_program(const Model& model, const BlockSource& blocks, const Axes& start,
                     const std::function<void(const Tick&)>& on_tick, std::uint64_t max_ticks) {
  std::uint32_t first = 0;
  while (first + 1 < blocks.count && blocks.at(first).motion == Motion::kNone) ++first;
  ProgramRunner run(model, start, first, max_ticks);
  for (std::size_t i = 0; i < blocks.count; ++i)
    if (!run.add(blocks.at(i), static_cast<std::uint32_t>(i), on_tick)) break;
  return run.finish(on_tick);
}

namespace {

/// Segments of the program, from its blocks alone: a dwell or a program stop ends one (the
/// machine is at rest or about to be), and positioning (rapids) and cutting are separate segments.
std::vector<std::uint32_t> segment_blocks(std::span<const BlockBrief> program, std::size_t& count) {
  std::vector<std::uint32_t> of_block(program.size(), 0);
  std::uint32_t seg = 0;
  bool seg_has_motion = false;
  Motion last_motion = Motion::kNone;
  for (std::size_t i = 0; i < program.size(); ++i) {
    const BlockBrief& b = program[i];
    if (is_motion(b.motion) && b.motion != Motion::kRapid && last_motion == Motion::kRapid && seg_has_motion) ++seg;
    if (is_motion(b.motion)) seg_has_motion = true, last_motion = b.motion;
    of_block[i] = seg;
    if ((b.motion == Motion::kDwell || b.stop != ProgramStop::kNone) && seg_has_motion) {
      ++seg;
      seg_has_motion = false;
    }
  }
  count = static_cast<std::size_t>(seg) + 1;
  return of_block;
}

/// Passes over the raw samples that do little per tick map them faster than the trimmer thread
/// follows: they trim as they go, every this many ticks (2.5 MB of exact samples).
constexpr std::size_t kTrimEvery = std::size_t{1} << 16;

/// Every tick of a recorded run on a feed move that moves the nominal tip: its segment and tip.
template <class F>
void for_each_cutting_tip(const Model& model, const Nominal& nom, F&& f) {
  for (std::size_t n = 0; n < nom.raw.size(); ++n) {
    if (n % kTrimEvery == 0) trim_scratch_if_grown();
    const BlockBrief& b = nom.brief[nom.block[n]];
    if (is_motion(b.motion) && b.motion != Motion::kRapid && (n == 0 || nom.raw[n] != nom.raw[n - 1]))
      f(nom.segment_of_block[nom.block[n]], forward_kinematics(model.kin, nom.raw[n], tool_length_of(model, b)).tip);
  }
}

/// Times, lines and circles of the segments, from the recorded nominal run.
void describe_segments(const Model& model, Nominal& nom) {
  const std::size_t nseg = nom.segments.size();
  std::vector<bool> seen(nseg, false);
  std::uint32_t last_block = std::numeric_limits<std::uint32_t>::max();
  for (std::size_t n = 0; n < nom.raw.size(); ++n) {
    if (n % kTrimEvery == 0) trim_scratch_if_grown();
    const std::uint32_t b = nom.block[n];
    const std::uint32_t s = nom.segment_of_block[b];
    Segment& g = nom.segments[s];
    const double t = static_cast<double>(n) * nom.period;
    if (!seen[s]) {
      seen[s] = true;
      g.t_begin = t;
      g.first_line = nom.brief[b].line;
    }
    g.t_end = t;
    if (b != last_block && is_motion(nom.brief[b].motion)) g.last_line = std::max(g.last_line, nom.brief[b].line);
    last_block = b;
  }
  std::vector<CircleFit> fits(nseg);
  for_each_cutting_tip(model, nom, [&](std::uint32_t s, const Vec3& tip) { fits[s].sum(tip); });
  bool any = false;
  for (CircleFit& f : fits) any = f.solve() || any;
  if (any) for_each_cutting_tip(model, nom, [&](std::uint32_t s, const Vec3& tip) { fits[s].check(tip); });
  for (std::size_t s = 0; s < nseg; ++s) {
    if (nom.segments[s].last_line == 0) nom.segments[s].last_line = nom.segments[s].first_line;
    fits[s].describe(nom.segments[s]);
  }
}

double max_ticks_of(const Model& model, double max_machine_time) {
  return std::floor(max_machine_time / model.interp.period);
}

std::uint64_t tick_bound(double max_ticks) {
  return max_ticks < 1.8e19 ? static_cast<std::uint64_t>(max_ticks) : UINT64_MAX;
}

void add_tracking(AxisStats& axes, const Axes& reference, const Axes& actual) {
  for (std::size_t i = 0; i < kNumAxes; ++i)
    axes.max_tracking[i] = std::max(axes.max_tracking[i], std::abs(reference[i] - actual[i]));
}

/// The distance of the program's own actual joints from the planned reference, tick by tick. The
/// reference is planned after the run, so the run is simulated once more for it (interpolator and
/// drives only, the same ticks): cheaper than holding the actual joints of the whole run, 40 bytes
/// a tick, through the planner, where the peak memory is.
void add_tracking_against_reference(const Model& model, std::span<const ResolvedBlock> program, const Axes& start,
                                    const Nominal& nom, std::uint64_t max_ticks, AxisStats& axes) {
  const Axes& ref_end = nom.reference.empty() ? start : nom.reference.back();
  run_program(
      model, program, start,
      [&](const Tick& t) {
        const auto n = static_cast<std::size_t>(t.n);
        add_tracking(axes, n < nom.reference.size() ? nom.reference[n] : ref_end, t.actual);
      },
      max_ticks);
}

/// What a tap sees of a tick: the tick with its tool tip and its contour error (0 off cutting moves).
void hand_on(const std::function<void(const Tick&)>& tap, const Tick& t, bool cutting, double e, const Vec3& tip) {
  if (!tap) return;
  Tick marked = t;
  marked.contour = cutting ? e : 0.0;
  marked.tip = tip;
  tap(marked);
}

}  // namespace

/// The figures of one run against the nominal path, gathered tick by tick: contour error on
/// cutting moves and on rapids, per segment, what the run demanded of the axes, following error,
/// travel margin, and the decimated series for the figures.
class RunAccumulator {
 public:
  /// `series`: gather the decimated series for the figures (a streaming run without a report
  /// draws none, and growing them cost it page faults and copies).
  RunAccumulator(const Model& model, std::size_t segments, bool series = true) : model_(model), keep_series_(series) {
    ev_.per_segment.assign(segments, ErrorStats{});
    ev_.demand.assign(std::max<std::size_t>(1, segments), SegmentDemand{});
    seg_sq_.assign(segments, 0.0);
    seg_n_.assign(segments, 0);
    for (std::size_t i = 0; i < kNumAxes; ++i) ev_.axes.travel_margin[i] = std::numeric_limits<double>::infinity();
  }

  /// One tick: `b` the program block it stands for, in segment `seg`; `e` the distance of the
  /// actual tool tip `tip` to the nominal path, whose nearest point is `nearest`.
  /// Returns whether the tick is on a cutting move (where the contour error counts).
  bool add(const Tick& t, const ResolvedBlock& b, std::uint32_t seg, double e, const Vec3& tip, const Vec3& nearest) {
    const double time = static_cast<double>(t.n) * model_.interp.period;
    const bool cutting = is_cutting(b);
    if (cutting) add_error(ev_.contour, sum_sq_, count_, e, time, b.line);
    else if (b.motion == Motion::kRapid) add_error(ev_.rapid, rapid_sq_, rapid_count_, e, time, b.line);
    if (cutting && seg < ev_.per_segment.size()) add_error(ev_.per_segment[seg], seg_sq_[seg], seg_n_[seg], e, time, b.line);
    add_demand(t, ev_.demand[std::min<std::size_t>(seg, ev_.demand.size() - 1)]);
    add_axes(t);
    if (keep_series_) add_series(t, cutting ? e : 0.0, seg, tip, nearest);
    return cutting;
  }

  /// The distance of the actual joints from the planned reference at the same tick.
  void track(const Axes& reference, const Axes& actual) { add_tracking(ev_.axes, reference, actual); }

  Evaluation finish(const RunStats& stats) {
    ev_.stats = stats;
    ev_.contour.rms = rms(sum_sq_, count_);
    ev_.rapid.rms = rms(rapid_sq_, rapid_count_);
    for (std::size_t s = 0; s < ev_.per_segment.size(); ++s) ev_.per_segment[s].rms = rms(seg_sq_[s], seg_n_[s]);
    for (std::size_t i = 0; i < kNumAxes; ++i) {
      ev_.axes.rms_following[i] = rms(fe_sq_[i], ticks_);
      ev_.axes.peak_velocity[i] = stats.interp.peak_velocity[i];
      ev_.axes.peak_acceleration[i] = stats.interp.peak_acceleration[i];
      ev_.axes.saturated_ticks[i] = stats.saturated_ticks[i];
    }
    return std::move(ev_);
  }

 private:
  static double rms(double sum_sq, std::uint64_t n) { return n ? std::sqrt(sum_sq / static_cast<double>(n)) : 0.0; }

  void add_demand(const Tick& t, SegmentDemand& dm) {
    const double T = model_.interp.period;
    for (std::size_t i = 0; i < kNumAxes; ++i) {
      if (t.saturated & (1u << i)) ++dm.saturated_ticks[i];
      if (t.n >= 2)
        dm.peak_acceleration[i] = std::max(dm.peak_acceleration[i], std::abs(t.command[i] - 2 * c1_[i] + c2_[i]) / (T * T));
    }
    c2_ = c1_;
    c1_ = t.command;
  }

  void add_axes(const Tick& t) {
    ++ticks_;
    for (std::size_t i = 0; i < kNumAxes; ++i) {
      const double fe = t.command[i] - t.actual[i];
      ev_.axes.max_following[i] = std::max(ev_.axes.max_following[i], std::abs(fe));
      fe_sq_[i] += fe * fe;
      const auto& tr = model_.kin.travel[i];
      ev_.axes.travel_margin[i] = std::min(ev_.axes.travel_margin[i], std::min(t.actual[i] - tr.min, tr.max - t.actual[i]));
    }
  }

  // The series keeps one point per bucket of ticks (the largest contour error in it, the rest
  // at its end). The length of the run is not known in advance: when the series reaches
  // 2 kSeriesPoints the buckets are merged in pairs and doubled, so it ends with kSeriesPoints
  // to 2 kSeriesPoints points.
  static constexpr std::size_t kSeriesPoints = 20000;

  void add_series(const Tick& t, double e, std::uint32_t seg, const Vec3& tip, const Vec3& nearest) {
    bucket_max_ = std::max(bucket_max_, e);
    if ((t.n + 1) % bucket_ != 0) return;
    Series& s = ev_.series;
    s.t.push_back(static_cast<double>(t.n) * model_.interp.period);
    s.contour.push_back(bucket_max_);
    bucket_max_ = 0;
    for (std::size_t i = 0; i < kNumAxes; ++i) s.following[i].push_back(t.command[i] - t.actual[i]);
    for (std::size_t k = 0; k < 3; ++k) {
      s.tip[k].push_back(tip[k]);
      s.nominal[k].push_back(nearest[k]);
    }
    s.segment.push_back(seg);
    if (s.t.size() == 2 * kSeriesPoints) halve_series();
  }

  void halve_series() {
    Series& s = ev_.series;
    auto keep_later = [](auto& v) {
      for (std::size_t j = 0; 2 * j + 1 < v.size(); ++j) v[j] = v[2 * j + 1];
      v.resize(v.size() / 2);
    };
    for (std::size_t j = 0; 2 * j + 1 < s.contour.size(); ++j) s.contour[j] = std::max(s.contour[2 * j], s.contour[2 * j + 1]);
    s.contour.resize(s.contour.size() / 2);
    keep_later(s.t);
    keep_later(s.segment);
    for (auto& v : s.following) keep_later(v);
    for (auto& v : s.tip) keep_later(v);
    for (auto& v : s.nominal) keep_later(v);
    bucket_ *= 2;
  }

  const Model& model_;
  bool keep_series_;
  Evaluation ev_;
  std::vector<double> seg_sq_;
  std::vector<std::uint64_t> seg_n_;
  double sum_sq_ = 0, rapid_sq_ = 0;
  std::uint64_t count_ = 0, rapid_count_ = 0, ticks_ = 0;
  Axes fe_sq_{}, c1_{}, c2_{};  // c1_, c2_: the two previous smoothed commands
  std::size_t bucket_ = 1;
  double bucket_max_ = 0;
};

namespace {

/// The recorded run's series grew by doubling, so up to half of their room is spare: scratch-file
/// disk taken ahead (gcpipe/scratch.hpp), given back before the planner.
void shrink_recorded(Nominal& nom) {
  nom.raw.shrink_to_fit();
  nom.block.shrink_to_fit();
}

/// The program with every feed move's F multiplied by `f` (in G93, F is 1/min: smaller is slower
/// too; rapids keep the machine's rapid rate), block by block as the run asks: the slowed
/// baseline runs the program several times, and a copy a run was 472 bytes a block.
BlockSource with_feeds_scaled(std::span<const ResolvedBlock> program, double f) {
  if (f == 1.0) return BlockSource::of(program);
  auto scaled = std::make_shared<ResolvedBlock>();
  return {program.size(), [program, f, scaled](std::size_t i) -> const ResolvedBlock& {
            const ResolvedBlock& b = program[i];
            if (b.motion != Motion::kLinear && b.motion != Motion::kArcCW && b.motion != Motion::kArcCCW) return b;
            *scaled = b;
            scaled->feed *= f;
            return *scaled;
          }};
}

/// The program's own run, evaluated as it goes: each tick's raw sample is the nominal (pushed to
/// the contour search), its actual is measured against the nominal path so far. With
/// `record` the run is also recorded for the report and the compensation: raw samples and blocks
/// (the tracking error against the reference built after it is add_tracking_against_reference's).
struct OwnRun {
  Evaluation eval;
};

OwnRun run_own_program(const Model& model, std::span<const ResolvedBlock> program, const Axes& start, Nominal& nom,
                       bool record, std::uint64_t max_ticks, const std::function<void(const Tick&)>& on_tick,
                       double feed_factor, bool evaluate) {
  OwnRun own;
  RunAccumulator acc(model, nom.segments.size(), record);
  ContourSearch contour;
  Vec3 last_nominal{};
  // Everything but the interpolator, the drives and the kinematics, on a second thread (on
  // `gcpipe simulate`'s benchmark the two take about 0.3 and 0.9 G instructions): it alone
  // touches acc, contour and own until finish(); nom's samples are recorded on the simulation's
  // thread. The tool tips are worked out on the simulation's thread, the lighter one.
  struct Tips {
    Tick t;
    Vec3 nominal, actual;
  };
  auto evaluate_tick = [&](const Tips& tips) {
    const Tick& t = tips.t;
    const ResolvedBlock& b = program[t.block];
    const Vec3& nominal = tips.nominal;
    if (contour.size() == 0 || dist3(last_nominal, nominal) > 1e-9) contour.push(nominal), last_nominal = nominal;
    const Vec3& tip = tips.actual;
    Vec3 nearest;
    const double e = contour.distance(tip, nearest);
    const bool cutting = acc.add(t, b, nom.segment_of_block[t.block], e, tip, nearest);
    hand_on(on_tick, t, cutting, e, tip);
  };
  ChunkedWorker<Tips> evaluation(256, 8, [&](const std::vector<Tips>& ticks) {
    for (const Tips& t : ticks) evaluate_tick(t);
  });
  nom.stats = run_program(
      model, with_feeds_scaled(program, feed_factor), start,
      [&](const Tick& t) {
        // The raw samples are recorded on this thread, not the evaluation's: a thread's own
        // malloc arena keeps the memory a growing series leaves behind (tens of MB on a long
        // program) resident to the end, where the main arena's is given back after the plan.
        if (record) {
          nom.raw.push_back(t.raw);
          nom.block.push_back(t.block);
        }
        if (!evaluate) return;  // the look-ahead control's run is another (run_commands)
        const double tool = tool_length_of(model, nom.brief[t.block]);
        evaluation.push({t, forward_kinematics(model.kin, t.raw, tool).tip, forward_kinematics(model.kin, t.actual, tool).tip});
      },
      max_ticks);
  evaluation.finish();
  own.eval = acc.finish(nom.stats);
  return own;
}

}  // namespace

Nominal build_nominal(const Model& model, std::span<const ResolvedBlock> program, const Axes& start,
                      const ReferencePlan& plan, double max_machine_time) {
  Nominal nom;
  nom.period = model.interp.period;
  nom.brief.reserve(program.size());
  for (const ResolvedBlock& b : program) nom.brief.push_back(brief_of(b));
  const double max_ticks = max_ticks_of(model, max_machine_time);
  nom.stats = run_program(
      model, program, start,
      [&](const Tick& t) {
        nom.raw.push_back(t.raw);
        nom.block.push_back(t.block);
      },
      tick_bound(max_ticks));
  if (nom.raw.empty() || !nom.stats.ok) return nom;
  shrink_recorded(nom);
  std::size_t nseg = 0;
  nom.segment_of_block = segment_blocks({nom.brief.data(), nom.brief.size()}, nseg);
  nom.segments.assign(nseg, Segment{});
  describe_segments(model, nom);
  plan_reference(model, plan, max_ticks, nom);
  return nom;
}

void give_back_freed_memory() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

namespace {
// How far back from where the nominal has got a window's search starts [raw ticks]: the search
// of a whole run looks back ContourSearch::kLookBack points, about as many ticks.
constexpr std::uint64_t kWindowLookBack = ContourSearch::kLookBack + 500;
// A node program's actual may run slightly ahead of its reference's progress [raw ticks].
constexpr std::size_t kAheadOfProgress = 300;

std::size_t first_raw_tick(const Nominal& nom, bool on_reference_clock, std::uint64_t first_tick) {
  if (first_tick == 0) return 0;
  std::uint64_t raw = first_tick;
  if (on_reference_clock && !nom.progress.empty()) raw = nom.progress[std::min<std::size_t>(first_tick, nom.progress.size() - 1)];
  return static_cast<std::size_t>(raw > kWindowLookBack ? raw - kWindowLookBack : 0);
}
}  // namespace

ContourMeter::ContourMeter(const Model& model, const Nominal& nom, bool on_reference_clock, std::uint64_t first_tick,
                           bool reusable)
    : model_(model), nom_(nom), on_reference_clock_(on_reference_clock),
      path_(std::make_unique<NominalPolyline>(model, nom, search_, first_raw_tick(nom, on_reference_clock, first_tick),
                                              reusable)) {
  if (reusable) search_.keep_all_points();
}

void ContourMeter::rewind() {
  path_->rewind();
  search_.rewind();
}

ContourMeter::~ContourMeter() = default;

double ContourMeter::distance(const Tick& t, const ResolvedBlock& b, Vec3& tip, Vec3& nearest) {
  return distance_beyond(t, b, -std::numeric_limits<double>::infinity(), tip, nearest);
}

double ContourMeter::distance_beyond(const Tick& t, const ResolvedBlock& b, double bound, Vec3& tip, Vec3& nearest) {
  tip = forward_kinematics(model_.kin, t.actual, tool_length_of(model_, b)).tip;
  const std::size_t n = static_cast<std::size_t>(t.n);
  // The raw tick the nominal has reached: the tick itself for the program's own run; for a
  // node program, which follows the planned reference, the reference's progress plus a
  // margin for an actual that runs slightly ahead.
  std::size_t raw_tick = n;
  if (on_reference_clock_ && !nom_.progress.empty())
    raw_tick = static_cast<std::size_t>(nom_.progress[std::min(n, nom_.progress.size() - 1)]) + kAheadOfProgress;
  const std::size_t limit = path_->index_of_tick(raw_tick);
  // The points up to the segment that ends at `limit` (at least the first segment), as the
  // search over a whole polyline takes them.
  path_->fill(std::max<std::size_t>(limit, 1) + 1);
  return search_.distance_beyond(tip, limit, bound, nearest);
}

RunEvaluation::RunEvaluation(const Model& model, const Nominal& nom, std::span<const ResolvedBlock> program,
                             const Axes& start, bool on_reference_clock)
    : nom_(nom), program_(program), meter_(model, nom, on_reference_clock),
      acc_(std::make_unique<RunAccumulator>(model, nom.segments.size())),
      ref_end_(nom.reference.empty() ? start : nom.reference.back()) {}

RunEvaluation::~RunEvaluation() = default;

void RunEvaluation::add(const Tick& t, std::uint32_t src, const TickFn& also) {
  const ResolvedBlock& b = program_[std::min<std::size_t>(src, program_.size() - 1)];
  Vec3 tip, nearest;
  const double e = meter_.distance(t, b, tip, nearest);
  const std::uint32_t seg = nom_.segment_of_block.empty() ? 0 : nom_.segment_of_block[std::min<std::size_t>(src, nom_.segment_of_block.size() - 1)];
  const bool cutting = acc_->add(t, b, seg, e, tip, nearest);
  const std::size_t n = static_cast<std::size_t>(t.n);
  acc_->track(n < nom_.reference.size() ? nom_.reference[n] : ref_end_, t.actual);
  hand_on(also, t, cutting, e, tip);
}

Evaluation RunEvaluation::finish(const RunStats& stats) { return acc_->finish(stats); }

Evaluation evaluate(const Model& model, const Nominal& nom, std::span<const ResolvedBlock> program,
                    const BlockSource& blocks, const Axes& start,
                    const std::function<std::uint32_t(std::uint32_t)>& source_block,
                    const std::function<void(const Tick&)>& also, bool on_reference_clock) {
  RunEvaluation ev(model, nom, program, start, on_reference_clock);
  const RunStats stats =
      run_program(model, blocks, start, [&](const Tick& t) { ev.add(t, source_block(t.block), also); });
  return ev.finish(stats);
}

}  // namespace gcpipe::simulate

namespace gcpipe::simulate {

std::string travel_error(const Model& model, const interpolate::InterpolateStats& s) {
  if (s.first_violation_axis < 0) return {};
  const auto i = static_cast<std::size_t>(s.first_violation_axis);
  const char* unit = i >= static_cast<std::size_t>(kA) ? "deg" : "mm";
  char msg[300];
  std::snprintf(msg, sizeof msg,
                "axis %c goes to %.3f %s, outside its travel [%g, %g] %s (%llu samples beyond it): the machine cannot "
                "run this program; check the work offset, the tool length and the program's coordinates",
                kAxisLetters[i], s.first_violation_position, unit, model.kin.travel[i].min, model.kin.travel[i].max, unit,
                static_cast<unsigned long long>(s.travel_violations[i]));
  return msg;
}

namespace {

/// The look-ahead control runs the program: its plan (the reference, with its in-position waits)
/// fed to the drives. Its ticks go to `on_tick`; its evaluation is the program's "before".
void run_lookahead_control(SimulationRun& run, const Model& model, const BlockStore& p, const RunBounds& bounds,
                           double max_ticks, const std::function<void(const Tick&)>& on_tick) {
  Nominal& nom = *run.nominal;
  shrink_recorded(nom);
  describe_segments(model, nom);
  plan_reference(model, bounds.plan, max_ticks, nom);
  if (nom.reference_too_long || nom.reference.empty()) {
    run.note = "the look-ahead control's plan runs longer than max_machine_time";
    return;
  }
  const InPositionWaits waits = add_in_position_waits(model, nom, run.start);
  nom.in_position_ticks = waits.ticks, nom.in_position_checks = waits.checks, nom.in_position_capped = waits.capped;
  Evaluation ev = run_commands(model, nom, p, run.start, nom.reference.size(),
                               [&nom](std::size_t n) { return nom.reference[n]; }, on_tick);
  // The interpolator's figures of the path (travel, TCP, velocity-limited blocks) with the
  // control run's ticks, torque limits and command peaks.
  RunStats s = nom.stats;
  s.ticks = ev.stats.ticks;
  s.saturated_ticks = ev.stats.saturated_ticks;
  s.interp.peak_velocity = ev.stats.interp.peak_velocity;
  s.interp.peak_acceleration = ev.stats.interp.peak_acceleration;
  ev.stats = s;
  run.before = std::move(ev);
}

/// simulate_program's run of `p` (a BlockStore: its briefs are what the passes read), its feeds
/// multiplied by `feed_factor`, into `run` (whose program is `p` or left empty).
void simulate_into(SimulationRun& run, const Model& model, const BlockStore& p, double feed_factor,
                   const RunBounds& bounds, const std::function<void(const Tick&)>& on_tick, const Progress& progress) {
  std::size_t first = 0;
  while (first < p.size() && p[first].motion == Motion::kNone) ++first;
  if (first == p.size()) {
    run.note = "the program moves nothing";
    return;
  }
  // Where the machine stands when the program starts (the machine file's home), else where the
  // program's first move starts.
  run.start = model.start ? *model.start : machine_start(model.kin, p[first], tool_length_of(model, p[first]));
  if (progress) progress("simulating the program (interpolator + feed drives)", 0, 1);
  Nominal& nom = run.nominal.emplace();
  nom.period = model.interp.period;
  std::size_t nseg = 0;
  nom.brief.assign(p.briefs().begin(), p.briefs().end());
  nom.segment_of_block = segment_blocks(p.briefs(), nseg);
  nom.segments.assign(nseg, Segment{});
  const double max_ticks = max_ticks_of(model, bounds.max_machine_time);
  // Under the look-ahead control the interpolator's run at the programmed feeds is the nominal
  // path only: the machine runs the plan made from it (run_lookahead_control).
  const bool lookahead = model.interp.control == interpolate::Control::kLookahead;
  const bool record = bounds.record_nominal || lookahead;
  OwnRun own = run_own_program(model, p, run.start, nom, record, tick_bound(max_ticks), lookahead ? TickFn{} : on_tick,
                               feed_factor, !lookahead);
  if (!nom.stats.ok) {
    // The interpolator's messages name the block already ("line 4 (G1 X100 F1.5): ...").
    const bool named = nom.stats.message.rfind("line ", 0) == 0;
    run.note = named ? nom.stats.message : "line " + std::to_string(nom.stats.failed_line) + ": " + nom.stats.message;
    return;
  }
  const std::string travel = travel_error(model, nom.stats.interp);
  if (!travel.empty()) {
    run.note = travel;
    run.travel_line = nom.stats.interp.first_violation_line;
    return;
  }
  if (lookahead) return run_lookahead_control(run, model, p, bounds, max_ticks, on_tick);
  if (bounds.record_nominal) {
    shrink_recorded(nom);
    describe_segments(model, nom);
    plan_reference(model, bounds.plan, max_ticks, nom);
    add_tracking_against_reference(model, p, run.start, nom, tick_bound(max_ticks), own.eval.axes);
  }
  run.before = std::move(own.eval);
}

}  // namespace

SimulationRun simulate_program(const Model& model, BlockStore program, const RunBounds& bounds,
                               const std::function<void(const Tick&)>& on_tick, const Progress& progress) {
  SimulationRun run;
  run.program = std::move(program);
  simulate_into(run, model, run.program, 1.0, bounds, on_tick, progress);
  return run;
}

SimulationRun simulate_program(const Model& model, std::span<const ResolvedBlock> program, const RunBounds& bounds,
                               const std::function<void(const Tick&)>& on_tick, const Progress& progress) {
  BlockStore store(program.size());
  for (const ResolvedBlock& b : program) store.push_back(b);
  return simulate_program(model, std::move(store), bounds, on_tick, progress);
}

}  // namespace gcpipe::simulate

namespace gcpipe::simulate {

namespace {

}  // namespace

SlowedBaseline slowed_original(const Model& model, const BlockStore& program, double target_cycle_time,
                               double cycle_at_one, const RunBounds& bounds) {
  // Only the program's own run is needed (its cycle and contour error): no planned reference,
  // no recorded nominal.
  RunBounds own = bounds;
  own.record_nominal = false;
  auto run_at = [&](double f) {
    SimulationRun run;  // the program is not copied into it: the run scales its feeds as it goes
    simulate_into(run, model, program, f, own, {}, {});
    SlowedBaseline r;
    if (!run.before) {
      r.note = run.note;
      return r;
    }
    r.ok = true;
    r.feed_factor = f;
    r.cycle_time = static_cast<double>(run.before->stats.ticks) * model.interp.period;
    r.contour = run.before->contour;
    return r;
  };
  // The cycle is about a + b / f (a: rapids and dwells, which do not scale; b / f: feed moves), so
  // f <- f * cycle(f) / target converges on the factor geometrically, with ratio a / target:
  // two or three runs where the feed moves dominate.
  SlowedBaseline best;
  double f = std::min(1.0, cycle_at_one / target_cycle_time);
  for (int k = 0; k < 8; ++k) {
    if (f < 1.0 / 64) {
      best.ok = false;
      best.note = "the program does not slow to the compensated cycle time at 1/64 of its feeds";
      return best;
    }
    const SlowedBaseline r = run_at(f);
    if (!r.ok) return r;
    if (!best.ok || std::abs(r.cycle_time / target_cycle_time - 1) < std::abs(best.cycle_time / target_cycle_time - 1)) best = r;
    if (std::abs(r.cycle_time / target_cycle_time - 1) <= 0.02 || !(r.cycle_time > 0)) break;
    const double next = std::min(1.0, f * r.cycle_time / target_cycle_time);
    if (next == f) break;  // at full feed and still longer than the target: nothing to slow
    f = next;
  }
  return best;
}

}  // namespace gcpipe::simulate
