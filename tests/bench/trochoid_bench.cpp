// G275 expansion speed (segments/s) and output size for the paper's slot (seed 000 Table 2:
// D20, W28, 120 long including the round ends, K1.5) at 1 um chord tolerance.
//   build-*/tests/trochoid_bench            (numbers in stages/trochoid/README.md)
#include <benchmark/benchmark.h>

#include <string>
#include <vector>

#include "trochoid.hpp"
#include "write.hpp"

namespace {

gcpipe::ResolvedBlock paper_slot() {
  gcpipe::ResolvedBlock b;
  b.line = 12;
  b.motion = gcpipe::Motion::kTrochoidSlot;
  b.start = {0, 14, 0, 0, 0};
  b.target = {0, 106, 5, 0, 0};
  b.feed = 1200;
  b.spindle = gcpipe::Spindle::kCW;
  b.spindle_speed = 4000;
  b.slot.start = {0, 14, 0};
  b.slot.end = {0, 106, 0};
  b.slot.bottom = -10;
  b.slot.clearance = 5;
  b.slot.width = 28;
  b.slot.step = 1.5;
  b.slot.depth_step = 0;
  b.slot.tool_diameter = 20;
  return b;
}

// Expansion alone (the steady engagement of the cycle's (R, K, r) is cached after the first call;
// BM_FirstExpansion measures it).
void BM_Expand(benchmark::State& state) {
  gcpipe::TrochoidOptions opt;
  opt.chord_tolerance = 0.001;
  opt.arcs = state.range(0) != 0;
  const gcpipe::TrochoidExpander x(opt);
  const auto in = paper_slot();
  std::vector<gcpipe::ResolvedBlock> out;
  std::size_t blocks = 0;
  for (auto _ : state) {
    out.clear();
    x.expand(in, out);
    blocks = out.size();
    benchmark::DoNotOptimize(out.data());
  }
  state.counters["blocks"] = double(blocks);
  state.counters["segments/s"] = benchmark::Counter(double(blocks), benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_Expand)->Arg(0)->Arg(1)->ArgNames({"arcs"})->Unit(benchmark::kMillisecond);

// Expansion plus writing the G-code text: the output size in bytes.
void BM_ExpandAndWrite(benchmark::State& state) {
  gcpipe::TrochoidOptions opt;
  opt.arcs = state.range(0) != 0;
  const gcpipe::TrochoidExpander x(opt);
  const auto in = paper_slot();
  std::vector<gcpipe::ResolvedBlock> out;
  std::string text;
  for (auto _ : state) {
    out.clear();
    text.clear();
    x.expand(in, out);
    gcpipe::Writer w;
    for (const auto& b : out) w.write(b, text);
    benchmark::DoNotOptimize(text.data());
  }
  state.counters["blocks"] = double(out.size());
  state.counters["bytes"] = double(text.size());
  state.counters["segments/s"] = benchmark::Counter(double(out.size()), benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_ExpandAndWrite)->Arg(0)->Arg(1)->ArgNames({"arcs"})->Unit(benchmark::kMillisecond);

// The steady-state engagement analysis a new (R, K, D) costs once (validation and air part).
void BM_SteadyEngagement(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(gcpipe::steady_engagement(4.0, 1.5, 10.0));
}
BENCHMARK(BM_SteadyEngagement)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
