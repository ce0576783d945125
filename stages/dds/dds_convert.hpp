// Conversions between the stage cores' plain structs and the IDL wire types (idl/gcpipe.idl).
//
// Only node code includes this: it pulls in the generated header (light: std types only), never
// the Fast DDS entity headers. to_msg copies every field; from_msg checks every enumeration and
// returns false with a reason for a value the C++ enum does not have, so a corrupt or foreign
// sample is reported instead of becoming a wrong motion. Round trip: tests/dds_convert_test.cpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <map>
#include <set>
#include <string>

#include "gcpipe.h"  // generated from idl/gcpipe.idl
#include "gcpipe/block.hpp"
#include "gcpipe/diagnostic.hpp"
#include "gcpipe/telemetry.hpp"
#include "parse.hpp"

namespace gcpipe::dds {

void to_msg(const ResolvedBlock& block, msg::Block& out);
/// False (and `why` says which field and value) when an enumeration holds an unknown value.
bool from_msg(const msg::Block& in, ResolvedBlock& out, std::string* why = nullptr);

/// What a LineDiagnostic says about its line (wire octet `line_status`, idl/gcpipe.idl).
using gcpipe::DiagnosticKind;
/// kRejected -> kLineRejected, kDeleted -> kLineDeleted (kBlock has no diagnostic).
DiagnosticKind kind_of(LineStatus status);

void to_msg(const Diagnostic& diag, DiagnosticKind kind, msg::LineDiagnostic& out);
bool from_msg(const msg::LineDiagnostic& in, Diagnostic& out, DiagnosticKind& kind,
              std::string* why = nullptr);

void to_msg(const ParseSummary& summary, msg::ParseCounts& out);
ParseSummary from_msg(const msg::ParseCounts& in);

/// Telemetry for monitors, field for field.
void to_msg(const IkTelemetry& point, msg::IkResult& out);
void to_msg(const SampleTelemetry& sample, msg::AxisSample& out);

/// The order in which a BlockBatch's items reach the writer, identical to batch mode's: merge
/// blocks and diagnostics by line; on equal lines the diagnostic first (a line has at most one,
/// and it precedes the skip moves that replace a rejected cycle); equal-line blocks keep their
/// order. Calls on_block(index) / on_diagnostic(index); stops when one returns false.
template <class OnBlock, class OnDiagnostic>
void for_each_in_line_order(const msg::BlockBatch& batch, OnBlock&& on_block,
                            OnDiagnostic&& on_diagnostic) {
  const auto& blocks = batch.blocks();
  const auto& diags = batch.diagnostics();
  std::size_t b = 0, d = 0;
  while (b < blocks.size() || d < diags.size()) {
    const bool block_first =
        d == diags.size() || (b < blocks.size() && blocks[b].line() < diags[d].line());
    if (block_first ? !on_block(b++) : !on_diagnostic(d++)) return;
  }
}

/// What a consumer of a BlockBatch topic received of one program.
struct BatchArrivals {
  std::uint64_t blocks = 0;
  std::uint64_t lines_rejected = 0;   //!< diagnostics of kind kLineRejected
  std::uint64_t lines_deleted = 0;    //!< kLineDeleted
  std::uint64_t blocks_rejected = 0;  //!< kBlockRejected
  std::uint64_t diagnostics() const { return lines_rejected + lines_deleted + blocks_rejected; }
  void count(DiagnosticKind kind);
};

/// What a BlockBatch end marker states (idl/gcpipe.idl).
struct BatchTotals {
  ParseSummary summary;               //!< the parser's, forwarded unchanged
  std::uint64_t blocks_sent = 0;      //!< by the immediate upstream
  std::uint64_t diagnostics_sent = 0;
  std::uint64_t blocks_rejected = 0;  //!< by stages after the parser, along the chain
  bool stopped = false;
};
BatchTotals totals_of(const msg::BlockBatch& end_marker);
void set_totals(const BatchTotals& totals, msg::BlockBatch& end_marker);

/// The identities a finished program must satisfy on one BlockBatch edge, as one message per
/// violated identity; empty when consistent:
///  - blocks and diagnostics received = what the upstream says it sent (exact, every edge);
///  - block-rejected diagnostics received = blocks_rejected;
///  - the parser's accounting adds up: emitted + rejected + deleted = read;
///  - rejected-line and deleted-line diagnostics received = the parser's counts, or at most
///    those when strict mode stopped the program downstream of the parser.
std::string check_counts(const BatchTotals& sent, const BatchArrivals& received);

/// Why a program that a second writer also sends on `edge` is refused: one edge has one writer,
/// so two mean the stage runs twice on this DDS domain (two pipelines sharing it, or a stage
/// started by hand beside the launcher's). Said before any sequence error the mix causes.
std::string second_writer_error(const std::string& edge);

/// What every consumer of a BlockBatch stream tracks per program (its own state derives from it).
struct BatchProgram {
  std::string file;
  std::uint64_t writer = 0;      //!< the writer that opened the program (RawReader::take)
  std::uint64_t next_batch = 0;  //!< input sequence number expected next
  BatchArrivals arrived;         //!< what came in, checked against upstream's end marker
  std::string error;             //!< first sign of lost or corrupt input; processing stops there
};

/// The bookkeeping every BlockBatch consumer (trochoid and write nodes) does around its own work:
/// programs replayed from upstream's history are skipped whole, a program is opened on its first
/// batch, batches must come in sequence from the start, and at the end marker upstream's error
/// and counts are checked. `Program` derives from BatchProgram.
template <class Program>
class BatchIntake {
 public:
  /// `edge`: the input topic, named when a second writer sends the same program.
  BatchIntake(std::string node, std::string edge) : node_(std::move(node)), edge_(std::move(edge)) {}

  /// The program `batch` belongs to, or nullptr when it is skipped: `replayed` says the batch was
  /// published before this node started (Participant::published_before_start); `writer` is who
  /// sent it (RawReader::take). A new program is built by `make()`; a second writer and sequence
  /// problems are recorded as its error.
  template <class Make>
  Program* admit(const msg::BlockBatch& batch, bool replayed, std::uint64_t writer, Make make) {
    const std::uint64_t id = batch.program_id();
    if (skipped_.count(id) != 0) {
      if (batch.end_of_program()) skipped_.erase(id);
      return nullptr;
    }
    auto it = programs_.find(id);
    if (it == programs_.end() && replayed) {
      std::fprintf(stderr,
                   "gcpipe node %s: skipping program %llu ('%s'), published before this node started "
                   "(--replay takes it)\n",
                   node_.c_str(), static_cast<unsigned long long>(id), batch.file().c_str());
      if (!batch.end_of_program()) skipped_.insert(id);
      return nullptr;
    }
    if (it == programs_.end()) {
      it = programs_.emplace(id, make()).first;
      it->second.file = batch.file();
      if (batch.sequence_number() != 0)
        fail(it->second, id,
             "joined the program at batch " + std::to_string(batch.sequence_number()) +
                 ": its beginning is no longer available upstream");
      it->second.next_batch = batch.sequence_number();
      it->second.writer = writer;
    }
    Program& prog = it->second;
    if (writer != prog.writer) fail(prog, id, second_writer_error(edge_));
    if (batch.sequence_number() != prog.next_batch)
      fail(prog, id, "batch " + std::to_string(prog.next_batch) + " is missing (got batch " +
                         std::to_string(batch.sequence_number()) + ")");
    prog.next_batch = batch.sequence_number() + 1;
    return &prog;
  }

  /// At the end marker: upstream's error, then whether what arrived matches what upstream sent.
  void close(Program& prog, const msg::BlockBatch& end) const {
    if (!end.error().empty()) fail(prog, end.program_id(), "upstream: " + end.error());
    if (prog.error.empty()) {
      const std::string counts = check_counts(totals_of(end), prog.arrived);
      if (!counts.empty()) fail(prog, end.program_id(), counts);
    }
  }

  /// Records a program's first error and says it on stderr.
  void fail(Program& prog, std::uint64_t id, const std::string& why) const {
    if (!prog.error.empty()) return;
    prog.error = why;
    std::fprintf(stderr, "gcpipe node %s: program %llu (%s): %s\n", node_.c_str(),
                 static_cast<unsigned long long>(id), prog.file.c_str(), why.c_str());
  }

  void erase(std::uint64_t id) { programs_.erase(id); }
  /// No program in flight.
  bool empty() const { return programs_.empty(); }
  /// Program `id` is in flight.
  bool holds(std::uint64_t id) const { return programs_.count(id) != 0; }
  /// Calls f(id, program) for every program in flight whose writer `gone(writer)` says left,
  /// then forgets those.
  template <class Gone, class F>
  void drain_if(Gone gone, F f) {
    for (auto it = programs_.begin(); it != programs_.end();) {
      if (!gone(it->second.writer)) {
        ++it;
        continue;
      }
      f(it->first, it->second);
      it = programs_.erase(it);
    }
  }

 private:
  std::string node_, edge_;
  std::map<std::uint64_t, Program> programs_;
  std::set<std::uint64_t> skipped_;  // programs published before this node started
};

}  // namespace gcpipe::dds
