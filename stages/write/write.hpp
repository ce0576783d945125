// Stage `write`: resolved blocks back to ISO 6983 text.
//
// Output is explicit and portable: absolute (G90), every number with a decimal point (so Fanuc's
// decimal-point rule cannot misread it), incremental IJK arc centres, one block per line, N = the
// source line number so every output block points back to the line it came from. Lengths are in
// the block's source units (G21 unless the source was inch): an arc's radius tolerance depends on
// them. Modal words are written when they change, as a post-processor does.
// parse(write(parse(p))) == parse(p) block for block (tests/write_test.cpp): discrete fields
// identical, numbers within 1e-9 relative (IJK are re-added to the start on reading).
#pragma once

#include <cstdint>
#include <string>

#include "gcpipe/block.hpp"
#include "gcpipe/diagnostic.hpp"

namespace gcpipe {

class Config;

struct WriteOptions {
  /// Decimal places for coordinates; -1 = the shortest text that reads back to the same double.
  int decimals = -1;
  /// Fanuc: `G4 X<s>`, TCP as G43.4 H / G43 / G49. LinuxCNC: `G4 P<s>`, TCP as M428 / M429.
  /// Parse the output with the same dialect.
  Dialect dialect = Dialect::kFanuc;
  /// Write `N<source line>` on each block.
  bool source_line_numbers = true;
};

/// Reads the `write` section of a pipeline config.
WriteOptions load_write_options(const Config& write_section);

class Writer {
 public:
  explicit Writer(WriteOptions options = {});

  /// Appends the text of one block (one line, or nothing for a block with nothing to say).
  void write(const ResolvedBlock& block, std::string& out);
  /// Appends a comment line recording a source line that produced no block (rejected, or skipped
  /// by block delete), so the output shows what was dropped and why.
  void write_diagnostic(const Diagnostic& diag, std::string& out);

 private:
  WriteOptions opt_;
  // What the output has established so far; starts at the control defaults the header asserts.
  bool header_done_ = false;
  bool have_motion_ = false;
  Motion motion_ = Motion::kNone;
  Plane plane_ = Plane::kXY;
  FeedMode feed_mode_ = FeedMode::kUnitsPerMinute;
  bool inch_ = false;
  double feed_ = 0;
  bool have_pos_ = false;
  Axes pos_{};  // program coordinates the output has reached
  std::int32_t work_offset_ = 54;
  bool tlo_active_ = false;
  std::int32_t tlo_ = 0;
  bool tcp_ = false;
  double spindle_speed_ = 0;
  Spindle spindle_ = Spindle::kOff;
  std::int32_t tool_ = 0;
  std::uint8_t coolant_ = 0;
};

}  // namespace gcpipe
