// Stage `compensate`: a program is run through the machine model (interpolator + feed drives of
// the config), and a new program in machine axes is computed whose *simulated* actual motion
// follows the original's nominal tool path. Maths, convergence and limits: README.md beside this
// file.
//
//   1. Nominal run. The original program is interpolated (TCP blocks through the kinematics per
//      tick) and simulated. Its raw, unsmoothed joint samples R_n define the nominal path; the
//      contour error "before" is the distance from FK(actual) to that path.
//   2. Reference. The path planned as a look-ahead control runs it (stages/simulate/reference.cpp):
//      feed planned over the whole program, corners passed at the speed compensate.path_tolerance
//      allows, jerk-limited by smoothing the path parameter; it lies within path_tolerance of the
//      nominal path, and its duration is the planned cycle time the compensated program keeps.
//   3. Nodes. The compensated program is a chain of G93 G1 blocks in machine axes, one per node
//      (node_period, a multiple of the interpolation period). Kinematic linearisation: a node
//      interval is halved while joint-linear motion between its ends leaves the reference tool-tip
//      path by more than linearisation_tolerance.
//   4. Iterative learning control. u_{k+1} = u_k + gain * Q[L e_k], e_k = r - y_k per axis, with
//      L a FIR inverse of the whole chain acc/dec + feed drive per axis, designed from the chain's
//      simulated step response (chain_inverse.hpp); the start is u_0 = L r. Each iterate is
//      simulated with the same interpolator and drives as the original; an iterate that would
//      exceed an axis's velocity, acceleration, torque or travel is rejected and the gain halved.
//      The learning runs window by window (16 s and a 2 s margin): each window is learned from the
//      machine state the committed nodes before it leave (simulate::MachineRun), its nodes are
//      committed, and only a window's series are held and replayed.
// The model comes from the config (machine file, interpolate section, drives file), so a drives
// file calibrated from measured traces is compensated against with no code change.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "gcpipe/block.hpp"
#include "gcpipe/kinematics.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "simulate.hpp"

namespace gcpipe {
class Config;
}

namespace gcpipe::compensate {

/// `compensate` section of a pipeline config (README.md beside this file lists the keys).
struct CompensateOptions {
  bool enabled = true;                  //!< false: batch simulates and reports, writes no nodes
  double node_period = 0.004;           //!< [s] time between points of the compensated program
  double linearisation_tolerance = 0.001;  //!< [mm] tool-tip deviation of joint-linear motion
  simulate::ReferencePlan reference;    //!< path_tolerance, blend_time, reference_acceleration
  int max_iterations = 25;              //!< ILC iterations after the model-inverse start
  double gain = 1.0;                    //!< ILC learning gain (0, 1]
  double max_machine_time = 3600;       //!< [s] longer programs are simulated but not compensated
  std::uint64_t max_blocks = 500000;    //!< more blocks: not simulated (memory is per block)
  /// Three-axis programs in the source's work frame (CompensatedFrames::work_frame); false: every
  /// program in machine joints behind the guard (README "Output": what the work frame costs).
  bool work_frame = false;
  bool slowed_baseline = true;          //!< also simulate the original slowed to the compensated
                                        //!< cycle time (the baseline in report.json)
  /// Look-ahead control: slow the plan locally where the drives' model inverse needs more
  /// acceleration than an axis has (local_slowdown.hpp). Off by default: measured, it cost
  /// 6-15 % of the cycle on the CAM-like programs and did not lower their error (README.md
  /// beside this file, "Slowing where the drives cannot follow").
  bool slow_for_drive_limits = false;
};

/// Reads the `compensate` section; unknown keys rejected; throws ConfigError.
CompensateOptions load_compensate_options(const Config& section);

/// The simulation bounds and reference plan of these options.
simulate::RunBounds run_bounds(const CompensateOptions& options);

// The simulation (model, run, nominal, evaluation) lives in stages/simulate: one harness and one
// contour metric for `gcpipe simulate`, the compensation and the report.
using simulate::AxisStats;
using simulate::ErrorStats;
using simulate::Evaluation;
using simulate::Model;
using simulate::Nominal;
using simulate::Progress;
using simulate::RunStats;
using simulate::Segment;
using simulate::SegmentDemand;
using simulate::Series;
using simulate::Tick;
using simulate::build_nominal;
using simulate::dist3;
using simulate::lerp;
using simulate::evaluate;
using simulate::load_model;
using simulate::machine_start;
using simulate::run_program;
using simulate::tool_length_of;

/// One ILC iteration as recorded in the report.
struct Iteration {
  int index = 0;             //!< 0: model-inverse start
  double max_contour = 0;    //!< [mm]
  double rms_contour = 0;    //!< [mm], an upper bound: ticks that cannot raise a largest error are measured near their previous match only
  double gain = 0;
  bool accepted = true;
  std::string rejected_because;  //!< which limit an iterate broke
};

/// One point of the compensated program.
struct Node {
  std::uint64_t tick = 0;    //!< time = tick * period
  Axes joints{};             //!< [mm, deg]
  std::uint32_t block = 0;   //!< source block index it belongs to (for N numbers and M words)
};

/// One window of the learning: the part of the compensated clock whose nodes it committed.
struct LearningWindow {
  double t_begin = 0, t_end = 0;  //!< [s]
  int iterations = 0;             //!< learning iterations it ran (the start included)
  bool out_of_iterations = false; //!< still gaining when compensate.max_iterations ran out
};

/// Result of the compensation.
struct Result {
  bool compensated = false;
  std::string note;                     //!< why not, or what limits the result
  /// Every node, node 0 (the start) first, when compensate() was given no NodeSink; with one they
  /// went to it window by window and are not kept.
  std::vector<Node> nodes;
  std::uint64_t points = 0;    //!< nodes after node 0: the timed points of the compensated program
  std::uint64_t end_tick = 0;  //!< the last node's tick: the compensated cycle time is end_tick * period
  std::vector<Iteration> iterations;
  std::uint64_t linearisation_splits = 0;   //!< node intervals halved
  double linearisation_max_deviation = 0;   //!< [mm] after splitting
  double source_joint_linear_deviation = 0; //!< [mm] worst tool-tip deviation if the source's
                                            //!< TCP blocks were run joint-linearly between IK ends
  std::uint64_t source_blocks_needing_split = 0;
  /// Per one-second window of the compensated clock (key: the window's index = its first second)
  /// that broke a limit in some iteration: the last limit it broke, e.g. "axis X acceleration
  /// 5062 > limit 5050 at t 28-29 s". Only such windows are kept.
  std::map<std::size_t, std::string> window_limits;
  std::vector<LearningWindow> windows;  //!< in order
  std::uint64_t learning_ticks = 0;     //!< ticks the learning simulated (its runs and commits)
  /// The window that committed time t [s] (the last one past the end), or null.
  const LearningWindow* window_at(double t) const {
    for (const LearningWindow& w : windows)
      if (t < w.t_end) return &w;
    return windows.empty() ? nullptr : &windows.back();
  }
};

/// Where the learning hands its nodes as it commits them, window by window, in order (node 0
/// first): `learned` says whether a window so far has learned anything (a program none of whose
/// windows learns is not compensated, Result::compensated).
using NodeSink = std::function<void(std::span<const Node> nodes, bool learned)>;

/// Computes the compensated nodes. `program` is the original, `nominal` its nominal run.
/// `before` is evaluate()'s figures for the program itself (its per-segment demand bounds the
/// learning). Without a `sink` the nodes are collected in Result::nodes.
Result compensate(const Model& model, const Nominal& nominal, std::span<const ResolvedBlock> program,
                  const Axes& start, const Evaluation& before, const CompensateOptions& options,
                  const Progress& progress, const NodeSink& sink = {});

/// How compensated.nc states its frames (compensate_program.cpp chooses; README "Output").
struct CompensatedFrames {
  /// A three-axis program (no TCP, A and C never move): the points in the source's work
  /// coordinates with its tool length (G54.., G43 H as the source has them), so the control's
  /// own offsets and tool lengths are honoured; a move that starts where only the control knows
  /// the tool is written as the source wrote it (as_source). Otherwise the points are machine
  /// joints of the machine file under G49 (tool-centre-point blocks; a non-TCP block keeps its
  /// G43 H), behind a guard.
  bool work_frame = false;
  /// Per program block (work_frame only): its move goes out as the source wrote it, not as timed
  /// points (moves_written_as_source).
  std::vector<bool> as_source;
  /// Called before the first timed point and before the first point after each tool change,
  /// with the index of that point's source block: where the guard of a five-axis program goes.
  std::function<void(std::size_t block)> section_start;
};

/// The compensated program's blocks made as the nodes come, window by window: the node blocks
/// (G93 G1, N = source line) interleaved with the program's non-motion blocks, in program order,
/// each handed to `emit` (valid during the call) with the index of the program block it stands
/// for and the reference tick its move starts from.
class CompensatedBlocks {
 public:
  /// `tick`: the reference tick the block's move starts from (its first point's predecessor).
  using Emit = std::function<void(const ResolvedBlock& block, std::size_t source, std::uint64_t tick)>;
  CompensatedBlocks(std::span<const ResolvedBlock> program, double period, Emit emit, CompensatedFrames frames = {});
  /// The next nodes, in order; the first call's first node is node 0, the start.
  void add(std::span<const Node> nodes);
  /// The program's blocks after the last node.
  void finish();

 private:
  void pass_block(std::size_t i);
  void note_motion(const ResolvedBlock& b, ResolvedBlock& c);
  void settle_before(std::size_t i);
  bool next_move_written_as_source(std::size_t i) const;
  void node(const Node& nd);
  std::span<const ResolvedBlock> program_;
  double period_;
  Emit emit_;
  CompensatedFrames frames_;
  bool started_ = false;
  Node last_node_;               // the node the next one moves from
  std::size_t next_ = 0;         // next program block not yet passed
  std::uint64_t noted_line_ = 0; // source line of the last motion note
  bool have_node_ = false;       // a node block was written
  bool section_open_ = false;    // the guard hook ran since the start or the last tool change
  bool after_points_ = false;    // timed points were the last moves written (work frame)
  double last_feed_ = 0;
  Axes last_target_{};           // where the last block written leaves the machine
  ResolvedBlock block_;          // the node block being handed on
};

/// Per block of a three-axis program: whether its move goes out as the source wrote it. A timed
/// point in work coordinates moves from where the machine file's frames put the tool; where the
/// control's frames may put it elsewhere, that is a jump. So a G28 / G30 / G53 move goes out as
/// such (it ends at a position only the control knows), and so does every move until X Y and Z
/// have each been given an absolute position again after the program start, such a move, a
/// change of work system, origin (G10, G92, G52) or (for Z) tool length.
std::vector<bool> moves_written_as_source(std::span<const ResolvedBlock> program);

/// True when the program is three-axis as CompensatedFrames::work_frame means it: no
/// tool-centre-point block, and A and C never move.
bool three_axis_program(std::span<const ResolvedBlock> program);

/// CompensatedBlocks of a result's collected nodes in a vector (for tests: on a long program they
/// take 472 bytes a node).
std::vector<ResolvedBlock> compensated_blocks(std::span<const ResolvedBlock> program, const Result& result,
                                              double period);

/// "axis X acceleration 5062 > limit 5050", as the learning says why it held back: whole units, or
/// as many decimals (up to 3) as the two need not to read the same (an iterate over the limit by a
/// fraction read "5050 > limit 5050").
std::string acceleration_over_limit(char axis, double peak, double limit);

}  // namespace gcpipe::compensate
