#include "dds_runtime.hpp"

#include "output_dir.hpp"
#include "stage.hpp"

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <fastdds/dds/log/Log.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <vector>

#include "gcpipe/pipeline_config.hpp"
#include "gcpipePubSubTypes.h"

namespace gcpipe::dds {

namespace fdds = eprosima::fastdds::dds;
using Clock = std::chrono::steady_clock;

namespace {

constexpr const char* kParticipantProfile = "gcpipe_participant";
constexpr const char* kWriterProfile = "gcpipe_writer";
constexpr const char* kReaderProfile = "gcpipe_reader";
constexpr const char* kMonitorWriterProfile = "gcpipe_monitor_writer";
constexpr const char* kMonitorReaderProfile = "gcpipe_monitor_reader";
// How often blocking waits look at the stop flag [s]: short enough that Ctrl-C feels immediate.
constexpr double kPollPeriod = 0.1;



eprosima::fastrtps::Duration_t duration(double seconds) {
  return eprosima::fastrtps::Duration_t(static_cast<long double>(seconds));
}

using ReturnCode = eprosima::fastrtps::types::ReturnCode_t;
bool ok(const ReturnCode& rc) { return rc == ReturnCode::RETCODE_OK; }

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

std::string seconds_text(double s) {
  std::ostringstream o;
  o << s << " s";
  return o.str();
}

}  // namespace

const char* type_name(MessageType type) {
  switch (type) {
    case MessageType::kProgramChunk: return "ProgramChunk";
    case MessageType::kBlockBatch: return "BlockBatch";
    case MessageType::kGcodeChunk: return "GcodeChunk";
    case MessageType::kIkBatch: return "IkBatch";
    case MessageType::kSampleBatch: return "SampleBatch";
    case MessageType::kReportFragment: return "ReportFragment";
  }
  return "?";
}

MessageType message_type_from_name(const std::string& name) {
  if (name == "program" || name == "ProgramChunk") return MessageType::kProgramChunk;
  if (name == "blocks" || name == "BlockBatch") return MessageType::kBlockBatch;
  if (name == "gcode" || name == "GcodeChunk") return MessageType::kGcodeChunk;
  if (name == "ik" || name == "IkBatch") return MessageType::kIkBatch;
  if (name == "samples" || name == "SampleBatch") return MessageType::kSampleBatch;
  throw std::runtime_error("unknown message type '" + name +
                           "' (known: program, blocks, gcode, ik, samples, or ProgramChunk, BlockBatch, "
                           "GcodeChunk, IkBatch, SampleBatch)");
}

MessageType telemetry_type(pipeline::Telemetry telemetry) {
  return telemetry == pipeline::Telemetry::kIkPoints ? MessageType::kIkBatch : MessageType::kSampleBatch;
}

bool default_topic_type(const std::string& topic, MessageType& type) {
  if (topic == pipeline::kProgramTopic) {
    type = MessageType::kProgramChunk;
    return true;
  }
  for (const pipeline::StageInfo& s : pipeline::registry()) {
    if (s.telemetry != pipeline::Telemetry::kNone && topic == s.telemetry_topic) {
      type = telemetry_type(s.telemetry);
      return true;
    }
    if (topic != s.topic) continue;
    type = s.output == pipeline::Port::kGcode ? MessageType::kGcodeChunk : MessageType::kBlockBatch;
    return true;
  }
  return false;
}

void check_topic_name(const std::string& topic) {
  bool ok = !topic.empty() && topic.size() <= 200 && !(topic[0] >= '0' && topic[0] <= '9');
  for (const char c : topic)
    ok = ok && ((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_');
  if (!ok)
    throw std::runtime_error("topic name '" + topic +
                             "' is not usable: give 1..200 characters of A-Z a-z 0-9 _, not "
                             "starting with a digit");
}

std::filesystem::path default_profiles_path() {
  if (const char* env = std::getenv("GCPIPE_DDS_PROFILES"); env != nullptr && *env != '\0')
    return env;
  return default_pipeline_config().parent_path() / "dds_profiles.xml";
}

int default_domain(int fallback) {
  const char* env = std::getenv("GCPIPE_DDS_DOMAIN");
  if (env == nullptr || *env == '\0') return fallback;
  std::string_view s(env);
  int value = -1;
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  if (ec != std::errc() || p != s.data() + s.size() || value < 0 || value > 232)
    throw std::runtime_error("GCPIPE_DDS_DOMAIN='" + std::string(s) +
                             "' is not a DDS domain id (an integer in [0, 232])");
  return value;
}

// One stop flag for the whole process: the pipeline runner and the DDS loops poll the same.
void install_stop_handlers() { pipeline::install_stop_handlers(); }

bool stop_requested() { return pipeline::stop_requested(); }

// ---------------------------------------------------------------------------------------------

namespace {

// FNV-1a over the writer's 16-byte GUID: an id that tells the writers of one topic apart.
std::uint64_t writer_id(const fdds::InstanceHandle_t& handle) {
  std::uint64_t h = 1469598103934665603ull;
  for (int i = 0; i < 16; ++i) h = (h ^ handle.value[i]) * 1099511628211ull;
  return h == 0 ? 1 : h;
}

// What an edge writer's stage is doing (msg::Heartbeat::state).
enum class Activity : std::uint8_t {
  kIdle = 0,       // no program
  kHolding = 1,    // a program in flight, waiting for input
  kWorking = 2,    // handling an input sample: a stall when no progress for stall_timeout
  kBlocked = 3,    // a write waits for a reader downstream (that reader's stall, if any)
  kLeft = 4,       // the writer was deleted in good order
  kFinishing = 5,  // the program's end (Stage::finish): judged once the stage reported a step
  kReporting = 6,  // the program's report and figures: long steps that report nothing
};

// One edge writer's heartbeat: its sample and the state the stage thread updates.
struct Pulse {
  fdds::DataWriter* writer = nullptr;  // on EDGE_heartbeat
  std::mutex mutex;                    // guards `sample` (the stage thread sets the file and name)
  msg::Heartbeat sample;
  std::atomic<std::uint64_t> program{0}, progress{0};
  std::atomic<std::uint8_t> state{0};

  void beat() {
    std::lock_guard<std::mutex> lock(mutex);
    sample.program_id(program.load());
    sample.progress(progress.load());
    sample.state(state.load());
    writer->write(&sample);
  }
};

// The thread that sends every edge writer's heartbeat of one participant. A thread of its own, so
// that a stage busy in a long computation still beats; a frozen or killed process does not.
class Pulses {
 public:
  ~Pulses() { stop(); }
  void add(Pulse* p, double period) {
    std::lock_guard<std::mutex> lock(mutex_);
    pulses_.insert(p);
    if (!thread_.joinable()) thread_ = std::thread([this, period] { run(period); });
  }
  void remove(Pulse* p) {
    std::lock_guard<std::mutex> lock(mutex_);
    pulses_.erase(p);
  }
  void stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

 private:
  void run(double period) {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!stopping_) {
      for (Pulse* p : pulses_) p->beat();
      wake_.wait_for(lock, std::chrono::duration<double>(period), [this] { return stopping_; });
    }
  }
  std::mutex mutex_;
  std::condition_variable wake_;
  std::set<Pulse*> pulses_;
  std::thread thread_;
  bool stopping_ = false;
};

}  // namespace

// Participants dropped because their discovery lease ran out (their process died or froze), as
// opposed to those that left in good order: a reader that went away with one of them died.
class DroppedParticipants : public fdds::DomainParticipantListener {
 public:
  void on_participant_discovery(fdds::DomainParticipant*, eprosima::fastrtps::rtps::ParticipantDiscoveryInfo&& info) override {
    if (info.status == eprosima::fastrtps::rtps::ParticipantDiscoveryInfo::DROPPED_PARTICIPANT) ++dropped_;
  }
  int count() const { return dropped_.load(); }

 private:
  std::atomic<int> dropped_{0};
};

struct Participant::Impl {
  DdsOptions options;
  DroppedParticipants dropped;
  double start_time = 0;  // [s since the Unix epoch]
  fdds::DomainParticipant* participant = nullptr;
  fdds::Publisher* publisher = nullptr;
  fdds::Subscriber* subscriber = nullptr;
  // Each type is registered once; a topic is created once per name and may then be shared by
  // a reader and a writer of this process (a node reading and writing the same name is refused
  // by the node, not here).
  std::string type_names[kMessageTypes];
  std::map<std::string, std::pair<MessageType, fdds::Topic*>> topics;
  std::string heartbeat_type;
  std::map<std::string, fdds::Topic*> heartbeat_topics;  // by edge
  Pulses pulses;

  // EDGE_heartbeat, the edge's watchdog topic (type msg::Heartbeat). Null when it cannot be
  // created (a DDS Security identity made before heartbeats existed does not grant it): the
  // edge then goes without, and its readers rely on the discovery lease as before.
  fdds::Topic* heartbeat_topic(const std::string& edge) {
    if (auto it = heartbeat_topics.find(edge); it != heartbeat_topics.end()) return it->second;
    if (heartbeat_type.empty()) {
      fdds::TypeSupport support(new msg::HeartbeatPubSubType());
      if (!ok(support.register_type(participant))) return nullptr;
      heartbeat_type = support.get_type_name();
    }
    fdds::Topic* created = participant->create_topic(edge + "_heartbeat", heartbeat_type, fdds::TOPIC_QOS_DEFAULT);
    heartbeat_topics.emplace(edge, created);
    return created;
  }

  fdds::Topic* topic(MessageType type, const std::string& name) {
    check_topic_name(name);
    if (auto it = topics.find(name); it != topics.end()) {
      if (it->second.first != type)
        throw std::runtime_error("topic " + name + " is already used with type " +
                                 type_name(it->second.first) + ", not " + type_name(type));
      return it->second.second;
    }
    std::string& registered = type_names[static_cast<int>(type)];
    if (registered.empty()) {
      fdds::TypeSupport support;
      switch (type) {
        case MessageType::kProgramChunk: support = fdds::TypeSupport(new msg::ProgramChunkPubSubType()); break;
        case MessageType::kBlockBatch: support = fdds::TypeSupport(new msg::BlockBatchPubSubType()); break;
        case MessageType::kGcodeChunk: support = fdds::TypeSupport(new msg::GcodeChunkPubSubType()); break;
        case MessageType::kIkBatch: support = fdds::TypeSupport(new msg::IkBatchPubSubType()); break;
        case MessageType::kSampleBatch: support = fdds::TypeSupport(new msg::SampleBatchPubSubType()); break;
        case MessageType::kReportFragment: support = fdds::TypeSupport(new msg::ReportFragmentPubSubType()); break;
      }
      if (!ok(support.register_type(participant)))
        throw std::runtime_error(std::string("cannot register type ") + type_name(type) +
                                 " for topic " + name);
      registered = support.get_type_name();
    }
    fdds::Topic* created = participant->create_topic(name, registered, fdds::TOPIC_QOS_DEFAULT);
    if (created == nullptr) throw std::runtime_error("cannot create topic " + name);
    topics.emplace(name, std::make_pair(type, created));
    return created;
  }
};

namespace {

constexpr const char* kNetworkParticipantProfile = "gcpipe_network_participant";

void load_profiles_file(const std::filesystem::path& path, const char* what) {
  const std::string file = path.string();
  if (!std::filesystem::is_regular_file(path))
    throw std::runtime_error(std::string(what) + " file '" + file + "' does not exist");
  if (!ok(fdds::DomainParticipantFactory::get_instance()->load_XML_profiles_file(file)))
    throw std::runtime_error(std::string(what) + " file '" + file +
                             "' could not be loaded (Fast DDS printed the reason above)");
}

// DDS Security (builtin PKI-DH authentication, access control by signed governance and
// permissions, AES-GCM-GMAC): the identity folder's six files, made by make_security.sh.
void add_security(fdds::DomainParticipantQos& qos, const std::filesystem::path& identity) {
  struct File { const char* property; const char* name; };
  static constexpr File kFiles[] = {
      {"dds.sec.auth.builtin.PKI-DH.identity_ca", "identity_ca.pem"},
      {"dds.sec.auth.builtin.PKI-DH.identity_certificate", "cert.pem"},
      {"dds.sec.auth.builtin.PKI-DH.private_key", "key.pem"},
      {"dds.sec.access.builtin.Access-Permissions.permissions_ca", "permissions_ca.pem"},
      {"dds.sec.access.builtin.Access-Permissions.governance", "governance.p7s"},
      {"dds.sec.access.builtin.Access-Permissions.permissions", "permissions.p7s"}};
  auto& properties = qos.properties().properties();
  properties.emplace_back("dds.sec.auth.plugin", "builtin.PKI-DH");
  properties.emplace_back("dds.sec.access.plugin", "builtin.Access-Permissions");
  properties.emplace_back("dds.sec.crypto.plugin", "builtin.AES-GCM-GMAC");
  for (const File& f : kFiles) {
    const auto path = std::filesystem::absolute(identity / f.name);
    if (!std::filesystem::is_regular_file(path))
      throw std::runtime_error("DDS identity '" + identity.string() + "' has no " + f.name +
                               ": make one with stages/dds/make_security.sh");
    properties.emplace_back(f.property, "file://" + path.string());
  }
}

}  // namespace

Participant::Participant(const DdsOptions& options) : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  impl_->start_time = std::chrono::duration<double>(
                          std::chrono::system_clock::now().time_since_epoch()).count();
  if (impl_->options.profiles.empty()) impl_->options.profiles = default_profiles_path();
  if (options.domain < 0 || options.domain > 232)
    throw std::runtime_error("DDS domain id " + std::to_string(options.domain) +
                             " is outside [0, 232]");
  // Fast DDS prints errors only; its warnings say why a participant could not be created under
  // DDS Security (a certificate, a permission's subject) and are worth reading then.
  if (const char* v = std::getenv("GCPIPE_DDS_WARNINGS"); v != nullptr && *v == '1')
    fdds::Log::SetVerbosity(fdds::Log::Kind::Warning);
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  // load_profiles() must run before any default QoS is read, or the XML is silently ignored.
  factory->load_profiles();
  load_profiles_file(impl_->options.profiles, "DDS profiles");
  const bool network = !options.network.empty();
  if (network) load_profiles_file(options.network, "DDS network");
  const char* profile = network ? kNetworkParticipantProfile : kParticipantProfile;
  const std::string file = (network ? options.network : impl_->options.profiles).string();
  fdds::DomainParticipantQos qos;
  if (!ok(factory->get_participant_qos_from_profile(profile, qos)))
    throw std::runtime_error("'" + file + "' has no participant profile '" + profile + "'");
  if (!options.identity.empty()) add_security(qos, options.identity);
  // The listener hears discovery only: no status of the entities (they have their own listeners).
  impl_->participant =
      factory->create_participant(static_cast<fdds::DomainId_t>(options.domain), qos, &impl_->dropped, fdds::StatusMask::none());
  if (impl_->participant == nullptr)
    throw std::runtime_error("cannot create the DDS participant from profile '" + std::string(profile) + "' of '" +
                             file + "' on domain " + std::to_string(options.domain) +
                             (options.identity.empty() ? "" : " with identity '" + options.identity.string() + "'"));
  fdds::PublisherQos pub_qos = fdds::PUBLISHER_QOS_DEFAULT;
  fdds::SubscriberQos sub_qos = fdds::SUBSCRIBER_QOS_DEFAULT;
  if (!options.partition.empty()) {
    pub_qos.partition().push_back(options.partition.c_str());
    sub_qos.partition().push_back(options.partition.c_str());
    // "*" matches every named partition but not the default one (Fast DDS, as the DDS standard
    // has it): a reader for every pipeline names the default too.
    if (options.partition == "*") sub_qos.partition().push_back("");
  }
  impl_->publisher = impl_->participant->create_publisher(pub_qos);
  impl_->subscriber = impl_->participant->create_subscriber(sub_qos);
  if (impl_->publisher == nullptr || impl_->subscriber == nullptr)
    throw std::runtime_error("cannot create the DDS publisher/subscriber");
}

void shm_files_mapped_by(int pid, std::set<std::string>& out) {
  std::ifstream maps("/proc/" + std::to_string(pid) + "/maps");
  for (std::string line; std::getline(maps, line);) {
    const auto at = line.find("/dev/shm/");
    if (at == std::string::npos || line.find("fastrtps", at) == std::string::npos) continue;
    if (line.size() >= 10 && line.compare(line.size() - 10, 10, " (deleted)") == 0) continue;
    out.insert(line.substr(at));
  }
}

// A killed process's port queue stays mapped by nobody and `fastdds shm clean` leaves it (it has
// no lock file).
void remove_unmapped_shm_files(const std::set<std::string>& files) {
  std::set<std::string> live;
  for (const auto& entry : std::filesystem::directory_iterator("/proc")) {
    const std::string name = entry.path().filename().string();
    if (name.empty() || name.find_first_not_of("0123456789") != std::string::npos) continue;
    shm_files_mapped_by(std::stoi(name), live);
  }
  std::error_code ec;
  for (const auto& f : files) {
    if (live.count(f) != 0) continue;
    std::filesystem::remove(f, ec);
    // Its lock file, and a port queue's named semaphore (sem_open maps it only while in use).
    const std::string name = std::filesystem::path(f).filename().string();
    std::filesystem::remove(f + "_el", ec);
    if (name.rfind("fastrtps_port", 0) == 0) std::filesystem::remove("/dev/shm/sem." + name + "_mutex", ec);
  }
}

std::size_t clean_dead_shared_memory() {
  std::set<std::string> files;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator("/dev/shm", ec)) {
    const std::string name = entry.path().filename().string();
    // The data files: lock files and semaphores go with them in remove_unmapped_shm_files.
    if (name.rfind("fastrtps_", 0) != 0 || name.ends_with("_el") || name.ends_with("_sl")) continue;
    files.insert(entry.path().string());
  }
  remove_unmapped_shm_files(files);
  std::size_t left = 0;
  for (const auto& f : files) left += std::filesystem::exists(f, ec);
  return files.size() - left;
}

namespace {

// The port queues this process owns: /dev/shm/fastrtps_portN whose lock file (`_el`) it holds.
std::set<std::string> own_shm_ports() {
  std::set<std::string> inodes;  // "dev:inode" of the files this process holds a lock on
  std::ifstream locks("/proc/locks");
  const std::string me = std::to_string(::getpid());
  for (std::string line; std::getline(locks, line);) {
    std::istringstream in(line);
    std::vector<std::string> f;
    for (std::string w; in >> w;) f.push_back(w);
    if (f.size() >= 6 && f[1] != "->" && f[4] == me) inodes.insert(f[5].substr(f[5].rfind(':') + 1));
  }
  std::set<std::string> own;
  if (inodes.empty()) return own;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator("/dev/shm", ec)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("fastrtps_port", 0) != 0 || name.size() < 4 || name.compare(name.size() - 3, 3, "_el") != 0) continue;
    struct stat st {};
    if (::stat(e.path().c_str(), &st) == 0 && inodes.count(std::to_string(st.st_ino)) != 0)
      own.insert(e.path().string().substr(0, e.path().string().size() - 3));
  }
  return own;
}

}  // namespace

Participant::~Participant() {
  if (impl_->participant == nullptr) return;
  // Fast DDS removes this process's port queue as the participant goes, except when a process
  // that sent to it was killed meanwhile (its reference to the queue is never given back): the
  // queue is then left behind, mapped by nobody (a feed whose parse node was killed mid-program,
  // Launch.ARestartedStage...). Such a queue of our own is removed here.
  const std::set<std::string> own = own_shm_ports();
  impl_->pulses.stop();
  impl_->participant->delete_contained_entities();
  fdds::DomainParticipantFactory::get_instance()->delete_participant(impl_->participant);
  std::set<std::string> left;
  for (const auto& f : own)
    if (std::filesystem::exists(f)) left.insert(f);
  if (!left.empty()) remove_unmapped_shm_files(left);
}

const DdsOptions& Participant::options() const { return impl_->options; }

bool Participant::published_before_start(double source_time) const {
  return !impl_->options.replay && source_time < impl_->start_time;
}

// ---------------------------------------------------------------------------------------------

// Why creating an entity can fail: inconsistent resource limits in the XML make Fast DDS return
// null without an exception; under DDS Security so does a topic the permissions do not grant.
std::string creation_hint(const Participant::Impl& owner, const char* verb) {
  std::string hint = "(check max_samples >= max_instances * max_samples_per_instance";
  if (!owner.options.identity.empty())
    hint += "; or the permissions of identity '" + owner.options.identity.string() + "' do not allow it to " +
            verb + " this topic";
  return hint + ")";
}

// How many readers left: a reader that leaves while a program is being sent will never take its
// rest, even when another reader (its stage restarted) matched in the meantime and keeps the
// matched count up.
class LostReaders : public fdds::DataWriterListener {
 public:
  void on_publication_matched(fdds::DataWriter*, const fdds::PublicationMatchedStatus& status) override {
    if (status.current_count_change < 0) lost_ += -status.current_count_change;
  }
  int lost() const { return lost_.load(); }

 private:
  std::atomic<int> lost_{0};
};

struct RawWriter::Impl {
  Participant::Impl* owner = nullptr;
  fdds::DataWriter* writer = nullptr;
  LostReaders listener;
  int lost_before_first_sample = -1;  // -1: nothing published yet
  int dropped_before_first_sample = 0;  // participants dropped on this domain before it
  std::unique_ptr<Pulse> pulse;  // the edge's heartbeat; null for a monitor copy, a report writer
  // A reader left since the first sample (for one-program writers). Checked while samples are
  // still to be written only: a reader that took the end marker and left is done, not lost.
  bool reader_left_mid_program() const {
    return lost_before_first_sample >= 0 && listener.lost() > lost_before_first_sample;
  }
};

RawWriter::RawWriter(Participant& participant, MessageType type, const std::string& topic, bool monitor,
                     const char* profile_name)
    : impl_(std::make_unique<Impl>()), topic_(topic), monitor_(monitor),
      subscribers_(participant.options().subscribers) {
  impl_->owner = &participant.impl();
  const char* profile = profile_name ? profile_name : monitor ? kMonitorWriterProfile : kWriterProfile;
  fdds::Topic* dds_topic = impl_->owner->topic(type, topic);
  const auto mask = fdds::StatusMask::publication_matched();
  if (monitor && profile_name == nullptr && participant.options().monitor_history > 0) {
    // The one QoS taken from an option, not the XML: how long a monitor copy keeps a sample for
    // late monitors (pipeline.monitor_history), so a pipeline file can set it without its own
    // copy of dds_profiles.xml. The rest stays the profile's.
    fdds::DataWriterQos qos;
    if (!ok(impl_->owner->publisher->get_datawriter_qos_from_profile(profile, qos)))
      throw std::runtime_error(std::string("no data_writer profile '") + profile + "' in '" +
                               impl_->owner->options.profiles.string() + "'");
    qos.lifespan().duration = duration(participant.options().monitor_history);
    impl_->writer = impl_->owner->publisher->create_datawriter(dds_topic, qos, &impl_->listener, mask);
  } else {
    impl_->writer = impl_->owner->publisher->create_datawriter_with_profile(dds_topic, profile, &impl_->listener, mask);
  }
  // Inconsistent resource limits in the XML make this return null without an exception.
  if (impl_->writer == nullptr)
    throw std::runtime_error("cannot create a writer of " + topic + " from profile '" + profile + "' of '" +
                             impl_->owner->options.profiles.string() + "' " + creation_hint(*impl_->owner, "publish"));
  if (!monitor && profile_name == nullptr) start_heartbeat();
}

namespace {

// The heartbeat's QoS, set here rather than in the XML (whose default profiles are the edges'):
// best effort, since a lost beat is made good by the next and a beat must never wait for a
// reader (reliable, the beats of one writer in about one run of six never reached a node whose
// edge from that writer worked: DdsPipeline.*MiddleNode*, 2026-11-28; the late-joining volatile
// reader and keep-last 1 writer of Fast DDS 2.9's reliable protocol were not traced further);
// keep-last 1, since only the newest beat matters; volatile, since an old beat says nothing of now.
fdds::DataWriterQos heartbeat_writer_qos() {
  fdds::DataWriterQos qos;
  qos.reliability().kind = fdds::BEST_EFFORT_RELIABILITY_QOS;
  qos.durability().kind = fdds::VOLATILE_DURABILITY_QOS;
  qos.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
  qos.history().depth = 1;
  return qos;
}

// Keeps the last beats of every writer of the edge (one instance for all: the type has no key).
fdds::DataReaderQos heartbeat_reader_qos() {
  fdds::DataReaderQos qos;
  qos.reliability().kind = fdds::BEST_EFFORT_RELIABILITY_QOS;
  qos.durability().kind = fdds::VOLATILE_DURABILITY_QOS;
  qos.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
  qos.history().depth = 64;
  return qos;
}

}  // namespace

void RawWriter::start_heartbeat() {
  Participant::Impl& owner = *impl_->owner;
  fdds::Topic* topic = owner.heartbeat_topic(topic_);
  fdds::DataWriter* w = topic ? owner.publisher->create_datawriter(topic, heartbeat_writer_qos()) : nullptr;
  if (w == nullptr) {
    say_line("gcpipe: no heartbeat on " + topic_ + "_heartbeat (its readers rely on the discovery lease): " +
             creation_hint(owner, "publish"));
    return;
  }
  auto pulse = std::make_unique<Pulse>();
  pulse->writer = w;
  pulse->sample.writer(id());
  pulse->sample.stage("?");
  pulse->sample.pid(static_cast<std::uint64_t>(::getpid()));
  pulse->sample.period(owner.options.heartbeat_period);
  impl_->pulse = std::move(pulse);
  owner.pulses.add(impl_->pulse.get(), owner.options.heartbeat_period);
}

RawWriter::~RawWriter() {
  if (Pulse* p = impl_->pulse.get()) {
    // The last beat says the writer leaves in good order: its readers then know it did not die.
    impl_->owner->pulses.remove(p);
    p->state = static_cast<std::uint8_t>(Activity::kLeft);
    p->beat();
    impl_->owner->publisher->delete_datawriter(p->writer);
  }
  if (impl_->writer != nullptr) impl_->owner->publisher->delete_datawriter(impl_->writer);
}

std::uint64_t RawWriter::id() const { return writer_id(impl_->writer->get_instance_handle()); }

void RawWriter::set_stage_name(const std::string& stage) {
  if (Pulse* p = impl_->pulse.get()) {
    std::lock_guard<std::mutex> lock(p->mutex);
    p->sample.stage(stage);
  }
}

void RawWriter::working(std::uint64_t program, const std::string& file) {
  Pulse* p = impl_->pulse.get();
  if (p == nullptr) return;
  if (p->program.load() != program) {
    std::lock_guard<std::mutex> lock(p->mutex);
    p->sample.file(file);
  }
  p->program = program;
  p->state = static_cast<std::uint8_t>(Activity::kWorking);
  ++p->progress;
}

void RawWriter::finishing() {
  if (Pulse* p = impl_->pulse.get()) p->state = static_cast<std::uint8_t>(Activity::kFinishing);
}

void RawWriter::reporting() {
  if (Pulse* p = impl_->pulse.get()) p->state = static_cast<std::uint8_t>(Activity::kReporting);
}

void RawWriter::holding() {
  if (Pulse* p = impl_->pulse.get()) p->state = static_cast<std::uint8_t>(Activity::kHolding);
}

void RawWriter::idle() {
  if (Pulse* p = impl_->pulse.get()) {
    p->program = 0;
    p->state = static_cast<std::uint8_t>(Activity::kIdle);
  }
}

void RawWriter::progressed() {
  if (Pulse* p = impl_->pulse.get()) ++p->progress;
}

int RawWriter::matched_readers() const {
  fdds::PublicationMatchedStatus status;
  impl_->writer->get_publication_matched_status(status);
  return status.current_count;
}

bool RawWriter::wait_for_readers() { return wait_for_readers(subscribers_); }

bool RawWriter::wait_for_readers(int count) {
  const auto& o = impl_->owner->options;
  const auto t0 = Clock::now();
  while (matched_readers() < count) {
    if (stop_requested()) return false;
    if (seconds_since(t0) > o.match_timeout)
      throw std::runtime_error(std::string("no reader of ") + topic_ + " within " +
                               seconds_text(o.match_timeout) + " on domain " +
                               std::to_string(o.domain) + " (waiting for " +
                               std::to_string(count) + ", matched " +
                               std::to_string(matched_readers()) + ")");
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

bool RawWriter::publish(const void* sample) {
  // A monitor's copy: keep-last never blocks on a reader; a lost copy only thins the view.
  if (monitor_) return impl_->writer->write(const_cast<void*>(sample)), true;
  const auto& o = impl_->owner->options;
  const auto t0 = Clock::now();
  // A reader that matched and is gone now (its process died, or stopped announcing itself for
  // the discovery lease) will never take the rest: say so at once instead of filling the history
  // and waiting out write_timeout.
  if (impl_->lost_before_first_sample < 0) {
    impl_->lost_before_first_sample = impl_->listener.lost();
    impl_->dropped_before_first_sample = impl_->owner->dropped.count();
  }
  auto check_readers = [&] {
    if (const int left = o.fail_on_lost_reader ? matched_readers() : subscribers_; left < subscribers_)
      throw std::runtime_error(std::string("writing to ") + topic_ + ": a reader went away (" + std::to_string(left) +
                               " of " + std::to_string(subscribers_) +
                               " left): its stage stopped or died, the rest of the program is not sent");
    if (o.fail_on_lost_reader && impl_->reader_left_mid_program())
      throw std::runtime_error(std::string("writing to ") + topic_ +
                               ": a reader went away mid-program (its stage stopped or died; a restarted stage "
                               "does not take a program in flight): the rest of the program is not sent");
  };
  check_readers();
  // Waiting for a reader downstream is not a stall of this stage: its heartbeat says blocked.
  Pulse* pulse = impl_->pulse.get();
  const std::uint8_t before = pulse ? pulse->state.load() : 0;
  struct Restore {
    Pulse* p;
    std::uint8_t state;
    ~Restore() {
      if (p) {
        p->state = state;
        ++p->progress;
      }
    }
  } restore{pulse, before};
  // write() blocks up to the profile's max_blocking_time, then returns false with the sample
  // not stored; a retry is therefore safe and cannot duplicate it.
  while (!impl_->writer->write(const_cast<void*>(sample))) {
    if (pulse) pulse->state = static_cast<std::uint8_t>(Activity::kBlocked);
    if (blocked_writes_++ == 0)
      std::cerr << "gcpipe: " << topic_
                << ": history full, a reader lags behind; retrying the write until it catches up"
                << " (at most " << o.write_timeout << " s per write)" << std::endl;
    if (stop_requested()) return false;
    check_readers();  // blocked by a reader that died: its acknowledgements never come
    if (seconds_since(t0) > o.write_timeout)
      throw std::runtime_error(std::string("writing to ") + topic_ +
                               " stayed blocked for " + seconds_text(o.write_timeout) +
                               ": a reader stopped acknowledging (history full)");
  }
  return true;
}

bool RawWriter::wait_acknowledged() { return wait_acknowledged(impl_->owner->options.ack_timeout); }

bool RawWriter::wait_acknowledged(double limit) {
  const auto t0 = Clock::now();
  for (;;) {
    if (ok(impl_->writer->wait_for_acknowledgments(duration(std::min(limit, kPollPeriod))))) return true;
    if (stop_requested() || seconds_since(t0) > limit) return false;
  }
}

bool RawWriter::reader_died_mid_program() const {
  return impl_->reader_left_mid_program() && impl_->owner->dropped.count() > impl_->dropped_before_first_sample;
}

// ---------------------------------------------------------------------------------------------

namespace {

// Which writers left: Fast DDS 2.9's DataReader::get_matched_publications is not implemented, so
// the matched-status callbacks are recorded instead (on Fast DDS's event thread).
class GoneWriters : public fdds::DataReaderListener {
 public:
  void on_subscription_matched(fdds::DataReader*, const fdds::SubscriptionMatchedStatus& status) override {
    const std::uint64_t id = writer_id(status.last_publication_handle);
    std::lock_guard<std::mutex> lock(mutex_);
    if (status.current_count_change < 0) gone_.insert(id);
    else if (status.current_count_change > 0) gone_.erase(id);
  }
  bool gone(std::uint64_t id) const {
    std::lock_guard<std::mutex> lock(mutex_);
    return gone_.count(id) != 0;
  }

 private:
  mutable std::mutex mutex_;
  std::set<std::uint64_t> gone_;
};

}  // namespace

namespace {

// What the heartbeats of one edge's writers said last, kept by Fast DDS's receive thread as they
// arrive (a reader busy in its stage does not delay their clock).
class HeartbeatWatch : public fdds::DataReaderListener {
 public:
  struct Writer {
    msg::Heartbeat last;
    Clock::time_point heard, moved;  // last beat; last beat whose progress or state changed
    bool reported = false;           // its program was handed out as lost
    std::uint64_t finish_base = 0;   // progress when it began finishing the program
  };

  void on_data_available(fdds::DataReader* reader) override {
    msg::Heartbeat beat;
    fdds::SampleInfo info;
    while (ok(reader->take_next_sample(&beat, &info))) {
      if (!info.valid_data) continue;
      const auto now = Clock::now();
      std::lock_guard<std::mutex> lock(mutex_);
      auto [it, fresh] = writers_.try_emplace(beat.writer());
      Writer& w = it->second;
      if (fresh || w.last.progress() != beat.progress() || w.last.state() != beat.state() ||
          w.last.program_id() != beat.program_id()) {
        w.moved = now;
        if (w.last.program_id() != beat.program_id()) w.reported = false;
        if (beat.state() == static_cast<std::uint8_t>(Activity::kFinishing) && (fresh || w.last.state() != beat.state()))
          w.finish_base = beat.progress();
      }
      w.heard = now;
      w.last = beat;
    }
  }

  // Why `w` is taken for dead, frozen or stalled; "" when it is not.
  std::string trouble(const Writer& w, const std::string& edge, const DdsOptions& o) const {
    const auto& b = w.last;
    if (b.state() == static_cast<std::uint8_t>(Activity::kLeft)) return "";
    const double silent = std::chrono::duration<double>(Clock::now() - w.heard).count();
    const std::string who = "the " + b.stage() + " stage (pid " + std::to_string(b.pid()) + ", writer of " + edge + ")";
    std::ostringstream o_;
    o_ << std::fixed << std::setprecision(1);
    const char* doing = b.state() == static_cast<std::uint8_t>(Activity::kFinishing) ? "finishing" : "working on";
    if (silent > o.heartbeat_timeout) {
      o_ << who << " sent no heartbeat for " << silent << " s (bound " << o.heartbeat_timeout
         << " s, pipeline.heartbeat_timeout): it died or is frozen";
      return o_.str();
    }
    const double still = std::chrono::duration<double>(Clock::now() - w.moved).count();
    // At the program's end only a stage that reports its steps (the compensation, window by
    // window; the simulation's ticks) can be told stalled; one that does not (the trochoid
    // stage's engagement analysis) is covered by its heartbeat alone.
    const auto state = static_cast<Activity>(b.state());
    const bool judged = state == Activity::kWorking || (state == Activity::kFinishing && b.progress() > w.finish_base);
    if (judged && still > o.stall_timeout) {
      o_ << who << " made no progress for " << still << " s while " << doing << " program " << b.program_id()
         << " (bound " << o.stall_timeout << " s, pipeline.stall_timeout): it is stalled";
      return o_.str();
    }
    return "";
  }

  std::string trouble_of(std::uint64_t writer, const std::string& edge, const DdsOptions& o) const {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = writers_.find(writer);
    return it == writers_.end() ? "" : trouble(it->second, edge, o);
  }

  std::vector<RawReader::LostProgram> lost(const std::string& edge, const DdsOptions& o) {
    std::vector<RawReader::LostProgram> out;
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto& [id, w] : writers_) {
      if (w.reported || w.last.program_id() == 0) continue;
      const auto state = static_cast<Activity>(w.last.state());
      // A stage stopped in good order (SIGTERM) with a program in hand loses it as surely.
      std::string why = state == Activity::kLeft
                            ? "the " + w.last.stage() + " stage (pid " + std::to_string(w.last.pid()) + ", writer of " +
                                  edge + ") stopped"
                            : state == Activity::kIdle ? "" : trouble(w, edge, o);
      if (why.empty()) continue;
      w.reported = true;
      out.push_back({id, w.last.program_id(), w.last.file(), std::move(why)});
    }
    return out;
  }

 private:
  mutable std::mutex mutex_;
  std::map<std::uint64_t, Writer> writers_;
};

}  // namespace

struct RawReader::Impl {
  Participant::Impl* owner = nullptr;
  fdds::DataReader* reader = nullptr;
  GoneWriters listener;
  fdds::DataReader* heartbeats = nullptr;  // EDGE_heartbeat; null for a monitor's reader
  HeartbeatWatch watch;
  std::vector<double> hop_latencies;  // [s] of the samples taken since the last report
};

RawReader::RawReader(Participant& participant, MessageType type, const std::string& topic, bool monitor)
    : impl_(std::make_unique<Impl>()), topic_(topic) {
  impl_->owner = &participant.impl();
  const char* profile = monitor ? kMonitorReaderProfile : kReaderProfile;
  impl_->reader = impl_->owner->subscriber->create_datareader_with_profile(
      impl_->owner->topic(type, topic), profile, &impl_->listener, fdds::StatusMask::subscription_matched());
  if (impl_->reader == nullptr)
    throw std::runtime_error("cannot create a reader of " + topic + " from profile '" + profile + "' of '" +
                             impl_->owner->options.profiles.string() + "' " + creation_hint(*impl_->owner, "subscribe"));
  if (!monitor) {
    fdds::Topic* beats = impl_->owner->heartbeat_topic(topic);
    if (beats != nullptr)
      impl_->heartbeats = impl_->owner->subscriber->create_datareader(beats, heartbeat_reader_qos(), &impl_->watch,
                                                                      fdds::StatusMask::data_available());
    if (impl_->heartbeats == nullptr)
      say_line("gcpipe: cannot read " + topic + "_heartbeat (a dead writer is then noticed by the discovery lease only)");
  }
}

RawReader::~RawReader() {
  if (impl_->heartbeats != nullptr) impl_->owner->subscriber->delete_datareader(impl_->heartbeats);
  if (impl_->reader != nullptr) impl_->owner->subscriber->delete_datareader(impl_->reader);
}

struct HeartbeatWatcher::Impl {
  Participant::Impl* owner = nullptr;
  struct Edge {
    std::string topic;
    fdds::DataReader* reader = nullptr;
    HeartbeatWatch watch;
  };
  std::vector<std::unique_ptr<Edge>> edges;
};

HeartbeatWatcher::HeartbeatWatcher(Participant& participant, const std::vector<std::string>& topics)
    : impl_(std::make_unique<Impl>()) {
  impl_->owner = &participant.impl();
  for (const std::string& topic : topics) {
    auto edge = std::make_unique<Impl::Edge>();
    edge->topic = topic;
    if (fdds::Topic* beats = impl_->owner->heartbeat_topic(topic))
      edge->reader = impl_->owner->subscriber->create_datareader(beats, heartbeat_reader_qos(), &edge->watch,
                                                                 fdds::StatusMask::data_available());
    if (edge->reader != nullptr) impl_->edges.push_back(std::move(edge));
  }
}

HeartbeatWatcher::~HeartbeatWatcher() {
  for (auto& edge : impl_->edges) impl_->owner->subscriber->delete_datareader(edge->reader);
}

std::vector<RawReader::LostProgram> HeartbeatWatcher::programs_lost() {
  std::vector<RawReader::LostProgram> all;
  for (auto& edge : impl_->edges) {
    auto lost = edge->watch.lost(edge->topic, impl_->owner->options);
    all.insert(all.end(), lost.begin(), lost.end());
  }
  return all;
}

std::string RawReader::writer_trouble(std::uint64_t writer) const {
  return impl_->watch.trouble_of(writer, topic_, impl_->owner->options);
}

std::vector<RawReader::LostProgram> RawReader::programs_lost_upstream() {
  return impl_->watch.lost(topic_, impl_->owner->options);
}

bool RawReader::take(void* sample, double timeout_s, double* source_time, std::uint64_t* writer) {
  const auto t0 = Clock::now();
  fdds::SampleInfo info;
  for (;;) {
    // Samples without data (a writer leaving changes the instance state) are skipped.
    while (ok(impl_->reader->take_next_sample(sample, &info))) {
      if (!info.valid_data) continue;
      impl_->hop_latencies.push_back(
          static_cast<double>(info.reception_timestamp.to_ns() - info.source_timestamp.to_ns()) * 1e-9);
      if (source_time != nullptr)
        *source_time = static_cast<double>(info.source_timestamp.to_ns()) * 1e-9;
      if (writer != nullptr) *writer = writer_id(info.publication_handle);
      return true;
    }
    const double left = timeout_s - seconds_since(t0);
    if (left <= 0 || stop_requested()) return false;
    impl_->reader->wait_for_unread_message(duration(std::min(left, kPollPeriod)));
  }
}

std::string RawReader::take_hop_latency_text() {
  std::vector<double>& v = impl_->hop_latencies;
  if (v.empty()) return "";
  auto quantile = [&v](double q) {
    const auto k = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5);
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
    return v[k] * 1e3;
  };
  std::ostringstream o;
  o << std::fixed << std::setprecision(3) << "hop latency from " << topic_ << ": p50 " << quantile(0.5)
    << " ms, p99 " << quantile(0.99) << " ms, max " << quantile(1.0) << " ms over " << v.size() << " samples";
  v.clear();
  return o.str();
}

bool RawReader::writer_gone(std::uint64_t writer) const { return impl_->listener.gone(writer); }

int RawReader::matched_writers() const {
  fdds::SubscriptionMatchedStatus status;
  impl_->reader->get_subscription_matched_status(status);
  return status.current_count;
}

void say_line(const std::string& line) {
  const std::string whole = line + "\n";
  std::cerr.write(whole.data(), static_cast<std::streamsize>(whole.size()));
  std::cerr.flush();
}

int run_stage_node(const std::string& node, Participant& participant, RawWriter& output, bool forever,
                   const std::function<Taken(double timeout)>& take, int& status) {
  // `gcpipe launch` takes this line as "started": the participant, reader and writer exist.
  // Each line is written whole (one write): the stages of a group print from their own threads.
  say_line("gcpipe node " + node + ": up on domain " + std::to_string(participant.options().domain) +
           ", waiting for " + std::to_string(output.subscribers()) + " reader(s) of " + output.topic());
  if (!output.wait_for_readers()) return 130;
  say_line("gcpipe node " + node + ": ready, " + std::to_string(output.matched_readers()) + " reader(s) of " +
           output.topic() + " matched");
  bool done = false;
  const double idle_timeout = participant.options().idle_timeout;
  auto last_sample = std::chrono::steady_clock::now();
  while (!done && !stop_requested()) {
    const Taken t = take(0.1);
    if (t == Taken::kNothing) {
      const std::chrono::duration<double> idle = std::chrono::steady_clock::now() - last_sample;
      if (idle_timeout > 0 && idle.count() > idle_timeout && !forever) {
        std::cerr << "gcpipe node " << node << ": nothing arrived for " << idle_timeout << " s\n";
        break;
      }
      continue;
    }
    last_sample = std::chrono::steady_clock::now();
    if (t == Taken::kProgramEnd && !forever) done = true;
  }
  if (!done && !forever) {
    std::cerr << "gcpipe node " << node << ": stopped before the end of the program\n";
    status = 1;
  }
  if (!output.wait_acknowledged()) {
    std::cerr << "gcpipe node " << node << ": not every sample was acknowledged by the readers of "
              << output.topic() << "\n";
    status = 1;
  }
  return status;
}

}  // namespace gcpipe::dds
