#include "stock.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

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

double HeightField::depth_at(double x, double y, double z, double ux, double uy, double r, double phi,
                             double flute_length) const {
  // n = u turned +90 deg: with an M3 (clockwise) spindle phi runs from n towards u.
  // The probe sits one node spacing outside the tool circle: the nearest node to a point on the
  // circle itself may lie inside the disc cut one step back (the walls would flicker), and one
  // spacing out it cannot; the radial depth is read at most one spacing too large.
  const double nx = -uy, ny = ux;
  const double s = std::sin(phi), c = std::cos(phi);
  const double rp = r + h_;
  const double px = x + rp * (s * ux + c * nx), py = y + rp * (s * uy + c * ny);
  return std::clamp(height(px, py) - z, 0.0, flute_length);
}

Engagement engagement_at(const HeightField& stock, double x, double y, double z, double ux, double uy,
                         double tool_radius, double flute_length, int samples) {
  Engagement e;
  e.depth.resize(static_cast<std::size_t>(samples));
  const double dphi = 2 * std::numbers::pi / samples;
  int engaged = 0;
  for (int i = 0; i < samples; ++i) {
    // Only the front half can cut: behind the feed normal h = c sin(phi) < 0 (the tool moves
    // away from whatever is there).
    if ((i + 0.5) * dphi > std::numbers::pi) break;
    const double a = stock.depth_at(x, y, z, ux, uy, tool_radius, (i + 0.5) * dphi, flute_length);
    e.depth[static_cast<std::size_t>(i)] = a;
    if (a > 0) ++engaged;
    e.axial_depth = std::max(e.axial_depth, a);
  }
  e.angle = engaged * dphi;
  e.radial_depth = e.angle >= std::numbers::pi ? 2 * tool_radius : tool_radius * (1 - std::cos(e.angle));
  return e;
}

}  // namespace gcpipe::force
