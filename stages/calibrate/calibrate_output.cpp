// calibration.json, calibrated.yaml + calibrated_drives.yaml, report.txt, and run_calibrate.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "calibrate.hpp"
#include "gcpipe/config.hpp"
#include "gcpipe/pipeline_config.hpp"

namespace gcpipe::calibrate {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string axis(int a) { return std::string(1, kAxisLetters[a]); }

std::string num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

/// Shortest text that reads back as the same double.
std::string exact(double v) {
  char buf[64];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  (void)ec;
  return std::string(buf, end);
}

/// Writes `text` to dir/name.part, then renames it to dir/name: a reader never sees half a file.
void write_atomic(const fs::path& dir, const std::string& name, const std::string& text) {
  const fs::path part = dir / (name + ".part"), final_path = dir / name;
  {
    std::ofstream out(part, std::ios::binary);
    out << text;
    out.flush();
    if (!out) throw std::runtime_error(part.string() + ": cannot write (check space and permissions)");
  }
  fs::rename(part, final_path);
}

json error_json(const PredictionError& e) {
  json j;
  for (int a = 0; a < kNumAxes; ++a) {
    j["rms_um"][axis(a)] = e.rms_um[a];
    j["max_um"][axis(a)] = e.max_um[a];
    if (a == kA || a == kC) j["rms_deg"][axis(a)] = e.rms_deg[a];
  }
  j["tip_rms_um"] = e.tip_rms_um;
  j["tip_max_um"] = e.tip_max_um;
  return j;
}

json declared_json(const Calibration& c) {
  json j = json::object();
  for (int a = 0; a < kNumAxes; ++a) {
    if (c.axes[a].declared.empty()) continue;
    for (const auto& d : c.axes[a].declared)
      j[axis(a)][d.name] = {{"config", d.config}, {"fitted", d.fitted}, {"sigma", d.sigma}, {"held", d.held},
                            {"unit", d.unit}, {"why", d.why}};
  }
  return j;
}

json score_json(int a, const CandidateScore& s) {
  json p = json::object();
  for (const auto& q : s.params) p[q.name] = {{"value", q.value}, {"unit", q.unit}, {"sigma", q.sigma}};
  return {{"axis", axis(a)}, {"name", s.effect}, {"parameters", p}, {"criterion_before", s.criterion_before},
          {"criterion_after", s.criterion_after}, {"evidence", s.evidence}, {"heldout_rms_before", std::sqrt(s.heldout_before)},
          {"heldout_rms_after", std::sqrt(s.heldout_after)}, {"round", s.round}, {"named", s.named},
          {"reason", s.reason}, {"seconds", s.seconds}};
}

}  // namespace

std::string calibration_json(const Calibration& c) {
  json j;
  j["trace"] = c.traces.size() == 1 ? json(c.traces.front()) : json(c.traces);
  j["rows"] = c.rows;
  j["rows_skipped"] = c.rows_skipped;
  j["rows_unused"] = c.rows_unused;
  j["period_s"] = c.period;
  j["heldout_from_row"] = c.split;
  j["scored_from_row"] = c.begin;
  j["rotary_radius_mm"] = kRotaryRadiusMm;
  j["criterion"] = "BIC = N_eff ln(SSE/N) + k ln(N_eff), N_eff = N / correlation time of the residual";
  for (int a = 0; a < kNumAxes; ++a) j["noise_um"][axis(a)] = (a == kA || a == kC) ? c.noise[a] * M_PI / 180 * kRotaryRadiusMm * 1000 : c.noise[a] * 1000;
  j["declared"] = declared_json(c);
  j["torque"] = json::object();
  for (int a = 0; a < kNumAxes; ++a) {
    const auto& id = c.axes[a];
    if (c.effort_kind[a].empty() || !id.moving) continue;
    j["torque"][axis(a)] = {{"column", c.effort_kind[a]}, {"heldout_rms_config_Nm", id.torque_rms_config},
                            {"heldout_rms_calibrated_Nm", id.torque_rms_calibrated}};
  }
  j["effects"] = json::array();
  j["candidates"] = json::array();
  for (int a = 0; a < kNumAxes; ++a) {
    for (const auto& s : c.axes[a].named) {
      json e = score_json(a, s);
      j["effects"].push_back({{"axis", e["axis"]}, {"name", e["name"]}, {"parameters", e["parameters"]},
                              {"criterion_before", e["criterion_before"]}, {"criterion_after", e["criterion_after"]}});
    }
    for (const auto& s : c.axes[a].candidates) j["candidates"].push_back(score_json(a, s));
  }
  j["unidentified"] = json::array();
  for (int a = 0; a < kNumAxes; ++a)
    if (c.nnoe[a]) {
      json fpe = json::array();
      for (const auto& [st, v] : c.nnoe[a]->candidates) fpe.push_back({{"structure", st.text()}, {"fpe", v}});
      j["unidentified"].push_back({{"axis", axis(a)}, {"model", "nnoe"}, {"structure", c.nnoe[a]->structure.text()},
                                   {"explained_fraction", c.nnoe[a]->explained_fraction}, {"fpe", c.nnoe[a]->fpe},
                                   {"structures_tried", fpe},
                                   {"weights", std::vector<double>(c.nnoe[a]->net.parameters().data(), c.nnoe[a]->net.parameters().data() + c.nnoe[a]->net.parameter_count())},
                                   {"y_scale", c.nnoe[a]->y_scale}, {"u_scale", {c.nnoe[a]->u_scale[0], c.nnoe[a]->u_scale[1]}}});
    }
  j["prediction_error"] = {{"declared", error_json(c.declared)}, {"refit", error_json(c.refit)},
                           {"calibrated", error_json(c.calibrated)}, {"calibrated_with_nnoe", error_json(c.with_nnoe)}};
  j["config"] = "calibrated.yaml";
  return j.dump(2) + "\n";
}

namespace {

void axis_yaml(std::ostringstream& y, int a, const servo::DriveParams& p) {
  y << "  " << axis(a) << ":\n";
  if (p.model == servo::DriveModel::kIdeal) {
    y << "    model: ideal\n";
    return;
  }
  y << "    J: " << num(p.J) << "\n    J1: " << num(p.J1) << "\n    C: " << num(p.C) << "\n    Kpp: " << num(p.Kpp)
    << "\n    Kvp: " << num(p.Kvp) << "\n    Kvi: " << num(p.Kvi) << "\n    K_FFP: " << num(p.K_FFP)
    << "\n    Ta: " << num(p.Ta) << "\n    Tp: " << num(p.Tp) << "\n    Ts: " << num(p.Ts) << "\n";
  if (p.lead > 0) y << "    lead: " << num(p.lead) << "\n";
  if (p.torque_limit > 0) y << "    torque_limit: " << num(p.torque_limit) << "\n";
  std::string later;
  std::ostringstream e;
  for (const auto& ef : p.effects) {
    std::string line = "      " + ef.type + ": {";
    // The NNOE is recurrent: its numbers are written to every digit.
    const auto text = [&](double v) { return ef.type == "nnoe" ? exact(v) : num(v); };
    for (std::size_t i = 0; i < ef.values.size(); ++i) line += (i ? ", " : "") + ef.values[i].first + ": " + text(ef.values[i].second);
    for (const auto& [key, list] : ef.lists) {
      line += ", " + key + ": [";
      for (std::size_t i = 0; i < list.size(); ++i) line += (i ? ", " : "") + exact(list[i]);
      line += "]";
    }
    line += "}\n";
    // A measurement delay skews the log, not the table: a model that carried it would make the
    // compensation lead the real machine. It is reported, and left out of the model.
    if (ef.type == "measurement_delay") later += "      # measured, not part of the machine (the log lags the motion):\n      # " + line.substr(6);
    else e << line;
  }
  if (!e.str().empty() || !later.empty()) y << "    effects:\n" << e.str() << later;
}

}  // namespace

std::string drives_text(const servo::DriveSet& d, const std::string& header) {
  std::ostringstream y;
  y << header << "substeps: " << d.substeps << "\nsaturation_margin: " << num(d.saturation_margin) << "\naxes:\n";
  for (int a = 0; a < kNumAxes; ++a) axis_yaml(y, a, d.axes[a]);
  if (!d.prediction_warnings.empty()) {
    y << "prediction_warnings:\n";
    for (const auto& w : d.prediction_warnings) {
      std::string q;
      for (char ch : w) q += ch == '"' || ch == '\\' ? std::string("\\") + ch : std::string(1, ch);
      y << "  - \"" << q << "\"\n";
    }
  }
  return y.str();
}

servo::EffectSettings nnoe_effect(const NnoeModel& m, double period) {
  servo::EffectSettings e;
  e.type = "nnoe";
  e.values = {{"period", period},
              {"decimation", static_cast<double>(m.decimation)},
              {"na", static_cast<double>(m.structure.na)},
              {"nb", static_cast<double>(m.structure.nb)},
              {"hidden", static_cast<double>(m.structure.hidden)},
              {"y_scale", m.y_scale},
              {"y_offset", m.y_offset}};
  const auto& w = m.net.parameters();
  e.lists = {{"u_scale", m.u_scale}, {"u_offset", m.u_offset}, {"weights", std::vector<double>(w.data(), w.data() + w.size())}};
  return e;
}

std::vector<std::string> prediction_warnings(const Calibration& c) {
  std::vector<std::string> out;
  for (int a = 0; a < kNumAxes; ++a) {
    const auto& id = c.axes[a];
    if (!id.moving || id.config.model != servo::DriveModel::kDrive) continue;
    const bool rot = a == kA || a == kC;
    const double noise_um = (rot ? c.noise[a] * M_PI / 180 * kRotaryRadiusMm : c.noise[a]) * 1000;
    const double err = c.nnoe[a] ? c.with_nnoe.rms_um[a] : c.calibrated.rms_um[a];
    if (id.base.structural_mismatch || err > 5 * std::max(noise_um, 0.05))
      out.push_back(std::string(1, kAxisLetters[a]) + ": the calibrated model predicts the measured trace to " + num(err) + " um rms" +
                    (rot ? " at 100 mm" : "") + " (noise " + num(noise_um) + " um)" +
                    (id.base.structural_mismatch ? "; " + id.base.mismatch : "") +
                    ": a compensation with it is no better than that");
  }
  return out;
}

std::string drives_yaml(const Calibration& c, const servo::DriveSet& configured) {
  std::string h = "# Drives calibrated by gcpipe calibrate from " + std::to_string(c.rows) + " rows of";
  for (const auto& t : c.traces) h += " " + t;
  h += ".\n# Fitted values and their 1-sigma: calibration.json (declared, effects). Keys: stages/servo/README.md.\n";
  // Every value this file changes from the config, with its 1-sigma, where a reader sees it.
  for (int a = 0; a < kNumAxes; ++a)
    for (const auto& d : c.axes[a].declared)
      if (!d.held && d.fitted != d.config)
        h += "#   " + std::string(1, kAxisLetters[a]) + " " + d.name + " = " + num(d.fitted) + " +- " + num(d.sigma) + " " + d.unit + " (config " + num(d.config) + ")\n";
  servo::DriveSet d = c.drives;
  for (int a = 0; a < kNumAxes; ++a)
    if (c.nnoe[a]) d.axes[static_cast<std::size_t>(a)].effects.push_back(nnoe_effect(*c.nnoe[a], c.period));
  d.prediction_warnings = prediction_warnings(c);
  d.substeps = configured.substeps;
  d.saturation_margin = configured.saturation_margin;
  return drives_text(d, h);
}

/// The pipeline config with `servo.drives` pointing at the drives file and every other relative
/// path (machine, ik.model) made absolute, so it loads from OUTDIR as is.
std::string pipeline_yaml(const std::string& config_path, const std::string& drives_file) {
  YAML::Node root = YAML::LoadFile(config_path);
  const fs::path dir = fs::absolute(fs::path(config_path)).parent_path();
  auto absolute = [&](YAML::Node n) {
    if (n && n.IsScalar() && fs::path(n.as<std::string>()).is_relative()) n = (dir / n.as<std::string>()).lexically_normal().string();
  };
  absolute(root["machine"]);
  if (root["ik"] && root["ik"]["model"]) absolute(root["ik"]["model"]);
  root["servo"]["drives"] = drives_file;
  YAML::Emitter em;
  em << root;
  return "# Pipeline config written by gcpipe calibrate: " + config_path +
         " with the drives of " + drives_file +
         ".\n# Use it as is: gcpipe batch PROGRAM.nc --config calibrated.yaml\n" + em.c_str() + "\n";
}

}  // namespace gcpipe::calibrate

namespace gcpipe::calibrate {

namespace {

std::string fixed(double v, int places = 3) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", places, v);
  return buf;
}

void report_errors(std::ostringstream& r, const char* name, const PredictionError& e) {
  r << "  " << name << ":";
  for (int a = 0; a < kNumAxes; ++a) r << " " << axis(a) << " " << fixed(e.rms_um[a]) << " (max " << fixed(e.max_um[a]) << ")";
  r << "  tip " << fixed(e.tip_rms_um) << " (max " << fixed(e.tip_max_um) << ") um\n";
}

void report_axis(std::ostringstream& r, const Calibration& c, int a) {
  const auto& id = c.axes[a];
  r << "\naxis " << axis(a) << ": " << (id.moving ? "" : "not moving; ") << id.refit_note << "\n";
  if (c.effort_kind[a] == "torque" && id.moving)
    r << "  torque column: fitted with the positions; held-out torque rms " << num(id.torque_rms_config) << " -> "
      << num(id.torque_rms_calibrated) << " N*m\n";
  for (const auto& d : id.declared)
    r << "  " << d.name << " [" << d.unit << "]: config " << num(d.config) << ", fitted " << num(d.fitted) << " +- " << num(d.sigma)
      << (d.held ? "  (held: " + d.why + ")" : d.why.empty() ? "" : "  (" + d.why + ")") << "\n";
  for (const auto& s : id.candidates) {
    r << "  round " << s.round << " " << s.effect << ": BIC " << fixed(s.criterion_before, 1) << " -> " << fixed(s.criterion_after, 1)
      << " (drop on the candidate's residual " << fixed(s.evidence, 1) << ")"
      << ", held-out rms " << fixed(std::sqrt(s.heldout_before) * 1000) << " -> " << fixed(std::sqrt(s.heldout_after) * 1000) << " um/mdeg; "
      << s.reason << ";";
    for (const auto& p : s.params) r << " " << p.name << " = " << num(p.value) << " +- " << num(p.sigma) << " " << p.unit;
    r << "\n";
  }
  if (c.nnoe[a])
    r << "  unidentified: NNOE " << c.nnoe[a]->structure.text() << " explains " << fixed(100 * c.nnoe[a]->explained_fraction, 1)
      << " % of the remaining held-out residual\n";
}

}  // namespace

namespace {

/// The lines a process engineer reads first (issue 29 item 8): per axis what was identified
/// against the config, the effects named, what was seen and not named, what could not be
/// identified and why, and the prediction error before and after.
void summary(std::ostringstream& r, const Calibration& c) {
  r << "SUMMARY\n";
  if (c.period > 0.01)
    r << "  samples every " << num(c.period * 1000) << " ms: a drive's loop (time constants of 5-30 ms), backlash reversals, delays of\n"
      << "  milliseconds and any periodic error shorter than 10 samples at the feed are not visible at this rate; what such a\n"
      << "  trace can show is slow: a scale or offset error, a gain on the velocity, friction from a current column.\n";
  for (int a = 0; a < kNumAxes; ++a) {
    const auto& id = c.axes[a];
    if (!id.moving) { r << "  " << axis(a) << ": does not move in the trace\n"; continue; }
    const bool rot = a == kA || a == kC;
    r << "  " << axis(a) << ": prediction error rms " << fixed(c.declared.rms_um[a], 2) << " -> " << fixed(c.calibrated.rms_um[a], 2)
      << (rot ? " um at 100 mm" : " um") << " (with the NNOE " << fixed(c.with_nnoe.rms_um[a], 2) << "), noise "
      << fixed((rot ? c.noise[a] * M_PI / 180 * kRotaryRadiusMm : c.noise[a]) * 1000, 2) << "\n";
    if (id.config.model != servo::DriveModel::kDrive) {
      r << "     ideal axis in the config: nothing is written for it" << (c.nnoe[a] ? " (an NNOE explains " + fixed(100 * c.nnoe[a]->explained_fraction, 1) + " % of its residual)" : "")
        << "; give it drives in the config to use what is found\n";
      continue;
    }
    std::string fitted, held;
    for (const auto& d : id.declared) {
      if (!d.held && d.fitted != d.config) fitted += "  " + d.name + " " + num(d.fitted) + " +- " + num(d.sigma) + " (config " + num(d.config) + ")";
      else if (d.held && d.why.find("feature off") == std::string::npos) held += (held.empty() ? "" : "; ") + d.name + ": " + d.why;
    }
    r << "     identified:" << (fitted.empty() ? " nothing (the configured drive stands)" : fitted) << "\n";
    if (id.base.structural_mismatch) r << "     STRUCTURAL MISMATCH: " << id.base.mismatch << "\n";
    if (id.named.empty()) r << "     effects named: none\n";
    for (const auto& n : id.named) {
      r << "     effect named: " << n.effect;
      for (const auto& p : n.params) r << " " << p.name << " " << num(p.value) << " +- " << num(p.sigma) << " " << p.unit;
      r << "\n";
    }
    for (const auto& s : id.candidates)
      if (s.reason.rfind("seen, not named", 0) == 0) r << "     " << s.effect << " " << s.reason << "\n";
    if (!held.empty()) r << "     kept at the config: " << held << "\n";
  }
  r << "\n";
}

}  // namespace

std::string report_text(const Calibration& c) {
  std::ostringstream r;
  summary(r, c);
  r << "gcpipe calibrate: " << c.rows << " rows at " << num(c.period) << " s";
  for (const auto& t : c.traces) r << ", " << t;
  r << "\nrows skipped (bad): " << c.rows_skipped << ", rows unused (outside the longest gap-free stretch): " << c.rows_unused
    << "\nfit on rows [" << c.begin << ", " << c.split << "), held out [" << c.split << ", " << c.rows << ")"
    << (c.begin > 1 ? " (the trace starts in motion: the first rows are a transient the replay from rest cannot know)" : "") << "\n"
    << "criterion: BIC on the fit rows with N_eff = N / correlation time; an effect is named when BIC drops by more than 10\n"
    << "and the held-out mean square falls by at least 2 % and its size exceeds 3 sigma.\n"
    << "noise estimate (um; A, C in um at " << kRotaryRadiusMm << " mm):";
  for (int a = 0; a < kNumAxes; ++a) r << " " << axis(a) << " " << fixed((a == kA || a == kC) ? c.noise[a] * M_PI / 180 * kRotaryRadiusMm * 1000 : c.noise[a] * 1000);
  r << "\n\nnamed effects:\n";
  int named = 0;
  for (int a = 0; a < kNumAxes; ++a)
    for (const auto& s : c.axes[a].named) {
      ++named;
      r << "  " << axis(a) << " " << s.effect << ":";
      for (const auto& p : s.params) r << " " << p.name << " = " << num(p.value) << " +- " << num(p.sigma) << " " << p.unit;
      r << "\n";
    }
  if (named == 0) r << "  none\n";
  r << "\nprediction error, rms (max) per axis over all rows, um (A, C at " << kRotaryRadiusMm << " mm):\n";
  report_errors(r, "declared  ", c.declared);
  report_errors(r, "refit     ", c.refit);
  report_errors(r, "calibrated", c.calibrated);
  report_errors(r, "+ NNOE    ", c.with_nnoe);
  for (int a = 0; a < kNumAxes; ++a) report_axis(r, c, a);
  return r.str();
}

void write_outputs(const Calibration& c, const compensate::Model& model, const std::string& config_path,
                   const std::string& outdir, bool plots) {
  const fs::path dir(outdir);
  fs::create_directories(dir);
  write_atomic(dir, "calibrated_drives.yaml", drives_yaml(c, model.drives));
  write_atomic(dir, "calibrated.yaml", pipeline_yaml(config_path, "calibrated_drives.yaml"));
  write_atomic(dir, "calibration.json", calibration_json(c));
  write_atomic(dir, "report.txt", report_text(c));
  if (plots) write_plots(c, outdir);
}

std::optional<std::string> mixed_periods(const std::vector<MeasuredTrace>& traces) {
  for (const auto& t : traces)
    if (std::abs(t.period - traces.front().period) > 1e-3 * traces.front().period)
      return t.file + ": period " + std::to_string(t.period) + " s differs from " + traces.front().file + " (" +
             std::to_string(traces.front().period) + " s); calibrate traces of one sampling period together";
  return std::nullopt;
}

bool read_options(const std::optional<std::string>& format, const std::vector<std::string>& columns, double period,
                  bool skip_bad_rows, ReadOptions& o, std::ostream& err) {
  o.skip_bad_rows = skip_bad_rows;
  o.columns = columns;
  o.period = period;
  if (!format) return true;
  o.format = parse_format(*format);
  if (!o.format) err << "unknown --format '" << *format << "' (use csv, umich, halsampler or shdr)\n";
  return o.format.has_value();
}

namespace {

bool read_all(const CalibrateRequest& q, std::vector<MeasuredTrace>& traces, std::ostream& err, bool& skipped) {
  ReadOptions o;
  if (!read_options(q.format, q.columns, q.period, q.skip_bad_rows, o, err)) return false;
  bool ok = true;
  for (const auto& path : q.traces) {
    ReadResult r = read_trace_file(path, o);
    for (std::size_t i = 0; i < r.diagnostics.size() && i < 20; ++i) err << format(r.diagnostics[i]) << "\n";
    if (r.diagnostics.size() > 20) err << path << ": " << r.diagnostics.size() - 20 << " more problems not shown\n";
    if (!r.trace) {
      err << path << ": trace rejected" << (q.skip_bad_rows ? "" : " (--skip-bad-rows uses the usable rest)") << "\n";
      ok = false;
      continue;
    }
    skipped = skipped || r.trace->rows_skipped > 0 || r.trace->rows_unused > 0;
    traces.push_back(std::move(*r.trace));
  }
  if (auto why = mixed_periods(traces)) {
    err << *why << "\n";
    ok = false;
  }
  return ok && !traces.empty();
}

}  // namespace

int run_calibrate(const CalibrateRequest& q, std::ostream& out, std::ostream& err) {
  if (q.traces.empty() || q.config.empty() || q.outdir.empty()) {
    err << "usage: gcpipe calibrate TRACE... --config CFG -o OUTDIR [--format csv|umich|halsampler|shdr] [--columns LIST] [--period S] [--skip-bad-rows]\n";
    return 2;
  }
  compensate::Model model;
  try {
    model = compensate::load_model(load_pipeline_config(q.config));
  } catch (const std::exception& e) {
    err << e.what() << "\n";
    return 1;
  }
  std::vector<MeasuredTrace> traces;
  bool skipped = false;
  if (!read_all(q, traces, err, skipped)) return 1;
  if (std::abs(traces.front().period - model.interp.period) > 1e-6)
    err << "note: the trace is sampled every " << traces.front().period << " s, the config's interpolation period is "
        << model.interp.period << " s; the drives are simulated at the trace's period\n";
  try {
    const Calibration c = calibrate_traces(traces, model);
    write_outputs(c, model, q.config, q.outdir, q.plots);
    out << report_text(c);
  } catch (const std::exception& e) {
    err << "gcpipe calibrate: " << e.what() << "\n";
    return 1;
  }
  return skipped ? 3 : 0;
}

}  // namespace gcpipe::calibrate
