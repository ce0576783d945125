// `gcpipe launch` and `gcpipe stream`: a pipeline file names the stages that run as DDS nodes;
// the supervisor starts one `gcpipe node STAGE` process per stage (any order: every publisher
// waits for its readers), waits until each says it is ready, prints one status line per process,
// stops them all on SIGINT/SIGTERM, and on a crash either stops the pipeline (exit status names
// the stage) or starts the stage again, as the file says. POSIX processes only: nothing here
// includes Fast DDS, the nodes do.
#pragma once

#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace gcpipe::dds {

/// Set by the supervisor for the processes it starts: its pid.
inline constexpr const char* kSupervisorPidVariable = "GCPIPE_SUPERVISOR_PID";

/// In a process started by a supervisor: SIGTERM when the supervisor dies, however it dies
/// (prctl PR_SET_PDEATHSIG), and at once if it is already gone. Nothing otherwise.
void follow_supervisor();

/// A pipeline file (pipeline_configs/pipelines/streaming.yaml; format in stages/dds/README.md).
struct LaunchPlan {
  std::string name;                 //!< for status lines
  int domain = 0;                   //!< DDS domain id: two pipelines on one host take two ids
  std::filesystem::path config;     //!< the pipeline config every node reads
  std::filesystem::path profiles;   //!< QoS/transport profiles; empty: the nodes' default
  std::filesystem::path network;    //!< participant profile for a shop network; empty: this host only
  std::filesystem::path identity;   //!< DDS Security identity of the nodes; empty: no security
  bool restart = false;             //!< on a crash: start the stage again (else stop the pipeline)
  int max_restarts = 3;             //!< per stage, then the pipeline stops
  /// [s] between a crash and the restart: the crashed process's participant must be gone from
  /// its peers first (the discovery lease, 8 s), or the restarted one, which takes the same
  /// ports, can stay deaf to them (see stages/dds/README.md, "Crash")
  double restart_delay = 9;
  double ready_timeout = 30;        //!< [s] every process must say it is ready by then
  double stop_timeout = 5;          //!< [s] after SIGTERM, then SIGKILL
  double timeout = 30;              //!< [s] the nodes' --timeout: longest wait for readers, a blocked
                                    //!< write, acknowledgements (then the node stops, loudly)
  double monitor_history = 5;       //!< [s] what a late monitor still gets (--monitor-history)
  double heartbeat_timeout = 4;     //!< [s] an edge writer this long silent is dead or frozen (--heartbeat-timeout)
  double stall_timeout = 10;        //!< [s] a stage this long working without progress is stalled (--stall-timeout)
  std::vector<std::string> nodes;   //!< registered stages with a DDS node, in chain order
  /// Stages run together in one process (`groups: [parse+trochoid+write]`), each group in
  /// chain order; a stage of no group runs in a process of its own.
  std::vector<std::vector<std::string>> groups;
};

/// Reads and checks a pipeline file; throws ConfigError naming file, line and key.
LaunchPlan load_launch_plan(const std::filesystem::path& file);

/// One supervised process: gcpipe with `args`.
struct LaunchProcess {
  std::string name;
  std::vector<std::string> args;
  std::string ready_text;  //!< a line of its output containing this: ready; empty: ready at start
  bool one_shot = false;   //!< expected to exit (a feed, a sink): an exit in `ok_statuses` is not a crash
  std::vector<int> ok_statuses{0};  //!< a sink's 3 (lines rejected) is a result, as batch's 3
};

/// The node processes of `plan`: `node STAGE --config --domain --subscribers N [--forever]`, where
/// N counts the plan's nodes that read the stage's output topic plus `extra_readers[topic]`
/// (sinks), so that nobody has to count readers by hand.
std::vector<LaunchProcess> node_processes(const LaunchPlan& plan, bool forever,
                                          const std::map<std::string, int>& extra_readers = {});

/// Arguments every process of the plan gets: --domain, --profiles.
std::vector<std::string> plan_dds_args(const LaunchPlan& plan);

/// `parts` with `separator` between them: a group's name (parse+trochoid), a comma list for an option.
std::string joined(const std::vector<std::string>& parts, char separator);

class Supervisor {
 public:
  /// `exe`: the gcpipe executable to start; `verbose`: forward every line of every process.
  Supervisor(std::filesystem::path exe, const LaunchPlan& plan, std::ostream& log, bool verbose);
  ~Supervisor();
  Supervisor(const Supervisor&) = delete;
  Supervisor& operator=(const Supervisor&) = delete;

  void add(LaunchProcess p);
  /// Starts every process added; false (and all stopped) when one could not be started.
  bool start();
  /// Supervises until every one-shot process has exited (with launch's forever nodes: until
  /// stopped (SIGINT/SIGTERM), a crash the plan does not restart, or a process not ready
  /// within ready_timeout. Stops whatever still runs, then returns 0 on success; 1 with message()
  /// naming the stage otherwise; 130 when stopped by a signal.
  int run();
  const std::string& message() const { return message_; }
  /// Exit status of a process that ended (-1 while it runs; 128 + signal when killed).
  int exit_status(const std::string& name) const;

 private:
  struct Child {
    LaunchProcess spec;
    int pid = -1;
    int out_fd = -1;
    std::string partial;            //!< output not yet ended by a newline
    std::deque<std::string> tail;   //!< last lines, printed when it fails
    bool ready = false;
    int status = -1;
    int restarts = 0;
    double started_at = 0;
    double restart_at = -1;         //!< [s] when a crashed process is started again (-1: none due)
  };
  bool spawn(Child& c);
  void await_up(Child& c);
  void say_if_all_ready();
  void read_output(Child& c, bool drain);
  void on_line(Child& c, const std::string& line);
  bool reap(Child& c, bool& fatal);
  bool restart_if_due(Child& c);
  void stop_all();
  void sample_shm();
  void status_line(const Child& c, const std::string& what);
  double now() const;

  std::filesystem::path exe_;
  LaunchPlan plan_;
  std::ostream& log_;
  bool verbose_;
  std::vector<Child> children_;
  std::string message_;
  bool any_killed_ = false;
  bool all_ready_said_ = false;
  std::set<std::string> shm_seen_;  //!< /dev/shm files the children mapped
  double next_shm_sample_ = 0;
  double t0_ = 0;
};

}  // namespace gcpipe::dds
