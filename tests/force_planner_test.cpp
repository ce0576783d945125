// The force-aware feed under the drives (stages/force/README.md sec. 6c): a feed the force would
// allow above an axis's velocity limit gets the limit, a short fast block between slow ones gets
// only the speed it can reach, and the cycle times are the interpolator's.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "drive_limits.hpp"
#include "force_options.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "interpolate.hpp"
#include "parse.hpp"
#include "path_force.hpp"
#include "stock.hpp"
#include "trochoid.hpp"
#include "force_test_util.hpp"

namespace gcpipe::force {
namespace {

/// Drives without acc/dec (the velocity bound is then max_velocity itself).
interpolate::InterpolateOptions plain_drives(double vx, double ax) {
  interpolate::InterpolateOptions o;
  o.smoothing = interpolate::Smoothing::kNone;
  o.max_velocity = {vx, 500, 500, 100, 100};
  o.max_acceleration = {ax, 1e6, 1e6, 1e6, 1e6};
  return o;
}

const ResolvedBlock& nth_feed_block(const std::vector<ResolvedBlock>& blocks, int n) {
  for (const ResolvedBlock& b : blocks)
    if (b.motion == Motion::kLinear && n-- == 0) return b;
  throw std::runtime_error("no such feed block");
}

TEST(ForcePlanner, ForceFeedAboveTheXVelocityLimitGetsTheLimit) {
  // A full slot along +X at Z-5 through a block topped at 0, F1200 S4000; the target force is
  // out of reach, so the force alone asks max_feed_factor x F = 3600 mm/min.
  const auto blocks = test::trochoid_blocks("G0 X-15 Y0 Z-5\nG1 X60 F1200 S4000 M3\nG0 Z50\n");
  ForceOptions o;
  o.tool = {20, 3, 30, 60, 600, 0.8};
  o.target_force = 1e6;
  o.sample_spacing = 0.5;
  const auto moves = moves_from_blocks(blocks);
  const PathForce swept = sweep_path(moves, o, HeightField(-20, -15, 80, 15, 0.0, 0.1));
  const auto by_force = apply_feeds(blocks, moves, plan_feeds(moves, swept, o));
  ASSERT_NEAR(nth_feed_block(by_force, 0).feed, 3600, 1e-9);
  // X at 25 mm/s: on a straight X move the path speed is the X speed, 60 * 25 = 1500 mm/min.
  const auto io = plain_drives(25, 1e6);
  const DriveRun run = run_on_drives(blocks, io, blocks.front().start);
  ASSERT_TRUE(run.failure.empty()) << run.failure;
  const auto planned = limit_feeds_to_drives(by_force, run.blocks);
  EXPECT_NEAR(nth_feed_block(planned, 0).feed, 1500, 1e-6);
  // A 3-4-5 diagonal: X moves 3/5 of the path, so X at 25 mm/s allows 25 * 5/3 mm/s of path.
  const auto diagonal = test::trochoid_blocks("G0 X0 Y0 Z0\nG1 X30 Y40 F6000\nG0 Z50\n");
  const DriveRun d = run_on_drives(diagonal, io, diagonal.front().start);
  const auto capped = limit_feeds_to_drives(diagonal, d.blocks);
  EXPECT_NEAR(nth_feed_block(capped, 0).feed, 60 * 25 * 5.0 / 3.0, 1e-6);
}

TEST(ForcePlanner, ShortFastBlockBetweenSlowOnesGetsOnlyTheSpeedItReaches) {
  // 20 mm at F600 (10 mm/s), 0.5 mm at F6000, 20 mm at F600, along X at a_X = 1000 mm/s^2. The
  // short block starts and ends at 10 mm/s; speeding up over half its length and slowing down
  // over the other half: v^2 = 10^2 + 2 * 1000 * 0.25, v = 24.49 mm/s, F = 1469.7 mm/min.
  const auto blocks = test::trochoid_blocks("G0 X0 Y0 Z0\nG1 X20 F600\nX20.5 F6000\nX40.5 F600\nG0 Z50\n");
  const double a = 1000, v0 = 10, s = 0.5;
  const double expected = 60 * std::sqrt(v0 * v0 + 2 * a * (s / 2));
  const DriveRun run = run_on_drives(blocks, plain_drives(500, a), blocks.front().start);
  const auto planned = limit_feeds_to_drives(blocks, run.blocks);
  EXPECT_NEAR(nth_feed_block(planned, 1).feed, expected, 1e-6);
  EXPECT_NEAR(nth_feed_block(planned, 0).feed, 600, 1e-9);  // long enough for its own feed
  EXPECT_NEAR(nth_feed_block(planned, 2).feed, 600, 1e-9);
  // From rest (a rapid before it) into a long block at the same feed: 2 mm reach v^2 = 2 a s.
  const auto from_rest = test::trochoid_blocks("G0 X0 Y0 Z0\nG1 X2 F6000\nX100\nG0 Z50\n");
  const DriveRun r2 = run_on_drives(from_rest, plain_drives(500, a), from_rest.front().start);
  const auto p2 = limit_feeds_to_drives(from_rest, r2.blocks);
  EXPECT_NEAR(nth_feed_block(p2, 0).feed, 60 * std::sqrt(2 * a * 2), 1e-6);
  // The long block ends at rest (a rapid follows): it reaches 100 mm/s easily, no cap.
  EXPECT_NEAR(nth_feed_block(p2, 1).feed, 6000, 1e-9);
}

/// Counts the interpolator's samples: the program's time on its own clock.
class CountSamples final : public interpolate::SampleSink {
 public:
  void sample(const Axes&) override { ++n; }
  std::uint64_t n = 0;
};

double interpolator_clock(const std::vector<ResolvedBlock>& blocks, const interpolate::InterpolateOptions& o) {
  interpolate::Interpolator interp(o, blocks.front().start);
  CountSamples sink;
  for (const ResolvedBlock& b : blocks) EXPECT_EQ(interp.add(b, sink).status, interpolate::InterpolateStatus::kOk);
  return static_cast<double>(sink.n) * o.period;
}

TEST(ForcePlanner, CycleTimesAreTheInterpolatorsOnTheProgrammedAndPlannedSlot) {
  const auto blocks = test::seed000_slot_blocks();
  ForceOptions o;
  o.tool = {20, 3, 30, 60, 600, 0.8};
  o.sample_spacing = 0.1;
  o.target_force = 185;
  o.peak_force = 740;
  const auto moves = moves_from_blocks(blocks);
  const PathForce swept = sweep_path(moves, o, make_stock(moves, o));
  // mx330's limits, seed 002's Ts 0.05 s, exponential acc/dec: the default pipeline's interpolator.
  interpolate::InterpolateOptions io;
  io.smoothing_time = {0.05, 0.064, 0.064, 0.05, 0.05};
  io.max_velocity = {500, 500, 500, 100, 100};
  io.max_acceleration = {5000, 5000, 5000, 1000, 1000};
  const DriveRun before = run_on_drives(blocks, io, blocks.front().start);
  const auto planned = limit_feeds_to_drives(apply_feeds(blocks, moves, plan_feeds(moves, swept, o)), before.blocks);
  const DriveRun after = run_on_drives(planned, io, planned.front().start);
  ASSERT_TRUE(before.failure.empty() && after.failure.empty());
  const double T = io.period;
  EXPECT_NEAR(before.cycle_time, interpolator_clock(blocks, io), 2 * T);
  EXPECT_NEAR(after.cycle_time, interpolator_clock(planned, io), 2 * T);
  EXPECT_LT(after.cycle_time, 0.9 * before.cycle_time);
  std::printf("seed 000 slot on the interpolator: %.3f s -> %.3f s (feed moves %.3f -> %.3f s)\n", before.cycle_time,
              after.cycle_time, before.feed_move_time, after.feed_move_time);
}

}  // namespace
}  // namespace gcpipe::force
