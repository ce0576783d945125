// Subcommands of the `gcpipe` executable. Each lives in cmd_<name>.cpp and is listed once in
// main.cpp's table; main() only dispatches.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace gcpipe::cli {

/// A subcommand: `run` gets the arguments after the subcommand name and returns the exit code.
struct Command {
  const char* name;
  const char* summary;  //!< one line for `gcpipe --help`
  const char* usage;    //!< full text for `gcpipe <name> --help`
  int (*run)(const std::vector<std::string>& args);
};

/// Minimal option parser: `--key value`, `--flag`, positionals. Unknown options are errors that
/// say what is accepted.
class Args {
 public:
  /// `with_value`: options that take a value; `flags`: options that do not.
  Args(const std::vector<std::string>& args, std::initializer_list<std::string_view> with_value,
       std::initializer_list<std::string_view> flags);
  bool ok() const { return error_.empty(); }
  const std::string& error() const { return error_; }
  bool flag(std::string_view name) const;
  std::optional<std::string> value(std::string_view name) const;
  std::string value_or(std::string_view name, std::string fallback) const;
  /// Parses a numeric option; sets error() on a bad value.
  double number_or(std::string_view name, double fallback);
  const std::vector<std::string>& positional() const { return positional_; }
  bool help() const { return help_; }

 private:
  std::vector<std::pair<std::string, std::string>> values_;
  std::vector<std::string> flags_;
  std::vector<std::string> positional_;
  std::string error_;
  bool help_ = false;
};

/// Prints "gcpipe <cmd>: <message>" to stderr and returns 2 (usage error).
int usage_error(const Command& cmd, const std::string& message);

}  // namespace gcpipe::cli
