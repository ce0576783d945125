// What a late monitor still gets from a monitor copy (issue 11: "a late monitor sees at least the
// last N seconds, configurable"): the samples published within DdsOptions::monitor_history, within
// the profile's depth; with 0, the depth alone.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>
#include <vector>

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

}  // namespace
}  // namespace gcpipe::dds
