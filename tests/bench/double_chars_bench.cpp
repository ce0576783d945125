// write_shortest on 1 M circle coordinates and write_fixed(.., 6) on 1 M trace times (the trace
// writer's two formatters), best of 9 passes, ns a value: build/tests/double_chars_bench.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>
#include "gcpipe/double_chars.hpp"
int main() {
  const int n = 1000000;
  std::vector<double> xs(n), ts(n);
  for (int k = 0; k < n; ++k) xs[k] = 10 * std::cos(5.0 * k * 0.001) - 0.3 * std::sin(0.7 * k * 0.001), ts[k] = k * 0.001;
  char buf[64];
  unsigned long sum = 0;
  double best_s = 1e9, best_f = 1e9;
  for (int pass = 0; pass < 9; ++pass) {
    auto t0 = std::chrono::steady_clock::now();
    for (double v : xs) sum += gcpipe::write_shortest(buf, v) - buf + buf[3];
    auto t1 = std::chrono::steady_clock::now();
    for (double v : ts) sum += gcpipe::write_fixed(buf, buf + sizeof buf, v, 6) - buf + buf[2];
    auto t2 = std::chrono::steady_clock::now();
    best_s = std::min(best_s, std::chrono::duration<double, std::nano>(t1 - t0).count() / n);
    best_f = std::min(best_f, std::chrono::duration<double, std::nano>(t2 - t1).count() / n);
  }
  std::printf("write_shortest %.1f ns, write_fixed(6) %.1f ns (check %lu)\n", best_s, best_f, sum);
}
