// The compensation of one whole program, as the compensate stage runs it in batch mode and in its
// DDS node: the learning on the program's simulation, and the text of compensated.nc. One
// function, so both write the same bytes.
#pragma once

#include <optional>
#include <span>
#include <string>

#include "compensate.hpp"
#include "write.hpp"

namespace gcpipe::compensate {

struct ProgramCompensation {
  std::optional<Result> result;  //!< set when compensation ran (options.enabled)
  std::string text;              //!< compensated.nc, empty when not compensated
  std::string note;              //!< why there is no compensated program
};

/// Compensates the simulated program `run` (simulate::simulate_program). Never throws for a
/// program the machine cannot run: the reason goes to `note`.
ProgramCompensation compensate_program(const Model& model, const CompensateOptions& options,
                                       const WriteOptions& write_options, const simulate::SimulationRun& run,
                                       const Progress& progress);

}  // namespace gcpipe::compensate
