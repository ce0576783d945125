// Unit tests of the feed-drive core: config loading, the exact discretisation against RK4 and its
// convergence, the look-ahead streaming, and the pluggable effects.
#include <gtest/gtest.h>

#include <bit>

#include <cmath>
#include <complex>
#include <cstdio>
#include <numbers>
#include <vector>

#include "gcpipe/config.hpp"
#include "servo.hpp"

using namespace gcpipe;
using namespace gcpipe::servo;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kT = 0.001;

DriveSet seed002() {
  return load_drives(Config::load_file(std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/drives/seed002.yaml"));
}

std::string load_error(const std::string& yaml) {
  try {
    load_drives(Config::from_string(yaml, "drives.yaml"));
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

// Runs one axis over a command sequence; returns actual positions (one per step).
std::vector<double> run(AxisDrive& d, const std::vector<double>& cmd, std::vector<double>* torque = nullptr) {
  std::vector<double> out;
  const auto w = static_cast<std::size_t>(d.window());
  d.reset(cmd[0]);
  for (std::size_t k = 0; k + w <= cmd.size(); ++k) {
    const AxisState s = d.step(std::span<const double>(cmd.data() + k, w));
    out.push_back(s.position);
    if (torque) torque->push_back(s.torque);
  }
  return out;
}

// A demanding command: start from rest with a velocity step, a circle component, then a stop.
std::vector<double> test_command(double amplitude, double omega, std::size_t n) {
  std::vector<double> c(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * kT;
    c[k] = t < 0.6 ? amplitude * std::sin(omega * t) + 20 * t : c[k - 1];
  }
  return c;
}

}  // namespace

TEST(ServoConfig, Seed002LoadsWithTable1Values) {
  const DriveSet d = seed002();
  EXPECT_DOUBLE_EQ(d.axes[kX].Kvp, 177.5);
  EXPECT_DOUBLE_EQ(d.axes[kX].lead, 0.016);
  EXPECT_NEAR(d.axes[kX].r(), 0.016 / (2 * kPi), 1e-15);
  EXPECT_DOUBLE_EQ(d.axes[kY].r(), 1.0);
  EXPECT_DOUBLE_EQ(d.axes[kC].J + d.axes[kC].J1, 5.9);
  EXPECT_DOUBLE_EQ(d.axes[kC].torque_limit, 725);
  EXPECT_TRUE(d.axes[kC].rotary);
  EXPECT_EQ(d.axes[kZ].model, DriveModel::kIdeal);
}

TEST(ServoConfig, RejectsUnknownKeysAndOutOfRangeValuesNamingTheAxis) {
  EXPECT_NE(load_error("axes: {X: {Jx: 1}}").find("Jx"), std::string::npos);
  EXPECT_NE(load_error("axes: {Q: {}}").find("Q"), std::string::npos);
  EXPECT_NE(load_error("substep: 3").find("substep"), std::string::npos);
  const std::string e = load_error("axes: {Y: {Kpp: -3}}");
  EXPECT_NE(e.find("axes.Y.Kpp"), std::string::npos) << e;
  EXPECT_NE(e.find("-3"), std::string::npos) << e;
  EXPECT_NE(load_error("axes: {C: {lead: 0.01}}").find("rotary"), std::string::npos);
  EXPECT_NE(load_error("axes: {X: {effects: {glue: {}}}}").find("unknown effect"), std::string::npos);
  EXPECT_NE(load_error("axes: {X: {effects: {backlash: {wdth: 1}}}}").find("wdth"), std::string::npos);
  EXPECT_NE(load_error("axes: {X: {effects: {lead_error: {amplitude: 0.001}}}}").find("period"), std::string::npos);
  EXPECT_EQ(load_error("axes: {X: {effects: {backlash: {width: 0.01}, coulomb_friction: {torque: 2}}}}"), "");
}

// The exact step and RK4 solve the same equations: with many sub-steps RK4 must agree to
// rounding, and its error must fall as h^4 (order 4) when the sub-step halves.
TEST(ServoDiscretisation, Rk4ConvergesToTheExactStepAtFourthOrder) {
  const DriveSet d = seed002();
  for (int axis : {kX, kY, kC}) {
    DriveParams p = d.axes[static_cast<std::size_t>(axis)];
    p.torque_limit = 0;  // the linear model: the exact step is exact only without the limit
    const auto cmd = test_command(p.rotary ? 30.0 : 5.0, 2 * kPi, 1200);
    AxisDrive exact(p, kT, 1, 0.9);
    const auto ref = run(exact, cmd);
    double prev_err = 0;
    std::printf("axis %c:", kAxisLetters[axis]);
    // From 2: X's Tp = 15.5 ms splits each period at its middle, so 1 and 2 sub-steps coincide.
    for (int n : {2, 4, 8, 16, 32}) {
      AxisDrive rk(p, kT, n, 0.9);
      rk.force_rk4(true);
      const auto got = run(rk, cmd);
      double err = 0;
      for (std::size_t i = 0; i < got.size(); ++i) err = std::max(err, std::abs(got[i] - ref[i]));
      std::printf("  N=%d max|RK4-exact| %.3e", n, err);
      if (prev_err > 1e-11) EXPECT_LT(err, prev_err / 10) << "substeps " << n;
      prev_err = err;
    }
    std::printf("\n");
    EXPECT_LT(prev_err, 1e-6);
  }
}

// An axis at rest repeats its last step's result instead of working it out again: the same bits
// as working every step out, through holds (reached exactly or still settling), moves that
// resume after a hold, sub-micrometre steps, and torque-limited moves, on every axis of seed 002.
TEST(ServoDiscretisation, RepeatedRestStepsChangeNoBit) {
  const DriveSet d = seed002();
  for (int axis : {kX, kY, kZ, kA, kC}) {
    for (const bool limited : {false, true}) {
      DriveParams p = d.axes[static_cast<std::size_t>(axis)];
      if (!limited) p.torque_limit = 0;
      std::vector<double> cmd(3000, 0.0);
      for (std::size_t k = 0; k < cmd.size(); ++k) {
        const double t = static_cast<double>(k) * kT;
        cmd[k] = t < 0.3 ? 0.0 : t < 0.8 ? 40 * (t - 0.3) : t < 1.5 ? 20.0 : t < 1.6 ? 20.0 + 1e-7 * static_cast<double>(k % 3)
                 : t < 2.2 ? 20.0 + 1e-4 : t < 2.4 ? 20.0 + 2000 * (t - 2.2) * (t - 2.2) : cmd[k - 1];
      }
      AxisDrive repeating(p, kT, 8, 0.9), working(p, kT, 8, 0.9);
      working.repeat_rests(false);
      const auto w = static_cast<std::size_t>(repeating.window());
      repeating.reset(cmd[0]), working.reset(cmd[0]);
      for (std::size_t k = 0; k + w <= cmd.size(); ++k) {
        const AxisState a = repeating.step(std::span<const double>(cmd.data() + k, w));
        const AxisState b = working.step(std::span<const double>(cmd.data() + k, w));
        ASSERT_EQ(std::bit_cast<std::uint64_t>(a.position), std::bit_cast<std::uint64_t>(b.position)) << axis << " " << k;
        ASSERT_EQ(std::bit_cast<std::uint64_t>(a.velocity), std::bit_cast<std::uint64_t>(b.velocity)) << axis << " " << k;
        ASSERT_EQ(std::bit_cast<std::uint64_t>(a.torque), std::bit_cast<std::uint64_t>(b.torque)) << axis << " " << k;
        ASSERT_EQ(a.saturated, b.saturated) << axis << " " << k;
      }
    }
  }
}

// With the torque limit active the model is nonlinear; the sub-stepped RK4 solution must still
// converge (checked against 256 sub-steps), and at 1 ms the exact-step/RK4 switch must agree
// with an all-RK4 run.
TEST(ServoDiscretisation, SaturatedRunConvergesWithSubsteps) {
  DriveParams c = seed002().axes[kC];
  std::vector<double> cmd(1500);
  double y = 0;
  const double a = std::exp(-kT / c.Ts);
  for (std::size_t k = 0; k < cmd.size(); ++k) {  // 12 rad/s step through exponential smoothing
    y = a * y + (1 - a) * 12.0 * static_cast<double>(k) * kT * 180 / kPi;
    cmd[k] = y;
  }
  AxisDrive fine(c, kT, 256, 0.9);
  fine.force_rk4(true);
  std::vector<double> tq;
  const auto ref = run(fine, cmd, &tq);
  double peak = 0;
  for (double t : tq) peak = std::max(peak, std::abs(t));
  EXPECT_NEAR(peak, 725, 1e-9);  // the limit is reached
  double prev = 0;
  std::printf("saturated C:");
  for (int n : {2, 4, 8, 16, 32}) {
    AxisDrive rk(c, kT, n, 0.9);
    const auto got = run(rk, cmd);  // mixed exact / RK4 path as in production
    double err = 0;
    for (std::size_t i = 0; i < got.size(); ++i) err = std::max(err, std::abs(got[i] - ref[i]));
    std::printf("  N=%d max err %.3e deg", n, err);
    if (n > 2) EXPECT_LT(err, prev) << n;
    prev = err;
  }
  std::printf("\n");
  EXPECT_LT(prev, 1e-5);
}

TEST(ServoSimulatorStream, EveryPushedCommandComesOutOnceInOrder) {
  const DriveSet d = seed002();
  ServoSimulator sim(d, kT);
  const Axes start{13, 0, 0, 0, 0};
  const ServoSample first = sim.reset(start, 0);
  EXPECT_EQ(first.actual, start);
  std::vector<ServoSample> out;
  ServoSample s;
  const int n = 500;
  for (int k = 1; k <= n; ++k) {
    Axes c = start;
    c[kX] += 0.01 * k;
    c[kC] += 0.1 * k;
    if (sim.push(c, s)) out.push_back(s);
  }
  while (sim.flush(s)) out.push_back(s);
  ASSERT_EQ(out.size(), static_cast<std::size_t>(n));
  for (int k = 1; k <= n; ++k) {
    EXPECT_NEAR(out[static_cast<std::size_t>(k - 1)].t, k * kT, 1e-12);
    EXPECT_NEAR(out[static_cast<std::size_t>(k - 1)].command[kX], 13 + 0.01 * k, 1e-12);
  }
  EXPECT_EQ(out.back().actual[kZ], 0.0);  // ideal axis
}

// Backlash is a play operator: approaching a position from below leaves the table half a gap
// short, from above half a gap beyond; the difference is the configured width.
TEST(ServoEffects, BacklashHysteresisEqualsWidth) {
  DriveParams p = seed002().axes[kY];
  p.Kvi = 0;
  // Without feed-forward the Y loop is overdamped (zeta ~ 2), so the motor never overshoots and
  // the approach direction is the commanded one; with K_FFP = 100 % it overshoots by more than
  // the gap at the end of the ramp and the table ends on the other side.
  p.K_FFP = 0;
  const double width = 0.004;  // mm
  p.effects.push_back({"backlash", {{"width", width}}});
  AxisDrive d(p, kT, 8, 0.9);
  std::vector<double> cmd;
  for (int k = 0; k < 1500; ++k) cmd.push_back(std::min(1.0, k * 0.002));       // up to 1 mm
  for (int k = 0; k < 1500; ++k) cmd.push_back(std::max(0.5, 1.0 - k * 0.002)); // down to 0.5
  const auto out = run(d, cmd);
  const double up = out[1400], down = out.back();
  EXPECT_NEAR(up, 1.0 - width / 2, 1e-6);
  EXPECT_NEAR(down, 0.5 + width / 2, 1e-6);
  // Without the effect the same axis lands on the commands.
  p.effects.clear();
  AxisDrive clean(p, kT, 8, 0.9);
  const auto ref = run(clean, cmd);
  EXPECT_NEAR(ref[1400], 1.0, 1e-6);
  EXPECT_NEAR(ref.back(), 0.5, 1e-6);
}

// Coulomb friction at constant speed: the velocity loop must supply T_f more torque, so (with the
// integrator off) the following error grows by T_f / (Kvp Kpp) motor radians.
TEST(ServoEffects, CoulombFrictionAddsTheAnalyticFollowingError) {
  DriveParams p = seed002().axes[kX];
  p.Kvi = 0;
  const double tf = 3.0;  // N*m
  const double v = 50.0;  // mm/s
  std::vector<double> cmd;
  for (int k = 0; k < 3000; ++k) cmd.push_back(v * k * kT);
  AxisDrive clean(p, kT, 8, 0.9);
  const auto a = run(clean, cmd);
  p.effects.push_back({"coulomb_friction", {{"torque", tf}, {"velocity_band", 0.01}}});
  AxisDrive rough(p, kT, 8, 0.9);
  const auto b = run(rough, cmd);
  const double extra = a[2500] - b[2500];
  const double expected = tf / (p.Kvp * p.Kpp) * p.load_per_motor_rad();
  std::printf("friction: extra following error %.6f um, analytic %.6f um\n", extra * 1e3, expected * 1e3);
  EXPECT_NEAR(extra, expected, 0.01 * expected);
  // At standstill after a stop the friction leaves a position error that Kpp*Kvp cannot remove
  // without the integrator: |e| <= T_f / (Kvp Kpp).
  std::vector<double> stop(cmd.begin(), cmd.begin() + 1000);
  for (int k = 0; k < 2000; ++k) stop.push_back(stop.back());
  AxisDrive rough2(p, kT, 8, 0.9);
  const auto c = run(rough2, stop);
  EXPECT_LE(std::abs(c.back() - stop.back()), expected * 1.01);
}

TEST(ServoEffects, OffsetAndLeadErrorShapeThePositionChain) {
  DriveParams p = seed002().axes[kX];
  p.effects.push_back({"offset", {{"value", 0.002}}});
  p.effects.push_back({"lead_error", {{"amplitude", 0.001}, {"period", 16.0}, {"phase", 0.0}}});
  AxisDrive d(p, kT, 8, 0.9);
  std::vector<double> cmd(400, 4.0);  // rest at 4 mm: a quarter of the 16 mm error period
  const auto out = run(d, cmd);
  // Chain order: offset first, then lead error of the offset position.
  const double x = 4.0 + 0.002;
  EXPECT_NEAR(out.back(), x + 0.001 * std::sin(2 * kPi * x / 16.0), 1e-9);
}

// A feedback delay d in the position loop: the closed loop becomes
// Gv (Kpp + H) / (s + Kpp Gv e^{-s d}); the loop samples feedback once per sub-step h, which adds
// h/2 of delay. The simulated sinusoid gain must match that response.
TEST(ServoEffects, FeedbackDelayMatchesDelayedLoopResponse) {
  DriveParams p = seed002().axes[kY];
  p.K_FFP = 0;
  const double delay = 0.004;
  const int sub = 8;
  p.effects.push_back({"feedback_delay", {{"delay", delay}}});
  AxisDrive d(p, kT, sub, 0.9);
  const double w = 30.0, amp = 1.0;
  std::vector<double> cmd;
  for (int k = 0; k < 4000; ++k) cmd.push_back(amp * std::sin(w * k * kT));
  const auto out = run(d, cmd);
  double peak = 0;
  for (std::size_t k = 3000; k < out.size(); ++k) peak = std::max(peak, std::abs(out[k]));
  const std::complex<double> s(0, w);
  const double Jt = p.J + p.J1;
  const std::complex<double> Kc = p.Kvp + p.Kvi / s;
  const std::complex<double> Gv = Kc / (Jt * s + p.C + Kc);
  const double de = delay + 0.5 * kT / sub;
  const double g = std::abs(Gv * p.Kpp / (s + p.Kpp * Gv * std::exp(-s * de))) * first_order_hold_gain(w, kT);
  const double g0 = std::abs(drive_response(p, w));
  std::printf("feedback delay: simulated gain %.5f, delayed-loop %.5f, no delay %.5f\n", peak / amp, g, g0);
  EXPECT_NEAR(peak / amp, g, 2e-3);
  EXPECT_GT(std::abs(g - g0), 10 * 2e-3);  // the effect is visible at this tolerance
}

// A negative Tp: the feed-forward reads the command velocity |Tp| in the past (a drive that
// averages its feed-forward without look-ahead). The simulated steady-state response to a sine,
// amplitude and phase, must equal the continuous model's K_FFP e^{s Tp} s / (1 + Ta s) branch
// (drive_response, a second formulation) times the linear join's sinc^2; whole and fractional
// periods of lag, exact step and RK4.
TEST(ServoFeedForward, NegativeTpLagsTheFeedForwardLikeTheTransferFunction) {
  for (const double Tp : {-0.003, -0.0047, 0.0047}) {
    for (const bool rk4 : {false, true}) {
      DriveParams p = seed002().axes[kY];
      p.torque_limit = 0;
      p.Tp = Tp;
      p.Ta = 0.002;
      AxisDrive d(p, kT, 8, 0.9);
      d.force_rk4(rk4);
      const double w = 40.0, amp = 1.0;
      std::vector<double> cmd;
      for (int k = 0; k < 4000; ++k) cmd.push_back(amp * std::sin(w * k * kT));
      const auto out = run(d, cmd);
      // Steady-state phasor of the output over whole cycles from 2 s on (sample k is the position
      // at t = (k + 1) T).
      std::complex<double> acc = 0;
      std::size_t n = 0;
      const auto cycle = static_cast<std::size_t>(std::lround(2 * kPi / w / kT * 5));  // ~5 cycles
      for (std::size_t k = 2000; k < 2000 + cycle && k < out.size(); ++k, ++n) {
        const double t = static_cast<double>(k + 1) * kT;
        acc += out[k] * std::exp(std::complex<double>(0, -w * t));
      }
      const std::complex<double> sim = 2.0 * acc / static_cast<double>(n) * std::complex<double>(0, 1) / amp;
      const std::complex<double> model = drive_response(p, w) * first_order_hold_gain(w, kT);
      DriveParams none = p;
      none.Tp = 0;
      const std::complex<double> at_zero = drive_response(none, w) * first_order_hold_gain(w, kT);
      std::printf("Tp %+.4f s %s: simulated %.5f%+.5fi, transfer function %.5f%+.5fi (Tp = 0: %.5f%+.5fi)\n", Tp,
                  rk4 ? "RK4  " : "exact", sim.real(), sim.imag(), model.real(), model.imag(), at_zero.real(), at_zero.imag());
      EXPECT_LT(std::abs(sim - model), 2e-3) << Tp;
      EXPECT_GT(std::abs(model - at_zero), 10 * 2e-3) << Tp;  // the lag is visible at this tolerance
    }
  }
}

// A lagging feed-forward lives in the drive's own history: a copy carries it, reset clears it.
TEST(ServoFeedForward, NegativeTpHistoryIsCopiedAndReset) {
  DriveParams p = seed002().axes[kY];
  p.Tp = -0.0047;
  AxisDrive a(p, kT, 8, 0.9);
  const auto cmd = test_command(5.0, 2 * kPi, 1200);
  a.reset(cmd[0]);
  for (std::size_t k = 0; k + 2 <= 600; ++k) a.step(std::span<const double>(cmd.data() + k, 2));
  AxisDrive b = a;
  for (std::size_t k = 600; k + 2 <= cmd.size(); ++k) {
    const AxisState x = a.step(std::span<const double>(cmd.data() + k, 2));
    const AxisState y = b.step(std::span<const double>(cmd.data() + k, 2));
    ASSERT_EQ(x.position, y.position) << k;
  }
  AxisDrive fresh(p, kT, 8, 0.9);
  EXPECT_EQ(run(a, cmd), run(fresh, cmd));
  EXPECT_EQ(a.window(), 2);
}

// Every drives file, and the servo/interpolate sections of every pipeline config that has them.
#include <filesystem>

#include "gcpipe/pipeline_config.hpp"
#include "interpolate.hpp"

TEST(ServoConfig, EveryShippedDrivesFileAndServoSectionLoads) {
  namespace fs = std::filesystem;
  const fs::path root = fs::path(GCPIPE_SOURCE_DIR) / "pipeline_configs";
  int drives = 0, pipelines = 0;
  for (const auto& e : fs::directory_iterator(root / "drives")) {
    if (e.path().extension() != ".yaml") continue;
    EXPECT_NO_THROW(load_drives(Config::load_file(e.path()))) << e.path();
    ++drives;
  }
  for (const auto& e : fs::directory_iterator(root)) {
    if (e.path().extension() != ".yaml") continue;
    const PipelineConfig pc = load_pipeline_config(e.path());
    if (!pc.root.has("servo")) continue;
    const Config s = pc.root.section("servo");
    EXPECT_NO_THROW(load_drives(Config::load_file(s.resolve(s.string("drives", ""))))) << e.path();
    EXPECT_NO_THROW(interpolate::load_interpolate_options(pc.root.section("interpolate"))) << e.path();
    ++pipelines;
  }
  EXPECT_GE(drives, 1);
  EXPECT_GE(pipelines, 1);
}
