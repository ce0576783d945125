#include "trochoid_node.hpp"

#include <chrono>
#include <iostream>
#include <map>
#include <set>
#include <vector>

#include "dds_convert.hpp"
#include "dds_runtime.hpp"

namespace gcpipe {

namespace {

// One program in flight. Programs are told apart by id, so several feeders may share the topics.
struct Program : dds::BatchProgram {
  std::uint64_t next_out = 0;     // output sequence number
  msg::BlockBatch out;            // output batch being filled
  std::size_t out_size = 0;       // its serialized size so far [bytes]
  bool strict = false;            // this node's option or the upstream's mode
  bool stopped = false;           // strict mode met a rejected line or cycle: nothing more out
  std::uint64_t blocks_sent = 0, diagnostics_sent = 0, block_rejections_sent = 0;
  std::uint64_t cycles_expanded = 0, cycles_rejected = 0;
};

}  // namespace

struct TrochoidNode::Impl {
  dds::Participant& participant;
  TrochoidExpander expander;
  TrochoidNodeOptions options;
  dds::Reader<msg::BlockBatch> reader;
  dds::Writer<msg::BlockBatch> writer;
  dds::BatchIntake<Program> intake{"trochoid"};
  int status = 0;
  // Reused for every block: one cycle may expand into tens of thousands of blocks.
  ResolvedBlock block;
  Diagnostic diag;
  std::vector<ResolvedBlock> expanded;

  Impl(dds::Participant& p, TrochoidOptions to, TrochoidNodeOptions o)
      : participant(p), expander(to), options(std::move(o)), reader(p, options.input_topic),
        writer(p, options.output_topic) {}

  bool publish(std::uint64_t id, Program& prog) {
    prog.out.program_id(id);
    prog.out.file(prog.file);
    prog.out.sequence_number(prog.next_out++);
    prog.out.strict(prog.strict);
    if (!writer.publish(prog.out)) return false;
    prog.blocks_sent += prog.out.blocks().size();
    prog.diagnostics_sent += prog.out.diagnostics().size();
    prog.out.blocks().clear();
    prog.out.diagnostics().clear();
    prog.out_size = 0;
    return true;
  }

  void fail(Program& prog, std::uint64_t id, const std::string& why) { intake.fail(prog, id, why); }

  // Appends one output item; publishes when the batch is full. False when publishing failed.
  bool add_block(std::uint64_t id, Program& prog, const ResolvedBlock& b) {
    msg::Block& m = prog.out.blocks().emplace_back();
    dds::to_msg(b, m);
    prog.out_size += msg::Block::getCdrSerializedSize(m);
    return prog.out_size < options.batch_bytes || publish(id, prog);
  }
  bool add_diagnostic(std::uint64_t id, Program& prog, const msg::LineDiagnostic& m) {
    if (m.line_status() == static_cast<std::uint8_t>(dds::DiagnosticKind::kBlockRejected))
      ++prog.block_rejections_sent;
    prog.out.diagnostics().push_back(m);
    prog.out_size += msg::LineDiagnostic::getCdrSerializedSize(m);
    return prog.out_size < options.batch_bytes || publish(id, prog);
  }

  // Batch mode's loop body for one input batch: diagnostics are forwarded, every block goes
  // through step(); in strict mode nothing follows the first rejected line or cycle (arrivals are
  // still counted, so the end marker's totals can be checked).
  void process(Program& prog, std::uint64_t id, const msg::BlockBatch& batch) {
    std::string why;
    dds::DiagnosticKind kind{};
    const auto& blocks = batch.blocks();
    const auto& diags = batch.diagnostics();
    dds::for_each_in_line_order(
        batch,
        [&](std::size_t b) {
          if (!dds::from_msg(blocks[b], block, &why)) {
            fail(prog, id, "batch " + std::to_string(batch.sequence_number()) + ", line " +
                               std::to_string(blocks[b].line()) + ": " + why);
            return false;
          }
          ++prog.arrived.blocks;
          if (prog.stopped) return true;
          expanded.clear();
          const TrochoidExpander::Status st = expander.step(block, prog.file, expanded, diag);
          if (!st.ok()) {
            ++prog.cycles_rejected;
            msg::LineDiagnostic m;
            dds::to_msg(diag, dds::DiagnosticKind::kBlockRejected, m);
            if (!add_diagnostic(id, prog, m)) return false;
          } else if (st.code == TrochoidExpander::Status::Code::kExpanded) {
            ++prog.cycles_expanded;
          }
          for (const ResolvedBlock& e : expanded)
            if (!add_block(id, prog, e)) return false;
          if (!st.ok() && prog.strict) prog.stopped = true;
          return true;
        },
        [&](std::size_t d) {
          if (!dds::from_msg(diags[d], diag, kind, &why)) {
            fail(prog, id, "batch " + std::to_string(batch.sequence_number()) + ", line " +
                               std::to_string(diags[d].line()) + ": " + why);
            return false;
          }
          prog.arrived.count(kind);
          if (prog.stopped) return true;
          if (!add_diagnostic(id, prog, diags[d])) return false;
          if (kind == dds::DiagnosticKind::kLineRejected && prog.strict) prog.stopped = true;
          return true;
        });
  }

  // Returns true when the program is finished (end marker published).
  bool handle(const msg::BlockBatch& batch, double source_time) {
    const std::uint64_t id = batch.program_id();
    Program* found =
        intake.admit(batch, participant.published_before_start(source_time), [] { return Program(); });
    if (found == nullptr) return false;
    Program& prog = *found;
    prog.strict = prog.strict || options.strict || batch.strict();
    if (prog.error.empty()) process(prog, id, batch);
    if (!batch.end_of_program()) return false;

    intake.close(prog, batch);
    const dds::BatchTotals upstream = dds::totals_of(batch);
    prog.out.end_of_program(true);
    dds::BatchTotals totals;
    totals.summary = upstream.summary;
    totals.blocks_sent = prog.blocks_sent + prog.out.blocks().size();
    totals.diagnostics_sent = prog.diagnostics_sent + prog.out.diagnostics().size();
    totals.blocks_rejected = prog.block_rejections_sent;
    totals.stopped = upstream.stopped || prog.stopped;
    dds::set_totals(totals, prog.out);
    prog.out.error(prog.error);
    if (!prog.error.empty()) status = 1;
    publish(id, prog);
    std::cerr << "gcpipe node trochoid: program " << id << " '" << prog.file << "': "
              << prog.arrived.blocks << " blocks and " << prog.arrived.diagnostics()
              << " diagnostics in " << prog.next_batch << " batches; " << prog.cycles_expanded
              << " G275 cycles expanded, " << prog.cycles_rejected << " rejected; "
              << totals.blocks_sent << " blocks and " << totals.diagnostics_sent
              << " diagnostics out in " << prog.next_out << " batches"
              << (prog.stopped ? " (strict stop)" : "")
              << "; writes retried on a full history: " << writer.blocked_writes() << "\n";
    intake.erase(id);
    return true;
  }
};

TrochoidNode::TrochoidNode(dds::Participant& participant, TrochoidOptions trochoid_options,
                           TrochoidNodeOptions node_options)
    : impl_(std::make_unique<Impl>(participant, trochoid_options, std::move(node_options))) {}

TrochoidNode::~TrochoidNode() = default;

int TrochoidNode::run() {
  return dds::run_reader_node(
      "trochoid", impl_->participant, impl_->reader, impl_->writer, impl_->options.forever,
      [this](const msg::BlockBatch& sample, double source_time) { return impl_->handle(sample, source_time); },
      impl_->status);
}

}  // namespace gcpipe
