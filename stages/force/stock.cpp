#include "stock.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

namespace gcpipe::force {

HeightField::HeightField(double xmin, double ymin, double xmax, double ymax, double top, double cell)
    : x0_(xmin), y0_(ymin), h_(cell) {
  nx_ = static_cast<int>(std::ceil((xmax - xmin) / cell)) + 1;
  ny_ = static_cast<int>(std::ceil((ymax - ymin) / cell)) + 1;
  top_.assign(static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_), static_cast<float>(top));
}

double HeightField::height(double x, double y) const {
  const long ix = std::lround((x - x0_) / h_), iy = std::lround((y - y0_) / h_);
  if (ix < 0 || iy < 0 || ix >= nx_ || iy >= ny_) return -std::numeric_limits<double>::infinity();
  return top_[static_cast<std::size_t>(iy) * static_cast<std::size_t>(nx_) + static_cast<std::size_t>(ix)];
}

void HeightField::cut_row(int iy, double xa, double xb, float z) {
  const int ix0 = std::max(0, static_cast<int>(std::ceil((xa - x0_) / h_)));
  const int ix1 = std::min(nx_ - 1, static_cast<int>(std::floor((xb - x0_) / h_)));
  float* row = top_.data() + static_cast<std::size_t>(iy) * static_cast<std::size_t>(nx_);
  for (int ix = ix0; ix <= ix1; ++ix) row[ix] = std::min(row[ix], z);
}

void HeightField::cut_disc(double x, double y, double r, double z) {
  const int iy0 = std::max(0, static_cast<int>(std::ceil((y - r - y0_) / h_)));
  const int iy1 = std::min(ny_ - 1, static_cast<int>(std::floor((y + r - y0_) / h_)));
  for (int iy = iy0; iy <= iy1; ++iy) {
    const double dy = y0_ + iy * h_ - y;
    const double half = std::sqrt(std::max(r * r - dy * dy, 0.0));
    cut_row(iy, x - half, x + half, static_cast<float>(z));
  }
}

void HeightField::cut_disc_after(double px, double py, double x, double y, double r, double z) {
  const int iy0 = std::max(0, static_cast<int>(std::ceil((y - r - y0_) / h_)));
  const int iy1 = std::min(ny_ - 1, static_cast<int>(std::floor((y + r - y0_) / h_)));
  const float zf = static_cast<float>(z);
  for (int iy = iy0; iy <= iy1; ++iy) {
    const double yy = y0_ + iy * h_;
    const double half = std::sqrt(std::max(r * r - (yy - y) * (yy - y), 0.0));
    const double dp = yy - py;
    if (dp * dp >= r * r) {  // the row misses the old disc: all of it is new
      cut_row(iy, x - half, x + half, zf);
      continue;
    }
    // New span minus the old one: at most two pieces; the old span's own nodes are done.
    const double ph = std::sqrt(r * r - dp * dp);
    const double pa = px - ph, pb = px + ph;
    if (x - half < pa) cut_row(iy, x - half, std::min(x + half, pa), zf);
    if (x + half > pb) cut_row(iy, std::max(x - half, pb), x + half, zf);
  }
}

SweptStock::SweptStock(HeightField field, double tool_radius, double recent)
    : field_(std::move(field)), r_(tool_radius), rp_(tool_radius - field_.cell()), recent_(recent) {}

void SweptStock::flush_before(double s) {
  std::size_t n = 0;
  for (; n < trail_.size() && trail_[n].s < s; ++n) {
    const Disc& d = trail_[n];
    // Only the crescent when the last disc on the grid is at or below this one (a descending
    // helix re-cuts the whole disc).
    if (have_last_ && last_.z <= d.z) field_.cut_disc_after(last_.x, last_.y, d.x, d.y, r_, d.z);
    else field_.cut_disc(d.x, d.y, r_, d.z);
    last_ = d;
    have_last_ = true;
  }
  trail_.erase(trail_.begin(), trail_.begin() + static_cast<std::ptrdiff_t>(n));
}

void SweptStock::cut(double x, double y, double z, double s) {
  trail_.push_back({x, y, z, s});
  flush_before(s - recent_);
}

void SweptStock::end_run() {
  flush_before(std::numeric_limits<double>::infinity());
  have_last_ = false;
}

double SweptStock::top_at(double x, double y) const {
  double top = field_.height(x, y);
  for (const Disc& d : trail_)
    if ((x - d.x) * (x - d.x) + (y - d.y) * (y - d.y) < rp_ * rp_) top = std::min(top, d.z);
  return top;
}

Engagement engagement_at(const SweptStock& stock, double x, double y, double z, double ux, double uy,
                         double flute_length, int samples) {
  Engagement e;
  e.depth.assign(static_cast<std::size_t>(samples), 0.0);
  const double dphi = 2 * std::numbers::pi / samples;
  const double rp = stock.probe_radius();
  const double nx = -uy, ny = ux;  // n = u turned +90 deg: with M3 phi runs from n towards u
  int engaged = 0;
  for (int i = 0; i < samples && (i + 0.5) * dphi < std::numbers::pi; ++i) {
    const double phi = (i + 0.5) * dphi, s = std::sin(phi), c = std::cos(phi);
    const double top = stock.top_at(x + rp * (s * ux + c * nx), y + rp * (s * uy + c * ny));
    const double a = std::clamp(top - z, 0.0, flute_length);
    e.depth[static_cast<std::size_t>(i)] = a;
    if (a > 0) ++engaged;
    e.axial_depth = std::max(e.axial_depth, a);
  }
  const double r = rp + stock.field().cell();
  e.angle = engaged * dphi;
  e.radial_depth = e.angle >= std::numbers::pi ? 2 * r : r * (1 - std::cos(e.angle));
  return e;
}

}  // namespace gcpipe::force
