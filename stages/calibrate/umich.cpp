#include "umich.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <stdexcept>

namespace gcpipe::calibrate {

namespace {

constexpr double kMoving = 0.5;  // mm/s: below this the sign of the friction is not known

struct Rows {
  std::vector<double> vc, va, a, i;
};

/// Samples of one axis with the command shifted by `d` samples; accelerations by central
/// differences of the actual velocity. Stationary samples are left out of the current fit.
Rows rows(const std::vector<MeasuredTrace>& set, int axis, int d) {
  Rows r;
  for (const auto& tr : set) {
    if (tr.format != TraceFormat::kUmichCsv) throw std::invalid_argument(tr.file + ": not a UMich trace");
    const auto& vc = tr.command_velocity[axis];
    const auto& va = tr.actual_velocity[axis];
    for (std::size_t k = 3 + 1; k + 1 < tr.size(); ++k) {
      r.vc.push_back(vc[k - static_cast<std::size_t>(d)]);
      r.va.push_back(va[k]);
      r.a.push_back((va[k + 1] - va[k - 1]) / (2 * tr.period));
      r.i.push_back(tr.effort[axis].empty() ? 0 : tr.effort[axis][k]);
    }
  }
  return r;
}

double rms(const std::vector<double>& e) {
  double s = 0;
  for (double v : e) s += v * v;
  return std::sqrt(s / static_cast<double>(std::max<std::size_t>(1, e.size())));
}

void fit_velocity(const std::vector<MeasuredTrace>& fit, const std::vector<MeasuredTrace>& pred, int axis, UmichAxis& out) {
  double best = INFINITY;
  for (int d = 0; d <= 3; ++d) {
    const Rows r = rows(fit, axis, d);
    double num = 0, den = 0;
    for (std::size_t k = 0; k < r.vc.size(); ++k) { num += r.vc[k] * r.va[k]; den += r.vc[k] * r.vc[k]; }
    const double g = den > 0 ? num / den : 1;
    std::vector<double> e;
    for (std::size_t k = 0; k < r.vc.size(); ++k) e.push_back(r.va[k] - g * r.vc[k]);
    if (rms(e) < best) { best = rms(e); out.gain = g; out.delay_s = d * fit.front().period; }
  }
  const int d = static_cast<int>(std::lround(out.delay_s / fit.front().period));
  const Rows p0 = rows(pred, axis, 0), p = rows(pred, axis, d);
  std::vector<double> e0, e1;
  for (std::size_t k = 0; k < p.vc.size(); ++k) { e0.push_back(p0.va[k] - p0.vc[k]); e1.push_back(p.va[k] - out.gain * p.vc[k]); }
  out.v_rms_before = rms(e0);
  out.v_rms_after = rms(e1);
}

Eigen::MatrixXd design(const Rows& r, std::vector<double>& y) {
  std::vector<std::size_t> keep;
  for (std::size_t k = 0; k < r.va.size(); ++k)
    if (std::abs(r.va[k]) > kMoving) keep.push_back(k);
  Eigen::MatrixXd A(static_cast<Eigen::Index>(keep.size()), 4);
  y.clear();
  for (std::size_t j = 0; j < keep.size(); ++j) {
    const std::size_t k = keep[j];
    A.row(static_cast<Eigen::Index>(j)) << (r.va[k] > 0 ? 1.0 : -1.0), r.va[k], r.a[k], 1.0;
    y.push_back(r.i[k]);
  }
  return A;
}

void fit_current(const std::vector<MeasuredTrace>& fit, const std::vector<MeasuredTrace>& pred, int axis, UmichAxis& out) {
  std::vector<double> y;
  const Eigen::MatrixXd A = design(rows(fit, axis, 0), y);
  if (A.rows() < 8) return;
  const Eigen::Map<const Eigen::VectorXd> Y(y.data(), static_cast<Eigen::Index>(y.size()));
  const Eigen::MatrixXd N = A.transpose() * A;
  const Eigen::Vector4d x = N.ldlt().solve(A.transpose() * Y);
  const double s2 = (Y - A * x).squaredNorm() / static_cast<double>(A.rows() - 4);
  const Eigen::Vector4d sig = (N.ldlt().solve(Eigen::Matrix4d::Identity()) * s2).diagonal().cwiseSqrt();
  const double mean = Y.mean();
  for (int i = 0; i < 4; ++i) { out.current[i] = x[i]; out.current_sigma[i] = sig[i]; }
  std::vector<double> yp;
  const Eigen::MatrixXd P = design(rows(pred, axis, 0), yp);
  std::vector<double> e0, e1;
  for (Eigen::Index k = 0; k < P.rows(); ++k) {
    e0.push_back(yp[static_cast<std::size_t>(k)] - mean);
    e1.push_back(yp[static_cast<std::size_t>(k)] - P.row(k).dot(x));
  }
  out.i_rms_before = rms(e0);
  out.i_rms_after = rms(e1);
  out.fit_samples = static_cast<std::size_t>(A.rows());
  out.predict_samples = static_cast<std::size_t>(P.rows());
}

}  // namespace

std::array<UmichAxis, 3> umich_analysis(const std::vector<MeasuredTrace>& fit, const std::vector<MeasuredTrace>& predict) {
  std::array<UmichAxis, 3> out;
  for (int a = 0; a < 3; ++a) {
    fit_velocity(fit, predict, a, out[a]);
    fit_current(fit, predict, a, out[a]);
  }
  return out;
}

}  // namespace gcpipe::calibrate
