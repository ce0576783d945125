// The streaming pipeline's commands: feed, node, sink, monitor (built with GCPIPE_WITH_DDS).
// Options come from main.cpp; the work is in stages/dds (gcpipe_dds): feed, sink, monitor and
// StageNode, which runs any registered stage.
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <memory>
#include <thread>
#include <vector>

#include "commands.hpp"
#include "dds_runtime.hpp"
#include "dds_tools.hpp"
#include "launcher.hpp"
#include "monitor.hpp"
#include "parse.hpp"
#include "stage.hpp"
#include "stage_node.hpp"
#include "gcpipe/config.hpp"
#include "program_stream.hpp"

namespace gcpipe::cli {

namespace {

dds::DdsOptions dds_options(const DdsArgs& a) {
  dds::DdsOptions o;
  o.domain = a.domain ? *a.domain : dds::default_domain(0);
  o.subscribers = a.subscribers;
  o.match_timeout = o.write_timeout = o.ack_timeout = a.timeout;
  o.idle_timeout = a.idle_timeout;
  o.monitor_history = a.monitor_history;
  o.heartbeat_timeout = a.heartbeat_timeout;
  // Eight beats within the timeout: a silence that long is not a few beats late on a busy core.
  o.heartbeat_period = a.heartbeat_timeout / 8;
  o.stall_timeout = a.stall_timeout;
  o.replay = a.replay;
  o.partition = a.partition;
  if (!a.profiles.empty()) o.profiles = a.profiles;
  o.network = a.network;
  o.identity = a.identity;
  return o;
}

// A monitor watches every pipeline on its domain unless told a partition: each `gcpipe stream`
// run has its own partition, `gcpipe launch` the default one.
// (Not with DDS Security: its permissions grant the default partition only, and a reader of
// another is refused at creation.)
dds::DdsOptions monitor_options(const MonitorArgs& a) {
  dds::DdsOptions o = dds_options(a);
  if (o.partition.empty() && o.identity.empty()) o.partition = "*";
  return o;
}

// --in, --out or --readers: none, or one value per stage.
template <class T>
void check_per_stage(const std::vector<T>& values, std::size_t stages, const char* option) {
  if (!values.empty() && values.size() != stages)
    throw std::invalid_argument(std::string(option) + " gives " + std::to_string(values.size()) + " values for " +
                                std::to_string(stages) + " stages: give one per stage, comma-separated");
}

// Stage k's node options: its declared edges (dds::edges) renamed by --in/--out, its readers.
dds::StageNodeOptions stage_node_options(const NodeArgs& a, std::size_t k) {
  const std::string& stage = a.stages[k];
  const pipeline::StageInfo& info = pipeline::find_stage(stage);
  if (*info.topic == '\0' && a.out.empty())
    throw std::invalid_argument("stage '" + stage + "' has no DDS node yet (nodes: every stage with a topic in gcpipe stages)");
  if (a.strict && stage != "parse" && stage != "trochoid")
    throw std::invalid_argument("--strict belongs to the parse and trochoid nodes, not " + stage);
  dds::StageNodeOptions o;
  o.stage = stage;
  o.input_topic = a.in.empty() ? pipeline::input_topic(stage) : a.in[k];
  o.output_topic = a.out.empty() ? std::string(info.topic) : a.out[k];
  dds::check_topic_name(o.input_topic);
  dds::check_topic_name(o.output_topic);
  if (o.input_topic == o.output_topic)
    throw std::invalid_argument("--in and --out name the same topic '" + o.input_topic + "'");
  o.subscribers = a.readers.empty() ? -1 : a.readers[k];
  o.batch_bytes = a.batch_bytes;
  o.forever = a.forever;
  o.strict = a.strict;
  o.pipeline_stages = a.pipeline_stages;
  o.report_dir = a.report_dir;
  o.report_readers = a.report_readers;
  o.program_id = a.program_id;
  return o;
}

// Every stage's options, or a usage error.
std::vector<dds::StageNodeOptions> group_options(const NodeArgs& a) {
  check_per_stage(a.in, a.stages.size(), "--in");
  check_per_stage(a.out, a.stages.size(), "--out");
  check_per_stage(a.readers, a.stages.size(), "--readers");
  std::vector<dds::StageNodeOptions> out;
  for (std::size_t k = 0; k < a.stages.size(); ++k) {
    if (std::find(a.stages.begin(), a.stages.begin() + static_cast<std::ptrdiff_t>(k), a.stages[k]) !=
        a.stages.begin() + static_cast<std::ptrdiff_t>(k))
      throw std::invalid_argument("stage '" + a.stages[k] + "' is given twice");
    out.push_back(stage_node_options(a, k));
  }
  return out;
}

}  // namespace

int run_feed(const FeedArgs& a) {
  dds::FeedOptions f;
  f.input = a.input;
  f.chunk_bytes = a.chunk_bytes != 0 ? a.chunk_bytes : a.rate > 0 ? dds::FeedOptions::kPacedChunkBytes : f.chunk_bytes;
  f.bytes_per_second = a.rate;
  f.program_id = a.program_id;
  f.topic = a.topic.empty() ? dds::kProgramTopicName : a.topic;
  // Cut lines exactly where batch mode's reader cuts them, so the parser sees the same text.
  f.max_line_length = load_parse_options(load_config_option(a.config).root.section("parse")).max_line_length;
  dds::install_stop_handlers();
  dds::Participant participant(dds_options(a));
  return dds::run_feed(participant, f, std::cerr);
}

int run_node(const NodeArgs& a) {
  const PipelineConfig pc = load_config_option(a.config);
  std::vector<dds::StageNodeOptions> stages;
  try {
    stages = group_options(a);
  } catch (const std::exception& e) {
    std::cerr << "gcpipe node: " << e.what() << "\n";
    return 2;
  }
  dds::install_stop_handlers();
  dds::DdsOptions options = dds_options(a);
  options.fail_on_lost_reader = !a.forever;
  dds::Participant participant(options);
  if (stages.size() == 1) return dds::StageNode(participant, pc, stages.front()).run();
  // A group: every node (reader, writers) is made before any runs, on one participant; then
  // each runs in its own thread, exactly as it would in a process of its own.
  std::vector<std::unique_ptr<dds::StageNode>> nodes;
  for (const auto& o : stages) nodes.push_back(std::make_unique<dds::StageNode>(participant, pc, o));
  dds::say_line("gcpipe node " + dds::joined(a.stages, '+') + ": up on domain " + std::to_string(options.domain) + ", " +
                std::to_string(nodes.size()) + " stages in one process");
  std::vector<int> status(nodes.size(), 0);
  std::vector<std::thread> threads;
  for (std::size_t k = 0; k < nodes.size(); ++k)
    threads.emplace_back([&, k] {
      try {
        status[k] = nodes[k]->run();
      } catch (const std::exception& e) {
        dds::say_line("gcpipe node " + stages[k].stage + ": " + e.what());
        status[k] = 1;
        // Its reader and writers go now, as they would with a process of its own: the stages
        // after it see its writer leave and end the program with the reason.
        nodes[k].reset();
      }
    });
  for (auto& t : threads) t.join();
  return *std::max_element(status.begin(), status.end());
}

int run_sink(const SinkArgs& a) {
  dds::install_stop_handlers();
  dds::Participant participant(dds_options(a));
  return dds::run_sink(participant, dds::SinkOptions{a.output, a.in.empty() ? dds::kGcodeTopicName : a.in, a.program_id},
                       std::cerr);
}

int run_report_sink(const ReportSinkArgs& a) {
  for (const auto& s : a.stages) pipeline::find_stage(s);  // an unknown name is an error, not a wait
  const PipelineConfig pc = load_config_option(a.config);
  dds::install_stop_handlers();
  dds::Participant participant(dds_options(a));
  dds::ReportSinkOptions o;
  o.dir = a.output;
  o.stages = a.stages;
  o.config_file = pc.root.file();
  o.machine = pc.machine.name;
  o.program_id = a.program_id;
  return dds::run_report_sink(participant, o, std::cerr);
}

// --pipeline: a pipeline file, or the name of one beside the shipped streaming.yaml.
int run_pipeline_monitor(const MonitorArgs& a) {
  namespace fs = std::filesystem;
  fs::path file = a.pipeline;
  if (!fs::exists(file)) file = default_streaming_file().parent_path() / (a.pipeline + ".yaml");
  if (!fs::exists(file)) {
    std::cerr << "gcpipe monitor: no pipeline file '" << a.pipeline << "' (nor " << file.string() << ")\n";
    return 2;
  }
  const dds::LaunchPlan plan = dds::load_launch_plan(file);
  dds::DdsOptions options = monitor_options(a);
  if (!a.domain) options.domain = dds::default_domain(plan.domain);  // --domain, $GCPIPE_DDS_DOMAIN, the file's
  if (!plan.profiles.empty() && a.profiles.empty()) options.profiles = plan.profiles;
  // The pipeline's network, but the monitor's own identity (the plan's is the nodes').
  if (!plan.network.empty() && a.network.empty()) options.network = plan.network;
  dds::install_stop_handlers();
  dds::Participant participant(options);
  return dds::run_pipeline_monitor(participant, plan.name, dds::watched_stages(plan.nodes), a.period, std::cout,
                                   a.plot);
}

int run_monitor(const MonitorArgs& a) {
  if (!a.pipeline.empty()) return run_pipeline_monitor(a);
  if (a.topic.empty()) {
    std::cerr << "gcpipe monitor: give a topic or --pipeline NAME (see gcpipe monitor --help)\n";
    return 2;
  }
  dds::MessageType type{};
  try {
    dds::check_topic_name(a.topic);
    if (!a.type.empty()) type = dds::message_type_from_name(a.type);
    else if (!dds::default_topic_type(a.topic, type))
      throw std::invalid_argument("topic '" + a.topic + "' is not one of the pipeline's; give its type with --type program|blocks|gcode|ik|samples");
    if (!a.plot.empty() && type != dds::MessageType::kSampleBatch)
      throw std::invalid_argument("--plot draws the simulated contour error: watch gcpipe_samples, not " + a.topic);
  } catch (const std::exception& e) {
    std::cerr << "gcpipe monitor: " << e.what() << "\n";
    return 2;
  }
  dds::install_stop_handlers();
  dds::Participant participant(monitor_options(a));
  return dds::run_monitor(participant, type, a.topic, a.period, std::cout, a.plot);
}

}  // namespace gcpipe::cli
