// simulate::ContourSearch: the one contour metric, over a sliding window of the nominal polyline.
#include <algorithm>
#include <cmath>
#include <limits>

#include "contour.hpp"
#include "simulate.hpp"

namespace gcpipe::simulate {

void ContourSearch::Boxes::open(const Vec3& p) {
  for (int k = 0; k < 3; ++k) lo[k].push_back(p[k]), hi[k].push_back(p[k]);
}

void ContourSearch::Boxes::grow(const Vec3& p) {
  for (int k = 0; k < 3; ++k) lo[k].back() = std::min(lo[k].back(), p[k]), hi[k].back() = std::max(hi[k].back(), p[k]);
}

void ContourSearch::Boxes::drop_front(std::size_t n) {
  for (int k = 0; k < 3; ++k) {
    lo[k].erase(lo[k].begin(), lo[k].begin() + static_cast<std::ptrdiff_t>(n));
    hi[k].erase(hi[k].begin(), hi[k].begin() + static_cast<std::ptrdiff_t>(n));
  }
}

double ContourSearch::Boxes::distance_sq(std::size_t i, const Vec3& p) const {
  double dd = 0;
  for (int k = 0; k < 3; ++k) {
    const double o = std::max({lo[k][i] - p[k], 0.0, p[k] - hi[k][i]});
    dd += o * o;
  }
  return dd;
}

// Bitwise & of the six comparisons, no early exit: the loop has no branch to mispredict.
void ContourSearch::Boxes::near(std::size_t a, std::size_t b, const Vec3& p, double best, std::uint8_t* hit) const {
  const double* lx = lo[0].data(); const double* ly = lo[1].data(); const double* lz = lo[2].data();
  const double* hx = hi[0].data(); const double* hy = hi[1].data(); const double* hz = hi[2].data();
  const double x0 = p[0] + best, x1 = p[0] - best, y0 = p[1] + best, y1 = p[1] - best;
  const double z0 = p[2] + best, z1 = p[2] - best;
  for (std::size_t i = a; i < b; ++i)
    hit[i - a] = static_cast<std::uint8_t>((lx[i] <= x0) & (hx[i] >= x1) & (ly[i] <= y0) & (hy[i] >= y1) &
                                           (lz[i] <= z0) & (hz[i] >= z1));
}

// Group g holds segments [g kGroup, (g + 1) kGroup), so its box holds points g kGroup ..
// (g + 1) kGroup; a point that ends one group's last segment also starts the next group.
void ContourSearch::push(const Vec3& p) {
  const std::size_t i = size();
  win_.push_back(p);
  if (i == 0) return;
  const std::size_t g = (i - 1) / kGroup;
  if (g - first_ / kGroup == boxes_.size()) {  // the first segment of a new group
    if (g % kGroupsPerSuper == 0) supers_.open(point(i - 1));
    boxes_.open(point(i - 1));
  }
  boxes_.grow(p);
  supers_.grow(p);
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
  boxes_.drop_front(drop / kGroup);
  supers_.drop_front(drop / kSuperSpan);
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
void ContourSearch::scan(std::size_t a, std::size_t b, const Vec3& p, Match& m) const {
  for (std::size_t i = a; i < b; ++i) {  // segments [a, b)
    if (i >= warm_a_ && i < warm_b_) continue;  // scanned by the warm start: no closer there
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
  warm_a_ = warm_b_ = 0;
  if (j_ >= lo && j_ < hi) {
    scan(j_ > lo + 2 ? j_ - 2 : lo, std::min(hi, j_ + 8), actual, m);
    warm_a_ = j_ > lo + 2 ? j_ - 2 : lo, warm_b_ = std::min(hi, j_ + 8);
  }
  // Two levels of boxes: a group of 8 segments, a super-group of 64; a box farther than the best
  // match so far cannot hold a closer segment. All super-groups of the window are tested at once
  // against the bound of the warm start; those near enough, and their groups, again against the
  // best match so far.
  const std::size_t s0 = first_ / kSuperSpan;
  const std::size_t sa = lo / kSuperSpan - s0, sb = std::min(supers_.size(), (hi + kSuperSpan - 1) / kSuperSpan - s0);
  if (sa >= sb) return finish(m, closest);
  hit_.resize(sb - sa);
  supers_.near(sa, sb, actual, m.dist, hit_.data());
  for (std::size_t k = sa; k < sb; ++k)
    if (hit_[k - sa] && supers_.distance_sq(k, actual) < m.sq) scan_super(k + s0, lo, hi, actual, m);
  return finish(m, closest);
}

double ContourSearch::finish(const Match& m, Vec3& closest) {
  j_ = m.segment;
  const Vec3& u = point(m.segment);
  const Vec3& v = point(m.segment + 1);
  closest = {u[0] + m.s * (v[0] - u[0]), u[1] + m.s * (v[1] - u[1]), u[2] + m.s * (v[2] - u[2])};
  return m.dist;
}

// The groups of super-group `sg` (global index) within the window [lo, hi), in order.
void ContourSearch::scan_super(std::size_t sg, std::size_t lo, std::size_t hi, const Vec3& p, Match& m) const {
  const std::size_t g0 = first_ / kGroup;
  const std::size_t ga = std::max(sg * kGroupsPerSuper, lo / kGroup);
  const std::size_t gb = std::min({(sg + 1) * kGroupsPerSuper, (hi + kGroup - 1) / kGroup, g0 + boxes_.size()});
  std::uint8_t hit[kGroupsPerSuper];
  if (ga >= gb) return;
  boxes_.near(ga - g0, gb - g0, p, m.dist, hit);
  for (std::size_t g = ga; g < gb; ++g)
    if (hit[g - ga] && boxes_.distance_sq(g - g0, p) < m.sq)
      scan(std::max(lo, g * kGroup), std::min(hi, (g + 1) * kGroup), p, m);
}

}  // namespace gcpipe::simulate
