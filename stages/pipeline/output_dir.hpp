// Outputs a user can trust: every file is written as NAME.part and renamed to NAME only when it
// is complete, so a file under its final name is never cut short (an interrupted run leaves
// .part files, which the next run removes); SIGINT and SIGTERM set a flag that long loops poll
// so a run stops cleanly.
#pragma once

#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

namespace gcpipe::pipeline {

/// A file written as `path`.part and renamed to `path` by commit(). "-" writes to standard
/// output (nothing to rename). Destroyed without commit(): the .part is removed.
class AtomicFile {
 public:
  explicit AtomicFile(const std::string& path);  // throws std::runtime_error with the reason
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  /// Appends `buffer` once it holds 1 MiB (or at once with `force`) and clears it.
  void write(std::string& buffer, bool force = false);
  /// Flushes, closes and renames to the final name.
  void commit();
  const std::string& path() const { return path_; }

 private:
  std::FILE* f_ = nullptr;
  std::string path_, part_;
  bool direct_ = false;  //!< a device or pipe: written in place, never renamed over
};

/// Writes `text` to `path` through an AtomicFile.
void write_file_atomically(const std::filesystem::path& path, std::string text);

/// Prepares `dir` for a run: creates it (and dir/plots), then removes the files an earlier run
/// may have left (`names`, relative to dir, and every *.part in dir and dir/plots), so that no
/// file in it can pass for this run's. Throws naming the folder when it cannot.
void prepare_output_dir(const std::filesystem::path& dir, const std::vector<std::string>& names);

/// SIGINT and SIGTERM set a flag (a second one ends the process at once).
void install_stop_handlers();
bool stop_requested();
/// The signal that asked to stop (0 when none), for the exit status 128 + signal.
int stop_signal();

}  // namespace gcpipe::pipeline
