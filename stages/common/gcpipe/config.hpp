// Typed access to YAML configuration files, with errors that name file, line, key, value and the
// reason. yaml-cpp stays behind this interface so its headers are compiled in one file only.
//
// Every read states its unit and valid range; unknown keys are rejected so that a typo in a config
// is an error rather than a silently ignored setting.
#pragma once

#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace gcpipe {

/// Thrown for a config that cannot be used. what() = "file:line:col: key 'a.b': reason".
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One value a stage read from a config, as `gcpipe config --print` shows it: the file and
/// dotted key, the value as text, and whether the file gave it or the stage's default did.
struct ConfigRead {
  std::string file, key, value;
  bool defaulted = false;
};

/// While one of these lives on a thread, every value read through Config on that thread is
/// appended to it (the effective config: what the stages used, defaults included). Nothing is
/// recorded when none lives, which is every run but `gcpipe config`.
class ConfigReadLog {
 public:
  ConfigReadLog();
  ~ConfigReadLog();
  ConfigReadLog(const ConfigReadLog&) = delete;
  ConfigReadLog& operator=(const ConfigReadLog&) = delete;
  const std::vector<ConfigRead>& reads() const { return reads_; }
  /// Appends to the log living on this thread, if any.
  static void note(ConfigRead read);

 private:
  std::vector<ConfigRead> reads_;
  ConfigReadLog* outer_;
};

/// A read-only view of one mapping inside a YAML document.
class Config {
 public:
  /// Loads a YAML file; throws ConfigError when it cannot be read or parsed.
  static Config load_file(const std::filesystem::path& path);
  /// Parses YAML text; `name` stands in for the file name in messages.
  static Config from_string(std::string_view yaml, std::string name = "<string>");

  Config();  // an empty mapping
  ~Config();
  Config(const Config&);
  Config& operator=(const Config&);

  bool has(std::string_view key) const;
  /// True when `key` is present and holds a mapping (a key that takes a name or a mapping).
  bool is_mapping(std::string_view key) const;
  /// The mapping under `key`; an empty mapping when absent; throws if `key` is not a mapping.
  Config section(std::string_view key) const;
  /// Keys of this mapping in file order (as strings).
  std::vector<std::string> keys() const;
  /// Throws for any key of this mapping that is not in `known` (catches typos).
  void reject_unknown(std::initializer_list<std::string_view> known) const;

  /// A number in [min, max]; `unit` is only used in messages ("mm", "1/s", "" for none).
  double number(std::string_view key, double fallback, std::string_view unit, double min,
                double max) const;
  /// A required number in [min, max].
  double number(std::string_view key, std::string_view unit, double min, double max) const;
  /// An integer in [min, max].
  std::int64_t integer(std::string_view key, std::int64_t fallback, std::int64_t min,
                       std::int64_t max) const;
  bool boolean(std::string_view key, bool fallback) const;
  std::string string(std::string_view key, std::string fallback) const;
  /// One of `allowed`.
  std::string choice(std::string_view key, std::string fallback,
                     std::initializer_list<std::string_view> allowed) const;
  /// A sequence of exactly `n` numbers (n = 0: any length), each in [min, max].
  std::vector<double> numbers(std::string_view key, std::size_t n, std::string_view unit,
                              double min, double max) const;

  /// A required non-empty sequence of strings (names), each one of `allowed` when that is given.
  std::vector<std::string> strings(std::string_view key, const std::vector<std::string>& allowed = {}) const;

  /// Dotted path of this mapping from the document root ("" for the root).
  const std::string& path() const;
  /// File this config was read from.
  const std::string& file() const;
  /// `relative` resolved against the directory of file() (for `machine: machines/mx330.yaml`).
  std::filesystem::path resolve(const std::string& relative) const;
  /// The file named by `key`, resolved like resolve(); throws error(key, ...) naming the key, the
  /// value and the resolved path when it is empty, missing or a directory (`what`: what it should
  /// name, for the message, e.g. "the machine file").
  std::filesystem::path file_path(std::string_view key, std::string_view what) const;
  /// The same for a folder (`what`: e.g. "the identity folder").
  std::filesystem::path dir_path(std::string_view key, std::string_view what) const;
  /// Builds the error for `key` of this mapping, with its position in the file.
  ConfigError error(std::string_view key, const std::string& reason) const;

 private:
  struct Impl;
  std::shared_ptr<const Impl> impl_;
  /// Records a value read from `key` for an active ConfigReadLog.
  void note(std::string_view key, std::string value, bool defaulted) const;
  explicit Config(std::shared_ptr<const Impl> impl);
};

}  // namespace gcpipe
