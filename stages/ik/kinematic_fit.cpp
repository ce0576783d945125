#include "kinematic_fit.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <numbers>

namespace gcpipe {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;

// path = b(joints) + M(joints) theta with theta = (cx, cy, ay, az, ox, oy, oz). From the forward
// chain with p = (X - cx, Y - ay, Z - az):
//   w_x = cx + cC px + sC (cA py + sA pz + ay - cy)
//   w_y = cy - sC px + cC (cA py + sA pz + ay - cy)
//   w_z = -sA py + cA pz + az,          path = w - o
// collected by parameter (derivation in the README).
void linear_rows(const Axes& j, double s, Eigen::Matrix<double, 3, 7>& M, Eigen::Vector3d& b) {
  const double ta = s * j[kA] * kDegToRad, tc = s * j[kC] * kDegToRad;
  const double cA = std::cos(ta), sA = std::sin(ta), cC = std::cos(tc), sC = std::sin(tc);
  const double v0 = cA * j[kY] + sA * j[kZ];
  b << cC * j[kX] + sC * v0, -sC * j[kX] + cC * v0, -sA * j[kY] + cA * j[kZ];
  M << 1 - cC, -sC, sC * (1 - cA), -sC * sA, -1, 0, 0,
       sC, 1 - cC, cC * (1 - cA), -cC * sA, 0, -1, 0,
       0, 0, sA, 1 - cA, 0, 0, -1;
}

KinematicFitResult solve(std::span<const KinematicSample> samples, RotaryConvention convention,
                         bool origin_only) {
  const double s = convention == RotaryConvention::kTableRightHand ? 1.0 : -1.0;
  const int n = static_cast<int>(samples.size());
  const int cols = origin_only ? 3 : 7;
  Eigen::MatrixXd A(3 * n, cols);
  Eigen::VectorXd y(3 * n);
  Eigen::Matrix<double, 3, 7> M;
  Eigen::Vector3d b;
  for (int i = 0; i < n; ++i) {
    const KinematicSample& k = samples[static_cast<std::size_t>(i)];
    linear_rows(k.joints, s, M, b);
    A.middleRows(3 * i, 3) = origin_only ? Eigen::MatrixXd(M.rightCols(3)) : Eigen::MatrixXd(M);
    y.segment(3 * i, 3) =
        Eigen::Vector3d(k.path_pos[0], k.path_pos[1], k.path_pos[2]) - b;
  }
  const Eigen::VectorXd theta = A.colPivHouseholderQr().solve(y);
  KinematicFitResult r;
  if (!origin_only) {
    r.c_x = theta[0];
    r.c_y = theta[1];
    r.a_y = theta[2];
    r.a_z = theta[3];
  }
  r.origin = {theta[cols - 3], theta[cols - 2], theta[cols - 1]};
  return evaluate_geometry(samples, r, convention);
}

}  // namespace

MachineKinematics KinematicFitResult::model(const MachineKinematics& base) const {
  MachineKinematics m = base;
  m.c_centre = {c_x, c_y, 0};
  m.a_offset_y = a_y - c_y;
  m.a_offset_z = a_z;
  m.tool_length = 0;
  return m;
}

KinematicFitResult evaluate_geometry(std::span<const KinematicSample> samples,
                                     const KinematicFitResult& geometry,
                                     RotaryConvention convention) {
  // Through forward_kinematics, not the linear rows: the fit's algebra is checked on every call.
  MachineKinematics base;
  base.convention = convention;
  const MachineKinematics m = geometry.model(base);
  KinematicFitResult r = geometry;
  r.samples = samples.size();
  double sum = 0;
  r.max = 0;
  for (const KinematicSample& k : samples) {
    const ToolPose p = forward_kinematics(m, k.joints, 0);
    const double e = std::hypot(p.tip[0] - geometry.origin[0] - k.path_pos[0],
                                p.tip[1] - geometry.origin[1] - k.path_pos[1],
                                p.tip[2] - geometry.origin[2] - k.path_pos[2]);
    sum += e * e;
    r.max = std::max(r.max, e);
  }
  r.rms = samples.empty() ? 0 : std::sqrt(sum / static_cast<double>(samples.size()));
  return r;
}

KinematicFitResult fit_table_geometry(std::span<const KinematicSample> samples,
                                      RotaryConvention convention) {
  return solve(samples, convention, false);
}

KinematicFitResult fit_untransformed_offset(std::span<const KinematicSample> samples) {
  KinematicFitResult r;
  r.samples = samples.size();
  if (samples.empty()) return r;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const KinematicSample& k : samples)
    mean += Eigen::Vector3d(k.joints[kX] - k.path_pos[0], k.joints[kY] - k.path_pos[1],
                            k.joints[kZ] - k.path_pos[2]);
  mean /= static_cast<double>(samples.size());
  r.origin = {mean.x(), mean.y(), mean.z()};
  double sum = 0;
  for (const KinematicSample& k : samples) {
    const double e = (Eigen::Vector3d(k.joints[kX] - k.path_pos[0], k.joints[kY] - k.path_pos[1],
                                      k.joints[kZ] - k.path_pos[2]) - mean).norm();
    sum += e * e;
    r.max = std::max(r.max, e);
  }
  r.rms = std::sqrt(sum / static_cast<double>(samples.size()));
  return r;
}

KinematicFitResult fit_origin_only(std::span<const KinematicSample> samples,
                                   RotaryConvention convention) {
  return solve(samples, convention, true);
}

}  // namespace gcpipe
