#include "error_budget.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <unordered_map>

#include "plot.hpp"

namespace gcpipe::compensate {

namespace {

/// Force samples hashed by 1 mm XY cells for nearest-sample queries.
class SampleGrid {
 public:
  SampleGrid(const force::PathForce& f, const Vec3& origin) : f_(f), o_(origin) {
    for (std::size_t i = 0; i < f.samples.size(); ++i) cells_[key(f.samples[i].x - o_[0], f.samples[i].y - o_[1])].push_back(i);
  }
  /// The sample nearest (x, y) within 1 mm at the same Z level (0.5 mm), or -1.
  long nearest(double x, double y, double z) const {
    long best = -1;
    double d2 = 1.0;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy) {
        const auto it = cells_.find(key(x + dx, y + dy));
        if (it == cells_.end()) continue;
        for (std::size_t i : it->second) {
          const auto& s = f_.samples[i];
          if (std::abs(s.z - o_[2] - z) > 0.5) continue;
          const double e = (s.x - o_[0] - x) * (s.x - o_[0] - x) + (s.y - o_[1] - y) * (s.y - o_[1] - y);
          if (e < d2) { d2 = e; best = static_cast<long>(i); }
        }
      }
    return best;
  }

 private:
  static long long key(double x, double y) {
    return (static_cast<long long>(std::floor(x)) << 32) ^ (static_cast<long long>(std::floor(y)) & 0xffffffffLL);
  }
  const force::PathForce& f_;
  Vec3 o_;
  std::unordered_map<long long, std::vector<std::size_t>> cells_;
};

}  // namespace

ErrorBudget error_budget(const simulate::Series& series, const force::PathForce& force, const Vec3& origin) {
  ErrorBudget b;
  const SampleGrid grid(force, origin);
  std::size_t matched = 0, cutting = 0, dominated = 0;
  for (std::size_t k = 0; k < series.t.size(); ++k) {
    const long i = grid.nearest(series.nominal[0][k], series.nominal[1][k], series.nominal[2][k]);
    const double defl = i < 0 ? 0.0 : 1e3 * force.samples[static_cast<std::size_t>(i)].deflection;
    const double contour = 1e3 * series.contour[k];
    b.t.push_back(series.t[k]);
    b.contour_um.push_back(contour);
    b.deflection_um.push_back(defl);
    if (i < 0) continue;
    ++matched;
    if (defl <= 0) continue;
    ++cutting;
    if (defl > contour) ++dominated;
  }
  b.matched_fraction = series.t.empty() ? 0 : static_cast<double>(matched) / static_cast<double>(series.t.size());
  b.deflection_dominates = cutting == 0 ? 0 : static_cast<double>(dominated) / static_cast<double>(cutting);
  return b;
}

nlohmann::ordered_json error_budget_json(const ErrorBudget& b) {
  const double c = b.contour_um.empty() ? 0 : *std::max_element(b.contour_um.begin(), b.contour_um.end());
  const double d = b.deflection_um.empty() ? 0 : *std::max_element(b.deflection_um.begin(), b.deflection_um.end());
  return {{"max_contour_error_um", c},
          {"max_deflection_um", d},
          {"deflection_dominates_fraction", b.deflection_dominates},
          {"matched_fraction", b.matched_fraction},
          {"note", "per simulated time bucket: the servo contour error and the static tool deflection under the mean "
                   "cutting force of the nearest force sample (cantilever, stages/force/README.md sec. 4)"}};
}

void plot_error_budget(const std::filesystem::path& png, const ErrorBudget& b, const std::string& title) {
  plot::Figure f;
  f.title(title);
  char note[200];
  std::snprintf(note, sizeof note, "deflection above the contour error in %.0f %% of the cutting time",
                100 * b.deflection_dominates);
  f.note(note);
  f.xlabel("time [s]");
  f.ylabel("error [um]");
  f.line(b.t, b.contour_um, plot::palette(0), 2, "servo contour error (simulated, uncompensated)");
  f.line(b.t, b.deflection_um, plot::palette(3), 2, "tool deflection under the mean cutting force");
  f.save_png(png);
}

}  // namespace gcpipe::compensate
