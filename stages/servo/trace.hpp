// The axis trace shared by simulation and measured data: CSV with the header
//   t,X_cmd,Y_cmd,Z_cmd,A_cmd,C_cmd,X,Y,Z,A,C
// in s, mm and deg, one row per tick. Measured traces (SERVO GUIDE, halscope exports converted to
// this layout) and simulated ones are read by the same reader, so the calibration loop compares
// like with like.
#pragma once

#include <cstdint>
#include <istream>
#include <ostream>
#include <string>
#include <string_view>

#include "gcpipe/block.hpp"
#include "gcpipe/diagnostic.hpp"
#include "gcpipe/double_chars.hpp"

namespace gcpipe {

/// The header line, exactly.
inline constexpr std::string_view kTraceHeader = "t,X_cmd,Y_cmd,Z_cmd,A_cmd,C_cmd,X,Y,Z,A,C";

/// One tick: time [s], commanded and actual joints [mm, deg].
struct TraceRow {
  double t = 0;
  Axes command{};
  Axes actual{};
};

/// Writes the header on construction, then one line per row. Time with 6 decimals (1 us),
/// positions in the shortest text that reads back to the same double.
class TraceWriter {
 public:
  explicit TraceWriter(std::ostream& out);
  void row(const TraceRow& r);
  std::uint64_t rows() const { return rows_; }

 private:
  std::ostream& out_;
  std::string line_;
  std::uint64_t rows_ = 0;
};

/// Formats one row without the line terminator (used by the writer and the tests).
std::string format_trace_row(const TraceRow& r);
/// Appends the same text to `out` (no line end): no allocation per row on a long trace.
void append_trace_row(std::string& out, const TraceRow& r);

/// Appends the text of append_trace_row, row after row, faster: a column whose value is the same
/// double as in the row before (a still axis: on most traces several of the ten) has its text
/// copied instead of formatted again, and the row goes into `out` in one append. Shortest
/// round-trip formatting is most of a trace's cost (`gcpipe simulate`'s writer thread).
class TraceRowFormatter {
 public:
  void append(std::string& out, const TraceRow& r);

 private:
  struct Column {
    std::uint64_t bits = 0;  //!< of the value formatted last
    char text[kShortestDoubleChars] = {};  //!< its text
    std::uint8_t size = 0;   //!< 0: nothing formatted yet
  };
  /// Column i (commands 0 .. kNumAxes - 1, then actuals) takes the double whose bits are `bits`.
  void format_column(Column& c, std::size_t i, std::uint64_t bits, double v);
  Column columns_[2 * kNumAxes];
};

enum class TraceStatus : std::uint8_t {
  kRow,    //!< `row` holds the next tick
  kError,  //!< `diag` says where (line:col) and why; the reader continues with the next line
  kEnd,    //!< no more input
};

/// Reads a trace; every problem is a Diagnostic with line:col, never an exception. A wrong header
/// is reported once on line 1 and every data line is still checked.
class TraceReader {
 public:
  TraceReader(std::istream& in, std::string file);
  TraceStatus next(TraceRow& row, Diagnostic& diag);
  std::uint64_t line() const { return line_; }

 private:
  TraceStatus parse(std::string_view text, TraceRow& row, Diagnostic& diag);
  std::istream& in_;
  std::string file_;
  std::string buf_;
  std::uint64_t line_ = 0;
  bool header_done_ = false;
  bool have_prev_ = false;
  double prev_t_ = 0;
};

}  // namespace gcpipe
