#include "launcher.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <ostream>
#include <set>
#include <thread>

#include "dds_runtime.hpp"
#include "gcpipe/config.hpp"
#include "gcpipe/stop.hpp"
#include "stage.hpp"

extern char** environ;

namespace gcpipe::dds {

void follow_supervisor() {
  const char* v = std::getenv(kSupervisorPidVariable);
  if (v == nullptr || *v == '\0') return;
  const long supervisor = std::strtol(v, nullptr, 10);
  ::prctl(PR_SET_PDEATHSIG, SIGTERM);
  // It may have died before the line above: then the signal never comes.
  if (static_cast<long>(::getppid()) != supervisor) ::raise(SIGTERM);
}

namespace {

constexpr std::size_t kTailLines = 20;

// The topic stage `name` reads in a plan: the output topic of its nearest upstream that runs in
// the plan (a stage left out is skipped over, as `--in` would be given by hand), or the program.
std::string plan_input_topic(const std::vector<std::string>& nodes, const std::string& name) {
  std::string up = pipeline::find_stage(name).upstream;
  while (!up.empty()) {
    if (std::find(nodes.begin(), nodes.end(), up) != nodes.end()) return pipeline::find_stage(up).topic;
    up = pipeline::find_stage(up).upstream;
  }
  return pipeline::kProgramTopic;
}

std::vector<std::string> stages_with_nodes() {
  std::vector<std::string> out;
  for (const auto& info : pipeline::registry())
    if (*info.topic != '\0') out.emplace_back(info.name);
  return out;
}

std::string describe(int status) {
  if (status >= 128) return "killed by signal " + std::to_string(status - 128);
  return "exit status " + std::to_string(status);
}

}  // namespace

namespace {

// `groups: [parse+trochoid+write, ik+simulate]`: stages of `nodes`, each in one group at most,
// put in chain order.
std::vector<std::vector<std::string>> load_groups(const Config& root, const std::vector<std::string>& nodes) {
  std::vector<std::vector<std::string>> groups;
  std::set<std::string> grouped;
  for (const std::string& text : root.strings("groups")) {
    std::vector<std::string> group;
    for (std::size_t from = 0;;) {
      const std::size_t plus = text.find('+', from);
      group.push_back(text.substr(from, plus == std::string::npos ? std::string::npos : plus - from));
      if (plus == std::string::npos) break;
      from = plus + 1;
    }
    if (group.size() < 2) throw root.error("groups", "'" + text + "' is one stage: a group joins two or more with '+'");
    for (const std::string& stage : group) {
      if (std::find(nodes.begin(), nodes.end(), stage) == nodes.end())
        throw root.error("groups", "stage '" + stage + "' of group '" + text + "' is not in nodes");
      if (!grouped.insert(stage).second) throw root.error("groups", "stage '" + stage + "' is in two groups");
    }
    std::sort(group.begin(), group.end(), [&](const std::string& a, const std::string& b) {
      return std::find(nodes.begin(), nodes.end(), a) < std::find(nodes.begin(), nodes.end(), b);
    });
    groups.push_back(std::move(group));
  }
  return groups;
}

// The processes of a plan: each group, and each stage of no group, in chain order (a group where
// its first stage is).
std::vector<std::vector<std::string>> process_units(const LaunchPlan& plan) {
  std::vector<std::vector<std::string>> units;
  std::set<std::string> done;
  for (const std::string& n : plan.nodes) {
    if (done.count(n) != 0) continue;
    std::vector<std::string> unit{n};
    for (const auto& g : plan.groups)
      if (std::find(g.begin(), g.end(), n) != g.end()) unit = g;
    done.insert(unit.begin(), unit.end());
    units.push_back(std::move(unit));
  }
  return units;
}

// The readers a stage's node waits for: the nodes (and sinks) of the file that read its topic. A
// written program (G-code: write, compensate) has at least one, the sink a user starts by hand
// for `gcpipe launch`; any other edge nobody in the file reads has none (the last stage of a
// monitoring pipeline, whose telemetry is for monitors), and its node does not wait.
int readers_of(const pipeline::StageInfo& stage, const std::map<std::string, int>& readers) {
  const auto it = readers.find(stage.topic);
  const int n = it == readers.end() ? 0 : it->second;
  return stage.output == pipeline::Port::kGcode ? std::max(1, n) : n;
}

}  // namespace

std::string joined(const std::vector<std::string>& parts, char separator) {
  std::string out;
  for (const auto& p : parts) out += (out.empty() ? "" : std::string(1, separator)) + p;
  return out;
}


LaunchPlan load_launch_plan(const std::filesystem::path& file) {
  const Config root = Config::load_file(file);
  root.reject_unknown({"pipeline", "nodes", "groups"});
  const Config p = root.section("pipeline");
  p.reject_unknown({"name", "domain", "config", "profiles", "network", "identity", "on_crash", "max_restarts", "restart_delay",
                    "ready_timeout", "stop_timeout", "timeout", "monitor_history", "heartbeat_timeout",
                    "stall_timeout"});
  LaunchPlan plan;
  plan.name = p.string("name", file.stem().string());
  plan.domain = static_cast<int>(p.integer("domain", 0, 0, 232));
  // Normalised (no "pipelines/../"), so that report.json names the config as batch does.
  plan.config = p.file_path("config", "the pipeline config the nodes read").lexically_normal();
  if (p.has("profiles")) plan.profiles = p.file_path("profiles", "the DDS profiles XML");
  if (p.has("network")) plan.network = p.file_path("network", "the DDS network profile XML");
  if (p.has("identity")) plan.identity = p.dir_path("identity", "the nodes' DDS Security identity folder");
  plan.restart = p.choice("on_crash", "stop", {"stop", "restart"}) == "restart";
  plan.max_restarts = static_cast<int>(p.integer("max_restarts", 3, 0, 100));
  plan.restart_delay = p.number("restart_delay", 9, "s", 0, 600);
  plan.ready_timeout = p.number("ready_timeout", 30, "s", 0.1, 3600);
  plan.stop_timeout = p.number("stop_timeout", 5, "s", 0.1, 600);
  plan.timeout = p.number("timeout", 30, "s", 0.1, 1e6);
  plan.monitor_history = p.number("monitor_history", 5, "s", 0, 1e6);
  plan.heartbeat_timeout = p.number("heartbeat_timeout", 4, "s", 1, 3600);
  plan.stall_timeout = p.number("stall_timeout", 10, "s", 1, 1e6);
  plan.nodes = root.strings("nodes", stages_with_nodes());
  std::set<std::string> seen;
  for (const auto& n : plan.nodes)
    if (!seen.insert(n).second) throw root.error("nodes", "stage '" + n + "' is listed twice: one node per stage");
  if (root.has("groups")) plan.groups = load_groups(root, plan.nodes);
  return plan;
}

std::vector<std::string> plan_dds_args(const LaunchPlan& plan) {
  std::vector<std::string> a{"--domain", std::to_string(plan.domain)};
  if (!plan.profiles.empty()) a.insert(a.end(), {"--profiles", plan.profiles.string()});
  if (!plan.network.empty()) a.insert(a.end(), {"--network", plan.network.string()});
  if (!plan.identity.empty()) a.insert(a.end(), {"--identity", plan.identity.string()});
  a.insert(a.end(), {"--monitor-history", std::to_string(plan.monitor_history)});
  a.insert(a.end(), {"--heartbeat-timeout", std::to_string(plan.heartbeat_timeout)});
  a.insert(a.end(), {"--stall-timeout", std::to_string(plan.stall_timeout)});
  return a;
}

std::vector<LaunchProcess> node_processes(const LaunchPlan& plan, bool forever,
                                          const std::map<std::string, int>& extra_readers) {
  std::map<std::string, int> readers = extra_readers;
  for (const auto& n : plan.nodes) ++readers[plan_input_topic(plan.nodes, n)];
  std::vector<LaunchProcess> out;
  for (const auto& unit : process_units(plan)) {
    std::vector<std::string> inputs, counts;
    for (const auto& n : unit) {
      inputs.push_back(plan_input_topic(plan.nodes, n));
      counts.push_back(std::to_string(readers_of(pipeline::find_stage(n), readers)));
    }
    LaunchProcess p;
    p.name = joined(unit, '+');
    p.args = {"node"};
    p.args.insert(p.args.end(), unit.begin(), unit.end());
    p.args.insert(p.args.end(), {"--config", plan.config.string(), "--in", joined(inputs, ','), "--readers",
                                 joined(counts, ',')});
    if (forever) p.args.emplace_back("--forever");
    const auto dds = plan_dds_args(plan);
    p.args.insert(p.args.end(), dds.begin(), dds.end());
    p.args.insert(p.args.end(), {"--timeout", std::to_string(plan.timeout)});
    p.ready_text = "gcpipe node " + p.name + ": up";
    p.one_shot = !forever;
    out.push_back(std::move(p));
  }
  return out;
}

Supervisor::Supervisor(std::filesystem::path exe, const LaunchPlan& plan, std::ostream& log, bool verbose)
    : exe_(std::move(exe)), plan_(plan), log_(log), verbose_(verbose) {}

Supervisor::~Supervisor() { stop_all(); }

void Supervisor::add(LaunchProcess p) {
  Child c;
  c.spec = std::move(p);
  children_.push_back(std::move(c));
}

double Supervisor::now() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count() - t0_;
}

void Supervisor::status_line(const Child& c, const std::string& what) {
  char when[32];
  std::snprintf(when, sizeof when, "%7.2f s", now());
  log_ << "gcpipe launch " << plan_.name << ": " << when << "  " << c.spec.name << ": " << what << std::endl;
}

// The child's stdout and stderr go to one pipe that the supervisor reads line by line.
bool Supervisor::spawn(Child& c) {
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0) return false;
  std::vector<char*> argv;
  const std::string exe = exe_.string();
  argv.push_back(const_cast<char*>(exe.c_str()));
  for (const auto& a : c.spec.args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, fds[1], 1);
  posix_spawn_file_actions_adddup2(&fa, fds[1], 2);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  // The child learns who supervises it (follow_supervisor): a supervisor killed with SIGKILL,
  // which cannot stop its children, must not leave them serving on the domain.
  setenv(kSupervisorPidVariable, std::to_string(getpid()).c_str(), 1);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, exe.c_str(), &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  close(fds[1]);
  if (rc != 0) {
    close(fds[0]);
    return false;
  }
  fcntl(fds[0], F_SETFL, O_NONBLOCK);
  c.pid = pid;
  c.out_fd = fds[0];
  c.ready = c.spec.ready_text.empty();
  c.status = -1;
  c.started_at = now();
  status_line(c, "started (pid " + std::to_string(pid) + ")");
  return true;
}

bool Supervisor::start() {
  t0_ = 0;
  t0_ = now();
  for (Child& c : children_) {
    if (!spawn(c)) {
      message_ = "could not start " + c.spec.name + " (" + exe_.string() + ")";
      stop_all();
      return false;
    }
    await_up(c);
  }
  say_if_all_ready();  // the last one may be ready at start (a feed)
  return true;
}

// One process at a time: the next starts once this one says it is up (its DDS participant, reader
// and writer exist) or after kStartGap at most. Eleven participants created in the same instant
// now and then left a pair that never matched (Fast DDS 2.9 on this host; 2 runs in 5 of
// gcpipe stream's test), so creation is not left to race.
void Supervisor::await_up(Child& c) {
  constexpr double kStartGap = 2.0;  // [s]
  const double t = now();
  while (!c.ready && c.out_fd >= 0 && now() - t < kStartGap && !stop_requested()) {
    read_output(c, false);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

void Supervisor::on_line(Child& c, const std::string& line) {
  if (verbose_) log_ << "[" << c.spec.name << "] " << line << "\n";
  c.tail.push_back(line);
  if (c.tail.size() > kTailLines) c.tail.pop_front();
  if (!c.ready && line.find(c.spec.ready_text) != std::string::npos) {
    c.ready = true;
    char took[48];
    std::snprintf(took, sizeof took, "ready after %.2f s", now() - c.started_at);
    status_line(c, took);
    sample_shm();
    say_if_all_ready();
  }
}

void Supervisor::say_if_all_ready() {
  if (all_ready_said_ || !std::all_of(children_.begin(), children_.end(), [](const Child& k) { return k.ready; }))
    return;
  all_ready_said_ = true;
  log_ << "gcpipe launch " << plan_.name << ": all " << children_.size() << " processes ready (DDS domain "
       << plan_.domain << ")" << std::endl;
}

void Supervisor::read_output(Child& c, bool drain) {
  if (c.out_fd < 0) return;
  char buf[4096];
  for (;;) {
    const ssize_t n = read(c.out_fd, buf, sizeof buf);
    if (n > 0) {
      c.partial.append(buf, static_cast<std::size_t>(n));
      std::size_t nl;
      while ((nl = c.partial.find('\n')) != std::string::npos) {
        on_line(c, c.partial.substr(0, nl));
        c.partial.erase(0, nl + 1);
      }
      continue;
    }
    if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR)) {  // closed: the child is gone
      if (!c.partial.empty()) on_line(c, c.partial), c.partial.clear();
      close(c.out_fd);
      c.out_fd = -1;
    }
    if (!drain || c.out_fd < 0 || (n < 0 && errno == EAGAIN)) return;
  }
}

// True when `c` ended; `fatal` when that ends the pipeline (a crash not restarted).
bool Supervisor::reap(Child& c, bool& fatal) {
  if (c.pid <= 0) return false;
  int st = 0;
  if (waitpid(c.pid, &st, WNOHANG) != c.pid) return false;
  read_output(c, true);
  c.pid = -1;
  c.status = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
  if (WIFSIGNALED(st)) any_killed_ = true;
  const auto& ok = c.spec.ok_statuses;
  if (c.spec.one_shot && std::find(ok.begin(), ok.end(), c.status) != ok.end()) {
    status_line(c, "finished, " + describe(c.status));
    return true;
  }
  status_line(c, "stopped unexpectedly, " + describe(c.status));
  for (const auto& l : c.tail) log_ << "    | " << l << "\n";
  if (plan_.restart && c.restarts < plan_.max_restarts && !c.spec.one_shot) {
    ++c.restarts;
    char when[96];
    std::snprintf(when, sizeof when, " in %.1f s, once its peers have dropped the dead participant", plan_.restart_delay);
    status_line(c, "restarting (" + std::to_string(c.restarts) + " of " + std::to_string(plan_.max_restarts) + ")" + when);
    c.restart_at = now() + plan_.restart_delay;
    return true;
  }
  fatal = true;
  message_ = "stage " + c.spec.name + " stopped (" + describe(c.status) + "); the pipeline was stopped";
  return true;
}

// Starts a crashed process again when its delay is over; false when it cannot be started.
bool Supervisor::restart_if_due(Child& c) {
  if (c.restart_at < 0 || now() < c.restart_at) return true;
  c.restart_at = -1;
  if (spawn(c)) return true;
  message_ = "stage " + c.spec.name + " could not be started again";
  return false;
}

int Supervisor::run() {
  for (;;) {
    std::vector<pollfd> fds;
    for (const Child& c : children_)
      if (c.out_fd >= 0) fds.push_back({c.out_fd, POLLIN, 0});
    if (!fds.empty()) poll(fds.data(), fds.size(), 100);
    else std::this_thread::sleep_for(std::chrono::milliseconds(50));
    bool fatal = false;
    if (now() > next_shm_sample_) sample_shm();
    for (Child& c : children_) {
      read_output(c, false);
      reap(c, fatal);
      if (!fatal && !restart_if_due(c)) fatal = true;
      if (fatal) break;
    }
    if (fatal) {
      stop_all();
      return 1;
    }
    if (stop_requested()) {
      log_ << "gcpipe launch " << plan_.name << ": stopping every process (signal)" << std::endl;
      stop_all();
      return 128 + (gcpipe::stop_signal() != 0 ? gcpipe::stop_signal() : SIGINT);  // 130 SIGINT, 143 SIGTERM
    }
    for (const Child& c : children_)
      if (c.pid > 0 && !c.ready && now() - c.started_at > plan_.ready_timeout) {
        message_ = c.spec.name + " did not say it was ready within " + std::to_string(plan_.ready_timeout) + " s";
        for (const auto& l : c.tail) log_ << "    | " << l << "\n";
        stop_all();
        return 1;
      }
    // Done when there are one-shot processes (a stream: feed, nodes, sinks) and all have ended.
    const bool any_one_shot = std::any_of(children_.begin(), children_.end(), [](const Child& c) { return c.spec.one_shot; });
    const bool one_shots_done = std::all_of(children_.begin(), children_.end(), [](const Child& c) {
      return !c.spec.one_shot || c.pid <= 0;
    });
    if (any_one_shot && one_shots_done) {
      stop_all();
      return 0;
    }
  }
}

// SIGTERM to every process still running, SIGKILL after stop_timeout; then the shared memory of
// any process that did not exit by itself (Fast DDS leaves its segments behind a killed process).
// What each live process maps now (its own port queue and its peers'): a process killed later
// leaves its queue mapped by nobody, and stop_all() then knows it was the pipeline's.
void Supervisor::sample_shm() {
  next_shm_sample_ = now() + 0.5;
  for (const Child& c : children_)
    if (c.pid > 0) shm_files_mapped_by(c.pid, shm_seen_);
}

void Supervisor::stop_all() {
  sample_shm();
  bool any = false;
  for (Child& c : children_)
    if (c.pid > 0) kill(c.pid, SIGTERM), any = true;
  const double deadline = now() + plan_.stop_timeout;
  while (any) {
    any = false;
    for (Child& c : children_) {
      if (c.pid <= 0) continue;
      read_output(c, false);
      int st = 0;
      if (waitpid(c.pid, &st, WNOHANG) == c.pid) {
        c.status = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
        c.pid = -1;
        read_output(c, true);
        status_line(c, "stopped, " + describe(c.status));
        continue;
      }
      if (now() > deadline) {
        kill(c.pid, SIGKILL);
        waitpid(c.pid, &st, 0);
        c.status = 128 + SIGKILL;
        c.pid = -1;
        any_killed_ = true;
        status_line(c, "killed after " + std::to_string(plan_.stop_timeout) + " s");
        continue;
      }
      any = true;
    }
    if (any) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  for (Child& c : children_)
    if (c.out_fd >= 0) close(c.out_fd), c.out_fd = -1;
  // Not `fastdds shm clean`: it acts on every pipeline of the host, and it may take the port of a
  // participant that is starting at that moment (created, not yet locked) for a zombie; the
  // files our own processes mapped are all this pipeline may remove.
  any_killed_ = false;
  remove_unmapped_shm_files(shm_seen_);
  shm_seen_.clear();
}

int Supervisor::exit_status(const std::string& name) const {
  for (const Child& c : children_)
    if (c.spec.name == name) return c.status;
  return -1;
}

}  // namespace gcpipe::dds
