#include "synthetic_program.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <sstream>

namespace gcpipe::cli {

SyntheticProgram::SyntheticProgram(std::uint64_t seed) : rng_(seed) {}

void SyntheticProgram::header(std::string& out) {
  out += "%\nO4711 (SYNTHETIC FIVE-AXIS LOAD TEST)\nG21 G17 G40 G80 G90 G94\nT1 M6\nG54\n"
         "G43.4 H1\nS12000 M3\nM8\nG0 X0. Y0. Z5. A0. C0.\nG1 Z0. F800.\n";
}

void SyntheticProgram::next(std::string& out) {
  std::uniform_real_distribution<double> step(-2.0, 2.0), unit(0.0, 1.0);
  char buf[160];
  int n = 0;
  const double r = unit(rng_);
  ++n_;
  if (r < 0.70) {
    // Simultaneous five-axis move, CAM-style precision.
    x_ = std::clamp(x_ + step(rng_), -200.0, 200.0);
    y_ = std::clamp(y_ + step(rng_), -200.0, 200.0);
    z_ = std::clamp(z_ + step(rng_) / 10, -50.0, 50.0);
    a_ = std::clamp(a_ + step(rng_), -110.0, 5.0);
    c_ += step(rng_) * 3;
    n = std::snprintf(buf, sizeof buf, "G1 X%.4f Y%.4f Z%.4f A%.3f C%.3f\n", x_, y_, z_, a_, c_);
  } else if (r < 0.92) {
    // An arc of radius 2..10 mm around a centre chosen so both radii agree to the printed digits.
    const double radius = 2 + 8 * unit(rng_);
    const double phi0 = 2 * std::numbers::pi * unit(rng_);
    const double sweep = (0.2 + 2.5 * unit(rng_)) * (unit(rng_) < 0.5 ? 1 : -1);
    const double cx = x_ - radius * std::cos(phi0), cy = y_ - radius * std::sin(phi0);
    const double ex = cx + radius * std::cos(phi0 + sweep), ey = cy + radius * std::sin(phi0 + sweep);
    n = std::snprintf(buf, sizeof buf, "G%d X%.4f Y%.4f I%.4f J%.4f\n", sweep < 0 ? 2 : 3, ex, ey, cx - x_, cy - y_);
    x_ = ex;
    y_ = ey;
  } else if (r < 0.97) {
    n = std::snprintf(buf, sizeof buf, "G1 X%.4f Y%.4f F%.0f\n", x_, y_, 300 + std::floor(2000 * unit(rng_)));
  } else {
    n = std::snprintf(buf, sizeof buf, "(block %llu: finishing pass)\n", static_cast<unsigned long long>(n_));
  }
  out.append(buf, static_cast<std::size_t>(n));
}

void SyntheticProgram::footer(std::string& out) { out += "G0 Z50.\nM9\nM5\nG49\nM30\n%\n"; }

std::string cam_like_program(std::uint64_t seed, int segments) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> length(0.1, 2.0), turn(5.0, 120.0), unit(0.0, 1.0);
  std::ostringstream p;
  p.setf(std::ios::fixed);
  p.precision(4);
  p << "%\nO1200 (generated CAM-like program, seed " << seed << ")\nG17 G21 G90 G94 G54\n";
  // A post's header: the tool, the spindle, then the tool length switched on with the move down
  // (9465c2f: the planner used to stall on this G43).
  p << "T1 M6\nS9000 M3\nG0 X0 Y0\nG43 H1 Z5\nG1 Z0 F500\n";
  double x = 0, y = 0, heading = 0;
  for (int k = 0; k < segments; ++k) {
    if (k % 40 == 0) p << "F" << std::round(500 + 5500 * unit(rng)) << "\n";
    const double sign = unit(rng) < 0.5 ? -1 : 1;
    // Turn back towards the middle when the path wanders off: the part is 60 mm wide.
    const double towards = std::atan2(-y, -x);
    double d = sign * turn(rng) * std::numbers::pi / 180;
    if (std::hypot(x, y) > 30) d = std::remainder(towards - heading, 2 * std::numbers::pi) * 0.5;
    heading += d;
    if (k % 25 == 12) {  // an arc of 20-90 degrees, radius 2-10 mm, tangent to the heading
      const double r = 2 + 8 * unit(rng), sweep = (20 + 70 * unit(rng)) * std::numbers::pi / 180 * sign;
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
  p << "G0 Z5\nM5\nG49\nM30\n%\n";
  return p.str();
}


}  // namespace gcpipe::cli
