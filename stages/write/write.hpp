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
  /// Fanuc: `G4 X<s>`, TCP as G43.4 H / G43.5 H (tool vector I J K) / G43 / G49. LinuxCNC:
  /// `G4 P<s>`, TCP as M428 / M429; LinuxCNC has no tool-vector TCP, so blocks in G43.5 mode are
  /// refused (see Writer::write). Parse the output with the same dialect.
  Dialect dialect = Dialect::kFanuc;
  /// Write `N<source line>` on each block.
  bool source_line_numbers = true;
  /// Keep the source's frames (output.nc, the write stage): positions in the program's own
  /// coordinates, G54..G59 and G43 H / G49 where the source states them, G10 / G92 / G52 / G28 /
  /// G30 / G53 written as such, so the output runs on the control's own work offsets, tool
  /// table and reference positions as the source does (docs/reference.md, "The write stage").
  /// Off: every position in the machine file's G5x frame under a header that asserts G54 and
  /// G49, as compensated.nc needs (its points are machine positions computed with that file).
  bool source_frames = false;
};

/// Reads the `write` section of a pipeline config.
WriteOptions load_write_options(const Config& write_section);

class Writer {
 public:
  explicit Writer(WriteOptions options = {});

  /// Appends the text of one block (one line, or nothing for a block with nothing to say).
  /// Returns false when the block cannot be said in the output dialect: a block in G43.5 mode
  /// (tool vector) with dialect linuxcnc. Such a block is replaced by a comment line
  /// `(gcpipe: line N not written: ...)` and counted in refused_blocks(); the writer's state does
  /// not advance, so the next writable block restates whatever it needs.
  bool write(const ResolvedBlock& block, std::string& out);
  /// Blocks refused so far (see write()).
  std::uint64_t refused_blocks() const { return refused_; }
  /// Appends a comment line recording a source line that produced no block (rejected, or skipped
  /// by block delete), so the output shows what was dropped and why.
  void write_diagnostic(const Diagnostic& diag, std::string& out);

 private:
  struct Line;
  bool refuse(const ResolvedBlock& b, std::string& out);
  bool write_program_start(const ResolvedBlock& b, std::string& out);
  void units_and_offset(const ResolvedBlock& b, Line& line);
  void path_control(const ResolvedBlock& b, Line& line);
  void tool_length_and_tcp(const ResolvedBlock& b, Line& line);
  void feed_mode_tool_spindle_coolant(const ResolvedBlock& b, Line& line);
  void motion(const ResolvedBlock& b, Line& line);
  void motion_word(Motion m, const char* text, Line& line);
  void axes(const ResolvedBlock& b, Line& line, std::uint8_t must);
  void feed(const ResolvedBlock& b, Line& line, bool always);
  void tool_vector(const ResolvedBlock& b, Line& line);
  void arc(const ResolvedBlock& b, Line& line);
  void slot(const ResolvedBlock& b, Line& line);
  void program_stop(const ResolvedBlock& b, Line& line);
  // -- source frames (WriteOptions::source_frames)
  const Axes& origin_of(const ResolvedBlock& b) const;
  void work_offset(const ResolvedBlock& b, Line& line);
  void distance(bool incremental, Line& line);
  std::uint8_t axes_to_write(const ResolvedBlock& b, std::uint8_t must) const;
  void frame_statement(const ResolvedBlock& b, Line& line);
  void reference_return(const ResolvedBlock& b, Line& line);
  void machine_move(const ResolvedBlock& b, Line& line);
  void set_origin(const ResolvedBlock& b, Line& line);
  void tool_entry(const ResolvedBlock& b, Line& line);
  void statement_words(const ResolvedBlock& b, const Axes& values, Line& line);
  void forget_after(const ResolvedBlock& b);

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
  PathMode path_mode_ = PathMode::kBlend;  // G64 without P: the control's own blending
  double path_tolerance_ = 0;              // [mm]
  bool tlo_active_ = false;
  std::int32_t tlo_ = 0;
  double tlo_length_ = 0;  // the length in force as the parser has it (a G10 may change it)
  bool tcp_ = false;
  bool tool_vector_mode_ = false;
  bool tool_vector_written_ = false;  // an I J K vector has been written since G43.5
  Vec3 tool_vector_{0, 0, 1};
  std::uint64_t refused_ = 0;
  double spindle_speed_ = 0;
  Spindle spindle_ = Spindle::kOff;
  std::int32_t tool_ = 0;
  std::uint8_t coolant_ = 0;
  // Source frames: whether the output has selected a work system yet (before, the control's own
  // is in force), the distance mode the output is in, and the axes whose position in program
  // coordinates the control is known to share with the parser (an absolute position written since
  // the start, a G28/G30/G53, a change of work system or of the origin in force): a G91 move of
  // any other axis is written as the increment it is.
  bool work_offset_written_ = false;
  bool incremental_ = false;
  std::uint8_t known_ = 0;
  std::string note_;  // a line said differently than the source (a dialect cannot say it), said before it
};

}  // namespace gcpipe
