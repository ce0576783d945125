#include "write_node.hpp"

#include <chrono>
#include <iostream>
#include <map>
#include <set>

#include "dds_convert.hpp"
#include "dds_runtime.hpp"

namespace gcpipe {

namespace {

struct Program {
  explicit Program(const WriteOptions& o) : writer(o) {}
  Writer writer;
  std::string file;
  std::uint64_t next_batch = 0;
  std::uint64_t next_chunk = 0;
  dds::BatchArrivals arrived;
  std::uint64_t bytes = 0;        // text published so far [bytes]
  std::uint64_t last_line = 0;    // last source line written
  std::string text;               // text not yet published
  std::string error;
};

}  // namespace

struct WriteNode::Impl {
  dds::Participant& participant;
  WriteOptions write_options;
  WriteNodeOptions options;
  dds::Reader<msg::BlockBatch> reader;
  dds::Writer<msg::GcodeChunk> writer;
  std::map<std::uint64_t, Program> programs;
  std::set<std::uint64_t> skipped;  // programs published before this node started
  int status = 0;
  msg::GcodeChunk chunk;

  Impl(dds::Participant& p, WriteOptions wo, WriteNodeOptions o)
      : participant(p), write_options(wo), options(o), reader(p, o.input_topic),
        writer(p, o.output_topic) {}

  bool publish(std::uint64_t id, Program& prog) {
    chunk.program_id(id);
    chunk.file(prog.file);
    chunk.sequence_number(prog.next_chunk++);
    chunk.last_line(prog.last_line);
    prog.bytes += prog.text.size();
    chunk.text().swap(prog.text);
    const bool ok = writer.publish(chunk);
    prog.text.clear();
    return ok;
  }

  void fail(Program& prog, std::uint64_t id, const std::string& why) {
    if (!prog.error.empty()) return;
    prog.error = why;
    std::cerr << "gcpipe node write: program " << id << " (" << prog.file << "): " << why << "\n";
  }

  void write_batch(Program& prog, std::uint64_t id, const msg::BlockBatch& batch) {
    ResolvedBlock block;
    Diagnostic diag;
    dds::DiagnosticKind kind{};
    std::string why;
    const auto& blocks = batch.blocks();
    const auto& diags = batch.diagnostics();
    auto flush = [&] { return prog.text.size() < options.chunk_bytes || publish(id, prog); };
    dds::for_each_in_line_order(
        batch,
        [&](std::size_t b) {
          if (!dds::from_msg(blocks[b], block, &why)) {
            fail(prog, id, "batch " + std::to_string(batch.sequence_number()) + ", line " +
                               std::to_string(blocks[b].line()) + ": " + why);
            return false;
          }
          ++prog.arrived.blocks;
          prog.last_line = block.line;
          prog.writer.write(block, prog.text);
          return flush();
        },
        [&](std::size_t d) {
          if (!dds::from_msg(diags[d], diag, kind, &why)) {
            fail(prog, id, "batch " + std::to_string(batch.sequence_number()) + ", line " +
                               std::to_string(diags[d].line()) + ": " + why);
            return false;
          }
          prog.arrived.count(kind);
          prog.last_line = diag.line;
          prog.writer.write_diagnostic(diag, prog.text);
          return flush();
        });
  }

  bool handle(const msg::BlockBatch& batch, double source_time) {
    const std::uint64_t id = batch.program_id();
    if (skipped.count(id) != 0) {
      if (batch.end_of_program()) skipped.erase(id);
      return false;
    }
    auto it = programs.find(id);
    if (it == programs.end() && participant.published_before_start(source_time)) {
      // Replayed from the upstream node's history: an old program, not one sent to this node.
      std::cerr << "gcpipe node write: skipping program " << id << " ('" << batch.file()
                << "'), published before this node started (--replay takes it)\n";
      if (!batch.end_of_program()) skipped.insert(id);
      return false;
    }
    if (it == programs.end()) {
      it = programs.emplace(id, Program(write_options)).first;
      it->second.file = batch.file();
      if (batch.sequence_number() != 0)
        fail(it->second, id,
             "joined the program at batch " + std::to_string(batch.sequence_number()) +
                 ": its beginning is no longer available upstream");
      it->second.next_batch = batch.sequence_number();
    }
    Program& prog = it->second;
    if (batch.sequence_number() != prog.next_batch)
      fail(prog, id, "batch " + std::to_string(prog.next_batch) + " is missing (got batch " +
                         std::to_string(batch.sequence_number()) + ")");
    prog.next_batch = batch.sequence_number() + 1;
    if (prog.error.empty()) write_batch(prog, id, batch);
    if (!batch.end_of_program()) return false;

    if (!batch.error().empty()) fail(prog, id, "upstream: " + batch.error());
    if (prog.error.empty()) {
      std::string counts = dds::check_counts(dds::totals_of(batch), prog.arrived);
      if (!counts.empty()) fail(prog, id, counts);
    }
    chunk.end_of_program(true);
    chunk.byte_count(prog.bytes + prog.text.size());
    chunk.blocks_written(prog.arrived.blocks);
    chunk.diagnostics_written(prog.arrived.diagnostics());
    chunk.blocks_rejected(batch.blocks_rejected());
    chunk.stopped(batch.stopped());
    chunk.summary(batch.summary());
    chunk.error(prog.error);
    if (!prog.error.empty()) status = 1;
    publish(id, prog);
    std::cerr << "gcpipe node write: program " << id << " '" << prog.file << "': "
              << prog.arrived.blocks << " blocks, " << prog.arrived.diagnostics() << " diagnostics from "
              << prog.next_batch << " batches; " << prog.bytes << " bytes in " << prog.next_chunk
              << " chunks; writes retried on a full history: " << writer.blocked_writes() << "\n";
    chunk = msg::GcodeChunk();
    programs.erase(it);
    return true;
  }
};

WriteNode::WriteNode(dds::Participant& participant, WriteOptions write_options,
                     WriteNodeOptions node_options)
    : impl_(std::make_unique<Impl>(participant, write_options, node_options)) {}

WriteNode::~WriteNode() = default;

int WriteNode::run() {
  msg::BlockBatch batch;
  double source_time = 0;
  return dds::run_stage_node(
      "write", impl_->participant, impl_->writer, impl_->options.forever,
      [&](double timeout) {
        if (!impl_->reader.take(batch, timeout, &source_time)) return dds::Taken::kNothing;
        return impl_->handle(batch, source_time) ? dds::Taken::kProgramEnd : dds::Taken::kHandled;
      },
      impl_->status);
}

}  // namespace gcpipe
