// What the multi-process DDS tests share: the built gcpipe run as a child process with its output
// in a log file (optionally inside a network namespace), polling a log, reading a file whole.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace gcpipe_test {

namespace fs = std::filesystem;

inline const std::string kExe = GCPIPE_EXE;
inline constexpr double kProcessLimit = 180;  // [s] then the test kills the process and fails

inline std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

// Removes the Fast DDS shared-memory files that no live process maps (`gcpipe dds clean`): what
// killed processes left. Never `fastdds shm clean`, which acts on every pipeline of the host and
// may take the port of a participant that is starting (other engineers' tests run beside these).
inline void clean_dead_shared_memory() {
  [[maybe_unused]] const int rc = std::system((kExe + " dds clean > /dev/null 2>&1").c_str());
}

// One child process (gcpipe ARGS, or WRAPPER... gcpipe ARGS such as `ip netns exec NS`) with
// stdout+stderr in a log file.
struct Process {
  std::string name;
  pid_t pid = -1;
  fs::path log;
  bool killed = false;

  Process(std::string n, const std::vector<std::string>& args, const fs::path& dir,
          const std::vector<std::string>& wrapper = {})
      : name(std::move(n)), log(dir / (name + ".log")) {
    std::vector<char*> argv;
    for (const auto& w : wrapper) argv.push_back(const_cast<char*>(w.c_str()));
    argv.push_back(const_cast<char*>(kExe.c_str()));
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&fa, 1, 2);
    const int rc = posix_spawnp(&pid, argv[0], &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) pid = -1;
  }

  // Exit status, or -1 after killing a process that overran `limit` [s].
  int wait(double limit = kProcessLimit) {
    if (pid <= 0) return -2;
    const auto t0 = std::chrono::steady_clock::now();
    int status = 0;
    for (;;) {
      const pid_t r = waitpid(pid, &status, WNOHANG);
      if (r == pid) break;
      if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > limit) {
        kill(pid, SIGKILL);
        waitpid(pid, &status, 0);
        killed = true;
        pid = -1;
        return -1;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    pid = -1;
    if (WIFEXITED(status)) return WEXITSTATUS(status);
    return 128 + WTERMSIG(status);
  }

  ~Process() {
    // Left running by a failed assertion: kill it, and clean the shared memory it leaves.
    if (pid > 0 && wait(0) == -1) {
      clean_dead_shared_memory();
    }
  }
};

// Polls a process's log until it contains `text`; false after `limit` [s].
inline bool wait_for_log(const Process& p, const std::string& text, double limit = 60) {
  const auto t0 = std::chrono::steady_clock::now();
  while (slurp(p.log).find(text) == std::string::npos) {
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > limit)
      return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

}  // namespace gcpipe_test
