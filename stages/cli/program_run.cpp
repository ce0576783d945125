#include "program_run.hpp"

#include <unistd.h>

#include <algorithm>

#include "output_dir.hpp"
#include "parse.hpp"

namespace gcpipe::cli {

void PrintedLog::report(const Diagnostic& d) {
  if (d.severity == Severity::kError) ++errors_;
  if (file_) {
    kept_ += format(d);
    kept_ += '\n';
    file_->write(kept_);
  }
  // Errors are shown; warnings go to diagnostics.txt only, except the one a model known to
  // predict badly raises (calibrated drives): a user compensating with it must see it.
  const bool shown = d.severity == Severity::kError || d.message.rfind("calibrated drives:", 0) == 0;
  if (quiet_ || !shown) return;
  if (shown_max_ == 0 || shown_++ < shown_max_) std::fprintf(stderr, "%s\n", format(d).c_str());
  else ++not_shown_;
}

std::vector<std::string> chains(const std::vector<std::string>& last_stages) {
  std::vector<std::string> names;
  for (const auto& last : last_stages)
    for (const auto& n : pipeline::chain_to(last))
      if (std::find(names.begin(), names.end(), n) == names.end()) names.push_back(n);
  return names;
}

namespace {

bool show_progress(const ProgramArgs& a) {
  if (a.no_progress) return false;
  return a.progress || ::isatty(2);
}

}  // namespace

ProgramRun::ProgramRun(const ProgramArgs& args, const std::vector<std::string>& last_stages,
                       pipeline::DiagnosticLog& log, const pipeline::StageContext& overrides)
    : ProgramRun(args, [&last_stages](const PipelineConfig&) { return last_stages; }, log, overrides) {}

ProgramRun::ProgramRun(const ProgramArgs& args,
                       const std::function<std::vector<std::string>(const PipelineConfig&)>& last_stages,
                       pipeline::DiagnosticLog& log, const pipeline::StageContext& overrides)
    : config_(load_config_option(args.config, args.tool_table)), input_(args.input), progress_(show_progress(args)) {
  pipeline::StageContext c = overrides;
  c.config = &config_;
  c.file = input_.name();
  c.log = &log;
  c.strict = args.strict || load_parse_options(config_.root.section("parse")).strict;
  const bool shown = progress_;
  if (!c.progress)
    c.progress = [shown](const char* what, std::uint64_t done, std::uint64_t total) {
      if (!shown) {
      } else if (total == 0) std::fprintf(stderr, "%s...\n", what);
      else std::fprintf(stderr, "\r%s: %llu/%llu%s", what, static_cast<unsigned long long>(done),
                        static_cast<unsigned long long>(total), done == total ? "\n" : "");
      // Long steps poll for Ctrl-C here: no output file gets its final name after a stop.
      if (pipeline::stop_requested()) throw std::runtime_error("interrupted");
    };
  pipeline_ = std::make_unique<pipeline::Pipeline>(chains(last_stages(config_)), c);
}

bool ProgramRun::run() {
  const std::size_t max_line = load_parse_options(config_.root.section("parse")).max_line_length;
  bool complete = pipeline::run_lines(*pipeline_, input_.fd(), input_.name(), input_.size(), max_line, progress_, error_);
  pipeline_->finish(complete);
  return complete;
}

int exit_status(bool complete, const std::string& failure, std::uint64_t rejected) {
  if (pipeline::stop_requested()) return 128 + pipeline::stop_signal();
  if (!complete || !failure.empty()) return 1;
  return rejected > 0 ? 3 : 0;
}

}  // namespace gcpipe::cli
