// simulate::ContourSearch: the one contour metric, over a sliding window of the nominal polyline.
#include <algorithm>
#include <bit>
#include <cstdint>
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

namespace {

// A lower bound puts a group or a segment beyond the best match only when it exceeds it by this
// much: far above the rounding of coordinates up to 10^5 mm, far below any distance that matters.
// The tests stay conservative, so that the search still returns exactly the minimum.
constexpr double kSlack = 1e-6;  // [mm]

constexpr double kUnknown = -std::numeric_limits<double>::infinity();  // a bound not measured yet

// The motion is summed from 0 again after this much [mm], every bound forgotten: the sum's
// rounding stays far below kSlack.
constexpr double kRebase = 1000;

// Bit k set when far[k] <= reach (n <= 64): the super-groups whose kept bound does not pass them
// over, compared side by side. For the 8 groups of a super-group the same cost more instructions
// than it saved (measured), so they keep their loop.
std::uint64_t within_reach(const double* far, std::size_t n, double reach) {
  std::uint64_t near = 0;
  for (std::size_t k = 0; k < n; ++k) near |= static_cast<std::uint64_t>(far[k] <= reach) << k;
  return near;
}

}  // namespace

// Capsules come in whole super-groups, the groups not opened yet infinitely wide.
void ContourSearch::Capsules::open() {
  if (groups++ % kGroupsPerSuper != 0) return;
  shape.resize(shape.size() + kGroupsPerSuper);
  far.resize(far.size() + kGroupsPerSuper, kUnknown);
}

void ContourSearch::Capsules::drop_front(std::size_t n) {
  const auto drop = [n](std::vector<double>& v) { v.erase(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(n)); };
  shape.erase(shape.begin(), shape.begin() + static_cast<std::ptrdiff_t>(n));
  drop(far);
  groups -= n;
}

// Distance from p to the chord less the radius: no point of the group is nearer.
double ContourSearch::Capsules::lower_bound(std::size_t i, const Vec3& p) const {
  const Shape& c = shape[i];
  const double w0 = p[0] - c.a[0], w1 = p[1] - c.a[1], w2 = p[2] - c.a[2];
  const double t = std::clamp((w0 * c.d[0] + w1 * c.d[1] + w2 * c.d[2]) * c.inv_dd, 0.0, 1.0);
  const double e0 = w0 - t * c.d[0], e1 = w1 - t * c.d[1], e2 = w2 - t * c.d[2];
  return std::sqrt(e0 * e0 + e1 * e1 + e2 * e2) - c.radius;
}

// The distance to the chord is convex along each segment, so the polyline's farthest point from
// the chord is one of its vertices.
void ContourSearch::close_group(std::size_t g) {
  const std::size_t c = g - first_ / kGroup;
  const Vec3& a = point(g * kGroup);
  const Vec3& b = point((g + 1) * kGroup);
  const Vec3 d{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  Capsules::Shape& shape = capsules_.shape[c];
  for (int k = 0; k < 3; ++k) shape.a[k] = a[k], shape.d[k] = d[k];
  const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  shape.inv_dd = dd > 0 ? 1 / dd : 0;
  double radius_sq = 0, s = 0;
  for (std::size_t i = g * kGroup + 1; i < (g + 1) * kGroup; ++i)
    radius_sq = std::max(radius_sq, servo::segment_distance_sq(a, b, point(i), s));
  shape.radius = std::sqrt(radius_sq);
  capsules_.far[c] = kUnknown;
}

// Group g holds segments [g kGroup, (g + 1) kGroup), so its capsule holds points g kGroup ..
// (g + 1) kGroup; a point that ends one group's last segment also starts the next group.
void ContourSearch::push(const Vec3& p) {
  const std::size_t i = size();
  win_.push_back(p);
  for (int k = 0; k < 3; ++k) coord_[k].push_back(p[k]);
  if (i == 0) return;
  add_step(point(i - 1), p);
  const std::size_t g = (i - 1) / kGroup;
  if (g - first_ / kGroup == capsules_.groups) {  // the first segment of a new group
    if (g % kGroupsPerSuper == 0) supers_.open(point(i - 1)), super_far_.push_back(kUnknown);
    capsules_.open();
  }
  supers_.grow(p);
  super_far_.back() = kUnknown;
  if (i % kGroup == 0) close_group(g);
  drop_old_points();
}

// Segment a-b's vector and squared length, in servo::segment_distance_sq's arithmetic and order,
// kept so that each measurement of the segment does not work them out again.
void ContourSearch::add_step(const Vec3& a, const Vec3& b) {
  const double d0 = b[0] - a[0], d1 = b[1] - a[1], d2 = b[2] - a[2];
  step_[0].push_back(d0), step_[1].push_back(d1), step_[2].push_back(d2);
  step_[3].push_back(d0 * d0 + d1 * d1 + d2 * d2);
}

// Keeps the last kLookBack points and a super-group of slack behind them; drops older ones in
// whole super-groups, so that the boxes of the points kept stay as they were.
void ContourSearch::drop_old_points() {
  constexpr std::size_t kKeep = 2 * (kLookBack + kSuperSpan);
  if (keep_all_ || win_.size() < kKeep) return;
  const std::size_t newest = size() - 1;
  const std::size_t new_first = (newest - kLookBack - kSuperSpan) / kSuperSpan * kSuperSpan;
  const std::size_t drop = new_first - first_;
  win_.erase(win_.begin(), win_.begin() + static_cast<std::ptrdiff_t>(drop));
  for (auto& c : coord_) c.erase(c.begin(), c.begin() + static_cast<std::ptrdiff_t>(drop));
  for (auto& c : step_) c.erase(c.begin(), c.begin() + static_cast<std::ptrdiff_t>(drop));
  capsules_.drop_front(drop / kGroup);
  supers_.drop_front(drop / kSuperSpan);
  super_far_.erase(super_far_.begin(), super_far_.begin() + static_cast<std::ptrdiff_t>(drop / kSuperSpan));
  first_ = new_first;
}

// Squared distances (what servo::segment_distance takes the root of): the minimum is the same
// number, and the square root is taken once per better match. The segments are measured side by
// side, then taken in order: the first strictly nearer one wins, as in a scan one by one. A
// segment measured twice (the warm start's) gives the same number again and changes nothing.
void ContourSearch::scan(std::size_t a, std::size_t b, const Vec3& p, Match& m) const {
  constexpr std::size_t kBatch = 16;
  double sq[kBatch], s[kBatch];
  for (std::size_t from = a; from < b; from += kBatch) {
    const std::size_t n = std::min(kBatch, b - from);
    measure(from, n, p, sq, s);
    // The batch's least first (no branch per segment), then its first occurrence: the match a
    // scan one by one would end with.
    double least = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < n; ++k) least = sq[k] < least ? sq[k] : least;
    if (!(least < m.sq)) continue;
    std::size_t k = 0;
    while (sq[k] != least) ++k;
    m.sq = least, m.s = s[k], m.segment = from + k, m.dist = std::sqrt(least);
  }
}

// [a, b) less the segments [done.a, done.b) measured already (the warm start's): measured again
// they would only give the same numbers.
void ContourSearch::scan_except(std::size_t a, std::size_t b, const Range& done, const Vec3& p, Match& m) const {
  if (done.b <= a || b <= done.a) return scan(a, b, p, m);
  if (a < done.a) scan(a, done.a, p, m);
  if (done.b < b) scan(done.b, b, p, m);
}

// Segments a .. a+n-1 (global index), servo::segment_distance_sq's arithmetic in its order on
// each: the same doubles, computed two at a time from the arrays per axis. (An AVX2 clone of this
// loop, four at a time behind an ifunc, took 7 % fewer instructions of the whole run but made the
// search 14 % slower: 294 -> 338 ns a tick on the bench's geometry; the call is no longer inlined
// and the batches are short.)
void ContourSearch::measure(std::size_t a, std::size_t n, const Vec3& p, double* __restrict__ sq,
                            double* __restrict__ s) const {
  const double* x = coord_[0].data() + (a - first_);
  const double* y = coord_[1].data() + (a - first_);
  const double* z = coord_[2].data() + (a - first_);
  const double* dx = step_[0].data() + (a - first_);
  const double* dy = step_[1].data() + (a - first_);
  const double* dz = step_[2].data() + (a - first_);
  const double* ddv = step_[3].data() + (a - first_);
  for (std::size_t k = 0; k < n; ++k) {
    const double d0 = dx[k], d1 = dy[k], d2 = dz[k], dd = ddv[k];
    const double w0 = p[0] - x[k], w1 = p[1] - y[k], w2 = p[2] - z[k];
    const double t = std::clamp(dd > 0 ? (w0 * d0 + w1 * d1 + w2 * d2) / dd : 0.0, 0.0, 1.0);
    const double e0 = w0 - t * d0, e1 = w1 - t * d1, e2 = w2 - t * d2;
    sq[k] = e0 * e0 + e1 * e1 + e2 * e2;
    s[k] = t;
  }
}

// Each step is rounded up (relative and absolute) so that the sum never falls short of the path
// the actual took: an earlier bound less the motion since stays a bound.
void ContourSearch::add_motion(const Vec3& actual) {
  if (last_actual_) motion_ += dist3(*last_actual_, actual) * (1 + 1e-12) + 1e-12;
  last_actual_ = actual;
  if (motion_ <= kRebase) return;
  motion_ = 0;
  std::fill(super_far_.begin(), super_far_.end(), kUnknown);
  std::fill(capsules_.far.begin(), capsules_.far.end(), kUnknown);
}

void ContourSearch::rewind() {
  motion_ = 0;
  last_actual_.reset();
  j_ = 0;
  std::fill(super_far_.begin(), super_far_.end(), kUnknown);
  std::fill(capsules_.far.begin(), capsules_.far.end(), kUnknown);
}

void ContourSearch::begin_search(const Vec3& actual, std::size_t limit, std::size_t& lo, std::size_t& hi, Range& warm,
                                 Match& m) {
  hi = std::min(std::max<std::size_t>(limit, 1), size() - 1);  // last segment end
  lo = std::max(first_, hi > kLookBack ? hi - kLookBack : 0);
  add_motion(actual);
  // Start near the previous match: a tight bound makes the tests below skip most groups. The match
  // moves about one segment per tick, as the nominal does.
  warm = {0, 0};
  if (j_ >= lo && j_ < hi) warm = {j_ > lo + 2 ? j_ - 2 : lo, std::min(hi, j_ + 8)}, scan(warm.a, warm.b, actual, m);
}

// Takes the whole polyline's points up to the last segment's end (whole-polyline form); false
// when there is no segment to search yet (`closest` and the distance are then the first point's).
bool ContourSearch::take_points(const Vec3& actual, std::size_t limit, Vec3& closest, double& distance) {
  if (source_ != nullptr) {
    const std::size_t want = std::min(std::max<std::size_t>(limit, 1) + 1, source_->size());
    while (size() < want) push((*source_)[size()]);
  }
  if (size() >= 2) return true;
  closest = win_.empty() ? actual : win_.front();
  distance = win_.empty() ? 0.0 : dist3(win_.front(), actual);
  return false;
}

double ContourSearch::distance_beyond(const Vec3& actual, std::size_t limit, double bound, Vec3& closest) {
  double d = 0;
  if (!take_points(actual, limit, closest, d)) return d;
  std::size_t lo = 0, hi = 0;
  Range warm{0, 0};
  Match m;
  begin_search(actual, limit, lo, hi, warm, m);
  // No bound (distance()): never true, the window is searched.
  if (warm.b > warm.a && m.dist <= bound) return finish(m, closest);
  return search_window(actual, lo, hi, warm, m, closest);
}

// Two levels: a super-group of 64 segments (its box), a group of 8 (its capsule); one farther
// than the best match so far cannot hold a closer segment. One whose earlier distance, less the
// motion since, still exceeds the best match is passed over; the others are measured again.
double ContourSearch::search_window(const Vec3& actual, std::size_t lo, std::size_t hi, const Range& warm, Match& m,
                                    Vec3& closest) {
  const std::size_t s0 = first_ / kSuperSpan;
  const std::size_t sa = lo / kSuperSpan - s0, sb = std::min(supers_.size(), (hi + kSuperSpan - 1) / kSuperSpan - s0);
  // far - motion_ > best + kSlack as far > reach: one comparison per super-group passed over (the
  // slack covers the different rounding).
  // The candidates are picked first, all compared side by side (within_reach()), then tested
  // again with the reach of the moment, which only shrinks.
  double reach = m.dist + kSlack + motion_;
  static_assert(kLookBack / kSuperSpan + 2 <= 64, "the window's super-groups fit in a mask");
  for (std::uint64_t near = within_reach(super_far_.data() + sa, sb > sa ? sb - sa : 0, reach); near != 0; near &= near - 1) {
    const std::size_t k = sa + static_cast<std::size_t>(std::countr_zero(near));
    if (super_far_[k] > reach) continue;
    const double sq = supers_.distance_sq(k, actual);
    super_far_[k] = std::sqrt(sq) + motion_;
    if (sq < m.sq) scan_super(k + s0, lo, hi, warm, actual, m), reach = m.dist + kSlack + motion_;
  }
  return finish(m, closest);
}

double ContourSearch::finish(const Match& m, Vec3& closest) {
  j_ = m.segment;
  const Vec3& u = point(m.segment);
  const Vec3& v = point(m.segment + 1);
  closest = {u[0] + m.s * (v[0] - u[0]), u[1] + m.s * (v[1] - u[1]), u[2] + m.s * (v[2] - u[2])};
  return m.dist;
}

// The groups of super-group `sg` (global index) within the window [lo, hi), in order: those whose
// capsule may hold a segment nearer than the best match. A group's capsule bound is kept as the
// super-groups' are (plus the motion then, less the motion since): the groups beside a turn's
// nearest one are passed over for several ticks with one comparison.
void ContourSearch::scan_super(std::size_t sg, std::size_t lo, std::size_t hi, const Range& warm, const Vec3& p,
                               Match& m) {
  const std::size_t g0 = first_ / kGroup, first_group = sg * kGroupsPerSuper;
  const std::size_t ga = std::max(first_group, lo / kGroup);
  const std::size_t gb = std::min({first_group + kGroupsPerSuper, (hi + kGroup - 1) / kGroup, g0 + capsules_.groups});
  double reach = m.dist + kSlack + motion_;
  for (std::size_t g = ga; g < gb; ++g) {
    double& far = capsules_.far[g - g0];
    if (far > reach) continue;
    const double bound = capsules_.lower_bound(g - g0, p);
    far = bound + motion_;
    if (bound > m.dist + kSlack) continue;
    scan_except(std::max(lo, g * kGroup), std::min(hi, (g + 1) * kGroup), warm, p, m);
    reach = m.dist + kSlack + motion_;
  }
}

}  // namespace gcpipe::simulate
