// Stage `parse`: ISO 6983 text to resolved blocks.
//
// A streaming parser: lines in, resolved blocks and diagnostics out through a ParseSink, modal
// state carried between lines. A plain line gives one block; a canned cycle or G28 gives several
// plain moves carrying its line; o-word calls and loops give the blocks of the lines they run.
// Per-line problems are handed out as a Diagnostic, never thrown; construction with a bad config
// throws ConfigError. Dialect: Fanuc first, LinuxCNC spellings where they do not conflict
// (see README.md, "The parse stage", for the accepted language and every error).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "gcpipe/block.hpp"
#include "gcpipe/diagnostic.hpp"
#include "gcpipe/machine.hpp"

namespace gcpipe {

class Config;

/// The largest parse.max_line_length a config may set [bytes].
inline constexpr std::size_t kLargestLineLength = 65536;

struct ParseOptions {
  Dialect dialect = Dialect::kFanuc;
  /// Fanuc's decimal-point rule: an axis value written without a point counts in the smallest
  /// input increment (0.001 mm, 0.0001 inch, 0.001 deg): `Z50` = 0.050 mm. Off: plain decimals.
  bool decimal_point_increments = false;
  bool block_delete = true;          //!< skip lines starting with '/' (the operator's switch)
  bool strict = false;               //!< stop at the first error instead of skipping the line
  std::size_t max_line_length = 256; //!< longer lines are rejected [bytes]
  Units initial_units = Units::kMillimetre;
  /// I J K as absolute centres from the start (G90.1), as some Heidenhain/Mastercam posts write
  /// them; default incremental (G91.1). The program's own G90.1/G91.1 still switch.
  bool absolute_arc_centres = false;
  /// Leniency (off by default): the offset word along an arc's plane normal (K in G17, J in G18,
  /// I in G19), which Grbl ignores and FreeCAD posts write (`G2 X1 Y0 I.5 J0 K0`), is ignored
  /// with a warning on each line instead of rejecting the line, as LinuxCNC does.
  bool ignore_arc_normal_word = false;
  /// Flow control keeps lines to run again (loop bodies, lines after a call to a subroutine
  /// defined further down, subroutine bodies); more than this many is an error, not a memory
  /// blow-up.
  std::size_t max_buffered_lines = 200000;
  /// One loop may run at most this many passes, and one source line may make the parser run at
  /// most 1000 times as many lines on its behalf (nested loops, recursion): no input can hang.
  std::uint64_t max_loop_passes = 100000;
  /// One block may expand into at most this many moves (canned-cycle pecks times repeats): past it
  /// the block is an error before it is expanded, not gigabytes of pecks.
  std::uint64_t max_cycle_moves = 1000000;
  int max_call_depth = 64;  //!< subroutine calls nested deeper than this are an error
  /// A feed per minute (G94) below this [mm/min] is an error at its F word: a slip of the post
  /// (F0.001 for F1000) would run for hours. Inverse-time feeds (G93) are bounded by the
  /// simulation's machine-time limit instead.
  double min_feed = 1.0;
  /// Fanuc G76/G87: the direction of the shift Q at the oriented spindle stop, as the control's
  /// parameter 5101 bits RD2 RD1 (0..3): 0 + first axis of the plane (G17 +X, G18 +Z, G19 +Y),
  /// 1 - first axis, 2 + second axis (G17 +Y, G18 +X, G19 +Z), 3 - second axis.
  int boring_shift = 0;
};

/// Reads the `parse` section of a pipeline config (every key documented in the README).
ParseOptions load_parse_options(const Config& parse_section);

/// What happened to each line; the counts add up: read = emitted + rejected + deleted.
/// Each line is counted once, when the main program first runs it or passes over it.
struct ParseSummary {
  std::uint64_t lines_read = 0;
  /// Lines that produced output: one block, or several (a cycle, a call, a loop's last line,
  /// which runs the passes after the first).
  std::uint64_t blocks_emitted = 0;
  /// Lines with an error (one error diagnostic each). A call or loop whose expansion fails is
  /// rejected too, with the failing line's place in the diagnostic; moves it made before the
  /// error have been handed out.
  std::uint64_t lines_rejected = 0;
  /// Lines skipped (one note each): block delete '/', and lines the program does not run where
  /// they stand (subroutine definitions, branches not taken, loops that run zero times).
  std::uint64_t lines_deleted = 0;
  std::uint64_t bytes_read = 0;
  /// Blocks handed out in all (>= blocks_emitted: expansions count each move).
  std::uint64_t blocks_out = 0;
  std::uint64_t lines_not_run = 0;  //!< of lines_deleted: not run (flow control), not '/'
};

enum class LineStatus : std::uint8_t {
  kBlock,     //!< `block` holds the resolved line
  kRejected,  //!< `diag` says why; modal state unchanged
  kDeleted,   //!< skipped on purpose: block delete, or not run where it stands (flow control)
};

/// Receives the parser's output in program order; a callback returns false to stop the parse.
struct ParseSink {
  std::function<bool(const ResolvedBlock&)> block;
  /// Errors (a rejected line, severity kError) and notes (a skipped line, severity kNote).
  std::function<bool(const Diagnostic&)> diagnostic;
};

struct LineOutput;

class Parser {
 public:
  /// `file` names the source in diagnostics.
  Parser(ParseOptions options, MachineConfig machine, std::string file);
  ~Parser();
  Parser(Parser&&) noexcept;
  Parser& operator=(Parser&&) noexcept;

  /// Reads the next line of the program (no terminator) and hands what it makes to `sink`: for
  /// a plain program exactly one block or one diagnostic per line, at once. Inside flow control
  /// output may come later (a loop runs when its end is read; a call to a subroutine defined
  /// further down waits for the definition; under cutter compensation, G41/G42, each XY move
  /// and the blocks after it come out when the next XY move is read). `overlong_length` > 0
  /// tells that the reader cut the
  /// line at max_line_length and it really had that many bytes. Returns false once the sink
  /// asked to stop.
  bool feed(std::string_view line, const ParseSink& sink, std::size_t overlong_length = 0);
  /// End of input: reports what still waits (a call to an undefined subroutine, an unclosed
  /// loop or definition) and counts every line. Call once after the last feed().
  bool finish(const ParseSink& sink);

  /// feed() into `out` (cleared first): for tools and tests that look at one line at a time.
  bool feed(std::string_view line, LineOutput& out, std::size_t overlong_length = 0);
  bool finish(LineOutput& out);

  const ParseSummary& summary() const;
  const ParseOptions& options() const;
  /// True after M2/M30 or the tape's closing '%': later lines are still read and accounted for
  /// (a note each: not run), but nothing after the end runs.
  bool ended() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A whole program held in memory, line by line through `parser` into `sink`, then finish():
/// for text a stage wrote (compensated.nc read back) and for tests and tools. Returns false
/// when the sink asked to stop.
bool feed_text(Parser& parser, std::string_view text, const ParseSink& sink);

/// What one feed() or finish() handed out, in order.
struct LineOutput {
  std::vector<ResolvedBlock> blocks;
  std::vector<Diagnostic> diagnostics;
  const Diagnostic* error() const {
    for (const auto& d : diagnostics)
      if (d.severity == Severity::kError) return &d;
    return nullptr;
  }
};

}  // namespace gcpipe
