#include "simulation_report.hpp"

#include <cmath>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "compensate_plots.hpp"
#include "report.hpp"

namespace gcpipe::compensate {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Seed 002 eq. (20) is about synchronising X/Y with a turning C: computed at the program's fastest
// C speed when C turns and X, Y and C have drive models, and per circle segment at its own speed.
void recommend_kffp(const Model& model, const Nominal& nominal, ReportInput& rin) {
  const double omega = nominal.stats.interp.peak_velocity[kC] * kPi / 180.0;
  const auto& d = model.drives.axes;
  if (!(omega > 1e-6)) {
    rin.best_kffp_note = "no recommendation: C does not turn in this program";
    return;
  }
  if (d[kX].model != servo::DriveModel::kDrive || d[kY].model != servo::DriveModel::kDrive ||
      d[kC].model != servo::DriveModel::kDrive) {
    rin.best_kffp_note = "no recommendation: X, Y and C need drive models in the drives file";
    return;
  }
  const double T = model.interp.period;
  rin.best_kffp = servo::best_kffp(model.drives, model.interp.smoothing, T, omega, 2.0, 1.0);
  rin.best_kffp_omega = omega;
  std::vector<double> seg_omega(nominal.segments.size(), 0.0);
  for (std::size_t n = 1; n < nominal.raw.size(); ++n) {
    const std::size_t g = nominal.segment_of_block[nominal.block[n]];
    if (g < seg_omega.size())
      seg_omega[g] = std::max(seg_omega[g], std::abs(nominal.raw[n][kC] - nominal.raw[n - 1][kC]) / T * kPi / 180.0);
  }
  for (std::size_t g = 0; g < seg_omega.size(); ++g)
    if (seg_omega[g] > 1e-6 && nominal.segments[g].circle)
      rin.segment_kffp.push_back({g, {seg_omega[g], servo::best_kffp(model.drives, model.interp.smoothing, T, seg_omega[g], 2.0, 1.0)}});
}

// The runs every figure compares, in the palette's order: before, (feed-forward,) after. Under
// the look-ahead control the original runs the plan, whose clock is the reference's (its
// in-position waits shift the figure's path-length axis by the distance those waits stand for).
FigureRuns figure_runs(const Model& model, const Evaluation& before, const Evaluation* feedforward,
                       const Evaluation* after) {
  const bool planned = model.interp.control == interpolate::Control::kLookahead;
  FigureRuns runs{{plot::Role::kBefore, &before, planned, "the control runs the original"}};
  if (feedforward)
    runs.push_back({plot::Role::kFeedForward, feedforward, true, "the drives' model inverse, no learning"});
  if (after) runs.push_back({plot::Role::kAfter, after, true, "compensated.nc as written"});
  return runs;
}

void draw(pipeline::ReportContext& r, const Model& model, const Nominal& nominal, const FigureRuns& runs) {
  if (r.dir.empty()) return;
  if (r.progress) r.progress("drawing the error figures", 0, 0);
  const std::filesystem::path plots = r.dir / "plots";
  const std::string& base = r.input_base;
  plot_toolpath(plots / "toolpath.png", nominal, runs, base + ": tool path");
  r.files->push_back("plots/toolpath.png");
  if (plot_ballbar(plots / "ballbar.png", nominal, runs, base)) r.files->push_back("plots/ballbar.png");
  plot_contour_error(plots / "contour_error.png", model, nominal, runs, base + ": contour error along the program");
  r.files->push_back("plots/contour_error.png");
  plot_following_error(plots / "following_error.png", model, runs, base);
  r.files->push_back("plots/following_error.png");
}

}  // namespace

void report_simulation(pipeline::ReportContext& r, const SimulationOutcome& o) {
  if (o.run == nullptr || !o.run->before) {
    const std::string why = o.skipped.empty() ? o.not_compensated : o.skipped;
    (*r.json)["simulation"] = {{"skipped", why}};
    if (!o.not_compensated.empty()) (*r.json)["simulation"]["not_compensated"] = o.not_compensated;
    *r.text += "  simulate: skipped (" + why + ")\n";
    return;
  }
  const Nominal& nominal = *o.run->nominal;
  ReportInput rin;
  rin.model = o.model;
  rin.nominal = &nominal;
  rin.before = &*o.run->before;
  rin.after = o.after;
  rin.result = o.result;
  rin.slowed = o.slowed;
  rin.feedforward = o.feedforward;
  rin.feedforward_over_limit = o.feedforward_over_limit;
  rin.slowdown = o.slowdown;
  recommend_kffp(*o.model, nominal, rin);
  (*r.json)["simulation"] = report_json(rin);
  if (!o.not_compensated.empty()) (*r.json)["simulation"]["not_compensated"] = o.not_compensated;
  char buf[256];
  // The machine's time: the interpolator's run under seed 002's control, the plan with its
  // in-position waits under the look-ahead control (its run is the "before").
  const bool lookahead = o.model->interp.control == interpolate::Control::kLookahead;
  const double machine_time = lookahead ? static_cast<double>(o.run->before->stats.ticks - 1) * o.model->interp.period
                                        : static_cast<double>(nominal.raw.size() - 1) * o.model->interp.period;
  std::snprintf(buf, sizeof buf, "  simulate: %.3f s of machine time at %.4g s (%s control)\n", machine_time,
                o.model->interp.period, lookahead ? "look-ahead" : "seed 002's acc/dec-after-interpolation");
  *r.text += buf;
  *r.text += report_text(rin);
  if (!o.not_compensated.empty()) *r.text += "  not compensated: " + o.not_compensated + "\n";
  if (o.after != nullptr) {
    std::snprintf(buf, sizeof buf,
                  "  compensated.nc: %llu timed points (G93, machine axes), read back and simulated for the 'after' figures\n",
                  static_cast<unsigned long long>(o.written_nodes));
    *r.text += buf;
  }
  const FigureRuns runs = figure_runs(*o.model, *o.run->before, o.feedforward, o.after);
  const ToolpathView view = toolpath_view(nominal, runs);
  (*r.json)["simulation"]["toolpath_figure"] = {{"plane", view.plane}, {"magnification", view.magnification}};
  draw(r, *o.model, nominal, runs);
}

}  // namespace gcpipe::compensate
