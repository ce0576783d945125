#include "contour.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace gcpipe::servo {

double segment_distance(const Vec3& a, const Vec3& b, const Vec3& p, Vec3* closest) {
  double s = 0;
  const double sq = segment_distance_sq(a, b, p, s);
  if (closest != nullptr) *closest = {a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]), a[2] + s * (b[2] - a[2])};
  return std::sqrt(sq);
}

}  // namespace gcpipe::servo
