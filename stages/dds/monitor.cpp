#include "monitor.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <memory>
#include <optional>
#include <ostream>
#include <thread>

#include "contour_figure.hpp"
#include "dds_convert.hpp"
#include "gcpipe/kinematics.hpp"
#include "stage.hpp"

namespace gcpipe::dds {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// What the monitor extracts from one sample of each topic.
struct Seen {
  std::uint64_t program_id = 0, sequence = 0, items = 0, last_line = 0, errors = 0;
  bool end = false;
};

Seen inspect(const msg::ProgramChunk& c) {
  Seen s{c.program_id(), c.sequence_number(), c.lines().size(), 0, 0, c.end_of_program()};
  if (!c.lines().empty()) s.last_line = c.first_line() + c.lines().size() - 1;
  return s;
}
Seen inspect(const msg::BlockBatch& b) {
  Seen s{b.program_id(), b.sequence_number(), b.blocks().size(), 0, 0, b.end_of_program()};
  if (!b.blocks().empty()) s.last_line = b.blocks().back().line();
  if (!b.diagnostics().empty()) s.last_line = std::max(s.last_line, b.diagnostics().back().line());
  for (const auto& d : b.diagnostics())
    if (d.line_status() != static_cast<std::uint8_t>(DiagnosticKind::kLineDeleted)) ++s.errors;
  return s;
}
Seen inspect(const msg::GcodeChunk& g) {
  return Seen{g.program_id(), g.sequence_number(), g.text().size(), g.last_line(), 0,
              g.end_of_program()};
}
Seen inspect(const msg::IkBatch& b) {
  Seen s{b.program_id(), b.sequence_number(), b.points().size(), 0, 0, b.end_of_program()};
  if (!b.points().empty()) s.last_line = b.points().back().line();
  for (const auto& p : b.points())
    if (p.status() == static_cast<std::uint8_t>(IkStatus::kFailed)) ++s.errors;
  return s;
}
Seen inspect(const msg::SampleBatch& b) {
  Seen s{b.program_id(), b.sequence_number(), b.samples().size(), 0, 0, b.end_of_program()};
  if (!b.samples().empty()) s.last_line = b.samples().back().line();
  return s;
}

const char* item_name(MessageType t) {
  switch (t) {
    case MessageType::kProgramChunk: return "lines";
    case MessageType::kBlockBatch: return "blocks";
    case MessageType::kGcodeChunk: return "bytes";
    case MessageType::kIkBatch: return "points";
    case MessageType::kSampleBatch: return "ticks";
    case MessageType::kReportFragment: return "report parts";
  }
  return "items";
}

// What a monitor shows of the telemetry topics beside the counts: the IK flags, and the contour
// error and torque saturation of the simulated machine.
struct TelemetryFigures {
  std::uint64_t degraded = 0, diverged = 0, outside_envelope = 0;  // IK points
  double time = 0, contour_now = 0, contour_max = 0, contour_sum_sq = 0;  // ticks [s, mm]
  std::uint64_t cutting_ticks = 0;
  std::array<std::uint64_t, kNumAxes> saturated{};
  bool ik = false, samples = false;
  ContourFigure* figure = nullptr;  // monitor --plot: every tick goes to the live figure too

  void add(const msg::ProgramChunk&) {}
  void add(const msg::BlockBatch&) {}
  void add(const msg::GcodeChunk&) {}
  void add(const msg::IkBatch& b) {
    ik = true;
    for (const auto& p : b.points()) {
      if (p.status() == static_cast<std::uint8_t>(IkStatus::kDegraded)) ++degraded;
      if ((p.flags() & kIkNeuralDiverged) != 0) ++diverged;
      if ((p.flags() & kIkNeuralOutsideEnvelope) != 0) ++outside_envelope;
    }
  }
  void add(const msg::SampleBatch& b) {
    samples = true;
    for (const auto& s : b.samples()) {
      time = s.time();
      if (figure != nullptr) figure->add(s.time(), s.contour());
      // Rapids carry no contour error (0): the figures are the cutting moves', as report.json's.
      if (s.contour() > 0) {
        contour_now = s.contour();
        contour_max = std::max(contour_max, s.contour());
        contour_sum_sq += s.contour() * s.contour();
        ++cutting_ticks;
      }
      for (std::size_t i = 0; i < kNumAxes; ++i)
        if ((s.saturated() >> i) & 1u) ++saturated[i];
    }
  }
  void print(std::ostream& o) const {
    if (ik)
      o << "  degraded " << degraded << "  neural diverged " << diverged << "  outside envelope "
        << outside_envelope;
    if (!samples) return;
    const double rms = cutting_ticks ? std::sqrt(contour_sum_sq / static_cast<double>(cutting_ticks)) : 0.0;
    o << std::setprecision(3) << "  t " << time << " s  contour um: now " << contour_now * 1e3 << " max "
      << contour_max * 1e3 << " rms " << rms * 1e3 << "  torque-limited ticks";
    for (std::size_t i = 0; i < kNumAxes; ++i) o << " " << kAxisLetters[i] << " " << saturated[i];
  }
};

void print_end(std::ostream& out, const msg::ProgramChunk& c) {
  out << "end of program: " << c.line_count() << " lines, " << c.byte_count() << " bytes";
}
void print_end(std::ostream& out, const msg::BlockBatch& b) {
  const auto& s = b.summary();
  out << "end of program: " << s.lines_read() << " lines read, " << s.blocks_emitted()
      << " blocks, " << s.lines_rejected() << " rejected, " << s.lines_deleted() << " deleted"
      << "; sent " << b.blocks_sent() << " blocks, " << b.diagnostics_sent() << " diagnostics, "
      << b.blocks_rejected() << " blocks rejected" << (b.stopped() ? ", strict stop" : "")
      << (b.error().empty() ? "" : ", ERROR: " + b.error());
}
void print_end(std::ostream& out, const msg::IkBatch& b) {
  out << "end of program: " << b.item_count() << " IK points";
}
void print_end(std::ostream& out, const msg::SampleBatch& b) {
  out << "end of program: " << b.item_count() << " ticks";
}
void print_end(std::ostream& out, const msg::GcodeChunk& g) {
  out << "end of program: " << g.byte_count() << " bytes, " << g.blocks_written() << " blocks, "
      << g.diagnostics_written() << " diagnostics, " << g.blocks_rejected()
      << " blocks rejected" << (g.stopped() ? ", strict stop" : "")
      << (g.error().empty() ? "" : ", ERROR: " + g.error());
}

// What a monitor follows on one topic: the first program it sees there, counted as it arrives.
class Watch {
 public:
  virtual ~Watch() = default;
  /// Takes at most one sample within `timeout` [s]; true when one arrived.
  virtual bool poll(double timeout) = 0;
  /// "the writer of TOPIC matched" once, when it first connects.
  virtual void announce_match(std::ostream& out) = 0;
  /// One status line (without the newline); `dt` [s] since the last, for the rate.
  virtual void status(std::ostream& out, double dt) = 0;
  /// The end-of-program line, with what was missed.
  virtual void ending(std::ostream& out) const = 0;
  virtual bool ended() const = 0;
  /// The writer went away (for a second, with nothing left to take) before the program's end:
  /// the rest will never come (a dead stage, or a keep-last copy that dropped the end for a
  /// monitor that fell behind).
  virtual bool lost() = 0;
};

template <class T>
class TopicWatch final : public Watch {
 public:
  TopicWatch(Participant& p, std::string label, std::string topic, ContourFigure* figure)
      : label_(std::move(label)), topic_(std::move(topic)), reader_(p, monitor_topic(topic_), /*monitor=*/true) {
    figures_.figure = figure;
  }

  bool poll(double timeout) override {
    if (!reader_.take(sample_, timeout)) return false;
    const Seen s = inspect(sample_);
    if (samples_ == 0) {
      program_ = s.program_id;
      first_seq_ = s.sequence;
    }
    if (s.program_id != program_ || ended_) return true;  // another program: the first one is ours
    ++samples_;
    items_ += s.items;
    window_items_ += s.items;
    errors_ += s.errors;
    figures_.add(sample_);
    if (s.last_line != 0) last_line_ = s.last_line;
    if (s.end) {
      ended_ = true;
      last_ = sample_;
      end_sequence_ = s.sequence;
    }
    return true;
  }

  void announce_match(std::ostream& out) override {
    if (matched_ || reader_.matched_writers() == 0) return;
    // From here on nothing the writer publishes is missed, nor what its copy still holds (the
    // last monitor_history seconds, at most 256 batches).
    out << "gcpipe monitor: the writer of " << topic_ << " matched" << std::endl;
    matched_ = true;
  }

  void status(std::ostream& o, double dt) override {
    o << label_ << "  program " << program_ << "  batches " << samples_ << "  " << item_name(TypeOf<T>::value) << " "
      << items_ << " (" << std::fixed << std::setprecision(0) << (dt > 0 ? window_items_ / dt : 0.0) << "/s)"
      << "  last line " << last_line_ << "  errors " << errors_;
    figures_.print(o);
    window_items_ = 0;
  }

  void ending(std::ostream& o) const override {
    o << label_ << "  program " << program_ << "  ";
    if (!ended_) {
      o << "the writer went away after " << samples_ << " batches, before the end of the program: the rest was missed";
      return;
    }
    print_end(o, last_);
    if (first_seq_ != 0)
      o << "  (joined late, at batch " << first_seq_ << ": missed batches 0-" << (first_seq_ - 1)
        << ", gone from the writer's copy for monitors, which keeps pipeline.monitor_history seconds, at most "
           "256 batches)";
    else if (samples_ != end_sequence_ + 1) o << "  (" << (end_sequence_ + 1 - samples_) << " batches MISSING)";
  }

  bool ended() const override { return ended_; }

  bool lost() override {
    if (ended_ || !matched_ || reader_.matched_writers() > 0) {
      gone_since_.reset();
      return false;
    }
    if (!gone_since_) gone_since_ = Clock::now();
    return seconds_since(*gone_since_) > 1.0;
  }

 private:
  std::string label_, topic_;
  Reader<T> reader_;
  T sample_, last_;
  std::uint64_t program_ = 0, samples_ = 0, items_ = 0, errors_ = 0, last_line_ = 0;
  std::uint64_t first_seq_ = 0, end_sequence_ = 0, window_items_ = 0;
  TelemetryFigures figures_;
  bool matched_ = false, ended_ = false;
  std::optional<Clock::time_point> gone_since_;
};

// `figure`: the live figure the simulated ticks of this topic go to (SampleBatch only), or null.
std::unique_ptr<Watch> make_watch(Participant& p, MessageType type, const std::string& label, const std::string& topic,
                                  ContourFigure* figure = nullptr) {
  if (figure != nullptr && type != MessageType::kSampleBatch)
    throw std::invalid_argument("--plot draws the simulated contour error: watch gcpipe_samples (the simulate "
                                "stage's telemetry), or a pipeline with a simulate node; " + topic + " carries " +
                                type_name(type));
  switch (type) {
    case MessageType::kProgramChunk: return std::make_unique<TopicWatch<msg::ProgramChunk>>(p, label, topic, nullptr);
    case MessageType::kBlockBatch: return std::make_unique<TopicWatch<msg::BlockBatch>>(p, label, topic, nullptr);
    case MessageType::kGcodeChunk: return std::make_unique<TopicWatch<msg::GcodeChunk>>(p, label, topic, nullptr);
    case MessageType::kIkBatch: return std::make_unique<TopicWatch<msg::IkBatch>>(p, label, topic, nullptr);
    case MessageType::kSampleBatch: return std::make_unique<TopicWatch<msg::SampleBatch>>(p, label, topic, figure);
    case MessageType::kReportFragment: break;  // read by gcpipe report-sink, not monitored
  }
  throw std::invalid_argument("topic " + topic + " carries report parts: gcpipe report-sink reads them");
}

// The loop both views run: poll every watch, print a block of status lines every `period`, stop
// when every watch saw its program's end or lost its writer (then print the endings; 0 when all
// ended, 1 when some missed the end), on a stop request or after the idle timeout.
int watch_loop(Participant& participant, const std::vector<std::unique_ptr<Watch>>& watches, const std::string& header,
               double period, std::ostream& out, ContourFigure* figure, const std::string& figure_title) {
  const auto t0 = Clock::now();
  auto next_print = t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(period));
  auto window_start = t0, last_sample = t0;
  const double idle_timeout = participant.options().idle_timeout;
  auto print = [&] {
    const double dt = seconds_since(window_start);
    for (const auto& w : watches) {
      out << std::fixed << std::setprecision(1) << seconds_since(t0) << " s  " << header;
      w->status(out, dt);
      out << "\n";
    }
    out << std::flush;
    if (figure != nullptr) figure->draw(figure_title);
    window_start = Clock::now();
  };
  while (!stop_requested()) {
    bool all_done = true, all_ended = true, any = false;
    for (const auto& w : watches) {
      w->announce_match(out);
      // Everything that is there, without waiting: a slow poll would let the keep-last copy
      // drop samples the monitor could have had.
      bool took = false;
      for (int k = 0; k < 1000 && w->poll(0); ++k) took = any = true;
      all_ended = all_ended && w->ended();
      all_done = all_done && (w->ended() || (!took && w->lost()));
    }
    if (any) last_sample = Clock::now();
    else std::this_thread::sleep_for(std::chrono::milliseconds(10));
    if (all_done) {
      print();
      for (const auto& w : watches) {
        w->ending(out);
        out << "\n";
      }
      out << std::flush;
      return all_ended ? 0 : 1;
    }
    if (Clock::now() >= next_print) {
      print();
      next_print += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(period));
    }
    if (idle_timeout > 0 && seconds_since(last_sample) > idle_timeout) {
      out << "no sample for " << idle_timeout << " s; giving up" << std::endl;
      return 1;
    }
  }
  return 130;
}

// The live figure of --plot, or none.
std::unique_ptr<ContourFigure> live_figure(const std::filesystem::path& plot) {
  if (plot.empty()) return nullptr;
  return std::make_unique<ContourFigure>(plot);
}

}  // namespace

int run_monitor(Participant& participant, MessageType type, const std::string& topic, double period, std::ostream& out,
                const std::filesystem::path& plot) {
  const auto figure = live_figure(plot);
  std::vector<std::unique_ptr<Watch>> watches;
  watches.push_back(make_watch(participant, type, topic, topic, figure.get()));
  return watch_loop(participant, watches, "", period, out, figure.get(), "live contour error (" + topic + ")");
}

std::vector<WatchedStage> watched_stages(const std::vector<std::string>& nodes) {
  std::vector<WatchedStage> out;
  for (const std::string& n : nodes) {
    const pipeline::StageInfo& info = pipeline::find_stage(n);
    WatchedStage w;
    w.stage = n;
    w.topic = info.topic;
    if (!default_topic_type(w.topic, w.type)) continue;  // a stage without a node
    if (info.telemetry != pipeline::Telemetry::kNone) {
      w.telemetry_topic = info.telemetry_topic;
      w.telemetry_type = telemetry_type(info.telemetry);
    }
    out.push_back(w);
  }
  return out;
}

int run_pipeline_monitor(Participant& participant, const std::string& name, const std::vector<WatchedStage>& stages,
                         double period, std::ostream& out, const std::filesystem::path& plot) {
  const auto figure = live_figure(plot);
  bool drawn = false;
  std::vector<std::unique_ptr<Watch>> watches;
  std::size_t width = 0;
  for (const auto& s : stages) width = std::max(width, s.stage.size() + 10);
  auto label = [width](std::string text) { return text + std::string(width - std::min(width, text.size()), ' '); };
  for (const auto& s : stages) {
    watches.push_back(make_watch(participant, s.type, label(s.stage), s.topic));
    if (s.telemetry_topic.empty()) continue;
    const bool draws = figure && s.telemetry_type == MessageType::kSampleBatch;
    watches.push_back(make_watch(participant, s.telemetry_type, label(s.stage + " telemetry"), s.telemetry_topic,
                                 draws ? figure.get() : nullptr));
    drawn = drawn || draws;
  }
  if (figure && !drawn)
    throw std::invalid_argument("--plot draws the simulated contour error, and pipeline " + name +
                                " has no simulate node");
  out << "gcpipe monitor: pipeline " << name << " on domain " << participant.options().domain << ", " << stages.size()
      << " stages" << std::endl;
  return watch_loop(participant, watches, "", period, out, figure.get(), "live contour error (pipeline " + name + ")");
}

}  // namespace gcpipe::dds
