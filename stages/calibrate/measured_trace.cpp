#include "measured_trace.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>

namespace gcpipe::calibrate {

namespace {

constexpr std::size_t kMaxDiagnostics = 1000;  // a broken file must not fill memory with messages

struct Field {
  std::string_view text;
  std::size_t column = 0;  // 1-based byte column of its first character
};

std::vector<Field> split(std::string_view line) {
  std::vector<Field> out;
  std::size_t pos = 0;
  while (true) {
    const std::size_t comma = line.find(',', pos);
    const std::size_t end = comma == std::string_view::npos ? line.size() : comma;
    out.push_back({line.substr(pos, end - pos), pos + 1});
    if (comma == std::string_view::npos) break;
    pos = comma + 1;
  }
  return out;
}

Diagnostic diag(const std::string& file, std::uint64_t line, std::size_t col, std::string msg) {
  Diagnostic d;
  d.file = file;
  d.line = line;
  d.column = static_cast<std::uint32_t>(col);
  d.message = std::move(msg);
  return d;
}

/// Parses a finite double filling the whole field; on failure says why.
std::optional<std::string> to_number(std::string_view f, double& v, std::size_t& bad_offset) {
  bad_offset = 0;
  if (f.empty()) return "is empty";
  auto [p, ec] = std::from_chars(f.data(), f.data() + f.size(), v);
  if (ec != std::errc() || p != f.data() + f.size()) {
    bad_offset = ec == std::errc() ? static_cast<std::size_t>(p - f.data()) : 0;
    return "'" + std::string(f) + "' is not a number";
  }
  if (!std::isfinite(v)) return "'" + std::string(f) + "' is not finite";
  return std::nullopt;
}

// ---------------------------------------------------------------------------------------------
// Column layout of a file: which field goes where.

enum class Slot : std::uint8_t { kTime, kCommand, kActual, kEffort, kActualVelocity, kCommandVelocity, kIgnore };
struct Column {
  Slot slot = Slot::kIgnore;
  int axis = 0;
  std::string name;
};
struct Layout {
  TraceFormat format = TraceFormat::kSharedCsv;
  std::vector<Column> columns;
  double fixed_period = 0;  // > 0: no time column, t = row index x this (UMich)
  std::array<std::string, kNumAxes> effort_kind;
};

std::string expected_unit(const std::string& base) {
  if (base == "t") return "s";
  const char a = base[0];
  if (base.ends_with("_torque")) return "N*m";
  if (base.ends_with("_current")) return "A";
  return (a == 'A' || a == 'C') ? "deg" : "mm";
}

/// The shared CSV header: t,X_cmd..C_cmd,X..C then optional <axis>_torque / <axis>_current, each
/// name optionally with a [unit] that must be the documented one.
std::optional<Layout> shared_layout(std::string_view header, const std::string& file,
                                    std::vector<Diagnostic>& out) {
  static const char* kNames[11] = {"t", "X_cmd", "Y_cmd", "Z_cmd", "A_cmd", "C_cmd", "X", "Y", "Z", "A", "C"};
  const auto fields = split(header);
  Layout lay;
  int with_units = 0;
  for (const auto& f : fields) with_units += f.text.find('[') != std::string_view::npos;
  for (std::size_t i = 0; i < fields.size(); ++i) {
    std::string name(fields[i].text), unit;
    if (const auto b = name.find('['); b != std::string::npos) {
      if (name.back() != ']') {
        out.push_back(diag(file, 1, fields[i].column, "column '" + name + "': unit not closed with ']'"));
        return std::nullopt;
      }
      unit = name.substr(b + 1, name.size() - b - 2);
      name = name.substr(0, b);
    }
    if (i < 11 && name != kNames[i]) {
      out.push_back(diag(file, 1, fields[i].column,
                         "unknown header: column " + std::to_string(i + 1) + " is '" + name + "', expected '" +
                             kNames[i] + "' (shared trace CSV t,X_cmd,...,C_cmd,X,...,C; or pass --format)"));
      return std::nullopt;
    }
    if (with_units > 0 && unit.empty()) {
      out.push_back(diag(file, 1, fields[i].column,
                         "units missing for column '" + name + "': the header gives units for some columns; give [" +
                             expected_unit(name) + "] here too"));
      return std::nullopt;
    }
    if (!unit.empty() && unit != expected_unit(name)) {
      out.push_back(diag(file, 1, fields[i].column,
                         "column '" + name + "' is in '" + unit + "'; convert it to " + expected_unit(name)));
      return std::nullopt;
    }
    Column c;
    c.name = name;
    if (i == 0) c.slot = Slot::kTime;
    else if (i < 6) { c.slot = Slot::kCommand; c.axis = static_cast<int>(i) - 1; }
    else if (i < 11) { c.slot = Slot::kActual; c.axis = static_cast<int>(i) - 6; }
    else {
      const auto us = name.find('_');
      const std::string axis = name.substr(0, us), kind = us == std::string::npos ? "" : name.substr(us + 1);
      const auto a = std::string_view("XYZAC").find(axis);
      if (axis.size() != 1 || a == std::string_view::npos || (kind != "torque" && kind != "current")) {
        out.push_back(diag(file, 1, fields[i].column,
                           "unknown column '" + name + "': extra columns are <X|Y|Z|A|C>_torque or <X|Y|Z|A|C>_current"));
        return std::nullopt;
      }
      c.slot = Slot::kEffort;
      c.axis = static_cast<int>(a);
      lay.effort_kind[a] = kind;
    }
    lay.columns.push_back(c);
  }
  if (fields.size() < 11) {
    out.push_back(diag(file, 1, header.size() + 1,
                       "header has " + std::to_string(fields.size()) + " of the 11 columns t,X_cmd,...,C"));
    return std::nullopt;
  }
  return lay;
}

/// University of Michigan CSV: an unnamed index column, then X1_/Y1_/Z1_ quantities at 100 ms.
std::optional<Layout> umich_layout(std::string_view header, const std::string& file,
                                   std::vector<Diagnostic>& out) {
  const auto fields = split(header);
  Layout lay;
  lay.format = TraceFormat::kUmichCsv;
  lay.fixed_period = 0.1;  // the data set's documented sampling (PROVENANCE.md)
  int found = 0;
  for (const auto& f : fields) {
    Column c;
    c.name = std::string(f.text);
    for (int a = 0; a < 3; ++a) {
      const std::string p = std::string(1, "XYZ"[a]) + "1_";
      if (!c.name.starts_with(p)) continue;
      const std::string q = c.name.substr(3);
      c.axis = a;
      if (q == "ActualPosition") c.slot = Slot::kActual;
      else if (q == "CommandPosition") c.slot = Slot::kCommand;
      else if (q == "ActualVelocity") c.slot = Slot::kActualVelocity;
      else if (q == "CommandVelocity") c.slot = Slot::kCommandVelocity;
      else if (q == "CurrentFeedback") { c.slot = Slot::kEffort; lay.effort_kind[a] = "current"; }
    }
    found += c.slot != Slot::kIgnore;
    lay.columns.push_back(c);
  }
  if (found != 15) {
    out.push_back(diag(file, 1, 1, "UMich header lacks some of X1/Y1/Z1 _ActualPosition, _CommandPosition, "
                                    "_ActualVelocity, _CommandVelocity, _CurrentFeedback"));
    return std::nullopt;
  }
  return lay;
}

std::optional<Layout> detect(std::string_view header, const std::optional<TraceFormat>& forced,
                             const std::string& file, std::vector<Diagnostic>& out) {
  const bool umich = header.find("X1_ActualPosition") != std::string_view::npos;
  const TraceFormat f = forced ? *forced : (umich ? TraceFormat::kUmichCsv : TraceFormat::kSharedCsv);
  return f == TraceFormat::kUmichCsv ? umich_layout(header, file, out) : shared_layout(header, file, out);
}

/// One data row into `values` (per column; ignored columns left 0). nullopt when accepted.
std::optional<Diagnostic> parse_row(std::string_view line, const Layout& lay, const std::string& file,
                                    std::uint64_t n, std::vector<double>& values) {
  const auto fields = split(line);
  if (fields.size() < lay.columns.size())
    return diag(file, n, line.size() + 1,
                "row has " + std::to_string(fields.size()) + " of " + std::to_string(lay.columns.size()) +
                    " columns (truncated?)");
  if (fields.size() > lay.columns.size())
    return diag(file, n, fields[lay.columns.size()].column,
                "row has more than " + std::to_string(lay.columns.size()) + " columns");
  values.assign(lay.columns.size(), 0.0);
  for (std::size_t i = 0; i < fields.size(); ++i) {
    if (lay.columns[i].slot == Slot::kIgnore) continue;
    std::size_t off = 0;
    if (auto why = to_number(fields[i].text, values[i], off))
      return diag(file, n, fields[i].column + off, "column '" + lay.columns[i].name + "' " + *why);
  }
  return std::nullopt;
}

void store(MeasuredTrace& tr, const Layout& lay, const std::vector<double>& v, double t) {
  tr.t.push_back(t);
  for (std::size_t i = 0; i < lay.columns.size(); ++i) {
    const auto a = static_cast<std::size_t>(lay.columns[i].axis);
    switch (lay.columns[i].slot) {
      case Slot::kCommand: tr.command[a].push_back(v[i]); break;
      case Slot::kActual: tr.actual[a].push_back(v[i]); break;
      case Slot::kEffort: tr.effort[a].push_back(v[i]); break;
      case Slot::kActualVelocity: tr.actual_velocity[a].push_back(v[i]); break;
      case Slot::kCommandVelocity: tr.command_velocity[a].push_back(v[i]); break;
      default: break;
    }
  }
}

/// UMich has X Y Z only: A and C are held at zero so the five-axis code paths stay uniform.
void pad_axes(MeasuredTrace& tr) {
  for (int a = 0; a < kNumAxes; ++a) {
    tr.command[a].resize(tr.t.size(), 0.0);
    tr.actual[a].resize(tr.t.size(), 0.0);
  }
}

}  // namespace

std::optional<TraceFormat> parse_format(std::string_view name) {
  if (name == "csv" || name == "shared") return TraceFormat::kSharedCsv;
  if (name == "umich") return TraceFormat::kUmichCsv;
  return std::nullopt;
}

std::string_view format_name(TraceFormat f) { return f == TraceFormat::kUmichCsv ? "umich" : "csv"; }

namespace {

/// Keeps the longest stretch without gaps; with !skip any gap rejects the file.
bool cut_gaps(MeasuredTrace& tr, const ReadOptions& o, const std::vector<std::uint64_t>& lines,
              std::vector<Diagnostic>& out) {
  std::vector<double> dt;
  for (std::size_t i = 1; i < tr.t.size(); ++i) dt.push_back(tr.t[i] - tr.t[i - 1]);
  if (dt.empty()) return true;
  std::vector<double> s = dt;
  std::nth_element(s.begin(), s.begin() + static_cast<std::ptrdiff_t>(s.size() / 2), s.end());
  tr.period = s[s.size() / 2];
  std::size_t best_b = 0, best_e = 0, b = 0;
  for (std::size_t i = 0; i <= dt.size(); ++i) {
    const bool gap = i < dt.size() && dt[i] > o.max_gap * tr.period;
    if (gap && out.size() < kMaxDiagnostics)
      out.push_back(diag(tr.file, lines[i + 1], 1,
                         "gap of " + std::to_string(dt[i]) + " s before this row (period " +
                             std::to_string(tr.period) + " s): samples are missing"));
    if (gap || i == dt.size()) {
      if (i + 1 - b > best_e - best_b) { best_b = b; best_e = i + 1; }
      b = i + 1;
    }
  }
  if (best_e - best_b == tr.t.size()) return true;
  if (!o.skip_bad_rows) return false;
  tr.rows_unused = tr.t.size() - (best_e - best_b);
  auto cut = [&](std::vector<double>& v) {
    if (v.empty()) return;
    v = std::vector<double>(v.begin() + static_cast<std::ptrdiff_t>(best_b), v.begin() + static_cast<std::ptrdiff_t>(best_e));
  };
  cut(tr.t);
  for (int a = 0; a < kNumAxes; ++a) {
    cut(tr.command[a]); cut(tr.actual[a]); cut(tr.effort[a]); cut(tr.actual_velocity[a]); cut(tr.command_velocity[a]);
  }
  return true;
}

}  // namespace

ReadResult read_trace(std::istream& in, const std::string& file, const ReadOptions& o) {
  ReadResult r;
  std::string buf;
  if (!std::getline(in, buf)) {
    r.diagnostics.push_back(diag(file, 1, 1, "empty file: a trace needs a header line and rows"));
    return r;
  }
  if (!buf.empty() && buf.back() == '\r') buf.pop_back();
  const auto lay = detect(buf, o.format, file, r.diagnostics);
  if (!lay) return r;
  MeasuredTrace tr;
  tr.file = file;
  tr.format = lay->format;
  tr.effort_kind = lay->effort_kind;
  std::vector<double> values;
  std::vector<std::uint64_t> lines;  // source line of each kept row
  std::uint64_t n = 1, bad = 0;
  double prev_t = -INFINITY;
  while (std::getline(in, buf)) {
    ++n;
    if (!buf.empty() && buf.back() == '\r') buf.pop_back();
    ++tr.lines_read;
    auto d = parse_row(buf, *lay, file, n, values);
    const double t = lay->fixed_period > 0 ? static_cast<double>(tr.lines_read - 1) * lay->fixed_period : values.empty() ? 0 : values[0];
    if (!d && !(t > prev_t))
      d = diag(file, n, 1, "time " + std::to_string(t) + " s does not increase (previous " + std::to_string(prev_t) + " s)");
    if (d) {
      ++bad;
      if (r.diagnostics.size() < kMaxDiagnostics) r.diagnostics.push_back(*d);
      continue;
    }
    prev_t = t;
    store(tr, *lay, values, t);
    lines.push_back(n);
  }
  if (bad > 0 && !o.skip_bad_rows) return r;
  tr.rows_skipped = bad;
  if (tr.format == TraceFormat::kUmichCsv) pad_axes(tr);
  if (!cut_gaps(tr, o, lines, r.diagnostics)) return r;
  if (tr.size() < o.min_rows) {
    r.diagnostics.push_back(diag(file, n, 1,
                                 "only " + std::to_string(tr.size()) + " usable rows; the fit needs at least " +
                                     std::to_string(o.min_rows) + " (record a longer trace)"));
    return r;
  }
  r.trace = std::move(tr);
  return r;
}

ReadResult read_trace_file(const std::filesystem::path& path, const ReadOptions& options) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    ReadResult r;
    r.diagnostics.push_back(diag(path.string(), 0, 0, "cannot open the trace: check the path and permissions"));
    return r;
  }
  return read_trace(in, path.string(), options);
}

}  // namespace gcpipe::calibrate
