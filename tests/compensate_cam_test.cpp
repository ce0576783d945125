// Issue 12: compensation on CAM-like programs at production cycle time. A generated program of
// many short segments (0.1-2 mm), corners of 5-120 degrees, arcs and feeds of 500-6000 mm/min
// goes through `gcpipe batch`; the written compensated.nc, read back and simulated, must keep the
// planned cycle time (at most 1.02x), bring the cutting contour error down at least tenfold (the
// issue's target), and beat the sceptic's baseline: the original slowed to the same cycle time.
// Four seeds: 18.5x, 24.3x, 14.0x, 15.2x measured (docs/benchmarks.md, "Compensation figures"); with the
// first-order learning operator used before the chain inverse, seeds 1 and 2 stopped at 5.5x and 9.0x.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>

#include "cli_helpers.hpp"

namespace {

TEST(CompensateCam, GeneratedProgramsKeepThePlannedCycleTimeAndBeatTheSlowedOriginal) {
  for (std::uint64_t seed : {1, 2, 3, 4}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const fs::path dir = tmpdir("cam" + std::to_string(seed));
    // The generator is `gcpipe synth --cam-segments` (stages/cli/synthetic_program.cpp).
    const Outcome g = gcpipe({"synth", "--cam-segments", "400", "--seed", std::to_string(seed), "-o", (dir / "cam.nc").string()});
    ASSERT_EQ(g.status, 0) << g.err;
    // Seed 002's control (acc/dec after interpolation): the claim of issue 12 this test holds.
    // Under the look-ahead control, the default since issue 31, these programs reach 1.3-2.6x
    // (README.md's table, held back by X's acceleration limit); LookaheadControl.* test that one.
    Outcome r = gcpipe({"batch", (dir / "cam.nc").string(), "-o", (dir / "out").string(), "--quiet", "--config",
                        std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/seed002_control.yaml"});
    ASSERT_EQ(r.status, 0) << r.err;
    const auto sim = read_json(dir / "out" / "report.json").at("simulation");
    ASSERT_TRUE(sim.at("compensated").get<bool>()) << sim.at("note");
    const double planned = sim.at("cycle_time_planned_s"), after = sim.at("cycle_time_after_s");
    const double before = sim.at("cycle_time_before_s");
    const double e0 = sim.at("contour_error_before").at("cutting").at("max_mm");
    const double e1 = sim.at("contour_error_after").at("cutting").at("max_mm");
    std::printf("seed %llu: cycle %.2f s (control) / %.2f s (planned) -> %.2f s; cutting max %.1f -> %.1f um (%.1fx)\n",
                static_cast<unsigned long long>(seed), before, planned, after, e0 * 1e3, e1 * 1e3, e0 / e1);
    const double slowed = sim.at("slowed_original").at("contour_error").at("max_mm");
    EXPECT_LE(after, 1.02 * planned);
    EXPECT_GE(e0 / e1, 10.0);
    EXPECT_LT(e1, slowed) << "the original slowed to the same cycle time does better";
  }
}

}  // namespace
