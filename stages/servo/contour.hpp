// The geometry of the contour error: the distance from a point to a segment of the nominal
// polyline. The search along the path is simulate::ContourSearch (stages/simulate).
#pragma once

#include <algorithm>
#include <cstdint>

#include "gcpipe/block.hpp"

namespace gcpipe::servo {

/// Squared distance from `p` to the segment a-b [mm^2]; `s` receives the nearest point's place
/// along it (0 at a, 1 at b). Inline: the contour search calls it for every segment it measures.
inline double segment_distance_sq(const Vec3& a, const Vec3& b, const Vec3& p, double& s) {
  const double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double w[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  s = std::clamp(dd > 0 ? (w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) / dd : 0.0, 0.0, 1.0);
  const double e[3] = {w[0] - s * d[0], w[1] - s * d[1], w[2] - s * d[2]};
  return e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
}

/// Distance from `p` to the segment a-b [mm]; `closest` (if given) receives the segment's
/// nearest point.
double segment_distance(const Vec3& a, const Vec3& b, const Vec3& p, Vec3* closest = nullptr);


}  // namespace gcpipe::servo
