// Stage `interpolate`: resolved blocks to per-axis commanded positions at the interpolation
// period (ITP, 1 ms by default), followed by acceleration/deceleration after interpolation (the
// smoothing time constant Ts of seed 002 Table 1).
//
// Each block becomes a parametric path p(s), s in [0, 1], travelled at constant speed for a
// duration fixed by the feed (G94 along the tool-tip path or the XYZ path, G93 inverse time), the
// rapid rule, or the dwell, and lengthened when an axis would exceed its velocity limit.
// Tool-centre-point blocks (G43.4 / M428, G43.5) are interpolated as the control does: the path
// lies in the workpiece frame (tool tip, A and C or the tool vector) and every sample is turned
// into joints by inverse kinematics before smoothing; joint limits are measured on that joint
// path. The
// path is sampled on one global clock (t = n * period), so block boundaries that fall between
// samples cost no time and leave no velocity glitch. Each axis is then smoothed independently:
// linear acc/dec (moving average over Ts) or exponential acc/dec (first-order lag, time constant
// Ts). Maths and config keys: stages/interpolate/README.md.
#pragma once

#include <complex>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "gcpipe/block.hpp"
#include "gcpipe/kinematics.hpp"

namespace gcpipe {
class Config;
}

namespace gcpipe::interpolate {

enum class Smoothing : std::uint8_t {
  kNone,         //!< raw interpolator output
  kLinear,       //!< moving average over Ts: a velocity step becomes a ramp of length Ts
  kExponential,  //!< first-order lag of time constant Ts: initial acceleration dv/Ts
};

/// Which control runs the program (README.md beside this file, "Control models").
enum class Control : std::uint8_t {
  kAfterInterpolation,  //!< seed 002: blocks at their feed, acc/dec after interpolation (smoothing), no look-ahead
  kLookahead,           //!< a modern control: jerk-limited feed planned over a look-ahead of blocks BEFORE
                        //!< interpolation, corners blended within the path tolerance, exact stop with an
                        //!< in-position check at every rapid's end and at G61 / G09 blocks (the plan is
                        //!< stages/simulate/reference.cpp's; this interpolator then gives the path only)
};

struct InterpolateOptions {
  double period = 0.001;                  //!< interpolation period ITP [s]
  Control control = Control::kAfterInterpolation;
  /// kLookahead: the largest deviation of a blended corner from the programmed path [mm] where
  /// the program sets no G64 P (LinuxCNC's naive-CAM / blend tolerance, Fanuc's corner tolerance).
  double path_tolerance = 0.02;
  Smoothing smoothing = Smoothing::kExponential;
  Axes smoothing_time{};                  //!< Ts per axis [s] (0: no smoothing on that axis)
  Axes max_velocity{{500, 500, 500, 3600, 3600}};          //!< [mm/s, deg/s] (machine limits)
  Axes max_acceleration{{5000, 5000, 5000, 36000, 36000}}; //!< [mm/s^2, deg/s^2] (machine limits)
  Axes travel_min{{-1e9, -1e9, -1e9, -1e9, -1e9}};  //!< joint travel [mm, deg] (machine limits)
  Axes travel_max{{1e9, 1e9, 1e9, 1e9, 1e9}};       //!< joint travel [mm, deg] (machine limits)
  /// Optional length of the tool-tip path of a straight joint move [mm] (from forward
  /// kinematics); when empty, G94 feed is along XYZ, or along A/C in deg/min when no linear axis
  /// moves (the LinuxCNC rule). Ignored when `kinematics` is set (which measures lines and arcs).
  std::function<double(const Axes& from, const Axes& to)> tip_path_length;
  /// Machine model (not owned; must outlive the Interpolator). With it: tool-centre-point blocks
  /// are interpolated in the workpiece frame and converted to joints per sample, and G94 feed of
  /// joint moves that turn a rotary axis is along the tool-tip path (lines and arcs). Without it
  /// a block with `tcp` set is rejected kUnsupported. The tool length of a block is
  /// block.tool_length when block.tool_length_active, else kinematics->tool_length.
  const MachineKinematics* kinematics = nullptr;
  /// Machine-time bound [s]: a block that would end after it is not interpolated (kTooLong),
  /// checked before its first sample, so that one block (`G1 X100 F0.001`, an arc of thousands
  /// of turns, a long dwell) cannot run for hours or fill memory.
  double max_time = std::numeric_limits<double>::infinity();
  /// In G61 / G61.1 the next block starts once every axis's command is within this of the
  /// block's end [mm, deg] (a Fanuc control's in-position width, parameter 1826, is of this order).
  double in_position = 0.01;
};

/// Reads the `interpolate` section (period, smoothing); unknown keys rejected. The limits come
/// from the machine file (MachineKinematics::max_velocity / max_acceleration) and smoothing_time
/// from the drives file (Table 1 Ts): the caller fills them in.
InterpolateOptions load_interpolate_options(const Config& section);

/// Per-axis speed bound of a block [mm/s, deg/s]: the axis's velocity limit, and the speed whose
/// step the acc/dec turns into exactly the acceleration limit (linear: dv/Ts; exponential: initial
/// slope dv/Ts). A block that would need more is lengthened.
Axes speed_bound(const InterpolateOptions& options);

/// One axis of acceleration/deceleration after interpolation.
class AxisSmoother {
 public:
  AxisSmoother() = default;
  AxisSmoother(Smoothing kind, double Ts, double period, double start);
  double filter(double x);
  /// True when the output has reached `x` to within `tol`.
  bool settled(double x, double tol) const;
  /// Samples after which a held input is reached (linear) or 50 Ts (exponential).
  std::size_t settle_samples() const;

 private:
  Smoothing kind_ = Smoothing::kNone;
  std::vector<double> ring_;
  std::size_t head_ = 0, count_ = 0;
  double sum_ = 0, y_ = 0, a_ = 0;
  std::size_t settle_ = 0;
};

/// Frequency response of the smoother applied to samples of period T, at omega [rad/s]:
/// linear (1/N) sum_k e^{-j w k T}, exponential (1 - a) / (1 - a e^{-j w T}).
std::complex<double> smoothing_response(Smoothing kind, double Ts, double period, double omega);

/// Receives one commanded sample per period.
class SampleSink {
 public:
  virtual ~SampleSink() = default;
  virtual void sample(const Axes& command) = 0;
  /// The raw (unsmoothed) path sample of the same tick, called just before sample(): the nominal
  /// path for contour errors and the nominal angle of circle tests.
  virtual void raw_sample(const Axes& raw) { (void)raw; }
};

enum class InterpolateStatus : std::uint8_t {
  kOk,
  kUnsupported,  //!< a motion this stage does not execute (G275 must be expanded first; a
                 //!< tool-centre-point block without InterpolateOptions::kinematics)
  kInvalid,      //!< zero or negative feed, non-finite target, axis with no velocity limit,
                 //!< zero tool vector, tool vector reversed by 180 deg
  kTooLong,      //!< the block would end after InterpolateOptions::max_time
};

struct InterpolateResult {
  InterpolateStatus status = InterpolateStatus::kOk;
  std::string message;     //!< for kUnsupported / kInvalid: names the block and what to do
  double duration = 0;     //!< time the block takes [s]
  bool velocity_limited = false;  //!< the feed was lowered to respect an axis velocity limit
  double feed_factor = 1;         //!< when it was: the fraction of the programmed feed the block runs at
  // What the axes allow on this block whatever its feed, for a feed planner ahead of the
  // interpolator (stages/force: the force-aware feed is capped by the drives). At a G94 feed F
  // [length/min] the block takes max(60 feed_length / F, limit_duration): the largest feed the
  // limits let run as programmed is 60 feed_length / limit_duration.
  double feed_length = 0;     //!< length the G94 feed is measured along [mm; deg for rotary-only]; 0: not a G94 feed move
  double limit_duration = 0;  //!< shortest duration the joint velocity (and in TCP mode acceleration) limits allow [s]
  Axes axis_travel{};         //!< largest |dq_i/ds| over the block, s in [0, 1]: axis i moves at most axis_travel_i / duration [mm/s, deg/s]
};

struct InterpolateStats {
  std::uint64_t samples = 0;
  std::uint64_t blocks = 0;
  std::uint64_t velocity_limited_blocks = 0;
  /// Of the blocks whose feed was clamped to the axes' speed bound, as a control clamps a feed
  /// above an axis's maximum: the first and last source line, and the one clamped most.
  std::uint64_t first_clamped_line = 0, last_clamped_line = 0, most_clamped_line = 0;
  double most_clamped_factor = 1;  //!< the fraction of its programmed feed that block ran at
  double most_clamped_feed = 0;    //!< that block's programmed F [mm/min; 1/min in G93]
  bool most_clamped_inverse_time = false;  //!< that F is G93's
  Axes peak_velocity{};      //!< of the smoothed commands [mm/s, deg/s]
  Axes peak_acceleration{};  //!< of the smoothed commands [mm/s^2, deg/s^2]
  std::array<std::uint64_t, kNumAxes> travel_violations{};  //!< samples outside travel per axis
  std::uint64_t first_violation_line = 0;  //!< source line of the first such sample (0: none)
  int first_violation_axis = -1;           //!< its axis (index into X Y Z A C)
  double first_violation_position = 0;     //!< the farthest that axis is commanded beyond its travel [mm, deg]
  std::uint64_t tcp_blocks = 0;            //!< blocks interpolated in tool-centre-point mode
  /// Raw TCP samples whose inverse kinematics failed: joints outside travel (the joints are still
  /// the continuous solution and are emitted) or no finite solution (the previous joints are
  /// held, so no NaN reaches a command).
  std::uint64_t ik_failed_samples = 0;
  std::uint64_t ik_unreachable_samples = 0;  //!< of those, the ones without a finite solution
  std::uint64_t first_ik_failure_line = 0;   //!< source line of the first such sample (0: none)
};

class Interpolator {
 public:
  /// Starts at rest at `start`. Throws ConfigError for a non-positive period or Ts < 0.
  Interpolator(InterpolateOptions options, const Axes& start);
  /// Emits the samples whose time falls inside this block. Never throws.
  InterpolateResult add(const ResolvedBlock& block, SampleSink& sink);
  /// Holds the last position until every smoother has settled.
  void finish(SampleSink& sink);
  /// End of the raw (unsmoothed) path so far [mm, deg].
  const Axes& position() const { return raw_end_; }
  const InterpolateStats& stats() const { return stats_; }
  const InterpolateOptions& options() const { return opt_; }

 private:
  struct BlockPlan;  // one block's path, its TCP map and duration (interpolate.cpp)
  // The steps of add(), in order; the first three return a result when the block ends there.
  std::optional<InterpolateResult> plan_path(const ResolvedBlock& b, BlockPlan& plan, SampleSink& sink);
  std::optional<InterpolateResult> plan_duration(const ResolvedBlock& b, BlockPlan& plan, InterpolateResult& res) const;
  std::optional<InterpolateResult> tcp_duration(const ResolvedBlock& b, BlockPlan& plan, InterpolateResult& res,
                                                double length_xyz) const;
  bool travel_message(const ResolvedBlock& b, double duration, InterpolateResult& res) const;
  std::optional<InterpolateResult> account(const ResolvedBlock& b, const BlockPlan& plan, InterpolateResult& res);
  void count_clamped_feed(const ResolvedBlock& b, const InterpolateResult& res);
  void sample(const ResolvedBlock& b, const BlockPlan& plan, SampleSink& sink);
  void emit(const Axes& raw, SampleSink& sink);
  double hold_until_in_position(SampleSink& sink);
  double hold_end(SampleSink& sink, double tolerance);
  InterpolateOptions opt_;
  bool tcp_space_ = false;    // the last moving block was a TCP block (targets were tool tips)
  bool pole_turn_ = false;    // inside the C turn that precedes a G43.5 block leaving the pole
  std::array<AxisSmoother, kNumAxes> smooth_;
  std::uint64_t line_ = 0;    // source line of the block being sampled
  Axes raw_end_{};
  double t_block_ = 0;        // start time of the next block on the raw clock [s]
  std::uint64_t n_ = 0;       // index of the last emitted sample
  Axes prev_{}, prev2_{};     // last two smoothed samples (for the peak figures)
  InterpolateStats stats_;
};

}  // namespace gcpipe::interpolate
