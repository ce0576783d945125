#include "dds_tools.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <thread>
#include <cstdio>
#include <cstring>
#include <functional>
#include <fstream>
#include <iomanip>
#include <map>
#include <memory>
#include <ostream>
#include <random>
#include <set>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "dds_convert.hpp"
#include "output_dir.hpp"
#include "run_report.hpp"
#include "stage.hpp"
#include "gcpipe/line_reader.hpp"

namespace gcpipe::dds {

using Clock = std::chrono::steady_clock;

std::uint64_t random_program_id() {
  std::random_device rd;
  std::uint64_t id = 0;
  while (id == 0) id = (static_cast<std::uint64_t>(rd()) << 32) ^ rd();
  return id;
}

bool ProgramFilter::refuses(std::uint64_t id, const std::string& file, std::ostream& log) {
  if (only_ == 0 || id == only_) return false;
  if (refused_.insert(id).second)
    log << who_ << ": refusing program " << id << " ('" << file << "'): started for program " << only_
        << " only. Another pipeline publishes on this DDS domain: give each its own (--domain, or "
        << "GCPIPE_DDS_DOMAIN for the commands that read it)" << std::endl;
  return true;
}

namespace {

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Takes the next sample; false after idle_timeout without one (0 = never), on a stop request, or
// when `why_lost` (polled while nothing arrives) says what was awaited will never come, into `lost`.
template <class T>
bool take_or_idle(Reader<T>& reader, T& sample, double idle_timeout, bool& idle, double* source_time,
                  const std::function<std::string()>& why_lost = {}, std::string* lost = nullptr,
                  std::uint64_t* writer = nullptr) {
  const auto t0 = Clock::now();
  idle = false;
  while (!stop_requested()) {
    if (reader.take(sample, 0.1, source_time, writer)) return true;
    if (why_lost) {
      if (std::string why = why_lost(); !why.empty()) {
        *lost = std::move(why);
        return false;
      }
    }
    if (idle_timeout > 0 && seconds_since(t0) > idle_timeout) {
      idle = true;
      return false;
    }
  }
  return false;
}

// Sleeps until `bytes` are due at `rate` [bytes/s] since `start` (a paced feed), or a stop.
void wait_for_pace(Clock::time_point start, std::uint64_t bytes, double rate) {
  const auto due = start + std::chrono::duration_cast<Clock::duration>(
                               std::chrono::duration<double>(static_cast<double>(bytes) / rate));
  while (Clock::now() < due && !stop_requested())
    std::this_thread::sleep_for(std::min<Clock::duration>(due - Clock::now(), std::chrono::milliseconds(100)));
}

}  // namespace

// ---------------------------------------------------------------------------------------------

namespace {

// After every chunk was acknowledged: whether a reader died mid-program instead (the wait for
// acknowledgements ended when it was dropped for its discovery lease, not because it took the
// chunks), said in `log`. Fast DDS reports the dropped participant just after the unmatch that
// ended the wait: with a reader gone, that report is given a second to come.
bool reader_died(const Writer<msg::ProgramChunk>& writer, const std::string& topic, std::ostream& log) {
  for (int i = 0; i < 20 && !writer.reader_died_mid_program() && writer.matched_readers() < writer.subscribers(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  if (!writer.reader_died_mid_program()) return false;
  log << "gcpipe feed: a reader of " << topic << " went away mid-program (its stage stopped or died; a restarted "
      << "stage does not take a program in flight): the program was not delivered\n";
  return true;
}

}  // namespace

int run_feed(Participant& participant, const FeedOptions& o, std::ostream& log) {
  // "-" is standard input, named "<stdin>" in diagnostics as batch mode names it.
  const bool stdin_input = o.input == "-";
  const std::string name = stdin_input ? "<stdin>" : o.input.string();
  const int fd = stdin_input ? 0 : ::open(o.input.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0)
    throw std::runtime_error("cannot open program '" + name + "': " + std::strerror(errno));
  struct Closer {
    int fd;
    ~Closer() {
      if (fd > 0) ::close(fd);
    }
  } closer{fd};

  Writer<msg::ProgramChunk> writer(participant, o.topic);
  Writer<msg::ProgramChunk> monitor_copy(participant, monitor_topic(o.topic), /*monitor=*/true);
  if (!writer.wait_for_readers()) return 130;
  const auto t0 = Clock::now();

  const std::uint64_t id = o.program_id != 0 ? o.program_id : random_program_id();
  // The heartbeat says the program is in flight here (the parse node ends it if the feed dies
  // first); holding, not working: a paced feed waits between chunks by design.
  writer.set_stage_name("feed");
  writer.working(id, name);
  writer.holding();
  LineReader reader(fd, o.max_line_length);
  msg::ProgramChunk chunk;
  chunk.program_id(id);
  chunk.file(name);
  chunk.first_line(1);
  std::uint64_t lines = 0, chunks = 0;
  std::size_t size = 0;
  std::string_view line;
  bool overlong = false;
  std::size_t full_length = 0;
  // Paced by the bytes of the lines sent so far, not by reader.bytes_read(): the reader reads the
  // file in large blocks, and pacing by those released a block's worth of chunks at once (at
  // 2 MB/s, 11 chunks of 128 KB within 3 ms every 0.5 s), a burst the two-core VM's pipeline
  // met at full load (stages/dds/README.md, Speed).
  std::uint64_t line_bytes = 0;  // [bytes] of the lines taken so far, each with its newline
  auto publish = [&]() {
    if (o.bytes_per_second > 0) wait_for_pace(t0, line_bytes, o.bytes_per_second);
    chunk.sequence_number(chunks++);
    if (!writer.publish(chunk)) return false;
    monitor_copy.publish(chunk);
    chunk.first_line(lines + 1);
    chunk.lines().clear();
    size = 0;
    return true;
  };
  while (reader.next(line, overlong, full_length)) {
    msg::SourceLine& s = chunk.lines().emplace_back();
    s.text(std::string(line));
    s.full_length(overlong ? full_length : 0);
    ++lines;
    line_bytes += line.size() + 1;
    size += line.size() + 20;  // CDR: string length, terminator, padding, full_length
    if (size >= o.chunk_bytes && !publish()) return 130;
  }
  if (!reader.error().empty())
    throw std::runtime_error("reading '" + name + "': " + reader.error());
  chunk.end_of_program(true);
  chunk.line_count(lines);
  chunk.byte_count(reader.bytes_read());
  if (!publish()) return 130;
  const bool acked = writer.wait_acknowledged();
  log << "gcpipe feed: program " << id << " '" << name << "': " << lines
      << " lines, " << reader.bytes_read() << " bytes in " << chunks << " chunks, "
      << std::fixed << std::setprecision(3) << seconds_since(t0)
      << " s; writes retried on a full history: " << writer.blocked_writes() << "\n";
  writer.idle();  // delivered: the program is no longer in this process's hands
  if (!acked) {
    log << "gcpipe feed: not every chunk was acknowledged by the readers of " << o.topic
        << "\n";
    return 1;
  }
  return reader_died(writer, o.topic, log) ? 1 : 0;
}

// ---------------------------------------------------------------------------------------------

namespace {

// What the sink took of one program: the chunks in order into `out`, and the first error seen.
struct SinkReceipt {
  msg::GcodeChunk last;  //!< the end marker, when `complete`
  std::uint64_t id = 0, next = 0, bytes = 0;
  std::uint64_t writer = 0;  //!< who sent the first chunk
  std::string error;
  Clock::time_point t0;
  bool complete = false;
  int status = 0;  //!< when !complete: 1 idle, 130 stopped
};

// The edges a program crosses before it reaches `topic`, from the stage registry (a pipeline file
// may leave some stages out: their edges are then silent, which costs nothing).
std::vector<std::string> edges_before(const std::string& topic) {
  std::vector<std::string> edges{kProgramTopicName};
  const pipeline::StageInfo* stage = nullptr;
  for (const pipeline::StageInfo& s : pipeline::registry())
    if (topic == s.topic) stage = &s;
  if (stage == nullptr) return edges;  // a renamed topic: the chain before it is not known
  for (std::string up = stage->upstream; !up.empty(); up = pipeline::find_stage(up).upstream)
    if (const char* t = pipeline::find_stage(up).topic; *t != '\0') edges.emplace_back(t);
  return edges;
}

// Why the program cannot arrive whole any more, "" while it still can. Mid-program: its writer
// left, or the edge's watchdog says the stage before died, froze or stalls. Before its first
// chunk: the stage before held a program this sink waits for (a compensate node collects a whole
// program before it sends any) and died, froze or stalls; `r.id` then becomes that program.
std::string why_lost(Reader<msg::GcodeChunk>& reader, SinkReceipt& r, const SinkOptions& o,
                     HeartbeatWatcher* way) {
  const std::string after = " after chunk " + std::to_string(r.next) + " of the program: the rest is lost";
  // Earlier on the program's way (a sink that knows its program): a stage that held it and died.
  if (way != nullptr) {
    for (const RawReader::LostProgram& lost : way->programs_lost()) {
      if (lost.program_id != o.program_id) continue;
      if (r.id == 0) r.id = lost.program_id;
      return lost.why + ", holding program " + std::to_string(lost.program_id) + " ('" + lost.file +
             "'): the program is lost";
    }
  }
  if (r.id != 0) {
    if (const std::string trouble = reader.writer_trouble(r.writer); !trouble.empty()) return trouble + after;
    if (reader.matched_writers() == 0 || reader.writer_gone(r.writer))
      return "the writer of " + o.topic + " went away" + after + " (its stage stopped or died)";
    return "";
  }
  for (const RawReader::LostProgram& lost : reader.programs_lost_upstream()) {
    if (o.program_id != 0 && lost.program_id != o.program_id) continue;
    r.id = lost.program_id;
    return lost.why + ", holding program " + std::to_string(lost.program_id) + " ('" + lost.file +
           "') before it sent any of it: the program is lost";
  }
  return "";
}

// Takes the chunks of the first program published after the sink started (replays of older
// programs are skipped and said so) until its end marker, checking the sequence numbers.
SinkReceipt receive_program(Participant& participant, Reader<msg::GcodeChunk>& reader, const SinkOptions& o,
                            std::ofstream& out, std::ostream& log) {
  SinkReceipt r;
  std::unique_ptr<HeartbeatWatcher> way;
  if (o.program_id != 0) way = std::make_unique<HeartbeatWatcher>(participant, edges_before(o.topic));
  ProgramFilter ours("gcpipe sink", o.program_id);
  msg::GcodeChunk& chunk = r.last;
  const double idle_timeout = participant.options().idle_timeout;
  bool idle = false;
  std::set<std::uint64_t> skipped;  // programs published before the sink started
  double source_time = 0;
  std::uint64_t writer = 0;
  for (;;) {
    std::string lost;
    if (!take_or_idle(reader, chunk, idle_timeout, idle, &source_time, [&] { return why_lost(reader, r, o, way.get()); }, &lost,
                      &writer)) {
      if (idle)
        log << "gcpipe sink: nothing arrived on " << o.topic << " for " << idle_timeout << " s; giving up"
            << (ours.refused_any() ? " (only another pipeline's programs did: see above)" : "") << "\n";
      if (!lost.empty()) log << "gcpipe sink: " << lost << "\n";
      r.status = idle || !lost.empty() ? 1 : 130;
      return r;
    }
    // Another pipeline's program on a shared domain: never written.
    if (ours.refuses(chunk.program_id(), chunk.file(), log)) continue;
    if (r.id == 0 && skipped.count(chunk.program_id()) != 0) continue;
    if (r.id == 0 && participant.published_before_start(source_time)) {
      // Replayed from a writer's history (a node serving with --forever): an old program.
      if (skipped.insert(chunk.program_id()).second)
        log << "gcpipe sink: skipping program " << chunk.program_id() << " ('" << chunk.file()
            << "'), published before the sink started (--replay takes it)\n";
      continue;
    }
    if (r.next == 0 && r.id == 0) {
      r.id = chunk.program_id();
      r.writer = writer;
      r.t0 = Clock::now();
      if (chunk.sequence_number() != 0)
        r.error = "joined program " + std::to_string(r.id) + " at chunk " + std::to_string(chunk.sequence_number()) +
                  ": its beginning is lost";
      r.next = chunk.sequence_number();
    }
    if (chunk.program_id() != r.id) continue;  // another program: the first one is ours
    if (writer != r.writer && r.error.empty()) r.error = second_writer_error(o.topic);
    if (chunk.sequence_number() != r.next && r.error.empty())
      r.error = "chunk " + std::to_string(r.next) + " is missing (got chunk " + std::to_string(chunk.sequence_number()) + ")";
    r.next = chunk.sequence_number() + 1;
    out.write(chunk.text().data(), static_cast<std::streamsize>(chunk.text().size()));
    r.bytes += chunk.text().size();
    if (chunk.end_of_program()) {
      r.complete = true;
      return r;
    }
  }
}

// The end marker's checks: the writer's byte count and the parser's own accounting (the block
// and diagnostic counts were checked edge by edge by the nodes: an error would be in error()).
void check_end_marker(SinkReceipt& r, const ParseSummary& s) {
  auto add = [&r](const std::string& e) {
    if (e.empty()) return;
    if (!r.error.empty()) r.error += "; ";
    r.error += e;
  };
  add(r.last.error());
  if (r.last.byte_count() != r.bytes)
    add("received " + std::to_string(r.bytes) + " bytes, the writer sent " + std::to_string(r.last.byte_count()));
  if (s.blocks_emitted + s.lines_rejected + s.lines_deleted != s.lines_read)
    add("the parser's counts do not add up: " + std::to_string(s.lines_read) + " lines read != " +
        std::to_string(s.blocks_emitted) + " blocks + " + std::to_string(s.lines_rejected) + " rejected + " +
        std::to_string(s.lines_deleted) + " deleted");
}

void log_sink_summary(const SinkReceipt& r, const ParseSummary& s, std::ostream& log) {
  const msg::GcodeChunk& c = r.last;
  log << "gcpipe sink: program " << r.id << " '" << c.file() << "': " << s.lines_read << " lines read, "
      << s.blocks_emitted << " blocks parsed, " << s.lines_rejected << " rejected, " << s.lines_deleted
      << " deleted; " << c.blocks_rejected() << " blocks rejected by later stages; written " << c.blocks_written()
      << " blocks, " << c.diagnostics_written() << " diagnostics, " << r.bytes << " bytes in " << r.next << " chunks, "
      << std::fixed << std::setprecision(3) << seconds_since(r.t0) << " s"
      << (c.stopped() ? " (strict mode stopped at the first error)" : "") << "\n";
}

}  // namespace

int run_sink(Participant& participant, const SinkOptions& o, std::ostream& log) {
  Reader<msg::GcodeChunk> reader(participant, o.topic);
  const std::filesystem::path part = o.output.string() + ".part";
  // Opened before anything arrives, so an unwritable path fails at once, not mid-program.
  std::ofstream out(part, std::ios::binary | std::ios::trunc);
  if (!out) throw std::runtime_error("cannot write '" + part.string() + "'");
  // Scripts (and the tests) wait for this line before starting a feed: a program published
  // before the sink exists counts as a replay and is skipped without --replay.
  log << "gcpipe sink: ready on " << o.topic << "\n" << std::flush;
  SinkReceipt r = receive_program(participant, reader, o, out, log);
  if (!r.complete) {
    if (r.id != 0)
      log << "gcpipe sink: INCOMPLETE, program " << r.id << " ended before its end marker; " << r.bytes
          << " bytes left in '" << part.string() << "'\n";
    return r.status;
  }
  out.close();
  if (!out) throw std::runtime_error("writing '" + part.string() + "' failed");
  const ParseSummary s = from_msg(r.last.summary());
  check_end_marker(r, s);
  log_sink_summary(r, s, log);
  if (const std::string hop = reader.take_hop_latency_text(); !hop.empty()) log << "gcpipe sink: " << hop << "\n";
  if (!r.error.empty()) {
    log << "gcpipe sink: INCOMPLETE, output left in '" << part.string() << "': " << r.error << "\n";
    return 1;
  }
  std::filesystem::rename(part, o.output);
  // The exit status of `gcpipe batch` for the same program.
  if (r.last.stopped()) return 1;
  return s.lines_rejected + r.last.blocks_rejected() > 0 ? 3 : 0;
}

// ---------------------------------------------------------------------------------------------

namespace {

using Parts = std::map<std::string, msg::ReportFragment>;

// Takes report parts until every stage's part of one program is in (the first program published
// after the sink started). Returns 0, 1 (idle) or 130 (stop).
int collect_parts(Participant& participant, const ReportSinkOptions& o, Parts& parts, std::ostream& log) {
  Reader<msg::ReportFragment> reader(participant, kReportTopicName, /*monitor=*/true);
  log << "gcpipe report-sink: ready" << std::endl;
  const double idle_timeout = participant.options().idle_timeout;
  msg::ReportFragment part;
  std::uint64_t program = o.program_id;
  ProgramFilter ours("gcpipe report-sink", o.program_id);
  double source_time = 0;
  bool idle = false;
  while (parts.size() < o.stages.size()) {
    if (!take_or_idle(reader, part, idle_timeout, idle, &source_time)) {
      if (idle) log << "gcpipe report-sink: no report part for " << idle_timeout << " s; giving up\n";
      return idle ? 1 : 130;
    }
    if (ours.refuses(part.program_id(), part.file(), log)) continue;
    if (participant.published_before_start(source_time)) continue;
    if (program == 0) program = part.program_id();
    if (part.program_id() != program) continue;
    if (std::find(o.stages.begin(), o.stages.end(), part.stage()) == o.stages.end()) continue;
    parts[part.stage()] = part;
  }
  return 0;
}

}  // namespace

int run_report_sink(Participant& participant, const ReportSinkOptions& o, std::ostream& log) {
  const auto t0 = Clock::now();
  Parts parts;
  if (const int status = collect_parts(participant, o, parts, log); status != 0) return status;
  bool complete = true;
  for (const auto& [stage, part] : parts) complete = complete && part.complete();
  const std::string input = parts.begin()->second.file();
  pipeline::RunReport r;
  r.json = pipeline::report_head(input, o.config_file, o.machine, o.stages, complete);
  r.text = pipeline::report_text_head(o.command, input, o.dir, o.stages);
  r.files = pipeline::report_files();
  std::string diagnostics;
  for (const std::string& stage : o.stages) {
    const msg::ReportFragment& part = parts.at(stage);
    // A later part's key replaces an earlier one's in place, as one report object would.
    const nlohmann::ordered_json keys = nlohmann::ordered_json::parse(part.json());
    for (const auto& [key, value] : keys.items()) r.json[key] = value;
    r.text += part.text();
    r.files.insert(r.files.end(), part.files().begin(), part.files().end());
    diagnostics += part.diagnostics();
    if (r.failure.empty() && !part.failure().empty()) r.failure = stage + ": " + part.failure();
    if (stage == "compensate") r.compensated = part.text_bytes() > 0 && part.failure().empty();
  }
  // As batch says it: why a pipeline with a compensate stage wrote no compensated.nc.
  if (parts.count("compensate") != 0 && !r.compensated && r.failure.empty())
    r.not_compensated = pipeline::why_not_compensated(r);
  pipeline::write_file_atomically(o.dir / "diagnostics.txt", diagnostics);
  pipeline::write_run_report(std::move(r), o.dir, seconds_since(t0));
  log << "gcpipe report-sink: wrote the report of '" << input << "' (" << parts.size() << " parts) to "
      << o.dir.string() << "\n";
  return 0;
}

}  // namespace gcpipe::dds
