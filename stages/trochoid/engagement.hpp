// Radial engagement of a cylindrical tool following a path in XY, computed two independent ways.
//
// Engagement angle theta at a tool position p: the part of the tool's circumference (radius r)
// that touches material, i.e. is not inside the region swept before reaching p. Material thinner
// than h = min_chip left by the path more than kRecentTrail back is taken as cut: chords leave
// slivers up to the chord tolerance thick where the tool later runs tangent to an earlier outline
// (the walls), and counting them would make the angle a property of the tolerance. The tool's
// own recent trail is used exactly (the engaged arc starts tangent to it). The
// equivalent radial depth of cut is ae = r (1 - cos theta) (the ae of a straight cut with the
// same angle), D for theta >= pi.
//
// 1. ExactEngagement: the path is a polyline (the G1 program itself; arcs as chords); the region
//    swept before p is the union of the capsules (segment + radius r) of the segments behind p,
//    and, for the segment ending at p, its capsule without the disc at p (which covers exactly
//    the trailing half of p's circle). Each capsule covers at most three arcs of p's circle: two
//    end discs (law of cosines) and the strip (four half-plane constraints, each an arc). The
//    engaged angle is 2pi minus the union of the covered arcs. Exact for the polyline, up to
//    rounding (arcs under 1e-7 rad are dropped).
// 2. MaterialGrid: a raster of material pixels; the tool disc is swept through it and the
//    circumference is probed before each removal. Independent of 1, limited by the pixel size.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace gcpipe {

/// Default tolerance on earlier outlines: twice the default chord tolerance [mm].
inline constexpr double kMinChip = 0.002;
/// Path length behind the tool that is always used exactly [mm].
inline constexpr double kRecentTrail = 2.0;

struct Point2 {
  double x = 0, y = 0;  //!< [mm]
};

/// ae = r (1 - cos theta), D for theta >= pi [mm].
double equivalent_ae(double engaged_angle, double tool_radius);

/// Exact engagement at the vertices of a tool-centre polyline.
class ExactEngagement {
 public:
  /// `vertices` in path order; piece_start[k] != 0 where the tool arrives without cutting from
  /// vertex k-1 (first vertex, after a rapid or a move outside the analysed plane).
  ExactEngagement(std::vector<Point2> vertices, std::vector<std::uint8_t> piece_start,
                  double tool_radius, double min_chip = kMinChip);

  /// Engaged angle at vertex i, the material cut by everything before it [rad].
  double angle_at(std::size_t i) const;
  /// As angle_at, with only vertices from `first` on having cut (a window into the history).
  double angle_at(std::size_t i, std::size_t first) const;

  const std::vector<Point2>& vertices() const { return v_; }

 private:
  std::vector<Point2> v_;
  std::vector<std::uint8_t> start_;
  double r_;
  double h_;
  std::vector<double> s_;  // path length at each vertex
  double cell_ = 1;
  std::int64_t nx_ = 0, ny_ = 0;
  double x0_ = 0, y0_ = 0;
  std::vector<std::vector<std::uint32_t>> cells_;
};

/// Engaged angle at v[n-1] of a tool that followed the single polyline v[0..n-1] [rad].
double engaged_angle_polyline(const Point2* v, std::size_t n, double tool_radius,
                              double min_chip = kMinChip);

/// A raster of material, 1 byte per pixel, initially full.
class MaterialGrid {
 public:
  /// Covers [xmin, xmax] x [ymin, ymax] with square pixels of side `pixel` [mm].
  MaterialGrid(double xmin, double ymin, double xmax, double ymax, double pixel);

  double pixel() const { return h_; }
  int width() const { return nx_; }
  int height() const { return ny_; }
  /// Pixel centre coordinates [mm].
  double x_of(int ix) const { return x0_ + (ix + 0.5) * h_; }
  double y_of(int iy) const { return y0_ + (iy + 0.5) * h_; }
  bool material_at(int ix, int iy) const { return cells_[std::size_t(iy) * nx_ + ix] != 0; }
  /// Material at (x, y); outside the raster there is none.
  bool material(double x, double y) const;

  /// Engaged angle of a tool circle at (x, y), probing `probes` points [rad].
  double engaged_angle(double x, double y, double r, int probes = 1440) const;
  /// Removes every pixel whose centre lies in the disc.
  void remove_disc(double x, double y, double r);
  /// Removes the disc at (x, y) knowing the disc at (px, py) is already gone (fast: only the
  /// crescent is visited).
  void remove_disc_after(double px, double py, double x, double y, double r);
  /// Sweeps the tool from a to b in steps <= pixel, assuming the disc at a is removed. Returns the
  /// largest engaged angle met before each removal [rad].
  double sweep(Point2 a, Point2 b, double r);

 private:
  void fill_span(int iy, double xa, double xb);
  double x0_, y0_, h_;
  int nx_, ny_;
  std::vector<std::uint8_t> cells_;
};

}  // namespace gcpipe
