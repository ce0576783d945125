#include "path_force.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace gcpipe::force {

namespace {

constexpr double kPi = std::numbers::pi;

/// XY arc of a G2/G3 block as chords no further than `chord` from the circle.
void arc_moves(const ResolvedBlock& b, double chord, Move proto, std::vector<Move>& out) {
  const double cx = b.centre[0], cy = b.centre[1];
  const double r = std::max(b.radius, 1e-9);
  const double a0 = std::atan2(b.start[1] - cy, b.start[0] - cx);
  double a1 = std::atan2(b.target[1] - cy, b.target[0] - cx);
  const bool ccw = b.motion == Motion::kArcCCW;
  double sweep = ccw ? a1 - a0 : a0 - a1;
  while (sweep <= 1e-12) sweep += 2 * kPi;
  sweep += 2 * kPi * std::max(0, b.turns - 1);
  const double dmax = 2 * std::acos(std::max(-1.0, 1 - chord / r));
  const int n = std::max(1, static_cast<int>(std::ceil(sweep / dmax)));
  Vec3 prev{b.start[0], b.start[1], b.start[2]};
  for (int i = 1; i <= n; ++i) {
    const double t = static_cast<double>(i) / n;
    const double a = a0 + (ccw ? 1 : -1) * sweep * t;
    Vec3 p{cx + r * std::cos(a), cy + r * std::sin(a), b.start[2] + t * (b.target[2] - b.start[2])};
    if (i == n) p = {b.target[0], b.target[1], b.target[2]};
    proto.from = prev;
    proto.to = p;
    out.push_back(proto);
    prev = p;
  }
}

double xy_norm(double x, double y) { return std::sqrt(x * x + y * y); }

/// Immersion samples per revolution: about 720, a multiple of the flute count so that every
/// tooth lands on a sample (revolution_force's pitch).
int samples_per_revolution(int flutes) { return flutes * ((720 + flutes - 1) / flutes); }

/// Feed per tooth at or under c_hi whose instantaneous peak stays under `limit` (bisection; the
/// peak grows with the feed, each tooth's force being affine in c with a positive chip term).
double limit_peak(const ForceLaw& k, int flutes, const AxialProfile& profile, int steps, double c_hi,
                  double limit) {
  if (revolution_force(k, flutes, c_hi, profile, steps).peak <= limit) return c_hi;
  double lo = 0, hi = c_hi;
  for (int i = 0; i < 40; ++i) {
    const double mid = 0.5 * (lo + hi);
    (revolution_force(k, flutes, mid, profile, steps).peak <= limit ? lo : hi) = mid;
  }
  return lo;
}

/// Feed [mm/min] whose mean force is o.target_force and whose peak stays under the limit. The mean
/// is affine in u = c^p (RevolutionForce), so the quadratic of feed_for_mean_force gives u, and
/// c = u^(1/p).
double planned_feed(const ForceLaw& law, const RevolutionForce& f, const AxialProfile& profile, int steps,
                    const Move& m, const ForceOptions& o) {
  const ToolSpec& t = o.tool;
  const double c = m.feed / (t.flutes * m.spindle);
  const double u = law.chip_factor(c);
  const double c_max = o.max_feed_factor * m.feed / (t.flutes * m.spindle);
  const Force3 edge{f.mean.x - u * f.mean_per_feed.x, f.mean.y - u * f.mean_per_feed.y, f.mean.z - u * f.mean_per_feed.z};
  const double u_target = feed_for_mean_force(f.mean_per_feed, edge, o.target_force, law.chip_factor(c_max));
  double cp = law.feed_exponent == 1 ? u_target : std::pow(u_target, 1 / law.feed_exponent);
  const double peak = o.peak_force > 0 ? o.peak_force : 2 * o.target_force;
  cp = limit_peak(law, t.flutes, profile, steps, cp, peak);
  return std::max(cp * t.flutes * m.spindle, o.min_feed);
}

/// Everything one revolution at (x, y, z) moving along (ux, uy) gives.
ForceSample sample_at(const SweptStock& stock, const ForceOptions& o, const Move& m, double x, double y,
                      double z, double ux, double uy) {
  const ToolSpec& t = o.tool;
  const int steps = samples_per_revolution(t.flutes);
  const Engagement e = engagement_at(stock, x, y, z, ux, uy, t.flute_length, steps);
  const AxialProfile profile = [&](double phi) {
    const auto i = static_cast<std::size_t>(phi / (2 * kPi) * steps);
    return e.depth[std::min(i, e.depth.size() - 1)];
  };
  const double c = m.feed / (t.flutes * m.spindle);
  const ForceLaw& law = o.material.law;
  const RevolutionForce f = revolution_force(law, t.flutes, c, profile, steps);
  ForceSample s;
  s.x = x; s.y = y; s.z = z;
  s.feed = m.feed;
  s.angle = e.angle;
  s.radial_depth = e.radial_depth;
  s.axial_depth = e.axial_depth;
  s.mean_force = f.mean.norm();
  s.peak_force = f.peak;
  s.deflection = cantilever_deflection(xy_norm(f.mean.x, f.mean.y), t.stickout, t.modulus, t.effective_diameter());
  s.peak_deflection = cantilever_deflection(f.peak, t.stickout, t.modulus, t.effective_diameter());
  s.mean_tangential = f.mean_tangential;
  s.torque = f.mean_tangential * 0.5 * t.diameter * 1e-3;
  s.power = s.torque * 2 * kPi * m.spindle / 60;
  if (o.target_force > 0) s.planned_feed = planned_feed(law, f, profile, steps, m, o);
  return s;
}

}  // namespace

std::vector<Move> moves_from_blocks(const std::vector<ResolvedBlock>& blocks, double chord) {
  std::vector<Move> out;
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    const ResolvedBlock& b = blocks[i];
    if (b.motion != Motion::kRapid && b.motion != Motion::kLinear && b.motion != Motion::kArcCW &&
        b.motion != Motion::kArcCCW)
      continue;
    Move m;
    m.cutting = b.motion != Motion::kRapid;
    m.feed = m.cutting ? b.feed : 0;
    m.spindle = b.spindle_speed;
    m.block = i;
    const bool arc = b.motion == Motion::kArcCW || b.motion == Motion::kArcCCW;
    if (arc && b.plane == Plane::kXY) {
      arc_moves(b, chord, m, out);
      continue;
    }
    m.from = {b.start[0], b.start[1], b.start[2]};
    m.to = {b.target[0], b.target[1], b.target[2]};
    out.push_back(m);
  }
  return out;
}

HeightField make_stock(const std::vector<Move>& moves, const ForceOptions& o) {
  const auto& s = o.stock;
  if (s[2] > s[0]) return HeightField(s[0], s[1], s[2], s[3], s[4], o.cell);
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300, top = -1e300;
  for (const Move& m : moves) {
    if (!m.cutting) continue;
    for (const Vec3& p : {m.from, m.to}) {
      x0 = std::min(x0, p[0]); y0 = std::min(y0, p[1]);
      x1 = std::max(x1, p[0]); y1 = std::max(y1, p[1]);
      top = std::max(top, p[2]);
    }
  }
  if (top < -1e299) return HeightField(0, 0, 1, 1, -1e9, o.cell);  // nothing cuts
  const double margin = 0.5 * o.tool.diameter + 2;
  return HeightField(x0 - margin, y0 - margin, x1 + margin, y1 + margin, top, o.cell);
}

PathForce sweep_path(const std::vector<Move>& moves, const ForceOptions& o, HeightField field) {
  PathForce out;
  SweptStock stock(std::move(field), 0.5 * o.tool.diameter);
  double carry = 0, ux = 1, uy = 0, path = 0;
  for (std::size_t i = 0; i < moves.size(); ++i) {
    const Move& m = moves[i];
    if (!m.cutting || m.feed <= 0 || m.spindle <= 0) continue;
    const double dx = m.to[0] - m.from[0], dy = m.to[1] - m.from[1], dz = m.to[2] - m.from[2];
    const double len = std::sqrt(dx * dx + dy * dy + dz * dz);
    if (len <= 0) continue;
    const double lxy = xy_norm(dx, dy);
    if (lxy > 1e-9) { ux = dx / lxy; uy = dy / lxy; }  // a plunge keeps the last direction
    const double step = o.sample_spacing > 0 ? o.sample_spacing : m.feed / m.spindle;
    const double t0 = out.cutting_time;
    double s = carry;
    for (; s <= len; s += step) {
      const double f = s / len;
      const double x = m.from[0] + f * dx, y = m.from[1] + f * dy, z = m.from[2] + f * dz;
      ForceSample fs = sample_at(stock, o, m, x, y, z, ux, uy);
      fs.time = t0 + 60 * s / m.feed;
      fs.move = i;
      out.samples.push_back(fs);
      stock.cut(x, y, z, path + s);
    }
    carry = s - len;
    path += len;
    out.cutting_time += 60 * len / m.feed;
    if (i + 1 == moves.size() || !moves[i + 1].cutting) {  // a rapid follows: the run ends here
      stock.cut(m.to[0], m.to[1], m.to[2], path);
      stock.end_run();
    }
  }
  for (const ForceSample& fs : out.samples) {
    out.max_mean_force = std::max(out.max_mean_force, fs.mean_force);
    out.max_peak_force = std::max(out.max_peak_force, fs.peak_force);
    out.max_deflection = std::max(out.max_deflection, fs.peak_deflection);
    out.max_mean_tangential = std::max(out.max_mean_tangential, fs.mean_tangential);
    out.max_torque = std::max(out.max_torque, fs.torque);
    out.max_power = std::max(out.max_power, fs.power);
  }
  return out;
}

std::vector<double> plan_feeds(const std::vector<Move>& moves, const PathForce& swept, const ForceOptions& o) {
  std::vector<double> feed(moves.size(), std::numeric_limits<double>::infinity());
  for (const ForceSample& s : swept.samples) feed[s.move] = std::min(feed[s.move], s.planned_feed);
  // A move shorter than the sample spacing has no sample: it takes the smaller of the samples
  // before and after it (the engagement between them is not known to be lower).
  std::vector<double> next(moves.size(), std::numeric_limits<double>::infinity());
  double after = std::numeric_limits<double>::infinity();
  for (std::size_t i = moves.size(); i-- > 0;) {
    next[i] = after;
    if (moves[i].cutting && !std::isinf(feed[i])) after = feed[i];
  }
  double before = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < moves.size(); ++i) {
    if (!moves[i].cutting) { feed[i] = 0; continue; }
    if (std::isinf(feed[i])) feed[i] = std::min(before, next[i]);
    else before = feed[i];
    if (std::isinf(feed[i])) feed[i] = moves[i].feed;
    feed[i] = std::clamp(feed[i], o.min_feed, std::max(o.min_feed, o.max_feed_factor * moves[i].feed));
  }
  return feed;
}

std::vector<ResolvedBlock> apply_feeds(const std::vector<ResolvedBlock>& blocks, const std::vector<Move>& moves,
                                       const std::vector<double>& feeds) {
  std::vector<ResolvedBlock> out = blocks;
  std::vector<double> lowest(blocks.size(), std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < moves.size(); ++i)
    if (moves[i].cutting) lowest[moves[i].block] = std::min(lowest[moves[i].block], feeds[i]);
  for (std::size_t b = 0; b < out.size(); ++b)
    if (!std::isinf(lowest[b])) out[b].feed = lowest[b];
  return out;
}

std::vector<Move> with_spindle_speed(std::vector<Move> moves, double rpm) {
  if (rpm > 0)
    for (Move& m : moves) m.spindle = rpm;
  return moves;
}

}  // namespace gcpipe::force
