#include "axis_model.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace gcpipe::calibrate {

bool is_dynamic_effect(const std::string& type) {
  return type == "coulomb_friction" || type == "feedback_delay";
}

std::vector<double> simulate_motor(const servo::DriveParams& p, int substeps, double margin,
                                   double period, std::span<const double> c,
                                   std::vector<double>* torque) {
  servo::DriveParams dyn = p;
  dyn.effects.clear();
  for (const auto& e : p.effects)
    if (is_dynamic_effect(e.type)) dyn.effects.push_back(e);
  std::vector<double> y(c.size());
  if (c.empty()) return y;
  servo::AxisDrive d(dyn, period, substeps, margin);
  const auto w = static_cast<std::size_t>(d.window());
  // The commands followed by the last one held, as ServoSimulator::flush does at the end.
  std::vector<double> padded(c.begin(), c.end());
  padded.resize(c.size() + w, c.back());
  d.reset(c[0]);
  y[0] = c[0];
  if (torque) torque->assign(c.size(), 0.0);
  for (std::size_t k = 1; k < c.size(); ++k) {
    const servo::AxisState st = d.step(std::span<const double>(padded.data() + k - 1, w));
    y[k] = st.position;
    if (torque) (*torque)[k] = st.torque;
  }
  return y;
}

namespace {

void backlash(double width, std::vector<double>& y, std::vector<std::vector<double>>* dydp) {
  // Play operator; its derivative with respect to the width is -1/2 while pushed from below,
  // +1/2 from above, and held (the table does not move) inside the gap.
  const double h = width / 2;
  double out = y.empty() ? 0 : y[0], d = 0;
  if (dydp) dydp->assign(1, std::vector<double>(y.size(), 0.0));
  for (std::size_t k = 0; k < y.size(); ++k) {
    const double x = y[k];
    if (out < x - h) { out = x - h; d = -0.5; }
    else if (out > x + h) { out = x + h; d = 0.5; }
    y[k] = out;
    if (dydp) (*dydp)[0][k] = d;
  }
}

void lead_error(double a, double p, double phase_deg, std::vector<double>& y,
                std::vector<std::vector<double>>* dydp) {
  const double k = 2 * std::numbers::pi / p, ph = phase_deg * std::numbers::pi / 180;
  if (dydp) dydp->assign(3, std::vector<double>(y.size(), 0.0));
  for (std::size_t i = 0; i < y.size(); ++i) {
    const double x = y[i], arg = k * x + ph;
    y[i] = x + a * std::sin(arg);
    if (dydp) {
      (*dydp)[0][i] = std::sin(arg);
      (*dydp)[1][i] = a * std::cos(arg) * (-k * x / p);
      (*dydp)[2][i] = a * std::cos(arg) * std::numbers::pi / 180;
    }
  }
}

void measurement_delay(double delay, double period, std::vector<double>& y,
                       std::vector<std::vector<double>>* dydp) {
  // out(t) = in(t - delay) between ticks by a Catmull-Rom cubic (the simulator interpolates
  // linearly between 1/8-tick sub-steps; linear between whole ticks would be off by
  // f(1-f)/2 T^2 a, 13 nm rms on the test circle, the cubic by O(T^4)). Held before the start.
  const std::vector<double> x = y;
  const double q = delay / period;
  const auto n = static_cast<std::ptrdiff_t>(std::floor(q));
  const double s = 1 - (q - std::floor(q));  // position from x[k-n-1] towards x[k-n]
  if (dydp) dydp->assign(1, std::vector<double>(y.size(), 0.0));
  const auto at = [&](std::ptrdiff_t i) { return x[static_cast<std::size_t>(std::clamp<std::ptrdiff_t>(i, 0, static_cast<std::ptrdiff_t>(x.size()) - 1))]; };
  for (std::ptrdiff_t k = 0; k < static_cast<std::ptrdiff_t>(x.size()); ++k) {
    const double p0 = at(k - n - 2), p1 = at(k - n - 1), p2 = at(k - n), p3 = at(k - n + 1);
    const double c1 = -p0 + p2, c2 = 2 * p0 - 5 * p1 + 4 * p2 - p3, c3 = -p0 + 3 * p1 - 3 * p2 + p3;
    y[static_cast<std::size_t>(k)] = 0.5 * (2 * p1 + c1 * s + c2 * s * s + c3 * s * s * s);
    // d out / d delay = d out / ds * ds / d delay, ds / d delay = -1 / period.
    if (dydp) (*dydp)[0][static_cast<std::size_t>(k)] = -0.5 * (c1 + 2 * c2 * s + 3 * c3 * s * s) / period;
  }
}

}  // namespace

void apply_output_effect(const servo::EffectSettings& e, double period, std::vector<double>& y,
                         std::vector<std::vector<double>>* dydp) {
  if (e.type == "backlash") return backlash(e.get("width", 0), y, dydp);
  if (e.type == "lead_error")
    return lead_error(e.get("amplitude", 0), e.get("period", 1), e.get("phase", 0), y, dydp);
  if (e.type == "measurement_delay") return measurement_delay(e.get("delay", 0), period, y, dydp);
  if (e.type == "scale_error" || e.type == "offset") {
    const bool scale = e.type == "scale_error";
    const double s = scale ? e.get("ppm", 0) * 1e-6 : e.get("value", 0);
    if (dydp) dydp->assign(1, std::vector<double>(y.size(), 1.0));
    for (std::size_t i = 0; i < y.size(); ++i) {
      if (dydp && scale) (*dydp)[0][i] = y[i] * 1e-6;
      y[i] = scale ? y[i] * (1 + s) : y[i] + s;
    }
  }
}

double estimate_noise(std::span<const double> y) {
  if (y.size() < 8) return 0;
  std::vector<double> d;
  d.reserve(y.size());
  for (std::size_t k = 3; k < y.size(); ++k) d.push_back(std::abs(y[k] - 3 * y[k - 1] + 3 * y[k - 2] - y[k - 3]));
  const auto mid = d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2);
  std::nth_element(d.begin(), mid, d.end());
  return *mid / 0.6745 / std::sqrt(20.0);
}

double correlation_time(std::span<const double> r) {
  const std::size_t n = r.size();
  if (n < 4) return 1;
  double mean = 0;
  for (double v : r) mean += v;
  mean /= static_cast<double>(n);
  double c0 = 0;
  for (double v : r) c0 += (v - mean) * (v - mean);
  if (!(c0 > 0)) return 1;
  // Lags 1..16 one by one, then on a geometric grid where each sampled lag stands for the
  // `width` lags up to the next one: O(N log N) instead of O(N^2), exact enough for a variance
  // inflation factor.
  double tau = 1;
  for (std::size_t lag = 1; lag < std::min<std::size_t>(n / 2, 20000);) {
    const std::size_t width = lag < 16 ? 1 : lag / 8;
    double c = 0;
    for (std::size_t k = lag; k < n; ++k) c += (r[k] - mean) * (r[k - lag] - mean);
    const double rho = c / c0;
    if (rho <= 0) break;
    tau += 2 * rho * static_cast<double>(width);
    lag += width;
  }
  return std::max(1.0, tau);
}

}  // namespace gcpipe::calibrate
