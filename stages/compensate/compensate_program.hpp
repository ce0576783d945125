// The compensation of one whole program, as `gcpipe batch` and `gcpipe node compensate` both run
// it: nominal run, the "before" evaluation, the learning, and the text of compensated.nc. One
// function, so the batch job and the DDS node write the same bytes.
#pragma once

#include <optional>
#include <span>
#include <string>

#include "compensate.hpp"
#include "write.hpp"

namespace gcpipe::compensate {

struct ProgramCompensation {
  Axes start{};                      //!< machine joints the simulation starts from
  std::optional<Nominal> nominal;    //!< set when the program moves
  std::optional<Evaluation> before;  //!< set when the nominal run completed
  std::optional<Result> result;      //!< set when compensation ran (options.enabled)
  std::string text;                  //!< compensated.nc, empty when not compensated
  std::string note;                  //!< why there is no simulation or no compensated program
};

/// Runs the stage on `program` (the blocks after the trochoid stage, in order). Never throws for
/// a program the machine cannot run: the reason goes to `note`.
ProgramCompensation compensate_program(const Model& model, const CompensateOptions& options,
                                       const WriteOptions& write_options,
                                       std::span<const ResolvedBlock> program, const Progress& progress);

}  // namespace gcpipe::compensate
