// Tests of the second machine simulator (tests/unseen_machine): each compares it with something
// it does not compute itself: closed-loop transfer functions derived here (two formulations:
// polynomial residues and block-diagram state space), exact effect formulas, a smaller sub-step,
// the two-mass resonance formula and eigenvalues of the continuous closed loop.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <ctime>
#include <numbers>
#include <vector>

#include "unseen_machine/unseen_machine.hpp"

namespace {

using gcpipe::unseen::AxisMachine;
using gcpipe::unseen::AxisRun;
using gcpipe::unseen::Structure;
using cd = std::complex<double>;
constexpr double kPi = std::numbers::pi;
constexpr double kT = 1e-3;  // command period [s]

// ---- polynomials, ascending coefficients -------------------------------------------------------
using Poly = std::vector<double>;
cd eval(const Poly& p, cd s) {
  cd v = 0;
  for (auto it = p.rbegin(); it != p.rend(); ++it) v = v * s + *it;
  return v;
}
Poly derivative(const Poly& p) {
  Poly d;
  for (std::size_t i = 1; i < p.size(); ++i) d.push_back(static_cast<double>(i) * p[i]);
  return d;
}
Poly mul(const Poly& a, const Poly& b) {
  Poly r(a.size() + b.size() - 1, 0.0);
  for (std::size_t i = 0; i < a.size(); ++i)
    for (std::size_t j = 0; j < b.size(); ++j) r[i + j] += a[i] * b[j];
  return r;
}
std::vector<cd> roots(const Poly& p) {  // companion matrix
  const int n = static_cast<int>(p.size()) - 1;
  Eigen::MatrixXd C = Eigen::MatrixXd::Zero(n, n);
  for (int i = 1; i < n; ++i) C(i, i - 1) = 1;
  for (int i = 0; i < n; ++i) C(i, n - 1) = -p[i] / p[n];
  Eigen::VectorXcd e = C.eigenvalues();
  return {e.data(), e.data() + n};
}

// Rigid cascade, continuous time, ideal feed-forward (n = 1):
//   J s^2 th + c s th = (Kv + Ki/s) (Kp (th_r - th) + kff s th_r - s th)
//   H(s) = th/th_r = (Kv s + Ki)(Kp + kff s) / (J s^3 + (c + Kv) s^2 + (Kv Kp + Ki) s + Ki Kp)
struct Tf {
  Poly num, den;
};
// Without integral action (Ki = 0) numerator and denominator share a factor s, cancelled here.
Tf cascade_tf(const AxisMachine& m) {
  Tf tf{mul({m.Ki, m.Kv}, {m.Kp, m.kff}), {m.Ki * m.Kp, m.Kv * m.Kp + m.Ki, m.c + m.Kv, m.J}};
  if (m.Ki == 0) {
    tf.num.erase(tf.num.begin());
    tf.den.erase(tf.den.begin());
  }
  return tf;
}

// Response to a unit ramp starting at t = 0 (zero for t < 0), by residues of N/(D s^2):
//   r(t) = H(0) t + H'(0) + sum_p N(p) / (p^2 D'(p)) e^{p t}   (distinct, non-zero poles)
double ramp_response(const Tf& tf, double t) {
  if (t <= 0) return 0;
  const double N0 = tf.num[0], D0 = tf.den[0];
  const double N1 = tf.num.size() > 1 ? tf.num[1] : 0, D1 = tf.den[1];
  double r = N0 / D0 * t + (N1 * D0 - N0 * D1) / (D0 * D0);
  const Poly dD = derivative(tf.den);
  for (const cd p : roots(tf.den)) r += (eval(tf.num, p) / (p * p * eval(dD, p)) * std::exp(p * t)).real();
  return r;
}

// The same loop as a block-diagram state space, states [theta, w, I], input theta_r (and its
// derivative through kff): a second formulation of the frequency response.
cd cascade_state_space(const AxisMachine& m, double w) {
  Eigen::Matrix3cd A = Eigen::Matrix3cd::Zero();
  // e = Kp (r - th) + kff r' - w;  th' = w;  J w' = Kv e + Ki I - c w;  I' = e
  A(0, 1) = 1;
  A(1, 0) = -m.Kv * m.Kp / m.J;
  A(1, 1) = -(m.Kv + m.c) / m.J;
  A(1, 2) = m.Ki / m.J;
  A(2, 0) = -m.Kp;
  A(2, 1) = -1;
  const cd s(0, w);
  const cd e_per_r = m.Kp + m.kff * s;  // e's dependence on r
  Eigen::Vector3cd B(0, m.Kv / m.J * e_per_r, e_per_r);
  Eigen::Matrix3cd sI_A = s * Eigen::Matrix3cd::Identity() - A;
  return sI_A.partialPivLu().solve(B)(0);
}

// Amplitude and phase of the fundamental at w over samples [from, to): least squares on
// a sin + b cos + c0.
cd fit_sine(const std::vector<double>& y, double w, std::size_t from, std::size_t to) {
  Eigen::Matrix3d AtA = Eigen::Matrix3d::Zero();
  Eigen::Vector3d Aty = Eigen::Vector3d::Zero();
  for (std::size_t k = from; k < to; ++k) {
    const double t = static_cast<double>(k) * kT;
    const Eigen::Vector3d row(std::sin(w * t), std::cos(w * t), 1);
    AtA += row * row.transpose();
    Aty += row * y[k];
  }
  const Eigen::Vector3d x = AtA.ldlt().solve(Aty);
  return {x(0), x(1)};  // y = |H| sin(wt + phi): a = |H| cos phi, b = |H| sin phi
}

AxisMachine continuous_cascade() {
  AxisMachine m;
  m.structure = Structure::kCascade;
  m.lead = 0.016;
  m.J = 0.005;
  m.c = 0.001;
  m.Kp = 30;
  m.Kv = 0.75;                    // Kv/J = 150 rad/s
  m.Ki = 0.8 * m.Kp * m.Kv;       // corner 24 rad/s, near Kp
  m.control_period = 20e-6;       // continuous-time limit
  return m;
}

std::vector<double> step_command(std::size_t n, double height) {
  std::vector<double> c(n, height);
  c[0] = 0;
  return c;
}
std::vector<double> ramp_command(std::size_t n, double v) {
  std::vector<double> c(n);
  for (std::size_t k = 0; k < n; ++k) c[k] = v * static_cast<double>(k) * kT;
  return c;
}
// 0 -> stroke in `ramp` s, hold, back to 0 in `ramp` s, hold (smooth enough ends: linear).
std::vector<double> ramp_and_back(double stroke, double ramp, double hold) {
  std::vector<double> c;
  const auto nr = static_cast<std::size_t>(ramp / kT), nh = static_cast<std::size_t>(hold / kT);
  for (std::size_t k = 0; k < nr; ++k) c.push_back(stroke * static_cast<double>(k) / nr);
  for (std::size_t k = 0; k < nh; ++k) c.push_back(stroke);
  for (std::size_t k = 0; k < nr; ++k) c.push_back(stroke * (1 - static_cast<double>(k) / nr));
  for (std::size_t k = 0; k < nh; ++k) c.push_back(0);
  return c;
}
double max_abs_diff(const std::vector<double>& a, const std::vector<double>& b) {
  double m = 0;
  for (std::size_t i = 0; i < a.size(); ++i) m = std::max(m, std::abs(a[i] - b[i]));
  return m;
}

// ---- continuous-time limit vs analytic ---------------------------------------------------------

TEST(UnseenMachine, StepMatchesResiduesOfTheClosedLoop) {
  for (double corner : {0.8, 0.0}) {  // with and without integral action
    AxisMachine m = continuous_cascade();
    m.Ki = corner * m.Kp * m.Kv;
    const Tf tf = cascade_tf(m);
    // Self-check of the residue formula: r(0+) = 0.
    EXPECT_NEAR(ramp_response(tf, 1e-12), 0, 1e-9);
    const auto cmd = step_command(600, 1.0);  // 1 mm, reached linearly over the first period
    const AxisRun run = gcpipe::unseen::run_axis(m, cmd, kT);
    double worst = 0;
    for (std::size_t k = 0; k < cmd.size(); ++k) {
      const double t = static_cast<double>(k) * kT;
      const double expected = (ramp_response(tf, t) - ramp_response(tf, t - kT)) / kT;
      worst = std::max(worst, std::abs(run.actual[k] - expected));
    }
    std::printf("step, corner %.1f Kp: max |sim - analytic| = %.3g mm of 1 mm\n", corner, worst);
    EXPECT_LT(worst, 2e-3) << m.describe();
  }
}

TEST(UnseenMachine, RampFollowingErrorMatchesFinalValueTheorem) {
  // E(s)/R(s) = 1 - H(s). Ramp v/s^2: e_ss = lim s->0 (1 - H(s)) v / s:
  //   Ki > 0, kff = 0: numerator of 1-H is J s^3 + (c+Kv) s^2 + Ki s  ->  e_ss = v / Kp
  //     (the velocity integrator cancels the viscous torque; the position loop stays type 1);
  //   Ki = 0, kff = 0: (J s + c + Kv) / (Kv Kp)                         ->  e_ss = v/Kp (1 + c/Kv)
  //   Ki > 0, kff:     numerator J s^3 + (c + Kv(1-kff)) s^2 + Ki(1-kff) s -> e_ss = (1-kff) v/Kp
  //     (kff = 1: type 2, zero ramp error). Steady state of the SAMPLED loop too: w = v, tau = c v,
  //     e_v = 0, so Kp e_p = (1 - kff) v at every tick; checked with Tc = 0.5 ms as well.
  const double v = 100;  // mm/s
  struct Case {
    double corner, kff, Tff, Tc, c;
  };
  for (const Case cs : {Case{0.8, 0, 0, 20e-6, 0.15}, Case{0, 0, 0, 20e-6, 0.15},
                        Case{0.8, 1, 0, 20e-6, 0.15}, Case{0.8, 0.6, 8e-3, 0.5e-3, 0.15},
                        Case{0.8, 1, 5e-3, 0.25e-3, 0.15}}) {
    AxisMachine m = continuous_cascade();
    m.Ki = cs.corner * m.Kp * m.Kv;
    m.kff = cs.kff;
    m.Tff = cs.Tff;
    m.control_period = cs.Tc;
    m.c = cs.c;
    const double expected =
        cs.corner > 0 ? (1 - cs.kff) * v / m.Kp : v / m.Kp * (1 + m.c / m.Kv);
    const auto cmd = ramp_command(3000, v);
    const AxisRun run = gcpipe::unseen::run_axis(m, cmd, kT);
    const double err = cmd.back() - run.actual.back();
    std::printf("ramp %g mm/s: error %.6f mm, expected %.6f (%s)\n", v, err, expected, m.describe().c_str());
    EXPECT_NEAR(err, expected, 1e-4 * v / m.Kp + 1e-9) << m.describe();
  }
}

TEST(UnseenMachine, FrequencyResponseMatchesStateSpace) {
  AxisMachine m = continuous_cascade();
  m.kff = 0.5;
  for (double f : {1.0, 5.0, 15.0, 30.0}) {
    const double w = 2 * kPi * f;
    const cd Hss = cascade_state_space(m, w);
    const Tf tf = cascade_tf(m);
    const cd Hpoly = eval(tf.num, cd(0, w)) / eval(tf.den, cd(0, w));
    EXPECT_LT(std::abs(Hss - Hpoly), 1e-9 * std::abs(Hss)) << "the two derivations disagree at " << f;
    // Settle 1 s, then fit over a whole number of periods (>= 0.5 s).
    const auto periods = static_cast<std::size_t>(std::ceil(0.5 * f));
    const auto n_fit = static_cast<std::size_t>(std::lround(periods / f / kT));
    std::vector<double> cmd(1000 + n_fit);
    for (std::size_t k = 0; k < cmd.size(); ++k) cmd[k] = std::sin(w * static_cast<double>(k) * kT);
    const AxisRun run = gcpipe::unseen::run_axis(m, cmd, kT);
    const cd Hsim = fit_sine(run.actual, w, 1000, cmd.size());
    std::printf("%5.1f Hz: |H| sim %.5f analytic %.5f, phase sim %.5f analytic %.5f rad\n", f,
                std::abs(Hsim), std::abs(Hss), std::arg(Hsim), std::arg(Hss));
    EXPECT_NEAR(std::abs(Hsim) / std::abs(Hss), 1, 0.02) << f << " Hz";
    EXPECT_NEAR(std::arg(Hsim / Hss), 0, 0.02) << f << " Hz";  // rad
  }
}

// ---- numerics ----------------------------------------------------------------------------------

TEST(UnseenMachine, HalvingTheSubstepConvergesAtSecondOrder) {
  AxisMachine m;
  m.structure = Structure::kTwoMass;
  m.lead = 0.016;
  m.Jm = 0.004;
  m.Jt = 0.006;
  m.k = std::pow(2 * kPi * 80, 2) * (m.Jm * m.Jt / (m.Jm + m.Jt));
  m.d = 0.05 * 2 * std::sqrt(m.k * m.Jm * m.Jt / (m.Jm + m.Jt));
  m.c = 0.002;
  m.Kp = 40;
  m.Kv = 1.5;
  m.Ki = 0.7 * m.Kp * m.Kv;
  m.kff = 0.8;
  m.Tff = 4e-3;
  m.control_period = 0.5e-3;
  m.coulomb = 0.05;
  m.cogging = 0.02;
  m.cogging_order = 12;
  const auto cmd = ramp_and_back(20, 0.4, 0.3);
  std::vector<std::vector<double>> out;
  for (double h : {50e-6, 25e-6, 12.5e-6, 6.25e-6}) {
    m.substep = h;
    EXPECT_NEAR(gcpipe::unseen::integration_substep(m), h, 1e-15);
    out.push_back(gcpipe::unseen::run_axis(m, cmd, kT).actual);
  }
  const double d1 = max_abs_diff(out[0], out[1]), d2 = max_abs_diff(out[1], out[2]),
               d3 = max_abs_diff(out[2], out[3]);
  std::printf("max change on halving h: 50->25 us %.3g mm, 25->12.5 %.3g, 12.5->6.25 %.3g (ratios %.2f %.2f)\n",
              d1, d2, d3, d1 / d2, d2 / d3);
  EXPECT_LT(d1, 1e-4);  // mm, on a 20 mm move: the default 50 us is converged to 0.1 um
  EXPECT_GT(d1 / d2, 3.0);  // second order: ratio 4
  EXPECT_GT(d2 / d3, 3.0);
}

// ---- effects -----------------------------------------------------------------------------------

AxisMachine digital_cascade() {
  AxisMachine m = continuous_cascade();
  m.control_period = 0.25e-3;
  m.kff = 0.7;
  m.Tff = 3e-3;
  return m;
}

TEST(UnseenMachine, BacklashReversalJumpsByTheWidth) {
  AxisMachine m = digital_cascade();
  const auto cmd = ramp_and_back(10, 1.0, 0.5);
  const AxisRun clean = gcpipe::unseen::run_axis(m, cmd, kT);
  m.backlash = 0.02;
  const AxisRun play = gcpipe::unseen::run_axis(m, cmd, kT);
  // Play centred at rest; after the first 10 um of travel the table lags by w/2, after the
  // reversal it leads by w/2: the difference to the clean run swings by exactly w.
  const double before = play.actual[1400] - clean.actual[1400];   // holding at 10 mm
  const double after = play.actual[2900] - clean.actual[2900];    // back at 0
  EXPECT_NEAR(before, -0.01, 1e-12);
  EXPECT_NEAR(after, 0.01, 1e-12);
  EXPECT_NEAR(after - before, m.backlash, 1e-12);
  // The loop does not see the play: the torque is the same.
  EXPECT_LT(max_abs_diff(clean.torque, play.torque), 1e-12);
}

TEST(UnseenMachine, ScaleLeadAndDriftAreExactFormulasOfThePosition) {
  AxisMachine m = digital_cascade();
  const auto cmd = ramp_and_back(50, 1.0, 0.5);
  const AxisRun clean = gcpipe::unseen::run_axis(m, cmd, kT);
  AxisMachine e = m;
  e.scale_ppm = 35;
  e.lead_amp = 0.004;
  e.lead_period = 16;
  e.lead_phase = 0.7;
  e.drift_rate = 0.002;
  e.drift_onset = 0.8;
  const AxisRun run = gcpipe::unseen::run_axis(e, cmd, kT);
  double worst = 0;
  for (std::size_t k = 0; k < cmd.size(); ++k) {
    const double x = clean.actual[k], t = static_cast<double>(k) * kT;
    const double expected = x + 35e-6 * x + 0.004 * std::sin(2 * kPi * x / 16 + 0.7) +
                            (t > 0.8 ? 0.002 * (t - 0.8) : 0.0);
    worst = std::max(worst, std::abs(run.actual[k] - expected));
  }
  EXPECT_LT(worst, 1e-12);
}

TEST(UnseenMachine, MeasurementDelayShiftsTheOutput) {
  AxisMachine m = digital_cascade();
  const auto cmd = ramp_and_back(10, 0.5, 0.2);
  const AxisRun clean = gcpipe::unseen::run_axis(m, cmd, kT);
  m.measurement_delay = 3e-3;  // whole periods: an exact shift
  const AxisRun late = gcpipe::unseen::run_axis(m, cmd, kT);
  for (std::size_t k = 0; k < cmd.size(); ++k)
    ASSERT_NEAR(late.actual[k], clean.actual[k >= 3 ? k - 3 : 0], 1e-12) << k;
  EXPECT_LT(max_abs_diff(late.torque, clean.torque), 1e-12);
  // Between samples: the same machine logged every 10 us (the command joined linearly either way,
  // and n = 1 feed-forward is its exact slope, so the trajectory is the same) gives the judge.
  m.Tff = 0;
  m.measurement_delay = 0;
  std::vector<double> fine_cmd((cmd.size() - 1) * 100 + 1);
  for (std::size_t i = 0; i < fine_cmd.size(); ++i) {
    const std::size_t k = i / 100;
    const double f = static_cast<double>(i % 100) / 100;
    fine_cmd[i] = k + 1 < cmd.size() ? cmd[k] + f * (cmd[k + 1] - cmd[k]) : cmd[k];
  }
  const AxisRun fine = gcpipe::unseen::run_axis(m, fine_cmd, kT / 100);
  m.measurement_delay = 1.37e-3;
  const AxisRun frac = gcpipe::unseen::run_axis(m, cmd, kT);
  double worst = 0;
  for (std::size_t k = 2; k < cmd.size(); ++k)
    worst = std::max(worst, std::abs(frac.actual[k] - fine.actual[100 * k - 137]));
  std::printf("delay 1.37 ms: max |sim - (10 us run, shifted)| = %.3g mm\n", worst);
  EXPECT_LT(worst, 1e-10);
}

TEST(UnseenMachine, CoggingIsATorqueRippleTheLoopSupplies) {
  // At constant speed the motor turns at w = v/g rad/s; cogging T_c sin(n theta) is a torque
  // ripple at n w, well below the velocity loop's 150 rad/s here, so the controller supplies it:
  // the motor torque carries a ripple of about T_c at that frequency (the clean run: none).
  AxisMachine m = digital_cascade();
  const double v = 5;  // mm/s
  const auto cmd = ramp_command(6000, v);
  const double g = gcpipe::unseen::load_per_motor_rad(m);
  EXPECT_NEAR(g, 16.0 / (2 * kPi), 1e-12);  // mm per motor rad, lead 16 mm
  const double w = 6 * v / g;                // rad/s of the ripple, order 6
  const AxisRun clean = gcpipe::unseen::run_axis(m, cmd, kT);
  m.cogging = 0.05;
  m.cogging_order = 6;
  const AxisRun cog = gcpipe::unseen::run_axis(m, cmd, kT);
  std::vector<double> ripple(cmd.size());
  for (std::size_t k = 0; k < cmd.size(); ++k) ripple[k] = cog.torque[k] - clean.torque[k];
  const auto n_fit = static_cast<std::size_t>(std::lround(std::floor(4.0 * w / (2 * kPi)) * 2 * kPi / w / kT));
  const double amp = std::abs(fit_sine(ripple, w, cmd.size() - n_fit, cmd.size()));
  std::printf("cogging 0.05 N*m order 6: torque ripple %.4f N*m at %.2f Hz\n", amp, w / (2 * kPi));
  EXPECT_NEAR(amp / 0.05, 1, 0.05);
}

TEST(UnseenMachine, TorqueLimitHoldsAndTheLoopSettles) {
  AxisMachine m = digital_cascade();
  m.kff = 0;
  std::vector<double> cmd(1500, 10.0);
  for (std::size_t k = 0; k < 200; ++k) cmd[k] = 0.05 * static_cast<double>(k);  // 50 mm/s to 10 mm
  auto overshoot = [&](const AxisRun& r) { return *std::max_element(r.actual.begin(), r.actual.end()) - 10; };
  const AxisRun free_run = gcpipe::unseen::run_axis(m, cmd, kT);
  m.torque_limit = 1.0;  // N*m; the start of the ramp asks for more (about 0.1 s at the limit)
  const AxisRun run = gcpipe::unseen::run_axis(m, cmd, kT);
  double peak_torque = 0;
  for (double t : run.torque) peak_torque = std::max(peak_torque, std::abs(t));
  EXPECT_LE(peak_torque, 1.0 + 1e-12);
  EXPECT_GE(peak_torque, 1.0 - 1e-12);  // it did saturate
  EXPECT_NEAR(run.actual.back(), 10, 1e-4);
  std::printf("50 mm/s ramp to 10 mm: overshoot %.3f mm unlimited, %.3f mm at a 1 N*m limit\n",
              overshoot(free_run), overshoot(run));
  // The P position loop itself has no anti-windup, so saturation adds overshoot (the time lost at
  // the limit is a position error Kp turns into speed); the frozen integrator keeps it bounded.
  EXPECT_LT(overshoot(run), 0.15 * 10);
}

// ---- two-mass --------------------------------------------------------------------------------

double zero_crossing_frequency(const std::vector<double>& s, std::size_t from, std::size_t to) {
  std::vector<double> t;
  for (std::size_t k = from + 1; k < to; ++k)
    if ((s[k - 1] < 0) != (s[k] < 0)) t.push_back((k - 1 + s[k - 1] / (s[k - 1] - s[k])) * kT);
  if (t.size() < 3) return 0;
  return static_cast<double>(t.size() - 1) / (2 * (t.back() - t.front()));
}

TEST(UnseenMachine, TwoMassRingsAtItsResonance) {
  AxisMachine m;
  m.structure = Structure::kTwoMass;
  m.Jm = 0.01;
  m.Jt = 0.01;
  const double mu = m.Jm * m.Jt / (m.Jm + m.Jt), f_res = 60;
  m.k = std::pow(2 * kPi * f_res, 2) * mu;
  m.d = 2 * 0.01 * std::sqrt(m.k * mu);
  m.c = 0.001;
  m.Kp = 3;       // weak controller: the ringing is the free-free mode
  m.Kv = 0.2;     // Kv/J = 10 rad/s
  m.Ki = 0.5 * m.Kp * m.Kv;
  m.control_period = 50e-6;
  AxisMachine rigid = m;
  rigid.structure = Structure::kCascade;
  rigid.J = m.Jm + m.Jt;
  const auto cmd = step_command(500, 1.0);
  const AxisRun a = gcpipe::unseen::run_axis(m, cmd, kT);
  const AxisRun b = gcpipe::unseen::run_axis(rigid, cmd, kT);
  // Ringing = two-mass minus rigid (removes the slow response), second difference (acceleration,
  // weights the 60 Hz mode by (wT)^2 over the slow remainder).
  std::vector<double> acc(cmd.size(), 0.0);
  for (std::size_t k = 1; k + 1 < cmd.size(); ++k)
    acc[k] = (a.actual[k + 1] - b.actual[k + 1]) - 2 * (a.actual[k] - b.actual[k]) +
             (a.actual[k - 1] - b.actual[k - 1]);
  const double f = zero_crossing_frequency(acc, 10, 400);

  // The continuous closed loop [th_m, w_m, th_t, w_t, I], position loop on the table:
  Eigen::Matrix<double, 5, 5> A = Eigen::Matrix<double, 5, 5>::Zero();
  A(0, 1) = 1;
  A(2, 3) = 1;
  // e = -Kp th_t - w_m; tau = Kv e + Ki I
  A(1, 0) = -m.k / m.Jm;
  A(1, 1) = (-m.Kv - m.c - m.d) / m.Jm;
  A(1, 2) = (m.k - m.Kv * m.Kp) / m.Jm;
  A(1, 3) = m.d / m.Jm;
  A(1, 4) = m.Ki / m.Jm;
  A(3, 0) = m.k / m.Jt;
  A(3, 1) = m.d / m.Jt;
  A(3, 2) = -m.k / m.Jt;
  A(3, 3) = -m.d / m.Jt;
  A(4, 1) = -1;
  A(4, 2) = -m.Kp;
  double f_mode = 0;
  const Eigen::Matrix<cd, 5, 1> poles = A.eigenvalues();
  for (const cd p : poles) f_mode = std::max(f_mode, std::abs(p.imag()) / (2 * kPi));
  const double f_free = std::sqrt(m.k * (1 / m.Jm + 1 / m.Jt)) / (2 * kPi);
  std::printf("ringing %.3f Hz; free-free %.3f Hz; closed-loop mode %.3f Hz\n", f, f_free, f_mode);
  EXPECT_NEAR(f / f_free, 1, 0.05);
  EXPECT_NEAR(f / f_mode, 1, 0.01);
}

// ---- drawn machines ----------------------------------------------------------------------------

struct Base {
  gcpipe::unseen::Seed002Equivalent eq;
  bool rotary;
  double lead;
  double stroke;
};
// pipeline_configs/drives/seed002.yaml: X (ball screw), Y (direct, r = 1), C (rotary, J + J1).
const Base kBases[] = {
    {{60, 177.5, 0.198, 1.0, 4.5, 100}, false, 0.016, 100},
    {{60, 4700, 0.274, 5.0, 5.0, 100}, false, 0, 100},
    {{60, 4700, 0.274, 5.0, 4.2 + 1.7, 100}, true, 0, 90},
};

TEST(UnseenMachine, DrawIsDeterministicAndPinned) {
  for (const Base& b : kBases) {
    const AxisMachine a = gcpipe::unseen::draw_axis(7, b.eq, b.rotary, b.lead);
    const AxisMachine c = gcpipe::unseen::draw_axis(7, b.eq, b.rotary, b.lead);
    EXPECT_DOUBLE_EQ(a.Kp, c.Kp);
    EXPECT_DOUBLE_EQ(a.Kv, c.Kv);
    EXPECT_DOUBLE_EQ(a.Ki, c.Ki);
    EXPECT_DOUBLE_EQ(a.J, c.J);
    EXPECT_DOUBLE_EQ(a.k, c.k);
    EXPECT_DOUBLE_EQ(a.kff, c.kff);
    EXPECT_DOUBLE_EQ(a.measurement_delay, c.measurement_delay);
    EXPECT_EQ(a.structure, c.structure);
    const AxisMachine other = gcpipe::unseen::draw_axis(8, b.eq, b.rotary, b.lead);
    EXPECT_NE(a.J, other.J);
  }
  // Pinned (own uniforms over std::mt19937_64, whose sequence the standard fixes): the same
  // machine on any standard library, up to libm rounding.
  const AxisMachine x = gcpipe::unseen::draw_axis(1, kBases[0].eq, false, 0.016);
  std::printf("seed 1, X: %s\n", x.describe().c_str());
  EXPECT_EQ(x.structure, Structure::kCascade);
  EXPECT_NEAR(x.J, 2.71836479589, 1e-9);
  EXPECT_NEAR(x.Kp, 30.8872399175, 1e-8);
  EXPECT_NEAR(x.kff, 0.470752132490, 1e-11);
  EXPECT_NEAR(x.Tff, 0.010, 1e-15);
  EXPECT_NEAR(x.control_period, 0.5e-3, 1e-18);
  EXPECT_EQ(x.measurement_delay, 0.0);
}

TEST(UnseenMachine, DrawnMachinesRespectRangesAndStayBounded) {
  int two_mass = 0, delayed = 0, reduced = 0, total = 0;
  double worst_final = 0;
  for (const Base& b : kBases) {
    // Ramp over 1 s to the stroke, then stop for 1.5 s.
    std::vector<double> cmd(2500, b.stroke);
    for (std::size_t k = 0; k < 1000; ++k) cmd[k] = b.stroke * static_cast<double>(k) / 1000;
    for (std::uint64_t seed = 0; seed < 200; ++seed) {
      const AxisMachine m = gcpipe::unseen::draw_axis(seed, b.eq, b.rotary, b.lead);
      const auto eq = gcpipe::unseen::equivalent(m);
      const std::string what = m.describe();
      ++total;
      EXPECT_GE(eq.J, 0.5 * b.eq.J * (1 - 1e-12)) << what;
      EXPECT_LE(eq.J, 2 * b.eq.J * (1 + 1e-12)) << what;
      EXPECT_GE(eq.C, 0.5 * b.eq.C * (1 - 1e-12)) << what;
      EXPECT_LE(eq.C, 2 * b.eq.C * (1 + 1e-12)) << what;
      EXPECT_GT(eq.Kpp, 0) << what;
      EXPECT_LE(eq.Kpp, 2 * b.eq.Kpp * (1 + 1e-12)) << what;
      EXPECT_GE(eq.Kvp / eq.J, 2 * eq.Kpp * (1 - 1e-9)) << what;
      EXPECT_LE(eq.Kvp / eq.J, 0.5 / m.control_period * (1 + 1e-9)) << what;
      const double corner = eq.Kvi / eq.Kvp / eq.Kpp;
      EXPECT_GE(corner, 0.3 - 1e-9) << what;
      EXPECT_LE(corner, 1.5 + 1e-9) << what;
      EXPECT_GE(eq.K_FFP, 0) << what;
      EXPECT_LE(eq.K_FFP, 100) << what;
      EXPECT_TRUE(m.control_period == 0.25e-3 || m.control_period == 0.5e-3) << what;
      EXPECT_TRUE(m.measurement_delay == 0 || (m.measurement_delay >= 1e-3 && m.measurement_delay <= 4e-3))
          << what;
      EXPECT_GE(m.Tff, 1e-3 - 1e-12) << what;
      EXPECT_LE(m.Tff, 16e-3 + 1e-12) << what;
      if (m.structure == Structure::kTwoMass) {
        ++two_mass;
        const double f = std::sqrt(m.k * (1 / m.Jm + 1 / m.Jt)) / (2 * kPi);
        EXPECT_GE(f, 30 - 1e-9) << what;
        EXPECT_LE(f, 120 + 1e-9) << what;
      }
      if (m.measurement_delay > 0) ++delayed;
      if (eq.Kpp < 0.5 * b.eq.Kpp) ++reduced;
      // Every mode decays at least at 5 1/s (what draw_axis enforces).
      EXPECT_LT(gcpipe::unseen::loop_spectral_radius(m), std::exp(-5 * m.control_period) + 1e-12) << what;
      const AxisRun run = gcpipe::unseen::run_axis(m, cmd, kT);
      double peak = 0;
      for (double y : run.actual) peak = std::max(peak, std::isfinite(y) ? std::abs(y) : 1e300);
      EXPECT_LT(peak, 1.5 * b.stroke) << what;
      const double final_err = std::abs(run.actual.back() - b.stroke);
      worst_final = std::max(worst_final, final_err);
      EXPECT_LT(final_err, 1e-3 * b.stroke) << what;
    }
  }
  std::printf("%d drawn machines: %d two-mass, %d with a measurement delay, %d with Kp below 0.5 x base "
              "(reduced for stability); worst final error %.3g\n",
              total, two_mass, delayed, reduced, worst_final);
  EXPECT_GT(two_mass, total / 4);
  EXPECT_GT(delayed, total / 4);
}

// ---- speed figure (printed, not asserted) -----------------------------------------------------

TEST(UnseenMachine, SpeedFigure) {
  AxisMachine m = continuous_cascade();
  m.control_period = 0.25e-3;
  m.kff = 1;
  m.Tff = 4e-3;
  const auto cmd = ramp_and_back(100, 2.0, 3.0);  // 10 s
  const std::clock_t c0 = std::clock();
  double sink = 0;
  for (int rep = 0; rep < 5; ++rep) sink += gcpipe::unseen::run_axis(m, cmd, kT).actual.back();
  const double cpu = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
  std::printf("kCascade, Tc 0.25 ms, h %.3g us: %.3f ms CPU per second of 1 ms trace (%g)\n",
              gcpipe::unseen::integration_substep(m) * 1e6, cpu / (5 * cmd.size() * kT) * 1e3, sink);
  m.structure = Structure::kTwoMass;
  m.Jm = 0.002;
  m.Jt = 0.003;
  m.k = std::pow(2 * kPi * 80, 2) * 0.0012;
  m.coulomb = 0.05;
  const std::clock_t c1 = std::clock();
  sink = gcpipe::unseen::run_axis(m, cmd, kT).actual.back();
  const double cpu2 = static_cast<double>(std::clock() - c1) / CLOCKS_PER_SEC;
  std::printf("kTwoMass + Coulomb (Newton): %.3f ms CPU per second of trace (%g)\n",
              cpu2 / (cmd.size() * kT) * 1e3, sink);
}

}  // namespace
