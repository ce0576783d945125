#include "kienzle.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "gcpipe/split_fields.hpp"

namespace gcpipe::force {

namespace {

constexpr double kPi = std::numbers::pi;

/// A number cell; `blank_ok`: an empty cell reads as 0 (the aluminium rows have no strength).
double number_cell(const std::string& cell, bool blank_ok, const std::string& where, const std::string& column) {
  if (cell.empty() && blank_ok) return 0;
  std::size_t used = 0;
  double v = 0;
  try {
    v = std::stod(cell, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != cell.size()) throw std::runtime_error(where + ": column '" + column + "': '" + cell + "' is not a number");
  return v;
}

/// Column positions by header name; every column the model needs must be there.
std::map<std::string, std::size_t> header_columns(const std::string& line, const std::string& name) {
  std::map<std::string, std::size_t> at;
  const auto names = split_fields(line, '\t');
  for (std::size_t i = 0; i < names.size(); ++i) at[names[i]] = i;
  for (const char* need : {"group", "iso", "material", "condition", "tensile_N_mm2", "hardness_HB", "kc1_N_mm2", "mc"})
    if (!at.count(need)) throw std::runtime_error(name + ":1: no column '" + need + "' (not the VDI 3323 Kienzle table)");
  return at;
}

KienzleGroup parse_row(const std::vector<std::string>& cells, const std::map<std::string, std::size_t>& at,
                       const std::string& where) {
  const auto cell = [&](const char* column) -> const std::string& {
    const std::size_t i = at.at(column);
    if (i >= cells.size()) throw std::runtime_error(where + ": no value in column '" + column + "'");
    return cells[i];
  };
  KienzleGroup g;
  g.group = static_cast<int>(number_cell(cell("group"), false, where, "group"));
  g.iso = cell("iso");
  g.material = cell("material");
  g.condition = cell("condition");
  g.tensile_N_mm2 = number_cell(cell("tensile_N_mm2"), true, where, "tensile_N_mm2");
  g.hardness_HB = number_cell(cell("hardness_HB"), true, where, "hardness_HB");
  g.kc1 = number_cell(cell("kc1_N_mm2"), false, where, "kc1_N_mm2");
  g.mc = number_cell(cell("mc"), false, where, "mc");
  // Kienzle's exponent lies in (0, 1): otherwise the force would not grow with the chip.
  if (!(g.kc1 > 0) || !(g.mc >= 0 && g.mc < 1)) throw std::runtime_error(where + ": kc1 must be > 0 and mc in [0, 1)");
  return g;
}

std::string normalised_grade(const std::string& grade) {
  std::string out;
  for (char ch : grade)
    if (!std::isspace(static_cast<unsigned char>(ch))) out += static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
  if (out.rfind("AISI", 0) == 0) out.erase(0, 4);
  return out;
}

/// S_p(0, theta) for theta in [0, pi/4]: with u = sin(phi), sin^p dphi = u^p (1 - u^2)^(-1/2) du,
/// and (1 - u^2)^(-1/2) = sum_k C(2k, k) / 4^k u^(2k): the series in t = sin(theta) <= 0.71.
double sine_power_from_zero_series(double p, double theta) {
  const double t = std::sin(theta);
  double coefficient = 1, power = std::pow(t, p + 1), sum = 0;
  for (int k = 0; k < 400; ++k) {
    const double term = coefficient * power / (p + 2 * k + 1);
    sum += term;
    if (std::abs(term) <= 1e-17 * std::abs(sum)) break;
    coefficient *= (2.0 * k + 1) / (2.0 * k + 2);
    power *= t * t;
  }
  return sum;
}

/// S_p(theta, pi/2) for theta in [pi/4, pi/2]: with psi = pi/2 - phi and u = sin(psi),
/// sin^p(phi) dphi = (1 - u^2)^((p - 1)/2) du, a binomial series in s = cos(theta) <= 0.71.
double sine_power_to_half_series(double p, double theta) {
  const double s = std::cos(theta);
  double coefficient = 1, power = s, sum = 0;
  for (int k = 0; k < 400; ++k) {
    const double term = coefficient * power / (2 * k + 1);
    sum += term;
    if (std::abs(term) <= 1e-17 * std::abs(sum) || s == 0) break;
    coefficient *= -((p - 1) / 2 - k) / (k + 1);
    power *= s * s;
  }
  return sum;
}

/// S_p(0, pi/2) = B(1/2, (p + 1)/2) / 2.
double sine_power_half(double p) { return std::sqrt(kPi) * std::tgamma((p + 1) / 2) / (2 * std::tgamma(p / 2 + 1)); }

/// S_p(0, theta), theta in [0, pi], by the symmetry sin(pi - phi) = sin(phi).
double sine_power_upto(double p, double theta) {
  if (theta > kPi / 2) return 2 * sine_power_half(p) - sine_power_upto(p, kPi - theta);
  if (theta <= kPi / 4) return sine_power_from_zero_series(p, theta);
  return sine_power_half(p) - sine_power_to_half_series(p, theta);
}

/// The common factor N a kc1 c^p / (2 pi) of the closed forms.
double kienzle_scale(double kc1, double mc, const Cut& cut) {
  return cut.flutes * cut.axial_depth * kc1 * std::pow(cut.feed_per_tooth, 1 - mc) / (2 * kPi);
}

void check_angles(const Cut& cut) {
  if (!(cut.phi_start >= 0 && cut.phi_start <= cut.phi_exit && cut.phi_exit <= kPi))
    throw std::invalid_argument("Kienzle closed form: the engagement must lie in [0, pi] (the chip is c sin(phi))");
}

}  // namespace

std::string KienzleGroup::describe() const {
  std::ostringstream s;
  s << "VDI 3323 group " << group << " (ISO " << iso << ", " << material << ", " << condition;
  if (tensile_N_mm2 > 0) s << ", " << tensile_N_mm2 << " N/mm^2";
  s << ", " << hardness_HB << " HB): kc1 " << kc1 << " N/mm^2, mc " << mc;
  return s.str();
}

std::vector<KienzleGroup> parse_kienzle_table(std::istream& in, const std::string& name) {
  std::string line;
  if (!std::getline(in, line)) throw std::runtime_error(name + ": empty (no header line)");
  const auto at = header_columns(line, name);
  std::vector<KienzleGroup> rows;
  for (int n = 2; std::getline(in, line); ++n) {
    if (line.empty()) continue;
    const std::string where = name + ":" + std::to_string(n);
    rows.push_back(parse_row(split_fields(line, '\t'), at, where));
    for (std::size_t i = 0; i + 1 < rows.size(); ++i)
      if (rows[i].group == rows.back().group) throw std::runtime_error(where + ": group " + std::to_string(rows.back().group) + " twice");
  }
  return rows;
}

const std::vector<KienzleGroup>& kienzle_table() {
  static const std::vector<KienzleGroup> rows = [] {
    const EmbeddedKienzleTable& t = embedded_kienzle_table();
    std::istringstream in(t.tsv);
    return *t.tsv ? parse_kienzle_table(in, t.from) : std::vector<KienzleGroup>{};
  }();
  return rows;
}

const KienzleGroup& kienzle_group(int group) {
  const auto& rows = kienzle_table();
  if (rows.empty())
    throw std::invalid_argument("the VDI 3323 Kienzle table was not found when the build was configured (it is read "
                                "from GCPIPE_SHARED_DATA/force/vdi3323_kienzle.tsv; reconfigure with that folder present)");
  std::string have;
  for (const KienzleGroup& g : rows) {
    if (g.group == group) return g;
    have += (have.empty() ? "" : ", ") + std::to_string(g.group);
  }
  throw std::invalid_argument("VDI 3323 group " + std::to_string(group) + " is not in the table (it has " + have + ")");
}

std::string kienzle_source() {
  const std::string text = embedded_kienzle_table().provenance;
  const std::size_t start = text.find("Source:");
  if (start == std::string::npos) return "";
  const std::size_t end = text.find("\n\n", start);
  std::string paragraph = text.substr(start, end == std::string::npos ? std::string::npos : end - start);
  std::replace(paragraph.begin(), paragraph.end(), '\n', ' ');
  return paragraph;
}

double specific_cutting_force(const KienzleGroup& g, double h) { return g.kc1 * std::pow(h, -g.mc); }

ForceLaw kienzle_law(double kc1, double mc, const ForceRatios* ratios) {
  ForceLaw law;
  law.feed_exponent = 1 - mc;
  law.chip = {kc1, ratios ? ratios->radial * kc1 : 0.0, ratios ? ratios->axial * kc1 : 0.0};
  law.edge = {};
  law.radial_axial_known = ratios != nullptr;
  return law;
}

std::vector<int> grade_groups(const std::string& grade, const std::string& condition) {
  // PROVENANCE.md of the table, "grade names" (the only mapping shipped; README sec. 1b).
  struct Entry {
    std::vector<std::string> names;
    std::vector<std::pair<std::string, std::vector<int>>> by_condition;  // "" = the grade's only one
  };
  static const std::vector<Entry> grades = {
      {{"C45", "1045"}, {{"annealed", {2}}, {"quenched_and_tempered", {3}}}},
      {{"42CRMO4", "4140"}, {{"quenched_and_tempered", {7, 8, 9}}}},
      {{"1018"}, {{"", {1}}}},
      {{"316L"}, {{"", {14}}}},
      {{"H13"}, {{"annealed", {10}}}},
  };
  const std::string name = normalised_grade(grade);
  for (const Entry& e : grades) {
    if (std::find(e.names.begin(), e.names.end(), name) == e.names.end()) continue;
    std::string conditions;
    for (const auto& [c, groups] : e.by_condition) {
      if (c == condition) return groups;
      conditions += (conditions.empty() ? "" : ", ") + (c.empty() ? std::string("none (leave condition out)") : c);
    }
    throw std::invalid_argument("grade " + grade + (condition.empty() ? " needs a condition" : " " + condition + " is not stated") +
                                " (PROVENANCE.md states: " + conditions + ")");
  }
  throw std::invalid_argument("grade '" + grade + "' has no stated group (known: C45/1045, 42CrMo4/4140, 1018, 316L, H13; "
                              "other grades: give vdi3323_group)");
}

double sine_power_integral(double p, double a, double b) {
  if (!(p > -1)) throw std::invalid_argument("sine_power_integral: p must be > -1");
  if (!(a >= 0 && a <= b && b <= kPi)) throw std::invalid_argument("sine_power_integral: needs 0 <= a <= b <= pi");
  return sine_power_upto(p, b) - sine_power_upto(p, a);
}

double kienzle_mean_tangential_force(double kc1, double mc, const Cut& cut) {
  check_angles(cut);
  return kienzle_scale(kc1, mc, cut) * sine_power_integral(1 - mc, cut.phi_start, cut.phi_exit);
}

Force3 kienzle_mean_force_closed_form(double kc1, double mc, const ForceRatios& ratios, const Cut& cut) {
  // Per edge Fx = -Ft cos - Fr sin, Fy = Ft sin - Fr cos, Fz = Fa with Ft = kc1 a c^p sin^p,
  // Fr = radial Ft, Fa = axial Ft: int sin^p cos = sin^(p+1) / (p+1), int sin^p sin = S_(p+1).
  check_angles(cut);
  const double p = 1 - mc, q = p + 1;
  const double k = kienzle_scale(kc1, mc, cut);
  const auto sin_q = [q](double phi) { return std::pow(std::max(0.0, std::sin(phi)), q); };  // sin(pi) rounds
  const double sin_cos = (sin_q(cut.phi_exit) - sin_q(cut.phi_start)) / q;
  const double sin_sin = sine_power_integral(q, cut.phi_start, cut.phi_exit);
  const double tangential = k * sine_power_integral(p, cut.phi_start, cut.phi_exit);
  return {k * (-sin_cos - ratios.radial * sin_sin), k * (sin_sin - ratios.radial * sin_cos), ratios.axial * tangential};
}

}  // namespace gcpipe::force
