// Cutting force along a program: the feed moves as a polyline, swept through a height-field
// stock one spindle revolution at a time (the mean force of seed 003 is a per-revolution
// quantity); at each revolution the engagement, the mean and peak force of the mechanistic model
// and the tool deflection they cause. And the force-aware feed: per move, the feed whose
// predicted mean force is the target, never over the peak limit.
#pragma once

#include <cstddef>
#include <vector>

#include "force_options.hpp"
#include "gcpipe/block.hpp"
#include "stock.hpp"

namespace gcpipe::force {

/// One straight piece of the tool-tip path.
struct Move {
  Vec3 from{}, to{};          //!< [mm]
  double feed = 0;            //!< [mm/min]; 0 for rapids
  double spindle = 0;         //!< [rev/min]
  bool cutting = false;       //!< a feed move (G1/G2/G3); rapids never cut
  std::size_t block = 0;      //!< index of the block it came from
};

/// The blocks' moves in the XY plane (arcs as chords within `chord` mm); blocks with A/C motion
/// or in another plane are taken as their straight end-to-end line (2.5D model, README).
std::vector<Move> moves_from_blocks(const std::vector<ResolvedBlock>& blocks, double chord = 0.005);

struct ForceSample {
  double time = 0;              //!< since the first feed move, feed moves only [s]
  double x = 0, y = 0, z = 0;   //!< tool tip [mm]
  double feed = 0;              //!< [mm/min]
  double angle = 0;             //!< immersion with material [rad]
  double radial_depth = 0;      //!< equivalent ae [mm]
  double axial_depth = 0;       //!< largest a [mm]
  double mean_force = 0;        //!< |mean force vector| over the revolution [N]
  double peak_force = 0;        //!< largest instantaneous |F| in the revolution [N]
  double deflection = 0;        //!< tip deflection under the mean XY force [mm]
  double peak_deflection = 0;   //!< under the largest instantaneous force [mm]
  double mean_tangential = 0;   //!< mean over the revolution of the flutes' summed Ft [N]
  double torque = 0;            //!< mean spindle torque = mean_tangential * D / 2 [N m]
  double power = 0;             //!< mean cutting power = torque * omega [W]
  double planned_feed = 0;      //!< feed holding the target force here (0: planner off) [mm/min]
  std::size_t move = 0;         //!< index into the moves
};

struct PathForce {
  std::vector<ForceSample> samples;
  double cutting_time = 0;     //!< sum of feed-move length / feed [s] (no acceleration)
  double max_mean_force = 0;   //!< [N]
  double max_peak_force = 0;   //!< [N]
  double max_deflection = 0;   //!< under the peak force [mm]
  double max_mean_tangential = 0;  //!< [N]
  double max_torque = 0;       //!< [N m]
  double max_power = 0;        //!< [W]
};

/// The stock of `o.stock`, or when it is unset the box around the feed moves (tool radius + 2 mm
/// margin) topped at the highest point of any feed move.
HeightField make_stock(const std::vector<Move>& moves, const ForceOptions& o);

/// Sweeps the moves through (a copy of) `stock`, one sample per spindle revolution of travel or
/// per o.sample_spacing.
PathForce sweep_path(const std::vector<Move>& moves, const ForceOptions& o, HeightField stock);

/// Feed per move [mm/min] holding each revolution's predicted mean force at o.target_force and
/// its instantaneous peak under o.peak_force, within [o.min_feed, o.max_feed_factor * programmed].
/// A move gets the smallest feed of its revolutions (none: the next revolution's).
std::vector<double> plan_feeds(const std::vector<Move>& moves, const PathForce& swept, const ForceOptions& o);

/// The blocks with each feed block's F set to the smallest planned feed of its moves.
std::vector<ResolvedBlock> apply_feeds(const std::vector<ResolvedBlock>& blocks, const std::vector<Move>& moves,
                                       const std::vector<double>& feeds);

/// The moves with the spindle speed replaced by `rpm` (the config's spindle_speed); rpm 0: as is.
std::vector<Move> with_spindle_speed(std::vector<Move> moves, double rpm);

}  // namespace gcpipe::force
