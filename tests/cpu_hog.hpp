// An artificial load for the tests whose bounds must hold on a loaded machine (issue 34 item 2):
// N child processes that spin on a core each until the hog goes out of scope. They ask the kernel
// to kill them when the test process dies (PR_SET_PDEATHSIG), so a crashed test leaves no spinner.
#pragma once

#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <vector>

namespace gcpipe_test {

class CpuHog {
 public:
  explicit CpuHog(int processes) {
    const pid_t parent = getpid();
    for (int k = 0; k < processes; ++k) {
      const pid_t pid = fork();
      if (pid == 0) spin(parent);
      if (pid > 0) pids_.push_back(pid);
    }
  }
  ~CpuHog() {
    for (const pid_t pid : pids_) kill(pid, SIGKILL);
    for (const pid_t pid : pids_) waitpid(pid, nullptr, 0);
  }
  CpuHog(const CpuHog&) = delete;
  CpuHog& operator=(const CpuHog&) = delete;
  int processes() const { return static_cast<int>(pids_.size()); }

 private:
  [[noreturn]] static void spin(pid_t parent) {
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(0);  // the test died before the request took effect
    volatile unsigned long long n = 0;
    for (;;) n = n + 1;
  }
  std::vector<pid_t> pids_;
};

}  // namespace gcpipe_test
