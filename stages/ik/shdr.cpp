#include "shdr.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <limits>
#include <optional>

namespace gcpipe {
namespace {

bool parse_int(std::string_view s, int& out) {
  if (s.empty()) return false;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

bool parse_number(std::string_view s, double& out) {
  while (!s.empty() && s.front() == ' ') s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\r')) s.remove_suffix(1);
  if (s.empty()) return false;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size() && std::isfinite(out);
}

// Days from 1970-01-01 to y-m-d in the proleptic Gregorian calendar (H. Hinnant's algorithm).
long long days_from_civil(int y, int m, int d) {
  y -= m <= 2;
  const int era = (y >= 0 ? y : y - 399) / 400;
  const int yoe = y - era * 400;
  const int doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const int doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return static_cast<long long>(era) * 146097 + doe - 719468;
}

}  // namespace

double parse_iso8601_utc(std::string_view t) {
  const double bad = std::numeric_limits<double>::quiet_NaN();
  // YYYY-MM-DDThh:mm:ss then optional .fraction then Z
  if (t.size() < 20 || t[4] != '-' || t[7] != '-' || t[10] != 'T' || t[13] != ':' ||
      t[16] != ':' || t.back() != 'Z')
    return bad;
  int y = 0, mo = 0, d = 0, h = 0, mi = 0, s = 0;
  if (!parse_int(t.substr(0, 4), y) || !parse_int(t.substr(5, 2), mo) ||
      !parse_int(t.substr(8, 2), d) || !parse_int(t.substr(11, 2), h) ||
      !parse_int(t.substr(14, 2), mi) || !parse_int(t.substr(17, 2), s))
    return bad;
  if (mo < 1 || mo > 12 || d < 1 || d > 31 || h > 23 || mi > 59 || s > 60) return bad;
  double fraction = 0;
  const std::string_view rest = t.substr(19, t.size() - 20);
  if (!rest.empty()) {
    if (rest.front() != '.' || rest.size() < 2) return bad;
    double scale = 0.1;
    for (char c : rest.substr(1)) {
      if (c < '0' || c > '9') return bad;
      fraction += scale * (c - '0');
      scale *= 0.1;
    }
  }
  return static_cast<double>(days_from_civil(y, mo, d)) * 86400.0 + h * 3600.0 + mi * 60.0 + s +
         fraction;
}

bool parse_shdr_line(std::string_view line, ShdrRecord& record) {
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  const auto p1 = line.find('|');
  if (p1 == std::string_view::npos) return false;
  const auto p2 = line.find('|', p1 + 1);
  if (p2 == std::string_view::npos) return false;
  const auto p3 = line.find('|', p2 + 1);
  const double time = parse_iso8601_utc(line.substr(0, p1));
  if (std::isnan(time)) return false;
  const std::string_view item = line.substr(p1 + 1, p2 - p1 - 1);
  if (item.empty()) return false;
  record.time = time;
  record.item = item;
  record.value = line.substr(p2 + 1, p3 == std::string_view::npos ? std::string_view::npos
                                                                   : p3 - p2 - 1);
  return true;
}

namespace {

// "x y z": exactly three numbers separated by blanks.
bool parse_path_pos(std::string_view rest, Vec3& p) {
  int n = 0;
  while (!rest.empty()) {
    while (!rest.empty() && rest.front() == ' ') rest.remove_prefix(1);
    if (rest.empty()) break;
    const auto sp = rest.find(' ');
    double v = 0;
    if (n >= 3 || !parse_number(rest.substr(0, sp), v)) return false;
    p[static_cast<std::size_t>(n++)] = v;
    rest = sp == std::string_view::npos ? std::string_view() : rest.substr(sp);
  }
  return n == 3;
}

// The value of one record into its slot: UNAVAILABLE or a bad number empties the slot (the
// cycle then gives no sample), counted apart.
template <typename T, typename Parse>
void take_value(std::string_view value, std::optional<T>& slot, ShdrStats& stats, Parse parse) {
  T v{};
  if (value == "UNAVAILABLE") {
    ++stats.unavailable;
    slot.reset();
  } else if (parse(value, v)) {
    slot = v;
  } else {
    ++stats.rejected;
    slot.reset();
  }
}

// The items of one adapter cycle (records less than cycle_gap apart), made a sample once the
// cycle ends: only when every joint and the path position were reported.
struct CycleState {
  std::array<std::optional<double>, kNumAxes> joint;
  std::optional<Vec3> path;
  std::string program;
  double start = -std::numeric_limits<double>::infinity();
  bool open = false;

  void emit(std::vector<KinematicSample>& out, ShdrStats& stats) {
    if (!open) return;
    open = false;
    if (!path) return;
    KinematicSample s;
    for (std::size_t a = 0; a < kNumAxes; ++a) {
      if (!joint[a]) return;
      s.joints[a] = *joint[a];
    }
    s.time = start;
    s.path_pos = *path;
    s.program = program;
    out.push_back(std::move(s));
    ++stats.samples;
  }
};

}  // namespace

std::vector<KinematicSample> read_kinematic_trace(std::istream& in, ShdrStats& stats,
                                                  double cycle_gap) {
  static constexpr std::array<std::string_view, kNumAxes> kItems = {
      "Xposition", "Yposition", "Zposition", "Aposition", "Cposition"};
  std::vector<KinematicSample> out;
  CycleState cycle;
  ShdrRecord r;
  for (std::string line; std::getline(in, line);) {
    ++stats.lines;
    if (!parse_shdr_line(line, r)) {
      ++stats.rejected;
      continue;
    }
    ++stats.records;
    if (r.time - cycle.start > cycle_gap || r.time < cycle.start) {
      cycle.emit(out, stats);
      cycle.start = r.time;
    }
    cycle.open = true;
    if (r.item == "program") {
      cycle.program = r.value == "UNAVAILABLE" ? std::string() : std::string(r.value);
      continue;
    }
    const auto axis = std::find(kItems.begin(), kItems.end(), r.item);
    if (axis != kItems.end())
      take_value(r.value, cycle.joint[static_cast<std::size_t>(axis - kItems.begin())], stats, parse_number);
    else if (r.item == "path_pos")
      take_value(r.value, cycle.path, stats, parse_path_pos);
  }
  cycle.emit(out, stats);
  return out;
}

}  // namespace gcpipe
