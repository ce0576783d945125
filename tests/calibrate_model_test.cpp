// Every identified number derived twice: the calibration's own formulation of the output
// effects against the servo registry's classes run inside the simulator; the analytic
// Jacobians against central differences (effects and the NNOE's recurrent one); the fit's
// sigma against the spread of repeated fits; the noise estimate against the noise put in.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "axis_model.hpp"
#include "calibrate_test_util.hpp"
#include "identify.hpp"
#include "nnoe.hpp"

namespace gcpipe::calibrate {
namespace {

/// One axis (Y of seed 002) on the circle's commands.
struct AxisCase {
  servo::DriveParams p;
  std::vector<double> cmd;
};
AxisCase y_axis() {
  test::Scenario sc = test::circle_scenario();
  const MeasuredTrace tr = test::trace_of(sc, 1);
  return {sc.machine.drives.axes[kY], tr.command[kY]};
}

TEST(CalibrateModel, OutputEffectsEqualTheServoRegistryInsideTheSimulator) {
  const AxisCase c = y_axis();
  for (const auto& e : {test::effect("backlash", {{"width", 0.01}}),
                        test::effect("lead_error", {{"amplitude", 0.004}, {"period", 13}, {"phase", 25}}),
                        test::effect("scale_error", {{"ppm", 70}}),
                        test::effect("measurement_delay", {{"delay", 0.0023}})}) {
    servo::DriveParams with = c.p;
    with.effects.push_back(e);
    std::vector<double> ours = simulate_motor(c.p, 8, 0.9, 0.001, c.cmd);
    apply_output_effect(e, 0.001, ours);
    // The registry's effect inside servo::AxisDrive (RK4 path, sub-step position chain):
    servo::AxisDrive d(with, 0.001, 8, 0.9);
    const auto w = static_cast<std::size_t>(d.window());
    std::vector<double> pad(c.cmd);
    pad.resize(c.cmd.size() + w, c.cmd.back());
    d.reset(c.cmd[0]);
    double worst = 0, sq = 0;
    for (std::size_t k = 1; k < c.cmd.size(); ++k) {
      const double y = d.step(std::span<const double>(pad.data() + k - 1, w)).position;
      if (k > 10) worst = std::max(worst, std::abs(y - ours[k]));
      sq += (y - ours[k]) * (y - ours[k]);
    }
    const double rms = std::sqrt(sq / static_cast<double>(c.cmd.size()));
    std::cout << e.type << ": |registry - ours| max " << worst << " mm, rms " << rms << " mm\n";
    // Pointwise effects agree to the exact-vs-RK4 difference of the drive (< 1e-8 mm). The
    // delay is interpolated between ticks here (cubic) and between sub-steps there (linear).
    // The play operator acts on tick samples here and on 1/8-tick sub-steps in the simulator:
    // where the motor turns round inside a tick (Y overshoots at the ends of ramps) they
    // differ by the motion inside that tick, 0.11 um at most, 2 nm rms.
    const double max_tol = e.type == "backlash" ? 2e-4 : e.type == "measurement_delay" ? 5e-6 : 1e-8;
    const double rms_tol = e.type == "backlash" ? 5e-6 : e.type == "measurement_delay" ? 5e-7 : 1e-9;
    EXPECT_LT(worst, max_tol) << e.type;
    EXPECT_LT(rms, rms_tol) << e.type;
  }
}

TEST(CalibrateModel, AnalyticEffectJacobiansEqualCentralDifferences) {
  const AxisCase c = y_axis();
  const std::vector<double> base = simulate_motor(c.p, 8, 0.9, 0.001, c.cmd);
  struct Case { servo::EffectSettings e; std::vector<std::string> keys; };
  for (const auto& cs : {Case{test::effect("backlash", {{"width", 0.01}}), {"width"}},
                                Case{test::effect("lead_error", {{"amplitude", 0.004}, {"period", 13}, {"phase", 25}}), {"amplitude", "period", "phase"}},
                                Case{test::effect("scale_error", {{"ppm", 70}}), {"ppm"}},
                                Case{test::effect("measurement_delay", {{"delay", 0.0023}}), {"delay"}}}) {
    const servo::EffectSettings& e = cs.e;
    const std::vector<std::string>& keys = cs.keys;
    std::vector<double> y = base;
    std::vector<std::vector<double>> d;
    apply_output_effect(e, 0.001, y, &d);
    for (std::size_t i = 0; i < keys.size(); ++i) {
      auto at = [&](double delta) {
        servo::EffectSettings q = e;
        q.values[i].second += delta;
        std::vector<double> z = base;
        apply_output_effect(q, 0.001, z);
        return z;
      };
      const double h = 1e-6 * std::max(1.0, std::abs(e.values[i].second));
      const auto up = at(h), dn = at(-h);
      double worst = 0, scale = 0;
      for (std::size_t k = 0; k < y.size(); ++k) {
        const double fd = (up[k] - dn[k]) / (2 * h);
        // The play operator's derivative is undefined at the instant contact switches sides.
        if (e.type == "backlash" && std::abs(fd - d[i][k]) > 0.1) continue;
        worst = std::max(worst, std::abs(fd - d[i][k]));
        scale = std::max(scale, std::abs(fd));
      }
      EXPECT_LT(worst, 1e-5 * std::max(scale, 1e-3)) << e.type << "." << keys[i];
    }
  }
}

TEST(CalibrateModel, FitSigmaMatchesTheSpreadOfRepeatedFits) {
  // y = s x + noise, fitted 200 times: the reported sigma (tau = 1) against the std of s.
  std::mt19937_64 rng(3);
  const int n = 500;
  Eigen::VectorXd x(n);
  for (int i = 0; i < n; ++i) x[i] = std::sin(0.05 * i) * 3;
  std::vector<double> est, sig;
  for (int rep = 0; rep < 200; ++rep) {
    Eigen::VectorXd y(n);
    for (int i = 0; i < n; ++i) y[i] = 1.7 * x[i] + 0.1 * normal01(rng);
    ResidualFn r = [&](const Eigen::VectorXd& p, Eigen::MatrixXd* j) {
      if (j) *j = -x;
      return Eigen::VectorXd(y - p[0] * x);
    };
    const LsqResult f = least_squares(r, Eigen::VectorXd::Zero(1), Eigen::VectorXd::Constant(1, 1e-6), true, 1.0);
    est.push_back(f.x[0]);
    sig.push_back(f.sigma[0]);
  }
  double m = 0, v = 0, s = 0;
  for (double e : est) m += e / 200;
  for (double e : est) v += (e - m) * (e - m) / 199;
  for (double e : sig) s += e / 200;
  EXPECT_NEAR(std::sqrt(v), s, 0.15 * s);
  EXPECT_NEAR(s, 0.1 / x.norm(), 0.05 * s);  // the textbook sigma / sqrt(sum x^2)
}

TEST(CalibrateModel, NoiseEstimateRecoversTheNoisePutIn) {
  const MeasuredTrace tr = test::trace_of(test::circle_scenario(), 4);
  for (int a : {kX, kY, kZ}) EXPECT_NEAR(estimate_noise(tr.actual[static_cast<std::size_t>(a)]), 2e-4, 0.1 * 2e-4);
}

TEST(CalibrateModel, NnoeRecurrentJacobianEqualsFiniteDifferences) {
  std::mt19937_64 rng(5);
  const std::size_t n = 400;
  std::vector<double> r(n), v(n), a(n);
  for (std::size_t k = 0; k < n; ++k) {
    v[k] = std::sin(0.03 * static_cast<double>(k));
    a[k] = std::cos(0.07 * static_cast<double>(k));
    r[k] = 0.5 * std::sin(0.05 * static_cast<double>(k)) + 0.05 * normal01(rng);
  }
  NnoeModel m;
  m.structure = {2, 2, 5, {}};
  m.net = neural::Mlp({6, 5, 1});
  m.net.initialise(rng);
  const Eigen::VectorXd th = m.net.parameters();
  Eigen::MatrixXd jtj;
  Eigen::VectorXd jte;
  nnoe_output_error(m, r, v, a, 10, n, th, &jtj, &jte);
  // dS/dtheta = -J'e (e = r - r^): central differences of S itself.
  double worst = 0, scale = 0;
  for (Eigen::Index i = 0; i < th.size(); ++i) {
    Eigen::VectorXd up = th, dn = th;
    up[i] += 1e-6;
    dn[i] -= 1e-6;
    const double fd = (nnoe_output_error(m, r, v, a, 10, n, up, nullptr, nullptr) - nnoe_output_error(m, r, v, a, 10, n, dn, nullptr, nullptr)) / 2e-6;
    worst = std::max(worst, std::abs(fd + jte[i]));
    scale = std::max(scale, std::abs(fd));
  }
  EXPECT_LT(worst, 1e-6 * std::max(scale, 1.0));
}

}  // namespace
}  // namespace gcpipe::calibrate
