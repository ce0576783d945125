// Issue 12: compensation on CAM-like programs at production cycle time. A generated program of
// many short segments (0.1-2 mm), corners of 5-120 degrees, arcs and feeds of 500-6000 mm/min
// goes through `gcpipe batch`; the written compensated.nc, read back and simulated, must keep the
// planned cycle time (at most 1.02x), bring the cutting contour error down at least fivefold, and
// beat the sceptic's baseline: the original slowed to the same cycle time. (The target is
// tenfold; seeds 1 and 2 reach 5.5x and 9.0x, held back by the X acceleration limit at their
// sharpest corners:
// README.md, "Compensation on CAM-like programs".)
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>

#include "cli_helpers.hpp"

namespace {

constexpr double kPi = 3.14159265358979323846;

/// A CAM-style finishing pass: polyline runs with random turns, arcs between them, a feed per run.
std::string cam_like_program(std::uint64_t seed, int segments) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> length(0.1, 2.0), turn(5.0, 120.0), unit(0.0, 1.0);
  std::ostringstream p;
  p.setf(std::ios::fixed);
  p.precision(4);
  p << "%\nO1200 (generated CAM-like program, seed " << seed << ")\nG17 G21 G90 G94 G54\n";
  p << "G0 X0 Y0 Z5\nG1 Z0 F500\n";
  double x = 0, y = 0, heading = 0;
  for (int k = 0; k < segments; ++k) {
    if (k % 40 == 0) p << "F" << std::round(500 + 5500 * unit(rng)) << "\n";
    const double sign = unit(rng) < 0.5 ? -1 : 1;
    // Turn back towards the middle when the path wanders off: the part is 60 mm wide.
    const double towards = std::atan2(-y, -x);
    double d = sign * turn(rng) * kPi / 180;
    if (std::hypot(x, y) > 30) d = std::remainder(towards - heading, 2 * kPi) * 0.5;
    heading += d;
    if (k % 25 == 12) {  // an arc of 20-90 degrees, radius 2-10 mm, tangent to the heading
      const double r = 2 + 8 * unit(rng), sweep = (20 + 70 * unit(rng)) * kPi / 180 * sign;
      const double cx = x - sign * r * std::sin(heading), cy = y + sign * r * std::cos(heading);
      const double a0 = std::atan2(y - cy, x - cx), a1 = a0 + sweep;
      const double ex = cx + r * std::cos(a1), ey = cy + r * std::sin(a1);
      p << (sign > 0 ? "G3" : "G2") << " X" << ex << " Y" << ey << " I" << cx - x << " J" << cy - y << "\n";
      x = ex, y = ey, heading += sweep;
      continue;
    }
    const double l = length(rng);
    x += l * std::cos(heading), y += l * std::sin(heading);
    p << "G1 X" << x << " Y" << y << "\n";
  }
  p << "G0 Z5\nM30\n%\n";
  return p.str();
}

TEST(CompensateCam, GeneratedProgramsKeepThePlannedCycleTimeAndBeatTheSlowedOriginal) {
  for (std::uint64_t seed : {1, 2}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const fs::path dir = tmpdir("cam" + std::to_string(seed));
    {
      std::ofstream f(dir / "cam.nc");
      f << cam_like_program(seed, 400);
    }
    Outcome r = gcpipe({"batch", (dir / "cam.nc").string(), "-o", (dir / "out").string(), "--quiet"});
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
    EXPECT_GE(e0 / e1, 5.0);
    EXPECT_LT(e1, slowed) << "the original slowed to the same cycle time does better";
  }
}

}  // namespace
