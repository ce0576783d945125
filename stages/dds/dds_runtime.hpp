// Thin Fast DDS plumbing shared by every gcpipe node: a participant made from the XML profiles,
// and typed writers/readers of the pipeline's topics (one per edge, each of one of three types).
//
// This header is deliberately free of Fast DDS includes (they are heavy to compile): entities live
// behind pointers to implementation in dds_runtime.cpp. QoS comes from the named profiles in
// pipeline_configs/dds_profiles.xml (see stages/dds/README.md for the choices and the
// measurements behind them), but for two things set from options: the DDS Security properties of
// --identity, and the lifespan of the monitor copies (--monitor-history).
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <set>
#include <string>
#include <vector>

namespace gcpipe::msg {
class ProgramChunk;
class BlockBatch;
class GcodeChunk;
class IkBatch;
class SampleBatch;
class ReportFragment;
}  // namespace gcpipe::msg

namespace gcpipe::pipeline {
enum class Telemetry : std::uint8_t;
}  // namespace gcpipe::pipeline

namespace gcpipe::dds {

/// The wire types (idl/gcpipe.idl documents their samples). A topic is a name plus one of these;
/// the pipeline has one topic per edge, so several topics carry the same type. IkBatch and
/// SampleBatch are telemetry, on monitor topics only.
enum class MessageType { kProgramChunk, kBlockBatch, kGcodeChunk, kIkBatch, kSampleBatch, kReportFragment };
inline constexpr int kMessageTypes = 6;
const char* type_name(MessageType type);
/// The wire type of a stage's telemetry (IK points: IkBatch, else SampleBatch).
MessageType telemetry_type(pipeline::Telemetry telemetry);
/// Accepts program|blocks|gcode|ik|samples and the type names; throws otherwise.
MessageType message_type_from_name(const std::string& name);

/// Topic names are declared once, by the stages (StageInfo::topic, stages/pipeline/stage.hpp):
/// a node writes its stage's topic and reads its nearest upstream's; `gcpipe feed` writes
/// pipeline::kProgramTopic. Every node's --in/--out may rename them.
inline constexpr const char* kProgramTopicName = "gcpipe_program";
inline constexpr const char* kGcodeTopicName = "gcpipe_gcode";
/// Every node's part of each program's report (ReportFragment), for `gcpipe report-sink`.
inline constexpr const char* kReportTopicName = "gcpipe_report";
/// The type of a declared topic name (the program topic, a stage's, or a stage's telemetry
/// topic), false for any other name (then the type must be given).
bool default_topic_type(const std::string& topic, MessageType& type);
/// Throws std::runtime_error unless `topic` is a usable topic name: 1..200 characters of
/// [A-Za-z0-9_], not starting with a digit (a conservative subset of what DDS accepts).
void check_topic_name(const std::string& topic);

template <class T> struct TypeOf;
template <> struct TypeOf<msg::ProgramChunk> { static constexpr MessageType value = MessageType::kProgramChunk; };
template <> struct TypeOf<msg::BlockBatch> { static constexpr MessageType value = MessageType::kBlockBatch; };
template <> struct TypeOf<msg::GcodeChunk> { static constexpr MessageType value = MessageType::kGcodeChunk; };
template <> struct TypeOf<msg::IkBatch> { static constexpr MessageType value = MessageType::kIkBatch; };
template <> struct TypeOf<msg::SampleBatch> { static constexpr MessageType value = MessageType::kSampleBatch; };
template <> struct TypeOf<msg::ReportFragment> { static constexpr MessageType value = MessageType::kReportFragment; };

/// Where and how long; every field has a command-line option (stages/dds/README.md).
struct DdsOptions {
  int domain = 0;                  //!< DDS domain id [0, 232]; parallel pipelines need distinct ids
  std::filesystem::path profiles;  //!< XML profiles; empty = default_profiles_path()
  /// How this host reaches the others: an XML file holding the participant profile
  /// "gcpipe_network_participant" (transports, interfaces, peers; e.g.
  /// pipeline_configs/dds_network_shop.xml). Empty: the profiles' own participant (shared memory
  /// and loopback only). The edges' QoS stays in `profiles` either way.
  std::filesystem::path network;
  /// DDS Security identity: a folder made by stages/dds/make_security.sh (identity_ca.pem,
  /// cert.pem, key.pem, permissions_ca.pem, governance.p7s, permissions.p7s). Empty: no security.
  std::filesystem::path identity;
  /// DDS partition of every reader and writer of this participant: `gcpipe stream` gives each
  /// run its own, so two pipelines sharing a domain never match (a monitor's "*" sees them
  /// all). Empty: the default partition, as `gcpipe launch` and hand-started nodes use.
  std::string partition;
  int subscribers = 1;             //!< readers a writer waits for before its first sample [1, 100]
  double match_timeout = 30;       //!< [s] longest wait for those readers
  double write_timeout = 60;       //!< [s] longest a write may stay blocked on a full history
  double ack_timeout = 60;         //!< [s] longest wait, before leaving, for readers to acknowledge
  double idle_timeout = 0;         //!< [s] a consumer gives up after this long without a sample;
                                   //!< 0 = wait for ever (tests set it so nothing can hang)
  /// Also take programs that were published before this process started and are replayed from
  /// a writer's transient-local history (by default they are old news and skipped).
  bool replay = false;
  /// A writer whose matched readers fall below `subscribers` fails its next write at once (one
  /// program per process: a reader can only leave mid-program by dying). Off for --forever nodes,
  /// whose readers (sinks) come and go between programs.
  bool fail_on_lost_reader = true;
  /// [s] What a late monitor still gets: every monitor copy (EDGE_monitor, telemetry) keeps each
  /// sample this long (DDS lifespan), within its profile's depth (gcpipe_monitor_writer: 256
  /// batches). 0 = no time limit: the depth alone (the last 256 batches, however old).
  double monitor_history = 5;
  /// The watchdog on every edge (stages/dds/README.md, "Watchdog"): each edge writer sends a
  /// heartbeat every `heartbeat_period` [s] from a thread of its own; a reader that hears none
  /// from a writer for `heartbeat_timeout` [s] takes it for dead or frozen, and one whose stage
  /// works without progress for `stall_timeout` [s] for stalled. Neither rests on the discovery
  /// lease. pipeline.heartbeat_timeout / pipeline.stall_timeout in a pipeline file.
  double heartbeat_period = 0.5;
  double heartbeat_timeout = 4;
  double stall_timeout = 10;
};

/// pipeline_configs/dds_profiles.xml beside the default pipeline config; GCPIPE_DDS_PROFILES
/// overrides it.
std::filesystem::path default_profiles_path();
/// GCPIPE_DDS_DOMAIN when set (checked to be an integer in [0, 232]), else `fallback`.
int default_domain(int fallback = 0);

/// SIGINT and SIGTERM set a flag that every wait below polls, so nodes end cleanly (a killed
/// process leaves shared-memory segments behind).
void install_stop_handlers();
bool stop_requested();

/// One DomainParticipant per process, created from profile "gcpipe_participant" after
/// load_profiles() (otherwise the XML would be ignored). Throws std::runtime_error naming the
/// profile file, profile and domain when creation fails.
class Participant {
 public:
  explicit Participant(const DdsOptions& options);
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;
  const DdsOptions& options() const;
  /// True when a sample with this source timestamp [s since the Unix epoch] was published before
  /// this participant was created and `replay` is off: a consumer then skips its program.
  /// Compares clocks of two processes; exact on one host, subject to clock skew across hosts.
  bool published_before_start(double source_time) const;
  struct Impl;
  Impl& impl() { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

/// A writer of one topic from profile "gcpipe_writer".
class RawWriter {
 public:
  /// Throws when the name is unusable or the participant already has `topic` with another type.
  /// `monitor`: the copy of an edge that monitors read (profile "gcpipe_monitor_writer"):
  /// publish() never waits and never fails there. `profile` overrides the profile's name
  /// (gcpipe_report_writer).
  RawWriter(Participant& participant, MessageType type, const std::string& topic, bool monitor = false,
            const char* profile = nullptr);
  ~RawWriter();
  RawWriter(const RawWriter&) = delete;
  RawWriter& operator=(const RawWriter&) = delete;

  /// Blocks until options().subscribers readers matched (or `count`). Throws after
  /// match_timeout; false when a stop was requested.
  bool wait_for_readers();
  bool wait_for_readers(int count);
  int matched_readers() const;
  /// Writes one sample. write() returns false while the keep-all history is full and a reader
  /// lags; that is retried, never ignored (ignoring it lost samples in ../shared/DESIGN.md's
  /// measurement). Throws after write_timeout; false when a stop was requested.
  bool publish(const void* sample);
  /// True when every matched reader acknowledged every sample within ack_timeout.
  bool wait_acknowledged();
  /// The same within `limit` [s] instead of ack_timeout.
  bool wait_acknowledged(double limit);
  /// A reader left after the first sample, and a participant of the domain was dropped for a
  /// lapsed discovery lease meanwhile (a process died): wait_acknowledged() then ends because the
  /// dead reader was dropped, not because it took the samples. A reader that left in good order
  /// (its stage took the program and exited) is not counted.
  bool reader_died_mid_program() const;
  const std::string& topic() const { return topic_; }
  /// How often write() returned false (history full, a reader behind) and was retried.
  std::uint64_t blocked_writes() const { return blocked_writes_; }
  /// What the stage behind this writer is doing, for the edge's heartbeat (an edge writer only;
  /// a monitor copy has none). `working`: it took input of `program` and handles it (a stall is
  /// no progress in this state); `holding`: a program is in flight but it waits for input;
  /// `idle`: no program. `progressed` counts a step of a long computation (every publish and
  /// every sample taken count by themselves).
  void working(std::uint64_t program, const std::string& file);
  /// The program's end (Stage::finish): a stall only once the stage reported a step.
  void finishing();
  /// Its report and figures: never a stall (the heartbeat still tells death and freezing).
  void reporting();
  void holding();
  void idle();
  void progressed();
  /// The stage named in the heartbeat (default: the topic's writer, "?").
  void set_stage_name(const std::string& stage);
  /// This writer's id as its readers' take() names it.
  std::uint64_t id() const;
  /// Readers this writer waits for and must keep (default: the participant's `subscribers`;
  /// the stages of one process each have their own, `gcpipe node` groups).
  void set_subscribers(int count) { subscribers_ = count; }
  int subscribers() const { return subscribers_; }

 private:
  void start_heartbeat();
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string topic_;
  std::uint64_t blocked_writes_ = 0;
  bool monitor_ = false;
  int subscribers_ = 1;
};

/// The topic gcpipe monitor reads for the edge `topic`: a keep-last copy of it.
inline std::string monitor_topic(const std::string& topic) { return topic + "_monitor"; }

/// A reader of one topic from profile "gcpipe_reader".
class RawReader {
 public:
  RawReader(Participant& participant, MessageType type, const std::string& topic, bool monitor = false);
  ~RawReader();
  RawReader(const RawReader&) = delete;
  RawReader& operator=(const RawReader&) = delete;
  /// Takes the next sample with data into `sample` (of the topic's type). False when none came
  /// within `timeout_s` [s]. `source_time`: when the writer wrote it [s since the Unix epoch];
  /// `writer`: which writer sent it (a hash of its GUID, never 0), to tell two writers apart.
  bool take(void* sample, double timeout_s, double* source_time = nullptr, std::uint64_t* writer = nullptr);
  int matched_writers() const;
  /// True once the writer `writer` (as take() names it) was matched and no longer is: its
  /// process stopped or died, or its participant's lease ran out. Other writers may still be
  /// matched (a restarted stage), so a program in flight from this one will never be completed.
  bool writer_gone(std::uint64_t writer) const;
  const std::string& topic() const { return topic_; }
  /// What the edge's heartbeats say of writer `writer` (as take() names it): "" while it beats
  /// and, when working, progresses, or when it sent no heartbeat at all; else why it is taken for
  /// dead, frozen or stalled, naming its stage and pid.
  std::string writer_trouble(std::uint64_t writer) const;
  /// A program a writer of this edge had in flight (working on or holding) when its heartbeat
  /// lapsed or it stalled: it will never send the rest, maybe not even a first sample.
  struct LostProgram {
    std::uint64_t writer = 0, program_id = 0;
    std::string file, why;
  };
  /// Each such program once (later calls leave out what an earlier call returned).
  std::vector<LostProgram> programs_lost_upstream();
  /// The hop latency of the samples taken since the last call: reception minus source timestamp,
  /// the way across DDS from the writer's write() to this reader's history (not the time a
  /// sample then waits for this process), as "hop latency from TOPIC: p50 … ms, p99 … ms, max …
  /// ms over N samples"; "" when none was taken. Across hosts it includes their clock offset.
  std::string take_hop_latency_text();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string topic_;
};

/// The heartbeats of several edges, without their data: a sink that knows its program
/// (`--program-id`) watches every edge on its program's way, so that a stage that dies or stalls
/// holding the program is named even when it is not the sink's own writer (a trochoid node killed
/// with the program in hand: the write node after it never saw any of it).
class HeartbeatWatcher {
 public:
  HeartbeatWatcher(Participant& participant, const std::vector<std::string>& topics);
  ~HeartbeatWatcher();
  HeartbeatWatcher(const HeartbeatWatcher&) = delete;
  HeartbeatWatcher& operator=(const HeartbeatWatcher&) = delete;
  /// RawReader::programs_lost_upstream over every watched edge.
  std::vector<RawReader::LostProgram> programs_lost();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

template <class T>
class Writer : public RawWriter {
 public:
  Writer(Participant& p, const std::string& topic, bool monitor = false) : RawWriter(p, TypeOf<T>::value, topic, monitor) {}
  bool publish(const T& sample) { return RawWriter::publish(&sample); }
};

template <class T>
class Reader : public RawReader {
 public:
  Reader(Participant& p, const std::string& topic, bool monitor = false) : RawReader(p, TypeOf<T>::value, topic, monitor) {}
  bool take(T& sample, double timeout_s, double* source_time = nullptr, std::uint64_t* writer = nullptr) {
    return RawReader::take(&sample, timeout_s, source_time, writer);
  }
};

/// What a stage node's input step reports to run_stage_node.
enum class Taken : std::uint8_t {
  kNothing,     //!< no sample within the timeout
  kHandled,     //!< a sample was handled, the program goes on
  kProgramEnd,  //!< a sample was handled and it completed a program
};

/// The Fast DDS shared-memory files (segments, port queues) process `pid` maps now, into `out`.
void shm_files_mapped_by(int pid, std::set<std::string>& out);
/// Removes those of `files` that no live process on this host maps any more, with their lock
/// files and a port queue's semaphore. A file some process still maps is left alone.
void remove_unmapped_shm_files(const std::set<std::string>& files);

/// Removes every Fast DDS shared-memory file (segment, port queue) of this host that no live
/// process maps: what processes that died without closing their participant left behind (a
/// supervisor killed with SIGKILL, a node killed with -9). Returns how many files went.
std::size_t clean_dead_shared_memory();

/// Writes `line` and a newline to stderr in one write, so that lines of threads do not mix.
void say_line(const std::string& line);

/// The loop every stage node (parse, trochoid, write, compensate) runs: wait until the output has readers
/// (downstream first, so that no history fills with nobody to drain it), call `take` (which takes
/// at most one input sample within the timeout [s] and handles it) until a program ended (or
/// forever), give up after the participant's idle timeout, then wait until downstream has
/// acknowledged every sample. `status` is the node's exit status, which `take` may also set;
/// returns its final value.
int run_stage_node(const std::string& node, Participant& participant, RawWriter& output, bool forever,
                   const std::function<Taken(double timeout)>& take, int& status);

}  // namespace gcpipe::dds
