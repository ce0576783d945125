// gcpipe calibrate and gcpipe evaluate: measured traces against the model (stages/calibrate).
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "calibrate.hpp"
#include "calibrate_stage.hpp"
#include "pipeline.hpp"
#include "program_run.hpp"
#include "commands.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "output_dir.hpp"

namespace gcpipe::cli {

namespace {

/// Every trace file through the pipeline's calibrate stage, one after the other. False when a
/// read stopped (the reason on stderr).
bool feed_traces(pipeline::Pipeline& p, calibrate::CalibrateStage& stage, const std::vector<std::string>& traces) {
  for (const auto& path : traces) {
    InputFile input(path);
    stage.begin_trace(input.name());
    std::string error;
    // Trace rows are short; a row longer than this is cut and then fails the reader's checks.
    constexpr std::size_t kMaxRow = 1 << 16;
    if (!pipeline::run_lines(p, input.fd(), input.name(), input.size(), kMaxRow, false, error)) {
      std::cerr << "gcpipe calibrate: " << error << "\n";
      return false;
    }
  }
  return true;
}

}  // namespace

// `gcpipe calibrate` runs the registered calibrate stage through the pipeline runner, as every
// other command runs its chain: the traces' lines in, the stage's report writes OUTDIR.
int run_calibrate(const CalibrateArgs& a) {
  pipeline::install_stop_handlers();
  calibrate::ReadOptions read;
  if (!calibrate::read_options(a.format.empty() ? std::nullopt : std::optional(a.format), a.columns, a.period,
                               a.skip_bad_rows, read, std::cerr))
    return 2;
  const PipelineConfig config = load_config_option(a.config);
  PrintedLog log(20);
  pipeline::StageContext context;
  context.config = &config;
  context.file = a.traces.front();
  context.log = &log;
  context.progress = make_progress(show_progress(a.progress, a.no_progress));
  pipeline::Pipeline p(pipeline::chain_to("calibrate"), context);
  auto& stage = dynamic_cast<calibrate::CalibrateStage&>(*p.stage("calibrate"));
  stage.set_read_options(read);
  stage.set_plots(!a.no_plots);
  const bool complete = feed_traces(p, stage, a.traces);
  p.finish(complete);
  // Ctrl-C or SIGTERM during the identification (its progress polls for them): no outputs.
  if (pipeline::stop_requested()) return 128 + pipeline::stop_signal();
  nlohmann::ordered_json report;
  std::string text;
  std::vector<std::string> files;
  if (stage.calibration() != nullptr) std::filesystem::create_directories(a.outdir);
  p.report(report, text, a.outdir, std::filesystem::path(a.traces.front()).filename().string(), files, {});
  std::cout << text;
  if (log.not_shown() > 0) std::cerr << log.not_shown() << " more problems not shown\n";
  if (!p.failure().empty()) std::cerr << "gcpipe " << p.failure() << "\n";
  return exit_status(complete, p.failure(), p.rejected());
}

int run_evaluate(const EvaluateArgs& a) {
  calibrate::EvaluateRequest q;
  q.trace = a.trace;
  q.program = a.program;
  q.config = a.config.empty() ? default_pipeline_config().string() : a.config;
  if (!a.format.empty()) q.format = a.format;
  q.columns = a.columns;
  q.period = a.period;
  q.skip_bad_rows = a.skip_bad_rows;
  if (!a.json.empty()) q.json = a.json;
  if (!a.ran.empty()) q.ran = a.ran;
  return calibrate::run_evaluate(q, std::cout, std::cerr);
}

}  // namespace gcpipe::cli
