#include "synthetic_program.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

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

}  // namespace gcpipe::cli
