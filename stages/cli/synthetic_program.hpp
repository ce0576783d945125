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

}  // namespace gcpipe::cli
