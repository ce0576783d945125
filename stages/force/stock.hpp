// 2.5D stock for engagement: a height field (one top height per grid node) cut by a flat end
// mill. Enough for milling with the spindle along Z (every G275 slot and 3-axis program); a
// tilted tool would need dexels in three directions, which this model does not have.
//
// The engagement at a tool position is read on the tool's circle *before* the disc at that
// position is removed: at immersion phi (clockwise from the feed normal n, so phi = pi/2 is the
// front of the tool, see force_model.hpp) the point p + r (sin(phi) u + cos(phi) n) carries
// material up to the height H there; the edge length in cut is clamp(H - z_tip, 0, flute_length).
// Only phi in [0, pi] (the front half) is read: behind it the chip thickness c sin(phi) < 0.
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

  /// Axial depth of material on the circle of radius r around (x, y) at immersion phi, the feed
  /// along unit (ux, uy), for a tool tip at z, limited to `flute_length` [mm].
  double depth_at(double x, double y, double z, double ux, double uy, double r, double phi,
                  double flute_length) const;

 private:
  void cut_row(int iy, double xa, double xb, float z);
  double x0_, y0_, h_;
  int nx_, ny_;
  std::vector<float> top_;
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
Engagement engagement_at(const HeightField& stock, double x, double y, double z, double ux,
                         double uy, double tool_radius, double flute_length, int samples = 720);

}  // namespace gcpipe::force
