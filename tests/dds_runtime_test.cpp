// What a late monitor still gets from a monitor copy (issue 11: "a late monitor sees at least the
// last N seconds, configurable"): the samples published within DdsOptions::monitor_history, within
// the profile's depth; with 0, the depth alone. And the watchdog of an edge (issue 34 item 2): a
// stage that works without progress is named as stalled within its bound, one that progresses or
// waits for input never is, under a CPU hog.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>
#include <vector>

#include "cpu_hog.hpp"
#include "dds_runtime.hpp"
#include "gcpipe.h"

namespace gcpipe::dds {
namespace {

// Its own domain: no other test of the suite uses 230 (dds_pipeline_test takes 20-99, launch_test
// 224-229); above 215, so its ports lie above Linux's ephemeral range (stages/dds/README.md).
constexpr int kDomain = 230;

DdsOptions options(double monitor_history) {
  DdsOptions o;
  o.domain = kDomain;
  o.profiles = std::filesystem::path(GCPIPE_SOURCE_DIR) / "pipeline_configs" / "dds_profiles.xml";
  o.monitor_history = monitor_history;
  return o;
}

void publish(Writer<msg::GcodeChunk>& writer, std::uint64_t first, std::uint64_t count) {
  for (std::uint64_t k = first; k < first + count; ++k) {
    msg::GcodeChunk chunk;
    chunk.program_id(7);
    chunk.sequence_number(k);
    chunk.text("G1 X" + std::to_string(k) + "\n");
    writer.publish(chunk);
  }
}

// The sequence numbers a monitor reader that matches now receives, until nothing came for 1.5 s.
std::vector<std::uint64_t> late_monitor_receives(Participant& participant, const std::string& topic) {
  Reader<msg::GcodeChunk> reader(participant, topic, /*monitor=*/true);
  std::vector<std::uint64_t> seen;
  msg::GcodeChunk chunk;
  while (reader.take(chunk, 1.5)) seen.push_back(chunk.sequence_number());
  return seen;
}

std::vector<std::uint64_t> range(std::uint64_t first, std::uint64_t count) {
  std::vector<std::uint64_t> v;
  for (std::uint64_t k = first; k < first + count; ++k) v.push_back(k);
  return v;
}

// Batches 0-4, then 1.6 s later batches 5-9, on a monitor copy kept `history` seconds: what a
// monitor that starts after that receives.
std::vector<std::uint64_t> late_monitor_after_two_bursts(double history, const std::string& topic) {
  Participant participant(options(history));
  Writer<msg::GcodeChunk> copy(participant, topic, /*monitor=*/true);
  publish(copy, 0, 5);
  std::this_thread::sleep_for(std::chrono::milliseconds(1600));  // batches 0-4 are now 1.6 s old
  publish(copy, 5, 5);
  return late_monitor_receives(participant, topic);
}

TEST(DdsMonitorHistory, ALateMonitorGetsWhatWasPublishedWithinTheHistoryAndNothingOlder) {
  EXPECT_EQ(late_monitor_after_two_bursts(/*history=*/1.0, "gcpipe_test_history_1s"), range(5, 5));
}

TEST(DdsMonitorHistory, WithinTheHistoryALateMonitorGetsEverythingInOrder) {
  EXPECT_EQ(late_monitor_after_two_bursts(/*history=*/30.0, "gcpipe_test_history_30s"), range(0, 10));
}

TEST(DdsMonitorHistory, TheDepthBoundsWhatIsKeptHoweverRecent) {
  // 0: no time limit; and 300 batches published at once are more than the profile's 256.
  Participant participant(options(/*monitor_history=*/0.0));
  Writer<msg::GcodeChunk> copy(participant, "gcpipe_test_history_depth", /*monitor=*/true);
  publish(copy, 0, 300);
  EXPECT_EQ(late_monitor_receives(participant, "gcpipe_test_history_depth"), range(44, 256));
}

// ---- the watchdog (stages/dds/README.md, "Watchdog") ----

// Domain 231, of these tests alone (the monitor history tests above take 230).
DdsOptions watchdog_options(double stall_timeout) {
  DdsOptions o = options(5);
  o.domain = 231;
  o.heartbeat_period = 0.25;
  o.heartbeat_timeout = 4;
  o.stall_timeout = stall_timeout;
  return o;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// A writer and a reader of one edge in one participant (Fast DDS's in-process shortcut is off in
// dds_profiles.xml, so the heartbeats go through shared memory as between processes). The
// reader learns the writer's id from a first sample, as a node does.
struct Edge {
  Participant participant;
  Writer<msg::GcodeChunk> writer;
  Reader<msg::GcodeChunk> reader;
  std::uint64_t writer_id = 0;
  Edge(const DdsOptions& o, const std::string& topic) : participant(o), writer(participant, topic), reader(participant, topic) {
    writer.set_stage_name("compensate");
    writer.wait_for_readers();
    publish(writer, 0, 1);
    msg::GcodeChunk chunk;
    EXPECT_TRUE(reader.take(chunk, 10, nullptr, &writer_id));
  }
};

TEST(DdsWatchdog, AStageWorkingWithoutProgressIsNamedAsStalledWithinTheBound) {
  gcpipe_test::CpuHog hog(2);
  const double bound = 2;
  Edge edge(watchdog_options(bound), "gcpipe_test_watchdog_stall");
  EXPECT_EQ(edge.writer_id, edge.writer.id());  // the heartbeat names the writer as take() does
  edge.writer.working(42, "slot.nc");
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<RawReader::LostProgram> lost;
  while (lost.empty() && seconds_since(t0) < 30) {
    lost = edge.reader.programs_lost_upstream();
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  const double took = seconds_since(t0);
  std::printf("stall named %.2f s after the last progress (bound %.1f s)\n", took, bound);
  ASSERT_EQ(lost.size(), 1u);
  EXPECT_EQ(lost[0].program_id, 42u);
  EXPECT_EQ(lost[0].file, "slot.nc");
  EXPECT_NE(lost[0].why.find("the compensate stage"), std::string::npos) << lost[0].why;
  EXPECT_NE(lost[0].why.find("it is stalled"), std::string::npos) << lost[0].why;
  // Not before the bound, and within a beat or two of it, plus what a loaded machine may add.
  EXPECT_GE(took, bound - 0.3);
  EXPECT_LT(took, bound + 3);
  EXPECT_NE(edge.reader.writer_trouble(edge.writer_id), "");
  EXPECT_TRUE(edge.reader.programs_lost_upstream().empty()) << "a lost program is handed out once";
}

TEST(DdsWatchdog, AStageThatProgressesOrWaitsForInputIsNeverTakenForStalled) {
  gcpipe_test::CpuHog hog(2);
  Edge edge(watchdog_options(/*stall_timeout=*/1.5), "gcpipe_test_watchdog_busy");
  edge.writer.working(43, "long.nc");
  // Working with a step every 0.2 s for 4 s (beyond the 1.5 s bound), then holding the program
  // without input for 3 s: never a stall.
  auto check_for = [&](double seconds, bool progress) {
    const auto t0 = std::chrono::steady_clock::now();
    while (seconds_since(t0) < seconds) {
      if (progress) edge.writer.progressed();
      EXPECT_EQ(edge.reader.writer_trouble(edge.writer_id), "");
      EXPECT_TRUE(edge.reader.programs_lost_upstream().empty());
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
  };
  check_for(4, true);
  edge.writer.holding();
  check_for(3, false);
}

}  // namespace
}  // namespace gcpipe::dds
