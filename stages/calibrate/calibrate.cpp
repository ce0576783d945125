#include "calibrate.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <numbers>

#include "axis_model.hpp"
#include "gcpipe/kinematics.hpp"

namespace gcpipe::calibrate {

namespace {

/// Joins the traces end to end (the time axis continues; the drive restarts at every join).
void join(const std::vector<MeasuredTrace>& traces, Calibration& c, std::vector<std::size_t>& segments) {
  double t0 = 0;
  for (const auto& tr : traces) {
    segments.push_back(c.t.size());
    for (std::size_t k = 0; k < tr.size(); ++k) c.t.push_back(t0 + tr.t[k] - tr.t.front());
    t0 = c.t.back() + tr.period;
    for (int a = 0; a < kNumAxes; ++a) {
      c.command[a].insert(c.command[a].end(), tr.command[a].begin(), tr.command[a].end());
      c.actual[a].insert(c.actual[a].end(), tr.actual[a].begin(), tr.actual[a].end());
      // A torque or current column is used only when every joined trace has the same kind.
      const bool first = &tr == &traces.front();
      if (first) c.effort_kind[a] = tr.effort[a].size() == tr.size() ? tr.effort_kind[a] : "";
      if (tr.effort[a].size() != tr.size() || tr.effort_kind[a] != c.effort_kind[a]) c.effort_kind[a].clear();
      c.effort[a].insert(c.effort[a].end(), tr.effort[a].begin(), tr.effort[a].end());
    }
    c.traces.push_back(tr.file);
    c.rows_skipped += tr.rows_skipped;
    c.rows_unused += tr.rows_unused;
  }
  c.rows = c.t.size();
  for (int a = 0; a < kNumAxes; ++a)
    if (c.effort_kind[a].empty()) c.effort[a].clear();
}

/// Held-out part: the last trace when there are several (fit on some experiments, predict the
/// others), else the last 30 % of the one trace.
std::size_t split_of(const std::vector<std::size_t>& segments, std::size_t n) {
  if (segments.size() > 1) return segments.back();
  return static_cast<std::size_t>(0.7 * static_cast<double>(n));
}

double to_um(double v, int axis) {
  const bool rotary = axis == kA || axis == kC;
  return rotary ? v * std::numbers::pi / 180 * kRotaryRadiusMm * 1000 : v * 1000;
}

/// First sample to score. The replay starts the drive at rest on the first command; a trace
/// recorded while the axis was already moving (command changing, or actual away from command)
/// has a start transient the model cannot know, so the first 0.3 s (about five closed-loop time
/// constants at Kpp = 60 plus the acc/dec) are left out of every fit and score.
std::size_t settled_start(const std::vector<double>& cmd, const std::vector<double>& act, double period, double noise) {
  if (cmd.size() < 3) return 1;
  // A trace that starts at rest may start moving at once: the control's acc/dec makes its first
  // command step a small fraction of the speed that follows. Moving means a first step above 5 %
  // of the trace's top speed (and above 1 mm/s), or an actual already away from the command.
  double vmax = 0;
  for (std::size_t k = 1; k < cmd.size(); ++k) vmax = std::max(vmax, std::abs(cmd[k] - cmd[k - 1]) / period);
  const double v0 = std::abs(cmd[1] - cmd[0]) / period;
  const bool moving = (v0 > 0.05 * vmax && v0 > 1.0) || std::abs(act[0] - cmd[0]) > 10 * noise + 1e-3;
  return moving ? std::min(cmd.size() / 4, static_cast<std::size_t>(std::lround(0.3 / period))) : 1;
}

}  // namespace

PredictionError prediction_error(const Calibration& c, const compensate::Model& model,
                                 const std::array<const std::vector<double>*, kNumAxes>& pred) {
  PredictionError e;
  const std::size_t n = c.rows;
  double tip2 = 0;
  std::size_t count = 0;
  for (std::size_t k = c.begin; k < n; ++k) {
    Axes meas{}, mod{};
    for (int a = 0; a < kNumAxes; ++a) {
      meas[a] = c.actual[a][k];
      mod[a] = (*pred[a])[k];
      const double d = meas[a] - mod[a];
      e.rms_um[a] += d * d;
      e.max_um[a] = std::max(e.max_um[a], std::abs(to_um(d, a)));
    }
    const ToolPose pm = forward_kinematics(model.kin, meas), pp = forward_kinematics(model.kin, mod);
    const double d = std::sqrt(std::pow(pm.tip[0] - pp.tip[0], 2) + std::pow(pm.tip[1] - pp.tip[1], 2) +
                               std::pow(pm.tip[2] - pp.tip[2], 2)) * 1000;
    tip2 += d * d;
    e.tip_max_um = std::max(e.tip_max_um, d);
    ++count;
  }
  for (int a = 0; a < kNumAxes; ++a) {
    const double rms = std::sqrt(e.rms_um[a] / static_cast<double>(std::max<std::size_t>(count, 1)));
    e.rms_um[a] = to_um(rms, a);
    e.rms_deg[a] = (a == kA || a == kC) ? rms : 0;
  }
  e.tip_rms_um = std::sqrt(tip2 / static_cast<double>(std::max<std::size_t>(count, 1)));
  return e;
}

namespace {

/// NNOE on what the calibrated model leaves, where that is clearly above the noise (rms above
/// 1.5 x noise on the held-out part).
void fit_fallback(Calibration& c, int a, std::vector<double>& corrected) {
  const auto& id = c.axes[a];
  corrected = id.pred_calibrated;
  if (!id.moving) return;
  std::vector<double> r(c.rows);
  for (std::size_t k = 0; k < c.rows; ++k) r[k] = c.actual[a][k] - id.pred_calibrated[k];
  double s = 0;
  for (std::size_t k = c.split; k < c.rows; ++k) s += r[k] * r[k];
  const double rms = std::sqrt(s / static_cast<double>(std::max<std::size_t>(1, c.rows - c.split)));
  if (!(rms > 1.5 * c.noise[a])) return;
  // Inputs: the commanded velocity and acceleration (the commands drive the machine; the
  // prediction's own acceleration is filtered by the loop and misses what excites a mode).
  std::vector<double> v, acc;
  differentiate(c.command[a], c.period, v, acc);
  auto m = fit_nnoe(r, v, acc, 1, c.split, c.period);
  if (std::getenv("GCPIPE_CALIBRATE_DEBUG") && m) {
    std::fprintf(stderr, "nnoe axis %d: %s explained %.4f\n", a, m->structure.text().c_str(), m->explained_fraction);
    for (const auto& [st, f] : m->candidates) std::fprintf(stderr, "  %s FPE %.5f\n", st.text().c_str(), f);
  }
  if (!m || !(m->explained_fraction > 0)) return;
  const auto rh = m->simulate(v, acc);
  for (std::size_t k = 0; k < c.rows; ++k) corrected[k] += rh[k];
  c.nnoe[a] = std::move(m);
}

}  // namespace

Calibration calibrate_traces(const std::vector<MeasuredTrace>& traces, const compensate::Model& model,
                             const IdentifyOptions& options,
                             const std::function<void(std::uint64_t done, std::uint64_t total)>& progress) {
  constexpr std::uint64_t kSteps = 2 * kNumAxes;
  std::uint64_t done = 0;
  auto step = [&] {
    if (progress) progress(++done, kSteps);
  };
  if (progress) progress(0, kSteps);
  Calibration c;
  std::vector<std::size_t> segments;
  join(traces, c, segments);
  c.period = traces.front().period;
  c.split = split_of(segments, c.rows);
  c.drives = model.drives;
  // A configured NNOE correction (calibrated.yaml of an earlier run) is not a declared effect:
  // the fallback below fits a new one on what this calibration's model leaves.
  for (auto& axis : c.drives.axes) std::erase_if(axis.effects, [](const servo::EffectSettings& e) { return e.type == "nnoe"; });
  for (int a = 0; a < kNumAxes; ++a) {
    AxisSeries s;
    s.axis = a;
    s.period = c.period;
    s.substeps = model.drives.substeps;
    s.margin = model.drives.saturation_margin;
    s.command = c.command[a];
    s.actual = c.actual[a];
    s.split = c.split;
    s.begin = settled_start(c.command[a], c.actual[a], c.period, estimate_noise(c.actual[a]));
    c.begin = std::max(c.begin, s.begin);
    s.segments = segments;
    s.noise = c.noise[a] = estimate_noise(c.actual[a]);
    s.effort = c.effort[a];
    s.effort_kind = c.effort_kind[a];
    c.axes[a] = identify_axis(s, c.drives.axes[a], options);
    c.drives.axes[a] = c.axes[a].calibrated;
    step();
  }
  std::array<std::vector<double>, kNumAxes> corrected;
  for (int a = 0; a < kNumAxes; ++a) {
    fit_fallback(c, a, corrected[a]);
    step();
  }
  auto preds = [&](auto member) {
    std::array<const std::vector<double>*, kNumAxes> p{};
    for (int a = 0; a < kNumAxes; ++a) p[a] = &(c.axes[a].*member);
    return p;
  };
  c.declared = prediction_error(c, model, preds(&AxisIdentification::pred_declared));
  c.refit = prediction_error(c, model, preds(&AxisIdentification::pred_refit));
  c.calibrated = prediction_error(c, model, preds(&AxisIdentification::pred_calibrated));
  std::array<const std::vector<double>*, kNumAxes> pn{};
  for (int a = 0; a < kNumAxes; ++a) pn[a] = &corrected[a];
  c.with_nnoe = prediction_error(c, model, pn);
  return c;
}

}  // namespace gcpipe::calibrate
