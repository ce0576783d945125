// The inputs a measured-data spindle model (seed 003's NNOE trained by `gcpipe train-spindle`,
// spindle_model.hpp) needs, taken from a program as the interpolate stage times it: the machine's
// XYZ path speed, the spindle speed and whether a cutting move runs, one value every `period`
// seconds of the interpolator's clock (stages/force/README.md sec. 8b).
#pragma once

#include <vector>

#include "gcpipe/block.hpp"
#include "interpolate.hpp"

namespace gcpipe::force {

/// One value per model sample, the i-th at t_k = k * period, k = i + 1 (t = 0 is the start).
struct ProgramInputs {
  double period = 0;             //!< [s]
  std::vector<double> feed;      //!< commanded XYZ path speed of the machine axes over the tick ending at t_k [mm/s]
  std::vector<double> spindle;   //!< spindle speed of the block running at t_k, 0 when stopped (M5) [rev/min]
  std::vector<double> cutting;   //!< 1 when that block is a G1/G2/G3 move with the spindle turning, else 0
  std::string failure;           //!< the interpolator refused a block: its message ("": ran whole)
};

/// Runs `blocks` through an Interpolator with `o` from `start` (at rest) and samples the commanded
/// axes every `period` seconds (a whole number of interpolation periods, the nearest one). A
/// non-zero `spindle_rpm` replaces every running block's S (the force section's spindle_speed).
ProgramInputs sample_program_inputs(const std::vector<ResolvedBlock>& blocks, const interpolate::InterpolateOptions& o,
                                    const Axes& start, double period, double spindle_rpm = 0);

}  // namespace gcpipe::force
