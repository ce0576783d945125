#include "compensate_plots.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "plot.hpp"
#include "png.hpp"

namespace gcpipe::compensate {

namespace {

const cv::Scalar kNominal = plot::role_colour(plot::Role::kNominal);

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

// "before (control runs the original)": the role, then what the run is.
std::string run_label(const FigureRun& r) {
  std::string s = plot::role_name(r.role);
  if (!r.what.empty()) s += " (" + r.what + ")";
  return s;
}

// The raw sample of the nominal run that point i of a run's series stands for (FigureRun).
std::size_t raw_sample_of(const Nominal& nom, const FigureRun& run, std::size_t i) {
  const Series& s = run.evaluation->series;
  const auto n = static_cast<std::size_t>(std::max(0.0, std::round(s.t[i] / nom.period)));
  const std::size_t raw = run.on_reference_clock ? nom.progress[std::min(n, nom.progress.size() - 1)] : n;
  return std::min(raw, nom.raw.size() - 1);
}

// Per point of the run's series: on a cutting move, not a G0 rapid (whose error is no contour
// error of the part: it would choose the plane and the magnification otherwise). All points
// count when the nominal cannot say.
std::vector<bool> cutting_points(const Nominal& nom, const FigureRun& run) {
  const Series& s = run.evaluation->series;
  std::vector<bool> cutting(s.t.size(), true);
  if (nom.raw.size() == 0 || (run.on_reference_clock && nom.progress.size() == 0)) return cutting;
  for (std::size_t i = 0; i < s.t.size(); ++i)
    cutting[i] = nom.brief[nom.block[raw_sample_of(nom, run, i)]].motion != Motion::kRapid;
  return cutting;
}

/// The plane a tool path is drawn in: the two axes (0 X, 1 Y, 2 Z) that hold most of the run's
/// deviation from the nominal path (its sum of squares per axis over the run): the axis with the
/// least is the one looked along. A G18 profile's error lies in XZ and is drawn there.
struct Plane {
  std::size_t u = 0, v = 1;
  const char* name = "XY";
};

Plane plane_of_largest_error(const Series& s, const std::vector<bool>& cutting) {
  std::array<double, 3> sum{};
  for (std::size_t i = 0; i < s.t.size(); ++i)
    if (cutting[i])
      for (std::size_t k = 0; k < 3; ++k) sum[k] += (s.tip[k][i] - s.nominal[k][i]) * (s.tip[k][i] - s.nominal[k][i]);
  const auto normal = static_cast<std::size_t>(std::min_element(sum.begin(), sum.end()) - sum.begin());
  if (sum[normal] == sum[2]) return {0, 1, "XY"};  // a tie keeps the usual view
  if (normal == 0) return {1, 2, "YZ"};
  if (normal == 1) return {0, 2, "XZ"};
  return {0, 1, "XY"};
}

const char* kAxisName[3] = {"X [mm]", "Y [mm]", "Z [mm]"};

}  // namespace

namespace {

// What a tool-path panel shows: the whole path, or (zoom) a window of 2 half around (cu, cv).
struct View {
  Plane plane;
  bool zoom = false;
  double cu = 0, cv = 0, half = 0;
  bool shows(const Series& s, std::size_t i, double scale) const {
    return !zoom || (std::abs(s.nominal[plane.u][i] - cu) <= scale * half && std::abs(s.nominal[plane.v][i] - cv) <= scale * half);
  }
};

// The deviation's magnification in a view, chosen from the series' largest deviation in it: about
// 5 % of the extent shown, a 1-2-5 step, at least 1.
double magnification(const Series& b, const std::vector<bool>& cutting, const View& view) {
  const Plane& pl = view.plane;
  double u0 = 1e300, u1 = -1e300, v0 = 1e300, v1 = -1e300, emax = 0;
  for (std::size_t i = 0; i < b.t.size(); ++i) {
    if (!view.shows(b, i, 1.0)) continue;
    const double u = b.nominal[pl.u][i], v = b.nominal[pl.v][i];
    u0 = std::min(u0, u), u1 = std::max(u1, u), v0 = std::min(v0, v), v1 = std::max(v1, v);
    if (cutting[i]) emax = std::max(emax, std::hypot(b.tip[pl.u][i] - u, b.tip[pl.v][i] - v));
  }
  const double extent = view.zoom ? 2 * view.half : std::max(u1 - u0, v1 - v0);
  return emax > 0 ? std::max(1.0, nice_below(0.05 * extent / emax)) : 1.0;
}

// Panel of the tool path in a view, the deviation magnified enough to be seen.
cv::Mat toolpath_panel(const FigureRuns& runs, const std::vector<bool>& cutting, const View& view, const std::string& title) {
  const Series& b = runs.front().evaluation->series;
  const Plane& pl = view.plane;
  const bool zoom = view.zoom;
  const double cu = view.cu, cv = view.cv, half = view.half;
  auto in_view = [&](const Series& s, std::size_t i, double scale) { return view.shows(s, i, scale); };
  const double k = magnification(b, cutting, view);
  plot::FigureStyle style;
  style.height = 900;
  style.width = 900;
  plot::Figure fig(style);
  fig.title(zoom ? "around the largest error" : title);
  fig.note(std::string("plane ") + pl.name + (zoom ? "" : ", which holds most of the error") +
           fmt("; deviation from the nominal path magnified x%g", k));
  if (!zoom) {
    std::string maxima = "max contour error:";
    for (std::size_t i = 0; i < runs.size(); ++i)
      maxima += std::string(i == 0 ? " " : ", ") + plot::role_name(runs[i].role) +
                fmt(" %.2f um", runs[i].evaluation->contour.max * 1e3);
    fig.note(maxima);
  }
  fig.xlabel(kAxisName[pl.u]);
  fig.ylabel(kAxisName[pl.v]);
  fig.equal_aspect(true);
  if (zoom) fig.limits(cu - half, cu + half, cv - half, cv + half);
  auto draw = [&](const Series& s, bool nominal, cv::Scalar colour, int thick, std::string label) {
    std::vector<double> x, y;
    auto flush = [&] {
      if (!x.empty()) fig.line(std::move(x), std::move(y), colour, thick, label);
      label.clear();
      x.clear(), y.clear();
    };
    for (std::size_t i = 0; i < s.t.size(); ++i) {
      const double nu = s.nominal[pl.u][i], nv = s.nominal[pl.v][i];
      if (!in_view(s, i, 1.2)) {  // leave the window: end this stretch
        flush();
        continue;
      }
      // The nearest path point jumps where the actual passes a crossing of the path: the
      // nominal line is broken there instead of drawing a spoke across the loop.
      if (nominal && !x.empty() && std::hypot(nu - x.back(), nv - y.back()) > 0.5) flush();
      x.push_back(nominal ? nu : nu + k * (s.tip[pl.u][i] - nu));
      y.push_back(nominal ? nv : nv + k * (s.tip[pl.v][i] - nv));
    }
    flush();
  };
  draw(b, true, kNominal, 1, "nominal path");
  for (const FigureRun& r : runs) draw(r.evaluation->series, false, plot::role_colour(r.role), 2, run_label(r));
  return fig.render();
}

}  // namespace

// The first run's largest error on a cutting move: the centre of the zoomed panel.
std::size_t worst_cutting_point(const Series& b, const std::vector<bool>& cutting) {
  std::size_t worst = 0;
  for (std::size_t i = 1; i < b.contour.size(); ++i)
    if (cutting[i] && (!cutting[worst] || b.contour[i] > b.contour[worst])) worst = i;
  return worst;
}

ToolpathView toolpath_view(const Nominal& nominal, const FigureRuns& runs) {
  const Series& b = runs.front().evaluation->series;
  const std::vector<bool> cutting = cutting_points(nominal, runs.front());
  const View whole{plane_of_largest_error(b, cutting)};
  return {whole.plane.name, magnification(b, cutting, whole)};
}

void plot_toolpath(const std::filesystem::path& png, const Nominal& nominal, const FigureRuns& runs,
                   const std::string& title) {
  const Series& b = runs.front().evaluation->series;
  const std::vector<bool> cutting = cutting_points(nominal, runs.front());
  const Plane pl = plane_of_largest_error(b, cutting);
  std::vector<cv::Mat> panels{toolpath_panel(runs, cutting, View{pl}, title)};
  if (!b.t.empty()) {
    const std::size_t worst = worst_cutting_point(b, cutting);
    panels.push_back(toolpath_panel(runs, cutting, View{pl, true, b.nominal[pl.u][worst], b.nominal[pl.v][worst], 10.0}, title));
  }
  cv::Mat out;
  cv::hconcat(panels, out);
  plot::write_png(png, out);
}

bool plot_ballbar(const std::filesystem::path& png, const Nominal& nominal, const FigureRuns& runs,
                  const std::string& title) {
  const Evaluation& before = *runs.front().evaluation;
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
    st.margin_bottom = 75;  // the tick labels and the axis label below them, apart
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
    for (const FigureRun& r : runs) trace(*r.evaluation, plot::role_colour(r.role), plot::role_name(r.role));
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

std::vector<double> programmed_path_length(const Model& model, const Nominal& nom, const FigureRun& run) {
  const Series& s = run.evaluation->series;
  const std::size_t N = nom.raw.size();
  if (N == 0 || (run.on_reference_clock && nom.progress.size() == 0)) return {};
  // The raw sample each point stands for, then one pass over the raw samples in order summing
  // the tool tip's steps (forward kinematics with the block's tool length), read where asked.
  std::vector<std::pair<std::size_t, std::size_t>> wanted(s.t.size());  // (raw sample, point)
  for (std::size_t i = 0; i < s.t.size(); ++i) wanted[i] = {raw_sample_of(nom, run, i), i};
  std::sort(wanted.begin(), wanted.end());
  std::vector<double> length(s.t.size(), 0.0);
  double sum = 0;
  Vec3 last = forward_kinematics(model.kin, nom.raw[0], tool_length_of(model, nom.brief[nom.block[0]])).tip;
  std::size_t k = 0;
  for (const auto& [raw, point] : wanted) {
    for (; k < raw; ++k) {
      const Vec3 tip = forward_kinematics(model.kin, nom.raw[k + 1], tool_length_of(model, nom.brief[nom.block[k + 1]])).tip;
      sum += std::sqrt((tip[0] - last[0]) * (tip[0] - last[0]) + (tip[1] - last[1]) * (tip[1] - last[1]) +
                       (tip[2] - last[2]) * (tip[2] - last[2]));
      last = tip;
    }
    length[point] = sum;
  }
  return length;
}

// The log axis starts three decades below the smallest of the runs' largest errors, so that the
// run with the smallest error is a curve, not a line on the floor (at least 1 nm: compensated.nc
// is written to 0.1 um).
double contour_floor_um(const FigureRuns& runs) {
  double least = 1e300;
  for (const FigureRun& r : runs) least = std::min(least, r.evaluation->contour.max * 1e3);
  return std::max(1e-3, nice_below(least / 1000));
}

void plot_contour_error(const std::filesystem::path& png, const Model& model, const Nominal& nominal,
                        const FigureRuns& runs, const std::string& title) {
  plot::Figure fig;
  fig.title(title);
  std::vector<std::vector<double>> xs;
  for (const FigureRun& r : runs) xs.push_back(programmed_path_length(model, nominal, r));
  const bool along_path = std::all_of(xs.begin(), xs.end(), [](const auto& x) { return !x.empty(); });
  fig.xlabel(along_path ? "programmed path length run [mm] (each place of the part at one x)" : "time [s]");
  fig.ylabel("contour error [um], log scale");
  fig.log_y(contour_floor_um(runs));
  auto um = [](const std::vector<double>& v) {
    std::vector<double> r(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) r[i] = v[i] * 1e3;
    return r;
  };
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const Evaluation& ev = *runs[i].evaluation;
    fig.line(along_path ? xs[i] : ev.series.t, um(ev.series.contour), plot::role_colour(runs[i].role), 2,
             run_label(runs[i]) + fmt(": max %.2f um, RMS %.2f um (cutting moves)", ev.contour.max * 1e3, ev.contour.rms * 1e3));
  }
  fig.note("distance of the simulated tool tip to the nominal path (not to the time-matched point); the curves "
           "include rapids, the figures in the legend do not");
  fig.save_png(png);
}

void plot_following_error(const std::filesystem::path& png, const Model& model, const FigureRuns& runs,
                          const std::string& title) {
  auto panel = [&](const FigureRun& run) {
    const Evaluation& ev = *run.evaluation;
    plot::FigureStyle st;
    st.height = 560;
    plot::Figure f(st);
    f.title(title + ": following error, " + run_label(run));
    f.xlabel("time [s]");
    f.ylabel("command - actual [um | mdeg]");
    std::string ideal, still;
    for (int i = 0; i < kNumAxes; ++i) {
      const auto k = static_cast<std::size_t>(i);
      if (model.drives.axes[k].model == servo::DriveModel::kIdeal) {
        ideal += std::string(ideal.empty() ? "" : " ") + kAxisLetters[i];
        continue;
      }
      if (ev.axes.max_following[k] <= 0) {
        still += std::string(still.empty() ? "" : " ") + kAxisLetters[i];
        continue;
      }
      std::vector<double> v(ev.series.following[k].size());
      for (std::size_t j = 0; j < v.size(); ++j) v[j] = ev.series.following[k][j] * 1e3;
      char label[80];
      std::snprintf(label, sizeof label, i < kA ? "%c [um], max %.2f" : "%c [mdeg], max %.2f", kAxisLetters[i],
                    ev.axes.max_following[k] * 1e3);
      f.line(ev.series.t, std::move(v), plot::palette(i), 2, label);
    }
    if (!ideal.empty()) f.note(ideal + ": ideal drives (model: ideal, actual = command), not drawn");
    if (!still.empty()) f.note(still + ": no following error (the axis does not move)");
    return f.render();
  };
  std::vector<cv::Mat> panels;
  for (const FigureRun& r : runs) panels.push_back(panel(r));
  save_stack(png, panels);
}

}  // namespace gcpipe::compensate
