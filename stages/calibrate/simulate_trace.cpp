#include "simulate_trace.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

#include "mlp.hpp"

namespace gcpipe::calibrate {

double normal01(std::mt19937_64& rng) {
  const double u1 = 1.0 - neural::uniform01(rng);  // (0, 1]: log is finite
  const double u2 = neural::uniform01(rng);
  return std::sqrt(-2 * std::log(u1)) * std::cos(2 * std::numbers::pi * u2);
}

MeasuredTrace simulate_trace(const compensate::Model& machine, std::span<const ResolvedBlock> program,
                             const SimulateTraceOptions& o, std::string name) {
  std::size_t first = 0;
  while (first < program.size() && program[first].motion == Motion::kNone) ++first;
  if (first == program.size()) throw std::runtime_error(name + ": the program moves nothing");
  const Axes start = compensate::machine_start(machine.kin, program[first], compensate::tool_length_of(machine, program[first]));
  MeasuredTrace tr;
  tr.file = std::move(name);
  tr.period = machine.interp.period;
  std::mt19937_64 rng(o.seed);
  const auto stats = compensate::run_program(machine, program, start, [&](const compensate::Tick& t) {
    Axes act = t.actual;
    if (o.extra) o.extra(t, act);
    tr.t.push_back(static_cast<double>(t.n) * tr.period);
    for (std::size_t a = 0; a < kNumAxes; ++a) {
      tr.command[a].push_back(t.command[a]);
      tr.actual[a].push_back(act[a] + (o.noise[a] > 0 ? o.noise[a] * normal01(rng) : 0.0));
    }
    if (o.torque)
      for (std::size_t a = 0; a < kNumAxes; ++a)
        tr.effort[a].push_back(t.torque[a] + (o.torque_noise[a] > 0 ? o.torque_noise[a] * normal01(rng) : 0.0));
  });
  if (!stats.ok)
    throw std::runtime_error(tr.file + ": line " + std::to_string(stats.failed_line) + ": " + stats.message);
  tr.lines_read = tr.t.size();
  if (o.torque) tr.effort_kind.fill("torque");
  return tr;
}

}  // namespace gcpipe::calibrate
