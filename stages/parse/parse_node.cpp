#include "parse_node.hpp"

#include <chrono>
#include <iostream>
#include <map>
#include <optional>
#include <set>

#include "dds_convert.hpp"
#include "dds_runtime.hpp"

namespace gcpipe {

namespace {

// One program in flight. Programs are told apart by id, so several feeders may share the topic.
struct Program {
  std::string file;
  std::optional<Parser> parser;
  std::uint64_t next_chunk = 0;   // sequence number expected next
  std::uint64_t lines_seen = 0;   // source lines received so far
  std::uint64_t next_batch = 0;
  msg::BlockBatch batch;
  std::size_t batch_size = 0;     // serialized size of `batch` so far [bytes]
  std::uint64_t blocks_sent = 0, diagnostics_sent = 0;
  bool stopped = false;           // strict mode met a rejected line
  std::string error;              // first sign of lost input; parsing stops there
};

}  // namespace

struct ParseNode::Impl {
  dds::Participant& participant;
  ParseOptions parse_options;
  MachineConfig machine;
  ParseNodeOptions options;
  dds::Reader<msg::ProgramChunk> reader;
  dds::Writer<msg::BlockBatch> writer;
  std::map<std::uint64_t, Program> programs;
  std::set<std::uint64_t> skipped;  // programs published before this node started
  int status = 0;

  Impl(dds::Participant& p, ParseOptions po, MachineConfig m, ParseNodeOptions o)
      : participant(p), parse_options(po), machine(std::move(m)), options(o),
        reader(p, o.input_topic), writer(p, o.output_topic) {}

  bool publish(std::uint64_t id, Program& prog) {
    prog.batch.program_id(id);
    prog.batch.file(prog.file);
    prog.batch.sequence_number(prog.next_batch++);
    prog.batch.strict(parse_options.strict);
    if (!writer.publish(prog.batch)) return false;
    prog.blocks_sent += prog.batch.blocks().size();
    prog.diagnostics_sent += prog.batch.diagnostics().size();
    prog.batch.blocks().clear();
    prog.batch.diagnostics().clear();
    prog.batch_size = 0;
    return true;
  }

  void fail(Program& prog, std::uint64_t id, std::string why) {
    if (!prog.error.empty()) return;
    prog.error = std::move(why);
    std::cerr << "gcpipe node parse: program " << id << " (" << prog.file << "): " << prog.error
              << "\n";
  }

  // What the parser makes goes into the batch; a line may make several blocks (a canned cycle,
  // a subroutine call), or make them later (a loop runs when its end arrives).
  ParseSink batch_sink(Program& prog) {
    return ParseSink{[this, &prog](const ResolvedBlock& block) {
                       msg::Block& m = prog.batch.blocks().emplace_back();
                       dds::to_msg(block, m);
                       prog.batch_size += msg::Block::getCdrSerializedSize(m);
                       return true;
                     },
                     [this, &prog](const Diagnostic& diag) {
                       const LineStatus st = status_of(diag);
                       msg::LineDiagnostic& m = prog.batch.diagnostics().emplace_back();
                       dds::to_msg(diag, dds::kind_of(st), m);
                       prog.batch_size += msg::LineDiagnostic::getCdrSerializedSize(m);
                       if (st == LineStatus::kRejected && parse_options.strict) prog.stopped = true;
                       return !prog.stopped;
                     }};
  }

  void parse_lines(Program& prog, std::uint64_t id, const msg::ProgramChunk& chunk) {
    const ParseSink sink = batch_sink(prog);
    const std::size_t max_line = parse_options.max_line_length;
    for (std::size_t k = 0; k < chunk.lines().size(); ++k) {
      const std::uint64_t number = chunk.first_line() + k;
      if (number != prog.lines_seen + 1) {
        fail(prog, id, "chunk " + std::to_string(chunk.sequence_number()) + " starts at line " +
                           std::to_string(chunk.first_line()) + ", expected line " +
                           std::to_string(prog.lines_seen + 1));
        return;
      }
      prog.lines_seen = number;
      if (prog.stopped || !prog.error.empty()) continue;
      const msg::SourceLine& src = chunk.lines()[k];
      // Cut as batch mode's LineReader does when the feeder's limit was larger than ours.
      std::string_view text = src.text();
      std::size_t overlong = src.full_length();
      if (text.size() > max_line) {
        if (overlong == 0) overlong = text.size();
        text = text.substr(0, max_line);
      }
      prog.parser->feed(text, sink, overlong);
      if (prog.batch_size >= options.batch_bytes && !publish(id, prog)) return;
    }
  }

  // Returns true when the program is finished (end marker published).
  bool handle(const msg::ProgramChunk& chunk, double source_time) {
    const std::uint64_t id = chunk.program_id();
    if (skipped.count(id) != 0) {
      if (chunk.end_of_program()) skipped.erase(id);
      return false;
    }
    const bool inserted = programs.count(id) == 0;
    if (inserted && participant.published_before_start(source_time)) {
      // Replayed from the feeder's history: an old program, not one sent to this node.
      std::cerr << "gcpipe node parse: skipping program " << id << " ('" << chunk.file()
                << "'), published before this node started (--replay takes it)\n";
      if (!chunk.end_of_program()) skipped.insert(id);
      return false;
    }
    auto it = programs.try_emplace(id).first;
    Program& prog = it->second;
    if (inserted) {
      prog.file = chunk.file();
      prog.parser.emplace(parse_options, machine, chunk.file());
      if (chunk.sequence_number() != 0)
        fail(prog, id, "joined the program at chunk " + std::to_string(chunk.sequence_number()) +
                           ": its beginning is no longer available from the feeder");
      prog.next_chunk = chunk.sequence_number();
    }
    if (chunk.sequence_number() != prog.next_chunk)
      fail(prog, id, "chunk " + std::to_string(prog.next_chunk) + " is missing (got chunk " +
                         std::to_string(chunk.sequence_number()) + ")");
    prog.next_chunk = chunk.sequence_number() + 1;
    parse_lines(prog, id, chunk);
    if (!chunk.end_of_program()) return false;

    if (prog.error.empty() && chunk.line_count() != prog.lines_seen)
      fail(prog, id, "the feeder sent " + std::to_string(chunk.line_count()) +
                         " lines but " + std::to_string(prog.lines_seen) + " arrived");
    if (!prog.stopped && prog.error.empty()) prog.parser->finish(batch_sink(prog));
    prog.batch.end_of_program(true);
    dds::BatchTotals totals;
    totals.summary = prog.parser->summary();
    // Counted before publishing, as the end marker must state them: what went out plus itself.
    totals.blocks_sent = prog.blocks_sent + prog.batch.blocks().size();
    totals.diagnostics_sent = prog.diagnostics_sent + prog.batch.diagnostics().size();
    totals.stopped = prog.stopped;
    dds::set_totals(totals, prog.batch);
    prog.batch.error(prog.error);
    if (!prog.error.empty()) status = 1;
    publish(id, prog);
    const ParseSummary& sum = prog.parser->summary();
    std::cerr << "gcpipe node parse: program " << id << " '" << prog.file << "': "
              << sum.lines_read << " lines read, " << sum.blocks_emitted << " blocks, "
              << sum.lines_rejected << " rejected, " << sum.lines_deleted << " deleted, in "
              << prog.next_batch << " batches" << (prog.stopped ? " (strict stop)" : "")
              << "; writes retried on a full history: " << writer.blocked_writes() << "\n";
    programs.erase(it);
    return true;
  }
};

ParseNode::ParseNode(dds::Participant& participant, ParseOptions parse_options,
                     MachineConfig machine, ParseNodeOptions node_options)
    : impl_(std::make_unique<Impl>(participant, parse_options, std::move(machine), node_options)) {}

ParseNode::~ParseNode() = default;

int ParseNode::run() {
  return dds::run_reader_node(
      "parse", impl_->participant, impl_->reader, impl_->writer, impl_->options.forever,
      [this](const msg::ProgramChunk& sample, double source_time) { return impl_->handle(sample, source_time); },
      impl_->status);
}

}  // namespace gcpipe
