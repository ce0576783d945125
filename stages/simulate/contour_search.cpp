// simulate::ContourSearch: the one contour metric, over a sliding window of the nominal polyline.
#include <algorithm>
#include <cmath>
#include <limits>

#include "contour.hpp"
#include "simulate.hpp"

namespace gcpipe::simulate {

void ContourSearch::Box::add(const Vec3& p) {
  for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], p[k]), hi[k] = std::max(hi[k], p[k]);
}

// A quick test first: outside the box grown by `best` along one axis is farther than `best`.
// Most boxes of the window fail it on x or y, before the exact distance is needed.
bool ContourSearch::Box::within(const Vec3& p, double best) const {
  for (int k = 0; k < 3; ++k)
    if (p[k] < lo[k] - best || p[k] > hi[k] + best) return false;
  return distance_sq(p) < best * best;
}

double ContourSearch::Box::distance_sq(const Vec3& p) const {
  double dd = 0;
  for (int k = 0; k < 3; ++k) {
    const double o = std::max({lo[k] - p[k], 0.0, p[k] - hi[k]});
    dd += o * o;
  }
  return dd;
}

// Group g holds segments [g kGroup, (g + 1) kGroup), so its box holds points g kGroup ..
// (g + 1) kGroup; a point that ends one group's last segment also starts the next group.
void ContourSearch::push(const Vec3& p) {
  const std::size_t i = size();
  win_.push_back(p);
  if (i == 0) return;
  const std::size_t g = (i - 1) / kGroup;
  if (g - first_ / kGroup == boxes_.size()) {  // the first segment of a new group
    if (g % kGroupsPerSuper == 0) supers_.emplace_back();
    boxes_.emplace_back();
    boxes_.back().add(point(i - 1));
    supers_.back().add(point(i - 1));
  }
  boxes_.back().add(p);
  supers_.back().add(p);
  drop_old_points();
}

// Keeps the last kLookBack points and a super-group of slack behind them; drops older ones in
// whole super-groups, so that the boxes of the points kept stay as they were.
void ContourSearch::drop_old_points() {
  constexpr std::size_t kKeep = 2 * (kLookBack + kSuperSpan);
  if (win_.size() < kKeep) return;
  const std::size_t newest = size() - 1;
  const std::size_t new_first = (newest - kLookBack - kSuperSpan) / kSuperSpan * kSuperSpan;
  const std::size_t drop = new_first - first_;
  win_.erase(win_.begin(), win_.begin() + static_cast<std::ptrdiff_t>(drop));
  boxes_.erase(boxes_.begin(), boxes_.begin() + static_cast<std::ptrdiff_t>(drop / kGroup));
  supers_.erase(supers_.begin(), supers_.begin() + static_cast<std::ptrdiff_t>(drop / kSuperSpan));
  first_ = new_first;
}

namespace {

// The segment's bounding box grown by `best` leaves p out along one axis: farther than `best`.
bool outside_bounds(const Vec3& u, const Vec3& v, const Vec3& p, double best) {
  for (int k = 0; k < 3; ++k)
    if (p[k] < std::min(u[k], v[k]) - best || p[k] > std::max(u[k], v[k]) + best) return true;
  return false;
}

}  // namespace

// Squared distances (servo::segment_distance_sq, what segment_distance takes the root of): the
// minimum is the same number, and the square root is taken once per better match.
void ContourSearch::scan(std::size_t a, std::size_t b, const Vec3& p, Match& m) {
  for (std::size_t i = a; i < b; ++i) {  // segments [a, b)
    const Vec3& u = point(i);
    const Vec3& v = point(i + 1);
    if (outside_bounds(u, v, p, m.dist)) continue;  // no division for most segments of a group
    double s = 0;
    const double sq = servo::segment_distance_sq(u, v, p, s);
    if (sq < m.sq) m.sq = sq, m.s = s, m.segment = i, m.dist = std::sqrt(sq);
  }
}

double ContourSearch::distance(const Vec3& actual, std::size_t limit, Vec3& closest) {
  if (source_ != nullptr) {  // take the whole polyline's points up to the last segment's end
    const std::size_t want = std::min(std::max<std::size_t>(limit, 1) + 1, source_->size());
    while (size() < want) push((*source_)[size()]);
  }
  closest = win_.empty() ? actual : win_.front();
  if (size() < 2) return win_.empty() ? 0.0 : dist3(win_.front(), actual);
  const std::size_t hi = std::min(std::max<std::size_t>(limit, 1), size() - 1);  // last segment end
  const std::size_t lo = std::max(first_, hi > kLookBack ? hi - kLookBack : 0);
  Match m;
  // Start near the previous match: a tight bound makes the box test skip most groups. The match
  // moves about one segment per tick, as the nominal does.
  if (j_ >= lo && j_ < hi) scan(j_ > lo + 2 ? j_ - 2 : lo, std::min(hi, j_ + 8), actual, m);
  // Two levels of boxes: a group of 8 segments, a super-group of 64; a box farther than the best
  // match so far cannot hold a closer segment.
  const std::size_t g0 = first_ / kGroup, s0 = first_ / kSuperSpan;
  for (std::size_t sg = lo / kSuperSpan; sg * kSuperSpan < hi && sg - s0 < supers_.size(); ++sg) {
    if (!supers_[sg - s0].within(actual, m.dist)) continue;
    for (std::size_t g = sg * kGroupsPerSuper; g < (sg + 1) * kGroupsPerSuper && g * kGroup < hi && g - g0 < boxes_.size(); ++g) {
      if (g * kGroup + kGroup <= lo || !boxes_[g - g0].within(actual, m.dist)) continue;
      scan(std::max(lo, g * kGroup), std::min(hi, (g + 1) * kGroup), actual, m);
    }
  }
  j_ = m.segment;
  const Vec3& u = point(m.segment);
  const Vec3& v = point(m.segment + 1);
  closest = {u[0] + m.s * (v[0] - u[0]), u[1] + m.s * (v[1] - u[1]), u[2] + m.s * (v[2] - u[2])};
  return m.dist;
}

}  // namespace gcpipe::simulate
