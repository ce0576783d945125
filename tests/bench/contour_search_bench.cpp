// simulate::ContourSearch alone, timed: an R 10 circle at 50 mm/s sampled at 1 ms (the geometry of
// simulate_bench.sh, 2.4 turns in the window), the actual 0.3-0.6 mm inside and lagging; 200 000
// ticks streamed; best of 7 passes, ns a tick: build/tests/contour_search_bench. Instruction
// counts alone misled here (an AVX2 clone of the measuring loop: fewer instructions, slower), so
// each change to the search is timed with this as well.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>
#include "simulate.hpp"
using namespace gcpipe;
int main() {
  const double R = 10, w = 5.0, T = 0.001;
  const int n = 200000;
  std::vector<Vec3> pts(n), act(n);
  for (int k = 0; k < n; ++k) {
    pts[k] = {R * std::cos(w * k * T), R * std::sin(w * k * T), 0};
    const double r = R - 0.45 - 0.15 * std::sin(0.9 * k * T), t = k * T - 0.03;
    act[k] = {r * std::cos(w * t), r * std::sin(w * t), 0};
  }
  double best = 1e9, sum = 0;
  for (int pass = 0; pass < 7; ++pass) {
    simulate::ContourSearch s;
    Vec3 c;
    const auto t0 = std::chrono::steady_clock::now();
    for (int k = 0; k < n; ++k) {
      s.push(pts[k]);
      if (k > 0) sum += s.distance(act[k], c);
    }
    const double ns = std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count() / n;
    best = std::min(best, ns);
  }
  std::printf("%.1f ns/tick (check %.6f)\n", best, sum);
}
