#include "measured_trace.hpp"

#include "shdr.hpp"  // the one SHDR line grammar (stages/ik), shared with the kinematic fit

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>

namespace gcpipe::calibrate {

namespace {

constexpr std::size_t kMaxDiagnostics = 1000;  // a broken file must not fill memory with messages

struct Field {
  std::string_view text;
  std::size_t column = 0;  // 1-based byte column of its first character
};

/// Comma-separated fields (empty fields kept, so a missing value is seen as empty).
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

/// Whitespace-separated fields (halsampler prints one space between values; runs collapse).
std::vector<Field> split_blanks(std::string_view line) {
  std::vector<Field> out;
  std::size_t pos = 0;
  while (true) {
    pos = line.find_first_not_of(" \t", pos);
    if (pos == std::string_view::npos) break;
    const std::size_t end = std::min(line.find_first_of(" \t", pos), line.size());
    out.push_back({line.substr(pos, end - pos), pos + 1});
    pos = end;
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

enum class Slot : std::uint8_t { kTime, kSampleNumber, kCommand, kActual, kEffort, kActualVelocity, kCommandVelocity, kIgnore };
struct Column {
  Slot slot = Slot::kIgnore;
  int axis = 0;
  std::string name;
};
struct Layout {
  TraceFormat format = TraceFormat::kSharedCsv;
  std::vector<Column> columns;
  double fixed_period = 0;  // > 0 and no time column: t = row index (or sample number) x this
  bool blank_separated = false;  // halsampler: fields split on blanks, no header line
  std::array<std::string, kNumAxes> effort_kind;

  int find(Slot slot) const {
    for (std::size_t i = 0; i < columns.size(); ++i)
      if (columns[i].slot == slot) return static_cast<int>(i);
    return -1;
  }
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

/// A quantity of a user's column map: t, n, X_cmd..C_cmd, X..C, <axis>_torque,
/// <axis>_current, or "-" (ignored). nullopt for anything else.
std::optional<Column> quantity(std::string_view name) {
  Column c;
  c.name = std::string(name);
  if (name == "-") return c;
  if (name == "t") { c.slot = Slot::kTime; return c; }
  if (name == "n") { c.slot = Slot::kSampleNumber; return c; }
  const auto axis = std::string_view("XYZAC").find(name.empty() ? '?' : name[0]);
  if (axis == std::string_view::npos) return std::nullopt;
  c.axis = static_cast<int>(axis);
  const std::string_view rest = name.substr(1);
  if (rest.empty()) c.slot = Slot::kActual;
  else if (rest == "_cmd") c.slot = Slot::kCommand;
  else if (rest == "_torque" || rest == "_current") c.slot = Slot::kEffort;
  else return std::nullopt;
  return c;
}

constexpr const char* kQuantities = "n, t, X_cmd..C_cmd, X..C, <axis>_torque, <axis>_current or -";

/// Every axis with a command needs its actual and the other way round; at least one axis.
std::optional<std::string> check_axes(const Layout& lay) {
  std::array<int, kNumAxes> cmd{}, act{};
  for (const auto& c : lay.columns) {
    if (c.slot == Slot::kCommand) ++cmd[static_cast<std::size_t>(c.axis)];
    if (c.slot == Slot::kActual) ++act[static_cast<std::size_t>(c.axis)];
  }
  int axes = 0;
  for (int a = 0; a < kNumAxes; ++a) {
    const std::string name(1, "XYZAC"[a]);
    if (cmd[a] > 1 || act[a] > 1) return "axis " + name + " is mapped twice";
    if (cmd[a] != act[a]) return cmd[a] ? "column " + name + "_cmd has no actual column " + name : "column " + name + " has no command column " + name + "_cmd";
    axes += cmd[a];
  }
  if (axes == 0) return "no axis has both a command (X_cmd) and an actual (X) column";
  return std::nullopt;
}

/// halsampler output has no header: the columns come from the user (ReadOptions::columns), in
/// the order of the sampler's cfg string, with `n` first when halsampler ran with -t.
std::optional<Layout> halsampler_layout(const ReadOptions& o, const std::string& file, std::vector<Diagnostic>& out) {
  auto fail = [&](const std::string& why) {
    out.push_back(diag(file, 1, 1, "halsampler columns: " + why));
    return std::nullopt;
  };
  if (o.columns.empty())
    return fail("halsampler output has no header; give the pin of every column with --columns, e.g. "
                "--columns n,X_cmd,X,Y_cmd,Y --period 0.001");
  Layout lay;
  lay.format = TraceFormat::kHalsampler;
  lay.blank_separated = true;
  for (const auto& name : o.columns) {
    const auto c = quantity(name);
    if (!c) return fail("'" + name + "' is not one of " + kQuantities);
    if (c->slot == Slot::kEffort) lay.effort_kind[static_cast<std::size_t>(c->axis)] = name.substr(2);
    lay.columns.push_back(*c);
  }
  const bool has_t = lay.find(Slot::kTime) >= 0, has_n = lay.find(Slot::kSampleNumber) >= 0;
  if (has_t && has_n) return fail("give either t (seconds) or n (halsampler -t sample number), not both");
  if (!has_t && !(o.period > 0)) return fail("without a t column the time is n x period: give --period (the sampler thread's period, s)");
  if (auto why = check_axes(lay)) return fail(*why);
  lay.fixed_period = has_t ? 0 : o.period;
  return lay;
}

/// Recognises the format from the first line when the user did not name it.
TraceFormat detect_format(std::string_view first_line) {
  ShdrRecord record;
  if (first_line.find("X1_ActualPosition") != std::string_view::npos) return TraceFormat::kUmichCsv;
  if (parse_shdr_line(first_line, record)) return TraceFormat::kShdr;
  const bool numeric_start = first_line.find_first_not_of(" \t0123456789.+-eE") == std::string_view::npos &&
                             first_line.find_first_of("0123456789") != std::string_view::npos;
  return numeric_start ? TraceFormat::kHalsampler : TraceFormat::kSharedCsv;
}

std::optional<Layout> layout_for(TraceFormat f, std::string_view header, const ReadOptions& o, const std::string& file,
                                 std::vector<Diagnostic>& out) {
  switch (f) {
    case TraceFormat::kUmichCsv: return umich_layout(header, file, out);
    case TraceFormat::kHalsampler: return halsampler_layout(o, file, out);
    default: return shared_layout(header, file, out);
  }
}

/// One data row into `values` (per column; ignored columns left 0). nullopt when accepted.
std::optional<Diagnostic> parse_row(std::string_view line, const Layout& lay, const std::string& file,
                                    std::uint64_t n, std::vector<double>& values) {
  const auto fields = lay.blank_separated ? split_blanks(line) : split(line);
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

/// Axes a file does not carry (UMich: A and C; a three-axis halsampler or SHDR map) are held
/// at zero so the five-axis code paths stay uniform.
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
  if (name == "halsampler") return TraceFormat::kHalsampler;
  if (name == "shdr") return TraceFormat::kShdr;
  return std::nullopt;
}

std::string_view format_name(TraceFormat f) {
  switch (f) {
    case TraceFormat::kUmichCsv: return "umich";
    case TraceFormat::kHalsampler: return "halsampler";
    case TraceFormat::kShdr: return "shdr";
    default: return "csv";
  }
}

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

/// The rows a file gave and what was rejected: the checks every format shares (time increasing,
/// gaps, enough rows) live here once.
struct Rows {
  MeasuredTrace tr;
  std::vector<std::uint64_t> lines;  // source line of each kept row
  std::uint64_t bad = 0;
  double prev_t = -INFINITY;

  void reject(Diagnostic d, ReadResult& r) {
    ++bad;
    if (r.diagnostics.size() < kMaxDiagnostics) r.diagnostics.push_back(std::move(d));
  }
  void keep(const Layout& lay, const std::vector<double>& values, double t, std::uint64_t line, ReadResult& r) {
    if (!(t > prev_t)) {
      reject(diag(tr.file, line, 1, "time " + std::to_string(t) + " s does not increase (previous " + std::to_string(prev_t) + " s)"), r);
      return;
    }
    prev_t = t;
    store(tr, lay, values, t);
    lines.push_back(line);
  }
};

/// Bad rows reject the file unless skip_bad_rows; then gaps and the row count decide.
ReadResult finish(Rows& rows, const ReadOptions& o, std::uint64_t last_line, ReadResult r) {
  if (rows.bad > 0 && !o.skip_bad_rows) return r;
  MeasuredTrace& tr = rows.tr;
  tr.rows_skipped = rows.bad;
  pad_axes(tr);
  if (!cut_gaps(tr, o, rows.lines, r.diagnostics)) return r;
  if (tr.size() < o.min_rows) {
    r.diagnostics.push_back(diag(tr.file, last_line, 1,
                                 "only " + std::to_string(tr.size()) + " usable rows; the fit needs at least " +
                                     std::to_string(o.min_rows) + " (record a longer trace)"));
    return r;
  }
  r.trace = std::move(tr);
  return r;
}

/// Time of a row: its t column, else sample number (halsampler -t) or row index x the period.
double row_time(const Layout& lay, const std::vector<double>& values, std::uint64_t index) {
  if (const int i = lay.find(Slot::kTime); i >= 0) return values[static_cast<std::size_t>(i)];
  if (const int i = lay.find(Slot::kSampleNumber); i >= 0) return values[static_cast<std::size_t>(i)] * lay.fixed_period;
  return static_cast<double>(index) * lay.fixed_period;
}

/// CSV, UMich and halsampler: one row per line. `first` is the header (CSV, UMich) or the first
/// data line (halsampler, which prints no header).
ReadResult read_delimited(std::istream& in, const std::string& first, const Layout& lay, const std::string& file,
                          const ReadOptions& o) {
  Rows rows;
  rows.tr.file = file;
  rows.tr.format = lay.format;
  rows.tr.effort_kind = lay.effort_kind;
  ReadResult r;
  std::vector<double> values;
  std::uint64_t n = 0;
  std::string buf = first;
  bool have = lay.blank_separated;  // halsampler: the first line already is a row
  if (!have) ++n;
  while (have || std::getline(in, buf)) {
    have = false;
    ++n;
    if (!buf.empty() && buf.back() == '\r') buf.pop_back();
    ++rows.tr.lines_read;
    if (auto d = parse_row(buf, lay, file, n, values)) {
      rows.reject(*d, r);
      continue;
    }
    rows.keep(lay, values, row_time(lay, values, rows.tr.lines_read - 1), n, r);
  }
  return finish(rows, o, n, std::move(r));
}

// ---------------------------------------------------------------------------------------------
// MTConnect SHDR: `timestamp|item|value` records, sent only when a value changes. Records of one
// adapter poll cycle (closer than ReadOptions::shdr_cycle) form one row; an item not in the
// cycle keeps its last value.

/// The SHDR items read by default: <axis>position is the adapter's actual position (subType
/// ACTUAL in the NIST GF Agie device file); <axis>commanded the commanded one.
Layout shdr_default_layout() {
  Layout lay;
  lay.format = TraceFormat::kShdr;
  for (int a = 0; a < kNumAxes; ++a) {
    const std::string axis(1, "XYZAC"[a]);
    lay.columns.push_back({Slot::kActual, a, axis + "position"});
    lay.columns.push_back({Slot::kCommand, a, axis + "commanded"});
  }
  return lay;
}

/// The default items with the user's QUANTITY=ITEM pairs applied.
std::optional<Layout> shdr_layout(const ReadOptions& o, const std::string& file, std::vector<Diagnostic>& out) {
  Layout lay = shdr_default_layout();
  for (const auto& pair : o.columns) {
    const auto eq = pair.find('=');
    const auto c = eq == std::string::npos ? std::nullopt : quantity(pair.substr(0, eq));
    if (!c || c->slot == Slot::kTime || c->slot == Slot::kSampleNumber || c->slot == Slot::kIgnore || eq + 1 == pair.size()) {
      out.push_back(diag(file, 1, 1, "SHDR columns: '" + pair + "' is not QUANTITY=ITEM with QUANTITY one of X_cmd..C_cmd, X..C, <axis>_torque, <axis>_current"));
      return std::nullopt;
    }
    std::erase_if(lay.columns, [&](const Column& k) { return k.slot == c->slot && k.axis == c->axis; });
    lay.columns.push_back({c->slot, c->axis, pair.substr(eq + 1)});
    if (c->slot == Slot::kEffort) lay.effort_kind[static_cast<std::size_t>(c->axis)] = pair.substr(2, eq - 2);
  }
  return lay;
}

struct ShdrValue {
  double time = 0;
  std::uint64_t line = 0;
  std::size_t column = 0;      // index into the layout
  std::size_t text_col = 0;    // 1-based character column of the value
  std::string text;
};

/// Pass 1: every record of a mapped item, and which items were seen at all. A line that is not a
/// record is a bad row.
std::vector<ShdrValue> shdr_values(std::istream& in, std::string first, const Layout& lay, Rows& rows,
                                   std::vector<bool>& seen, ReadResult& r) {
  std::vector<ShdrValue> values;
  std::map<std::string, std::vector<std::size_t>, std::less<>> index;  // one item may feed several quantities
  for (std::size_t i = 0; i < lay.columns.size(); ++i) index[lay.columns[i].name].push_back(i);
  seen.assign(lay.columns.size(), false);
  std::uint64_t n = 0;
  ShdrRecord rec;
  for (bool have = true; have || std::getline(in, first); have = false) {
    ++n;
    ++rows.tr.lines_read;
    if (!first.empty() && first.back() == '\r') first.pop_back();
    if (first.empty()) continue;
    if (!parse_shdr_line(first, rec)) {
      rows.reject(diag(rows.tr.file, n, 1, "not an SHDR record: expected YYYY-MM-DDThh:mm:ss[.f]Z|item|value"), r);
      continue;
    }
    const auto it = index.find(rec.item);
    if (it == index.end()) continue;
    for (const std::size_t column : it->second) {
      seen[column] = true;
      values.push_back({rec.time, n, column, static_cast<std::size_t>(rec.value.data() - first.data()) + 1, std::string(rec.value)});
    }
  }
  return values;
}

/// Keeps the columns whose items occur (renumbering the values' columns); says why the rest
/// cannot be calibrated.
std::optional<std::string> shdr_used_columns(Layout& lay, const std::vector<bool>& seen, std::vector<ShdrValue>& values) {
  Layout used = lay;
  used.columns.clear();
  std::vector<std::size_t> renumber(lay.columns.size(), 0);
  for (std::size_t i = 0; i < lay.columns.size(); ++i)
    if (seen[i]) {
      renumber[i] = used.columns.size();
      used.columns.push_back(lay.columns[i]);
    }
  if (used.find(Slot::kCommand) < 0) {
    std::string items;
    for (const auto& c : lay.columns)
      if (c.slot == Slot::kCommand) items += (items.empty() ? "" : ", ") + c.name;
    return "no commanded positions in the SHDR stream (none of " + items +
           " occurs): without commands there is no residual to calibrate; if the adapter names them otherwise, "
           "map them with --columns X_cmd=ITEM,...";
  }
  if (auto why = check_axes(used)) return "SHDR items: " + *why + " (map items with --columns QUANTITY=ITEM)";
  for (auto& v : values) v.column = renumber[v.column];  // only seen columns have values
  lay = std::move(used);
  return std::nullopt;
}

/// Pass 2: one row per adapter cycle in which every used item has a value. UNAVAILABLE makes an
/// item unknown (no rows until it is known again); a value that is not a number is a bad row.
void shdr_rows(const std::vector<ShdrValue>& values, const Layout& lay, const ReadOptions& o, Rows& rows, ReadResult& r) {
  std::vector<std::optional<double>> held(lay.columns.size());
  double cycle_start = -INFINITY, t0 = NAN;
  std::uint64_t cycle_line = 0;
  bool cycle_bad = false;
  std::vector<double> row(lay.columns.size());
  auto close_cycle = [&] {
    if (cycle_line == 0 || cycle_bad) return;
    for (std::size_t i = 0; i < held.size(); ++i) {
      if (!held[i]) return;
      row[i] = *held[i];
    }
    if (std::isnan(t0)) t0 = cycle_start;  // times from the first row: epoch seconds lose precision
    rows.keep(lay, row, cycle_start - t0, cycle_line, r);
  };
  for (const auto& v : values) {
    if (v.time - cycle_start > o.shdr_cycle || v.time < cycle_start) {
      close_cycle();
      cycle_start = v.time;
      cycle_line = v.line;
      cycle_bad = false;
    }
    double x = 0;
    std::size_t off = 0;
    if (v.text == "UNAVAILABLE") held[v.column].reset();
    else if (auto why = to_number(v.text, x, off)) {
      rows.reject(diag(rows.tr.file, v.line, v.text_col + off, "item '" + lay.columns[v.column].name + "' " + *why), r);
      cycle_bad = true;
    } else held[v.column] = x;
  }
  close_cycle();
}

ReadResult read_shdr(std::istream& in, const std::string& first, const std::string& file, const ReadOptions& o) {
  ReadResult r;
  auto lay = shdr_layout(o, file, r.diagnostics);
  if (!lay) return r;
  Rows rows;
  rows.tr.file = file;
  rows.tr.format = TraceFormat::kShdr;
  std::vector<bool> seen;
  auto values = shdr_values(in, first, *lay, rows, seen, r);
  if (auto why = shdr_used_columns(*lay, seen, values)) {
    r.diagnostics.push_back(diag(file, 1, 1, *why));
    return r;
  }
  rows.tr.effort_kind = lay->effort_kind;
  shdr_rows(values, *lay, o, rows, r);
  return finish(rows, o, rows.tr.lines_read, std::move(r));
}

}  // namespace

ReadResult read_trace(std::istream& in, const std::string& file, const ReadOptions& o) {
  std::string first;
  if (!std::getline(in, first)) {
    ReadResult r;
    r.diagnostics.push_back(diag(file, 1, 1, "empty file: a trace needs a header line and rows"));
    return r;
  }
  if (!first.empty() && first.back() == '\r') first.pop_back();
  const TraceFormat f = o.format ? *o.format : detect_format(first);
  if (f == TraceFormat::kShdr) return read_shdr(in, first, file, o);
  ReadResult r;
  const auto lay = layout_for(f, first, o, file, r.diagnostics);
  if (!lay) return r;
  return read_delimited(in, first, *lay, file, o);
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
