// The geometry of the contour error: the distance from a point to a segment of the nominal
// polyline. The search along the path is simulate::ContourSearch (stages/simulate).
#pragma once

#include <cstdint>

#include "gcpipe/block.hpp"

namespace gcpipe::servo {

/// Distance from `p` to the segment a-b [mm]; `closest` (if given) receives the segment's
/// nearest point.
double segment_distance(const Vec3& a, const Vec3& b, const Vec3& p, Vec3* closest = nullptr);


}  // namespace gcpipe::servo
