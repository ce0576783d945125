// The streaming pipeline's commands: feed, node, sink, monitor (built with GCPIPE_WITH_DDS).
// Argument parsing only; the work is in stages/dds (gcpipe_dds) and the stage nodes.
#include <cmath>
#include <iostream>

#include "command.hpp"
#include "commands.hpp"
#include "dds_runtime.hpp"
#include "dds_tools.hpp"
#include "gcpipe/config.hpp"
#include "parse_node.hpp"
#include "program_stream.hpp"
#include "trochoid.hpp"
#include "trochoid_node.hpp"
#include "write_node.hpp"
#include "compensate_node.hpp"

namespace gcpipe::cli {
namespace {

#define GCPIPE_DDS_OPTIONS_HELP                                                                  \
  "DDS options (every command):\n"                                                             \
  "  --domain N          DDS domain id 0..232 (default $GCPIPE_DDS_DOMAIN, else 0); parallel\n"  \
  "                      pipelines on one host need distinct domains\n"                         \
  "  --profiles FILE     QoS/transport profiles (default $GCPIPE_DDS_PROFILES, else\n"          \
  "                      pipeline_configs/dds_profiles.xml)\n"                                   \
  "  --subscribers N     readers a publisher waits for before its first sample (default 1)\n"   \
  "  --timeout S         longest wait for readers, for a blocked write and for the final\n"      \
  "                      acknowledgements [s] (default 30)\n"                                    \
  "  --idle-timeout S    a consumer gives up after S seconds without a sample; 0 = never\n"      \
  "                      (default 0)\n"

// Reads the options above; returns false (after setting `error`) on a bad value.
bool dds_options(Args& args, dds::DdsOptions& o, std::string& error) {
  o.domain = dds::default_domain(0);
  const double domain = args.number_or("--domain", o.domain);
  const double subscribers = args.number_or("--subscribers", o.subscribers);
  const double timeout = args.number_or("--timeout", 30);
  o.idle_timeout = args.number_or("--idle-timeout", 0);
  if (!args.ok()) {
    error = args.error();
    return false;
  }
  if (domain < 0 || domain > 232 || domain != std::floor(domain)) {
    error = "--domain " + args.value_or("--domain", "") + ": a DDS domain id is an integer in [0, 232]";
    return false;
  }
  if (subscribers < 1 || subscribers > 100 || subscribers != std::floor(subscribers)) {
    error = "--subscribers must be an integer in [1, 100]";
    return false;
  }
  if (!(timeout > 0) || o.idle_timeout < 0) {
    error = "--timeout must be > 0 s and --idle-timeout >= 0 s";
    return false;
  }
  o.domain = static_cast<int>(domain);
  o.subscribers = static_cast<int>(subscribers);
  o.match_timeout = o.write_timeout = o.ack_timeout = timeout;
  o.replay = args.flag("--replay");
  if (auto p = args.value("--profiles")) o.profiles = *p;
  return true;
}

// Args takes initializer lists; these wrappers keep the option lists in one place.
#define GCPIPE_DDS_VALUES "--domain", "--profiles", "--subscribers", "--timeout", "--idle-timeout"

std::size_t size_option(Args& args, std::string_view name, std::size_t fallback) {
  const double v = args.number_or(name, static_cast<double>(fallback));
  if (v < 1024 || v > 1048576 || v != std::floor(v)) return 0;
  return static_cast<std::size_t>(v);
}

int run_feed(const std::vector<std::string>& argv) {
  Args args(argv, {GCPIPE_DDS_VALUES, "--config", "--chunk-bytes", "--program-id", "--out"}, {});
  dds::DdsOptions o;
  std::string error;
  if (!args.ok() || !dds_options(args, o, error))
    return usage_error(kFeedCommand, args.ok() ? error : args.error());
  if (args.positional().size() != 1) return usage_error(kFeedCommand, "give exactly one program");
  dds::FeedOptions f;
  f.input = args.positional()[0];
  f.chunk_bytes = size_option(args, "--chunk-bytes", f.chunk_bytes);
  const double id = args.number_or("--program-id", 0);
  if (!args.ok() || f.chunk_bytes == 0 || id < 0)
    return usage_error(kFeedCommand, args.ok() ? "--chunk-bytes must be in [1024, 1048576], "
                                                 "--program-id >= 0" : args.error());
  f.program_id = static_cast<std::uint64_t>(id);
  f.topic = args.value_or("--out", dds::kProgramTopicName);
  // Cut lines exactly where batch mode's reader cuts them, so the parser sees the same text.
  const PipelineConfig pc = load_config_option(args.value_or("--config", ""));
  f.max_line_length = load_parse_options(pc.root.section("parse")).max_line_length;
  dds::install_stop_handlers();
  dds::Participant participant(o);
  return dds::run_feed(participant, f, std::cerr);
}

int run_node(const std::vector<std::string>& argv) {
  Args args(argv, {GCPIPE_DDS_VALUES, "--config", "--batch-bytes", "--in", "--out"},
            {"--forever", "--strict", "--replay"});
  dds::DdsOptions o;
  std::string error;
  if (!args.ok() || !dds_options(args, o, error))
    return usage_error(kNodeCommand, args.ok() ? error : args.error());
  if (args.positional().size() != 1)
    return usage_error(kNodeCommand, "name the stage: gcpipe node parse|trochoid|write|compensate");
  const std::string& stage = args.positional()[0];
  const std::size_t batch_bytes = size_option(args, "--batch-bytes", 32 * 1024);
  if (!args.ok() || batch_bytes == 0)
    return usage_error(kNodeCommand, "--batch-bytes must be an integer in [1024, 1048576]");
  const bool forever = args.flag("--forever");
  // Each stage's default edge topics; --in/--out rename them (e.g. write --in gcpipe_blocks
  // runs the pipeline without the trochoid node).
  auto topics = [&args](const char* in, const char* out, std::string& in_topic,
                        std::string& out_topic, std::string& why) {
    in_topic = args.value_or("--in", in);
    out_topic = args.value_or("--out", out);
    try {
      dds::check_topic_name(in_topic);
      dds::check_topic_name(out_topic);
    } catch (const std::exception& e) {
      why = e.what();
      return false;
    }
    if (in_topic == out_topic) {
      why = "--in and --out name the same topic '" + in_topic + "'";
      return false;
    }
    return true;
  };
  const PipelineConfig pc = load_config_option(args.value_or("--config", ""));
  if (stage == "parse") {
    ParseOptions po = load_parse_options(pc.root.section("parse"));
    if (args.flag("--strict")) po.strict = true;
    ParseNodeOptions no{batch_bytes, forever};
    if (!topics(dds::kProgramTopicName, dds::kBlocksTopicName, no.input_topic, no.output_topic, error))
      return usage_error(kNodeCommand, error);
    dds::install_stop_handlers();
    dds::Participant participant(o);
    ParseNode node(participant, po, pc.machine, no);
    return node.run();
  }
  if (stage == "trochoid") {
    // The trochoid stage's strict mode is batch mode's: parse.strict or --strict.
    TrochoidNodeOptions no;
    no.batch_bytes = batch_bytes;
    no.forever = forever;
    no.strict = args.flag("--strict") || load_parse_options(pc.root.section("parse")).strict;
    if (!topics(dds::kBlocksTopicName, dds::kToolpathTopicName, no.input_topic, no.output_topic, error))
      return usage_error(kNodeCommand, error);
    const TrochoidOptions to = load_trochoid_options(pc.root.section("trochoid"));
    dds::install_stop_handlers();
    dds::Participant participant(o);
    TrochoidNode node(participant, to, no);
    return node.run();
  }
  if (stage == "write") {
    if (args.flag("--strict"))
      return usage_error(kNodeCommand, "--strict belongs to the parse and trochoid nodes");
    WriteOptions wo = load_write_options(pc.root.section("write"));
    WriteNodeOptions no{batch_bytes, forever};
    if (!topics(dds::kToolpathTopicName, dds::kGcodeTopicName, no.input_topic, no.output_topic, error))
      return usage_error(kNodeCommand, error);
    dds::install_stop_handlers();
    dds::Participant participant(o);
    WriteNode node(participant, wo, no);
    return node.run();
  }
  if (stage == "compensate") {
    if (args.flag("--strict"))
      return usage_error(kNodeCommand, "--strict belongs to the parse and trochoid nodes");
    // The same model and options `gcpipe batch` compensates with (servo section required).
    const compensate::Model model = compensate::load_model(pc);
    const compensate::CompensateOptions co = compensate::load_compensate_options(pc.root.section("compensate"));
    const WriteOptions wo = load_write_options(pc.root.section("write"));
    CompensateNodeOptions no{batch_bytes, forever};
    if (!topics(dds::kToolpathTopicName, dds::kCompensatedTopicName, no.input_topic, no.output_topic, error))
      return usage_error(kNodeCommand, error);
    dds::install_stop_handlers();
    dds::Participant participant(o);
    CompensateNode node(participant, model, co, wo, no);
    return node.run();
  }
  return usage_error(kNodeCommand, "unknown stage '" + stage + "' (known: parse, trochoid, write, compensate)");
}

int run_sink(const std::vector<std::string>& argv) {
  Args args(argv, {GCPIPE_DDS_VALUES, "-o", "--in"}, {"--replay"});
  dds::DdsOptions o;
  std::string error;
  if (!args.ok() || !dds_options(args, o, error))
    return usage_error(kSinkCommand, args.ok() ? error : args.error());
  if (!args.value("-o") || !args.positional().empty())
    return usage_error(kSinkCommand, "give the output file with -o OUT.nc (and nothing else)");
  dds::install_stop_handlers();
  dds::Participant participant(o);
  return dds::run_sink(participant,
                       dds::SinkOptions{*args.value("-o"), args.value_or("--in", dds::kGcodeTopicName)},
                       std::cerr);
}

int run_monitor(const std::vector<std::string>& argv) {
  Args args(argv, {GCPIPE_DDS_VALUES, "--period", "--type"}, {});
  dds::DdsOptions o;
  std::string error;
  if (!args.ok() || !dds_options(args, o, error))
    return usage_error(kMonitorCommand, args.ok() ? error : args.error());
  const double period = args.number_or("--period", 1.0);
  if (!args.ok() || !(period >= 0.05 && period <= 3600))
    return usage_error(kMonitorCommand, "--period must be in [0.05, 3600] s");
  if (args.positional().size() != 1)
    return usage_error(kMonitorCommand, "name one topic, e.g. gcpipe_blocks");
  const std::string topic = args.positional()[0];
  dds::MessageType type{};
  try {
    dds::check_topic_name(topic);
    if (auto t = args.value("--type")) type = dds::message_type_from_name(*t);
    else if (!dds::default_topic_type(topic, type))
      return usage_error(kMonitorCommand, "topic '" + topic + "' is not one of the default names; "
                                          "give its type with --type program|blocks|gcode");
  } catch (const std::exception& e) {
    return usage_error(kMonitorCommand, e.what());
  }
  dds::install_stop_handlers();
  dds::Participant participant(o);
  return dds::run_monitor(participant, type, topic, period, std::cout);
}

}  // namespace

constinit const Command kFeedCommand{
    "feed", "publish a program on the DDS pipeline (topic gcpipe_program)",
    "Usage: gcpipe feed IN.nc [--config CFG] [--chunk-bytes N] [--program-id ID] [--out TOPIC]\n"
    "                         [DDS options]\n"
    "\n"
    "Publishes the program's lines (IN.nc '-' = standard input) on gcpipe_program (or TOPIC)\n"
    "in chunks of about N bytes (default 32768),\n"
    "cut at parse.max_line_length of CFG as batch mode cuts them, then an end marker with the\n"
    "line count. Waits for the parse node before the first chunk and for its acknowledgement\n"
    "of the last one. The streaming pipeline, each command in its own process:\n"
    "  gcpipe sink -o OUT.nc & gcpipe node write & gcpipe node trochoid &\n"
    "  gcpipe node parse & gcpipe feed IN.nc\n"
    "OUT.nc is byte-identical to `gcpipe batch IN.nc -o DIR`'s DIR/output.nc.\n"
    "\n" GCPIPE_DDS_OPTIONS_HELP,
    run_feed};

constinit const Command kNodeCommand{
    "node", "run a pipeline stage as a DDS node: node parse | trochoid | write | compensate",
    "Usage: gcpipe node parse|trochoid|write|compensate [--config CFG] [--strict] [--forever]\n"
    "                 [--batch-bytes N] [--in TOPIC] [--out TOPIC] [--replay] [DDS options]\n"
    "\n"
    "  parse     reads gcpipe_program, runs the parser, publishes resolved blocks and line\n"
    "            diagnostics on gcpipe_blocks in batches of about N bytes (default 32768)\n"
    "  trochoid  reads gcpipe_blocks, expands G275 cycles (others copied), publishes on\n"
    "            gcpipe_toolpath in batches of about N bytes\n"
    "  write     reads gcpipe_toolpath, runs the G-code writer, publishes the text on\n"
    "            gcpipe_gcode in chunks of about N bytes\n"
    "  compensate  reads gcpipe_toolpath, collects each whole program, runs the batch job's\n"
    "            simulation and compensation (needs the config's servo section) and publishes\n"
    "            compensated.nc on gcpipe_compensated; beside the write node:\n"
    "              gcpipe sink --in gcpipe_compensated -o compensated.nc & gcpipe node compensate\n"
    "            (start the trochoid node with --subscribers 2 when write and compensate both read)\n"
    "            gives the bytes of `gcpipe batch`'s compensated.nc\n"
    "--in/--out rename the topics read/written; without the trochoid node:\n"
    "  gcpipe node write --in gcpipe_blocks\n"
    "Leaves after the first program's end marker (exit 0, or 1 when input went missing), or\n"
    "with --forever serves programs until SIGINT/SIGTERM. --strict (parse, trochoid) stops\n"
    "each program at its first rejected line or cycle, like `gcpipe batch --strict`; the\n"
    "trochoid node also follows the parse node's mode. Programs published\n"
    "before the node started (replayed from a writer's history) are skipped unless --replay.\n"
    "\n" GCPIPE_DDS_OPTIONS_HELP,
    run_node};

constinit const Command kSinkCommand{
    "sink", "write the program arriving on the DDS pipeline (topic gcpipe_gcode) to a file",
    "Usage: gcpipe sink -o OUT.nc [--in TOPIC] [--replay] [DDS options]\n"
    "\n"
    "Writes the first program arriving on gcpipe_gcode (or TOPIC) to OUT.nc and leaves after its end\n"
    "marker. Programs published before the sink started (replayed from the history of a\n"
    "write node serving with --forever) are skipped unless --replay. Before leaving it checks\n"
    "that no chunk or byte is missing, that no node reported lost input (each checks its own\n"
    "input edge) and that the parser's counts add up. The file appears only when complete\n"
    "(else OUT.nc.part).\n"
    "Exit status as gcpipe batch: 0 all lines and cycles accepted, 3 some rejected, 1 stopped by\n"
    "--strict or data lost (the message says which), 2 usage.\n"
    "\n" GCPIPE_DDS_OPTIONS_HELP,
    run_sink};

constinit const Command kMonitorCommand{
    "monitor", "print a live summary of a DDS pipeline topic",
    "Usage: gcpipe monitor TOPIC [--type program|blocks|gcode] [--period S] [DDS options]\n"
    "\n"
    "TOPIC: any topic; the default names gcpipe_program, gcpipe_blocks, gcpipe_toolpath and\n"
    "gcpipe_gcode imply their type, any other name needs --type.\n"
    "Prints one line every S seconds (default 1): batches, items (lines, blocks or bytes) and\n"
    "their rate, the last source line, errors (rejected lines and cycles); then the\n"
    "end-of-program counts, and\n"
    "leaves (exit 0). Started late, it still gets what the writer keeps (the last 256 batches,\n"
    "always including the end marker while the writer is alive). Ctrl-C leaves (exit 130).\n"
    "\n" GCPIPE_DDS_OPTIONS_HELP,
    run_monitor};

}  // namespace gcpipe::cli
