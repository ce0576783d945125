// The compensation of one whole program, as the compensate stage runs it in batch mode and in its
// DDS node: the learning on the program's simulation, and the text of compensated.nc. One
// function, so both write the same bytes.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "compensate.hpp"
#include "write.hpp"

namespace gcpipe::compensate {

/// Where compensated.nc's points lie: how far the compensation moved them off the path.
struct PointEnvelope {
  bool work_frame = false;  //!< CompensatedFrames::work_frame (three-axis, the source's frames)
  /// [mm] the largest distance of a written point's tool tip from the program's nominal path
  /// (the contour metric's search, reaching 0.25 s past the reference's progress at the point's
  /// tick, since the points lead the path by up to the learning operator's 0.1 s): every point of
  /// compensated.nc lies within this of the source's path.
  double envelope = 0;
  std::uint64_t points_clamped = 0;  //!< three-axis points lifted to their source block's lowest Z
};

struct ProgramCompensation {
  std::optional<Result> result;  //!< set when compensation ran (options.enabled)
  std::string text;              //!< compensated.nc when no TextSink took it; empty when not compensated
  std::string note;              //!< why there is no compensated program
  PointEnvelope envelope;        //!< of the points written
};

/// A motion block of compensated.nc: the program block it stands for (what a read-back of the
/// text measures it against) and the reference tick its move starts from (a rapid written as the
/// source wrote it runs on the control's clock, not the reference's: the read-back takes the
/// reference's up again at the next block).
struct PointSource {
  std::uint32_t block = 0;
  std::uint64_t tick = 0;
};

/// Where compensated.nc goes as it is written: pieces of whole lines, in order, each with the
/// source of each of its motion blocks, in order. The sink takes the piece (leaves it empty or
/// not, as it likes).
using TextSink = std::function<void(std::string& piece, const std::vector<PointSource>& points)>;

/// The checks compensated.nc read back must pass before `gcpipe batch` keeps it (issue 30
/// item 5), motion block by motion block as the parser reads the text: every timed point's tool
/// tip within the stated envelope of the source's path (and 5 um for the text's rounding); in a
/// three-axis program in its work frame, no point below its source block's lowest Z and every
/// move written as the source wrote it (rapids, G28 / G30 / G53) ending where the source's does.
class EnvelopeMeter;

class ReadBackChecks {
 public:
  ReadBackChecks(const Model& model, const Nominal& nom, std::span<const ResolvedBlock> program, bool work_frame);
  ~ReadBackChecks();
  ReadBackChecks(const ReadBackChecks&) = delete;
  ReadBackChecks& operator=(const ReadBackChecks&) = delete;
  /// A motion block of the text as read back (machine file frame), with what it stands for.
  void add(const ResolvedBlock& b, const PointSource& source);
  /// Empty when every check held; else each that failed, with its worst point.
  std::string failures(double envelope) const;

 private:
  struct Worst {
    double value = 0;
    std::uint64_t line = 0;
  };
  static void keep(Worst& w, double value, std::uint64_t line);
  std::span<const ResolvedBlock> program_;
  bool work_frame_;
  std::unique_ptr<EnvelopeMeter> meter_;
  Worst farthest_, below_floor_, rapid_off_;
};

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
