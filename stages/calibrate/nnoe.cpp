#include "nnoe.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace gcpipe::calibrate {

std::string NnoeStructure::text() const {
  return "na=" + std::to_string(na) + " nb=" + std::to_string(nb) + " hidden=" + std::to_string(hidden);
}

void differentiate(std::span<const double> y, double period, std::vector<double>& v, std::vector<double>& a) {
  const std::size_t n = y.size();
  v.assign(n, 0.0);
  a.assign(n, 0.0);
  for (std::size_t k = 1; k + 1 < n; ++k) {
    v[k] = (y[k + 1] - y[k - 1]) / (2 * period);
    a[k] = (y[k + 1] - 2 * y[k] + y[k - 1]) / (period * period);
  }
}

namespace {

int inputs_of(const NnoeStructure& s) { return s.na + 2 * s.nb; }

/// Regressor of sample t: r(t-1..t-na), v(t-1..t-nb), a(t-1..t-nb), normalised.
void regressor(const NnoeModel& m, const std::vector<double>& r, std::span<const double> v, std::span<const double> a,
               std::size_t t, double* x) {
  int j = 0;
  for (int i = 1; i <= m.structure.na; ++i) x[j++] = r[t - static_cast<std::size_t>(i)] / m.y_scale;
  for (int i = 1; i <= m.structure.nb; ++i) x[j++] = v[t - static_cast<std::size_t>(i)] / m.u_scale[0];
  for (int i = 1; i <= m.structure.nb; ++i) x[j++] = a[t - static_cast<std::size_t>(i)] / m.u_scale[1];
}

/// One network evaluation on one regressor (eq. 2), without the batch machinery.
double eval(const neural::Mlp& net, const double* x, std::vector<double>& h) {
  const auto W1 = net.weight(0), W2 = net.weight(1);
  const auto b1 = net.bias(0), b2 = net.bias(1);
  h.resize(static_cast<std::size_t>(W1.rows()));
  double out = b2[0];
  for (Eigen::Index i = 0; i < W1.rows(); ++i) {
    double z = b1[i];
    for (Eigen::Index j = 0; j < W1.cols(); ++j) z += W1(i, j) * x[j];
    out += W2(0, i) * std::tanh(z);
  }
  return out;
}

/// Parallel simulation over [0, end): r^(t) from its own past (eq. 12); held at +-20 scales so an
/// unstable candidate shows as a large error instead of overflowing.
std::vector<double> simulate_range(const NnoeModel& m, std::span<const double> v, std::span<const double> a, std::size_t end) {
  const std::size_t lag = static_cast<std::size_t>(std::max(m.structure.na, m.structure.nb));
  std::vector<double> r(end, 0.0), x(static_cast<std::size_t>(inputs_of(m.structure))), h;
  for (std::size_t t = lag; t < end; ++t) {
    regressor(m, r, v, a, t, x.data());
    r[t] = std::clamp(eval(m.net, x.data(), h), -20.0, 20.0) * m.y_scale;
  }
  return r;
}

double mse(std::span<const double> r, const std::vector<double>& rh, std::size_t b, std::size_t e) {
  double s = 0;
  for (std::size_t k = b; k < e; ++k) s += (r[k] - rh[k]) * (r[k] - rh[k]);
  return s / static_cast<double>(std::max<std::size_t>(1, e - b));
}

/// Training set of samples [b, e): regressors built from `past` (measured residual for the
/// series-parallel start, the model's own output for the output-error passes).
neural::Dataset dataset(const NnoeModel& m, const std::vector<double>& past, std::span<const double> target,
                        std::span<const double> v, std::span<const double> a, std::size_t b, std::size_t e) {
  neural::Dataset d;
  d.inputs.resize(inputs_of(m.structure), static_cast<Eigen::Index>(e - b));
  d.targets.resize(1, static_cast<Eigen::Index>(e - b));
  for (std::size_t t = b; t < e; ++t) {
    regressor(m, past, v, a, t, d.inputs.col(static_cast<Eigen::Index>(t - b)).data());
    d.targets(0, static_cast<Eigen::Index>(t - b)) = target[t] / m.y_scale;
  }
  return d;
}

double stdev(std::span<const double> x, std::size_t b, std::size_t e) {
  double s = 0, q = 0;
  for (std::size_t k = b; k < e; ++k) { s += x[k]; q += x[k] * x[k]; }
  const double n = static_cast<double>(e - b), m = s / n;
  return std::sqrt(std::max(q / n - m * m, 0.0));
}

/// Trains one structure: series-parallel LM, then output-error passes in which the past-output
/// regressors are the network's own simulation (the NNOE predictor of eq. 12); the gradient of
/// each pass treats those regressors as fixed (the recurrence is not differentiated), the
/// parameters kept are those with the lowest simulated error on the training part.
NnoeModel train_structure(const NnoeStructure& st, std::span<const double> r, std::span<const double> v,
                          std::span<const double> a, std::size_t b, std::size_t e, const NnoeOptions& o,
                          double ys, double vs, double as) {
  NnoeModel m;
  m.structure = st;
  m.y_scale = ys;
  m.u_scale[0] = vs;
  m.u_scale[1] = as;
  m.net = neural::Mlp({inputs_of(st), st.hidden, 1});
  std::mt19937_64 rng(o.seed);
  m.net.initialise(rng);
  neural::LevenbergMarquardtOptions lm;
  lm.max_iterations = o.max_iterations;
  const std::vector<double> measured(r.begin(), r.end());
  (void)neural::train_levenberg_marquardt(m.net, dataset(m, measured, r, v, a, b, e), {}, lm);
  Eigen::VectorXd best = m.net.parameters();
  double best_mse = mse(r, simulate_range(m, v, a, e), b, e);
  for (int pass = 0; pass < o.oe_passes; ++pass) {
    const std::vector<double> own = simulate_range(m, v, a, e);
    lm.max_iterations = o.max_iterations / 2;
    (void)neural::train_levenberg_marquardt(m.net, dataset(m, own, r, v, a, b, e), {}, lm);
    const double s = mse(r, simulate_range(m, v, a, e), b, e);
    if (s < best_mse) { best_mse = s; best = m.net.parameters(); }
  }
  m.net.set_parameters(best);
  // FPE = V (N + d) / (N - d) (Akaike), V the simulated mean square in normalised units.
  const double N = static_cast<double>(e - b), d = static_cast<double>(m.net.parameter_count());
  m.fpe = best_mse / (ys * ys) * (N + d) / std::max(N - d, 1.0);
  return m;
}

}  // namespace

std::vector<double> NnoeModel::simulate(std::span<const double> velocity, std::span<const double> accel) const {
  return simulate_range(*this, velocity, accel, velocity.size());
}

std::optional<NnoeModel> fit_nnoe(std::span<const double> r, std::span<const double> v, std::span<const double> a,
                                  std::size_t begin, std::size_t split, const NnoeOptions& o) {
  const std::size_t b = std::max<std::size_t>(begin, 8);
  const std::size_t e = std::min(split, b + o.max_train);
  if (e < b + 200) return std::nullopt;
  const double ys = std::max(stdev(r, b, e), 1e-12), vs = std::max(stdev(v, b, e), 1e-12), as = std::max(stdev(a, b, e), 1e-12);
  // Table 1 of seed 003 compares regressor sets of one and two past outputs and inputs; a
  // lightly damped mode needs two past outputs (a second-order recursion), so the grid spans
  // first to third order and two network sizes.
  const NnoeStructure grid[] = {{1, 1, 4}, {2, 2, 4}, {2, 2, 8}, {3, 3, 8}};
  std::optional<NnoeModel> best;
  std::vector<std::pair<NnoeStructure, double>> tried;
  for (const auto& st : grid) {
    NnoeModel m = train_structure(st, r, v, a, b, e, o, ys, vs, as);
    tried.emplace_back(st, m.fpe);
    if (!best || m.fpe < best->fpe) best = std::move(m);
  }
  best->candidates = tried;
  const std::vector<double> rh = best->simulate(v, a);
  const std::size_t n = r.size();
  const std::size_t hb = split < n ? split : b, he = split < n ? n : e;
  double s0 = 0, s1 = 0;
  for (std::size_t k = hb; k < he; ++k) { s0 += r[k] * r[k]; s1 += (r[k] - rh[k]) * (r[k] - rh[k]); }
  best->explained_fraction = s0 > 0 ? 1 - s1 / s0 : 0;
  return best;
}

}  // namespace gcpipe::calibrate
