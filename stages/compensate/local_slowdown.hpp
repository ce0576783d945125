// Issue 31 item 3: the compensated program keeps the control's timing, except where a drive
// limit forbids the pre-compensation at the control's speed. There the plan is slowed locally,
// and the report says where (lines, seconds) and by how much. Derivation: README.md beside this
// file, "Slowing where the drives cannot follow".
#pragma once

#include <optional>
#include <span>
#include <vector>

#include "chain_inverse.hpp"
#include "simulate.hpp"

namespace gcpipe::compensate {

/// One stretch the compensation's plan runs slower than the control's.
struct SlowStretch {
  std::uint64_t first_line = 0, last_line = 0;  //!< source lines
  double t_begin = 0, t_end = 0;                //!< [s] on the control's clock
  double factor = 1;                            //!< speed limit multiplied by this
};

struct LocalSlowdown {
  std::optional<simulate::SimulationRun> run;  //!< the program on the slowed plan (none: no slowing)
  std::vector<SlowStretch> stretches;
  int rounds = 0;                    //!< plans made
  double worst_over_limit = 0;       //!< the feed-forward's largest acceleration / limit left
};

/// The plan of `control` (its nominal path, its planned reference) slowed where the drives'
/// model-inverse command (feed-forward `ff`, measured on that plan) needs more acceleration than
/// an axis has: each such second, widened by 0.5 s either side, gets its speed limits multiplied
/// by 0.95 / sqrt(ratio) (on a fixed path the acceleration goes with the square of the speed),
/// and the plan is made again and measured again, at most `max_rounds` times.
LocalSlowdown slow_where_drives_cannot_follow(const simulate::Model& model, const simulate::SimulationRun& control,
                                              const FeedforwardRun& ff, simulate::ReferencePlan plan,
                                              double max_machine_time, int max_rounds = 3);

}  // namespace gcpipe::compensate
