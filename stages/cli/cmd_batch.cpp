// gcpipe batch: file in, files out; every registered stage in-process, in pipeline order.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "output_dir.hpp"
#include "program_run.hpp"

namespace gcpipe::cli {

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;

// Every file a batch run may write: an earlier run's are removed before this one starts.
const std::vector<std::string> kOutputs = {
    "output.nc", "compensated.nc", "report.json", "report.txt", "summary.json", "diagnostics.txt",
    "plots/toolpath.png", "plots/ballbar.png", "plots/contour_error.png", "plots/following_error.png",
    "plots/ik_divergence.png", "plots/ik_tip_error.png", "plots/trochoid_engagement.png",
    "plots/force_path.png", "plots/force_time.png", "plots/error_budget.png"};

// Simulation and compensation need the config's servo section; without it (or with
// --no-simulate) the batch runs the streaming stages only, in memory independent of the length.
std::string simulation_skipped(const BatchArgs& a, const PipelineConfig& pc) {
  if (a.no_simulate) return "--no-simulate given";
  if (!pc.root.has("servo")) return "the config has no servo section";
  return {};
}

Json report_head(const ProgramRun& run, const std::vector<std::string>& stages, bool complete) {
  Json j;
  j["input"] = run.input_name();
  j["config"] = run.config().root.file();
  j["machine"] = run.config().machine.name;
  j["stages"] = stages;
  j["complete"] = complete;
  return j;
}

std::string report_text_head(const ProgramRun& run, const fs::path& outdir, const std::vector<std::string>& stages) {
  std::string chain;
  for (const auto& s : stages) chain += (chain.empty() ? "" : " -> ") + s;
  return "gcpipe batch: " + run.input_name() + " -> " + outdir.string() + "\n  stages:   " + chain + "\n";
}

struct Outcome {
  bool complete = false;
  std::string failure;
  std::uint64_t rejected = 0;
};

// report.json, report.txt and summary.json (the report without the simulation and the file list).
void write_reports(ProgramRun& run, const BatchArgs& a, const Outcome& o, double seconds) {
  const fs::path outdir = a.outdir;
  const std::vector<std::string> stages = run.pipeline().names();
  Json report = report_head(run, stages, o.complete);
  std::string text = report_text_head(run, outdir, stages);
  std::vector<std::string> files = {"output.nc", "summary.json", "diagnostics.txt", "report.json", "report.txt"};
  const std::string base = fs::path(run.input_name()).filename().string();
  run.pipeline().report(report, text, outdir, base, files, {});
  const std::string skipped = simulation_skipped(a, run.config());
  if (!skipped.empty()) {
    report["simulation"] = {{"skipped", skipped}};
    text += "  simulate: skipped (" + skipped + ")\n";
  }
  if (!o.failure.empty()) report["failure"] = o.failure;
  if (fs::exists(outdir / "compensated.nc.part") || fs::exists(outdir / "compensated.nc"))
    files.insert(files.begin() + 5, "compensated.nc");
  Json summary = report;
  summary.erase("simulation");
  summary["seconds"] = seconds;
  report["outputs"] = files;
  report["seconds"] = seconds;
  text += "  output:   ";
  for (std::size_t i = 0; i < files.size(); ++i) text += (i == 0 ? "" : i < 6 ? ", " : "\n            ") + files[i];
  char buf[64];
  std::snprintf(buf, sizeof buf, "\n  time:     %.3f s\n", seconds);
  text += buf;
  if (!o.failure.empty()) text += "  failure:  " + o.failure + "\n";
  pipeline::write_file_atomically(outdir / "summary.json", summary.dump() + "\n");
  pipeline::write_file_atomically(outdir / "report.json", report.dump() + "\n");
  pipeline::write_file_atomically(outdir / "report.txt", text);
  if (!a.quiet) std::fputs(text.c_str(), stdout);
}

}  // namespace

int run_batch(const BatchArgs& a) {
  pipeline::install_stop_handlers();
  const fs::path outdir = a.outdir;
  pipeline::prepare_output_dir(outdir, kOutputs);
  const auto t0 = std::chrono::steady_clock::now();
  pipeline::AtomicFile diagnostics((outdir / "diagnostics.txt").string());
  PrintedLog log(20, &diagnostics, a.quiet);
  ProgramRun run(a, [&a](const PipelineConfig& pc) {
    return simulation_skipped(a, pc).empty() ? std::vector<std::string>{"write", "compensate"}
                                             : std::vector<std::string>{"write", "ik"};
  }, log);
  TextFileSink output((outdir / "output.nc").string());
  run.pipeline().attach("write", output);
  std::unique_ptr<TextFileSink> compensated;
  if (run.pipeline().stage("compensate") != nullptr) {
    compensated = std::make_unique<TextFileSink>((outdir / "compensated.nc").string());
    run.pipeline().attach("compensate", *compensated);
  }
  Outcome o;
  o.complete = run.run();
  o.failure = run.pipeline().failure();
  o.rejected = run.pipeline().rejected();
  if (pipeline::stop_requested()) return exit_status(o.complete, o.failure, o.rejected);  // nothing gets its final name
  log.flush();
  diagnostics.commit();
  output.commit();
  if (compensated && compensated->written()) compensated->commit();
  write_reports(run, a, o, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  if (!a.quiet && log.not_shown() > 0)
    std::cerr << "... " << log.not_shown() << " more in " << (outdir / "diagnostics.txt").string() << "\n";
  if (!o.complete) std::cerr << "gcpipe batch: " << run.error() << "\n";
  else if (!o.failure.empty()) std::cerr << "gcpipe batch: " << o.failure << "\n";
  return exit_status(o.complete, o.failure, o.rejected);
}

}  // namespace gcpipe::cli
