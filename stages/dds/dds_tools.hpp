// The pipeline's ends: `gcpipe feed`, `gcpipe sink`, `gcpipe report-sink` (the observer,
// `gcpipe monitor`, is monitor.hpp).
// (The stage nodes are in stages/<stage>/<stage>_node.hpp.) stages/cli only parses arguments.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "dds_runtime.hpp"

namespace gcpipe::dds {

struct FeedOptions {
  std::filesystem::path input;       //!< program file to publish; "-" = standard input
  /// Lines are cut at this length as batch mode's reader cuts them (parse.max_line_length) [bytes]
  std::size_t max_line_length = 256;
  std::size_t chunk_bytes = 128 * 1024;  //!< publish a chunk once it holds this much text [bytes]
  /// A paced feed's chunks (--rate without --chunk-bytes): 16 KB of text become about one block
  /// batch of the parse node (128 KB of blocks), where a 128 KB chunk became seven published back
  /// to back, a burst that kept Fast DDS's receive threads waiting for a core (p99 per hop
  /// 1.7-2.2 ms; with 16 KB chunks 0.16-0.53 ms: stages/dds/README.md, Speed).
  static constexpr std::size_t kPacedChunkBytes = 16 * 1024;
  /// At most this many bytes of the program a second, as a DNC drip feed sends a program at the
  /// control's pace (and as a latency measurement needs a stream below the pipeline's capacity);
  /// 0 = as fast as the readers take it [bytes/s].
  double bytes_per_second = 0;
  std::uint64_t program_id = 0;      //!< 0 = pick a random one
  std::string topic = kProgramTopicName;  //!< ProgramChunk topic written (--out)
};

/// Publishes a program on its topic and waits until its readers acknowledged all of it.
/// Returns the exit status (0 ok); throws for an unreadable file.
int run_feed(Participant& participant, const FeedOptions& options, std::ostream& log);

struct SinkOptions {
  std::filesystem::path output;  //!< written through a temporary file, renamed when complete
  std::string topic = kGcodeTopicName;  //!< GcodeChunk topic read (--in)
  /// The only program written; another one on the topic (another pipeline sharing the domain)
  /// is refused and named, never written. 0: the first program published after the sink started.
  std::uint64_t program_id = 0;
};

/// A random non-zero program id (what `gcpipe feed` publishes under unless told one).
std::uint64_t random_program_id();

/// The one program a sink or node was started for (`--program-id`, as `gcpipe stream` gives it):
/// any other is another pipeline's on a shared domain, refused and named once.
class ProgramFilter {
 public:
  /// `who` names the process in what it says ("gcpipe sink"); `only` 0 takes every program.
  ProgramFilter(std::string who, std::uint64_t only) : who_(std::move(who)), only_(only) {}
  /// True when program `id` is not the one: said to `log` the first time.
  bool refuses(std::uint64_t id, const std::string& file, std::ostream& log);
  bool refused_any() const { return !refused_.empty(); }

 private:
  std::string who_;
  std::uint64_t only_;
  std::set<std::uint64_t> refused_;
};

/// Writes the first program that arrives on its topic to `output` and returns after its end
/// marker, having checked that the chunks were contiguous, the bytes are the writer's, no stage
/// reported lost input, and the parser's accounting adds up. Returns batch mode's exit status
/// for the program: 0 all lines and cycles accepted, 3 some rejected, 1 strict mode stopped; 1
/// also when data went missing, and then the file is left as OUTPUT.part.
int run_sink(Participant& participant, const SinkOptions& options, std::ostream& log);

struct ReportSinkOptions {
  std::filesystem::path dir;         //!< report.json, report.txt, summary.json, diagnostics.txt
  std::vector<std::string> stages;   //!< the nodes whose parts make the report, in chain order
  std::string config_file;           //!< as report.json names it
  std::string machine;
  std::string command = "gcpipe stream";  //!< report.txt's first word
  std::uint64_t program_id = 0;      //!< the only program reported (0: the first after start)
};

/// Collects the report parts (gcpipe_report) of the first program published after it started,
/// one from every stage of `stages`, and writes the run's report files as `gcpipe batch` does
/// (pipeline/run_report.hpp; diagnostics.txt: each stage's diagnostics, in chain order).
/// Returns 0, 1 after the idle timeout, 130 on a stop request.
int run_report_sink(Participant& participant, const ReportSinkOptions& options, std::ostream& log);

}  // namespace gcpipe::dds
