#include "circle.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace gcpipe::servo {

namespace {
constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;

double wrap_pi(double a) { return std::remainder(a, 2 * kPi); }
}  // namespace

CirclePoint circle_point(const CircleTest& c, double t, double X, double Y, double C_deg) {
  return circle_point_at(c, c.omega * (t - c.t_start), X, Y, C_deg);
}

CirclePoint circle_point_at(const CircleTest& c, double nominal, double X, double Y, double C_deg) {
  CirclePoint p;
  const double c_act = (C_deg - c.c_start) * kDeg;
  // Commanded cutting point of the rotary axis: where the linear axes should be for the C angle
  // actually reached (Section 4.2: X_Rth = R_W cos(wt - alpha) + R_C).
  const double XR = c.R_W * std::cos(c_act) + c.R_C, YR = c.R_W * std::sin(c_act);
  p.alpha = nominal - c_act;                                  // eq. (8)
  p.beta = wrap_pi(nominal - std::atan2(Y, X - c.R_C));       // eq. (9)
  p.alpha_minus_beta = wrap_pi(std::atan2(Y, X - c.R_C) - c_act);  // eq. (10)
  p.radius_decrease = c.R_W - std::hypot(X - c.R_C, Y);       // eq. (11), sign of eq. (12)
  const double ex = X - XR, ey = Y - YR;                      // eq. (4)
  p.shape_error = ex;                                         // eq. (6)
  p.shape_error_exact = c.R_C - std::hypot(c.R_C - ex, ey);   // eq. (5)
  p.shape_error_model = -p.alpha_minus_beta * c.R_W * std::sin(nominal) -
                        p.radius_decrease * std::cos(nominal);  // eq. (7)
  return p;
}

CirclePoint CircleAnalyzer::add(double t, double X, double Y, double C_deg) {
  const CirclePoint p = circle_point(test_, t, X, Y, C_deg);
  if (s_.ticks == 0) {
    s_.min_radius_decrease = s_.max_radius_decrease = p.radius_decrease;
    min_e_ = max_e_ = p.shape_error;
  }
  ++s_.ticks;
  sum_a_ += p.alpha;
  sum_b_ += p.beta;
  sum_ab_ += p.alpha_minus_beta;
  sum_dr_ += p.radius_decrease;
  s_.min_radius_decrease = std::min(s_.min_radius_decrease, p.radius_decrease);
  s_.max_radius_decrease = std::max(s_.max_radius_decrease, p.radius_decrease);
  min_e_ = std::min(min_e_, p.shape_error);
  max_e_ = std::max(max_e_, p.shape_error);
  return p;
}

CircleSummary CircleAnalyzer::summary() const {
  CircleSummary s = s_;
  if (s.ticks == 0) return s;
  const double n = static_cast<double>(s.ticks);
  s.mean_alpha = sum_a_ / n;
  s.mean_beta = sum_b_ / n;
  s.mean_alpha_minus_beta = sum_ab_ / n;
  s.mean_radius_decrease = sum_dr_ / n;
  s.shape_error_half_amplitude = 0.5 * (max_e_ - min_e_);
  return s;
}

std::complex<double> command_response(const DriveParams& p, interpolate::Smoothing smoothing,
                                      double period, double omega) {
  return interpolate::smoothing_response(smoothing, p.Ts, period, omega) *
         first_order_hold_gain(omega, period) * drive_response(p, omega);
}

CirclePrediction predict_circle(const DriveSet& d, interpolate::Smoothing smoothing, double period,
                                const CircleTest& test) {
  CirclePrediction r;
  const auto gx = command_response(d.axes[kX], smoothing, period, test.omega);
  const auto gy = command_response(d.axes[kY], smoothing, period, test.omega);
  r.beta_x = -std::arg(gx);
  r.beta_y = -std::arg(gy);
  // The steady actual path is X = R_C + R_W |Gx| cos(phi - beta_x), Y = R_W |Gy| sin(phi - beta_y):
  // an ellipse unless the axes are alike. Its mean radius and mean eq.-(9) angle by quadrature
  // (the integrands are smooth and periodic, so the rectangle rule converges geometrically).
  const int n = 4096;
  double sum_r = 0, sum_b = 0;
  for (int i = 0; i < n; ++i) {
    const double phi = 2 * kPi * i / n;
    const double x = test.R_W * std::abs(gx) * std::cos(phi - r.beta_x);
    const double y = test.R_W * std::abs(gy) * std::sin(phi - r.beta_y);
    sum_r += std::hypot(x, y);
    sum_b += wrap_pi(phi - std::atan2(y, x));
  }
  r.radius_decrease = test.R_W - sum_r / n;
  r.beta = sum_b / n;
  return r;
}

CircleSummary simulate_circle(const DriveSet& d, interpolate::Smoothing smoothing, double period,
                              const CircleTest& test, double settle, double span) {
  ServoSimulator sim(d, period);
  const Axes start{test.R_C + test.R_W, 0, 0, 0, test.c_start};
  std::array<interpolate::AxisSmoother, kNumAxes> sm;
  for (std::size_t i = 0; i < kNumAxes; ++i)
    sm[i] = interpolate::AxisSmoother(smoothing, d.axes[i].Ts, period, start[i]);
  sim.reset(start, test.t_start);
  CircleAnalyzer an(test);
  const auto n = static_cast<std::size_t>(std::ceil((settle + span) / period));
  ServoSample out;
  auto take = [&](const ServoSample& s) {
    if (s.t >= test.t_start + settle - 1e-12 && s.t <= test.t_start + settle + span + 1e-12)
      an.add(s.t, s.actual[kX], s.actual[kY], s.actual[kC]);
  };
  for (std::size_t k = 1; k <= n + 200; ++k) {
    const double t = static_cast<double>(k) * period;
    Axes raw{test.R_C + test.R_W * std::cos(test.omega * t), test.R_W * std::sin(test.omega * t), 0, 0,
             test.c_start + test.omega * t / kDeg};
    Axes cmd;
    for (std::size_t i = 0; i < kNumAxes; ++i) cmd[i] = sm[i].filter(raw[i]);
    if (sim.push(cmd, out)) take(out);
  }
  return an.summary();
}

double rotary_ramp_lag(const DriveParams& c, interpolate::Smoothing smoothing, double period,
                       double omega, double settle, double span) {
  AxisDrive drive(c, period, 8, 0.9);
  drive.reset(0);
  interpolate::AxisSmoother sm(smoothing, c.Ts, period, 0.0);
  const int w = drive.window();
  const auto n = static_cast<std::size_t>(std::ceil((settle + span) / period));
  std::vector<double> cmd(n + static_cast<std::size_t>(w) + 1);
  cmd[0] = 0;
  for (std::size_t k = 1; k < cmd.size(); ++k)
    cmd[k] = sm.filter(omega * static_cast<double>(k) * period / kDeg);
  double sum = 0;
  std::size_t count = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const AxisState st = drive.step(std::span<const double>(cmd.data() + k, static_cast<std::size_t>(w)));
    const double t = static_cast<double>(k + 1) * period;
    if (t >= settle - 1e-12) {
      sum += omega * t - st.position * kDeg;  // C_in - G_R C_in, against the raw ramp
      ++count;
    }
  }
  return count ? sum / static_cast<double>(count) : 0.0;
}

BestKffp best_kffp(const DriveSet& d, interpolate::Smoothing smoothing, double period, double omega,
                   double settle, double span, double max_kffp) {
  BestKffp r;
  r.alpha = rotary_ramp_lag(d.axes[kC], smoothing, period, omega, settle, span);
  r.ok = true;
  for (int a : {kX, kY}) {
    DriveParams p = d.axes[static_cast<std::size_t>(a)];
    auto beta_minus_alpha = [&](double k) {
      p.K_FFP = k;
      return -std::arg(command_response(p, smoothing, period, omega)) - r.alpha;
    };
    double lo = 0, hi = max_kffp;
    double flo = beta_minus_alpha(lo), fhi = beta_minus_alpha(hi);
    if (flo * fhi > 0) {
      r.ok = false;
      r.message += std::string("axis ") + kAxisLetters[a] + ": no K_FFP in [0, " +
                   std::to_string(max_kffp) + "] % makes its phase delay equal the rotary lag " +
                   std::to_string(r.alpha * 1e3) + " mrad; ";
      continue;
    }
    // More feed-forward, less lag: beta falls monotonically with K_FFP here, so bisection.
    for (int it = 0; it < 100 && hi - lo > 1e-10; ++it) {
      const double mid = 0.5 * (lo + hi), fm = beta_minus_alpha(mid);
      if ((fm > 0) == (flo > 0)) { lo = mid; flo = fm; } else { hi = mid; }
    }
    r.K_FFP[a == kX ? 0 : 1] = 0.5 * (lo + hi);
  }
  return r;
}

RampTorque ramp_torque(const DriveParams& c0, interpolate::Smoothing smoothing, double period,
                       double omega, bool with_limit) {
  DriveParams c = c0;
  if (!with_limit) c.torque_limit = 0;
  AxisDrive drive(c, period, 16, 0.9);
  drive.reset(0);
  interpolate::AxisSmoother sm(smoothing, c.Ts, period, 0.0);
  const int w = drive.window();
  // Long enough for the acceleration transient: the smoothing plus the loop settle well inside.
  const double horizon = 10 * c.Ts + 0.5;
  const auto n = static_cast<std::size_t>(std::ceil(horizon / period));
  std::vector<double> cmd(n + static_cast<std::size_t>(w) + 1);
  cmd[0] = 0;
  for (std::size_t k = 1; k < cmd.size(); ++k)
    cmd[k] = sm.filter(omega * static_cast<double>(k) * period / kDeg);
  RampTorque r;
  for (std::size_t k = 0; k < n; ++k) {
    const AxisState st = drive.step(std::span<const double>(cmd.data() + k, static_cast<std::size_t>(w)));
    r.peak_torque = std::max(r.peak_torque, std::abs(st.torque));
    r.saturated = r.saturated || st.saturated;
  }
  return r;
}

double torque_onset_omega(const DriveParams& c, interpolate::Smoothing smoothing, double period,
                          double probe) {
  const RampTorque r = ramp_torque(c, smoothing, period, probe, false);
  return c.torque_limit * probe / r.peak_torque;
}

}  // namespace gcpipe::servo
