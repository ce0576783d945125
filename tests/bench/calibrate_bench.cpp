// Calibration speed (issue #13 target: a 10-minute 1 ms five-axis trace calibrated in <= 60 s
// on one core) and peak memory. An executable, not a test: build/tests/calibrate_bench [minutes]
// It simulates the trace first (seed 002 drives on all five axes, Z = Y and A = C; hidden
// effects: 10 um Y backlash, 3 um / 16 mm X lead error, 0.01 deg C backlash; 0.2 um noise;
// configured gains 20 % off), then times calibrate_traces alone.
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>

#include "calibrate.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "parse.hpp"
#include "simulate_trace.hpp"

using namespace gcpipe;
using namespace gcpipe::calibrate;

namespace {

std::vector<ResolvedBlock> program(const PipelineConfig& pc, int moves) {
  std::ostringstream p;
  p << "G21 G17 G90 G94\nG0 X0 Y0 Z0 A0 C0\n";
  std::mt19937_64 rng(42);
  for (int i = 0; i < moves; ++i) {
    auto u = [&](double lo, double hi) { return lo + (hi - lo) * neural::uniform01(rng); };
    p << "G1 X" << u(-40, 40) << " Y" << u(-40, 40) << " Z" << u(-20, 0) << " A" << u(-30, 0) << " C" << u(-90, 90)
      << " F" << u(800, 3000) << "\n";
  }
  p << "M30\n";
  Parser parser(ParseOptions{}, pc.machine, "bench.nc");
  std::vector<ResolvedBlock> out;
  feed_text(parser, p.str(), {[&out](const ResolvedBlock& b) {
                                out.push_back(b);
                                return true;
                              },
                              [](const Diagnostic&) { return true; }});
  return out;
}

servo::EffectSettings effect(std::string t, std::vector<std::pair<std::string, double>> v) {
  servo::EffectSettings e;
  e.type = std::move(t);
  e.values = std::move(v);
  return e;
}

}  // namespace

int main(int argc, char** argv) {
  const double minutes = argc > 1 ? std::atof(argv[1]) : 10.0;
  const PipelineConfig pc = load_pipeline_config(std::filesystem::path(GCPIPE_SOURCE_DIR) / "pipeline_configs" / "circle_test.yaml");
  compensate::Model machine = compensate::load_model(pc);
  machine.drives.axes[kZ] = machine.drives.axes[kY];
  machine.drives.axes[kA] = machine.drives.axes[kC];
  machine.drives.axes[kA].rotary = true;
  compensate::Model config = machine;
  for (auto& p : config.drives.axes) { p.Kpp *= 1.2; p.K_FFP *= 0.85; }
  machine.drives.axes[kY].effects.push_back(effect("backlash", {{"width", 0.010}}));
  machine.drives.axes[kX].effects.push_back(effect("lead_error", {{"amplitude", 0.003}, {"period", 16}, {"phase", 0}}));
  machine.drives.axes[kC].effects.push_back(effect("backlash", {{"width", 0.01}}));
  SimulateTraceOptions o;
  o.noise = {2e-4, 2e-4, 2e-4, 2e-4, 2e-4};
  const auto t0 = std::chrono::steady_clock::now();
  MeasuredTrace tr = simulate_trace(machine, program(pc, static_cast<int>(minutes * 60)), o, "bench");
  const std::size_t rows = static_cast<std::size_t>(minutes * 60000);
  if (tr.size() < rows) std::fprintf(stderr, "note: the program ran %zu rows, fewer than %zu\n", tr.size(), rows);
  for (auto* v : {&tr.t}) v->resize(std::min(rows, v->size()));
  for (int a = 0; a < kNumAxes; ++a) { tr.command[a].resize(tr.t.size()); tr.actual[a].resize(tr.t.size()); }
  rusage r1{};
  getrusage(RUSAGE_SELF, &r1);
  const auto t1 = std::chrono::steady_clock::now();
  const Calibration c = calibrate_traces({tr}, config);
  const auto t2 = std::chrono::steady_clock::now();
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  // CPU time of the calibration alone (the machine may be shared: wall time then overstates it).
  const auto cpu = [](const rusage& r) { return r.ru_utime.tv_sec + r.ru_stime.tv_sec + 1e-6 * (r.ru_utime.tv_usec + r.ru_stime.tv_usec); };
  std::printf("trace: %zu rows (%.1f min at 1 ms), simulated in %.1f s\n", tr.size(), tr.size() / 60000.0,
              std::chrono::duration<double>(t1 - t0).count());
  std::printf("calibrate_traces: %.1f s wall, %.1f s CPU (one thread), peak RSS %.1f MB\n", std::chrono::duration<double>(t2 - t1).count(),
              cpu(ru) - cpu(r1), ru.ru_maxrss / 1024.0);
  for (int a = 0; a < kNumAxes; ++a)
    for (const auto& n : c.axes[a].named) {
      std::printf("  %c %s:", kAxisLetters[a], n.effect.c_str());
      for (const auto& p : n.params) std::printf(" %s = %.6g +- %.2g", p.name.c_str(), p.value, p.sigma);
      std::printf("\n");
    }
  std::printf("prediction rms (um; A, C at 100 mm): declared");
  for (int a = 0; a < kNumAxes; ++a) std::printf(" %.3f", c.declared.rms_um[a]);
  std::printf(", calibrated");
  for (int a = 0; a < kNumAxes; ++a) std::printf(" %.3f", c.calibrated.rms_um[a]);
  std::printf("\n");
  return 0;
}
