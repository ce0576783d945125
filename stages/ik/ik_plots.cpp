#include "ik_plots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <opencv2/core.hpp>

#include "plot.hpp"

namespace gcpipe {

namespace {

const cv::Scalar kNeural(40, 39, 214);    // red
const cv::Scalar kAnalytic(180, 119, 31);  // blue

}  // namespace

void plot_ik_divergence(const std::filesystem::path& png, const IkSeries& s, const std::string& title) {
  // Axes differ in unit and tolerance (mm against 0.0002 deg), so each difference is drawn in
  // units of its own axis's tolerance: the flag threshold is +-1 for all of them.
  plot::Figure fig;
  fig.title(title);
  fig.xlabel("IK point (program order)");
  fig.ylabel("(neural - analytic) / tolerance of the axis");
  for (int i = 0; i < kNumAxes; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const double tol = s.tolerance[k] > 0 ? s.tolerance[k] : 1.0;
    double mx = 0;
    std::vector<double> y(s.diff[k].size());
    for (std::size_t j = 0; j < y.size(); ++j) {
      mx = std::max(mx, std::abs(s.diff[k][j]));
      y[j] = s.diff[k][j] / tol;
    }
    char label[96];
    std::snprintf(label, sizeof label, i < kA ? "%c: max |d| %.4g mm (tol %g)" : "%c: max |d| %.4g deg (tol %g)",
                  kAxisLetters[i], mx, s.tolerance[k]);
    fig.line(s.index, std::move(y), plot::palette(i), 1, label);
  }
  if (!s.index.empty()) {
    const double a = s.index.front(), b = s.index.back();
    fig.line({a, b}, {1.0, 1.0}, cv::Scalar(0, 0, 0), 1, "flag threshold");
    fig.line({a, b}, {-1.0, -1.0}, cv::Scalar(0, 0, 0), 1);
  }
  if (!s.flagged.empty()) fig.scatter(s.flagged, std::vector<double>(s.flagged.size(), 0.0), cv::Scalar(0, 0, 200), 3, "neural_diverged");
  char note[96];
  std::snprintf(note, sizeof note, "%zu points, %llu flagged neural_diverged", s.index.size(), static_cast<unsigned long long>(s.flagged_count));
  fig.note(note);
  fig.save_png(png);
}

void plot_ik_tip_error(const std::filesystem::path& png, const IkSeries& s, const std::string& title) {
  plot::Figure fig;
  fig.title(title);
  fig.xlabel("IK point (program order)");
  fig.ylabel("log10 tool-tip error [mm]");
  auto lg = [](const std::vector<double>& v) {
    std::vector<double> r(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) r[i] = std::log10(std::max(v[i], 1e-16));
    return r;
  };
  fig.line(s.index, lg(s.tip_error_neural), kNeural, 1, "neural IK: |FK(neural joints) - programmed tip|");
  fig.line(s.index, lg(s.tip_error_analytic), kAnalytic, 2, "analytic IK: |FK(analytic joints) - programmed tip|");
  fig.note("values below 1e-16 mm are drawn at -16");
  fig.save_png(png);
}

}  // namespace gcpipe
