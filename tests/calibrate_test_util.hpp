// Shared scenarios of the calibration tests: the seed 002 machine (circle_test.yaml), programs
// (circle, trochoidal slot, five-axis), a "true" machine with an effect, a configured model with
// the base parameters off by +-20 %, and 0.2 um (0.0002 deg) noise.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "compensate.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "identify.hpp"
#include "axis_model.hpp"
#include "parse.hpp"
#include "simulate_trace.hpp"

namespace gcpipe::calibrate::test {

inline std::vector<ResolvedBlock> parse_text(const std::string& text, const PipelineConfig& pc) {
  Parser parser(ParseOptions{}, pc.machine, "test.nc");
  std::vector<ResolvedBlock> out;
  feed_text(parser, text,
            {[&out](const ResolvedBlock& b) {
               out.push_back(b);
               return true;
             },
             [](const Diagnostic& d) {
               if (d.severity == Severity::kError) ADD_FAILURE() << format(d);
               return true;
             }});
  return out;
}

inline PipelineConfig circle_config() {
  return load_pipeline_config(std::filesystem::path(GCPIPE_SOURCE_DIR) / "pipeline_configs" / "circle_test.yaml");
}

/// Circle test at F3000, radius 20 mm, two turns each way: quadrant reversals on X and Y.
inline std::string circle_program() {
  return "G21 G17 G90 G94\nG0 X-20. Y0 Z0 A0 C0\nG1 X-20. Y0 F3000.\n"
         "G2 X-20. Y0 I20. J0 F3000.\nG2 X-20. Y0 I20. J0\nG3 X-20. Y0 I20. J0\nG3 X-20. Y0 I20. J0\n"
         "G4 X0.3\nM30\n";
}

/// The circle test as a shop runs it to tell dynamic errors from geometric ones: the same circle
/// at two feeds (F1500, then F3000), one turn each way, at rest between the two. A drive's gain
/// and lag change with the speed, a scale or other geometric error does not (README 7).
inline std::string circle_two_feeds_program() {
  return "G21 G17 G90 G94\nG0 X-20. Y0 Z0 A0 C0\nG1 X-20. Y0 F1500.\n"
         "G2 X-20. Y0 I20. J0 F1500.\nG3 X-20. Y0 I20. J0\nG4 X0.5\n"
         "G2 X-20. Y0 I20. J0 F3000.\nG3 X-20. Y0 I20. J0\nG4 X0.3\nM30\n";
}

/// Trochoidal slot along X: loops of radius 4 mm advancing 1.5 mm per loop, F2400.
inline std::string trochoid_program() {
  std::ostringstream p;
  p << "G21 G17 G90 G94\nG0 X0 Y0 Z0 A0 C0\nG1 X4. Y0 F2400.\n";
  for (int i = 0; i < 14; ++i) {
    const double x = 4.0 + 1.5 * i;
    p << "G3 X" << x - 8 << " Y0 I-4. J0\nG3 X" << x + 1.5 << " Y0 I" << (4 + 1.5 / 2) << " J0\n";
  }
  p << "G4 X0.3\nM30\n";
  return p.str();
}

/// Five-axis move: X Y with A and C together, joint mode, with reversals on every axis.
inline std::string five_axis_program() {
  return "G21 G17 G90 G94\nG0 X0 Y0 Z0 A0 C0\n"
         "G1 X30. Y10. Z-5. A-20. C40. F2000.\nG1 X-10. Y30. Z0 A-5. C100.\nG1 X20. Y-20. Z-8. A-30. C20.\n"
         "G1 X-30. Y0 Z-2. A-10. C-40.\nG1 X10. Y15. Z-6. A-25. C60.\nG1 X0 Y0 Z0 A0 C0\nG4 X0.3\nM30\n";
}

struct Scenario {
  PipelineConfig pc;
  compensate::Model machine;  //!< the "true" machine (add effects here)
  compensate::Model config;   //!< what the calibration is given
  std::vector<ResolvedBlock> program;
};

/// Base parameters of the configured model off by +-20 % (signs alternate between axes).
inline void perturb(compensate::Model& m) {
  for (int a : {kX, kY, kC}) {
    auto& p = m.drives.axes[static_cast<std::size_t>(a)];
    const double s = a == kY ? -1 : 1;
    p.Kpp *= 1 + 0.2 * s;
    p.K_FFP *= 1 - 0.15 * s;
    p.Ta *= 1 + 0.2 * s;
    // Inertia and gains together: a position trace sees them only as ratios (README).
    p.J *= 1 + 0.2 * s;
    p.J1 *= 1 + 0.2 * s;
    p.Kvp *= 1 + 0.2 * s;
    p.C *= 1 + 0.2 * s;
  }
}

inline Scenario make_scenario(const std::string& text) {
  Scenario s;
  s.pc = circle_config();
  s.machine = compensate::load_model(s.pc);
  s.config = s.machine;
  perturb(s.config);
  s.program = parse_text(text, s.pc);
  return s;
}
inline Scenario circle_scenario() { return make_scenario(circle_program()); }
inline Scenario trochoid_scenario() { return make_scenario(trochoid_program()); }
inline Scenario circle_two_feeds_scenario() { return make_scenario(circle_two_feeds_program()); }
inline Scenario five_axis_scenario() { return make_scenario(five_axis_program()); }

inline servo::EffectSettings effect(std::string type, std::vector<std::pair<std::string, double>> v) {
  servo::EffectSettings e;
  e.type = std::move(type);
  e.values = std::move(v);
  return e;
}

inline MeasuredTrace trace_of(const Scenario& sc, std::uint64_t seed) {
  SimulateTraceOptions o;
  o.noise = {2e-4, 2e-4, 2e-4, 2e-4, 2e-4};
  o.seed = seed;
  return simulate_trace(sc.machine, sc.program, o);
}

inline AxisSeries series_of(const MeasuredTrace& tr, const compensate::Model& cfg, int axis) {
  AxisSeries s;
  s.axis = axis;
  s.period = tr.period;
  s.substeps = cfg.drives.substeps;
  s.margin = cfg.drives.saturation_margin;
  s.command = tr.command[static_cast<std::size_t>(axis)];
  s.actual = tr.actual[static_cast<std::size_t>(axis)];
  s.begin = 1;
  s.split = static_cast<std::size_t>(0.7 * static_cast<double>(s.command.size()));
  s.noise = estimate_noise(s.actual);
  return s;
}

inline AxisIdentification identify(const Scenario& sc, int axis, std::uint64_t seed) {
  const MeasuredTrace tr = trace_of(sc, seed);
  return identify_axis(series_of(tr, sc.config, axis), sc.config.drives.axes[static_cast<std::size_t>(axis)], IdentifyOptions{});
}

inline double rms_error(const AxisSeries& s, const std::vector<double>& y) {
  double e = 0;
  for (std::size_t k = s.begin; k < y.size(); ++k) e += (s.actual[k] - y[k]) * (s.actual[k] - y[k]);
  return std::sqrt(e / static_cast<double>(y.size() - s.begin));
}

inline void print(const AxisIdentification& id) {
  std::cout << "axis " << kAxisLetters[id.axis] << " noise " << id.noise << " refit " << id.refit_kept << " " << id.refit_note << "\n";
  for (const auto& d : id.declared)
    std::cout << "  " << d.name << " config " << d.config << " fitted " << d.fitted << " +- " << d.sigma << (d.held ? " held: " + d.why : "") << "\n";
  for (const auto& c : id.candidates) {
    std::cout << "  round " << c.round << " " << c.effect << " BIC " << c.criterion_before << " -> " << c.criterion_after
              << " (evidence " << c.evidence << ") heldout rms " << std::sqrt(c.heldout_before) << " -> " << std::sqrt(c.heldout_after) << " " << c.reason << " (" << c.seconds << " s):";
    for (const auto& p : c.params) std::cout << " " << p.name << "=" << p.value << "+-" << p.sigma;
    std::cout << "\n";
  }
}

}  // namespace gcpipe::calibrate::test

namespace gcpipe::calibrate::test {

/// Identification of every axis of a simulated trace.
inline std::vector<AxisIdentification> identify_all(const Scenario& sc, std::uint64_t seed) {
  const MeasuredTrace tr = trace_of(sc, seed);
  std::vector<AxisIdentification> out;
  for (int a = 0; a < kNumAxes; ++a)
    out.push_back(identify_axis(series_of(tr, sc.config, a), sc.config.drives.axes[static_cast<std::size_t>(a)], IdentifyOptions{}));
  return out;
}

/// rms of measured - calibrated prediction over the whole trace (fit and held-out parts).
inline double calibrated_rms(const Scenario& sc, std::uint64_t seed, const AxisIdentification& id) {
  const MeasuredTrace tr = trace_of(sc, seed);
  return rms_error(series_of(tr, sc.config, id.axis), id.pred_calibrated);
}

/// Expects exactly `effects` named on `axis` (in any order) and nothing on the other axes.
inline void expect_named(const std::vector<AxisIdentification>& ids, int axis, std::vector<std::string> effects) {
  for (const auto& id : ids) {
    std::vector<std::string> got;
    for (const auto& n : id.named) got.push_back(n.effect);
    std::sort(got.begin(), got.end());
    std::vector<std::string> want = id.axis == axis ? effects : std::vector<std::string>{};
    std::sort(want.begin(), want.end());
    EXPECT_EQ(got, want) << "axis " << kAxisLetters[id.axis];
    if (got != want) print(id);
  }
}

inline double param(const AxisIdentification& id, const std::string& effect, const std::string& name) {
  for (const auto& n : id.named)
    if (n.effect == effect)
      for (const auto& p : n.params)
        if (p.name == name) return p.value;
  return NAN;
}

}  // namespace gcpipe::calibrate::test

#include <fstream>
#include <nlohmann/json.hpp>

#include "calibrate.hpp"
#include "trace.hpp"

namespace gcpipe::calibrate::test {

/// The University of Michigan mill's six experiments (../shared/data), bad rows skipped; empty
/// when the shared data is absent (the caller skips and says so), a failure when one is rejected.
inline std::vector<MeasuredTrace> umich_experiments() {
  const std::filesystem::path dir = std::filesystem::path(GCPIPE_SHARED_DATA) / "traces/umich_smart_cnc_mill";
  std::vector<MeasuredTrace> out;
  if (!std::filesystem::exists(dir)) return out;
  for (int i = 1; i <= 6; ++i) {
    ReadOptions o;
    o.skip_bad_rows = true;
    auto r = read_trace_file(dir / ("experiment_0" + std::to_string(i) + ".csv"), o);
    if (!r.trace) ADD_FAILURE() << "UMich experiment " << i << " rejected";
    else out.push_back(std::move(*r.trace));
  }
  return out;
}

/// A fresh directory under the build tree for one test.
inline std::filesystem::path scratch(const std::string& name) {
  const auto d = std::filesystem::path(GCPIPE_BINARY_DIR) / "calibrate_tests" / name;
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

/// A lightly damped structural mode (40 Hz, 2 %) excited by the commanded acceleration of one
/// axis and added to its actual position: an effect outside the catalogue.
struct StructuralMode {
  double hz = 40, zeta = 0.02, gain = 1;
  int axis = kX;
  double x = 0, xd = 0, p1 = NAN, p2 = NAN;
  void operator()(const compensate::Tick& t, Axes& actual) {
    const double p = t.command[static_cast<std::size_t>(axis)], T = 1e-3;
    const double a = std::isnan(p2) ? 0 : (p - 2 * p1 + p2) / (T * T);
    p2 = std::isnan(p1) ? p : p1;
    p1 = p;
    const double w = 2 * M_PI * hz, h = T / 20;
    for (int i = 0; i < 20; ++i) {
      xd += h * (-2 * zeta * w * xd - w * w * x - gain * a);
      x += h * xd;
    }
    actual[static_cast<std::size_t>(axis)] += x;
  }
};

/// The trace as the shared CSV (stages/servo/trace.hpp).
inline void write_csv(const MeasuredTrace& tr, const std::filesystem::path& path) {
  std::ofstream out(path);
  TraceWriter w(out);
  for (std::size_t k = 0; k < tr.size(); ++k) {
    TraceRow r;
    r.t = tr.t[k];
    for (std::size_t a = 0; a < kNumAxes; ++a) { r.command[a] = tr.command[a][k]; r.actual[a] = tr.actual[a][k]; }
    w.row(r);
  }
}

/// A pipeline config in `dir` for the drives `d` (circle_test.yaml otherwise).
inline std::filesystem::path write_config(const servo::DriveSet& d, const std::filesystem::path& dir, const std::string& stem) {
  const auto src = (std::filesystem::path(GCPIPE_SOURCE_DIR) / "pipeline_configs" / "circle_test.yaml").string();
  std::ofstream(dir / (stem + "_drives.yaml")) << drives_text(d, "# test drives\n");
  const auto cfg = dir / (stem + ".yaml");
  std::ofstream(cfg) << pipeline_yaml(src, stem + "_drives.yaml");
  return cfg;
}

inline nlohmann::json read_json(const std::filesystem::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in);
}

}  // namespace gcpipe::calibrate::test
