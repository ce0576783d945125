#include "chain_inverse.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "interpolate.hpp"
#include "servo.hpp"

namespace gcpipe::compensate {

namespace {

using Eigen::Index;

// Step response of axis `axis` of the model: raw command 0 -> 1 (mm or deg) at tick `onset`
// (>= 1), the actual position per tick (`ticks` values, tick 0 at rest).
std::vector<double> chain_step_response(const simulate::Model& model, std::size_t axis, std::size_t ticks,
                                        std::size_t onset) {
  servo::ServoSimulator sim(model.drives, model.interp.period);
  std::vector<double> y;
  y.reserve(ticks);
  y.push_back(sim.reset(Axes{}, 0.0).actual[axis]);
  interpolate::AxisSmoother smoother(model.interp.smoothing, model.interp.smoothing_time[axis], model.interp.period, 0.0);
  servo::ServoSample s;
  // Command p is pushed for tick p; the drive hands back tick p - (its look-ahead) meanwhile.
  for (std::size_t p = 1; y.size() < ticks; ++p) {
    Axes c{};
    c[axis] = smoother.filter(p >= onset ? 1.0 : 0.0);
    if (sim.push(c, s)) y.push_back(s.actual[axis]);
  }
  return y;
}

// The design's time scales (README.md beside this file, "The learning operator"). The filter
// reads the error from 0.1 s ahead (the chain's delay and more) to 0.2 s behind; the step
// response is followed for 1.5 s (X of seed 002, Kvp 177.5 on J 4.5, settles in about 0.4 s).
constexpr double kLeadSeconds = 0.10;
constexpr double kSpanSeconds = 0.30;
constexpr double kResponseSeconds = 1.5;
// The step comes at the first tick, so g leaves out what the drive does before the step: its
// feed-forward reads the command Tp ahead (X of seed 002: 15.5 ms) and answers early and sharply.
// Measured: with that part in g (a step 0.1 s in) the inverse is sharper, its first iterate
// breaks X's acceleration limit on the CAM-like programs and the learning ends at 5.3x / 9.8x
// instead of 18.5x / 24.3x (README.md beside this file, "Limits of the method").
constexpr std::size_t kOnsetTicks = 1;
// Taps 4 ms apart: the inverse's output is smooth on that scale (its target is the Gaussian
// below), and the update costs a quarter of 1 ms taps; measured: the same errors to 1-2 %.
constexpr double kStrideSeconds = 0.004;
// The target of chain * filter: a Gaussian of 10 ms standard deviation instead of a unit impulse.
// An exact inverse of acc/dec plus a drive (relative degree 3 and more) amplifies the tick-scale
// content of the error without bound; the Gaussian is the learning's low-pass Q, built into L.
// Chosen by measurement over the README's programs (sigma 8, 10, 12, 15, 20 ms).
constexpr double kTargetSigmaSeconds = 0.010;
// Weight of the taps' second difference against the fit: a tie-breaker only (the fit's residual
// is below 1 % on the shipped drive axes).
constexpr double kSmoothness = 1e-6;

Eigen::VectorXd impulse_response(const std::vector<double>& step) {
  Eigen::VectorXd g(static_cast<Index>(step.size()));
  g[0] = step[0];
  for (std::size_t k = 1; k < step.size(); ++k) g[static_cast<Index>(k)] = step[k] - step[k - 1];
  return g;
}

// A unit-sum Gaussian of `sigma` ticks centred on tick `centre`, over `length` ticks.
Eigen::VectorXd gaussian(std::size_t length, std::size_t centre, double sigma) {
  Eigen::VectorXd q = Eigen::VectorXd::Zero(static_cast<Index>(length));
  for (std::size_t k = 0; k < length; ++k) {
    const double z = (static_cast<double>(k) - static_cast<double>(centre)) / sigma;
    if (std::abs(z) < 5) q[static_cast<Index>(k)] = std::exp(-0.5 * z * z);
  }
  return q / q.sum();
}

// The target Gaussian (`sigma` ticks) at the taps, tap j reading `lead - stride j` ticks from its
// centre, with unit sum.
Eigen::VectorXd sampled_target(Index taps, Index stride, std::size_t lead, double sigma) {
  Eigen::VectorXd f(taps);
  for (Index j = 0; j < taps; ++j) {
    const double z = (static_cast<double>(stride * j) - static_cast<double>(lead)) / sigma;
    f[j] = std::exp(-0.5 * z * z);
  }
  return f / f.sum();
}

// Least squares for taps f (every `stride` ticks): min |g * f - q|^2 + w |D2 f|^2 subject to
// sum f = 1 / sum g and sum (stride j) f_j = (lead - mean delay of g) / sum g, so that a held
// error and a ramp come back exactly (the Gaussian has unit sum and its centre at `lead`).
// `step` is the response to a step at tick `onset`: g is taken as causal and `onset` late, so the
// target and the delay are `onset` late too.
AxisInverse design_axis(const std::vector<double>& step, std::size_t onset, std::size_t lead, std::size_t taps,
                        std::size_t stride, double sigma) {
  const Eigen::VectorXd g = impulse_response(step);
  const std::size_t centre = lead + onset;
  const Index G = g.size(), K = static_cast<Index>(taps), s = static_cast<Index>(stride);
  const Index H = G + s * (K - 1);
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(H, K);
  for (Index j = 0; j < K; ++j) A.block(s * j, j, G, 1) = g;
  const Eigen::VectorXd q = gaussian(static_cast<std::size_t>(H), centre, sigma);
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(K - 2, K);
  for (Index j = 0; j + 2 < K; ++j) D(j, j) = 1, D(j, j + 1) = -2, D(j, j + 2) = 1;
  const double dc = g.sum();
  const double g_delay = Eigen::VectorXd::LinSpaced(G, 0, static_cast<double>(G - 1)).dot(g) / dc;
  Eigen::MatrixXd C(2, K);
  C.row(0).setOnes();
  C.row(1) = Eigen::VectorXd::LinSpaced(K, 0, static_cast<double>(s * (K - 1))).transpose();
  // The KKT system of the constrained least squares.
  Eigen::MatrixXd kkt = Eigen::MatrixXd::Zero(K + 2, K + 2);
  kkt.topLeftCorner(K, K) = A.transpose() * A + kSmoothness * (D.transpose() * D);
  kkt.topRightCorner(K, 2) = C.transpose();
  kkt.bottomLeftCorner(2, K) = C;
  Eigen::VectorXd rhs(K + 2);
  rhs.head(K) = A.transpose() * q;
  rhs.tail(2) << 1.0 / dc, (static_cast<double>(centre) - g_delay) / dc;
  Eigen::VectorXd x = kkt.fullPivLu().solve(rhs);
  // A chain that is the identity (an ideal axis without acc/dec after interpolation, as under the
  // look-ahead control): its response to the comb of taps is a comb, which no taps fit to the
  // smooth target; the least squares then spread the DC constraint over every tap (a 300 ms
  // average: the feed-forward lagged Z by tens of um at every corner). Its inverse is the target
  // itself: the Gaussian sampled at the taps, scaled to unit sum (symmetric about the lead, so
  // the first-moment condition holds too).
  if (g.cwiseAbs().maxCoeff() > 0.99 * std::abs(dc)) x.head(K) = sampled_target(K, s, lead, sigma) / dc;
  AxisInverse f;
  f.taps.assign(x.data(), x.data() + K);
  f.lead = static_cast<std::ptrdiff_t>(lead);
  f.stride = static_cast<std::ptrdiff_t>(stride);
  f.residual = (A * x.head(K) - q).norm() / q.norm();
  return f;
}

}  // namespace

ChainInverse design_chain_inverse(const simulate::Model& model) {
  const double T = model.interp.period;
  const auto ticks = [T](double seconds) { return static_cast<std::size_t>(std::max(1L, std::lround(seconds / T))); };
  // Taps 4 ms apart fit a chain that is smooth on that scale (acc/dec after interpolation first);
  // the drives alone (the look-ahead control has no acc/dec after interpolation) answer within a
  // tick or two, and a comb of taps 4 ms apart cannot fit them: the least squares then spread the
  // DC condition over the whole span, a 300 ms average that lagged Y by 0.8 mm on a circle at
  // F3000. There the taps are every tick (four times the work of applying L).
  const std::size_t stride = model.interp.smoothing == interpolate::Smoothing::kNone ? 1 : ticks(kStrideSeconds);
  ChainInverse inv;
  // Under the look-ahead control the drives alone are the chain: their feed-forward reads the
  // command Tp ahead and answers before the step, and without that part g shows a delay of about
  // the drive's lag which the drives do not have (with it left out the feed-forward led Y by
  // 0.8 mm on a circle at F3000). There the step comes 0.1 s in, so g holds it.
  const std::size_t onset = model.interp.smoothing == interpolate::Smoothing::kNone ? ticks(kLeadSeconds) : kOnsetTicks;
  for (std::size_t i = 0; i < kNumAxes; ++i)
    inv.axis[i] = design_axis(chain_step_response(model, i, onset + ticks(kResponseSeconds), onset), onset,
                              ticks(kLeadSeconds), std::max<std::size_t>(3, ticks(kSpanSeconds) / stride), stride,
                              kTargetSigmaSeconds / T);
  inv.interleaved.assign(inv.axis[0].taps.size(), Axes{});
  for (std::size_t j = 0; j < inv.interleaved.size(); ++j)
    for (std::size_t i = 0; i < kNumAxes; ++i) inv.interleaved[j][i] = inv.axis[i].taps[j];
  return inv;
}

namespace {

// The five axes at once over a series of `size` ticks whose tick m, axis i, is `value(m, i)`:
// each tick is read once for the five axes (the taps interleaved).
template <class Value>
Axes apply_all(const ChainInverse& inv, std::int64_t size, std::int64_t n, Value&& value) {
  const AxisInverse& f = inv.axis[0];
  const std::int64_t last = size - 1;
  const std::int64_t top = n + f.lead;
  const std::int64_t K = static_cast<std::int64_t>(inv.interleaved.size());
  Axes v{};
  const bool inside = top <= last && top - (K - 1) * f.stride >= 0;
  for (std::int64_t j = 0; j < K; ++j) {
    const std::int64_t m = inside ? top - j * f.stride : std::clamp<std::int64_t>(top - j * f.stride, 0, last);
    const Axes& t = inv.interleaved[static_cast<std::size_t>(j)];
    for (std::size_t i = 0; i < kNumAxes; ++i) v[i] += t[i] * value(m, i);
  }
  return v;
}

}  // namespace

Axes apply_inverse(const ChainInverse& inv, const std::vector<Axes>& x, std::int64_t n) {
  return apply_all(inv, static_cast<std::int64_t>(x.size()), n,
                   [&](std::int64_t m, std::size_t i) { return x[static_cast<std::size_t>(m)][i]; });
}

Axes apply_inverse(const ChainInverse& inv, const std::vector<AxesF>& x, std::int64_t n) {
  return apply_all(inv, static_cast<std::int64_t>(x.size()), n,
                   [&](std::int64_t m, std::size_t i) { return static_cast<double>(x[static_cast<std::size_t>(m)][i]); });
}

Axes apply_inverse(const ChainInverse& inv, const simulate::JointSeries& x, std::int64_t n) {
  const auto size = static_cast<std::int64_t>(x.size());
  if (x.exact())
    return apply_all(inv, size, n, [&](std::int64_t m, std::size_t i) { return x.at(static_cast<std::size_t>(m), i); });
  // Compact: the arrays read directly (at() would test exact() at every tap; the model-inverse
  // start reads the reference this way at every node of every window).
  const double* base = x.base_data();
  const float* offset = x.offset_data();
  constexpr auto kA = static_cast<std::int64_t>(kNumAxes);
  constexpr auto kBits = static_cast<std::int64_t>(simulate::JointSeries::kBlockBits);
  return apply_all(inv, size, n, [&](std::int64_t m, std::size_t i) {
    return base[(m >> kBits) * kA + static_cast<std::int64_t>(i)] + static_cast<double>(offset[m * kA + static_cast<std::int64_t>(i)]);
  });
}

FeedforwardRun feedforward_run(const simulate::Model& model, const simulate::Nominal& nom,
                               std::span<const ResolvedBlock> program, const Axes& start) {
  const ChainInverse inv = design_chain_inverse(model);
  const double T = model.interp.period;
  const auto per_second = static_cast<std::size_t>(std::llround(1.0 / T));
  FeedforwardRun r;
  r.over_limit.assign(nom.reference.size() / per_second + 1, 0.0);
  Axes u1 = start, u2 = start;
  r.eval = simulate::run_commands(model, nom, program, start, nom.reference.size(), [&](std::size_t n) {
    const Axes u = apply_inverse(inv, nom.reference, static_cast<std::int64_t>(n));
    double& over = r.over_limit[n / per_second];
    for (std::size_t i = 0; i < kNumAxes && n >= 2; ++i)
      if (model.kin.max_acceleration[i] > 0)
        over = std::max(over, std::abs(u[i] - 2 * u1[i] + u2[i]) / (T * T) / model.kin.max_acceleration[i]);
    u2 = u1, u1 = u;
    return u;
  });
  return r;
}

}  // namespace gcpipe::compensate
