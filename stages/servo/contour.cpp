#include "contour.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace gcpipe::servo {

double segment_distance(const Vec3& a, const Vec3& b, const Vec3& p, Vec3* closest) {
  const double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double w[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  double s = dd > 0 ? (w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) / dd : 0.0;
  s = std::clamp(s, 0.0, 1.0);
  if (closest != nullptr) *closest = {a[0] + s * d[0], a[1] + s * d[1], a[2] + s * d[2]};
  const double e[3] = {w[0] - s * d[0], w[1] - s * d[1], w[2] - s * d[2]};
  return std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
}

}  // namespace gcpipe::servo
