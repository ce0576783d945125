// gcpipe calibrate and gcpipe evaluate: measured traces against the model (stages/calibrate).
#include <iostream>

#include "calibrate.hpp"
#include "commands.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "output_dir.hpp"

namespace gcpipe::cli {

int run_calibrate(const CalibrateArgs& a) {
  pipeline::install_stop_handlers();
  calibrate::CalibrateRequest q;
  q.traces = a.traces;
  q.config = a.config.empty() ? default_pipeline_config().string() : a.config;
  q.outdir = a.outdir;
  if (!a.format.empty()) q.format = a.format;
  q.columns = a.columns;
  q.period = a.period;
  q.skip_bad_rows = a.skip_bad_rows;
  q.plots = !a.no_plots;
  return calibrate::run_calibrate(q, std::cout, std::cerr);
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
  return calibrate::run_evaluate(q, std::cout, std::cerr);
}

}  // namespace gcpipe::cli
