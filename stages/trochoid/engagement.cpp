#include "engagement.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace gcpipe {

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

// The part of [0, 2pi) not yet covered, as sorted disjoint intervals.
struct Uncovered {
  std::vector<std::pair<double, double>> iv{{0.0, kTwoPi}};

  void subtract_one(double a, double b) {
    std::vector<std::pair<double, double>> next;
    next.reserve(iv.size() + 1);
    for (auto [lo, hi] : iv) {
      if (b <= lo || a >= hi) {
        next.emplace_back(lo, hi);
        continue;
      }
      if (a > lo) next.emplace_back(lo, a);
      if (b < hi) next.emplace_back(b, hi);
    }
    if (next != iv) dirty = true;
    iv.swap(next);
  }
  // Removes the arc centred at `c` with half-width `h` (h < pi).
  void subtract_arc(double c, double h) {
    c = std::fmod(c, kTwoPi);
    if (c < 0) c += kTwoPi;
    double a = c - h, b = c + h;
    if (a < 0) {
      subtract_one(a + kTwoPi, kTwoPi);
      subtract_one(0.0, b);
    } else if (b > kTwoPi) {
      subtract_one(a, kTwoPi);
      subtract_one(0.0, b - kTwoPi);
    } else {
      subtract_one(a, b);
    }
  }
  double measure() const {
    double m = 0;
    for (auto [lo, hi] : iv) m += hi - lo;
    return m;
  }
  // True when the disc of radius r around q can reach some uncovered point of the circle of
  // radius r around p: a cheap test that spares the trigonometry for most far samples. The
  // bounding circle of each uncovered arc is cached until the set changes.
  bool reachable(const Point2& p, const Point2& q, double r) {
    const double rp = radius;
    if (dirty) {
      bound.clear();
      for (auto [lo, hi] : iv) {
        const double mid = 0.5 * (lo + hi), half = 0.5 * (hi - lo);
        // Any point within `r` (here r + eps) of the arc is within r + chord/2 of its middle.
        const double reach = r + 2.0 * rp * std::sin(std::min(half, std::numbers::pi) * 0.5);
        bound.push_back({p.x + rp * std::cos(mid), p.y + rp * std::sin(mid), reach * reach});
      }
      dirty = false;
    }
    for (const auto& b : bound) {
      const double dx = q.x - b[0], dy = q.y - b[1];
      if (dx * dx + dy * dy <= b[2]) return true;
    }
    return false;
  }
  std::vector<std::array<double, 3>> bound;
  bool dirty = true;
  double radius = 0;  // of p's circle
};

// Part of the probe circle (radius rp around p) inside the disc of radius r around q.
void cover_disc(Uncovered& u, const Point2& p, const Point2& q, double rp, double r) {
  const double dx = q.x - p.x, dy = q.y - p.y;
  const double d2 = dx * dx + dy * dy;
  if (d2 >= (r + rp) * (r + rp)) return;
  const double d = std::sqrt(d2);
  if (d + rp <= r) {
    u.iv.clear();
    return;
  }
  const double c = (d2 + rp * rp - r * r) / (2.0 * d * rp);
  u.subtract_arc(std::atan2(dy, dx), std::acos(std::clamp(c, -1.0, 1.0)));
}

// Circle points x = p + r e(t) with r w.e(t) <= k: an arc, the whole circle, or nothing.
// Returns false for nothing; sets full for the whole circle.
bool half_plane_arc(double wx, double wy, double k, double r, double& centre, double& half,
                    bool& full) {
  full = false;
  if (k >= r) {
    full = true;
    return true;
  }
  if (k < -r) return false;
  centre = std::atan2(wy, wx) + std::numbers::pi;  // the arc is centred opposite to w
  half = std::numbers::pi - std::acos(k / r);
  return true;
}

// Part of the probe circle (radius rp around p) within r of the segment [a, b] (the capsule
// swept by the tool moving from a to b). `with_end_disc` false leaves out the disc at b (the
// query point itself).
void cover_capsule(Uncovered& u, const Point2& p, const Point2& a, const Point2& b, double rp,
                   double r, bool with_end_disc) {
  cover_disc(u, p, a, rp, r);
  if (u.iv.empty()) return;
  if (with_end_disc) cover_disc(u, p, b, rp, r);
  const double ux0 = b.x - a.x, uy0 = b.y - a.y;
  const double len = std::hypot(ux0, uy0);
  if (len == 0.0 || u.iv.empty()) return;
  const double ux = ux0 / len, uy = uy0 / len, nx = -uy, ny = ux;
  const double s0 = ux * (p.x - a.x) + uy * (p.y - a.y);  // p's position along the segment
  const double h0 = nx * (p.x - a.x) + ny * (p.y - a.y);  // .. and across it
  // Strip: 0 <= s0 + rp u.e <= len and |h0 + rp n.e| <= r.
  const double w[4][3] = {{-ux, -uy, s0}, {ux, uy, len - s0}, {nx, ny, r - h0}, {-nx, -ny, r + h0}};
  std::vector<std::pair<double, double>> strip{{0.0, kTwoPi}};
  for (const auto& c : w) {
    double centre = 0, half = 0;
    bool full = false;
    if (!half_plane_arc(c[0], c[1], c[2], rp, centre, half, full)) return;
    if (full) continue;
    // Intersect `strip` with the arc [centre - half, centre + half] (mod 2pi).
    centre = std::fmod(centre, kTwoPi);
    if (centre < 0) centre += kTwoPi;
    std::vector<std::pair<double, double>> arc;
    const double lo = centre - half, hi = centre + half;
    if (lo < 0) {
      arc = {{0.0, hi}, {lo + kTwoPi, kTwoPi}};
    } else if (hi > kTwoPi) {
      arc = {{0.0, hi - kTwoPi}, {lo, kTwoPi}};
    } else {
      arc = {{lo, hi}};
    }
    std::vector<std::pair<double, double>> next;
    for (auto [a0, a1] : strip)
      for (auto [b0, b1] : arc) {
        const double l = std::max(a0, b0), h = std::min(a1, b1);
        if (h > l) next.emplace_back(l, h);
      }
    strip.swap(next);
    if (strip.empty()) return;
  }
  for (auto [lo, hi] : strip) u.subtract_one(lo, hi);
}

// Arcs shorter than this are rounding noise where the circle grazes an outline [rad].
constexpr double kNoise = 1e-7;

double measure_without_noise(const Uncovered& u) {
  double m = 0;
  for (auto [lo, hi] : u.iv)
    if (hi - lo > kNoise) m += hi - lo;
  return m;
}

}  // namespace

double equivalent_ae(double engaged_angle, double tool_radius) {
  if (engaged_angle >= std::numbers::pi) return 2.0 * tool_radius;
  return tool_radius * (1.0 - std::cos(engaged_angle));
}

double engaged_angle_polyline(const Point2* v, std::size_t n, double tool_radius,
                              double min_chip) {
  if (n == 0) return 0.0;
  if (n == 1) return kTwoPi;
  const Point2 p = v[n - 1];
  Uncovered u;
  u.radius = tool_radius;
  // Most recent first: they cover most of the circle, so the set shrinks early.
  double back = 0;  // path length from the segment's end to p
  for (std::size_t k = n - 1; k-- > 0;) {
    const Point2 mid{0.5 * (v[k].x + v[k + 1].x), 0.5 * (v[k].y + v[k + 1].y)};
    const double len = std::hypot(v[k + 1].x - v[k].x, v[k + 1].y - v[k].y);
    const double rc = back > kRecentTrail ? tool_radius + min_chip : tool_radius;
    back += len;
    if (!u.reachable(p, mid, rc + 0.5 * len)) continue;
    cover_capsule(u, p, v[k], v[k + 1], tool_radius, rc, k + 1 != n - 1);
    if (u.iv.empty()) return 0.0;
  }
  return measure_without_noise(u);
}

ExactEngagement::ExactEngagement(std::vector<Point2> vertices, std::vector<std::uint8_t> piece_start,
                                 double tool_radius, double min_chip)
    : v_(std::move(vertices)), start_(std::move(piece_start)), r_(tool_radius), h_(min_chip) {
  if (!(min_chip >= 0 && min_chip < tool_radius))
    throw std::invalid_argument("ExactEngagement: min_chip must be in [0, tool radius)");
  s_.assign(v_.size(), 0.0);
  for (std::size_t k = 1; k < v_.size(); ++k)
    s_[k] = s_[k - 1] + (start_[k] ? 0.0 : std::hypot(v_[k].x - v_[k - 1].x, v_[k].y - v_[k - 1].y));
  if (!(tool_radius > 0)) throw std::invalid_argument("ExactEngagement: tool radius must be > 0");
  if (start_.size() != v_.size()) throw std::invalid_argument("ExactEngagement: one flag per vertex");
  if (v_.empty()) return;
  double xmin = v_[0].x, xmax = xmin, ymin = v_[0].y, ymax = ymin, longest = 0;
  for (std::size_t i = 0; i < v_.size(); ++i) {
    xmin = std::min(xmin, v_[i].x);
    xmax = std::max(xmax, v_[i].x);
    ymin = std::min(ymin, v_[i].y);
    ymax = std::max(ymax, v_[i].y);
    if (i > 0 && !start_[i]) longest = std::max(longest, std::hypot(v_[i].x - v_[i - 1].x, v_[i].y - v_[i - 1].y));
  }
  // Segments are filed under the cell of their midpoint; a query looks as far as 2r + half the
  // longest segment.
  cell_ = 2.0 * r_ + h_ + 0.5 * longest;
  x0_ = xmin;
  y0_ = ymin;
  nx_ = std::int64_t((xmax - xmin) / cell_) + 1;
  ny_ = std::int64_t((ymax - ymin) / cell_) + 1;
  cells_.resize(std::size_t(nx_ * ny_));
  // Item k: the segment ending at vertex k, or the lone disc of a piece's first vertex.
  for (std::size_t k = 0; k < v_.size(); ++k) {
    const Point2 m = start_[k] ? v_[k] : Point2{0.5 * (v_[k].x + v_[k - 1].x), 0.5 * (v_[k].y + v_[k - 1].y)};
    const auto cx = std::int64_t((m.x - x0_) / cell_);
    const auto cy = std::int64_t((m.y - y0_) / cell_);
    cells_[std::size_t(cy * nx_ + cx)].push_back(std::uint32_t(k));
  }
}

double ExactEngagement::angle_at(std::size_t i) const { return angle_at(i, 0); }

double ExactEngagement::angle_at(std::size_t i, std::size_t first) const {
  const Point2 p = v_.at(i);
  const auto cx = std::int64_t((p.x - x0_) / cell_);
  const auto cy = std::int64_t((p.y - y0_) / cell_);
  std::vector<std::uint32_t> cand;
  for (std::int64_t y = std::max<std::int64_t>(0, cy - 1); y <= std::min(ny_ - 1, cy + 1); ++y)
    for (std::int64_t x = std::max<std::int64_t>(0, cx - 1); x <= std::min(nx_ - 1, cx + 1); ++x)
      for (std::uint32_t k : cells_[std::size_t(y * nx_ + x)])
        if (k <= i && k >= first) cand.push_back(k);
  std::sort(cand.begin(), cand.end(), std::greater<>());
  Uncovered u;
  u.radius = r_;
  for (std::uint32_t k : cand) {
    if (k == i && start_[k]) continue;  // the tool arrives here: nothing of its own behind it
    const double rc = s_[i] - s_[k] > kRecentTrail ? r_ + h_ : r_;
    if (start_[k] || k == first) {
      if (k != i) cover_disc(u, p, v_[k], r_, rc);
    } else {
      const Point2 a = v_[k - 1], b = v_[k];
      const Point2 mid{0.5 * (a.x + b.x), 0.5 * (a.y + b.y)};
      if (!u.reachable(p, mid, rc + 0.5 * std::hypot(b.x - a.x, b.y - a.y))) continue;
      cover_capsule(u, p, a, b, r_, rc, k != i);
    }
    if (u.iv.empty()) return 0.0;
  }
  return measure_without_noise(u);
}

MaterialGrid::MaterialGrid(double xmin, double ymin, double xmax, double ymax, double pixel)
    : x0_(xmin), y0_(ymin), h_(pixel) {
  if (!(pixel > 0) || !(xmax > xmin) || !(ymax > ymin))
    throw std::invalid_argument("MaterialGrid: empty extent or non-positive pixel");
  nx_ = int(std::ceil((xmax - xmin) / pixel));
  ny_ = int(std::ceil((ymax - ymin) / pixel));
  cells_.assign(std::size_t(nx_) * std::size_t(ny_), 1);
}

bool MaterialGrid::material(double x, double y) const {
  const double fx = (x - x0_) / h_, fy = (y - y0_) / h_;
  if (fx < 0 || fy < 0) return false;
  const int ix = int(fx), iy = int(fy);
  if (ix >= nx_ || iy >= ny_) return false;
  return material_at(ix, iy);
}

double MaterialGrid::engaged_angle(double x, double y, double r, int probes) const {
  int hits = 0;
  for (int k = 0; k < probes; ++k) {
    const double a = kTwoPi * (k + 0.5) / probes;
    hits += material(x + r * std::cos(a), y + r * std::sin(a)) ? 1 : 0;
  }
  return kTwoPi * hits / probes;
}

void MaterialGrid::fill_span(int iy, double xa, double xb) {
  if (iy < 0 || iy >= ny_ || xb < xa) return;
  int a = int(std::ceil((xa - x0_) / h_ - 0.5));
  int b = int(std::floor((xb - x0_) / h_ - 0.5));
  a = std::max(a, 0);
  b = std::min(b, nx_ - 1);
  if (b < a) return;
  std::fill(cells_.begin() + std::ptrdiff_t(std::size_t(iy) * nx_ + a),
            cells_.begin() + std::ptrdiff_t(std::size_t(iy) * nx_ + b + 1), std::uint8_t{0});
}

void MaterialGrid::remove_disc(double x, double y, double r) {
  const int lo = std::max(0, int(std::ceil((y - r - y0_) / h_ - 0.5)));
  const int hi = std::min(ny_ - 1, int(std::floor((y + r - y0_) / h_ - 0.5)));
  for (int iy = lo; iy <= hi; ++iy) {
    const double dy = y_of(iy) - y;
    const double half = std::sqrt(std::max(0.0, r * r - dy * dy));
    fill_span(iy, x - half, x + half);
  }
}

void MaterialGrid::remove_disc_after(double px, double py, double x, double y, double r) {
  const int lo = std::max(0, int(std::ceil((y - r - y0_) / h_ - 0.5)));
  const int hi = std::min(ny_ - 1, int(std::floor((y + r - y0_) / h_ - 0.5)));
  for (int iy = lo; iy <= hi; ++iy) {
    const double yc = y_of(iy);
    const double dy = yc - y;
    const double half = std::sqrt(std::max(0.0, r * r - dy * dy));
    const double a = x - half, b = x + half;
    const double dpy = yc - py;
    if (dpy * dpy > r * r) {
      fill_span(iy, a, b);
      continue;
    }
    const double ph = std::sqrt(r * r - dpy * dpy);
    const double pa = px - ph, pb = px + ph;
    if (pb < a || pa > b) {
      fill_span(iy, a, b);
    } else {
      fill_span(iy, a, std::min(b, pa));
      fill_span(iy, std::max(a, pb), b);
    }
  }
}

double MaterialGrid::sweep(Point2 a, Point2 b, double r) {
  const double len = std::hypot(b.x - a.x, b.y - a.y);
  const int steps = std::max(1, int(std::ceil(len / h_)));
  double worst = 0;
  Point2 prev = a;
  for (int k = 1; k <= steps; ++k) {
    const double t = double(k) / steps;
    const Point2 q{a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t};
    worst = std::max(worst, engaged_angle(q.x, q.y, r));
    remove_disc_after(prev.x, prev.y, q.x, q.y, r);
    prev = q;
  }
  return worst;
}

}  // namespace gcpipe
