#include "trochoid_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "gcpipe/stop.hpp"
#include "plot.hpp"

namespace gcpipe {

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

bool is_feed(Motion m) {
  return m == Motion::kLinear || m == Motion::kArcCW || m == Motion::kArcCCW;
}

// Signed sweep of an XY arc block [rad]; a closed arc is a full turn.
double arc_sweep(const ResolvedBlock& b) {
  const double a0 = std::atan2(b.start[kY] - b.centre[1], b.start[kX] - b.centre[0]);
  const double a1 = std::atan2(b.target[kY] - b.centre[1], b.target[kX] - b.centre[0]);
  double d = a1 - a0;
  if (b.motion == Motion::kArcCCW) {
    while (d <= 1e-12) d += kTwoPi;
  } else {
    while (d >= -1e-12) d -= kTwoPi;
  }
  return d;
}

double block_length(const ResolvedBlock& b) {
  const double dz = b.target[kZ] - b.start[kZ];
  if (b.motion == Motion::kArcCW || b.motion == Motion::kArcCCW) {
    const double rho = std::hypot(b.start[kX] - b.centre[0], b.start[kY] - b.centre[1]);
    return std::hypot(rho * arc_sweep(b), dz);
  }
  return std::sqrt(std::pow(b.target[kX] - b.start[kX], 2) + std::pow(b.target[kY] - b.start[kY], 2) +
                   dz * dz);
}

}  // namespace

namespace {

// The moves that end in the analysis plane as a polyline: lines split to the query spacing,
// arcs as chords with a sagitta under 0.1 um; each vertex tagged with its block.
struct PlanePolyline {
  std::vector<Point2> verts;
  std::vector<std::uint8_t> piece_start;  //!< 1 where a connected piece begins
  std::vector<std::size_t> owner;         //!< block of each vertex

  void add(double x, double y, std::size_t blk, bool start) {
    verts.push_back({x, y});
    piece_start.push_back(start ? 1 : 0);
    owner.push_back(blk);
  }
  void add_line(const ResolvedBlock& b, std::size_t blk, double ds) {
    const double len = std::hypot(b.target[kX] - b.start[kX], b.target[kY] - b.start[kY]);
    const int n = std::max(1, int(std::ceil(len / ds)));
    for (int k = 1; k <= n; ++k) {
      const double t = double(k) / n;
      add(b.start[kX] + (b.target[kX] - b.start[kX]) * t, b.start[kY] + (b.target[kY] - b.start[kY]) * t, blk, false);
    }
  }
  void add_arc(const ResolvedBlock& b, std::size_t blk, double ds) {
    const double cx = b.centre[0], cy = b.centre[1];
    const double rho = std::hypot(b.start[kX] - cx, b.start[kY] - cy);
    const double a0 = std::atan2(b.start[kY] - cy, b.start[kX] - cx);
    const double sw = arc_sweep(b);
    const double max_step = std::min(ds / rho, 2.0 * std::acos(std::max(0.0, 1.0 - 1e-4 / rho)));
    const int n = std::max(1, int(std::ceil(std::abs(sw) / max_step)));
    for (int k = 1; k <= n; ++k) {
      const double t = a0 + sw * k / n;
      add(cx + rho * std::cos(t), cy + rho * std::sin(t), blk, false);
    }
  }
};

// Move counts and lengths, and the lowest feed end point (the default analysis plane).
double count_moves(const std::vector<ResolvedBlock>& blocks, PathAnalysis& a) {
  double zmin = std::numeric_limits<double>::infinity();
  for (const auto& b : blocks) {
    if (is_feed(b.motion)) {
      ++a.feed_moves;
      a.feed_length += block_length(b);
      zmin = std::min(zmin, b.target[kZ]);
    } else if (b.motion == Motion::kRapid) {
      ++a.rapid_moves;
      a.rapid_length += block_length(b);
    }
  }
  return zmin;
}

PlanePolyline plane_polyline(const std::vector<ResolvedBlock>& blocks, double z_cut, double ds,
                             std::vector<std::size_t>& breaks) {
  PlanePolyline pl;
  bool joined = false;
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    const auto& b = blocks[i];
    if (!is_feed(b.motion) || b.target[kZ] > z_cut + 1e-6) {
      if (b.motion != Motion::kNone) joined = false;
      continue;
    }
    if (!joined) {
      breaks.push_back(pl.verts.size());
      pl.add(b.start[kX], b.start[kY], i, true);
    }
    joined = true;
    if (b.motion == Motion::kLinear) pl.add_line(b, i, ds);
    else pl.add_arc(b, i, ds);
  }
  return pl;
}

// The largest engagement per block, over all blocks and over the cutting part of a cycle (the
// entry and the start circle finish the entry wedge; air moves are reported apart).
void block_maxima(const std::vector<TrochoidPart>* parts, std::size_t nblocks, PathAnalysis& a) {
  for (std::size_t i = 0; i < nblocks; ++i) {
    const double ang = a.block_angle[i];
    a.max_angle_all = std::max(a.max_angle_all, ang);
    const TrochoidPart p = parts && i < parts->size() ? (*parts)[i] : TrochoidPart::kLoops;
    // The start circle finishes the entry: in the floor plane it is the first pass, cutting the
    // helix's last wedge (axially at most one helix pitch) or the ring around a plunge.
    if (p == TrochoidPart::kEntry || p == TrochoidPart::kStartCircle) continue;
    if (ang > a.max_angle) {
      a.max_angle = ang;
      a.max_block = i;
    }
    if (p == TrochoidPart::kAir) a.max_air_angle = std::max(a.max_air_angle, ang);
  }
}

}  // namespace

PathAnalysis analyse_path(const std::vector<ResolvedBlock>& blocks,
                          const std::vector<TrochoidPart>* parts, const PathAnalysisOptions& opt) {
  PathAnalysis a;
  a.has_parts = parts != nullptr;
  a.block_angle.assign(blocks.size(), 0.0);
  const double zmin = count_moves(blocks, a);
  a.z_cut = std::isnan(opt.z_cut) ? zmin : opt.z_cut;
  if (!std::isfinite(a.z_cut)) return a;
  PlanePolyline pl = plane_polyline(blocks, a.z_cut, opt.sample_spacing, a.breaks);
  if (pl.verts.empty()) return a;
  ExactEngagement eng(pl.verts, pl.piece_start, opt.tool_radius, opt.min_chip);
  a.x.reserve(pl.verts.size());
  a.y.reserve(pl.verts.size());
  a.angle.reserve(pl.verts.size());
  for (std::size_t i = 0; i < pl.verts.size(); ++i) {
    if ((i & 0xff) == 0) throw_if_stop_requested();  // a vertex can take milliseconds where cycles overlap
    const double ang = eng.angle_at(i);
    const std::size_t blk = pl.owner[i];
    a.block_angle[blk] = std::max(a.block_angle[blk], ang);
    a.x.push_back(pl.verts[i].x);
    a.y.push_back(pl.verts[i].y);
    a.angle.push_back(ang);
  }
  a.block = std::move(pl.owner);
  block_maxima(parts, blocks.size(), a);
  return a;
}

std::vector<Point2> slot_outline(const TrochoidSlot& slot) {
  const double sx = slot.start[0], sy = slot.start[1], ex = slot.end[0], ey = slot.end[1];
  const double len = std::hypot(ex - sx, ey - sy);
  const double a = len > 0 ? std::atan2(ey - sy, ex - sx) : 0.0, h = 0.5 * slot.width;
  std::vector<Point2> o;
  // End cap around E from the right wall to the left, then the cap around S, closed.
  for (int k = 0; k <= 90; ++k) {
    const double t = a - 0.5 * std::numbers::pi + std::numbers::pi * k / 90;
    o.push_back({ex + h * std::cos(t), ey + h * std::sin(t)});
  }
  for (int k = 0; k <= 90; ++k) {
    const double t = a + 0.5 * std::numbers::pi + std::numbers::pi * k / 90;
    o.push_back({sx + h * std::cos(t), sy + h * std::sin(t)});
  }
  o.push_back(o.front());
  return o;
}

void write_engagement_png(const std::filesystem::path& png, const PathAnalysis& a,
                          double tool_radius, const std::string& title,
                          const std::vector<std::vector<Point2>>& outlines) {
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  auto grow = [&](double x, double y) {
    x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
  };
  for (std::size_t i = 0; i < a.x.size(); ++i) grow(a.x[i], a.y[i]);
  for (const auto& o : outlines)
    for (const auto& p : o) grow(p.x, p.y);
  plot::FigureStyle style;
  style.height = 1100;
  // Width for the data's aspect (equal scales), within what a screen shows at 100 %.
  const double aspect = x1 > x0 && y1 > y0 ? (x1 - x0) / (y1 - y0) : 1.0;
  const int area_h = style.height - style.margin_top - 56 - style.margin_bottom;
  const int chrome = style.width - plot::Figure::area_width(style, true);
  style.width = std::clamp(int(area_h * aspect * 1.06) + chrome, 900, 1800);
  plot::Figure fig(style);
  fig.title(title);
  fig.xlabel("X [mm]");
  fig.ylabel("Y [mm]");
  fig.equal_aspect(true);
  for (const auto& o : outlines) {
    std::vector<double> ox, oy;
    for (const auto& p : o) ox.push_back(p.x), oy.push_back(p.y);
    fig.line(std::move(ox), std::move(oy), cv::Scalar(150, 150, 150), 1,
             &o == &outlines.front() ? "slot outline" : "");
  }
  const double ae_max = equivalent_ae(a.max_angle, tool_radius);
  // Colour range: the loops' maximum; for another generator's path (no parts to leave the entry
  // out) the 99.5th percentile, so that a plunge does not flatten the scale.
  double ae_scale = ae_max;
  if (!a.has_parts && !a.angle.empty()) {
    std::vector<double> sorted = a.angle;
    std::sort(sorted.begin(), sorted.end());
    ae_scale = equivalent_ae(sorted[std::size_t(0.995 * double(sorted.size() - 1))], tool_radius);
  }
  fig.colourbar("radial engagement ae = r(1 - cos theta) [mm]", 0.0,
                ae_scale > 0 ? ae_scale * 1.05 : 1.0, plot::ColourMap::kTurbo);
  // One coloured polyline per contiguous piece; segment i takes the engagement met at its end.
  std::vector<std::size_t> starts = a.breaks;
  starts.push_back(a.x.size());
  for (std::size_t k = 0; k + 1 < starts.size(); ++k) {
    const std::size_t b = starts[k], e = starts[k + 1];
    if (e - b < 2) continue;
    std::vector<double> xs(a.x.begin() + std::ptrdiff_t(b), a.x.begin() + std::ptrdiff_t(e));
    std::vector<double> ys(a.y.begin() + std::ptrdiff_t(b), a.y.begin() + std::ptrdiff_t(e));
    std::vector<double> v;
    v.reserve(e - b);
    for (std::size_t i = b + 1; i < e; ++i) v.push_back(equivalent_ae(a.angle[i], tool_radius));
    fig.coloured_line(std::move(xs), std::move(ys), std::move(v), 1);
  }
  char buf[256];
  std::snprintf(buf, sizeof buf, a.has_parts ? "loops: max ae %.3f mm = %.1f %% of D%.4g (angle %.1f deg)"
                                           : "whole path: max ae %.3f mm = %.1f %% of D%.4g (angle %.1f deg)",
                ae_max, 100.0 * ae_max / (2.0 * tool_radius), 2.0 * tool_radius,
                a.max_angle * 180.0 / std::numbers::pi);
  fig.note(buf);
  std::snprintf(buf, sizeof buf, "plane Z%.4g; entry + start circle up to %.0f deg; %zu feed moves, %.0f mm",
                a.z_cut, a.max_angle_all * 180.0 / std::numbers::pi, a.feed_moves, a.feed_length);
  fig.note(buf);
  fig.save_png(png);
}

}  // namespace gcpipe
