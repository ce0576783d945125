// Contour error: the distance from the actual point to the nominal path (a polyline through the
// raw interpolated points, one per tick), not to the time-matched nominal point. A lagging axis
// that stays on the path has no contour error even though it trails in time.
#pragma once

#include <cstdint>
#include <deque>

#include "gcpipe/block.hpp"

namespace gcpipe::servo {

/// Distance from `p` to the segment a-b [mm]; `closest` (if given) receives the segment's
/// nearest point.
double segment_distance(const Vec3& a, const Vec3& b, const Vec3& p, Vec3* closest = nullptr);

class ContourTracker {
 public:
  /// `window`: how many of the newest nominal segments are searched. The actual trails the
  /// nominal by the smoothing and servo lag (tens of ms), so the nearest point of the path lies
  /// among the last few hundred ticks; a window keeps the cost per tick bounded and stops a
  /// match from jumping to a far part of a path that passes close by.
  explicit ContourTracker(std::size_t window = 600);
  /// Appends the next nominal point [mm].
  void add_nominal(const Vec3& p);
  /// Distance of `actual` to the nominal polyline near the previous match [mm]; 0 with no path.
  double distance(const Vec3& actual);

 private:
  std::deque<Vec3> pts_;
  std::size_t window_;
};

}  // namespace gcpipe::servo
