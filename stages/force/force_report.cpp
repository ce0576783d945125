#include "force_report.hpp"

#include <algorithm>
#include <cstdio>

#include <opencv2/core.hpp>

#include "plot.hpp"
#include "png.hpp"

namespace gcpipe::force {

namespace {

std::string stats_note(const PathForce& p, bool resultant) {
  char buf[240];
  if (resultant)
    std::snprintf(buf, sizeof buf,
                  "%zu revolutions, cutting time %.1f s; max mean force %.0f N, max peak %.0f N, max deflection %.1f um",
                  p.samples.size(), p.cutting_time, p.max_mean_force, p.max_peak_force, 1e3 * p.max_deflection);
  else
    std::snprintf(buf, sizeof buf,
                  "%zu revolutions, cutting time %.1f s; max mean tangential force %.0f N, torque %.1f N m, power %.0f W "
                  "(radial force not stated: no deflection)",
                  p.samples.size(), p.cutting_time, p.max_mean_tangential, p.max_torque, p.max_power);
  return buf;
}

}  // namespace

void write_force_path_png(const std::filesystem::path& png, const PathForce& p, const std::string& title,
                          bool resultant) {
  plot::Figure f;
  f.title(title);
  f.note(stats_note(p, resultant));
  f.xlabel("X [mm]");
  f.ylabel("Y [mm]");
  f.equal_aspect(true);
  std::vector<double> x, y, v;
  for (const ForceSample& s : p.samples) {
    x.push_back(s.x);
    y.push_back(s.y);
    v.push_back(resultant ? s.mean_force : s.mean_tangential);
  }
  const double top = resultant ? p.max_mean_force : p.max_mean_tangential;
  f.colourbar(resultant ? "mean force [N]" : "mean tangential force [N]", 0, std::max(1.0, top), plot::ColourMap::kTurbo);
  f.coloured_line(std::move(x), std::move(y), std::move(v), 2);
  f.save_png(png);
}

void write_force_time_png(const std::filesystem::path& png, const PathForce& p, const std::string& title,
                          bool resultant) {
  plot::FigureStyle style;
  style.height = 520;
  std::vector<double> t, first, second, ae, ap;
  for (const ForceSample& s : p.samples) {
    t.push_back(s.time);
    first.push_back(s.peak_force);
    second.push_back(resultant ? s.mean_force : s.mean_tangential);
    ae.push_back(s.radial_depth);
    ap.push_back(s.axial_depth);
  }
  plot::Figure force(style);
  force.title(title);
  force.note(stats_note(p, resultant));
  if (resultant) {
    force.ylabel("force [N]");
    force.line(t, first, plot::palette(1), 1, "peak |F| in the revolution");
    force.line(t, second, plot::palette(0), 2, "mean |F| over the revolution");
  } else {  // torque and power are this force times D/2 and times the cutting speed: the note
    force.ylabel("force [N]");
    force.line(t, second, plot::palette(0), 2, "mean tangential force over the revolution, flutes summed");
  }
  plot::Figure engagement(style);
  engagement.xlabel("cutting time [s] (feed moves at the programmed feed, no acceleration)");
  engagement.ylabel("depth [mm]");
  engagement.line(t, ae, plot::palette(2), 2, "radial ae");
  engagement.line(t, ap, plot::palette(3), 2, "axial ap");
  cv::Mat both;
  cv::vconcat(force.render(), engagement.render(), both);
  plot::write_png(png, both);
}

void write_prediction_png(const std::filesystem::path& png, const std::vector<double>& reference,
                          const std::vector<double>& predicted, double period, const std::string& title,
                          const std::string& note, const std::string& ylabel) {
  plot::Figure f;
  f.title(title);
  f.note(note);
  f.xlabel("time [s]");
  f.ylabel(ylabel);
  std::vector<double> t(reference.size());
  for (std::size_t i = 0; i < t.size(); ++i) t[i] = static_cast<double>(i) * period;
  f.line(t, reference, plot::palette(0), 1, "reference (measured / simulated with noise)");
  f.line(t, predicted, plot::palette(1), 2, "NNOE, parallel (output-error) run");
  f.save_png(png);
}

void write_spindle_prediction_png(const std::filesystem::path& png, const std::vector<double>& predicted,
                                  const std::vector<double>& cutting, const std::vector<double>& feed, double period,
                                  const std::string& title, const std::string& note, const std::string& ylabel) {
  plot::FigureStyle style;
  style.height = 520;
  std::vector<double> t(predicted.size()), in_cut_t, in_cut;
  for (std::size_t i = 0; i < t.size(); ++i) {
    t[i] = static_cast<double>(i) * period;
    if (cutting[i] == 0) continue;
    in_cut_t.push_back(t[i]);
    in_cut.push_back(predicted[i]);
  }
  plot::Figure quantity(style);
  quantity.title(title);
  quantity.note(note);
  quantity.ylabel(ylabel);
  quantity.line(t, predicted, plot::palette(0), 1, "NNOE, parallel (output-error) run along the program");
  quantity.scatter(in_cut_t, in_cut, plot::palette(1), 2, "samples in cutting moves");
  plot::Figure inputs(style);
  inputs.xlabel("time on the interpolator's clock [s]");
  inputs.ylabel("path feed [mm/s]");
  inputs.line(t, feed, plot::palette(2), 1, "XYZ path speed of the commanded axes");
  cv::Mat both;
  cv::vconcat(quantity.render(), inputs.render(), both);
  plot::write_png(png, both);
}

}  // namespace gcpipe::force
