#include "write_node.hpp"

#include <chrono>
#include <iostream>
#include <map>
#include <set>

#include "dds_convert.hpp"
#include "dds_runtime.hpp"

namespace gcpipe {

namespace {

struct Program : dds::BatchProgram {
  explicit Program(const WriteOptions& o) : writer(o) {}
  Writer writer;
  std::uint64_t next_chunk = 0;
  std::uint64_t bytes = 0;        // text published so far [bytes]
  std::uint64_t last_line = 0;    // last source line written
  std::string text;               // text not yet published
};

}  // namespace

struct WriteNode::Impl {
  dds::Participant& participant;
  WriteOptions write_options;
  WriteNodeOptions options;
  dds::Reader<msg::BlockBatch> reader;
  dds::Writer<msg::GcodeChunk> writer;
  dds::BatchIntake<Program> intake{"write"};
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

  void fail(Program& prog, std::uint64_t id, const std::string& why) { intake.fail(prog, id, why); }

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
    Program* found = intake.admit(batch, participant.published_before_start(source_time),
                                  [&] { return Program(write_options); });
    if (found == nullptr) return false;
    Program& prog = *found;
    if (prog.error.empty()) write_batch(prog, id, batch);
    if (!batch.end_of_program()) return false;

    intake.close(prog, batch);
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
    intake.erase(id);
    return true;
  }
};

WriteNode::WriteNode(dds::Participant& participant, WriteOptions write_options,
                     WriteNodeOptions node_options)
    : impl_(std::make_unique<Impl>(participant, write_options, node_options)) {}

WriteNode::~WriteNode() = default;

int WriteNode::run() {
  return dds::run_reader_node(
      "write", impl_->participant, impl_->reader, impl_->writer, impl_->options.forever,
      [this](const msg::BlockBatch& sample, double source_time) { return impl_->handle(sample, source_time); },
      impl_->status);
}

}  // namespace gcpipe
