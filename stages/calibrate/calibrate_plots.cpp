// plots/: residual before/after vs time, vs velocity (friction), vs position (lead error),
// hysteresis loop (backlash), and the criterion of every candidate as bars.
#include <algorithm>
#include <cmath>
#include <filesystem>

#include "axis_model.hpp"
#include "calibrate.hpp"
#include "plot.hpp"

namespace gcpipe::calibrate {

namespace fs = std::filesystem;

namespace {

const cv::Scalar kBefore(40, 39, 214);   // red
const cv::Scalar kRefit(14, 127, 255);   // orange
const cv::Scalar kAfter(180, 119, 31);   // blue

std::string axis(int a) { return std::string(1, kAxisLetters[a]); }
const char* unit_um(int a) { return (a == kA || a == kC) ? "mdeg" : "um"; }

/// Every k-th sample so that a series has at most ~20,000 points.
std::size_t stride(std::size_t n) { return std::max<std::size_t>(1, n / 20000); }

std::vector<double> residual(const Calibration& c, int a, const std::vector<double>& pred) {
  std::vector<double> r(c.rows);
  for (std::size_t k = 0; k < c.rows; ++k) r[k] = (c.actual[a][k] - pred[k]) * 1000;  // um or mdeg
  return r;
}

void time_plot(const Calibration& c, int a, const fs::path& png) {
  plot::Figure f;
  f.title("Axis " + axis(a) + ": measured - model, declared and calibrated");
  f.xlabel("t [s]");
  f.ylabel(std::string("residual [") + unit_um(a) + "]");
  const auto r0 = residual(c, a, c.axes[a].pred_declared), r1 = residual(c, a, c.axes[a].pred_calibrated);
  const auto rr = residual(c, a, c.axes[a].pred_refit);
  std::vector<double> t, y0, y1, yr;
  for (std::size_t k = 1; k < c.rows; k += stride(c.rows)) { t.push_back(c.t[k]); y0.push_back(r0[k]); y1.push_back(r1[k]); yr.push_back(rr[k]); }
  // The declared model's residual can be 1000x the calibrated one: it is drawn only when it
  // stays within 20x the refitted one, so the effect's shape stays visible.
  double m0 = 0, mr = 0;
  for (std::size_t i = 0; i < y0.size(); ++i) { m0 = std::max(m0, std::abs(y0[i])); mr = std::max(mr, std::abs(yr[i])); }
  if (m0 <= 20 * mr) f.line(t, y0, kBefore, 1, "declared model");
  else f.note("declared model off the scale: max |residual| " + std::to_string(m0) + " " + unit_um(a));
  f.line(t, yr, kRefit, 1, "refitted gains, no effects");
  f.line(t, y1, kAfter, 1, "calibrated model");
  f.note("held-out part from t = " + std::to_string(c.t[std::min(c.split, c.rows - 1)]) + " s");
  f.save_png(png);
}

/// Residual of the refitted model (before any effect) against a quantity, as dots: the shape
/// names the effect (a step at v = 0: friction; a sine in position: lead error).
void scatter_plot(const Calibration& c, int a, const std::vector<double>& x, const std::string& xlabel,
                  const std::string& what, const fs::path& png) {
  plot::Figure f;
  f.title("Axis " + axis(a) + ": residual of the refitted model vs " + what);
  f.xlabel(xlabel);
  f.ylabel(std::string("residual [") + unit_um(a) + "]");
  const auto r = residual(c, a, c.axes[a].pred_refit), r1 = residual(c, a, c.axes[a].pred_calibrated);
  std::vector<double> xs, ys, ys1;
  for (std::size_t k = 1; k < c.rows; k += stride(c.rows)) { xs.push_back(x[k]); ys.push_back(r[k]); ys1.push_back(r1[k]); }
  f.scatter(xs, ys, kRefit, 2, "refitted (no effects)");
  f.scatter(xs, ys1, kAfter, 2, "calibrated");
  f.save_png(png);
}

void hysteresis_plot(const Calibration& c, int a, const fs::path& png) {
  plot::Figure f;
  f.title("Axis " + axis(a) + ": hysteresis, residual of the refitted model vs commanded position");
  f.xlabel(std::string("command [") + ((a == kA || a == kC) ? "deg" : "mm") + "]");
  f.ylabel(std::string("residual [") + unit_um(a) + "]");
  const auto r = residual(c, a, c.axes[a].pred_refit);
  std::vector<double> xs, ys;
  for (std::size_t k = 1; k < c.rows; k += stride(c.rows)) { xs.push_back(c.command[a][k]); ys.push_back(r[k]); }
  f.line(xs, ys, kRefit, 1, "a backlash shows as two branches, one per direction, width apart");
  f.save_png(png);
}

/// BIC change of every candidate of the first round per axis, as bars (negative = better).
void criterion_plot(const Calibration& c, const fs::path& png) {
  plot::Figure f;
  f.title("Criterion change of every candidate (BIC after - before, first round; named ones in blue)");
  f.xlabel("candidate (index: see the notes)");
  f.ylabel("delta BIC (sign-preserving log10(1+|d|))");
  int i = 0;
  std::string legend;
  for (int a = 0; a < kNumAxes; ++a)
    for (const auto& s : c.axes[a].candidates) {
      if (s.round != 1) continue;
      ++i;
      const double d = s.criterion_after - s.criterion_before;
      const double h = (d < 0 ? -1 : 1) * std::log10(1 + std::abs(d));
      f.line({double(i), double(i)}, {0.0, h}, s.named ? kAfter : kBefore, 14);
      legend += std::to_string(i) + " " + axis(a) + " " + s.effect + "  ";
      if (i % 7 == 0) { f.note(legend); legend.clear(); }
    }
  if (!legend.empty()) f.note(legend);
  f.line({0.0, double(i + 1)}, {-std::log10(11.0), -std::log10(11.0)}, cv::Scalar(90, 90, 90), 1, "naming margin (delta BIC = -10)");
  f.save_png(png);
}

}  // namespace

std::vector<std::string> write_plots(const Calibration& c, const std::string& outdir) {
  const fs::path dir = fs::path(outdir) / "plots";
  fs::create_directories(dir);
  std::vector<std::string> written;
  auto save = [&](const std::string& name, auto&& draw) {
    const fs::path part = dir / (name + ".part.png"), final_path = dir / name;
    draw(part);
    fs::rename(part, final_path);
    written.push_back("plots/" + name);
  };
  for (int a = 0; a < kNumAxes; ++a) {
    if (!c.axes[a].moving) continue;
    std::vector<double> v, acc;
    differentiate(c.command[a], c.period, v, acc);
    save("residual_time_" + axis(a) + ".png", [&](const fs::path& p) { time_plot(c, a, p); });
    save("residual_velocity_" + axis(a) + ".png", [&](const fs::path& p) {
      scatter_plot(c, a, v, std::string("commanded velocity [") + ((a == kA || a == kC) ? "deg/s" : "mm/s") + "]", "velocity", p);
    });
    save("residual_position_" + axis(a) + ".png", [&](const fs::path& p) {
      scatter_plot(c, a, c.command[a], std::string("commanded position [") + ((a == kA || a == kC) ? "deg" : "mm") + "]", "position", p);
    });
    save("hysteresis_" + axis(a) + ".png", [&](const fs::path& p) { hysteresis_plot(c, a, p); });
  }
  save("criterion.png", [&](const fs::path& p) { criterion_plot(c, p); });
  return written;
}

}  // namespace gcpipe::calibrate
