// 2.5D stock for engagement: a height field (one top height per grid node) cut by a flat end
// mill. Enough for milling with the spindle along Z (every G275 slot and 3-axis program); a
// tilted tool would need dexels in three directions, which this model does not have.
//
// The engagement at a tool position is read on the tool's circle before the disc at that
// position is cut: at immersion phi (clockwise from the feed normal n, so phi = pi/2 is the front
// of the tool, see force_model.hpp) the material top H at p + rp (sin(phi) u + cos(phi) n) gives
// the edge length in cut clamp(H - z_tip, 0, flute_length). Only phi in [0, pi] (the front half)
// is read: behind it the chip thickness c sin(phi) < 0.
//
// Two sources of error are kept out (README sec. 3):
// - the probe radius is rp = r - cell, one node spacing inside the circle: where the tool runs
//   tangent to an old wall (every trochoid loop at the slot walls, every later pass along the
//   walls of the earlier one) a probe on the circle itself rounds to nodes beyond the wall half
//   the time and counts a sliver of zero thickness as engaged over ~2 sqrt(2 cell / r) rad;
// - the recent trail (the last `recent` mm of path) is not on the grid but kept as exact discs of
//   radius rp: the disc one sample back covers the sides of the circle only through node rounding,
//   and on the grid it would hide real material at phi near 0 and pi.
#pragma once

#include <cstdint>
#include <vector>

#include "force_model.hpp"

namespace gcpipe::force {

class HeightField {
 public:
  /// Block of stock [xmin, xmax] x [ymin, ymax] with top at `top` [mm], nodes `cell` mm apart.
  HeightField(double xmin, double ymin, double xmax, double ymax, double top, double cell);

  double cell() const { return h_; }
  /// Top of the stock at the node nearest to (x, y); -infinity outside the block [mm].
  double height(double x, double y) const;
  /// Lowers every node inside the disc of radius r around (x, y) to z.
  void cut_disc(double x, double y, double r, double z);
  /// As cut_disc, knowing the disc of the same radius at (px, py) was cut to a height <= z: only
  /// the crescent the step adds is visited (a sweep at fine spacing stays cheap).
  void cut_disc_after(double px, double py, double x, double y, double r, double z);

 private:
  void cut_row(int iy, double xa, double xb, float z);
  double x0_, y0_, h_;
  int nx_, ny_;
  std::vector<float> top_;
};

/// The height field plus the exact recent trail (see the file comment).
class SweptStock {
 public:
  SweptStock(HeightField field, double tool_radius, double recent = 2.0);

  /// The tool at (x, y, z), `s` mm along the path, cuts its disc.
  void cut(double x, double y, double z, double s);
  /// End of a cutting run (a rapid follows): the trail goes onto the grid.
  void end_run();
  /// Material top at the point, the trail included [mm].
  double top_at(double x, double y) const;
  double probe_radius() const { return rp_; }
  const HeightField& field() const { return field_; }

 private:
  struct Disc {
    double x, y, z, s;
  };
  void flush_before(double s);
  HeightField field_;
  double r_, rp_, recent_;
  std::vector<Disc> trail_;
  bool have_last_ = false;
  Disc last_{};  // the last disc put on the grid (crescent cuts)
};

/// Engagement of the tool at one position: the axial depth per immersion sample and what the
/// force model needs from it.
struct Engagement {
  std::vector<double> depth;   //!< a(phi_i) at phi_i = (i + 0.5) 2 pi / size [mm]
  double angle = 0;            //!< total immersion with material [rad]
  double radial_depth = 0;     //!< equivalent ae = r (1 - cos(angle)), D past pi [mm]
  double axial_depth = 0;      //!< largest a(phi) [mm]
};

/// Reads the engagement on the height field (see the file comment), `samples` immersion angles.
Engagement engagement_at(const SweptStock& stock, double x, double y, double z, double ux, double uy,
                         double flute_length, int samples = 720);

}  // namespace gcpipe::force
