// The streaming pipeline's commands: feed, node, sink, monitor (built with GCPIPE_WITH_DDS).
// Options come from main.cpp; the work is in stages/dds (gcpipe_dds) and the stage nodes.
#include <iostream>

#include "commands.hpp"
#include "compensate_node.hpp"
#include "dds_runtime.hpp"
#include "dds_tools.hpp"
#include "gcpipe/config.hpp"
#include "parse_node.hpp"
#include "program_stream.hpp"
#include "trochoid.hpp"
#include "trochoid_node.hpp"
#include "write_node.hpp"

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
  return o;
}

// The stage's declared edges (dds::edges), renamed by --in/--out.
void node_topics(const NodeArgs& a, std::string& in, std::string& out) {
  in = a.in.empty() ? dds::input_edge(a.stage).topic : a.in;
  out = a.out.empty() ? dds::output_edge(a.stage).topic : a.out;
  dds::check_topic_name(in);
  dds::check_topic_name(out);
  if (in == out) throw std::invalid_argument("--in and --out name the same topic '" + in + "'");
}

int run_node_of(const NodeArgs& a, const PipelineConfig& pc, dds::Participant& participant) {
  std::string in, out;
  node_topics(a, in, out);
  if (a.stage == "parse") {
    ParseOptions po = load_parse_options(pc.root.section("parse"));
    po.strict = po.strict || a.strict;
    ParseNode node(participant, po, pc.machine, ParseNodeOptions{a.batch_bytes, a.forever, in, out});
    return node.run();
  }
  if (a.stage == "trochoid") {
    // The trochoid stage's strict mode is batch mode's: parse.strict or --strict.
    TrochoidNodeOptions no{a.batch_bytes, a.forever, a.strict || load_parse_options(pc.root.section("parse")).strict, in, out};
    TrochoidNode node(participant, load_trochoid_options(pc.root.section("trochoid")), no);
    return node.run();
  }
  if (a.strict) throw std::invalid_argument("--strict belongs to the parse and trochoid nodes");
  if (a.stage == "write") {
    WriteNode node(participant, load_write_options(pc.root.section("write")), WriteNodeOptions{a.batch_bytes, a.forever, in, out});
    return node.run();
  }
  // compensate: the same model and options `gcpipe batch` compensates with (servo section required).
  CompensateNode node(participant, compensate::load_model(pc), compensate::load_compensate_options(pc.root.section("compensate")),
                      load_write_options(pc.root.section("write")), CompensateNodeOptions{a.batch_bytes, a.forever, in, out});
  return node.run();
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
  dds::install_stop_handlers();
  dds::Participant participant(dds_options(a));
  return run_node_of(a, pc, participant);
}

int run_sink(const SinkArgs& a) {
  dds::install_stop_handlers();
  dds::Participant participant(dds_options(a));
  return dds::run_sink(participant, dds::SinkOptions{a.output, a.in.empty() ? dds::kGcodeTopicName : a.in}, std::cerr);
}

int run_monitor(const MonitorArgs& a) {
  dds::MessageType type{};
  try {
    dds::check_topic_name(a.topic);
    if (!a.type.empty()) type = dds::message_type_from_name(a.type);
    else if (!dds::default_topic_type(a.topic, type))
      throw std::invalid_argument("topic '" + a.topic + "' is not one of the pipeline's; give its type with --type program|blocks|gcode");
  } catch (const std::exception& e) {
    std::cerr << "gcpipe monitor: " << e.what() << "\n";
    return 2;
  }
  dds::install_stop_handlers();
  dds::Participant participant(dds_options(a));
  return dds::run_monitor(participant, type, a.topic, a.period, std::cout);
}

}  // namespace gcpipe::cli
