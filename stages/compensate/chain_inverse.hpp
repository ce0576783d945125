// The learning operator of the compensation: per axis, a non-causal FIR filter that inverts the
// whole chain from a raw interpolated command to the simulated actual position (acc/dec after
// interpolation, then the feed drive of the drives file), designed from that chain's own step
// response. Derivation and checks: README.md beside this file, "The learning operator".
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "simulate.hpp"

namespace gcpipe::compensate {

/// du(n) = sum_j taps[j] e(n + lead - stride j): the correction of the raw command at tick n for
/// an error e of the actual position, such that the chain's response to du is e smoothed by a
/// 10 ms Gaussian, with no delay.
struct AxisInverse {
  std::vector<double> taps;
  std::ptrdiff_t lead = 0;    //!< ticks of e ahead of n that the first tap reads
  std::ptrdiff_t stride = 1;  //!< ticks between the samples of e that the taps read
  double residual = 0;        //!< |g * f - q| / |q| of the design (q the Gaussian target)
};

struct ChainInverse {
  std::array<AxisInverse, kNumAxes> axis;
  /// The same taps as axis[i].taps, tap by tap for all axes (every axis has the same lead,
  /// stride and count): the hot loop reads each tick of the series once for the five axes.
  std::vector<Axes> interleaved;
};

/// Designs the inverse of every axis: least squares on the chain's impulse response g,
/// min |g * f - q|^2 (q a 10 ms Gaussian centred `lead` ticks on), with the DC gain and the first
/// moment held exactly (a held error and a ramp come back exactly).
ChainInverse design_chain_inverse(const simulate::Model& model);

/// Joints or errors in single precision: the learning's error r - y (errors are small, so a
/// float's 7 digits are far below the 0.1 um the program is written with), 20 bytes a tick.
using AxesF = std::array<float, kNumAxes>;

/// The inverse applied to a per-tick series x at tick n (x clamped to its ends), the five axes in
/// one pass; for the ways a series is stored (exact, the learning's error in float, the compact
/// reference).
Axes apply_inverse(const ChainInverse& inv, const std::vector<Axes>& x, std::int64_t n);
Axes apply_inverse(const ChainInverse& inv, const std::vector<AxesF>& x, std::int64_t n);
Axes apply_inverse(const ChainInverse& inv, const simulate::JointSeries& x, std::int64_t n);

/// The configured control running the original with the drives' model inverse as feed-forward
/// and no learning: the command u = L r (r the reference, the look-ahead control's own plan) on
/// the reference clock, measured as every run is. The fair baseline of the learning: the same
/// clock, the same model, only the learning left out.
struct FeedforwardRun {
  simulate::Evaluation eval;
  /// Per second of the reference clock: the largest ratio, over the axes, of the feed-forward
  /// command's acceleration (second difference of its ticks) to the axis's limit. Above 1 the
  /// drives' limits forbid the pre-compensation at the planned speed there.
  std::vector<double> over_limit;
};
FeedforwardRun feedforward_run(const simulate::Model& model, const simulate::Nominal& nom,
                               std::span<const ResolvedBlock> program, const Axes& start);

}  // namespace gcpipe::compensate
