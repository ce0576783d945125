// NNOE force model inference speed on one core (issue 15: target >= 10 M one-step predictions/s).
// The eq. (13) network: 6 regressors, 12 tanh units, linear output (97 weights). Speed does not
// depend on the weights, so they are Glorot-random here. Two measurements:
//  - OneStepBatch: one-step predictions of many independent regressors at once (MlpInference,
//    float, vectorised tanh): what a feed planner evaluating candidate feeds needs;
//  - ParallelRun: the recurrent output-error simulation of one series (nnoe_simulate, double):
//    each step waits for the previous prediction, so no batching;
//  - ParallelRunFloat: the same recurrence in float (nnoe_simulate_float, neural::MlpSingle: the
//    hidden layer vectorised), over 100 000 steps including the input normalisation.
//
// Run: build/tests/force_nnoe_bench --benchmark_min_time=2
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "../force_nnoe_process.hpp"
#include "mlp.hpp"
#include "nnoe_fast.hpp"
#include "nnoe_force.hpp"

namespace {

using namespace gcpipe;

calibrate::NnoeModel eq13_model() {
  calibrate::NnoeModel m;
  m.structure = force::table1_structures(12)[4];
  m.net = neural::Mlp({6, 12, 1});
  std::mt19937_64 rng(3);
  m.net.initialise(rng);
  m.u_scale = {100, 2};
  m.u_offset = {175, 5};
  m.y_scale = 200;
  m.y_offset = 500;
  return m;
}

void OneStepBatch(benchmark::State& state) {
  const auto m = eq13_model();
  const neural::MlpInference inf(m.net);
  const std::size_t n = static_cast<std::size_t>(state.range(0));
  std::vector<float> x(6 * n), y;
  std::mt19937_64 rng(1);
  std::normal_distribution<float> g(0, 1);
  for (float& v : x) v = g(rng);
  neural::MlpInference::Workspace ws;
  for (auto _ : state) {
    inf.forward(x.data(), n, y, ws);
    benchmark::DoNotOptimize(y.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * static_cast<std::int64_t>(n));
}
BENCHMARK(OneStepBatch)->Arg(1024)->Arg(16384);

void ParallelRun(benchmark::State& state) {
  const auto m = eq13_model();
  const force::ForceSeries s = force::simulate_force_process({}, 10000, 5);
  const calibrate::Channels u{s.feed, s.depth};
  for (auto _ : state) {
    auto y = calibrate::nnoe_simulate(m, u, s.feed.size());
    benchmark::DoNotOptimize(y.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * 10000);
}
BENCHMARK(ParallelRun);

void ParallelRunFloat(benchmark::State& state) {
  const auto m = eq13_model();
  const force::ForceSeries s = force::simulate_force_process({}, 100000, 5);
  const calibrate::Channels u{s.feed, s.depth};
  for (auto _ : state) {
    auto y = calibrate::nnoe_simulate_float(m, u, s.feed.size());
    benchmark::DoNotOptimize(y.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * 100000);
}
BENCHMARK(ParallelRunFloat);

}  // namespace

BENCHMARK_MAIN();
