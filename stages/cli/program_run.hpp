// What every command that runs the pipeline on one program shares: the config, the input, the
// stage context, the diagnostics log, the chain of stages (a prefix of `gcpipe batch`'s) and the
// loop that reads the program into it.
#pragma once

#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "commands.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "output_dir.hpp"
#include "pipeline.hpp"
#include "program_stream.hpp"

namespace gcpipe::cli {

/// Progress on stderr wanted: --progress, or a terminal unless --no-progress.
bool show_progress(bool progress, bool no_progress);
/// The progress every command prints (one line per step, percent, elapsed and remaining time;
/// nothing when `show` is false); it also polls for SIGINT/SIGTERM and throws "interrupted".
pipeline::Progress make_progress(bool show);

/// Prints diagnostics to stderr (the first `shown_max`; all of them when 0) and keeps them for
/// diagnostics.txt when asked to.
class PrintedLog final : public pipeline::DiagnosticLog {
 public:
  /// `file`: every diagnostic also goes there (diagnostics.txt), flushed in 1 MiB pieces.
  explicit PrintedLog(std::uint64_t shown_max = 0, pipeline::AtomicFile* file = nullptr, bool quiet = false)
      : shown_max_(shown_max), file_(file), quiet_(quiet) {}
  void report(const Diagnostic& d) override;
  std::uint64_t errors() const { return errors_; }
  std::uint64_t not_shown() const { return not_shown_; }
  /// Writes what is still buffered to the file.
  void flush() {
    if (file_) file_->write(kept_, true);
  }

 private:
  std::uint64_t shown_max_;
  pipeline::AtomicFile* file_;
  bool quiet_;
  std::uint64_t errors_ = 0, shown_ = 0, not_shown_ = 0;
  std::string kept_;
};

/// An emitter that takes only written text (a stage with a G-code output) into a file.
class TextFileSink final : public pipeline::Emitter {
 public:
  explicit TextFileSink(const std::string& path) : file_(path) {}
  bool block(const ResolvedBlock&) override { return true; }
  bool diagnostic(const Diagnostic&, DiagnosticKind) override { return true; }
  bool text(std::string& gcode) override {
    written_ = true;
    file_.write(gcode, true);
    return true;
  }
  void product(const std::shared_ptr<const pipeline::Product>&) override {}
  /// Renames the file to its final name (only a complete file gets it).
  void commit() { file_.commit(); }
  bool written() const { return written_; }

 private:
  pipeline::AtomicFile file_;
  bool written_ = false;
};

/// One program through a chain of stages.
class ProgramRun {
 public:
  /// Loads the config, opens the input and builds the chain ending in `last_stages` (each with
  /// its upstreams). `log` receives every diagnostic.
  ProgramRun(const ProgramArgs& args, const std::vector<std::string>& last_stages, pipeline::DiagnosticLog& log,
             const pipeline::StageContext& overrides = {});
  /// The same, with the last stages chosen once the config is loaded.
  ProgramRun(const ProgramArgs& args,
             const std::function<std::vector<std::string>(const PipelineConfig&)>& last_stages,
             pipeline::DiagnosticLog& log, const pipeline::StageContext& overrides = {});
  const PipelineConfig& config() const { return config_; }
  const std::string& input_name() const { return input_.name(); }
  pipeline::Pipeline& pipeline() { return *pipeline_; }
  bool progress() const { return progress_; }
  /// Reads the program through the chain and finishes it. False when it was stopped (strict mode,
  /// a read error, a signal): `error()` says why; the stages were still finished.
  bool run();
  const std::string& error() const { return error_; }

 private:
  PipelineConfig config_;
  InputFile input_;
  bool progress_;
  std::unique_ptr<pipeline::Pipeline> pipeline_;
  std::string error_;
};

/// The stages of every chain named (each with its upstreams), without repeats, in pipeline order.
std::vector<std::string> chains(const std::vector<std::string>& last_stages);

/// Exit status of a finished run: 128 + signal when interrupted, 1 when stopped or when a stage
/// failed, 3 when lines were rejected, else 0.
int exit_status(bool complete, const std::string& failure, std::uint64_t rejected);

}  // namespace gcpipe::cli
