// The subcommands of `gcpipe`. Each command's options are a plain struct, declared on the command
// line in main.cpp (CLI11: the help text is generated from those declarations, so usage cannot
// drift from what is accepted), and run by run_<name>() in cmd_<name>.cpp, which returns the exit
// status: 0 ok, 3 finished with rejected lines, 1 stopped or failed, 2 usage, 130/143 interrupted.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace gcpipe::cli {

/// What every command that runs the pipeline on a program takes.
struct ProgramArgs {
  std::string input;      //!< program file, "-" = standard input
  std::string config;     //!< pipeline config; empty = pipeline_configs/default.yaml
  std::string tool_table; //!< a shop's tool table (LinuxCNC .tbl or YAML) instead of the machine file's tools
  bool strict = false;    //!< stop at the first rejected line
  bool progress = false;  //!< progress on stderr even when it is not a terminal
  bool no_progress = false;
};

struct BatchArgs : ProgramArgs {
  std::string outdir;
  bool quiet = false;
  bool no_simulate = false;
  bool keep_going = false;  //!< compensate a program with rejected lines (what was accepted)
  std::string model;        //!< neural IK model; given, the neural IK is compared on any program
};
int run_batch(const BatchArgs& args);

struct ParseArgs : ProgramArgs {
  std::string output = "-";
  bool json = false;
};
int run_parse(const ParseArgs& args);

struct TrochoidArgs : ProgramArgs {
  std::string output = "-";
  std::string png;
};
int run_trochoid(const TrochoidArgs& args);

struct IkArgs : ProgramArgs {
  std::string output = "-";
  std::string model;
  bool csv = false;
  bool tool_vector = false;
};
int run_ik(const IkArgs& args);

struct SimulateArgs : ProgramArgs {
  std::string output;
  std::string report;
  std::string circle;  //!< "R_C,R_W"
};
int run_simulate(const SimulateArgs& args);

struct ConfigArgs {
  std::string config;  //!< pipeline config; empty = pipeline_configs/default.yaml
  bool print = false;
};
int run_config(const ConfigArgs& args);

struct SynthArgs {
  double blocks = 0, megabytes = 0;
  int cam_segments = 0;  //!< > 0: a CAM-like 2.5D finishing pass instead (cam_like_program)
  std::uint64_t seed = 1;
  std::string output = "-";
};
int run_synth(const SynthArgs& args);

struct TrainIkArgs {
  std::string config, output, preset = "improved", trainer, c_output;
  std::uint64_t seed = 1;
  int samples = 0, max_iterations = 0;
  bool quiet = false;
};
int run_train_ik(const TrainIkArgs& args);

struct TrainSpindleArgs {
  std::vector<std::string> fit, verify;
  std::string output, png, quantity = "power";
  int hidden = 8, max_iterations = 40;
  bool quiet = false;
};
int run_train_spindle(const TrainSpindleArgs& args);

struct CalibrateArgs {
  std::vector<std::string> traces;
  std::string config, outdir, format;
  std::vector<std::string> columns;  // halsampler column map / SHDR item map
  double period = 0;                 // halsampler without a time column [s]
  bool skip_bad_rows = false, no_plots = false;
  bool progress = false, no_progress = false;
};
int run_calibrate(const CalibrateArgs& args);

struct EvaluateArgs {
  std::string trace, program, config, format, json, ran;
  std::vector<std::string> columns;
  double period = 0;
  bool skip_bad_rows = false;
};
int run_evaluate(const EvaluateArgs& args);

/// `gcpipe stages`: the registered stages, their edges and ports.
int run_stages();

#ifdef GCPIPE_WITH_DDS
/// What every DDS command takes (stages/dds/README.md).
struct DdsArgs {
  std::optional<int> domain;
  std::string profiles;
  std::string network;   //!< participant profile file for a shop network (dds_network_shop.xml)
  std::string identity;  //!< DDS Security identity folder (make_security.sh)
  int subscribers = 1;
  double timeout = 30;
  double idle_timeout = 0;
  double monitor_history = 5;  //!< [s] --monitor-history: what a late monitor still gets
  double heartbeat_timeout = 4;  //!< [s] --heartbeat-timeout: an edge writer this long silent is dead or frozen
  double stall_timeout = 10;     //!< [s] --stall-timeout: a stage this long working without progress is stalled
  std::string partition;       //!< --partition: DDS partition of every reader and writer
  bool replay = false;
};
struct FeedArgs : DdsArgs {
  std::string input, config, topic;
  std::size_t chunk_bytes = 0;  //!< 0: 128 KB, or 16 KB with --rate (dds::FeedOptions)
  double rate = 0;  //!< --rate [bytes/s]; 0 = unpaced
  std::uint64_t program_id = 0;
};
int run_feed(const FeedArgs& args);
struct NodeArgs : DdsArgs {
  /// One stage, or several run in this one process (a group: one thread and node per stage,
  /// one DDS participant); --in, --out and --readers then give one value per stage.
  std::vector<std::string> stages, in, out;
  std::vector<int> readers;  //!< --readers: readers of each stage's output (default --subscribers)
  std::string config;
  std::size_t batch_bytes = 128 * 1024;
  bool forever = false, strict = false;
  std::vector<std::string> pipeline_stages;  //!< --pipeline-stages
  std::string report_dir;                    //!< --report-dir
  int report_readers = 0;                    //!< --report-readers
  std::uint64_t program_id = 0;              //!< --program-id: the only program taken (0: any)
};
int run_node(const NodeArgs& args);
struct SinkArgs : DdsArgs {
  std::string output, in;
  std::uint64_t program_id = 0;  //!< --program-id: the only program taken (0: the first)
};
int run_sink(const SinkArgs& args);
struct ReportSinkArgs : DdsArgs {
  std::string output, config;
  std::vector<std::string> stages;
  std::uint64_t program_id = 0;  //!< --program-id: the only program taken (0: the first)
};
int run_report_sink(const ReportSinkArgs& args);
struct MonitorArgs : DdsArgs {
  std::string topic, type, pipeline;
  std::string plot;  //!< --plot FILE.png: the live contour-error figure
  double period = 1.0;
};
int run_monitor(const MonitorArgs& args);
struct LaunchArgs {
  std::string pipeline;  //!< the pipeline file
  std::optional<int> domain;
  bool verbose = false;
};
int run_launch(const LaunchArgs& args);
struct DdsCleanArgs {};
/// `gcpipe dds clean`: the shared memory of dead DDS processes on this host.
int run_dds_clean(const DdsCleanArgs& args);
struct StreamArgs : LaunchArgs {
  std::string input, output;
  std::string config;    //!< --config: replaces the pipeline file's config
  double feed_rate = 0;  //!< --feed-rate: the feed's --rate [bytes/s]; 0 = unpaced
};
int run_stream(const StreamArgs& args);

/// Runs the DDS command `name` (feed, node, sink, monitor, launch, stream; `args` its *Args) from
/// the plugin gcpipe_dds_commands.so beside the executable, which defines the run_* above: the
/// other commands do not load Fast DDS. Throws std::runtime_error when the plugin cannot be loaded.
int run_dds_command(const char* name, const void* args);
#endif

}  // namespace gcpipe::cli
