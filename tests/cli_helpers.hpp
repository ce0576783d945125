// Runs the gcpipe executable as a user does, for the tests of whole commands.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

extern char** environ;

namespace fs = std::filesystem;

struct Outcome {
  int status = -1;       // exit code
  double max_rss_mb = 0; // peak resident set of the process
  std::string out, err;
};

/// Starts gcpipe with `args` (stdout/stderr to files `out`, `err`); returns its pid.
inline pid_t spawn_gcpipe(const std::vector<std::string>& args, const fs::path& out, const fs::path& err) {
  std::vector<std::string> all{GCPIPE_EXE};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&fa, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  pid_t pid = 0;
  if (posix_spawn(&pid, argv[0], &fa, nullptr, argv.data(), environ) != 0) pid = -1;
  posix_spawn_file_actions_destroy(&fa);
  return pid;
}

inline std::string slurp(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

inline nlohmann::json read_json(const fs::path& p) { return nlohmann::json::parse(slurp(p)); }

/// Runs gcpipe with `args` to the end; stdout/stderr captured through files.
inline Outcome gcpipe(const std::vector<std::string>& args) {
  static int counter = 0;
  const fs::path dir = fs::temp_directory_path() / ("gcpipe_cli_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path out = dir / ("out" + std::to_string(counter)), err = dir / ("err" + std::to_string(counter++));
  Outcome r;
  const pid_t pid = spawn_gcpipe(args, out, err);
  if (pid < 0) return r;
  int st = 0;
  rusage ru{};
  wait4(pid, &st, 0, &ru);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
  r.max_rss_mb = static_cast<double>(ru.ru_maxrss) / 1024.0;
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

inline fs::path tmpdir(const std::string& name) {
  fs::path p = fs::temp_directory_path() / ("gcpipe_cli_" + std::to_string(::getpid()) + "_" + name);
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}


