#include "ik_plots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <opencv2/core.hpp>

#include "plot.hpp"

namespace gcpipe {

namespace {

// Red, orange and blue mean before, feed-forward and after in every figure (plot::Role): the two
// solvers take other colours.
const cv::Scalar kNeural = plot::palette(2);    // green
const cv::Scalar kAnalytic = plot::palette(4);  // purple

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
  char note[160];
  std::snprintf(note, sizeof note, "%llu points (%zu of them drawn), %llu flagged neural_diverged",
                static_cast<unsigned long long>(s.neural_points), s.index.size(), static_cast<unsigned long long>(s.flagged_count));
  fig.note(note);
  fig.save_png(png);
}

void plot_ik_tip_error(const std::filesystem::path& png, const IkSeries& s, const std::string& title) {
  plot::Figure fig;
  fig.title(title);
  fig.xlabel("IK point (program order)");
  fig.ylabel("tool-tip error [mm], log scale");
  fig.log_y(1e-16);
  fig.line(s.index, s.tip_error_neural, kNeural, 1, "neural IK: |FK(neural joints) - programmed tip|");
  fig.line(s.index, s.tip_error_analytic, kAnalytic, 2, "analytic IK: |FK(analytic joints) - programmed tip|");
  fig.note("values below 1e-16 mm are drawn at 1e-16");
  fig.save_png(png);
}

}  // namespace gcpipe
