// A "measured" trace made by gcpipe's own simulator: the program through the interpolator and
// the feed drives of `machine` (which may carry effects the calibration has to find), the
// smoothed commands and the actual joints recorded per tick, plus white Gaussian noise on the
// actual channel. Used by the tests, the benchmark and the closed-loop check.
#pragma once

#include <cstdint>
#include <functional>
#include <random>
#include <span>
#include <string>

#include "compensate.hpp"
#include "measured_trace.hpp"

namespace gcpipe::calibrate {

/// Noise per axis (standard deviation, mm or deg). A hook may change the actual joints of each
/// tick before the noise (for effects outside the servo catalogue, e.g. a structural mode).
struct SimulateTraceOptions {
  Axes noise{};
  std::uint64_t seed = 1;
  std::function<void(const compensate::Tick&, Axes& actual)> extra;
  bool torque = false;   //!< record the motor torque as `<axis>_torque` columns
  Axes torque_noise{};   //!< [N*m], drawn after the position noise
};

/// Runs `program` from where it believes it starts; throws std::runtime_error with the block's
/// line when the machine cannot run it.
MeasuredTrace simulate_trace(const compensate::Model& machine, std::span<const ResolvedBlock> program,
                             const SimulateTraceOptions& options, std::string name = "simulated");

/// Standard normal draw (Box-Muller on the platform-independent uniform01 of stages/ik/mlp.hpp).
double normal01(std::mt19937_64& rng);

}  // namespace gcpipe::calibrate
