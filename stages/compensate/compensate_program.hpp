// The compensation of one whole program, as the compensate stage runs it in batch mode and in its
// DDS node: the learning on the program's simulation, and the text of compensated.nc. One
// function, so both write the same bytes.
#pragma once

#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "compensate.hpp"
#include "write.hpp"

namespace gcpipe::compensate {

struct ProgramCompensation {
  std::optional<Result> result;  //!< set when compensation ran (options.enabled)
  std::string text;              //!< compensated.nc when no TextSink took it; empty when not compensated
  std::string note;              //!< why there is no compensated program
};

/// Where compensated.nc goes as it is written: pieces of whole lines, in order, each with the
/// program block each of its timed points stands for (in order: what a read-back of the text
/// measures them against). The sink takes the piece (leaves it empty or not, as it likes).
using TextSink = std::function<void(std::string& piece, const std::vector<std::uint32_t>& point_blocks)>;

/// The guard a five-axis compensated.nc (machine joints) carries before its first point
/// (`program_start`: the work offsets of every system the program uses, no G92 / external
/// offset) and before the first point after a tool change (the tool length the joints hold, from
/// the tool-centre-point block of `program` at or after `first`): checks of the control's own
/// offsets that stop the program with a message when they differ (LinuxCNC `o.. if` with
/// `(abort, ...)`, Fanuc `IF [...] THEN #3000 = n`). Empty when there is nothing to check.
std::string five_axis_guard(std::span<const ResolvedBlock> program, std::size_t first, bool program_start, Dialect d);

/// Compensates the simulated program `run` (simulate::simulate_program). Never throws for a
/// program the machine cannot run: the reason goes to `note`. With a `text` sink compensated.nc
/// goes to it window by window as the learning commits its nodes, once a window has learned
/// (until then it is held: a program none of whose windows learns is not written), and is not
/// kept; without one it is collected in ProgramCompensation::text.
ProgramCompensation compensate_program(const Model& model, const CompensateOptions& options,
                                       const WriteOptions& write_options, const simulate::SimulationRun& run,
                                       const Progress& progress, const TextSink& text = {});

}  // namespace gcpipe::compensate
