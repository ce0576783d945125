// Synthetic five-axis programs for load tests: seeded, endless, realistic line mix (linear XYZAC
// moves, G2/G3 arcs with exact centres, feed changes, comments), every line valid.
#pragma once

#include <cstdint>
#include <random>
#include <string>

namespace gcpipe::cli {

class SyntheticProgram {
 public:
  explicit SyntheticProgram(std::uint64_t seed);
  /// Appends the header lines (%, O number, setup blocks).
  void header(std::string& out);
  /// Appends one more motion or state block and its newline.
  void next(std::string& out);
  /// Appends the end of the program.
  void footer(std::string& out);

 private:
  std::mt19937_64 rng_;
  double x_ = 0, y_ = 0, z_ = 5, a_ = 0, c_ = 0;
  std::uint64_t n_ = 0;
};

/// A CAM-style 2.5D finishing pass for the compensation's tests and benchmark: polyline runs of
/// 0.1-2 mm with random turns of 5-120 degrees, a tangent arc (20-90 degrees, radius 2-10 mm)
/// every 25 moves, a feed of 500-6000 mm/min every 40; it turns back towards the middle beyond
/// 30 mm (a part 60 mm wide). `segments` motion blocks after the approach.
std::string cam_like_program(std::uint64_t seed, int segments);

}  // namespace gcpipe::cli
