#include "stage_node.hpp"

#include <iostream>
#include <map>
#include <set>

#include <nlohmann/json.hpp>

#include "dds_convert.hpp"
#include "dds_runtime.hpp"
#include "dds_tools.hpp"
#include "parse.hpp"
#include "stage.hpp"

namespace gcpipe::dds {

namespace {

using pipeline::Port;

// The diagnostics one program's stage raised, as diagnostics.txt has them: they go into the
// program's report part (the diagnostics themselves also travel downstream on the edge).
class CollectingLog final : public pipeline::DiagnosticLog {
 public:
  void report(const Diagnostic& d) override {
    lines += format(d);
    lines += '\n';
  }
  std::string lines;
};

// A stage's report of one program: its keys of report.json, its lines of report.txt, and the
// figures it drew into `dir` (none when empty).
nlohmann::ordered_json report_of(const pipeline::Stage& stage, std::string& text,
                                 const std::filesystem::path& dir = {}, const std::string& input = {},
                                 std::vector<std::string>* files = nullptr) {
  nlohmann::ordered_json j = nlohmann::ordered_json::object();
  std::vector<std::string> drawn;
  pipeline::ReportContext r;
  r.json = &j;
  r.text = &text;
  r.dir = dir;
  r.input_base = std::filesystem::path(input).filename().string();
  r.files = files ? files : &drawn;
  stage.report(r);
  return j;
}

// The parser's accounting, as the parse stage reports it.
ParseSummary parse_summary_of(const pipeline::Stage& stage) {
  std::string text;
  const nlohmann::ordered_json j = report_of(stage, text);
  ParseSummary s;
  s.lines_read = j.value("lines_read", 0ull);
  s.blocks_emitted = j.value("blocks_emitted", 0ull);
  s.lines_rejected = j.value("lines_rejected", 0ull);
  s.lines_deleted = j.value("lines_deleted", 0ull);
  s.bytes_read = j.value("bytes_read", 0ull);
  return s;
}

// What one program has sent downstream, and the batch or chunk being filled. The emitter the
// stage writes into.
struct Outbox final : pipeline::Emitter {
  Port port;
  std::size_t limit;
  RawWriter& writer;
  std::uint64_t id = 0;
  std::string file;
  bool strict = false;
  std::uint64_t sequence = 0;
  // kBlocks
  msg::BlockBatch batch;
  std::size_t batch_size = 0;
  std::uint64_t blocks_sent = 0, diagnostics_sent = 0, block_rejections_sent = 0;
  // kGcode
  std::string pending;  // text not yet published
  std::uint64_t bytes = 0;
  bool failed = false;  // a publish failed (stop requested or timeout)

  RawWriter* monitor = nullptr;  // the edge's copy for gcpipe monitor
  // The stage's telemetry (IK points or simulated ticks) for monitors: batches on a keep-last
  // monitor topic, never waited for. Null when the stage has none.
  RawWriter* telemetry = nullptr;
  msg::IkBatch ik;
  msg::SampleBatch samples;
  std::uint64_t telemetry_sequence = 0, telemetry_items = 0;
  static constexpr std::size_t kTelemetryBatch = 256;  // about 25-35 KB, as the edges' batches

  Outbox(Port p, std::size_t l, RawWriter& w, RawWriter* m, RawWriter* t)
      : port(p), limit(l), writer(w), monitor(m), telemetry(t) {}

  bool wants_telemetry() const override { return telemetry != nullptr; }
  void ik_point(const IkTelemetry& p) override { add_telemetry(ik, ik.points(), p); }
  void sample(const SampleTelemetry& s) override { add_telemetry(samples, samples.samples(), s); }
  template <class Batch, class Items, class Item>
  void add_telemetry(Batch& batch, Items& items, const Item& item) {
    to_msg(item, items.emplace_back());
    if (items.size() >= kTelemetryBatch) publish_telemetry(batch, items, false);
  }
  /// One IkBatch or SampleBatch; the end one carries the program's count.
  template <class Batch, class Items>
  void publish_telemetry(Batch& batch, Items& items, bool end) {
    telemetry_items += items.size();
    batch.program_id(id);
    batch.file(file);
    batch.sequence_number(telemetry_sequence++);
    batch.end_of_program(end);
    batch.item_count(end ? telemetry_items : 0);
    telemetry->publish(&batch);
    writer.progressed();  // the simulation's ticks, the IK's points: the stage works
    items.clear();
  }
  /// The telemetry's end batch (a stage emits one kind only).
  void finish_telemetry(pipeline::Telemetry kind) {
    if (telemetry == nullptr) return;
    if (kind == pipeline::Telemetry::kIkPoints) publish_telemetry(ik, ik.points(), true);
    else publish_telemetry(samples, samples.samples(), true);
  }

  bool block(const ResolvedBlock& b) override {
    msg::Block& m = batch.blocks().emplace_back();
    to_msg(b, m);
    batch_size += msg::Block::getCdrSerializedSize(m);
    return batch_size < limit || publish_batch();
  }
  bool diagnostic(const Diagnostic& d, DiagnosticKind kind) override {
    if (kind == DiagnosticKind::kBlockRejected) ++block_rejections_sent;
    msg::LineDiagnostic& m = batch.diagnostics().emplace_back();
    to_msg(d, kind, m);
    batch_size += msg::LineDiagnostic::getCdrSerializedSize(m);
    return batch_size < limit || publish_batch();
  }
  bool text(std::string& gcode) override {
    pending += gcode;
    gcode.clear();
    // Whole lines per chunk, so that a chunk never ends inside a line.
    std::size_t at = 0;
    while (pending.size() - at > limit) {
      const std::size_t cut = pending.find('\n', at + limit);
      if (cut == std::string::npos) break;
      if (!publish_text(pending.substr(at, cut + 1 - at), false)) return false;
      at = cut + 1;
    }
    pending.erase(0, at);
    return true;
  }
  void product(const std::shared_ptr<const pipeline::Product>&) override {}

  bool publish_batch() {
    batch.program_id(id);
    batch.file(file);
    batch.sequence_number(sequence++);
    batch.strict(strict);
    if (!writer.publish(&batch)) return !(failed = true);
    if (monitor) monitor->publish(&batch);
    blocks_sent += batch.blocks().size();
    diagnostics_sent += batch.diagnostics().size();
    batch.blocks().clear();
    batch.diagnostics().clear();
    batch_size = 0;
    return true;
  }
  bool publish_text(std::string piece, bool end, msg::GcodeChunk* marker = nullptr) {
    msg::GcodeChunk local;
    msg::GcodeChunk& chunk = marker ? *marker : local;
    chunk.program_id(id);
    chunk.file(file);
    chunk.sequence_number(sequence++);
    bytes += piece.size();
    chunk.text(std::move(piece));
    chunk.end_of_program(end);
    if (!writer.publish(&chunk)) return !(failed = true);
    if (monitor) monitor->publish(&chunk);
    return true;
  }
};

// One program in flight: the stage object, its outbox, and the input bookkeeping.
struct Program : BatchProgram {
  std::unique_ptr<CollectingLog> log;  // before `stage`, which holds a pointer to it
  std::unique_ptr<pipeline::Stage> stage;
  std::unique_ptr<Outbox> out;
  bool stopped = false;         // strict mode stopped it: inputs are still counted
  std::uint64_t next_chunk = 0, lines_seen = 0;  // ProgramChunk input
};

}  // namespace

struct StageNode::Impl {
  Participant& participant;
  const PipelineConfig& config;
  StageNodeOptions options;
  const pipeline::StageInfo& info;
  std::unique_ptr<RawReader> reader;
  std::unique_ptr<RawWriter> writer, monitor_writer, telemetry_writer, report_writer;
  BatchIntake<Program> intake;
  std::map<std::uint64_t, Program> chunk_programs;  // ProgramChunk input
  std::set<std::uint64_t> skipped;
  ProgramFilter ours{"gcpipe node " + options.stage, options.program_id};
  std::size_t max_line;
  bool config_strict;  // parse.strict: batch mode's strict mode, as --strict
  int status = 0;

  Impl(Participant& p, const PipelineConfig& c, StageNodeOptions o)
      : participant(p), config(c), options(std::move(o)), info(pipeline::find_stage(options.stage)),
        intake(options.stage, options.input_topic), max_line(load_parse_options(c.root.section("parse")).max_line_length),
        config_strict(load_parse_options(c.root.section("parse")).strict) {
    reader = std::make_unique<RawReader>(p, wire_type(info.input), options.input_topic);
    writer = std::make_unique<RawWriter>(p, wire_type(info.output), options.output_topic);
    if (options.subscribers >= 0) writer->set_subscribers(options.subscribers);
    writer->set_stage_name(options.stage);
    monitor_writer = std::make_unique<RawWriter>(p, wire_type(info.output), monitor_topic(options.output_topic), true);
    if (info.telemetry != pipeline::Telemetry::kNone) {
      telemetry_writer = std::make_unique<RawWriter>(p, telemetry_type(info.telemetry), monitor_topic(info.telemetry_topic), true);
    }
    // Keep-last and never waited for, unless the launcher says a report sink listens.
    report_writer = std::make_unique<RawWriter>(p, MessageType::kReportFragment, kReportTopicName, true,
                                                "gcpipe_report_writer");
  }

  static MessageType wire_type(Port p) {
    switch (p) {
      case Port::kProgram: return MessageType::kProgramChunk;
      case Port::kBlocks: return MessageType::kBlockBatch;
      case Port::kGcode: return MessageType::kGcodeChunk;
      case Port::kNone: break;  // a product and a report only: nothing to put on the wire
    }
    throw std::logic_error("no wire type");
  }

  Program make_program(const std::string& file, bool strict) {
    Program prog;
    prog.log = std::make_unique<CollectingLog>();
    pipeline::StageContext c;
    c.config = &config;
    c.file = file;
    c.log = prog.log.get();
    c.strict = strict;
    c.stages = {options.stage};
    c.pipeline_stages = options.pipeline_stages;
    // A long step (the compensation's learning, window by window) counts as progress for the
    // watchdog: the heartbeat then says the stage works, not that it stalled.
    c.progress = [w = writer.get()](const char*, std::uint64_t, std::uint64_t) { w->progressed(); };
    prog.stage = info.make(c);
    prog.out = std::make_unique<Outbox>(info.output, options.batch_bytes, *writer, monitor_writer.get(), telemetry_writer.get());
    prog.out->file = file;
    prog.out->strict = strict;
    return prog;
  }

  void fail(Program& prog, std::uint64_t id, const std::string& why) { intake.fail(prog, id, why); }

  // A program this node was not started for (StageNodeOptions::program_id): another pipeline's on
  // a shared domain. Not processed, so it can never reach this pipeline's files; named once.
  bool refused(std::uint64_t id, const std::string& file) {
    if (!ours.refuses(id, file, std::cerr)) return false;
    ended = false;
    return true;
  }

  // ---- ProgramChunk input (the parse stage) ----

  bool take_chunk(double timeout) {
    msg::ProgramChunk chunk;
    double source_time = 0;
    std::uint64_t writer = 0;
    if (!reader->take(&chunk, timeout, &source_time, &writer)) return false;
    const std::uint64_t id = chunk.program_id();
    this->writer->working(id, chunk.file());
    if (refused(id, chunk.file())) return true;
    if (skipped.count(id) != 0) {
      if (chunk.end_of_program()) skipped.erase(id);
      ended = false;
      return true;
    }
    auto it = chunk_programs.find(id);
    if (it == chunk_programs.end()) {
      if (participant.published_before_start(source_time)) {
        std::cerr << "gcpipe node " << options.stage << ": skipping program " << id << " ('" << chunk.file()
                  << "'), published before this node started (--replay takes it)\n";
        if (!chunk.end_of_program()) skipped.insert(id);
        ended = false;
        return true;
      }
      it = chunk_programs.emplace(id, make_program(chunk.file(), options.strict || config_strict)).first;
      it->second.file = chunk.file();
      it->second.out->id = id;
      if (chunk.sequence_number() != 0)
        fail(it->second, id, "joined the program at chunk " + std::to_string(chunk.sequence_number()) +
                                 ": its beginning is no longer available from the feeder");
      it->second.next_chunk = chunk.sequence_number();
      it->second.writer = writer;
    }
    Program& prog = it->second;
    if (writer != prog.writer) fail(prog, id, second_writer_error(options.input_topic));
    if (chunk.sequence_number() != prog.next_chunk)
      fail(prog, id, "chunk " + std::to_string(prog.next_chunk) + " is missing (got chunk " +
                         std::to_string(chunk.sequence_number()) + ")");
    prog.next_chunk = chunk.sequence_number() + 1;
    feed_lines(prog, id, chunk);
    ended = chunk.end_of_program();
    if (!ended) return true;
    if (prog.error.empty() && chunk.line_count() != prog.lines_seen)
      fail(prog, id, "the feeder sent " + std::to_string(chunk.line_count()) + " lines but " +
                         std::to_string(prog.lines_seen) + " arrived");
    finish_blocks(prog, id, parse_summary_of(*prog.stage), false, 0);
    chunk_programs.erase(it);
    return true;
  }

  void feed_lines(Program& prog, std::uint64_t id, const msg::ProgramChunk& chunk) {
    for (std::size_t k = 0; k < chunk.lines().size(); ++k) {
      const std::uint64_t number = chunk.first_line() + k;
      if (number != prog.lines_seen + 1) {
        fail(prog, id, "chunk " + std::to_string(chunk.sequence_number()) + " starts at line " +
                           std::to_string(chunk.first_line()) + ", expected line " + std::to_string(prog.lines_seen + 1));
        return;
      }
      prog.lines_seen = number;
      if (prog.stopped || !prog.error.empty() || prog.out->failed) continue;
      const msg::SourceLine& src = chunk.lines()[k];
      // Cut as batch mode's LineReader does when the feeder's limit was larger than ours.
      std::string_view text = src.text();
      std::size_t overlong = src.full_length();
      if (text.size() > max_line) {
        if (overlong == 0) overlong = text.size();
        text = text.substr(0, max_line);
      }
      if (!prog.stage->line(text, overlong, *prog.out) && !prog.out->failed) prog.stopped = true;
    }
  }

  // ---- BlockBatch input (every other stage) ----

  bool take_batch(double timeout) {
    msg::BlockBatch batch;
    double source_time = 0;
    std::uint64_t writer = 0;
    if (!reader->take(&batch, timeout, &source_time, &writer)) return false;
    const std::uint64_t id = batch.program_id();
    this->writer->working(id, batch.file());
    if (refused(id, batch.file())) return true;
    Program* found = intake.admit(batch, participant.published_before_start(source_time), writer, [&] {
      return make_program(batch.file(), options.strict || config_strict || batch.strict());
    });
    ended = false;
    if (found == nullptr) return true;
    Program& prog = *found;
    prog.out->id = id;
    if (prog.error.empty()) process(prog, id, batch);
    if (!batch.end_of_program()) return true;
    ended = true;
    intake.close(prog, batch);
    const BatchTotals upstream = totals_of(batch);
    if (info.output == Port::kBlocks) finish_blocks(prog, id, upstream.summary, upstream.stopped, upstream.blocks_rejected);
    else finish_text(prog, id, batch);
    intake.erase(id);
    return true;
  }

  // Batch mode's loop body for one input batch, in batch mode's order.
  void process(Program& prog, std::uint64_t id, const msg::BlockBatch& batch) {
    ResolvedBlock block;
    Diagnostic diag;
    DiagnosticKind kind{};
    std::string why;
    const auto& blocks = batch.blocks();
    const auto& diags = batch.diagnostics();
    auto bad = [&](std::uint64_t line) {
      fail(prog, id, "batch " + std::to_string(batch.sequence_number()) + ", line " + std::to_string(line) + ": " + why);
      return false;
    };
    for_each_in_line_order(
        batch,
        [&](std::size_t b) {
          if (!from_msg(blocks[b], block, &why)) return bad(blocks[b].line());
          ++prog.arrived.blocks;
          if (!prog.stopped && !prog.stage->block(block, *prog.out)) prog.stopped = !prog.out->failed;
          return !prog.out->failed;
        },
        [&](std::size_t d) {
          if (!from_msg(diags[d], diag, kind, &why)) return bad(diags[d].line());
          prog.arrived.count(kind);
          if (!prog.stopped && !prog.stage->diagnostic(diag, kind, *prog.out)) prog.stopped = !prog.out->failed;
          return !prog.out->failed;
        });
  }

  // ---- end of program ----

  std::set<std::uint64_t> finished;  // programs this node ended

  void finish_stage(Program& prog, std::uint64_t id, bool upstream_stopped) {
    finished.insert(id);
    const bool complete = prog.error.empty() && !prog.stopped && !upstream_stopped;
    writer->finishing();
    prog.stage->finish(complete, *prog.out);
    prog.out->finish_telemetry(info.telemetry);
    writer->reporting();
    const std::string failure = prog.stage->failure();
    if (prog.error.empty() && !failure.empty()) fail(prog, id, failure);
    if (prog.out->failed && prog.error.empty()) fail(prog, id, "a publish on " + options.output_topic + " failed");
    // What the stage says of the program, as batch's report.txt says it, and its report part.
    msg::ReportFragment part;
    std::vector<std::string> files;
    part.json(report_of(*prog.stage, part.text(), options.report_dir, prog.file, &files).dump());
    part.files(files);
    std::cerr << "gcpipe node " << options.stage << ": program " << id << " '" << prog.file << "':\n" << part.text();
    part.program_id(id);
    part.file(prog.file);
    part.stage(options.stage);
    part.complete(complete);
    part.diagnostics(std::move(prog.log->lines));
    part.failure(failure);
    part.rejected(prog.stage->rejected());
    part.text_bytes(prog.out->bytes + prog.out->pending.size());
    publish_report(part);
  }

  // The report part goes to a report sink the launcher started (waited for, and acknowledged
  // before the node moves on), or to whoever listens.
  void publish_report(msg::ReportFragment& part) {
    if (options.report_readers > 0 && !report_writer->wait_for_readers(options.report_readers)) return;
    report_writer->publish(&part);
    if (options.report_readers > 0 && !report_writer->wait_acknowledged())
      std::cerr << "gcpipe node " << options.stage << ": the report sink did not acknowledge the report part\n";
  }

  void finish_blocks(Program& prog, std::uint64_t id, const ParseSummary& summary, bool upstream_stopped,
                     std::uint64_t) {
    finish_stage(prog, id, upstream_stopped);
    Outbox& out = *prog.out;
    out.batch.end_of_program(true);
    BatchTotals totals;
    totals.summary = summary;
    totals.blocks_sent = out.blocks_sent + out.batch.blocks().size();
    totals.diagnostics_sent = out.diagnostics_sent + out.batch.diagnostics().size();
    totals.blocks_rejected = out.block_rejections_sent;
    totals.stopped = upstream_stopped || prog.stopped;
    set_totals(totals, out.batch);
    out.batch.error(prog.error);
    if (!prog.error.empty()) status = 1;
    out.publish_batch();
    std::cerr << "gcpipe node " << options.stage << ": program " << id << ": "
              << totals.blocks_sent << " blocks and " << totals.diagnostics_sent << " diagnostics out in "
              << out.sequence << " batches" << (prog.stopped ? " (strict stop)" : "")
              << "; writes retried on a full history: " << writer->blocked_writes() << "\n";
    print_hop_latency();
  }

  // The DDS hop into this node, for the program that just ended (the issue 11 benchmark's figure).
  void print_hop_latency() {
    const std::string text = reader->take_hop_latency_text();
    if (!text.empty()) std::cerr << "gcpipe node " << options.stage << ": " << text << "\n";
  }

  void finish_text(Program& prog, std::uint64_t id, const msg::BlockBatch& end) {
    finish_stage(prog, id, end.stopped());
    Outbox& out = *prog.out;
    msg::GcodeChunk marker;
    marker.byte_count(out.bytes + out.pending.size());
    marker.blocks_written(prog.arrived.blocks);
    marker.diagnostics_written(prog.arrived.diagnostics());
    // Upstream's accounting goes on, so that the sink exits with batch mode's status.
    marker.blocks_rejected(end.blocks_rejected());
    marker.stopped(end.stopped());
    marker.summary(end.summary());
    marker.error(prog.error);
    if (!prog.error.empty()) status = 1;
    out.publish_text(std::move(out.pending), true, &marker);
    std::cerr << "gcpipe node " << options.stage << ": program " << id << ": "
              << prog.arrived.blocks << " blocks, " << prog.arrived.diagnostics() << " diagnostics in; "
              << out.bytes << " bytes out in " << out.sequence << " chunks"
              << (prog.error.empty() ? "" : "; " + prog.error) << "\n";
    print_hop_latency();
  }

  bool ended = false;

  // Between input samples: a program in flight waits for its input, else there is none.
  void say_what_it_does_now() {
    if (chunk_programs.empty() && intake.empty()) writer->idle();
    else writer->holding();
  }

  // The writer of our input went away while programs were in flight (its stage stopped or died;
  // everything it had sent is in our history, and take() found nothing more). Each such program
  // is ended now with an end marker that carries the reason, so every stage downstream and the
  // sink stop at once with it, instead of waiting for batches that will never come.
  // A program's writer is gone when it was unmatched (even if another writer, a restarted stage,
  // is matched now), or when no writer is matched at all.
  // The watchdog (the input edge's heartbeats) says the same sooner and whatever the discovery
  // lease does: a writer that stopped beating or stalls is gone too, and the reason names it.
  bool end_orphaned_programs() {
    bool any = end_programs_lost_before_their_first_sample();
    if (chunk_programs.empty() && intake.empty()) return any;
    const bool none_left = reader->matched_writers() == 0;
    // The heartbeat's reason first: it names the stage and its pid. (A node that drained a
    // backlog of its input after the writer died may find the lease run out too by then.)
    auto why_gone = [&](std::uint64_t writer) -> std::string {
      if (std::string trouble = reader->writer_trouble(writer); !trouble.empty()) return trouble;
      if (none_left || reader->writer_gone(writer))
        return "the writer of " + options.input_topic + " went away mid-program (its stage stopped or died)";
      return "";
    };
    auto gone = [&](std::uint64_t writer) { return !why_gone(writer).empty(); };
    for (auto it = chunk_programs.begin(); it != chunk_programs.end();) {
      if (!gone(it->second.writer)) {
        ++it;
        continue;
      }
      auto& [id, prog] = *it;
      fail(prog, id, why_gone(prog.writer) + " after chunk " + std::to_string(prog.next_chunk) +
                         " of the program: the rest is lost");
      finish_blocks(prog, id, parse_summary_of(*prog.stage), false, 0);
      any = true;
      it = chunk_programs.erase(it);
    }
    intake.drain_if(gone, [&](std::uint64_t id, Program& prog) {
      fail(prog, id, why_gone(prog.writer) + " after batch " + std::to_string(prog.next_batch) +
                         " of the program: the rest is lost");
      finish_lost(prog, id);
      any = true;
    });
    return any;
  }

  void finish_lost(Program& prog, std::uint64_t id) {
    if (info.output == Port::kBlocks) finish_blocks(prog, id, ParseSummary{}, false, 0);
    else finish_text(prog, id, msg::BlockBatch{});
  }

  // A program the stage before held when it died or stalled, of which nothing reached this node
  // (a compensate node collects a whole program before it sends anything): ended here too, with
  // the reason, so that the stages after and the sink do not wait for it for ever.
  bool end_programs_lost_before_their_first_sample() {
    bool any = false;
    for (const RawReader::LostProgram& lost : reader->programs_lost_upstream()) {
      const std::uint64_t id = lost.program_id;
      if (chunk_programs.count(id) != 0 || intake.holds(id)) continue;  // ended above, with its count
      if (finished.count(id) != 0) continue;  // its end marker came before the writer's idle beat
      if (options.program_id != 0 && id != options.program_id) continue;  // another pipeline's
      Program prog = make_program(lost.file, options.strict || config_strict);
      prog.file = lost.file;
      prog.out->id = id;
      fail(prog, id, lost.why + ", holding program " + std::to_string(id) + " before it sent any of it: the program is lost");
      finish_lost(prog, id);
      any = true;
    }
    return any;
  }
};

StageNode::StageNode(Participant& participant, const PipelineConfig& config, StageNodeOptions options)
    : impl_(std::make_unique<Impl>(participant, config, std::move(options))) {
  const Port in = impl_->info.input, out = impl_->info.output;
  if (in == Port::kGcode || out == Port::kProgram || out == Port::kNone)
    throw std::runtime_error("stage '" + impl_->options.stage + "' has no DDS node: its ports have no wire type");
}

StageNode::~StageNode() = default;

int StageNode::run() {
  Impl& m = *impl_;
  const int status = run_stage_node(
      m.options.stage, m.participant, *m.writer, m.options.forever,
      [&m](double timeout) {
        const bool took = m.info.input == Port::kProgram ? m.take_chunk(timeout) : m.take_batch(timeout);
        const bool orphans_ended = !took && m.end_orphaned_programs();
        m.say_what_it_does_now();
        if (!took) return orphans_ended ? Taken::kProgramEnd : Taken::kNothing;
        return m.ended ? Taken::kProgramEnd : Taken::kHandled;
      },
      m.status);
  // A copy for monitors deleted as the process ends loses what it still holds, its end marker
  // too: the monitors matched now get a second at most to take it. Waiting for the edge's own
  // readers is not enough: under load the write node, acknowledged by its sink, left before a
  // monitor had any of its copy (Stream.TheMonitoringPipeline... saw 6 of 7 ends). A frozen
  // monitor delays that exit by the second, never the program.
  m.monitor_writer->wait_acknowledged(1.0);
  if (m.telemetry_writer) m.telemetry_writer->wait_acknowledged(1.0);
  return status;
}

}  // namespace gcpipe::dds
