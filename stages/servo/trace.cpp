#include "trace.hpp"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>

#include "gcpipe/double_chars.hpp"

namespace gcpipe {

namespace {

void append_number(std::string& s, double v) {
  char buf[kShortestDoubleChars];
  s.append(buf, write_shortest(buf, v));
}

void append_time(std::string& s, double v) {
  char buf[64];
  s.append(buf, write_fixed(buf, buf + sizeof buf, v, 6));
}

constexpr const char* kColumns[11] = {"t", "X_cmd", "Y_cmd", "Z_cmd", "A_cmd", "C_cmd",
                                      "X",   "Y",     "Z",     "A",     "C"};

}  // namespace

std::string format_trace_row(const TraceRow& r) {
  std::string s;
  append_trace_row(s, r);
  return s;
}

void append_trace_row(std::string& s, const TraceRow& r) {
  append_time(s, r.t);
  for (double v : r.command) {
    s += ',';
    append_number(s, v);
  }
  for (double v : r.actual) {
    s += ',';
    append_number(s, v);
  }
}

// The row is built in one buffer with room for every column at full width, so that a column's
// text is copied whole (a fixed size: two moves, no call) and the end advanced by its length.
void TraceRowFormatter::append(std::string& s, const TraceRow& r) {
  constexpr std::size_t kTimeRoom = 64;
  char row[kTimeRoom + 2 * kNumAxes * (1 + sizeof Column::text)];
  char* p = write_fixed(row, row + kTimeRoom, r.t, 6);
  for (std::size_t i = 0; i < 2 * kNumAxes; ++i) {
    const double v = i < kNumAxes ? r.command[i] : r.actual[i - kNumAxes];
    Column& c = columns_[i];
    const auto bits = std::bit_cast<std::uint64_t>(v);
    if (c.size == 0 || c.bits != bits) format_column(c, i, bits, v);
    *p++ = ',';
    std::memcpy(p, c.text, sizeof c.text);
    p += c.size;
  }
  s.append(row, static_cast<std::size_t>(p - row));
}

// An axis that follows its command exactly (a still axis, or one settling as the bench's Z does,
// down to subnormals) has the same double in both columns: the command's text, formatted just
// before in this row, is copied rather than worked out again.
void TraceRowFormatter::format_column(Column& c, std::size_t i, std::uint64_t bits, double v) {
  c.bits = bits;
  const Column& command = columns_[i >= kNumAxes ? i - kNumAxes : i];
  if (i >= kNumAxes && command.size != 0 && command.bits == bits) {
    std::memcpy(c.text, command.text, sizeof c.text);
    c.size = command.size;
    return;
  }
  c.size = static_cast<std::uint8_t>(write_shortest(c.text, v) - c.text);
}

TraceWriter::TraceWriter(std::ostream& out) : out_(out) { out_ << kTraceHeader << '\n'; }

void TraceWriter::row(const TraceRow& r) {
  line_ = format_trace_row(r);
  line_ += '\n';
  out_.write(line_.data(), static_cast<std::streamsize>(line_.size()));
  ++rows_;
}

TraceReader::TraceReader(std::istream& in, std::string file) : in_(in), file_(std::move(file)) {}

TraceStatus TraceReader::next(TraceRow& row, Diagnostic& diag) {
  while (std::getline(in_, buf_)) {
    ++line_;
    std::string_view text = buf_;
    if (!text.empty() && text.back() == '\r') text.remove_suffix(1);
    diag = Diagnostic{};
    diag.file = file_;
    diag.line = line_;
    diag.severity = Severity::kError;
    if (!header_done_) {
      header_done_ = true;
      if (text != kTraceHeader) {
        std::size_t col = 0;
        while (col < text.size() && col < kTraceHeader.size() && text[col] == kTraceHeader[col]) ++col;
        diag.column = static_cast<std::uint32_t>(col + 1);
        diag.message = "trace header must be exactly '" + std::string(kTraceHeader) + "' (s, mm, deg)";
        return TraceStatus::kError;
      }
      continue;
    }
    if (text.empty()) {
      diag.column = 1;
      diag.message = "empty line inside the trace";
      return TraceStatus::kError;
    }
    return parse(text, row, diag);
  }
  return TraceStatus::kEnd;
}

TraceStatus TraceReader::parse(std::string_view text, TraceRow& row, Diagnostic& diag) {
  double v[11];
  std::size_t pos = 0;
  for (int i = 0; i < 11; ++i) {
    const std::size_t comma = text.find(',', pos);
    const std::size_t end = comma == std::string_view::npos ? text.size() : comma;
    const std::string_view field = text.substr(pos, end - pos);
    diag.column = static_cast<std::uint32_t>(pos + 1);
    if (field.empty()) {
      diag.message = std::string("column '") + kColumns[i] + "' is empty";
      return TraceStatus::kError;
    }
    auto [p, ec] = std::from_chars(field.data(), field.data() + field.size(), v[i]);
    if (ec != std::errc() || p != field.data() + field.size()) {
      diag.column = static_cast<std::uint32_t>(pos + 1 + (ec == std::errc() ? static_cast<std::size_t>(p - field.data()) : 0));
      diag.message = std::string("column '") + kColumns[i] + "': '" + std::string(field) + "' is not a number";
      return TraceStatus::kError;
    }
    if (!std::isfinite(v[i])) {
      diag.message = std::string("column '") + kColumns[i] + "' is not finite";
      return TraceStatus::kError;
    }
    if (i < 10 && comma == std::string_view::npos) {
      diag.column = static_cast<std::uint32_t>(text.size() + 1);
      diag.message = "row has " + std::to_string(i + 1) + " of 11 columns (truncated?)";
      return TraceStatus::kError;
    }
    if (i == 10 && comma != std::string_view::npos) {
      diag.column = static_cast<std::uint32_t>(comma + 1);
      diag.message = "row has more than 11 columns";
      return TraceStatus::kError;
    }
    pos = end + 1;
  }
  if (have_prev_ && !(v[0] > prev_t_)) {
    diag.column = 1;
    diag.message = "time " + std::string(text.substr(0, text.find(','))) + " s does not increase";
    return TraceStatus::kError;
  }
  have_prev_ = true;
  prev_t_ = v[0];
  row.t = v[0];
  for (std::size_t i = 0; i < 5; ++i) {
    row.command[i] = v[1 + i];
    row.actual[i] = v[6 + i];
  }
  return TraceStatus::kRow;
}

}  // namespace gcpipe
