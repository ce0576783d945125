// Validation of the feed-drive model against seed 002 (Suzuki et al. 2019). Each test compares the
// time-stepped simulation with a second formulation (frequency response, analytic ramp lag) or
// with the paper's own numbers; see stages/servo/README.md for the figures they print.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <deque>
#include <numbers>
#include <optional>
#include <vector>

#include "circle.hpp"
#include "gcpipe/config.hpp"
#include "servo.hpp"

using namespace gcpipe;
using namespace gcpipe::servo;
using interpolate::Smoothing;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kT = 0.001;

DriveSet seed002() {
  return load_drives(Config::load_file(std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/drives/seed002.yaml"));
}

const double kOmegas[] = {0.5 * kPi, kPi, 1.5 * kPi, 2 * kPi, 3 * kPi, 4 * kPi};

}  // namespace

// Eq. (12): with X and Y alike the steady circle is round and its radius decrease is
// (1 - |G_L(jw)|) R_W, G_L being the model's own response from raw interpolated samples to the
// axis (smoothing x first-order hold x drive).
TEST(Seed002Circle, RadiusDecreaseMatchesFrequencyResponseWithAlikeAxes) {
  DriveSet d = seed002();
  d.axes[kX] = d.axes[kY];
  d.axes[kX].rotary = false;
  for (Smoothing sm : {Smoothing::kExponential, Smoothing::kLinear, Smoothing::kNone}) {
    for (double w : kOmegas) {
      CircleTest c;
      c.omega = w;
      const double span = 2 * 2 * kPi / w;
      const CircleSummary s = simulate_circle(d, sm, kT, c, 1.5, span);
      const double g = std::abs(command_response(d.axes[kY], sm, kT, w));
      const double expected = (1 - g) * c.R_W;
      std::printf("smoothing %d  w = %5.3f pi rad/s: dR simulated %.6f um, (1-|G_L|) R_W %.6f um, ripple %.2e um\n",
                  static_cast<int>(sm), w / kPi, s.mean_radius_decrease * 1e3, expected * 1e3,
                  (s.max_radius_decrease - s.min_radius_decrease) * 1e3);
      EXPECT_NEAR(s.mean_radius_decrease, expected, 0.02 * std::abs(expected)) << "w = " << w;
    }
  }
}

// DESIGN.md section 4's radius-reduction formula is the small-speed limit of the same model:
// dR ~ v^2/(2R) ((1 - a^2)/Kv^2 + Ts^2) for an ideal velocity loop with feed-forward fraction a
// and exponential smoothing, v^2 T^2/(24 R) instead of the Ts^2 term for a moving average.
TEST(Seed002Circle, DesignRadiusFormulaIsTheSmallSpeedLimit) {
  DriveSet d = seed002();
  for (double a : {0.0, 0.5}) {
    DriveParams p = d.axes[kY];
    p.Kvp = 1e6;  // velocity loop far faster than the position loop: G = (Kv + a s)/(s + Kv)
    p.C = 0;
    p.Kvi = 0;
    p.Ta = 0;
    p.Tp = 0;
    p.K_FFP = 100 * a;
    d.axes[kX] = d.axes[kY] = p;
    d.axes[kX].rotary = false;
    for (Smoothing sm : {Smoothing::kExponential, Smoothing::kLinear}) {
      CircleTest c;
      c.omega = 0.5 * kPi;
      const double v = c.omega * c.R_W;
      const double ts_term = sm == Smoothing::kExponential ? p.Ts * p.Ts : p.Ts * p.Ts / 12;
      const double formula = v * v / (2 * c.R_W) * ((1 - a * a) / (p.Kpp * p.Kpp) + ts_term);
      const CircleSummary s = simulate_circle(d, sm, kT, c, 1.5, 2 * 2 * kPi / c.omega);
      std::printf("a = %.1f smoothing %d: dR simulated %.4f um, DESIGN formula %.4f um\n", a,
                  static_cast<int>(sm), s.mean_radius_decrease * 1e3, formula * 1e3);
      EXPECT_NEAR(s.mean_radius_decrease, formula, 0.05 * formula);
    }
  }
}

// Table 1 as printed: X and Y differ, the steady path is an ellipse; its mean radius decrease is
// predicted by the per-axis responses (quadrature over one period of the predicted ellipse).
TEST(Seed002Circle, RadiusDecreaseAndPhaseMatchPredictionWithTable1Axes) {
  const DriveSet d = seed002();
  for (double w : kOmegas) {
    CircleTest c;
    c.omega = w;
    const double span = 2 * 2 * kPi / w;
    const CircleSummary s = simulate_circle(d, Smoothing::kExponential, kT, c, 1.5, span);
    const CirclePrediction p = predict_circle(d, Smoothing::kExponential, kT, c);
    std::printf("w = %5.3f pi: dR sim %.4f um pred %.4f um | beta sim %.5f mrad pred %.5f mrad (X %.5f, Y %.5f)\n",
                w / kPi, s.mean_radius_decrease * 1e3, p.radius_decrease * 1e3, s.mean_beta * 1e3,
                p.beta * 1e3, p.beta_x * 1e3, p.beta_y * 1e3);
    EXPECT_NEAR(s.mean_radius_decrease, p.radius_decrease, 0.02 * std::abs(p.radius_decrease));
    EXPECT_NEAR(s.mean_beta, p.beta, 0.02 * std::abs(p.beta) + 1e-6);
  }
}

namespace {

// Section 3: J1 = 1.70, 3.24, 4.77 on the C table; Section 5.2 rounds J + J1 to 5.9, 7.4, 8.9.
const double kTotalInertia[3] = {5.9, 7.4, 8.9};
const double kPaperOnset[3] = {9.39, 7.58, 5.83};  // rad/s, Section 5.2

DriveParams c_axis(double total_inertia, double kffp) {
  DriveParams c = seed002().axes[kC];
  c.J1 = total_inertia - c.J;
  c.K_FFP = kffp;
  return c;
}

}  // namespace

// Fig. 17/18: torque saturation (725 N*m) sets in at w = 9.39 / 7.58 / 5.83 rad/s. The model
// reproduces this with exponential acc/dec after interpolation (time constant Ts = 0.064 s, whose
// initial acceleration w/Ts is the paper's "dw/dt = w/0.064") and K_FFP of C in 89..97 %; the
// README shows why J*dw/dt with a linear 0.064 s ramp cannot (it needs J_eff = 0.84 J).
TEST(Seed002Torque, SaturationOnsetWithinFivePercentOfThePaper) {
  for (double kffp : {90.0, 92.0, 96.0}) {
    for (int i = 0; i < 3; ++i) {
      const DriveParams c = c_axis(kTotalInertia[i], kffp);
      const double onset = torque_onset_omega(c, Smoothing::kExponential, kT);
      std::printf("K_FFP %.0f %%  J+J1 %.1f: onset %.3f rad/s (paper %.2f, %+.1f %%)\n", kffp,
                  kTotalInertia[i], onset, kPaperOnset[i], 100 * (onset / kPaperOnset[i] - 1));
      EXPECT_NEAR(onset, kPaperOnset[i], 0.05 * kPaperOnset[i]) << "J+J1 " << kTotalInertia[i];
      // Second formulation: run with the limit in force just below and just above the onset.
      EXPECT_FALSE(ramp_torque(c, Smoothing::kExponential, kT, 0.98 * onset, true).saturated);
      EXPECT_TRUE(ramp_torque(c, Smoothing::kExponential, kT, 1.02 * onset, true).saturated);
    }
  }
}

// The readings the README rejects, checked so the claim stays true: a linear 0.064 s ramp
// (acceleration w/0.064 held for 64 ms) needs the full J*dw/dt and puts every onset more than
// 10 % below the paper, whatever K_FFP; exponential smoothing at K_FFP = 100 % misses 7.4 by
// a little more than 5 %.
TEST(Seed002Torque, LinearRampReadingMissesThePaper) {
  for (double kffp : {0.0, 100.0}) {
    for (int i = 0; i < 3; ++i) {
      const double onset = torque_onset_omega(c_axis(kTotalInertia[i], kffp), Smoothing::kLinear, kT);
      std::printf("linear ramp, K_FFP %.0f %%, J+J1 %.1f: onset %.3f rad/s (paper %.2f, %+.1f %%); J*a alone: %.3f\n",
                  kffp, kTotalInertia[i], onset, kPaperOnset[i], 100 * (onset / kPaperOnset[i] - 1),
                  725 * 0.064 / kTotalInertia[i]);
      EXPECT_LT(onset, 0.9 * kPaperOnset[i]);
    }
  }
  const double onset74 = torque_onset_omega(c_axis(7.4, 100), Smoothing::kExponential, kT);
  EXPECT_LT(onset74, 0.95 * kPaperOnset[1]);
}

// Section 3's Kpp = 30 instead of Table 1's 60, with the exponential smoothing that works for 60:
// at least one onset is off by more than 5 % for every K_FFP of C from 80 to 100 %.
TEST(Seed002Torque, Section3Kpp30MissesThePaper) {
  for (double kffp : {80.0, 90.0, 100.0}) {
    double worst = 0;
    for (int i = 0; i < 3; ++i) {
      DriveParams c = c_axis(kTotalInertia[i], kffp);
      c.Kpp = 30;
      const double onset = torque_onset_omega(c, Smoothing::kExponential, kT);
      worst = std::max(worst, std::abs(onset / kPaperOnset[i] - 1));
      std::printf("Kpp 30, K_FFP %.0f %%, J+J1 %.1f: onset %.3f rad/s (%+.1f %%)\n", kffp, kTotalInertia[i],
                  onset, 100 * (onset / kPaperOnset[i] - 1));
    }
    EXPECT_GT(worst, 0.05) << kffp;
  }
}

// Eq. (20): with the Best K_FFP of X and Y computed from the model, the simulated steady
// relative angle difference alpha - beta vanishes to within 1 % of alpha.
// The last case (J + J1 = 8.9, w = 2 pi > its 6.05 rad/s onset) starts torque-saturated.
// Above about 3 pi no K_FFP >= 0 lets X lag as much as C (README), so the sweep stops at 2 pi.
TEST(Seed002BestKffp, SimulatedAlphaMinusBetaVanishes) {
  struct Case { double w, total_inertia; };
  for (Case k : {Case{0.5 * kPi, 5.9}, Case{kPi, 5.9}, Case{1.5 * kPi, 5.9}, Case{2 * kPi, 5.9},
                 Case{2 * kPi, 8.9}}) {
    const double w = k.w;
    DriveSet d = seed002();
    d.axes[kC].J1 = k.total_inertia - d.axes[kC].J;
    if (k.total_inertia > 8) {
      EXPECT_TRUE(ramp_torque(d.axes[kC], Smoothing::kExponential, kT, w, true).saturated);
    }
    CircleTest c;
    c.omega = w;
    const double settle = 1.5, span = 2 * 2 * kPi / w;
    const CircleSummary before = simulate_circle(d, Smoothing::kExponential, kT, c, settle, span);
    const BestKffp best = best_kffp(d, Smoothing::kExponential, kT, w, settle, span);
    ASSERT_TRUE(best.ok) << best.message;
    d.axes[kX].K_FFP = best.K_FFP[0];
    d.axes[kY].K_FFP = best.K_FFP[1];
    const CircleSummary after = simulate_circle(d, Smoothing::kExponential, kT, c, settle, span);
    std::printf("J+J1 %.1f w = %.1f pi: alpha %.4f mrad; K_FFP X %.3f %% Y %.3f %%; alpha-beta %.4f -> %.6f mrad; "
                "shape error half-amplitude %.3f -> %.3f um\n",
                k.total_inertia, w / kPi, best.alpha * 1e3, best.K_FFP[0], best.K_FFP[1],
                before.mean_alpha_minus_beta * 1e3, after.mean_alpha_minus_beta * 1e3,
                before.shape_error_half_amplitude * 1e3, after.shape_error_half_amplitude * 1e3);
    EXPECT_NEAR(after.mean_alpha, best.alpha, 1e-3 * std::abs(best.alpha));
    EXPECT_LT(std::abs(after.mean_alpha_minus_beta), 0.01 * std::abs(best.alpha));
  }
}

// Eq. (17) second formulation for the rotary lag: after the smoothing has settled, the ramp lag
// in the time domain equals w * (Ts + the drive's quasi-steady ramp lag time).
TEST(Seed002BestKffp, NoSolutionWhenXCannotLagEnough) {
  const BestKffp best = best_kffp(seed002(), Smoothing::kExponential, kT, 3.2 * kPi, 1.5, 0.625);
  EXPECT_FALSE(best.ok);
  EXPECT_NE(best.message.find("axis X"), std::string::npos) << best.message;
}

TEST(Seed002BestKffp, RampLagMatchesAnalyticLimit) {
  const DriveSet d = seed002();
  for (double kffp : {0.0, 50.0, 100.0}) {
    DriveParams c = d.axes[kC];
    c.K_FFP = kffp;
    const double w = kPi;
    const double sim = rotary_ramp_lag(c, Smoothing::kExponential, kT, w, 1.5, 1.0);
    // Exponential smoothing y_k = a y_{k-1} + (1-a) x_k lags a ramp by T a / (1 - a) samples' time.
    const double a = std::exp(-kT / c.Ts);
    const double expected = w * (kT * a / (1 - a) + ramp_lag_time(c));
    std::printf("K_FFP %.0f %%: ramp lag %.6f mrad, analytic %.6f mrad\n", kffp, sim * 1e3, expected * 1e3);
    EXPECT_NEAR(sim, expected, 1e-3 * expected);
  }
}

// The whole chain on the sample program: parser -> interpolator (G93 arcs with C) -> drives.
// In each condition's steady part the radius decrease and the eq.-(9) phase delay must match the
// frequency-response prediction as closely as the direct circle runs above do (2 %), and the
// rotary lag alpha must match the ramp lag of eq. (20).
#include <fstream>

#include "gcpipe/pipeline_config.hpp"
#include "parse.hpp"

namespace {

struct Recorder final : interpolate::SampleSink {
  ServoSimulator* sim = nullptr;
  std::deque<Axes> raw;
  std::vector<std::pair<Axes, ServoSample>> ticks;  // (raw nominal, servo tick)
  void raw_sample(const Axes& r) override { raw.push_back(r); }
  void sample(const Axes& c) override {
    ServoSample s;
    if (sim->push(c, s)) take(s);
  }
  void take(const ServoSample& s) {
    ticks.emplace_back(raw.front(), s);
    raw.pop_front();
  }
};

}  // namespace

TEST(Seed002Sample, ProgramThroughParserAndInterpolatorMatchesPrediction) {
  const std::string root = GCPIPE_SOURCE_DIR;
  const PipelineConfig pc = load_pipeline_config(root + "/pipeline_configs/circle_test.yaml");
  const DriveSet d = load_drives(Config::load_file(root + "/pipeline_configs/drives/seed002.yaml"));
  interpolate::InterpolateOptions io = interpolate::load_interpolate_options(pc.root.section("interpolate"));
  io.max_velocity = pc.machine.kinematics.max_velocity;
  io.max_acceleration = pc.machine.kinematics.max_acceleration;
  for (std::size_t i = 0; i < kNumAxes; ++i) io.smoothing_time[i] = d.axes[i].Ts;
  ASSERT_EQ(io.smoothing, Smoothing::kExponential);

  Parser parser(load_parse_options(pc.root.section("parse")), pc.machine, "circle_test_seed002.nc");
  std::ifstream in(root + "/samples/circle_test_seed002.nc");
  ASSERT_TRUE(in) << "sample missing";
  ServoSimulator sim(d, io.period);
  Recorder rec;
  rec.sim = &sim;
  std::optional<interpolate::Interpolator> ip;
  double t = 0;
  struct Window { double omega, begin, end; };
  std::vector<Window> windows;
  std::string line;
  LineOutput out;
  while (std::getline(in, line)) {
    parser.feed(line, out);
    ASSERT_EQ(out.error(), nullptr) << format(*out.error());
    if (out.blocks.size() != 1 || out.blocks[0].motion == Motion::kNone) continue;
    const ResolvedBlock& b = out.blocks[0];
    if (!ip) {
      ip.emplace(io, b.start);
      rec.raw.push_back(b.start);
      rec.take(sim.reset(b.start, 0));
    }
    const auto r = ip->add(b, rec);
    ASSERT_EQ(r.status, interpolate::InterpolateStatus::kOk) << r.message;
    if (b.motion == Motion::kArcCCW) {
      EXPECT_EQ(b.feed_mode, FeedMode::kInverseTime);
      const double w = 2 * kPi * b.feed / 60;
      if (windows.empty() || std::abs(windows.back().omega - w) > 1e-9) windows.push_back({w, t, t});
      windows.back().end = t + r.duration;
    }
    t += r.duration;
  }
  ip->finish(rec);
  ServoSample s;
  while (sim.flush(s)) rec.take(s);
  ASSERT_EQ(windows.size(), 6u);
  for (const Window& win : windows) {
    CircleTest c;
    c.omega = win.omega;
    double sum_dr = 0, sum_b = 0, sum_a = 0;
    std::size_t n = 0;
    // Steady part: 1 s after the start, whole turns up to the end of the condition.
    const double period = 2 * kPi / win.omega;
    const double begin = win.begin + std::ceil(1.0 / period) * period;
    for (const auto& [nominal, tick] : rec.ticks) {
      if (tick.t <= begin + 1e-9 || tick.t > win.end + 1e-9) continue;
      const CirclePoint p = circle_point_at(c, nominal[kC] * kPi / 180, tick.actual[kX], tick.actual[kY], tick.actual[kC]);
      sum_dr += p.radius_decrease;
      sum_b += p.beta;
      sum_a += p.alpha;
      ++n;
    }
    ASSERT_GT(n, 100u);
    const CirclePrediction pred = predict_circle(d, Smoothing::kExponential, kT, c);
    const double alpha = rotary_ramp_lag(d.axes[kC], Smoothing::kExponential, kT, win.omega, 1.5, period);
    std::printf("sample w = %.2f pi: dR %.3f um (pred %.3f), beta %.4f mrad (pred %.4f), alpha %.4f mrad (ramp lag %.4f)\n",
                win.omega / kPi, sum_dr / n * 1e3, pred.radius_decrease * 1e3, sum_b / n * 1e3, pred.beta * 1e3,
                sum_a / n * 1e3, alpha * 1e3);
    EXPECT_NEAR(sum_dr / n, pred.radius_decrease, 0.02 * pred.radius_decrease);
    EXPECT_NEAR(sum_b / n, pred.beta, 0.02 * pred.beta);
    EXPECT_NEAR(sum_a / n, alpha, 0.02 * alpha);
  }
}
