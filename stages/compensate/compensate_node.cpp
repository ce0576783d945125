#include "compensate_node.hpp"

#include <iostream>

#include "compensate_program.hpp"
#include "dds_convert.hpp"
#include "dds_runtime.hpp"

namespace gcpipe {

namespace {

struct Program : dds::BatchProgram {
  std::vector<ResolvedBlock> blocks;
  bool too_many = false;  // more than compensate.max_blocks: collected no further
};

}  // namespace

struct CompensateNode::Impl {
  dds::Participant& participant;
  compensate::Model model;
  compensate::CompensateOptions options;
  WriteOptions write_options;
  CompensateNodeOptions node_options;
  dds::Reader<msg::BlockBatch> reader;
  dds::Writer<msg::GcodeChunk> writer;
  dds::BatchIntake<Program> intake{"compensate"};
  int status = 0;

  Impl(dds::Participant& p, compensate::Model m, compensate::CompensateOptions o, WriteOptions wo,
       CompensateNodeOptions no)
      : participant(p), model(std::move(m)), options(o), write_options(wo), node_options(no),
        reader(p, no.input_topic), writer(p, no.output_topic) {}

  void collect(Program& prog, std::uint64_t id, const msg::BlockBatch& batch) {
    ResolvedBlock block;
    Diagnostic diag;
    dds::DiagnosticKind kind{};
    std::string why;
    const auto& blocks = batch.blocks();
    const auto& diags = batch.diagnostics();
    // The order batch mode sees them in (by line, a diagnostic before the blocks of its line).
    dds::for_each_in_line_order(
        batch,
        [&](std::size_t b) {
          if (!dds::from_msg(blocks[b], block, &why)) {
            intake.fail(prog, id, "batch " + std::to_string(batch.sequence_number()) + ", line " +
                                      std::to_string(blocks[b].line()) + ": " + why);
            return false;
          }
          ++prog.arrived.blocks;
          if (prog.blocks.size() >= options.max_blocks) {
            prog.too_many = true;
            prog.blocks.clear();
            prog.blocks.shrink_to_fit();
          }
          if (!prog.too_many) prog.blocks.push_back(block);
          return true;
        },
        [&](std::size_t d) {
          if (!dds::from_msg(diags[d], diag, kind, &why)) {
            intake.fail(prog, id, "batch " + std::to_string(batch.sequence_number()) + ", line " +
                                      std::to_string(diags[d].line()) + ": " + why);
            return false;
          }
          prog.arrived.count(kind);
          return true;
        });
  }

  void publish(std::uint64_t id, const Program& prog, const msg::BlockBatch& end, const std::string& text,
               const std::string& error) {
    msg::GcodeChunk chunk;
    std::uint64_t sequence = 0;
    std::size_t at = 0;
    // Whole lines per chunk, as the write node cuts them.
    while (text.size() - at > node_options.chunk_bytes) {
      std::size_t cut = text.find('\n', at + node_options.chunk_bytes);
      if (cut == std::string::npos) break;
      chunk.program_id(id);
      chunk.file(prog.file);
      chunk.sequence_number(sequence++);
      chunk.text(text.substr(at, cut + 1 - at));
      writer.publish(chunk);
      at = cut + 1;
    }
    chunk = msg::GcodeChunk();
    chunk.program_id(id);
    chunk.file(prog.file);
    chunk.sequence_number(sequence);
    chunk.text(text.substr(at));
    chunk.end_of_program(true);
    chunk.byte_count(text.size());
    chunk.blocks_written(prog.arrived.blocks);
    chunk.diagnostics_written(prog.arrived.diagnostics());
    chunk.error(error);
    // Upstream's accounting goes on, so that the sink exits with batch mode's status.
    chunk.blocks_rejected(end.blocks_rejected());
    chunk.stopped(end.stopped());
    chunk.summary(end.summary());
    writer.publish(chunk);
  }

  bool handle(const msg::BlockBatch& batch, double source_time) {
    const std::uint64_t id = batch.program_id();
    Program* found = intake.admit(batch, participant.published_before_start(source_time), [] { return Program(); });
    if (found == nullptr) return false;
    Program& prog = *found;
    if (prog.error.empty()) collect(prog, id, batch);
    if (!batch.end_of_program()) return false;
    intake.close(prog, batch);
    std::string error = prog.error;
    std::string text;
    if (error.empty() && batch.stopped()) error = "the program was stopped upstream: batch mode compensates only whole programs";
    if (error.empty() && prog.too_many)
      error = "the program has more than compensate.max_blocks = " + std::to_string(options.max_blocks) + " blocks";
    if (error.empty()) {
      const simulate::SimulationRun sim = simulate::simulate_program(
          model, std::move(prog.blocks), {options.reference_smoothing, options.max_machine_time});
      compensate::ProgramCompensation run = compensate::compensate_program(model, options, write_options, sim, {});
      if (run.text.empty()) error = "not compensated: " + run.note;
      text = std::move(run.text);
    }
    if (!error.empty()) status = 1;
    publish(id, prog, batch, text, error);
    std::cerr << "gcpipe node compensate: program " << id << " '" << prog.file << "': " << prog.arrived.blocks
              << " blocks; " << (error.empty() ? std::to_string(text.size()) + " bytes of compensated program" : error)
              << "\n";
    intake.erase(id);
    return true;
  }
};

CompensateNode::CompensateNode(dds::Participant& participant, compensate::Model model,
                               compensate::CompensateOptions options, WriteOptions write_options,
                               CompensateNodeOptions node_options)
    : impl_(std::make_unique<Impl>(participant, std::move(model), options, write_options, node_options)) {}

CompensateNode::~CompensateNode() = default;

int CompensateNode::run() {
  return dds::run_reader_node(
      "compensate", impl_->participant, impl_->reader, impl_->writer, impl_->node_options.forever,
      [this](const msg::BlockBatch& sample, double source_time) { return impl_->handle(sample, source_time); },
      impl_->status);
}

}  // namespace gcpipe
