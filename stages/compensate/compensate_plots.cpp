#include "compensate_plots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "plot.hpp"
#include "png.hpp"

namespace gcpipe::compensate {

namespace {

const cv::Scalar kNominal(120, 120, 120);
const cv::Scalar kBefore(40, 39, 214);   // red
const cv::Scalar kAfter(180, 119, 31);   // blue

/// 1, 2 or 5 x 10^k at or below v.
double nice_below(double v) {
  if (!(v > 0)) return 1;
  const double e = std::pow(10.0, std::floor(std::log10(v)));
  const double f = v / e;
  return (f >= 5 ? 5 : f >= 2 ? 2 : 1) * e;
}

void save_stack(const std::filesystem::path& png, const std::vector<cv::Mat>& panels) {
  cv::Mat out;
  cv::vconcat(panels, out);
  plot::write_png(png, out);
}

std::string fmt(const char* f, double a, double b = 0, double c = 0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, f, a, b, c);
  return buf;
}

}  // namespace

void plot_toolpath(const std::filesystem::path& png, const Evaluation& before, const Evaluation* after,
                   const std::string& title) {
  const Series& b = before.series;
  // Panel 1: the whole path; panel 2: a 20 mm window around the worst error before compensation,
  // where the deviation is magnified enough to be seen.
  auto panel = [&](double cx, double cy, double half, bool zoom) {
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300, emax = 0;
    for (std::size_t i = 0; i < b.t.size(); ++i) {
      const double x = b.nominal[0][i], y = b.nominal[1][i];
      if (zoom && (std::abs(x - cx) > half || std::abs(y - cy) > half)) continue;
      x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
      emax = std::max(emax, std::hypot(b.tip[0][i] - x, b.tip[1][i] - y));
    }
    const double extent = zoom ? 2 * half : std::max(x1 - x0, y1 - y0);
    const double k = emax > 0 ? std::max(1.0, nice_below(0.05 * extent / emax)) : 1.0;
    plot::FigureStyle style;
    style.height = 900;
    style.width = 900;
    plot::Figure fig(style);
    fig.title(zoom ? "around the largest error" : title);
    fig.note(fmt("tool tip, workpiece frame; deviation from the nominal path magnified x%g", k));
    if (!zoom)
      fig.note(fmt("max contour error: before %.2f um", before.contour.max * 1e3) +
               (after ? fmt(", after %.2f um (%.1fx smaller)", after->contour.max * 1e3,
                            after->contour.max > 0 ? before.contour.max / after->contour.max : 0.0)
                      : std::string()));
    fig.xlabel("X [mm]");
    fig.ylabel("Y [mm]");
    fig.equal_aspect(true);
    if (zoom) fig.limits(cx - half, cx + half, cy - half, cy + half);
    auto draw = [&](const Series& s, bool nominal, cv::Scalar colour, int thick, const char* label) {
      std::vector<double> x, y;
      for (std::size_t i = 0; i < s.t.size(); ++i) {
        const double nx = s.nominal[0][i], ny = s.nominal[1][i];
        if (zoom && (std::abs(nx - cx) > 1.2 * half || std::abs(ny - cy) > 1.2 * half)) {
          if (!x.empty()) {  // leave the window: end this stretch
            fig.line(std::move(x), std::move(y), colour, thick, label);
            label = "";
            x.clear(), y.clear();
          }
          continue;
        }
        // The nearest path point jumps where the actual passes a crossing of the path: the
        // nominal line is broken there instead of drawing a spoke across the loop.
        if (nominal && !x.empty() && std::hypot(nx - x.back(), ny - y.back()) > 0.5) {
          fig.line(std::move(x), std::move(y), colour, thick, label);
          label = "";
          x.clear(), y.clear();
        }
        x.push_back(nominal ? nx : nx + k * (s.tip[0][i] - nx));
        y.push_back(nominal ? ny : ny + k * (s.tip[1][i] - ny));
      }
      if (!x.empty()) fig.line(std::move(x), std::move(y), colour, thick, label);
    };
    draw(b, true, kNominal, 1, "nominal path");
    draw(b, false, kBefore, 2, "actual, uncompensated");
    if (after) draw(after->series, false, kAfter, 2, "actual, compensated");
    return fig.render();
  };
  std::size_t worst = 0;
  double wmax = -1;
  for (std::size_t i = 0; i < b.t.size(); ++i)
    if (b.contour[i] > wmax) wmax = b.contour[i], worst = i;
  std::vector<cv::Mat> panels{panel(0, 0, 0, false)};
  if (!b.t.empty()) panels.push_back(panel(b.nominal[0][worst], b.nominal[1][worst], 10.0, true));
  cv::Mat out;
  cv::hconcat(panels, out);
  plot::write_png(png, out);
}

bool plot_ballbar(const std::filesystem::path& png, const Nominal& nominal, const Evaluation& before,
                  const Evaluation* after, const std::string& title) {
  std::vector<std::size_t> circles;
  for (std::size_t s = 0; s < nominal.segments.size() && circles.size() < 6; ++s)
    if (nominal.segments[s].circle) circles.push_back(s);
  if (circles.empty()) return false;
  // Common radial scale over all panels: the largest |radial deviation| before compensation.
  auto radial = [&](const Series& s, std::size_t i, std::size_t seg) {
    const Segment& g = nominal.segments[seg];
    return std::hypot(s.tip[0][i] - g.circle_centre[0], s.tip[1][i] - g.circle_centre[1]) - g.circle_radius;
  };
  double dmax = 0;
  for (std::size_t seg : circles)
    for (std::size_t i = 0; i < before.series.t.size(); ++i)
      if (before.series.segment[i] == seg) dmax = std::max(dmax, std::abs(radial(before.series, i, seg)));
  const double ring = nice_below(std::max(dmax, 1e-6) / 2);  // ring spacing [mm]
  std::vector<cv::Mat> rows;
  std::vector<cv::Mat> row;
  const int cols = std::min<int>(3, static_cast<int>(circles.size()));
  for (std::size_t c = 0; c < circles.size(); ++c) {
    const std::size_t seg = circles[c];
    const Segment& g = nominal.segments[seg];
    plot::FigureStyle st;
    st.width = 620;
    st.height = 660;
    st.margin_left = 60;
    st.margin_bottom = 50;
    st.grid = false;
    plot::Figure f(st);
    // Polar: radius = 3 rings + deviation; the dashed-looking reference is the nominal circle.
    const double base = 3 * ring;
    auto circle = [&](double r, cv::Scalar col, int th, const char* label) {
      std::vector<double> x, y;
      for (int a = 0; a <= 360; ++a) {
        x.push_back(r * std::cos(a * M_PI / 180));
        y.push_back(r * std::sin(a * M_PI / 180));
      }
      f.line(std::move(x), std::move(y), col, th, label);
    };
    for (int r = 1; r <= 5; ++r) circle(r * ring, cv::Scalar(225, 225, 225), 1, "");
    circle(base, kNominal, 1, "nominal");
    auto trace = [&](const Evaluation& ev, cv::Scalar col, const char* label) {
      std::vector<double> x, y;
      for (std::size_t i = 0; i < ev.series.t.size(); ++i) {
        if (ev.series.segment[i] != seg) continue;
        const double ang = std::atan2(ev.series.tip[1][i] - g.circle_centre[1], ev.series.tip[0][i] - g.circle_centre[0]);
        const double r = std::max(0.0, base + radial(ev.series, i, seg));
        x.push_back(r * std::cos(ang));
        y.push_back(r * std::sin(ang));
      }
      f.line(std::move(x), std::move(y), col, 2, label);
    };
    trace(before, kBefore, "before");
    if (after) trace(*after, kAfter, "after");
    f.equal_aspect(true);
    f.limits(-5.4 * ring, 5.4 * ring, -5.4 * ring, 5.4 * ring);
    f.title(fmt("lines %.0f-%.0f, R %.3f mm", static_cast<double>(g.first_line), static_cast<double>(g.last_line), g.circle_radius));
    f.note(fmt("rings every %g um; nominal = 3rd ring", ring * 1e3));
    f.xlabel("radial deviation [mm] around the nominal ring");
    row.push_back(f.render());
    if (static_cast<int>(row.size()) == cols || c + 1 == circles.size()) {
      while (static_cast<int>(row.size()) < cols) row.push_back(cv::Mat(row[0].size(), row[0].type(), cv::Scalar(255, 255, 255)));
      cv::Mat r;
      cv::hconcat(row, r);
      rows.push_back(r);
      row.clear();
    }
  }
  // A title strip across the panels.
  cv::Mat head(50, rows[0].cols, rows[0].type(), cv::Scalar(255, 255, 255));
  cv::putText(head, title + ": ballbar-style polar plot of the tool tip (workpiece frame)", {20, 34},
              cv::FONT_HERSHEY_SIMPLEX, 0.8, cv::Scalar(0, 0, 0), 2, cv::LINE_AA);
  rows.insert(rows.begin(), head);
  save_stack(png, rows);
  return true;
}

void plot_contour_error(const std::filesystem::path& png, const Evaluation& before, const Evaluation* after,
                        const std::string& title, const Evaluation* feedforward) {
  plot::Figure fig;
  fig.title(title);
  fig.xlabel("time [s]");
  fig.ylabel("contour error [um]");
  auto um = [](const std::vector<double>& v) {
    std::vector<double> r(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) r[i] = v[i] * 1e3;
    return r;
  };
  fig.line(before.series.t, um(before.series.contour), kBefore, 2,
           fmt("uncompensated: max %.2f um, RMS %.2f um", before.contour.max * 1e3, before.contour.rms * 1e3));
  if (feedforward)
    fig.line(feedforward->series.t, um(feedforward->series.contour), plot::palette(2), 2,
             fmt("model-inverse feed-forward, no learning: max %.2f um, RMS %.2f um", feedforward->contour.max * 1e3,
                 feedforward->contour.rms * 1e3));
  if (after)
    fig.line(after->series.t, um(after->series.contour), kAfter, 2,
             fmt("compensated: max %.2f um, RMS %.2f um", after->contour.max * 1e3, after->contour.rms * 1e3));
  fig.note("distance of the simulated tool tip to the nominal path (not to the time-matched point)");
  fig.save_png(png);
}

void plot_following_error(const std::filesystem::path& png, const Evaluation& before, const Evaluation* after,
                          const std::string& title) {
  auto panel = [&](const Evaluation& ev, const std::string& what) {
    plot::FigureStyle st;
    st.height = 560;
    plot::Figure f(st);
    f.title(title + ": " + what);
    f.xlabel("time [s]");
    f.ylabel("command - actual [um | mdeg]");
    for (int i = 0; i < kNumAxes; ++i) {
      const auto k = static_cast<std::size_t>(i);
      if (ev.axes.max_following[k] <= 0) continue;
      std::vector<double> v(ev.series.following[k].size());
      for (std::size_t j = 0; j < v.size(); ++j) v[j] = ev.series.following[k][j] * 1e3;
      char label[80];
      std::snprintf(label, sizeof label, i < kA ? "%c [um], max %.2f" : "%c [mdeg], max %.2f", kAxisLetters[i],
                    ev.axes.max_following[k] * 1e3);
      f.line(ev.series.t, std::move(v), plot::palette(i), 2, label);
    }
    return f.render();
  };
  std::vector<cv::Mat> panels{panel(before, "following error, uncompensated")};
  if (after) panels.push_back(panel(*after, "following error, compensated program"));
  save_stack(png, panels);
}

}  // namespace gcpipe::compensate
