// The streaming pipeline's commands: feed, node, sink, monitor (built with GCPIPE_WITH_DDS).
// Options come from main.cpp; the work is in stages/dds (gcpipe_dds): feed, sink, monitor and
// StageNode, which runs any registered stage.
#include <filesystem>
#include <iostream>

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
  o.replay = a.replay;
  if (!a.profiles.empty()) o.profiles = a.profiles;
  o.network = a.network;
  o.identity = a.identity;
  return o;
}

// The stage's declared edges (dds::edges), renamed by --in/--out.
void node_topics(const NodeArgs& a, std::string& in, std::string& out) {
  const pipeline::StageInfo& info = pipeline::find_stage(a.stage);
  if (*info.topic == '\0' && a.out.empty())
    throw std::invalid_argument("stage '" + a.stage + "' has no DDS node yet (nodes: every stage with a topic in gcpipe stages)");
  in = a.in.empty() ? pipeline::input_topic(a.stage) : a.in;
  out = a.out.empty() ? std::string(info.topic) : a.out;
  dds::check_topic_name(in);
  dds::check_topic_name(out);
  if (in == out) throw std::invalid_argument("--in and --out name the same topic '" + in + "'");
}

}  // namespace

int run_feed(const FeedArgs& a) {
  dds::FeedOptions f;
  f.input = a.input;
  f.chunk_bytes = a.chunk_bytes;
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
  try {
    std::string in, out;
    node_topics(a, in, out);
  } catch (const std::exception& e) {
    std::cerr << "gcpipe node: " << e.what() << "\n";
    return 2;
  }
  if (a.strict && a.stage != "parse" && a.stage != "trochoid") {
    std::cerr << "gcpipe node: --strict belongs to the parse and trochoid nodes\n";
    return 2;
  }
  dds::install_stop_handlers();
  dds::DdsOptions options = dds_options(a);
  options.fail_on_lost_reader = !a.forever;
  dds::Participant participant(options);
  std::string in, out;
  node_topics(a, in, out);
  dds::StageNodeOptions o;
  o.stage = a.stage;
  o.batch_bytes = a.batch_bytes;
  o.forever = a.forever;
  o.strict = a.strict;
  o.input_topic = in;
  o.output_topic = out;
  o.pipeline_stages = a.pipeline_stages;
  o.report_dir = a.report_dir;
  o.report_readers = a.report_readers;
  dds::StageNode node(participant, pc, o);
  return node.run();
}

int run_sink(const SinkArgs& a) {
  dds::install_stop_handlers();
  dds::Participant participant(dds_options(a));
  return dds::run_sink(participant, dds::SinkOptions{a.output, a.in.empty() ? dds::kGcodeTopicName : a.in}, std::cerr);
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
  dds::DdsOptions options = dds_options(a);
  if (!a.domain) options.domain = plan.domain;
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
  dds::Participant participant(dds_options(a));
  return dds::run_monitor(participant, type, a.topic, a.period, std::cout, a.plot);
}

}  // namespace gcpipe::cli
