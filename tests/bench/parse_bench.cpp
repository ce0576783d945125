// Parse throughput on one core: MB/s and blocks/s with full modal resolution, and peak RSS.
//
//   build/tests/bench/parse_bench --benchmark_counters_tabular=true
//
// Inputs: a generated 1M-block five-axis program with arcs (gcpipe synth, seed 1), a generated
// program of canned cycles and o-word loops, and the largest
// real program under ../shared/data (skipped when absent). Lines are split in memory so the figure
// is the parser's, not the disk's; `gcpipe parse` end to end is measured in the README.
#include <benchmark/benchmark.h>
#include <sys/resource.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "parse.hpp"
#include "synthetic_program.hpp"
#include "write.hpp"

namespace {

using namespace gcpipe;

const std::string& synthetic_1m() {
  static const std::string text = [] {
    std::string s;
    cli::SyntheticProgram gen(1);
    gen.header(s);
    for (int i = 0; i < 1'000'000; ++i) gen.next(s);
    gen.footer(s);
    return s;
  }();
  return text;
}

// Mostly canned cycles and o-word loops, as a drilling post and a hand-written pattern give
// them: lists of G81/G83 holes, and every 50 holes a small repeat loop of incremental G81 holes
// (a square that comes back where it started, so positions stay in range).
// Each cycle line expands to 3..8 moves, so blocks/s says more than MB/s here.
const std::string& cycles_and_loops() {
  static const std::string text = [] {
    std::string s = "G21 G90 G17 G99 F300 S2000 M3\nG0 X0 Y0 Z20\n#<pitch> = 4\n";
    char line[160];
    for (int i = 0; i < 200'000; ++i) {
      const double x = (i % 400) * 2.5, y = (i / 400 % 400) * 2.5;
      if (i % 3 == 0) std::snprintf(line, sizeof line, "G83 X%.3f Y%.3f Z-12.5 R1.0 Q2.5\n", x, y);
      else std::snprintf(line, sizeof line, "G81 X%.3f Y%.3f Z-3.0 R1.0\n", x, y);
      s += line;
      if (i % 50 == 49) {
        std::snprintf(line, sizeof line, "G80\no%d repeat [4]\n  G91 G81 X#<pitch> Z-4 R0\n  Y#<pitch>\n  X[-#<pitch>]\n  Y[-#<pitch>]\n  G90 G80\no%d endrepeat\n",
                      i, i);
        s += line;
      }
    }
    s += "G80\nM2\n";
    return s;
  }();
  return text;
}

std::string largest_real_program() {
  namespace fs = std::filesystem;
  const fs::path root = GCPIPE_SHARED_DATA;
  if (!fs::exists(root)) return {};
  fs::path best;
  std::uintmax_t size = 0;
  for (const auto& e : fs::recursive_directory_iterator(root))
    if (e.path().extension() == ".ngc" && e.file_size() > size) {
      size = e.file_size();
      best = e.path();
    }
  std::ifstream f(best, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

double peak_rss_mb() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return static_cast<double>(ru.ru_maxrss) / 1024.0;
}

// Parses every line of `text`; with `write`, also formats each block (the batch core path).
void run(benchmark::State& state, const std::string& text, Dialect dialect, bool write) {
  if (text.empty()) {
    state.SkipWithError("../shared/data is absent");
    return;
  }
  std::uint64_t blocks = 0;
  for (auto _ : state) {
    ParseOptions o;
    o.dialect = dialect;
    MachineConfig m;
    m.tools[1] = {100, 10};
    Parser p(o, m, "bench.nc");
    Writer w;
    std::string out;
    const ParseSink sink{[&](const ResolvedBlock& b) {
                           if (write) {
                             w.write(b, out);
                             if (out.size() > (1u << 16)) out.clear();
                           }
                           return true;
                         },
                         [](const Diagnostic&) { return true; }};
    const char* s = text.data();
    const char* end = s + text.size();
    while (s < end) {
      const char* nl = static_cast<const char*>(std::memchr(s, '\n', static_cast<std::size_t>(end - s)));
      if (nl == nullptr) nl = end;
      p.feed(std::string_view(s, static_cast<std::size_t>(nl - s)), sink);
      s = nl + 1;
    }
    p.finish(sink);
    blocks = p.summary().blocks_out;
    if (p.summary().lines_rejected != 0) state.SkipWithError("benchmark input has rejected lines");
    benchmark::DoNotOptimize(out.data());
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * text.size()));
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * blocks));
  state.counters["MB"] = static_cast<double>(text.size()) / 1e6;
  state.counters["peak_rss_MB"] = peak_rss_mb();
}

void BM_ParseSynthetic1M(benchmark::State& s) { run(s, synthetic_1m(), Dialect::kFanuc, false); }
void BM_ParseWriteSynthetic1M(benchmark::State& s) { run(s, synthetic_1m(), Dialect::kFanuc, true); }
void BM_ParseCyclesAndLoops(benchmark::State& s) { run(s, cycles_and_loops(), Dialect::kLinuxCnc, false); }
void BM_ParseLargestReal(benchmark::State& s) {
  static const std::string text = largest_real_program();
  run(s, text, Dialect::kLinuxCnc, false);
}

}  // namespace

BENCHMARK(BM_ParseSynthetic1M)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_ParseWriteSynthetic1M)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_ParseCyclesAndLoops)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK(BM_ParseLargestReal)->Unit(benchmark::kMillisecond)->MinTime(2);
BENCHMARK_MAIN();
