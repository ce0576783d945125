// The drives under the force-aware feed: what the machine's axes let a block run at, measured by
// the interpolate stage itself (one kinematics, one feed rule: stages/interpolate), and the
// program's time as that interpolator runs it. The planner's rules: stages/force/README.md sec. 6c.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "gcpipe/block.hpp"
#include "interpolate.hpp"

namespace gcpipe::force {

/// What the drives allow on one block, whatever its feed.
struct BlockDrive {
  bool planned = false;  //!< a G94 feed move: its feed is the planner's to set
  bool stops = true;     //!< the path speed is 0 where the block ends (exact stop, or not a feed move)
  double length = 0;     //!< length the feed is measured along [mm]
  double max_feed = std::numeric_limits<double>::infinity();   //!< every axis within its velocity limit [mm/min]
  double max_accel = std::numeric_limits<double>::infinity();  //!< along the path, every axis within its acceleration limit [mm/s^2]
};

/// The program as the interpolator runs it.
struct DriveRun {
  std::vector<BlockDrive> blocks;  //!< one per block
  double cycle_time = 0;           //!< every block's duration, rapids and dwells included [s]
  double feed_move_time = 0;       //!< the G1/G2/G3 blocks' durations [s]
  std::string failure;             //!< the interpolator refused a block: its message ("": ran whole)
};

/// Runs `blocks` through an Interpolator with `o` from `start` (joints at rest; no samples kept).
DriveRun run_on_drives(const std::vector<ResolvedBlock>& blocks, const interpolate::InterpolateOptions& o,
                       const Axes& start);

/// Highest speed [mm/s] inside a block of length s [mm] entered at v_in and left at v_out at
/// acceleration a: up at a, then down at a, v^2 = (v_in^2 + v_out^2 + 2 a s) / 2.
double reachable_peak(double v_in, double v_out, double a, double s);

/// The planned feeds capped by the drives: each G94 feed block's F at most its max_feed, and at
/// most the highest speed the path reaches inside the block between the junction speeds of the
/// forward/backward pass at max_accel (README sec. 6c).
std::vector<ResolvedBlock> limit_feeds_to_drives(std::vector<ResolvedBlock> blocks, const std::vector<BlockDrive>& drives);

}  // namespace gcpipe::force
