// Simulated machine time per wall-clock second of the feed-drive model (stages/servo), five axes
// at 1 ms on one core. Target (issue 5): >= 10 000 x real time. Run: build/tests/servo_bench.
// The counter `realtime_x` is simulated seconds per wall second.
#include <benchmark/benchmark.h>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "gcpipe/config.hpp"
#include "interpolate.hpp"
#include "servo.hpp"

using namespace gcpipe;
using namespace gcpipe::servo;

namespace {

constexpr double kT = 0.001;

// Seed 002's X, Y, C, with Z a copy of Y and A a copy of C, so that all five axes run the model.
DriveSet five_drives() {
  DriveSet d = load_drives(Config::load_file(std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/drives/seed002.yaml"));
  d.axes[kZ] = d.axes[kY];
  d.axes[kA] = d.axes[kC];
  d.axes[kA].rotary = true;
  return d;
}

// 10 s of smoothed circle-test commands at w = pi (all axes moving).
std::vector<Axes> commands(double omega) {
  std::vector<Axes> c;
  const double a = std::exp(-kT / 0.064);
  Axes y{13, 0, 0, 0, 0};
  for (int k = 1; k <= 10000; ++k) {
    const double t = k * kT;
    const Axes raw{5 + 8 * std::cos(omega * t), 8 * std::sin(omega * t), 2 * std::sin(omega * t),
                   10 * std::sin(omega * t), omega * t * 180 / std::numbers::pi};
    for (std::size_t i = 0; i < kNumAxes; ++i) y[i] = a * y[i] + (1 - a) * raw[i];
    c.push_back(y);
  }
  return c;
}

void run(benchmark::State& state, const DriveSet& d, const std::vector<Axes>& cmd) {
  ServoSimulator sim(d, kT);
  ServoSample out;
  double sink = 0;
  std::int64_t ticks = 0;
  for (auto _ : state) {
    sim.reset({13, 0, 0, 0, 0});
    for (const Axes& c : cmd)
      if (sim.push(c, out)) sink += out.actual[kX];
    while (sim.flush(out)) sink += out.actual[kX];
    ticks += static_cast<std::int64_t>(cmd.size());
  }
  benchmark::DoNotOptimize(sink);
  state.counters["realtime_x"] = benchmark::Counter(static_cast<double>(ticks) * kT, benchmark::Counter::kIsRate);
}

// The production path: exact discretisation, torque well below the limit.
void BM_FiveAxesExact(benchmark::State& state) {
  static const DriveSet d = five_drives();
  static const auto cmd = commands(std::numbers::pi);
  run(state, d, cmd);
}
BENCHMARK(BM_FiveAxesExact)->Unit(benchmark::kMillisecond);

// Worst case: every axis has backlash and friction, so every period runs RK4 on 8 sub-steps.
void BM_FiveAxesEffectsRk4(benchmark::State& state) {
  static const DriveSet d = [] {
    DriveSet x = five_drives();
    for (auto& p : x.axes) {
      p.effects.push_back({"backlash", {{"width", 0.002}}});
      p.effects.push_back({"coulomb_friction", {{"torque", 2.0}, {"velocity_band", 0.01}}});
    }
    return x;
  }();
  static const auto cmd = commands(std::numbers::pi);
  run(state, d, cmd);
}
BENCHMARK(BM_FiveAxesEffectsRk4)->Unit(benchmark::kMillisecond);

// Interpolator + smoothing + drives on a G93 circle with C (the sample program's inner loop).
void BM_InterpolateAndFiveAxes(benchmark::State& state) {
  static const DriveSet d = five_drives();
  struct Sink final : interpolate::SampleSink {
    ServoSimulator* sim;
    ServoSample out;
    double acc = 0;
    void sample(const Axes& c) override {
      if (sim->push(c, out)) acc += out.actual[kY];
    }
  };
  ServoSimulator sim(d, kT);
  Sink sink;
  sink.sim = &sim;
  std::int64_t ticks = 0;
  for (auto _ : state) {
    interpolate::InterpolateOptions o;
    for (std::size_t i = 0; i < kNumAxes; ++i) o.smoothing_time[i] = d.axes[i].Ts;
    o.max_velocity = {500, 500, 500, 1200, 1200};
    o.max_acceleration = {5000, 5000, 5000, 20000, 20000};
    const Axes start{13, 0, 0, 0, 0};
    interpolate::Interpolator ip(o, start);
    sim.reset(start);
    ResolvedBlock b;
    b.motion = Motion::kArcCCW;
    b.feed_mode = FeedMode::kInverseTime;
    b.feed = 30;  // one turn in 2 s: w = pi
    b.centre = {5, 0, 0};
    b.target = start;
    for (int turn = 1; turn <= 5; ++turn) {
      b.target[kC] = 360.0 * turn;
      ip.add(b, sink);
      b.start = b.target;
    }
    ip.finish(sink);
    while (sim.flush(sink.out)) sink.acc += sink.out.actual[kY];
    ticks += static_cast<std::int64_t>(ip.stats().samples);
  }
  benchmark::DoNotOptimize(sink.acc);
  state.counters["realtime_x"] = benchmark::Counter(static_cast<double>(ticks) * kT, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_InterpolateAndFiveAxes)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
