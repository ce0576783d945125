// The one loop that reads a program and hands each line's outcome on, shared by `parse`,
// `batch` and the stage commands so they cannot drift apart.
#pragma once

#include <cstdio>
#include <functional>
#include <string>

#include "gcpipe/block.hpp"
#include "gcpipe/diagnostic.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "parse.hpp"

namespace gcpipe::cli {

/// An open input: a file or standard input ("-").
class InputFile {
 public:
  explicit InputFile(const std::string& path);  // throws std::runtime_error with the reason
  ~InputFile();
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;
  int fd() const { return fd_; }
  /// Size in bytes, 0 when unknown (a pipe).
  std::uint64_t size() const { return size_; }
  const std::string& name() const { return name_; }

 private:
  int fd_ = -1;
  std::uint64_t size_ = 0;
  std::string name_;
};

/// Called for what the parser makes: blocks (a line may yield several: a canned cycle, a
/// subroutine call) and diagnostics (rejected / skipped lines). Return false to stop.
struct LineSink {
  std::function<bool(const ResolvedBlock&)> block;
  std::function<bool(const Diagnostic&)> diagnostic;
};

/// The diagnostic handler of the single-stage commands: print to stderr, count the errors.
std::function<bool(const Diagnostic&)> print_diagnostics(std::uint64_t& errors);

/// Streams `in` through `parser`. Strict mode stops after the first rejected line. Prints a
/// progress line to stderr about once a second when `progress` is set. Returns false if the
/// stream was stopped early (strict mode, a sink returned false, or a read error in `error`).
bool stream_program(InputFile& in, Parser& parser, const LineSink& sink, bool progress,
                    std::string& error);

/// Loads --config (or the default) and prints which file was used when `verbose`.
PipelineConfig load_config_option(const std::string& path_or_empty);

/// Writes `text` to `path` ("-" = stdout); throws std::runtime_error with the reason.
class OutputFile {
 public:
  explicit OutputFile(const std::string& path);
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;
  /// Appends and flushes in large chunks; `buffer` is cleared.
  void write(std::string& buffer, bool force = false);
  void close();

 private:
  std::FILE* f_ = nullptr;
  std::string path_;
};

}  // namespace gcpipe::cli
