// Second machine simulator for tests: equations and choices in unseen_machine.hpp.
#include "unseen_machine/unseen_machine.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <sstream>
#include <stdexcept>

namespace gcpipe::unseen {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kFrictionBand = 0.01;  // rad/s, tanh(w / band)
constexpr double kMaxSubstep = 50e-6;   // s
constexpr double kMinDecay = 5.0;       // 1/s, slowest decay of a drawn machine's closed loop

using Mat4 = Eigen::Matrix4d;
using Vec4 = Eigen::Vector4d;

bool two_mass(const AxisMachine& m) { return m.structure == Structure::kTwoMass; }
double motor_inertia(const AxisMachine& m) { return two_mass(m) ? m.Jm : m.J; }
int feedback_index(const AxisMachine& m) { return two_mass(m) ? 2 : 0; }
bool nonlinear(const AxisMachine& m) { return m.coulomb != 0 || m.cogging != 0; }

void validate(const AxisMachine& m) {
  auto bad = [&](const char* what) {
    throw std::invalid_argument(std::string("unseen machine: ") + what + " (" + m.describe() + ")");
  };
  if (two_mass(m)) {
    if (!(m.Jm > 0) || !(m.Jt > 0)) bad("Jm and Jt must be > 0");
    if (!(m.k > 0) || !(m.d >= 0)) bad("k must be > 0, d >= 0");
  } else if (!(m.J > 0)) {
    bad("J must be > 0");
  }
  if (!(m.c >= 0) || !(m.Kp >= 0) || !(m.Kv >= 0) || !(m.Ki >= 0)) bad("c, Kp, Kv, Ki must be >= 0");
  if (!(m.kff >= 0 && m.kff <= 1)) bad("kff must be in [0, 1]");
  if (!(m.Tff >= 0) || !(m.measurement_delay >= 0) || !(m.torque_limit >= 0)) bad("Tff, delay, limit >= 0");
  if (!(m.control_period > 0)) bad("control_period must be > 0");
  if (!(m.substep >= 0)) bad("substep must be >= 0");
  if (!(m.backlash >= 0)) bad("backlash must be >= 0");
  if (m.lead_amp != 0 && !(m.lead_period > 0)) bad("lead_period must be > 0 with lead_amp");
  if (m.cogging != 0 && m.cogging_order <= 0) bad("cogging_order must be > 0 with cogging");
  if (!m.rotary && m.lead < 0) bad("lead must be >= 0");
}

// Continuous plant dx/dt = A x + B tau (linear part), state [th_m, w_m, th_t, w_t]; kCascade uses
// the first two (the other rows are zero, so the Tustin step leaves them at 0).
void plant(const AxisMachine& m, Mat4& A, Vec4& B) {
  A.setZero();
  B.setZero();
  A(0, 1) = 1;
  if (!two_mass(m)) {
    A(1, 1) = -m.c / m.J;
    B(1) = 1 / m.J;
    return;
  }
  A(1, 0) = -m.k / m.Jm;
  A(1, 1) = -(m.c + m.d) / m.Jm;
  A(1, 2) = m.k / m.Jm;
  A(1, 3) = m.d / m.Jm;
  A(2, 3) = 1;
  A(3, 0) = m.k / m.Jt;
  A(3, 1) = m.d / m.Jt;
  A(3, 2) = -m.k / m.Jt;
  A(3, 3) = -m.d / m.Jt;
  B(1) = 1 / m.Jm;
}

// Nonlinear torque T_nl(theta_m, w_m) opposing the motor and its derivatives.
struct NlTorque {
  double value, d_theta, d_w;
};
NlTorque nl_torque(const AxisMachine& m, double theta, double w) {
  NlTorque t{0, 0, 0};
  if (m.coulomb != 0) {
    const double th = std::tanh(w / kFrictionBand);
    t.value += m.coulomb * th;
    t.d_w += m.coulomb * (1 - th * th) / kFrictionBand;
  }
  if (m.cogging != 0) {
    const double n = m.cogging_order;
    t.value += m.cogging * std::sin(n * theta);
    t.d_theta += m.cogging * n * std::cos(n * theta);
  }
  return t;
}

struct Substeps {
  int per_tick;
  double h;
};
Substeps substeps(const AxisMachine& m) {
  Mat4 A;
  Vec4 B;
  plant(m, A, B);
  double rate = A.eigenvalues().cwiseAbs().maxCoeff();
  const double Jmot = motor_inertia(m);
  rate = std::max(rate, std::abs(m.coulomb) / (kFrictionBand * Jmot));
  if (m.cogging != 0) rate = std::max(rate, std::sqrt(m.cogging_order * std::abs(m.cogging) / Jmot));
  double hmax = m.substep > 0 ? m.substep : kMaxSubstep;
  if (rate > 0) hmax = std::min(hmax, 0.1 / rate);
  const int n = std::max(1, static_cast<int>(std::ceil(m.control_period / hmax - 1e-9)));
  return {n, m.control_period / n};
}

// Play element (dead band of width w), starts centred.
struct Play {
  double w, out;
  double operator()(double in) {
    if (in - out > w / 2) out = in - w / 2;
    else if (in - out < -w / 2) out = in + w / 2;
    return out;
  }
};

std::uint64_t bits(std::mt19937_64& rng) { return rng(); }
double uniform(std::mt19937_64& rng, double lo, double hi) {
  const double u = static_cast<double>(bits(rng) >> 11) * 0x1.0p-53;  // [0, 1)
  return lo + (hi - lo) * u;
}
double log_uniform(std::mt19937_64& rng, double lo, double hi) {
  return lo * std::exp(uniform(rng, 0, 1) * std::log(hi / lo));
}

}  // namespace

std::string AxisMachine::describe() const {
  std::ostringstream o;
  o.precision(6);
  o << (structure == Structure::kTwoMass ? "two-mass" : "cascade") << (rotary ? " rotary" : " linear")
    << " lead=" << lead;
  if (structure == Structure::kTwoMass) o << " Jm=" << Jm << " Jt=" << Jt << " k=" << k << " d=" << d;
  else o << " J=" << J;
  o << " c=" << c << " Kp=" << Kp << " Kv=" << Kv << " Ki=" << Ki << " kff=" << kff << " Tff=" << Tff
    << " Tc=" << control_period << " delay=" << measurement_delay;
  if (torque_limit != 0) o << " limit=" << torque_limit;
  if (substep != 0) o << " substep=" << substep;
  if (backlash != 0) o << " backlash=" << backlash;
  if (coulomb != 0) o << " coulomb=" << coulomb;
  if (lead_amp != 0) o << " lead_err=" << lead_amp << "/" << lead_period << "@" << lead_phase;
  if (scale_ppm != 0) o << " scale_ppm=" << scale_ppm;
  if (cogging != 0) o << " cogging=" << cogging << "x" << cogging_order;
  if (drift_rate != 0) o << " drift=" << drift_rate << "@" << drift_onset;
  return o.str();
}

double load_per_motor_rad(const AxisMachine& m) {
  if (m.rotary) return 180.0 / kPi;
  return m.lead > 0 ? 1000.0 * m.lead / (2 * kPi) : 1000.0;
}

double integration_substep(const AxisMachine& m) {
  validate(m);
  return substeps(m).h;
}

Seed002Equivalent equivalent(const AxisMachine& m) {
  return {m.Kp, m.Kv, m.Ki, m.c, two_mass(m) ? m.Jm + m.Jt : m.J, 100.0 * m.kff};
}

double loop_spectral_radius(const AxisMachine& m) {
  validate(m);
  const Substeps s = substeps(m);
  Mat4 A;
  Vec4 B;
  plant(m, A, B);
  const Mat4 L = Mat4::Identity() - 0.5 * s.h * A;
  const Mat4 M = L.partialPivLu().solve(Mat4::Identity() + 0.5 * s.h * A);
  const Vec4 N = L.partialPivLu().solve(s.h * B);
  Mat4 P = Mat4::Identity();
  Vec4 Q = Vec4::Zero();
  for (int i = 0; i < s.per_tick; ++i) {
    Q = M * Q + N;
    P = M * P;
  }
  const int n = two_mass(m) ? 4 : 2;
  Eigen::RowVector4d E = Eigen::RowVector4d::Zero();  // e_v = E x (zero command)
  E(feedback_index(m)) -= m.Kp;
  E(1) -= 1;
  const double Tc = m.control_period;
  Eigen::MatrixXd Phi = Eigen::MatrixXd::Zero(n + 1, n + 1);
  const Mat4 top = P + Q * ((m.Kv + m.Ki * Tc) * E);
  Phi.topLeftCorner(n, n) = top.topLeftCorner(n, n);
  Phi.topRightCorner(n, 1) = (Q * m.Ki).head(n);
  Phi.bottomLeftCorner(1, n) = Tc * E.head(n);
  Phi(n, n) = 1;
  return Phi.eigenvalues().cwiseAbs().maxCoeff();
}

AxisRun run_axis(const AxisMachine& m, std::span<const double> command, double period) {
  validate(m);
  if (!(period > 0)) throw std::invalid_argument("unseen machine: period must be > 0");
  AxisRun run;
  const std::size_t count = command.size();
  if (count == 0) return run;
  run.actual.resize(count);
  run.torque.resize(count);

  const double g = load_per_motor_rad(m);
  const Substeps s = substeps(m);
  const double h = s.h, Tc = m.control_period;
  const int fb = feedback_index(m);
  const bool nl = nonlinear(m);

  // Command in motor radians and the feed-forward of every segment (prefix sums of v_k).
  std::vector<double> cmd(count);
  for (std::size_t i = 0; i < count; ++i) cmd[i] = command[i] / g;
  const std::size_t nff = std::max<std::size_t>(1, static_cast<std::size_t>(std::lround(m.Tff / period)));
  std::vector<double> vsum(count + nff + 1, 0.0);  // vsum[k+1] = v_0 + ... + v_k
  for (std::size_t k = 0; k < count + nff; ++k) {
    const double v = k + 1 < count ? (cmd[k + 1] - cmd[k]) / period : 0.0;
    vsum[k + 1] = vsum[k] + v;
  }
  auto segment = [&](double t) {
    return static_cast<std::size_t>(std::max(0.0, std::floor(t / period + 1e-9)));
  };
  auto theta_r = [&](double t) {
    const std::size_t k = segment(t);
    if (k + 1 >= count) return cmd[count - 1];
    const double f = std::clamp(t / period - static_cast<double>(k), 0.0, 1.0);
    return cmd[k] + f * (cmd[k + 1] - cmd[k]);
  };
  auto v_ff = [&](double t) {
    if (m.kff == 0) return 0.0;
    const std::size_t k = std::min(segment(t), count + nff - 1);
    const std::size_t lo = k + 1 >= nff ? k + 1 - nff : 0;
    return m.kff * (vsum[k + 1] - vsum[lo]) / static_cast<double>(nff);
  };

  // Tustin step matrices.
  Mat4 A;
  Vec4 B;
  plant(m, A, B);
  const Mat4 L = Mat4::Identity() - 0.5 * h * A;
  const Mat4 R = Mat4::Identity() + 0.5 * h * A;
  const auto lu = L.partialPivLu();
  const Mat4 M = lu.solve(R);
  const Vec4 N = lu.solve(h * B);
  const double Jmot = motor_inertia(m);

  // f_nl(x): only the motor speed row.
  auto step_nonlinear = [&](const Vec4& x, double tau) {
    const NlTorque t0 = nl_torque(m, x(0), x(1));
    const Vec4 rhs = R * x + h * B * tau - Vec4(0, 0.5 * h * t0.value / Jmot, 0, 0);
    Vec4 y = M * x + N * tau;
    for (int it = 0; it < 20; ++it) {
      const NlTorque t1 = nl_torque(m, y(0), y(1));
      const Vec4 res = L * y + Vec4(0, 0.5 * h * t1.value / Jmot, 0, 0) - rhs;
      Mat4 jac = L;
      jac(1, 0) += 0.5 * h * t1.d_theta / Jmot;
      jac(1, 1) += 0.5 * h * t1.d_w / Jmot;
      const Vec4 dy = jac.partialPivLu().solve(res);
      y -= dy;
      if (dy.cwiseAbs().maxCoeff() <= 1e-13 * (1 + y.cwiseAbs().maxCoeff())) break;
    }
    return y;
  };

  Play play{m.backlash, 0};
  auto output = [&](const Vec4& x, double t) {
    double y = g * x(fb);
    if (m.backlash > 0) y = play(y);
    const double y1 = y;
    if (m.lead_amp != 0) y += m.lead_amp * std::sin(2 * kPi * y1 / m.lead_period + m.lead_phase);
    if (m.scale_ppm != 0) y += m.scale_ppm * 1e-6 * y1;
    if (m.drift_rate != 0 && t > m.drift_onset) y += m.drift_rate * (t - m.drift_onset);
    return y;
  };

  // At rest at command[0].
  Vec4 x = Vec4::Zero();
  x(0) = cmd[0];
  if (two_mass(m)) x(2) = cmd[0];
  play.out = g * x(fb);
  double integral = 0, tau = 0;
  const double y_start = output(x, 0);
  double y_prev = y_start;

  const double delay = m.measurement_delay;
  const double t_end = static_cast<double>(count - 1) * period;  // the delayed log needs no more
  const double eps = 1e-9 * h;
  std::size_t next_out = 0, next_torque = 0;
  // Samples whose delayed time is at or before 0.
  while (next_out < count && static_cast<double>(next_out) * period - delay <= eps) run.actual[next_out++] = y_start;

  for (std::int64_t tick = 0; next_out < count || next_torque < count; ++tick) {
    const double t0 = static_cast<double>(tick) * Tc;
    // Controller.
    const double e_v = m.Kp * (theta_r(t0) - x(fb)) + v_ff(t0) - x(1);
    const double candidate = integral + Tc * e_v;
    tau = m.Kv * e_v + m.Ki * candidate;
    if (m.torque_limit > 0 && std::abs(tau) > m.torque_limit) {
      tau = std::clamp(m.Kv * e_v + m.Ki * integral, -m.torque_limit, m.torque_limit);
    } else {
      integral = candidate;
    }
    const double t_next = static_cast<double>(tick + 1) * Tc;
    while (next_torque < count && static_cast<double>(next_torque) * period < t_next - eps)
      run.torque[next_torque++] = tau;
    // Plant over the tick.
    for (int i = 1; i <= s.per_tick; ++i) {
      const double ta = t0 + (i - 1) * h, tb = t0 + i * h;
      x = nl ? step_nonlinear(x, tau) : Vec4(M * x + N * tau);
      const double y = output(x, tb);
      while (next_out < count) {
        const double tq = static_cast<double>(next_out) * period - delay;
        if (tq > tb + eps) break;
        const double f = std::clamp((tq - ta) / h, 0.0, 1.0);
        run.actual[next_out++] = y_prev + f * (y - y_prev);
      }
      y_prev = y;
    }
    if (t0 > t_end + 2 * Tc + period) break;  // guard (never reached when the loops above fill)
  }
  return run;
}

AxisMachine draw_axis(std::uint64_t seed, const Seed002Equivalent& base, bool rotary, double lead) {
  std::mt19937_64 rng(seed);
  AxisMachine m;
  m.rotary = rotary;
  m.lead = lead;
  // Fixed order of draws: every draw below happens for every seed.
  const bool twomass = (bits(rng) >> 63) != 0;
  const double J = base.J * log_uniform(rng, 0.5, 2);
  m.c = base.C * log_uniform(rng, 0.5, 2);
  m.Kp = base.Kpp * log_uniform(rng, 0.5, 2);
  m.Kv = base.Kvp * log_uniform(rng, 0.5, 2);
  const double corner = uniform(rng, 0.3, 1.5);
  m.kff = uniform(rng, 0, 1);
  m.Tff = static_cast<double>(1 + bits(rng) % 16) * 1e-3;
  m.control_period = (bits(rng) >> 63) ? 0.5e-3 : 0.25e-3;
  const double delay = uniform(rng, 1e-3, 4e-3);
  m.measurement_delay = (bits(rng) >> 63) ? delay : 0.0;
  const double split = uniform(rng, 0.3, 0.7);
  const double f_res = log_uniform(rng, 30, 120);
  const double zeta = uniform(rng, 0.02, 0.1);

  m.structure = twomass ? Structure::kTwoMass : Structure::kCascade;
  m.J = J;
  m.Jm = split * J;
  m.Jt = J - m.Jm;
  const double mu = m.Jm * m.Jt / J, w_res = 2 * kPi * f_res;
  m.k = w_res * w_res * mu;
  m.d = 2 * zeta * std::sqrt(m.k * mu);

  // Clamps: 2 Kp <= Kv/J <= 0.5/Tc.
  const double cap = 0.5 / m.control_period;
  if (2 * m.Kp > cap) m.Kp = cap / 2;
  m.Kv = std::clamp(m.Kv, 2 * m.Kp * J, cap * J);
  m.Ki = corner * m.Kp * m.Kv;
  const double rho_max = std::exp(-kMinDecay * m.control_period);
  for (int i = 0; i < 40 && loop_spectral_radius(m) > rho_max; ++i) {
    m.Kp *= 0.8;
    m.Kv *= 0.8;
    m.Ki *= 0.8 * 0.8;  // keeps the corner Ki/Kv at the same multiple of Kp
  }
  return m;
}

}  // namespace gcpipe::unseen
