// gcpipe batch: file in, files out; every stage, in-process, in pipeline order:
// parse -> trochoid -> ik -> interpolate -> servo -> compensate -> write -> plots.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>

#include "command.hpp"
#include "commands.hpp"
#include "compensate.hpp"
#include "circle.hpp"
#include "compensate_plots.hpp"
#include "compensate_program.hpp"
#include "gcpipe/config.hpp"
#include "gcpipe/number_format.hpp"
#include "ik.hpp"
#include "neural_ik.hpp"
#include "program_stream.hpp"
#include "report.hpp"
#include "trochoid.hpp"
#include "trochoid_report.hpp"
#include "write.hpp"

namespace gcpipe::cli {
namespace {

namespace fs = std::filesystem;

/// IK points kept for the figures: every `stride`-th, the stride doubling whenever the store
/// fills, so that a long program keeps an even sample in bounded memory.
struct IkSampler {
  compensate::IkSeries s;
  std::uint64_t seen = 0, stride = 1;
  static constexpr std::size_t kCap = 100000;
  void add(const IkPoint& p, const MachineKinematics& kin, double tool_length) {
    const std::uint64_t k = seen++;
    if (!p.has_neural) return;
    if ((p.flags & kIkNeuralDiverged) != 0) s.flagged.push_back(static_cast<double>(k));
    if (k % stride != 0) return;
    s.index.push_back(static_cast<double>(k));
    for (std::size_t i = 0; i < kNumAxes; ++i) s.diff[i].push_back(p.neural_joints[i] - p.joints[i]);
    auto tip_error = [&](const Axes& q) {
      const Vec3 t = forward_kinematics(kin, q, tool_length).tip;
      return std::sqrt((t[0] - p.pose.tip[0]) * (t[0] - p.pose.tip[0]) + (t[1] - p.pose.tip[1]) * (t[1] - p.pose.tip[1]) +
                       (t[2] - p.pose.tip[2]) * (t[2] - p.pose.tip[2]));
    };
    s.tip_error_analytic.push_back(tip_error(p.joints));
    s.tip_error_neural.push_back(tip_error(p.neural_joints));
    if (s.index.size() >= kCap) thin();
  }
  void thin() {
    auto half = [](std::vector<double>& v) {
      std::size_t j = 0;
      for (std::size_t i = 0; i < v.size(); i += 2) v[j++] = v[i];
      v.resize(j);
    };
    half(s.index);
    for (auto& d : s.diff) half(d);
    half(s.tip_error_analytic);
    half(s.tip_error_neural);
    stride *= 2;
  }
};

void ik_json(std::string& json, const IkSummary& s, bool neural, const Axes& tol) {
  json += "{\"points\":" + std::to_string(s.points) + ",\"ok\":" + std::to_string(s.ok) + ",\"degraded\":" +
          std::to_string(s.degraded) + ",\"failed\":" + std::to_string(s.failed) +
          ",\"first_failed_line\":" + std::to_string(s.first_failed_line) + ",\"flags\":{";
  bool first = true;
  for (int bit = 0; bit < 16; ++bit) {
    if (s.flag_counts[bit] == 0) continue;
    if (!first) json += ',';
    first = false;
    append_json_string(json, ik_flags_to_string(1u << bit));
    json += ":" + std::to_string(s.flag_counts[bit]);
  }
  json += "},\"neural\":";
  if (!neural) {
    json += "null}";
    return;
  }
  json += "{\"points\":" + std::to_string(s.neural_points) + ",\"units\":\"mm (X Y Z), deg (A C)\",\"tolerance\":[";
  for (int i = 0; i < kNumAxes; ++i) {
    if (i) json += ',';
    append_json_number(json, tol[static_cast<std::size_t>(i)]);
  }
  json += "],\"max_abs_diff\":[";
  for (int i = 0; i < kNumAxes; ++i) {
    if (i) json += ',';
    append_json_number(json, s.neural_max_abs_diff[static_cast<std::size_t>(i)]);
  }
  json += "],\"rms_diff\":[";
  for (int i = 0; i < kNumAxes; ++i) {
    if (i) json += ',';
    append_json_number(json, s.neural_points ? std::sqrt(s.neural_sum_sq_diff[static_cast<std::size_t>(i)] /
                                                         static_cast<double>(s.neural_points))
                                             : 0.0);
  }
  json += "]}}";
}

int run_batch(const std::vector<std::string>& argv) {
  std::string stop_reason;
  Args args(argv, {"--config", "-o"}, {"--strict", "--quiet", "--no-progress", "--no-simulate"});
  if (!args.ok()) return usage_error(kBatchCommand, args.error());
  if (args.positional().size() != 1) return usage_error(kBatchCommand, "give exactly one input program");
  if (!args.value("-o")) return usage_error(kBatchCommand, "give the output directory with -o OUTDIR");
  const fs::path outdir = *args.value("-o");
  PipelineConfig pc = load_config_option(args.value_or("--config", ""));
  ParseOptions po = load_parse_options(pc.root.section("parse"));
  WriteOptions wo = load_write_options(pc.root.section("write"));
  if (args.flag("--strict")) po.strict = true;
  const IkOptions ik_options = load_ik_options(pc.root.section("ik"));
  const std::optional<neural::NeuralIk> neural_model = load_ik_model(ik_options, pc.machine.name);
  // Simulation and compensation need the servo section; without it (or with --no-simulate) the
  // batch runs the streaming stages only, in memory independent of the program's length.
  const bool simulate = !args.flag("--no-simulate") && pc.root.has("servo");
  std::optional<compensate::Model> model;
  compensate::CompensateOptions co;
  if (simulate) {
    model = compensate::load_model(pc);
    co = compensate::load_compensate_options(pc.root.section("compensate"));
  }
  std::error_code ec;
  fs::create_directories(outdir / "plots", ec);
  if (ec) throw std::runtime_error(outdir.string() + ": cannot create output directory: " + ec.message());

  InputFile in(args.positional()[0]);
  const std::string base = fs::path(in.name()).filename().string();
  const auto t0 = std::chrono::steady_clock::now();
  const bool quiet = args.flag("--quiet");
  const bool progress = !args.flag("--no-progress") && !quiet && ::isatty(2);
  auto say = [&](const char* what) {
    if (progress) std::fprintf(stderr, "%s...\n", what);
  };
  Parser parser(po, pc.machine, in.name());
  const TrochoidExpander trochoid(load_trochoid_options(pc.root.section("trochoid")));
  IkStage ik(pc.machine.kinematics, ik_options, pc.machine.initial_position, neural_model ? &*neural_model : nullptr);
  IkSampler ik_plot;
  ik_plot.s.tolerance = ik_options.neural_tolerance;
  Writer writer(wo);
  OutputFile program((outdir / "output.nc").string());
  OutputFile diagnostics((outdir / "diagnostics.txt").string());
  std::string text, diag_text;
  std::uint64_t shown = 0, blocks_out = 0, cycles = 0, cycles_rejected = 0;
  auto report = [&](const Diagnostic& d) {
    writer.write_diagnostic(d, text);
    program.write(text);
    diag_text += format(d);
    diag_text += '\n';
    diagnostics.write(diag_text);
    if (d.severity == Severity::kError && !quiet && shown++ < 20) std::cerr << format(d) << "\n";
  };
  // The expanded cycles are kept for the engagement figure (only the cycles, not the program).
  std::vector<ResolvedBlock> expanded, figure_blocks;
  std::vector<TrochoidPart> parts, figure_parts;
  std::vector<std::vector<Point2>> outlines;
  double tool_diameter = 0;
  // The whole program is kept for the simulation (the learning iterations replay it).
  std::vector<ResolvedBlock> whole;
  std::string simulate_note = simulate ? "" : (args.flag("--no-simulate") ? "--no-simulate given" : "the config has no servo section");
  LineSink sink;
  sink.block = [&](const ResolvedBlock& b) {
    expanded.clear();
    parts.clear();
    Diagnostic d;
    const auto st = trochoid.step(b, in.name(), expanded, d, &parts);
    if (!st.ok()) {
      report(d);
      ++cycles_rejected;
    } else if (st.code == TrochoidExpander::Status::Code::kExpanded) {
      ++cycles;
      if (tool_diameter == 0) tool_diameter = b.slot.tool_diameter;
      outlines.push_back(slot_outline(b.slot));
      figure_blocks.insert(figure_blocks.end(), expanded.begin(), expanded.end());
      figure_parts.insert(figure_parts.end(), parts.begin(), parts.end());
    }
    for (const auto& e : expanded) {
      writer.write(e, text);
      IkPoint p;
      if (ik.step(e, p)) ik_plot.add(p, pc.machine.kinematics, e.tool_length_active ? e.tool_length : pc.machine.kinematics.tool_length);
    }
    if (simulate && simulate_note.empty()) {
      if (whole.size() + expanded.size() > co.max_blocks) {
        simulate_note = "the program has more than compensate.max_blocks = " + std::to_string(co.max_blocks) + " blocks";
        whole.clear();
        whole.shrink_to_fit();
      } else {
        whole.insert(whole.end(), expanded.begin(), expanded.end());
      }
    }
    blocks_out += expanded.size();
    program.write(text);
    if (!st.ok() && po.strict) {
      stop_reason = "stopped at the first error (parse.strict is on)";
      return false;
    }
    return true;
  };
  sink.diagnostic = [&](const Diagnostic& d) {
    report(d);
    return true;
  };
  std::string error;
  const bool complete = stream_program(in, parser, sink, progress, error);
  if (error.empty()) error = stop_reason;
  program.write(text, true);
  program.close();
  diagnostics.write(diag_text, true);
  diagnostics.close();
  std::vector<std::string> plots;
  double max_engagement = 0, max_ae = 0;
  if (cycles > 0) {
    say("drawing the trochoid engagement figure");
    PathAnalysisOptions ao;
    ao.tool_radius = 0.5 * tool_diameter;
    const PathAnalysis a = analyse_path(figure_blocks, &figure_parts, ao);
    max_engagement = a.max_angle * 180 / 3.14159265358979323846;
    max_ae = equivalent_ae(a.max_angle, ao.tool_radius);
    char title[200];
    std::snprintf(title, sizeof title, "%s: G275 tool centre path, D%g mm", base.c_str(), tool_diameter);
    write_engagement_png(outdir / "plots" / "trochoid_engagement.png", a, ao.tool_radius, title, outlines);
    plots.push_back("plots/trochoid_engagement.png");
  }
  if (neural_model && !ik_plot.s.index.empty()) {
    say("drawing the IK figures");
    compensate::plot_ik_divergence(outdir / "plots" / "ik_divergence.png", ik_plot.s,
                                   base + ": neural against analytic IK, per axis");
    compensate::plot_ik_tip_error(outdir / "plots" / "ik_tip_error.png", ik_plot.s,
                                  base + ": tool-tip error of each IK solver");
    plots.push_back("plots/ik_divergence.png");
    plots.push_back("plots/ik_tip_error.png");
  }

  // Simulation, compensation, the compensated program and its own simulation.
  std::optional<compensate::Nominal> nominal;
  std::optional<compensate::Evaluation> before, after;
  std::optional<compensate::Result> result;
  compensate::ReportInput rin;
  bool compensated_written = false;
  std::uint64_t written_nodes = 0;
  if (simulate && simulate_note.empty() && complete) {
    compensate::Progress prog;
    if (progress)
      prog = [](const char* what, std::uint64_t done, std::uint64_t total) {
        std::fprintf(stderr, "\r%s: %llu/%llu", what, static_cast<unsigned long long>(done), static_cast<unsigned long long>(total));
        if (done == total) std::fprintf(stderr, "\n");
      };
    compensate::ProgramCompensation run = compensate::compensate_program(*model, co, wo, whole, prog);
    if (progress) std::fprintf(stderr, "\n");
    nominal = std::move(run.nominal);
    before = std::move(run.before);
    result = std::move(run.result);
    if (!before || !result || !result->compensated) simulate_note = run.note;
    if (!run.text.empty()) {
      {
        OutputFile cf((outdir / "compensated.nc").string());
        cf.write(run.text, true);
        cf.close();
      }
      // Read the written program back with the parser and simulate what was written: the
      // "after" figures are those of the file, rounding included.
      say("re-reading and simulating compensated.nc");
      ParseOptions rpo = po;
      rpo.strict = true;
      rpo.dialect = wo.dialect;
      rpo.decimal_point_increments = false;
      Parser reparse(rpo, pc.machine, (outdir / "compensated.nc").string());
      std::vector<ResolvedBlock> back;
      InputFile cin((outdir / "compensated.nc").string());
      LineSink rs;
      std::string rerr;
      std::uint64_t rejected = 0;
      rs.block = [&](const ResolvedBlock& b) {
        if (b.motion != Motion::kNone) back.push_back(b);
        return true;
      };
      rs.diagnostic = [&](const Diagnostic& d) {
        ++rejected;
        std::cerr << format(d) << "\n";
        return false;
      };
      const bool reread = stream_program(cin, reparse, rs, false, rerr);
      written_nodes = back.size();
      if (!reread || rejected > 0 || back.size() + 1 != result->nodes.size()) {
        throw std::runtime_error("compensated.nc does not read back as written (" + std::to_string(back.size()) +
                                 " motion blocks for " + std::to_string(result->nodes.size() - 1) + " points): " + rerr);
      }
      const auto& nodes = result->nodes;
      after = compensate::evaluate(*model, *nominal, whole, back, run.start,
                                   [&nodes](std::uint32_t i) { return nodes[std::min<std::size_t>(i + 1, nodes.size() - 1)].block; },
                                   {}, true);
      compensated_written = true;
    }
  }
  if (before) {
    say("drawing the error figures");
    rin.model = &*model;
    rin.nominal = &*nominal;
    rin.before = &*before;
    rin.after = after ? &*after : nullptr;
    rin.result = result ? &*result : nullptr;
    // Seed 002 eq. (20) is about synchronising X/Y with a turning C: computed at the program's
    // fastest C speed when C turns and X, Y and C have drive models.
    const double omega = nominal->stats.interp.peak_velocity[kC] * 3.14159265358979323846 / 180.0;
    const auto& d = model->drives.axes;
    if (!(omega > 1e-6)) {
      rin.best_kffp_note = "no recommendation: C does not turn in this program";
    } else if (d[kX].model != servo::DriveModel::kDrive || d[kY].model != servo::DriveModel::kDrive ||
               d[kC].model != servo::DriveModel::kDrive) {
      rin.best_kffp_note = "no recommendation: X, Y and C need drive models in the drives file";
    } else {
      rin.best_kffp = servo::best_kffp(model->drives, model->interp.smoothing, model->interp.period, omega, 2.0, 1.0);
      rin.best_kffp_omega = omega;
      // And per segment (a circle-test condition each): at that segment's C speed.
      std::vector<double> seg_omega(nominal->segments.size(), 0.0);
      const double T = model->interp.period;
      for (std::size_t n = 1; n < nominal->raw.size(); ++n) {
        const std::size_t g = nominal->segment_of_block[nominal->block[n]];
        if (g < seg_omega.size())
          seg_omega[g] = std::max(seg_omega[g], std::abs(nominal->raw[n][kC] - nominal->raw[n - 1][kC]) / T * 3.14159265358979323846 / 180.0);
      }
      for (std::size_t g = 0; g < seg_omega.size(); ++g)
        if (seg_omega[g] > 1e-6 && nominal->segments[g].circle)
          rin.segment_kffp.push_back({g, {seg_omega[g], servo::best_kffp(model->drives, model->interp.smoothing, T, seg_omega[g], 2.0, 1.0)}});
    }
    plot_toolpath(outdir / "plots" / "toolpath.png", *before, rin.after, base + ": tool path");
    plots.push_back("plots/toolpath.png");
    if (plot_ballbar(outdir / "plots" / "ballbar.png", *nominal, *before, rin.after, base)) plots.push_back("plots/ballbar.png");
    plot_contour_error(outdir / "plots" / "contour_error.png", *before, rin.after, base + ": contour error, before and after compensation");
    plots.push_back("plots/contour_error.png");
    plot_following_error(outdir / "plots" / "following_error.png", *before, rin.after, base);
    plots.push_back("plots/following_error.png");
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  const ParseSummary& s = parser.summary();
  std::string stages = "\"parse\",\"trochoid\",\"ik\"";
  if (before) stages += ",\"interpolate\",\"servo\"";
  if (compensated_written) stages += ",\"compensate\"";
  stages += ",\"write\",\"plots\"";
  std::string json = "{\"input\":";
  append_json_string(json, in.name());
  json += ",\"config\":";
  append_json_string(json, pc.root.file());
  json += ",\"machine\":";
  append_json_string(json, pc.machine.name);
  json += ",\"stages\":[" + stages + "],\"complete\":";
  json += complete ? "true" : "false";
  json += ",\"trochoid\":{\"cycles_expanded\":" + std::to_string(cycles) + ",\"cycles_rejected\":" +
          std::to_string(cycles_rejected) + ",\"max_engagement_deg\":";
  append_json_number(json, max_engagement);
  json += ",\"max_ae_mm\":";
  append_json_number(json, max_ae);
  json += "},\"ik\":";
  ik_json(json, ik.summary(), neural_model.has_value(), ik_options.neural_tolerance);
  json += ",\"blocks_written\":" + std::to_string(blocks_out);
  json += ",\"lines_read\":" + std::to_string(s.lines_read) + ",\"blocks_emitted\":" +
          std::to_string(s.blocks_emitted) + ",\"lines_rejected\":" + std::to_string(s.lines_rejected) +
          ",\"lines_deleted\":" + std::to_string(s.lines_deleted) + ",\"bytes_read\":" + std::to_string(s.bytes_read);
  std::string summary_json = json + ",\"seconds\":";
  append_json_number(summary_json, seconds);
  summary_json += "}\n";
  {
    OutputFile summary((outdir / "summary.json").string());
    summary.write(summary_json, true);
    summary.close();
  }
  // report.json: the summary plus the simulation and compensation figures and the file list.
  json += ",\"simulation\":";
  if (before) {
    json += compensate::report_json(rin);
  } else {
    json += "{\"skipped\":";
    append_json_string(json, simulate_note);
    json += "}";
  }
  json += ",\"outputs\":[\"output.nc\",\"summary.json\",\"diagnostics.txt\",\"report.json\",\"report.txt\"";
  if (compensated_written) json += ",\"compensated.nc\"";
  for (const auto& p : plots) {
    json += ',';
    append_json_string(json, p);
  }
  json += "],\"seconds\":";
  append_json_number(json, seconds);
  json += "}\n";
  {
    OutputFile rj((outdir / "report.json").string());
    rj.write(json, true);
    rj.close();
  }

  std::string txt;
  char buf[512];
  std::snprintf(buf, sizeof buf, "gcpipe batch: %s -> %s\n", in.name().c_str(), outdir.string().c_str());
  txt += buf;
  std::string chain = "parse -> trochoid -> ik";
  if (before) chain += " -> interpolate -> servo";
  if (compensated_written) chain += " -> compensate";
  chain += " -> write -> plots";
  txt += "  stages:   " + chain + "\n";
  std::snprintf(buf, sizeof buf, "  lines:    %llu read = %llu emitted + %llu rejected + %llu skipped (block delete)\n",
                static_cast<unsigned long long>(s.lines_read), static_cast<unsigned long long>(s.blocks_emitted),
                static_cast<unsigned long long>(s.lines_rejected), static_cast<unsigned long long>(s.lines_deleted));
  txt += buf;
  if (cycles + cycles_rejected > 0) {
    std::snprintf(buf, sizeof buf, "  trochoid: %llu G275 cycles expanded, %llu rejected; max radial engagement %.1f deg (ae %.3f mm)\n",
                  static_cast<unsigned long long>(cycles), static_cast<unsigned long long>(cycles_rejected), max_engagement, max_ae);
    txt += buf;
  }
  {
    std::string ik_text = format_summary(ik.summary(), neural_model.has_value());
    std::string indented = "  ik:       ";
    for (char c : ik_text) {
      indented += c;
      if (c == '\n') indented += "            ";
    }
    txt += indented + "\n";
  }
  if (before) {
    std::snprintf(buf, sizeof buf, "  simulate: %.3f s of machine time at %.4g s\n",
                  static_cast<double>(nominal->raw.size() - 1) * model->interp.period, model->interp.period);
    txt += buf;
    txt += compensate::report_text(rin);
    if (compensated_written) {
      std::snprintf(buf, sizeof buf, "  compensated.nc: %llu timed points (G93, machine axes), read back and simulated for the 'after' figures\n",
                    static_cast<unsigned long long>(written_nodes));
      txt += buf;
    }
  } else if (!simulate_note.empty()) {
    txt += "  simulate: skipped (" + simulate_note + ")\n";
  }
  std::snprintf(buf, sizeof buf, "  written:  %llu blocks to output.nc\n", static_cast<unsigned long long>(blocks_out));
  txt += buf;
  txt += "  output:   output.nc, report.json, report.txt, summary.json, diagnostics.txt";
  if (compensated_written) txt += ", compensated.nc";
  txt += "\n";
  for (const auto& p : plots) txt += "            " + p + "\n";
  std::snprintf(buf, sizeof buf, "  time:     %.3f s\n", seconds);
  txt += buf;
  {
    OutputFile rt((outdir / "report.txt").string());
    std::string copy = txt;
    rt.write(copy, true);
    rt.close();
  }
  if (!quiet) {
    if (shown > 20) std::cerr << "... " << (shown - 20) << " more in " << (outdir / "diagnostics.txt").string() << "\n";
    std::fputs(txt.c_str(), stdout);
  }
  if (!complete) {
    std::cerr << "gcpipe batch: " << error << "\n";
    return 1;
  }
  return s.lines_rejected + cycles_rejected > 0 ? 3 : 0;
}

}  // namespace

constinit const Command kBatchCommand{
    "batch", "run the whole pipeline on a program: file in, files out",
    "Usage: gcpipe batch IN.nc -o OUTDIR [--config CFG] [--strict] [--quiet] [--no-simulate]\n"
    "\n"
    "Runs every stage in-process, in pipeline order:\n"
    "parse -> trochoid -> ik -> interpolate -> servo -> compensate -> write -> plots, and writes\n"
    "  OUTDIR/compensated.nc   the program in machine axes (G93 timed points) whose simulated\n"
    "                          motion follows the nominal path; N = source line, M/S/T words and\n"
    "                          comments kept, each source motion line noted\n"
    "  OUTDIR/report.json      contour error before/after (whole program and per segment between\n"
    "                          dwells), per-axis following error, travel margins, IK divergence,\n"
    "                          learning iterations, Best K_FFP (seed 002 eq. 20); report.txt: readable\n"
    "  OUTDIR/plots/*.png      toolpath, contour_error, following_error, ballbar (circles),\n"
    "                          ik_divergence and ik_tip_error (neural model configured),\n"
    "                          trochoid_engagement (G275 cycles)\n"
    "  OUTDIR/output.nc        the program as parsed and expanded (N = source line); byte-identical\n"
    "                          to the DDS pipeline feed -> node parse -> node trochoid -> node write -> sink\n"
    "  OUTDIR/summary.json     counts: lines read = emitted + rejected + skipped; cycles; IK\n"
    "  OUTDIR/diagnostics.txt  every rejected or skipped line as file:line:col: reason\n"
    "\n"
    "  --config CFG     pipeline config (default pipeline_configs/default.yaml); simulation and\n"
    "                   compensation need its servo section, the neural IK its ik.model\n"
    "  --strict         stop at the first error (default: reject the line and go on)\n"
    "  --no-simulate    streaming stages only (parse, trochoid, ik, write): memory independent of\n"
    "                   the program's length; the simulation keeps the program in memory\n"
    "  --quiet          print nothing but errors that stop the run\n"
    "Exit status: 0 all lines accepted, 3 some lines rejected, 1 stopped, 2 usage.\n",
    run_batch};

}  // namespace gcpipe::cli
