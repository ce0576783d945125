// The input program of a command and the config it names (the loop that reads the program into
// the stages is pipeline::run_lines).
#pragma once

#include <cstdint>
#include <string>

#include "gcpipe/pipeline_config.hpp"

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

/// Loads --config (or the default); `tool_table` (--tool-table), when given, replaces the machine
/// file's tools.
PipelineConfig load_config_option(const std::string& path_or_empty, const std::string& tool_table = "");

}  // namespace gcpipe::cli
