// Stage `simulate`: a program through the machine model (interpolator with TCP per tick, acc/dec,
// the five feed drives of seed 002, forward kinematics) and its contour error against the nominal
// tool path. The one simulation harness and the one contour metric of gcpipe: `gcpipe simulate`,
// the compensation and the report all call these functions (README.md beside this file).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <deque>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "gcpipe/block.hpp"
#include "gcpipe/block_store.hpp"
#include "gcpipe/kinematics.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "interpolate.hpp"
#include "joint_series.hpp"
#include "servo.hpp"

namespace gcpipe::simulate {

/// Distance between two points [mm].
inline double dist3(const Vec3& a, const Vec3& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

/// Joint-linear interpolation a + (b - a) s.
inline Axes lerp(const Axes& a, const Axes& b, double s) {
  Axes r;
  for (std::size_t i = 0; i < kNumAxes; ++i) r[i] = a[i] + (b[i] - a[i]) * s;
  return r;
}

/// A block whose contour error counts: feed moves and dwells cut (or stand in the cut); rapids
/// position the tool and are reported apart.
inline bool is_cutting(const ResolvedBlock& b) { return b.motion != Motion::kRapid && b.motion != Motion::kNone; }

/// The machine as the simulation (and the compensation) sees it. Every part comes from the config.
struct Model {
  MachineKinematics kin;
  interpolate::InterpolateOptions interp;  //!< period, smoothing, limits, Ts per axis
  servo::DriveSet drives;
  std::optional<Axes> start;  //!< the machine file's start_position (home, Z up): runs start there
};

/// The model of a pipeline config: machine kinematics and limits, the `interpolate` section, the
/// drives file named by `servo.drives` (Ts per axis from it). Throws ConfigError naming the key.
Model load_model(const PipelineConfig& pc);

/// One simulated tick.
struct Tick {
  std::uint64_t n = 0;      //!< tick index, t = n * period
  Axes raw{};               //!< raw interpolated joints (before acc/dec) [mm, deg]
  Axes command{};           //!< smoothed command [mm, deg]
  Axes actual{};            //!< actual joints [mm, deg]
  Axes torque{};            //!< [N*m]
  std::uint8_t saturated = 0;  //!< bit per axis: torque-limited in this tick
  std::uint32_t block = 0;  //!< index of the block whose raw sample this is
  double contour = 0;       //!< contour error [mm] (set by evaluate(); 0 on rapids)
  Vec3 tip{};               //!< actual tool tip, workpiece frame [mm] (set by evaluate())
};

/// How a run ended.
struct RunStats {
  bool ok = true;
  std::string message;            //!< when !ok: the block and why the machine would stop
  std::uint64_t failed_line = 0;  //!< source line of that block
  std::uint64_t ticks = 0;
  interpolate::InterpolateStats interp;
  std::array<std::uint64_t, kNumAxes> saturated_ticks{};
};

/// A program handed to the simulation block by block: `count` blocks, `at(i)` block i, valid until
/// the next call. A generated program (the compensation's node program, or compensated.nc read
/// back) is made one block at a time this way instead of held whole (472 bytes a block, one block
/// a node: on a long program the largest thing in memory).
struct BlockSource {
  std::size_t count = 0;
  std::function<const ResolvedBlock&(std::size_t)> at;
  /// The blocks of a program held in memory.
  static BlockSource of(std::span<const ResolvedBlock> blocks) {
    return {blocks.size(), [blocks](std::size_t i) -> const ResolvedBlock& { return blocks[i]; }};
  }
};

using TickFn = std::function<void(const Tick&)>;

/// The machine model running one block at a time: interpolator (TCP per tick), acc/dec and the
/// five drives. A copy is the whole machine state at that point (every part is vectors and
/// numbers), from which a run can go on along another program: the compensation learns a window
/// of the program from the state in which the nodes before it leave the machine. Ticks are
/// numbered from the run's start and handed on as the drives finish them (their feed-forward
/// reads a few ticks ahead, so the newest ticks come with the next block or finish()).
class MachineRun {
 public:
  /// At rest at `start`; the first tick (tick 0) is handed on by the first add() or finish().
  /// After `max_ticks` ticks no more are handed on and add() says so.
  MachineRun(const Model& model, const Axes& start, std::uint32_t first_block, std::uint64_t max_ticks = UINT64_MAX);
  /// Runs block `b`, which stands for program block `source` (Tick::block of its samples; a
  /// block without motion makes none). Not kOk: the block cannot be run and made no tick.
  interpolate::InterpolateResult add(const ResolvedBlock& b, std::uint32_t source, const TickFn& on_tick);
  /// Holds the last position until acc/dec and drives have settled, handing on every tick.
  void finish(const TickFn& on_tick);
  /// `max_ticks` reached: later ticks were simulated but not handed on.
  bool over() const { return sink_.over; }
  std::uint64_t ticks() const { return sink_.n; }
  const interpolate::InterpolateStats& interp_stats() const { return interp_.stats(); }
  const std::array<std::uint64_t, kNumAxes>& saturated_ticks() const { return sink_.saturated; }

 private:
  struct Sink final : interpolate::SampleSink {
    servo::ServoSimulator sim;
    std::deque<std::pair<Axes, std::uint32_t>> raw;  // raw samples whose drive tick is still to come
    std::uint32_t block = 0;
    std::uint64_t n = 0;
    std::uint64_t max_ticks = UINT64_MAX;
    bool over = false;
    bool first_pending = true;  // tick 0 (at rest) not yet handed on
    std::array<std::uint64_t, kNumAxes> saturated{};
    const TickFn* on_tick = nullptr;  // of the add() or finish() running
    Sink(const Model& m) : sim(m.drives, m.interp.period) {}
    void raw_sample(const Axes& r) override { raw.emplace_back(r, block); }
    void sample(const Axes& c) override;
    void emit(const servo::ServoSample& s);
  };
  void emit_first();
  interpolate::Interpolator interp_;
  Sink sink_;
  servo::ServoSample first_{};
};

/// A program run as its blocks come, one at a time (run_program is a loop over it): for blocks
/// made by another step as it goes (compensated.nc read back while the compensation writes it).
class ProgramRunner {
 public:
  /// At rest at `start`; `first_block`: the first block that moves (its index).
  ProgramRunner(const Model& model, const Axes& start, std::uint32_t first_block, std::uint64_t max_ticks = UINT64_MAX);
  /// Runs block `b`, block `i` of the program. False when the run stopped at it (a block the
  /// interpolator cannot run, or past `max_ticks`) or before: later blocks are not run.
  bool add(const ResolvedBlock& b, std::uint32_t i, const TickFn& on_tick);
  /// Settles the run (unless it was cut off at `max_ticks`) and gives its figures.
  RunStats finish(const TickFn& on_tick);

 private:
  double period_;
  std::uint64_t max_ticks_;
  MachineRun run_;
  RunStats stats_;
  bool stopped_ = false, over_ = false;
};

/// Interpolates `blocks` (from rest at `start`) at the model's period, runs the five drives and
/// calls `on_tick` for every tick, in order. Blocks without motion are skipped by the
/// interpolator; a block it cannot run stops the run (RunStats::ok false).
/// After `max_ticks` ticks the run stops with RunStats::ok false (a bound on memory and time).
RunStats run_program(const Model& model, const BlockSource& blocks, const Axes& start,
                     const std::function<void(const Tick&)>& on_tick, std::uint64_t max_ticks = UINT64_MAX);
inline RunStats run_program(const Model& model, std::span<const ResolvedBlock> blocks, const Axes& start,
                            const std::function<void(const Tick&)>& on_tick, std::uint64_t max_ticks = UINT64_MAX) {
  return run_program(model, BlockSource::of(blocks), start, on_tick, max_ticks);
}

/// The contour metric: the distance from the actual tool tip to the nominal tool-tip polyline
/// among the points the nominal could have reached by now, looking back at most kLookBack points.
/// The window stops a looping path (a trochoid) from matching a crossing of a much earlier loop;
/// the actual trails the nominal by the acc/dec and servo lag (tens of ms), far less than the
/// window. Segments are grouped in two levels of bounding boxes, so that most of the window is
/// skipped once a good match is known. A group that passes its box is tested once more against
/// its capsule (the chord from its first to its last point, thickened to hold every point): on a
/// curve far tighter than a box, so where the turns of a loop lie on top of each other (the
/// simulate benchmark's circles) only the groups beside the nearest point of each turn are
/// measured, their segments side by side (vectorised). A super-group's distance, once measured,
/// bounds it while the actual moves (less the distance moved), so that each tick measures only the
/// super-groups the actual may have come near. Every test is a lower bound with a margin:
/// the result is exactly the minimum over the window, the same double as measuring every segment.
/// The distance is to the path, not to the time-matched point: an axis that trails in time on the
/// path has no contour error.
///
/// The search holds only a sliding window of the polyline (about 2 kLookBack points), so a
/// streaming simulation needs memory for the window, not for the program: points are pushed as
/// the nominal reaches them, or taken from a whole polyline as `limit` advances.
class ContourSearch {
 public:
  static constexpr std::size_t kGroup = 8;
  static constexpr std::size_t kGroupsPerSuper = 8;
  static constexpr std::size_t kLookBack = 3000;
  /// Streaming: the caller pushes the polyline point by point (push()).
  ContourSearch() = default;
  /// Over a whole polyline `pts` [mm], without repeated points; must outlive the search.
  explicit ContourSearch(const std::vector<Vec3>& pts) : source_(&pts) {}
  /// Appends the next polyline point (not equal to the previous one).
  void push(const Vec3& p);
  /// Points pushed (or taken from the whole polyline) so far.
  std::size_t size() const { return first_ + win_.size(); }
  /// `limit`: the newest polyline index the nominal has reached at this tick; it never
  /// decreases from call to call. Returns the distance [mm]; `closest` receives the nearest
  /// point of the path.
  double distance(const Vec3& actual, std::size_t limit, Vec3& closest) {
    return distance_beyond(actual, limit, -std::numeric_limits<double>::infinity(), closest);
  }
  /// As distance(), where the distance exceeds `bound`. Where it does not, returns a distance
  /// to a segment near the previous match when that is within `bound` already (an upper bound of
  /// the least: the search of the whole window is left out), else the least. A caller that only
  /// needs to know the ticks beyond `bound`, and by how much, gets the same answers faster.
  double distance_beyond(const Vec3& actual, std::size_t limit, double bound, Vec3& closest);
  /// Streaming form: up to the newest point pushed.
  double distance(const Vec3& actual, Vec3& closest) { return distance(actual, size() == 0 ? 0 : size() - 1, closest); }
  /// Keeps every point pushed from now on, instead of the last kLookBack and some: a window's
  /// polyline, searched again by run after run (rewind()).
  void keep_all_points() { keep_all_ = true; }
  /// Forgets the run measured so far (its last match and the bounds kept from it) and keeps the
  /// points: the next distance() calls measure a new run from the first point, as a new search
  /// given the same points would.
  void rewind();

 private:
  /// The bounding boxes of the super-groups, structure of arrays.
  struct Boxes {
    std::array<std::vector<double>, 3> lo, hi;
    std::size_t size() const { return lo[0].size(); }
    void open(const Vec3& p);  //!< a new box holding p
    void grow(const Vec3& p);  //!< the newest box grows to hold p
    void drop_front(std::size_t n);
    double distance_sq(std::size_t i, const Vec3& p) const;
  };
  /// Per group: the points of a complete group lie within `radius` of the chord a..a+d. An
  /// incomplete group (the newest) has an infinite radius: it is always measured. The shape of a
  /// group is one 64-byte record (lower_bound() reads it whole); the kept bounds, scanned group
  /// after group, are an array of their own.
  struct Capsules {
    struct Shape {
      double a[3] = {}, d[3] = {};
      double inv_dd = 0;  //!< 1 / |d|^2, 0 when d is 0
      double radius = std::numeric_limits<double>::infinity();  //!< [mm]
    };
    std::vector<Shape> shape;
    /// Kept lower bound as super_far_: lower_bound() when last worked out plus the motion then.
    std::vector<double> far;
    std::size_t groups = 0;      //!< opened; the arrays hold whole super-groups
    void open();                 //!< a new, incomplete group
    void drop_front(std::size_t n);  //!< n: whole super-groups of groups
    /// No point of group i is nearer to p than this [mm] (-inf for an incomplete group).
    double lower_bound(std::size_t i, const Vec3& p) const;
  };
  struct Match {
    double sq = 1e300, dist = 1e300;  //!< squared distance and distance [mm^2, mm]
    double s = 0;                     //!< along the segment, 0..1
    std::size_t segment = 0;          //!< global index
  };
  struct Range {
    std::size_t a, b;  //!< segments [a, b) (global indices)
  };
  static constexpr std::size_t kSuperSpan = kGroup * kGroupsPerSuper;
  const Vec3& point(std::size_t i) const { return win_[i - first_]; }
  void drop_old_points();
  void add_motion(const Vec3& actual);
  void close_group(std::size_t g);  //!< group g (global index) got its last point: its capsule
  void add_step(const Vec3& a, const Vec3& b);
  void scan(std::size_t a, std::size_t b, const Vec3& p, Match& m) const;
  void scan_except(std::size_t a, std::size_t b, const Range& done, const Vec3& p, Match& m) const;
  void measure(std::size_t a, std::size_t n, const Vec3& p, double* sq, double* s) const;
  double finish(const Match& m, Vec3& closest);  //!< remembers the match, returns its distance
  bool take_points(const Vec3& actual, std::size_t limit, Vec3& closest, double& distance);
  /// Adds the motion; the window [lo, hi) of segments to search and the warm start near the
  /// previous match, measured into `m`.
  void begin_search(const Vec3& actual, std::size_t limit, std::size_t& lo, std::size_t& hi, Range& warm, Match& m);
  double search_window(const Vec3& actual, std::size_t lo, std::size_t hi, const Range& warm, Match& m, Vec3& closest);
  void scan_super(std::size_t sg, std::size_t lo, std::size_t hi, const Range& warm, const Vec3& p, Match& m);

  const std::vector<Vec3>* source_ = nullptr;
  std::vector<Vec3> win_;          //!< points first_ .. size()-1
  std::size_t first_ = 0;          //!< global index of win_[0]; a multiple of kSuperSpan
  std::array<std::vector<double>, 3> coord_;  //!< the points again, one array per axis (scan)
  std::array<std::vector<double>, 4> step_;   //!< per segment from first_: its vector, squared length
  Boxes supers_;                   //!< from super-group first_ / kSuperSpan
  Capsules capsules_;              //!< from group first_ / kGroup
  /// Per super-group, as supers_: its box's distance from the actual when last measured plus
  /// motion_ then (-inf: not measured since the box grew). Less the motion since, still a lower
  /// bound (the triangle inequality): a far super-group is passed over with one comparison until
  /// the actual has moved far enough to come near it.
  std::vector<double> super_far_;
  double motion_ = 0;  //!< [mm] path of the actual since the last rebase, rounded up
  std::optional<Vec3> last_actual_;
  std::size_t j_ = 0;              //!< segment of the previous match (global index)
  bool keep_all_ = false;          //!< no point is dropped (keep_all_points())
};

/// Joints at which the machine starts, at rest, for the program's first moving block: where the
/// program believes it is. In TCP mode the parser's position is a tool tip (with A C or a tool
/// vector), so it is turned into joints.
Axes machine_start(const MachineKinematics& kin, const ResolvedBlock& first_motion, double tool_length);

/// Tool length in force for a block [mm].
double tool_length_of(const Model& model, const ResolvedBlock& b);
double tool_length_of(const Model& model, const BlockBrief& b);

/// Contour and axis error figures of one simulated run against the nominal path.
struct ErrorStats {
  double max = 0;            //!< [mm]
  double rms = 0;            //!< [mm]
  double t_at_max = 0;       //!< [s]
  std::uint64_t line_at_max = 0;  //!< source line
};

struct AxisStats {
  Axes max_following{};      //!< max |command - actual| [mm, deg]
  Axes rms_following{};      //!< [mm, deg]
  Axes max_tracking{};       //!< max |reference - actual| [mm, deg]
  Axes travel_margin{};      //!< smallest distance of the actual joint to its travel limit
                             //!< [mm, deg] (negative: outside)
  Axes peak_velocity{};      //!< of the smoothed commands [mm/s, deg/s]
  Axes peak_acceleration{};  //!< [mm/s^2, deg/s^2]
  std::array<std::uint64_t, kNumAxes> saturated_ticks{};
};

/// A part of the program between dwells or stops (one circle-test condition, one cycle).
struct Segment {
  std::uint64_t first_line = 0, last_line = 0;
  double t_begin = 0, t_end = 0;  //!< [s] in the original's time
  bool circle = false;            //!< the nominal tool-tip path of the segment is a circle
  double circle_radius = 0;       //!< [mm]
  std::array<double, 2> circle_centre{};  //!< [mm] (workpiece X Y)
};

/// Decimated per-tick series for the figures (<= about 20,000 points per series).
struct Series {
  std::vector<double> t;                    //!< [s]
  std::vector<double> contour;              //!< max contour error in the bucket [mm]
  std::array<std::vector<double>, kNumAxes> following;  //!< command - actual at the bucket end
  std::array<std::vector<double>, 3> tip;   //!< actual tool tip, workpiece frame [mm]
  std::array<std::vector<double>, 3> nominal;  //!< nearest point of the nominal path [mm]
  std::vector<std::uint32_t> segment;       //!< segment index of the bucket end
};



/// How the compensation's reference is planned (the `compensate` section; derivation in
/// stages/compensate/README.md, "Reference").
struct ReferencePlan {
  double tolerance = 0.02;    //!< [mm] largest tool-tip deviation of the reference from the path
  double blend_time = 0.01;   //!< [s] first moving average of the blend (the second is half of it)
  double acceleration = 0.3;  //!< planned acceleration, a fraction of every axis's limit (0.5 left the
                              //!< compensation too little headroom on the seed 002 circle test)
  double smoothing = 2.0;     //!< speed-profile smoothing, in units of the slowest axis's Ts
  /// [s] of the program as the control runs it planned at a time (plus a margin past it): the
  /// planner holds a chunk's series, not the program's. Not a config key (tests shorten it).
  double chunk_seconds = 120;
  /// Stretches of the path planned slower than the control plans them: the speed limit of every
  /// raw step from `first` to `last` is multiplied by `factor` (the compensation slows where a
  /// drive limit forbids its pre-compensation at the control's speed).
  struct SpeedCap {
    std::size_t first = 0, last = 0;  //!< raw samples
    double factor = 1;
  };
  std::vector<SpeedCap> caps;
};

/// The nominal run of the original program.
struct Nominal {
  double period = 0.001;
  JointSeries raw{JointSeries::kExact};  //!< R_n, n = 0..N-1: exact while the reference is
                                       //!< planned, compact after (joint_series.hpp)
  ScratchArray<std::uint32_t> block;   //!< block index of each raw sample
  JointSeries reference;               //!< r_n (planned and blended path), n = 0..E-1, stored
                                       //!< compactly (joint_series.hpp: within 0.5 nm)
  ScratchArray<std::uint32_t> progress; //!< p_n, the raw index r_n has reached (whole samples:
                                       //!< every user asks which sample, and 4 bytes a tick)
  bool reference_too_long = false;     //!< the reference would exceed max_machine_time (empty)
  /// Look-ahead control: ticks its in-position checks added to the plan, how many checks, and
  /// how many waits were cut at 2 s (a drive that does not get within interpolate.in_position).
  std::uint64_t in_position_ticks = 0, in_position_checks = 0, in_position_capped = 0;
  ScratchArray<BlockBrief> brief;               //!< per program block: what the passes over
                                                //!< the raw samples read (not the blocks' pages)
  std::vector<std::uint32_t> segment_of_block;  //!< per program block
  std::vector<Segment> segments;
  RunStats stats;
};

/// Evaluation of one run against the nominal: contour error per tick and the axis figures.
/// What a run demanded of the axes within one segment (the compensation's limits are judged
/// against the original's own figures segment by segment).
struct SegmentDemand {
  std::array<std::uint64_t, kNumAxes> saturated_ticks{};  //!< torque-limited ticks
  Axes peak_acceleration{};  //!< of the smoothed commands, second difference [mm/s^2, deg/s^2]
};

struct Evaluation {
  RunStats stats;
  ErrorStats contour;  //!< on cutting moves (G1 G2 G3 at feed) and dwells: what the part sees
  ErrorStats rapid;    //!< on G0 positioning moves: not a cutting error, reported apart
  AxisStats axes;
  std::vector<ErrorStats> per_segment;
  std::vector<SegmentDemand> demand;  //!< per segment
  Series series;
};

/// Progress callback: (what, done, total).
using Progress = std::function<void(const char* what, std::uint64_t done, std::uint64_t total)>;

/// Runs the original program and builds the nominal path and reference.
/// Programs longer than `max_machine_time` [s] stop the run (Nominal::stats.ok false).
Nominal build_nominal(const Model& model, std::span<const ResolvedBlock> program, const Axes& start,
                      const ReferencePlan& plan = {}, double max_machine_time = 3600);

/// The compensation's reference for a recorded nominal run (raw samples and blocks): the path
/// planned with look-ahead (speed limited where the direction changes and where the path stops,
/// reached with the plan's path acceleration, never faster than programmed), then blended by
/// two moving averages; where the blend leaves the path by more than `plan.tolerance` the speed
/// is lowered and the plan made again. Fills reference and progress, or sets
/// reference_too_long when the plan would run past `max_ticks`.
void plan_reference(const Model& model, const ReferencePlan& plan, double max_ticks, Nominal& nom);

/// Hands the heap's free pages back to the system (glibc's malloc_trim; elsewhere nothing). Called
/// where a phase has freed its long series (the planner's, the learning's): the next phase's
/// series seldom fit the holes they leave, and the holes would stay resident beside them.
void give_back_freed_memory();

class NominalPolyline;

/// The contour metric of one run against the nominal path, tick by tick: what evaluate() measures.
/// A run on the reference clock (a node program) may begin at reference tick `first_tick` (a
/// window of the compensation, run from the machine state there): the search then starts far
/// enough back to hold the points the actual may still be near.
class ContourMeter {
 public:
  /// `reusable`: the points are kept for runs after the first (rewind()), as the compensation's
  /// learning measures run after run of one window against the same stretch of the path.
  ContourMeter(const Model& model, const Nominal& nom, bool on_reference_clock, std::uint64_t first_tick = 0,
               bool reusable = false);
  ~ContourMeter();
  ContourMeter(const ContourMeter&) = delete;
  ContourMeter& operator=(const ContourMeter&) = delete;
  /// The distance of tick `t`'s actual tool tip (for program block `b`) to the path; its tip and
  /// the nearest point of the path go to `tip` and `nearest`.
  double distance(const Tick& t, const ResolvedBlock& b, Vec3& tip, Vec3& nearest);
  /// As distance() where the distance exceeds `bound`; below it, possibly an upper bound
  /// of the distance (ContourSearch::distance_beyond).
  double distance_beyond(const Tick& t, const ResolvedBlock& b, double bound, Vec3& tip, Vec3& nearest);
  /// Starts measuring a new run from `first_tick` (a reusable meter): the same distances as a
  /// new meter, without making the path's points again.
  void rewind();

 private:
  const Model& model_;
  const Nominal& nom_;
  bool on_reference_clock_;
  ContourSearch search_;
  std::unique_ptr<NominalPolyline> path_;
};

class RunAccumulator;

/// The look-ahead control's in-position check (control.cpp): where its plan (the reference)
/// stands still, at an exact stop, a dwell or the end, the next motion waits until every axis's
/// actual position is within interpolate.in_position of it (at most 2 s; longer waits are cut
/// and counted). The drives are run on the reference to find each wait, and the waits become
/// ticks of the reference, the control's timing the compensation keeps.
struct InPositionWaits {
  std::uint64_t ticks = 0, checks = 0, capped = 0;
};
InPositionWaits add_in_position_waits(const Model& model, Nominal& nom, const Axes& start);

/// Tick n's command of a run on the reference clock.
using CommandAt = std::function<Axes(std::size_t n)>;

/// The drives alone fed `command(n)` for ticks 1..ticks-1 (tick 0 is the rest at `start`),
/// measured against the nominal path on the reference clock: the look-ahead control's run
/// (command: its plan, the reference) and the same with the drives' model inverse as
/// feed-forward (compensate). RunStats::interp has the commands' peak velocity and acceleration.
Evaluation run_commands(const Model& model, const Nominal& nom, std::span<const ResolvedBlock> program,
                        const Axes& start, std::size_t ticks, const CommandAt& command, const TickFn& on_tick = {});

/// What evaluate() measures, for a run fed tick by tick (a ProgramRunner fed as blocks come).
class RunEvaluation {
 public:
  RunEvaluation(const Model& model, const Nominal& nominal, std::span<const ResolvedBlock> program, const Axes& start,
                bool on_reference_clock);
  ~RunEvaluation();
  RunEvaluation(const RunEvaluation&) = delete;
  RunEvaluation& operator=(const RunEvaluation&) = delete;
  /// Tick `t` of the run, which stands for program block `src`; `also` sees it with its error.
  void add(const Tick& t, std::uint32_t src, const TickFn& also = {});
  Evaluation finish(const RunStats& stats);

 private:
  const Nominal& nom_;
  std::span<const ResolvedBlock> program_;
  ContourMeter meter_;
  std::unique_ptr<RunAccumulator> acc_;
  Axes ref_end_;
};

/// Runs `blocks` and measures them against the nominal path. `source_block(i)` is the program
/// block that block i of `blocks` stands for (its tool length and segment); `also` sees every tick.
/// `on_reference_clock`: `blocks` is a node program, timed like the re-timed reference.
Evaluation evaluate(const Model& model, const Nominal& nominal, std::span<const ResolvedBlock> program,
                    const BlockSource& blocks, const Axes& start,
                    const std::function<std::uint32_t(std::uint32_t)>& source_block,
                    const std::function<void(const Tick&)>& also = {}, bool on_reference_clock = false);
inline Evaluation evaluate(const Model& model, const Nominal& nominal, std::span<const ResolvedBlock> program,
                           std::span<const ResolvedBlock> blocks, const Axes& start,
                           const std::function<std::uint32_t(std::uint32_t)>& source_block,
                           const std::function<void(const Tick&)>& also = {}, bool on_reference_clock = false) {
  return evaluate(model, nominal, program, BlockSource::of(blocks), start, source_block, also, on_reference_clock);
}

}  // namespace gcpipe::simulate

namespace gcpipe::simulate {

/// The simulation of one whole program: what `gcpipe simulate` reports and what the compensation
/// starts from. Handed from the simulate stage to the compensate stage in one process.
struct SimulationRun {
  BlockStore program;                  //!< the blocks simulated, in order (not in the process's memory)
  Axes start{};                        //!< machine joints the simulation starts from, at rest
  std::optional<Nominal> nominal;      //!< set when the program moves
  std::optional<Evaluation> before;    //!< set when the nominal run completed
  std::string note;                    //!< why there is no nominal or no evaluation
  std::uint64_t travel_line = 0;       //!< source line where an axis first leaves its travel (0: none)
};

/// Why a run cannot be machined because an axis leaves its travel (axis, position, limits), or
/// empty. Limits are errors, not flags: such a program is neither evaluated nor compensated.
std::string travel_error(const Model& model, const interpolate::InterpolateStats& stats);

/// Bounds of a simulation run (from the `compensate` section, whose reference it builds).
struct RunBounds {
  ReferencePlan plan;                //!< see plan_reference
  double max_machine_time = 3600;    //!< [s]
  /// Keep the nominal run (raw samples, segments, re-timed reference, tracking error) for the
  /// report and the compensation. Without it the run is evaluated as it streams, in memory
  /// bounded by the contour window: what `gcpipe simulate` needs for its trace. Nor are the
  /// figures' series gathered then (Evaluation::series stays empty).
  bool record_nominal = true;
};

/// The one harness: the program's own run in one pass, which is both the nominal (each tick's raw
/// sample) and the evaluated run (its actual against the nominal path so far, the contour metric
/// of `evaluate`); with `bounds.record_nominal` it is also recorded as build_nominal records it.
/// `on_tick` sees every tick of the run (trace output). Never throws for a program the machine
/// cannot run: the reason goes to `note`.
SimulationRun simulate_program(const Model& model, BlockStore program, const RunBounds& bounds,
                               const std::function<void(const Tick&)>& on_tick = {}, const Progress& progress = {});
/// The same for a program held in memory (tests, the calibration's programs).
SimulationRun simulate_program(const Model& model, std::span<const ResolvedBlock> program, const RunBounds& bounds,
                               const std::function<void(const Tick&)>& on_tick = {}, const Progress& progress = {});

}  // namespace gcpipe::simulate

namespace gcpipe::simulate {

/// The sceptic's baseline for a compensation: the original program with its feeds lowered until
/// it runs as long as the compensated one. Slowing down also shrinks the contour error; a
/// compensation is worth its name only where it beats this at the same cycle time.
struct SlowedBaseline {
  bool ok = false;
  std::string note;          //!< why there is none
  double feed_factor = 1;    //!< every G1/G2/G3 feed (G94 and G93) multiplied by this
  double cycle_time = 0;     //!< [s] of the slowed program
  ErrorStats contour;        //!< its contour error on cutting moves
};

/// Searches the feed factor that gives the program `target_cycle_time` [s] (to 2 %, at most 8
/// runs of its own, unplanned run), from its cycle at full feed `cycle_at_one` [s].
SlowedBaseline slowed_original(const Model& model, const BlockStore& program, double target_cycle_time,
                               double cycle_at_one, const RunBounds& bounds);

}  // namespace gcpipe::simulate
