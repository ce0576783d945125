// gcpipe batch: file in, files out; every registered stage in-process, in pipeline order.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "output_dir.hpp"
#include "program_run.hpp"
#include "run_report.hpp"

namespace gcpipe::cli {

namespace {

namespace fs = std::filesystem;

// Simulation and compensation need the config's servo section; without it (or with
// --no-simulate) the batch runs the streaming stages only, in memory independent of the length.
std::string simulation_skipped(const BatchArgs& a, const PipelineConfig& pc) {
  if (a.no_simulate) return "--no-simulate given";
  if (!pc.root.has("servo")) return "the config has no servo section";
  return {};
}

struct Outcome {
  bool complete = false;
  std::string failure;
  std::uint64_t rejected = 0;
};

// report.json, report.txt and summary.json: the stages' parts in the run's frame (run_report.hpp).
void write_reports(ProgramRun& run, const BatchArgs& a, const Outcome& o, double seconds) {
  const fs::path outdir = a.outdir;
  const std::vector<std::string> stages = run.pipeline().names();
  pipeline::RunReport r;
  r.json = pipeline::report_head(run.input_name(), run.config().root.file(), run.config().machine.name, stages, o.complete);
  r.text = pipeline::report_text_head("gcpipe batch", run.input_name(), outdir, stages);
  r.files = pipeline::report_files();
  const std::string base = fs::path(run.input_name()).filename().string();
  run.pipeline().report(r.json, r.text, outdir, base, r.files, {});
  r.simulation_skipped = simulation_skipped(a, run.config());
  r.failure = o.failure;
  r.compensated = fs::exists(outdir / "compensated.nc.part") || fs::exists(outdir / "compensated.nc");
  const std::string text = pipeline::write_run_report(std::move(r), outdir, seconds);
  if (!a.quiet) std::fputs(text.c_str(), stdout);
}

// A run that could not start (a bad config, a missing input, an output it cannot open) still
// leaves summary.json with its `failure`: the folder was emptied of the earlier run's results, and
// a script reading it must learn why there is nothing, not find nothing.
void write_failure_summary(const BatchArgs& a, const std::string& why) {
  nlohmann::ordered_json s;
  s["input"] = a.input;
  s["config"] = a.config.empty() ? default_pipeline_config().string() : a.config;
  s["complete"] = false;
  s["failure"] = why;
  pipeline::write_file_atomically(fs::path(a.outdir) / "summary.json", s.dump() + "\n");
}

int run_batch_in_prepared_folder(const BatchArgs& a);

}  // namespace

int run_batch(const BatchArgs& a) {
  pipeline::install_stop_handlers();
  pipeline::prepare_output_dir(a.outdir, pipeline::run_outputs());
  try {
    return run_batch_in_prepared_folder(a);
  } catch (const std::exception& e) {
    if (!pipeline::stop_requested()) write_failure_summary(a, e.what());
    throw;  // main prints it and exits 1 (128 + signal after a stop)
  }
}

namespace {

int run_batch_in_prepared_folder(const BatchArgs& a) {
  const fs::path outdir = a.outdir;
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
  // A compensate stage that failed (its read-back checks among others) keeps no compensated.nc.
  if (compensated && compensated->written() && run.pipeline().stage("compensate")->failure().empty()) compensated->commit();
  write_reports(run, a, o, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  if (!a.quiet && log.not_shown() > 0)
    std::cerr << "... " << log.not_shown() << " more in " << (outdir / "diagnostics.txt").string() << "\n";
  if (!o.complete) std::cerr << "gcpipe batch: " << run.error() << "\n";
  else if (!o.failure.empty()) std::cerr << "gcpipe batch: " << o.failure << "\n";
  return exit_status(o.complete, o.failure, o.rejected);
}

}  // namespace

}  // namespace gcpipe::cli
