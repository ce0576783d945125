// Analytic IK throughput on one core, batched: a path of poses solved with each point's answer as
// the next point's `previous` (inverse_kinematics_path), and tool-centre-point IK with A C given.
// Run: build/tests/ik_bench --benchmark_min_time=1 (figures in stages/ik/README.md).
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "gcpipe/kinematics.hpp"

using namespace gcpipe;

namespace {

// The LinuxCNC xyzac-trt machine (pipeline_configs/machines/linuxcnc_xyzac_trt.yaml), built in
// code so the benchmark does not depend on the working directory.
MachineKinematics linuxcnc_model() {
  MachineKinematics m;
  m.a_offset_y = 20;
  m.a_offset_z = 10;
  m.travel = {{{-200, 200}, {-100, 100}, {-120, 120}, {-100, 50}, {-36000, 36000}}};
  return m;
}

// A smooth 5-axis path (small steps, like interpolated G-code) sampled from joint space.
std::vector<ToolPose> make_path(const MachineKinematics& m, std::size_t n) {
  std::vector<ToolPose> poses(n);
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> jitter(-0.01, 0.01);
  Axes q{10, -20, 30, -40, 0};
  for (std::size_t i = 0; i < n; ++i) {
    q[kX] = 50 * std::sin(1e-3 * static_cast<double>(i)) + jitter(rng);
    q[kY] = 40 * std::cos(1.3e-3 * static_cast<double>(i)) + jitter(rng);
    q[kZ] = 20 + 10 * std::sin(0.7e-3 * static_cast<double>(i));
    q[kA] = -45 + 35 * std::sin(0.5e-3 * static_cast<double>(i));
    q[kC] = -0.05 * static_cast<double>(i);  // several turns over the batch
    poses[i] = forward_kinematics(m, q, 0);
  }
  return poses;
}

void BM_ToolVectorIkPath(benchmark::State& state) {
  const MachineKinematics m = linuxcnc_model();
  const auto n = static_cast<std::size_t>(state.range(0));
  const std::vector<ToolPose> poses = make_path(m, n);
  std::vector<IkResult> out(n);
  const Axes start{0, 0, 0, -5, 0};
  for (auto _ : state) {
    inverse_kinematics_path(m, poses, start, 0.0, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_ToolVectorIkPath)->Arg(4096)->Arg(65536);

void BM_TcpIkWithAC(benchmark::State& state) {
  const MachineKinematics m = linuxcnc_model();
  const auto n = static_cast<std::size_t>(state.range(0));
  const std::vector<ToolPose> poses = make_path(m, n);
  std::vector<double> a(n), c(n);
  for (std::size_t i = 0; i < n; ++i) {
    a[i] = -45 + 35 * std::sin(0.5e-3 * static_cast<double>(i));
    c[i] = -0.05 * static_cast<double>(i);
  }
  std::vector<IkResult> out(n);
  for (auto _ : state) {
    for (std::size_t i = 0; i < n; ++i)
      out[i] = inverse_kinematics_ac(m, poses[i].tip, a[i], c[i], 0.0);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_TcpIkWithAC)->Arg(4096)->Arg(65536);

void BM_ForwardKinematics(benchmark::State& state) {
  const MachineKinematics m = linuxcnc_model();
  const auto n = static_cast<std::size_t>(state.range(0));
  std::vector<Axes> q(n);
  for (std::size_t i = 0; i < n; ++i)
    q[i] = {std::sin(static_cast<double>(i)), 2.0, 3.0, -0.01 * static_cast<double>(i),
            0.1 * static_cast<double>(i)};
  std::vector<ToolPose> out(n);
  for (auto _ : state) {
    for (std::size_t i = 0; i < n; ++i) out[i] = forward_kinematics(m, q[i], 0.0);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_ForwardKinematics)->Arg(4096);

}  // namespace

BENCHMARK_MAIN();
