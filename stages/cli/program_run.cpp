#include "program_run.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>

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

bool show_progress(const ProgramArgs& a) { return gcpipe::cli::show_progress(a.progress, a.no_progress); }

/// One line per step: percent, elapsed and remaining time. On a terminal the line is redrawn in
/// place (at most 5 times a second); otherwise a plain line at every tenth and at the end, so
/// that a log shows the run without thousands of carriage returns.
class ProgressPrinter {
 public:
  explicit ProgressPrinter(bool terminal) : terminal_(terminal) {}

  void update(const char* what, std::uint64_t done, std::uint64_t total) {
    using Clock = std::chrono::steady_clock;
    const auto now = Clock::now();
    if (what != step_) {
      finish_step(now);
      step_ = what;
      start_ = now;
      last_ = Clock::time_point{};
      tenth_ = -1;
      open_ = false;
    }
    if (total == 0) {
      std::fprintf(stderr, "%s...\n", what);
      return;
    }
    open_ = done < total;
    const bool end = done >= total;
    const int tenth = static_cast<int>(10 * done / total);
    const bool due = terminal_ ? now - last_ >= std::chrono::milliseconds(200) : tenth != tenth_;
    if (!end && !due) return;
    last_ = now;
    tenth_ = tenth;
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    std::string left;
    if (!end && done > 0 && elapsed > 1.0)
      left = ", about " + seconds(elapsed * static_cast<double>(total - done) / static_cast<double>(done)) + " left";
    std::fprintf(stderr, "%s%s: %3.0f %% (%llu/%llu), %s%s%s", terminal_ ? "\r" : "", what,
                 100.0 * static_cast<double>(done) / static_cast<double>(total), static_cast<unsigned long long>(done),
                 static_cast<unsigned long long>(total), seconds(elapsed).c_str(), left.c_str(),
                 terminal_ && !end ? "\x1b[K" : "\n");
    if (terminal_ && end) std::fflush(stderr);
  }

  ~ProgressPrinter() { finish_step(std::chrono::steady_clock::now()); }

 private:
  // A step that stopped reporting before its last count (the next step began, or the run
  // ended): its line is closed with its time, so no step is left at "0 %".
  void finish_step(std::chrono::steady_clock::time_point now) {
    if (!open_) return;
    open_ = false;
    std::fprintf(stderr, "%s%s: done, %s\n", terminal_ ? "\r\x1b[K" : "", step_.c_str(),
                 seconds(std::chrono::duration<double>(now - start_).count()).c_str());
  }

  static std::string seconds(double s) {
    char b[32];
    if (s < 90) std::snprintf(b, sizeof b, "%.1f s", s);
    else std::snprintf(b, sizeof b, "%d min %02d s", static_cast<int>(s) / 60, static_cast<int>(s) % 60);
    return b;
  }
  bool terminal_;
  std::string step_;
  std::chrono::steady_clock::time_point start_, last_;
  int tenth_ = -1;
  bool open_ = false;  //!< the current step printed a line without reaching its total
};

}  // namespace

bool show_progress(bool progress, bool no_progress) {
  if (no_progress) return false;
  return progress || ::isatty(2);
}

pipeline::Progress make_progress(bool show) {
  auto printer = show ? std::make_shared<ProgressPrinter>(::isatty(2) != 0) : nullptr;
  return [printer](const char* what, std::uint64_t done, std::uint64_t total) {
    if (printer) printer->update(what, done, total);
    // Long steps poll for Ctrl-C here: no output file gets its final name after a stop.
    if (pipeline::stop_requested()) throw std::runtime_error("interrupted");
  };
}

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
  if (!c.progress) c.progress = make_progress(progress_);
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
