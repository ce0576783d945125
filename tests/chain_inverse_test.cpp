// The compensation's learning operator (stages/compensate/chain_inverse.hpp): a FIR inverse of
// acc/dec plus feed drive per axis, designed from the chain's step response. Checked against the
// simulator itself, not the impulse response it was designed from: an error shape put through
// the inverse and then through AxisSmoother + ServoSimulator must come back as the shape smoothed
// by the 10 ms Gaussian, closer than with the first-order operator it replaced; a held error and
// a ramp must come back exactly (the design's two constraints, to the solver's 1e-7).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>

#include "chain_inverse.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "interpolate.hpp"
#include "servo.hpp"

namespace gcpipe::compensate {
namespace {

namespace fs = std::filesystem;

simulate::Model default_model() {
  return simulate::load_model(load_pipeline_config(fs::path(GCPIPE_SOURCE_DIR) / "pipeline_configs" / "seed002_control.yaml"));
}

// A smooth error bump: raised cosine of `width` ticks starting at `start`, height 1.
std::vector<Axes> bump(std::size_t n, std::size_t start, std::size_t width, std::size_t axis) {
  std::vector<Axes> e(n, Axes{});
  for (std::size_t k = start; k < start + width && k < n; ++k)
    e[k][axis] = 0.5 * (1 - std::cos(2 * std::numbers::pi * static_cast<double>(k - start) / static_cast<double>(width)));
  return e;
}

// The chain's response to raw commands u (one axis), run through the simulator's own parts.
std::vector<double> chain_response(const simulate::Model& m, std::size_t axis, const std::vector<double>& u) {
  servo::ServoSimulator sim(m.drives, m.interp.period);
  std::vector<double> y{sim.reset(Axes{}, 0.0).actual[axis]};
  interpolate::AxisSmoother smoother(m.interp.smoothing, m.interp.smoothing_time[axis], m.interp.period, 0.0);
  servo::ServoSample s;
  for (std::size_t k = 1; k < u.size(); ++k) {
    Axes c{};
    c[axis] = smoother.filter(u[k]);
    if (sim.push(c, s)) y.push_back(s.actual[axis]);
  }
  while (sim.flush(s)) y.push_back(s.actual[axis]);
  y.resize(u.size());
  return y;
}

TEST(ChainInverse, TheDesignFitsItsTargetOnEveryAxis) {
  const ChainInverse inv = design_chain_inverse(default_model());
  for (std::size_t i = 0; i < kNumAxes; ++i) {
    SCOPED_TRACE(std::string("axis ") + kAxisLetters[i]);
    EXPECT_EQ(inv.axis[i].stride, 4);
    // The drive axes' responses are smooth enough for taps 4 ms apart (measured 0.1-0.3 %); the
    // ideal axes' chain is the acc/dec alone, whose sharp start a 4 ms comb of taps fits to 8 %.
    const bool drive = i == kX || i == kY || i == kC;
    EXPECT_LT(inv.axis[i].residual, drive ? 0.01 : 0.1);
  }
}

// The operator used before the chain inverse: first-order acc/dec and the drive's ramp lag d,
// u(n) = e(n + d) + Ts (e(n + d + 10) - e(n + d - 10)) / 20 ms.
double first_order(const simulate::Model& m, const std::vector<Axes>& e, std::size_t axis, std::int64_t n) {
  const double T = m.interp.period;
  const std::int64_t d = std::llround(servo::ramp_lag_time(m.drives.axes[axis]) / T), h = 10;
  const auto at = [&](std::int64_t k) { return e[static_cast<std::size_t>(std::clamp<std::int64_t>(k, 0, static_cast<std::int64_t>(e.size()) - 1))][axis]; };
  return at(n + d) + m.interp.smoothing_time[axis] * (at(n + d + h) - at(n + d - h)) / (2.0 * static_cast<double>(h) * T);
}

// Largest difference between the chain's response to u and the bump smoothed by the 10 ms
// Gaussian (what the design aims at).
double round_trip_error(const simulate::Model& m, const std::vector<Axes>& e, std::size_t axis, const std::vector<double>& u) {
  const std::vector<double> y = chain_response(m, axis, u);
  const std::size_t n = e.size();
  double worst = 0;
  for (std::size_t k = 0; k < n; ++k) {
    double smoothed = 0, weight = 0;
    for (int j = -50; j <= 50; ++j) {
      const double w = std::exp(-0.5 * (j / 10.0) * (j / 10.0));
      smoothed += w * e[static_cast<std::size_t>(std::clamp<std::int64_t>(static_cast<std::int64_t>(k) + j, 0, static_cast<std::int64_t>(n) - 1))][axis];
      weight += w;
    }
    worst = std::max(worst, std::abs(y[k] - smoothed / weight));
  }
  return worst;
}

// The round trip through the simulator's own smoother and drives (not the impulse response the
// design used): the chain inverse is checked against the first-order operator it replaced. The
// design leaves out the drive's answer before a step (its feed-forward reads the command Tp
// ahead; chain_inverse.cpp says why), so the round trip is not exact: measured 16 % of the bump
// on X (Tp 15.5 ms), 5.4 % on Y and C (Tp 5 ms), against 49.7 % / 16.2 % / 16.5 % first-order.
TEST(ChainInverse, AnErrorPutThroughTheInverseAndTheSimulatorComesBackCloserThanFirstOrder) {
  const simulate::Model m = default_model();
  const ChainInverse inv = design_chain_inverse(m);
  const std::size_t n = 1500;
  for (std::size_t axis : {kX, kY, kC}) {  // the three drive axes of seed 002 (Z and A are ideal)
    SCOPED_TRACE(std::string("axis ") + kAxisLetters[axis]);
    const std::vector<Axes> e = bump(n, 400, 120, axis);
    std::vector<double> u(n), u1(n);
    for (std::size_t k = 0; k < n; ++k) {
      u[k] = apply_inverse(inv, e, static_cast<std::int64_t>(k))[axis];
      u1[k] = first_order(m, e, axis, static_cast<std::int64_t>(k));
    }
    const double chain = round_trip_error(m, e, axis, u), before = round_trip_error(m, e, axis, u1);
    std::printf("axis %c: round trip off by %.1f %% (first-order operator: %.1f %%)\n", kAxisLetters[axis], 100 * chain, 100 * before);
    EXPECT_LT(chain, 0.7 * before);
    EXPECT_LT(chain, axis == kX ? 0.2 : 0.08);
  }
}

TEST(ChainInverse, AHeldErrorAndARampComeBackExactly) {
  const ChainInverse inv = design_chain_inverse(default_model());
  std::vector<Axes> held(2000, Axes{}), ramp(2000, Axes{});
  for (std::size_t k = 0; k < held.size(); ++k)
    for (std::size_t i = 0; i < kNumAxes; ++i) held[k][i] = 0.25, ramp[k][i] = 0.001 * static_cast<double>(k);
  for (std::size_t i = 0; i < kNumAxes; ++i) {
    SCOPED_TRACE(std::string("axis ") + kAxisLetters[i]);
    EXPECT_NEAR(apply_inverse(inv, held, 1000)[i], 0.25, 1e-6);
    // A ramp comes out led by the chain's mean delay: the same slope, shifted ahead.
    const double a = apply_inverse(inv, ramp, 1000)[i], b = apply_inverse(inv, ramp, 1100)[i];
    EXPECT_NEAR(b - a, 0.1, 1e-6);
    EXPECT_GE(a, 1.0 - 1e-6);
  }
}

}  // namespace
}  // namespace gcpipe::compensate
