// Issue 12, "bounded memory and time": what `gcpipe batch` needs in memory per second of machine
// time when it compensates. Two generated CAM-like programs, one four times the other, are
// compensated; the peak RSS may grow by at most kMaxGrowth per machine-second between them.
//
// The learning goes by windows, the planner by chunks, and compensated.nc goes out window by
// window, but the nominal run's raw samples and the planned reference are still held for the
// whole program (stages/compensate/README.md, "Memory"), so memory does grow with the program, and
// this test bounds the rate instead of asserting none: before issue 12's memory work it measured
// 0.71 MB a machine-second (71 -> 222 MB) and failed; after the first round 0.15 MB (49 -> 81 MB);
// then 0.065 MB (41.8 -> 55.6 MB, which fails it now); since the planner went by chunks and the
// text by windows 0.050-0.052 MB (40.7 -> 51.6 MB). It should be tightened towards a constant when
// the rest of the design makes those series windowed too.
#include <gtest/gtest.h>

#include <cstdio>

#include "cli_helpers.hpp"

namespace {

constexpr double kMaxGrowth = 0.062;  // [MB per machine-second]; 0.050-0.052 measured (three runs, 2026-11-26)

struct Compensated {
  double peak_rss_mb = 0;
  double machine_seconds = 0;  // the planned (and compensated) cycle time
  double cutting_max_before = 0, cutting_max_after = 0;
};

Compensated compensate_generated(const fs::path& dir, int segments) {
  const fs::path program = dir / ("cam" + std::to_string(segments) + ".nc");
  const fs::path out = dir / ("out" + std::to_string(segments));
  const Outcome g = gcpipe({"synth", "--cam-segments", std::to_string(segments), "--seed", "1", "-o", program.string()});
  EXPECT_EQ(g.status, 0) << g.err;
  const Outcome r = gcpipe({"batch", program.string(), "-o", out.string(), "--quiet"});
  EXPECT_EQ(r.status, 0) << r.err;
  Compensated c;
  c.peak_rss_mb = r.max_rss_mb;
  if (r.status != 0) return c;
  const auto sim = read_json(out / "report.json").at("simulation");
  EXPECT_TRUE(sim.at("compensated").get<bool>()) << sim.at("note");
  c.machine_seconds = sim.at("cycle_time_planned_s");
  c.cutting_max_before = sim.at("contour_error_before").at("cutting").at("max_mm");
  c.cutting_max_after = sim.at("contour_error_after").at("cutting").at("max_mm");
  return c;
}

TEST(CompensateMemory, PeakMemoryGrowsAtMostABoundedAmountPerMachineSecond) {
  const fs::path dir = tmpdir("compensate_memory");
  const Compensated short_run = compensate_generated(dir, 1000);
  const Compensated long_run = compensate_generated(dir, 4000);
  ASSERT_GT(short_run.machine_seconds, 30.0);
  ASSERT_GT(long_run.machine_seconds, 3.5 * short_run.machine_seconds);  // the growth is measured over minutes
  const double growth = (long_run.peak_rss_mb - short_run.peak_rss_mb) / (long_run.machine_seconds - short_run.machine_seconds);
  std::printf("peak RSS %.1f MB for %.1f s of machine time, %.1f MB for %.1f s: %.3f MB per machine-second\n",
              short_run.peak_rss_mb, short_run.machine_seconds, long_run.peak_rss_mb, long_run.machine_seconds, growth);
  RecordProperty("peak_rss_short_mb", std::to_string(short_run.peak_rss_mb));
  RecordProperty("peak_rss_long_mb", std::to_string(long_run.peak_rss_mb));
  RecordProperty("mb_per_machine_second", std::to_string(growth));
  EXPECT_LT(growth, kMaxGrowth);
  // The memory is not bought with the result: both programs are still compensated.
  EXPECT_LT(long_run.cutting_max_after, 0.5 * long_run.cutting_max_before);
  fs::remove_all(dir);
}

}  // namespace
