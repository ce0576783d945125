#include "trochoid.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <mutex>
#include <numbers>
#include <tuple>

#include "engagement.hpp"
#include "gcpipe/config.hpp"

namespace gcpipe {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kTwoPi = 2.0 * kPi;

std::string fmt(const char* f, auto... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, f, args...);
  return buf;
}

// Trochoid with constant advance V = K / 2pi in its own frame (front of the loop at phase 0,
// counter-clockwise), the shape of every loop far from the slot ends.
Point2 steady_point(double phi, double R, double V) {
  return {V * phi + R * std::cos(phi), R * std::sin(phi)};
}

// Exact steady engagement sampled at `sample_deg` along the path, probed every `query_deg`.
SteadyEngagement steady_engagement_at(double R, double K, double r, double sample_deg,
                                      double query_deg) {
  const double V = K / kTwoPi;
  const double ds = sample_deg * kPi / 180.0;
  // One revolution and a half of history is enough: each revolution sweeps (nearly) the disc of
  // radius R + r around its centre, and the part of an older, equal disc that lies ahead of the
  // bisector between two centres is inside the newer one; the leading side of the tool, the only
  // side that can touch material, lies ahead of it. (Checked against 3 revolutions in the tests.)
  const double history = 1.5 * kTwoPi;
  // The ideal curve as a fine polyline (chords of sample_deg), queried every query_deg.
  const int nh = int(std::ceil(history / ds));
  const int per_rev = int(std::lround(360.0 / sample_deg));
  std::vector<Point2> pts;
  pts.reserve(std::size_t(nh + per_rev + 1));
  for (int k = -nh; k <= per_rev; ++k) pts.push_back(steady_point(k * ds, R, V));
  const int every = std::max(1, int(std::lround(query_deg / sample_deg)));
  const int nq = per_rev / every;
  SteadyEngagement out;
  std::vector<double> angle(std::size_t(nq), 0.0);
  for (int q = 0; q < nq; ++q) {
    const std::size_t idx = std::size_t(nh + q * every);
    const double a = engaged_angle_polyline(pts.data(), idx + 1, r);
    angle[std::size_t(q)] = a;
    if (a > out.max_angle) {
      out.max_angle = a;
      out.phase_of_max = kTwoPi * q / nq;
    }
  }
  out.max_ae = equivalent_ae(out.max_angle, r);
  // Longest circular run of exactly zero engagement: the air part of every loop.
  int best_len = 0, best_start = 0;
  for (int s = 0; s < nq; ++s) {
    if (angle[std::size_t(s)] != 0.0 || angle[std::size_t((s + nq - 1) % nq)] == 0.0) continue;
    int len = 0;
    while (len < nq && angle[std::size_t((s + len) % nq)] == 0.0) ++len;
    if (len > best_len) {
      best_len = len;
      best_start = s;
    }
  }
  if (best_len > 1) {
    out.air_begin = kTwoPi * best_start / nq;
    out.air_end = kTwoPi * (best_start + best_len - 1) / nq;
  }
  return out;
}

// Steady engagement is a function of (R, K, r) only; programs repeat their cycles, so keep it.
SteadyEngagement cached_steady(double R, double K, double r) {
  static std::mutex mutex;
  static std::map<std::tuple<double, double, double>, SteadyEngagement> cache;
  std::lock_guard lock(mutex);
  auto key = std::make_tuple(R, K, r);
  auto it = cache.find(key);
  if (it != cache.end()) return it->second;
  auto s = steady_engagement(R, K, r);
  if (cache.size() > 1024) cache.clear();
  cache.emplace(key, s);
  return s;
}

double xy_length(const TrochoidSlot& s) { return std::hypot(s.end[0] - s.start[0], s.end[1] - s.start[1]); }

}  // namespace

const char* to_string(TrochoidPart p) {
  switch (p) {
    case TrochoidPart::kApproach: return "approach";
    case TrochoidPart::kEntry: return "entry";
    case TrochoidPart::kStartCircle: return "start_circle";
    case TrochoidPart::kLoops: return "loops";
    case TrochoidPart::kAir: return "air";
    case TrochoidPart::kEndCircle: return "end_circle";
    case TrochoidPart::kExit: return "exit";
  }
  return "?";
}

TrochoidOptions load_trochoid_options(const Config& c) {
  c.reject_unknown({"chord_tolerance", "arcs", "entry", "entry_angle", "entry_feed_factor",
                    "air_feed_factor", "air_feed", "air_margin", "approach_clearance",
                    "max_engagement_fraction", "max_axial_depth_factor", "max_report_blocks"});
  TrochoidOptions o;
  o.chord_tolerance = c.number("chord_tolerance", o.chord_tolerance, "mm", 1e-6, 1.0);
  o.arcs = c.boolean("arcs", o.arcs);
  const std::string entry = c.choice("entry", "helix", {"helix", "ramp", "plunge"});
  o.entry = entry == "helix" ? TrochoidEntry::kHelix
            : entry == "ramp" ? TrochoidEntry::kRamp
                              : TrochoidEntry::kPlunge;
  o.entry_angle_deg = c.number("entry_angle", o.entry_angle_deg, "deg", 0.1, 45.0);
  o.entry_feed_factor = c.number("entry_feed_factor", o.entry_feed_factor, "", 0.01, 1.0);
  o.air_feed_factor = c.number("air_feed_factor", o.air_feed_factor, "", 1.0, 20.0);
  o.air_feed = c.number("air_feed", o.air_feed, "mm/min", 0.0, 1e6);
  o.air_margin_deg = c.number("air_margin", o.air_margin_deg, "deg", 0.0, 90.0);
  o.approach_clearance = c.number("approach_clearance", o.approach_clearance, "mm", 0.0, 100.0);
  o.max_engagement_fraction =
      c.number("max_engagement_fraction", o.max_engagement_fraction, "", 0.01, 0.5);
  o.max_axial_depth_factor =
      c.number("max_axial_depth_factor", o.max_axial_depth_factor, "", 0.01, 10.0);
  o.max_report_blocks = static_cast<std::size_t>(c.integer("max_report_blocks", 50000, 0, 10000000));
  return o;
}

// --------------------------------------------------------------------------------------------
// Geometry

double SlotGeometry::advance(double phi) const {
  const double V = speed;
  if (phi <= phi_accel) return 0.0;
  if (phi <= phi_cruise) {
    // a' = V s(tau), s = 3 tau^2 - 2 tau^3: a' and a'' continuous at both ends.
    const double t = (phi - phi_accel) / kTwoPi;
    return kTwoPi * V * (t * t * t - 0.5 * t * t * t * t);
  }
  if (phi <= phi_decel) return kPi * V + V * (phi - phi_cruise);
  if (phi <= phi_end_circle) {
    const double t = (phi - phi_decel) / kTwoPi;
    return kPi * V + V * cruise_phase + kTwoPi * V * (t - t * t * t + 0.5 * t * t * t * t);
  }
  return length;
}

void SlotGeometry::point(double phi, double& x, double& y) const {
  const double a = advance(phi) + loop_radius * std::cos(phi);
  const double b = sigma * loop_radius * std::sin(phi);  // along n = u turned +90 deg
  x = sx + a * ux - b * uy;
  y = sy + a * uy + b * ux;
}

SlotGeometry make_slot_geometry(const TrochoidSlot& slot, bool spindle_ccw) {
  SlotGeometry g;
  g.sx = slot.start[0];
  g.sy = slot.start[1];
  g.ex = slot.end[0];
  g.ey = slot.end[1];
  g.length = xy_length(slot);
  g.ux = (g.ex - g.sx) / g.length;
  g.uy = (g.ey - g.sy) / g.length;
  g.loop_radius = 0.5 * (slot.width - slot.tool_diameter);
  g.tool_radius = 0.5 * slot.tool_diameter;
  g.step = slot.step;
  // With M3 (clockwise spindle seen from above) a counter-clockwise loop has the material on the
  // right of the motion at the loop front: climb milling. M4 mirrors it.
  const bool ccw = slot.climb != spindle_ccw;
  g.sigma = ccw ? 1.0 : -1.0;
  const double k_eff = std::min(slot.step, g.length);
  g.speed = k_eff / kTwoPi;
  g.cruise_phase = (g.length - k_eff) / g.speed;
  g.phase0 = 0.5 * kPi;  // start at a wall: seed 000 Table 4 starts there (x = -R at t = 0)
  g.phi_start_circle = g.phase0;
  g.phi_accel = g.phi_start_circle + kTwoPi;
  g.phi_cruise = g.phi_accel + kTwoPi;
  g.phi_decel = g.phi_cruise + g.cruise_phase;
  g.phi_end_circle = g.phi_decel + kTwoPi;
  g.phi_end = g.phi_end_circle + kTwoPi;
  return g;
}

// --------------------------------------------------------------------------------------------
// Engagement, bounds, scallop

SteadyEngagement steady_engagement(double loop_radius, double step, double tool_radius) {
  return steady_engagement_at(loop_radius, step, tool_radius, 0.25, 1.0);
}

double engagement_angle_front(double R, double K, double r) {
  const double c = (2.0 * R * (r - K) - K * K) / (2.0 * (R + K) * r);
  return std::acos(std::clamp(c, -1.0, 1.0));
}

double engagement_angle_estimate(double R, double K, double r) {
  // Circle model at every phase phi of the cutting half: the previous loop's outline is the
  // circle of radius rho = R + r around the centre one step back, B; the tool centre is
  // T = R e(phi) + K u from B. The uncut arc is centred on T - B with half-width alpha,
  // cos(alpha) = (rho^2 - d^2 - r^2) / (2 d r), d = |T - B|; the tool's own trail covers all of
  // its circle behind the radial direction e(phi), so the engaged angle is alpha + delta, delta
  // = angle from e(phi) to T - B.
  const double rho = R + r;
  double best = 0;
  for (int k = -900; k <= 900; ++k) {
    const double phi = k * kPi / 1800.0;
    const double tx = R * std::cos(phi) + K, ty = R * std::sin(phi);
    const double d = std::hypot(tx, ty);
    const double c = (rho * rho - d * d - r * r) / (2.0 * d * r);
    if (c >= 1.0) continue;
    const double alpha = std::acos(std::max(-1.0, c));
    const double delta = std::atan2(ty, tx) - phi;
    best = std::max(best, std::min(kPi, alpha + delta));
  }
  return best;
}

double step_bound_front(double R, double r, double f) {
  const double b = R + (1.0 - 2.0 * f) * r;
  return -b + std::sqrt(b * b + 4.0 * f * R * r);
}

double step_bound_estimate(double R, double r, double f) {
  double lo = 0.0, hi = 2.0 * r;
  for (int it = 0; it < 50; ++it) {
    const double mid = 0.5 * (lo + hi);
    (equivalent_ae(engagement_angle_estimate(R, mid, r), r) <= f * 2.0 * r ? lo : hi) = mid;
  }
  return lo;
}

double step_bound_exact(double R, double r, double f) {
  const double target = f * 2.0 * r;
  double lo = 0.0, hi = 2.0 * r;
  for (int it = 0; it < 24; ++it) {
    const double mid = 0.5 * (lo + hi);
    const double ae = equivalent_ae(steady_engagement_at(R, mid, r, 0.5, 1.0).max_angle, r);
    (ae <= target ? lo : hi) = mid;
  }
  return lo;
}

double wall_scallop_height(double R, double K, double r, bool backward_wall) {
  const double V = K / kTwoPi;
  const double rho_path = backward_wall ? (R - V) * (R - V) / R : (R + V) * (R + V) / R;
  const double rho = rho_path + r;
  return rho - std::sqrt(rho * rho - 0.25 * K * K);
}

// --------------------------------------------------------------------------------------------
// Expansion

namespace {

struct PassPlan {
  int passes = 1;
  double dz = 0;
};

PassPlan plan_passes(const TrochoidSlot& s) {
  const double depth = s.start[2] - s.bottom;
  PassPlan p;
  if (s.depth_step > 0) p.passes = std::max(1, int(std::ceil(depth / s.depth_step - 1e-9)));
  p.dz = depth / p.passes;
  return p;
}

// Appends blocks that all share the cycle block's source line and modal state.
class Emitter {
 public:
  Emitter(const ResolvedBlock& in, std::vector<ResolvedBlock>& out,
          std::vector<TrochoidPart>* parts, double tol, bool arcs)
      : in_(in), out_(out), parts_(parts), tol_(tol), arcs_(arcs), pos_(in.start) {
    base_ = in;
    base_.slot = {};
    base_.tool_change = false;
    base_.stop = ProgramStop::kNone;
    base_.program_number = -1;
    base_.percent = false;
    base_.dwell = 0;
    base_.turns = 1;
    base_.plane = Plane::kXY;
    base_.centre = {};
    base_.radius = 0;
    base_.comment.clear();
    base_.axis_words = (1u << kX) | (1u << kY) | (1u << kZ);
    first_ = out.size();
  }

  const Axes& pos() const { return pos_; }

  void rapid(double x, double y, double z) {
    if (x == pos_[kX] && y == pos_[kY] && z == pos_[kZ]) return;
    push(Motion::kRapid, x, y, z, in_.feed, TrochoidPart::kApproach);
  }
  void line(double x, double y, double z, double feed, TrochoidPart part) {
    if (x == pos_[kX] && y == pos_[kY] && z == pos_[kZ]) return;
    push(Motion::kLinear, x, y, z, feed, part);
  }
  // Circular arc around (cx, cy) from the current point, sweeping `sweep` rad (sign = sense),
  // Z changing linearly (helix). G1 chords within the tolerance, or G2/G3 of at most half a turn.
  void circle(double cx, double cy, double sweep, double z_end, double feed, TrochoidPart part,
              const double* exact_end = nullptr) {
    const double x0 = pos_[kX] - cx, y0 = pos_[kY] - cy, z0 = pos_[kZ];
    const double rho = std::hypot(x0, y0);
    const double a0 = std::atan2(y0, x0);
    const int n = arcs_ ? std::max(1, int(std::ceil(std::abs(sweep) / kPi - 1e-12)))
                        : std::max(1, int(std::ceil(std::abs(sweep) / std::sqrt(8.0 * tol_ / rho))));
    const bool full_turns = std::abs(std::remainder(sweep, kTwoPi)) < 1e-12;
    const double start_x = pos_[kX], start_y = pos_[kY];
    for (int k = 1; k <= n; ++k) {
      const double a = a0 + sweep * k / n;
      // A full turn ends exactly where it started, not a rounding error away.
      double x = k == n && full_turns ? start_x : cx + rho * std::cos(a);
      double y = k == n && full_turns ? start_y : cy + rho * std::sin(a);
      if (k == n && exact_end) x = exact_end[0], y = exact_end[1];
      const double z = z0 + (z_end - z0) * k / n;
      if (arcs_) {
        push(sweep > 0 ? Motion::kArcCCW : Motion::kArcCW, x, y, z, feed, part);
        auto& b = out_.back();
        b.centre = {cx, cy, b.start[kZ]};
        b.radius = rho;
      } else {
        push(Motion::kLinear, x, y, z, feed, part);
      }
    }
  }
  void arc_to(double x, double y, double cx, double cy, bool ccw, double feed, TrochoidPart part) {
    push(ccw ? Motion::kArcCCW : Motion::kArcCW, x, y, pos_[kZ], feed, part);
    auto& b = out_.back();
    b.centre = {cx, cy, b.start[kZ]};
    b.radius = std::hypot(b.start[kX] - cx, b.start[kY] - cy);
  }
  void finish(const std::string& note) {
    if (out_.size() == first_) return;
    ResolvedBlock& f = out_[first_];
    f.tool_change = in_.tool_change;
    f.program_number = in_.program_number;
    f.percent = in_.percent;
    f.comment = in_.comment.empty() ? note : in_.comment + " | " + note;
    out_.back().stop = in_.stop;
  }

 private:
  // Rounding leaves values like 1e-16 where a coordinate is 0; a picometre snap keeps the
  // written program free of such noise.
  static double snap(double v) { return std::abs(v) < 1e-12 ? 0.0 : v; }

  void push(Motion m, double x, double y, double z, double feed, TrochoidPart part) {
    x = snap(x), y = snap(y), z = snap(z);
    ResolvedBlock b = base_;
    b.motion = m;
    b.start = pos_;
    b.target = pos_;
    b.target[kX] = x;
    b.target[kY] = y;
    b.target[kZ] = z;
    b.feed = feed;
    out_.push_back(std::move(b));
    if (parts_) parts_->push_back(part);
    pos_ = out_.back().target;
  }

  const ResolvedBlock& in_;
  std::vector<ResolvedBlock>& out_;
  std::vector<TrochoidPart>* parts_;
  double tol_;
  bool arcs_;
  Axes pos_;
  ResolvedBlock base_;
  std::size_t first_ = 0;
};

// Phase step of the G1 chords along the loops: chord error <= h^2/8 max|P''| (linear
// interpolation of a vector function); |P''| <= R + |a''| and |a''| <= 1.5 V / 2pi < V.
double chord_step(const SlotGeometry& g, double tol) { return std::sqrt(8.0 * tol / (g.loop_radius + g.speed)); }

// Number of equal chords LoopWriter::piece cuts the phase span [a, b] into.
int chord_count(double a, double b, double dphi) { return std::max(1, int(std::ceil((b - a) / dphi))); }

struct Circle {
  double cx, cy, rho;
  bool ok;
};

Circle circumcircle(double ax, double ay, double bx, double by, double cx, double cy) {
  const double d = 2.0 * (ax * (by - cy) + bx * (cy - ay) + cx * (ay - by));
  const double scale = std::max({std::abs(bx - ax), std::abs(by - ay), std::abs(cx - ax), std::abs(cy - ay)});
  if (std::abs(d) < 1e-12 * scale * scale) return {0, 0, 0, false};
  const double a2 = ax * ax + ay * ay, b2 = bx * bx + by * by, c2 = cx * cx + cy * cy;
  const double ux = (a2 * (by - cy) + b2 * (cy - ay) + c2 * (ay - by)) / d;
  const double uy = (a2 * (cx - bx) + b2 * (ax - cx) + c2 * (bx - ax)) / d;
  return {ux, uy, std::hypot(ax - ux, ay - uy), true};
}

// Emits the loops from phase a to b at height z as G1 chords or fitted G2/G3.
class LoopWriter {
 public:
  LoopWriter(const SlotGeometry& g, Emitter& em, double tol, bool arcs)
      : g_(g), em_(em), tol_(tol), arcs_(arcs), dphi_(chord_step(g, tol)) {}

  void piece(double a, double b, double z, double feed, TrochoidPart part, bool pure_circle) {
    if (arcs_ && pure_circle) {
      const double centre = g_.advance(0.5 * (a + b));
      double cx = g_.sx + centre * g_.ux, cy = g_.sy + centre * g_.uy;
      double x, y;
      g_.point(b, x, y);
      em_.arc_to(x, y, cx, cy, g_.sigma > 0, feed, part);
      return;
    }
    if (arcs_) {
      fit(a, b, z, feed, part, 0);
      return;
    }
    const int n = chord_count(a, b, dphi_);
    for (int k = 1; k <= n; ++k) {
      double x, y;
      g_.point(k == n ? b : a + (b - a) * k / n, x, y);
      em_.line(x, y, z, feed, part);
    }
  }

 private:
  double lateral(double x, double y) const {
    return -(x - g_.sx) * g_.uy + (y - g_.sy) * g_.ux;
  }

  // Circle through the ends and the middle; accepted when 8 interior samples lie within the
  // tolerance of it and the arc does not reach past the wall line |lateral| = R.
  void fit(double a, double b, double z, double feed, TrochoidPart part, int depth) {
    double x0, y0, xm, ym, x1, y1;
    g_.point(a, x0, y0);
    g_.point(0.5 * (a + b), xm, ym);
    g_.point(b, x1, y1);
    const Circle c = circumcircle(x0, y0, xm, ym, x1, y1);
    bool ok = c.ok && depth < 30;
    const bool ccw = (xm - x0) * (y1 - y0) - (ym - y0) * (x1 - x0) > 0;
    if (ok) {
      for (int k = 1; k <= 8 && ok; ++k) {
        double x, y;
        g_.point(a + (b - a) * (k - 0.5) / 8.0, x, y);
        ok = std::abs(std::hypot(x - c.cx, y - c.cy) - c.rho) <= tol_;
      }
    }
    if (ok) {
      // Highest lateral reach of the arc: the circle's extreme if the arc passes it.
      const double wall = g_.loop_radius + 1e-9;
      const double a0 = std::atan2(y0 - c.cy, x0 - c.cx);
      const double a1 = std::atan2(y1 - c.cy, x1 - c.cx);
      auto within = [&](double dir) {
        auto norm = [](double v) { v = std::fmod(v, kTwoPi); return v < 0 ? v + kTwoPi : v; };
        const double span = ccw ? norm(a1 - a0) : norm(a0 - a1);
        const double off = ccw ? norm(dir - a0) : norm(a0 - dir);
        return off <= span;
      };
      const double nx = -g_.uy, ny = g_.ux;
      const double lat_c = lateral(c.cx, c.cy);
      for (double s : {1.0, -1.0}) {
        if (within(std::atan2(s * ny, s * nx)) && std::abs(lat_c + s * c.rho) > wall) ok = false;
      }
    }
    if (!ok) {
      if (depth >= 30 || !c.ok) {
        em_.line(x1, y1, z, feed, part);
        return;
      }
      fit(a, 0.5 * (a + b), z, feed, part, depth + 1);
      fit(0.5 * (a + b), b, z, feed, part, depth + 1);
      return;
    }
    em_.arc_to(x1, y1, c.cx, c.cy, ccw, feed, part);
  }

  const SlotGeometry& g_;
  Emitter& em_;
  double tol_;
  bool arcs_;
  double dphi_;
};

}  // namespace

TrochoidExpander::TrochoidExpander(TrochoidOptions options) : opt_(options) {}

std::string TrochoidExpander::validate(const ResolvedBlock& in) const {
  if (in.motion != Motion::kTrochoidSlot) return {};
  const TrochoidSlot& s = in.slot;
  if (in.plane != Plane::kXY)
    return fmt("G275 mills in the XY plane; G%d is in force: program G17 before the cycle", int(in.plane));
  if (in.feed_mode != FeedMode::kUnitsPerMinute)
    return "G275 needs feed per minute (G94); inverse-time feed G93 is in force";
  if (!(in.feed > 0)) return fmt("feed F%g: the cycle needs a feed > 0 mm/min", in.feed);
  if (!(s.tool_diameter > 0))
    return fmt("tool diameter %g mm: give D or a tool T with a diameter in the machine config", s.tool_diameter);
  if (!(s.width > 0)) return fmt("slot width W%g must be > 0 mm", s.width);
  if (!(s.step > 0)) return fmt("step K%g must be > 0 mm", s.step);
  if (s.width <= s.tool_diameter)
    return fmt("slot width W%g is not wider than the tool (D%g mm): trochoidal loops need W > D",
               s.width, s.tool_diameter);
  if (s.width >= 2.0 * s.tool_diameter)
    return fmt("slot width W%g is at least twice the tool diameter D%g: loops of radius R = (W-D)/2 "
               "= %g mm >= D/2 leave an uncut core; W must be < %g mm", s.width, s.tool_diameter,
               0.5 * (s.width - s.tool_diameter), 2.0 * s.tool_diameter);
  const double length = xy_length(s);
  if (length < 1e-6)
    return fmt("slot of zero length: end X%g Y%g is the start point", s.end[0], s.end[1]);
  if (!(s.bottom < s.start[2]))
    return fmt("floor Z%g is not below the start Z%g: nothing to cut", s.bottom, s.start[2]);
  if (s.clearance < s.start[2])
    return fmt("clearance R%g is below the start Z%g: the retracts would dive", s.clearance, s.start[2]);
  if (s.depth_step < 0) return fmt("step-down Q%g must be >= 0 (0 = one pass)", s.depth_step);
  const PassPlan pp = plan_passes(s);
  const double max_ap = opt_.max_axial_depth_factor * s.tool_diameter;
  if (pp.dz > max_ap + 1e-9)
    return fmt("axial depth per pass %g mm (%s, %d pass%s) exceeds %g x D = %g mm "
               "(trochoid.max_axial_depth_factor): give Q <= %g", pp.dz,
               s.depth_step > 0 ? "from Q" : "Q0 = full depth", pp.passes, pp.passes > 1 ? "es" : "",
               opt_.max_axial_depth_factor, max_ap, max_ap);
  const double R = 0.5 * (s.width - s.tool_diameter), r = 0.5 * s.tool_diameter;
  const double k_eff = std::min(s.step, length);
  const SteadyEngagement se = cached_steady(R, k_eff, r);
  const double limit = opt_.max_engagement_fraction * s.tool_diameter;
  if (se.max_ae > limit + 1e-9)
    return fmt("step K%g gives a radial engagement ae = %.3f mm = %.1f %% of D%g (engagement angle "
               "%.1f deg); the limit is %.1f %% (trochoid.max_engagement_fraction): K must be <= %.3f mm",
               s.step, se.max_ae, 100.0 * se.max_ae / s.tool_diameter, s.tool_diameter,
               se.max_angle * 180.0 / kPi, 100.0 * opt_.max_engagement_fraction,
               step_bound_exact(R, r, opt_.max_engagement_fraction));
  return {};
}

void TrochoidExpander::skip(const ResolvedBlock& in, std::vector<ResolvedBlock>& out) const {
  Emitter em(in, out, nullptr, opt_.chord_tolerance, false);
  const double safe = std::max(in.start[kZ], in.slot.clearance);
  em.rapid(in.start[kX], in.start[kY], safe);
  em.rapid(in.target[kX], in.target[kY], safe);
  em.rapid(in.target[kX], in.target[kY], in.target[kZ]);
  em.finish("G275 left out: rapid to where the program continues");
}

namespace {

// Break points of the loop phase: stretch boundaries, walls (vertices exactly on the wall lines,
// so no chord or arc can reach past them), and the air stretches of each revolution (`air`).
std::vector<double> loop_breaks(const SlotGeometry& g, const SteadyEngagement& se, double margin,
                                std::vector<std::pair<double, double>>& air) {
  std::vector<double> cuts{g.phi_start_circle, g.phi_accel, g.phi_cruise, g.phi_decel, g.phi_end_circle, g.phi_end};
  for (double w = g.phase0; w < g.phi_end; w += kPi) cuts.push_back(w);
  if (se.air_end > se.air_begin && se.air_end - se.air_begin > 2.0 * margin) {
    const double k0 = std::floor((g.phi_accel - se.air_end) / kTwoPi);
    for (double k = k0;; k += 1.0) {
      const double lo = std::max(g.phi_accel, se.air_begin + margin + kTwoPi * k);
      const double hi = std::min(g.phi_end, se.air_end - margin + kTwoPi * k);
      if (se.air_begin + margin + kTwoPi * k > g.phi_end) break;
      if (hi > lo) {
        air.emplace_back(lo, hi);
        cuts.push_back(lo);
        cuts.push_back(hi);
      }
    }
  }
  std::sort(cuts.begin(), cuts.end());
  cuts.erase(std::unique(cuts.begin(), cuts.end(), [](double a, double b) { return b - a < 1e-12; }), cuts.end());
  return cuts;
}

// The way down to pass depth z from z_top: a helix, a zig-zag ramp or a plunge, each ending on
// the loop's start point p0.
void write_entry(Emitter& em, const SlotGeometry& g, const TrochoidSlot& s, TrochoidEntry entry, double z_top, double z,
                 double entry_feed, double tan_a, const double p0[2]) {
  const double R = g.loop_radius, sx = g.sx, sy = g.sy;
  const double mx = 0.5 * (sx + p0[0]), my = 0.5 * (sy + p0[1]);
  switch (entry) {
    case TrochoidEntry::kHelix: {
      em.circle(mx, my, g.sigma * kPi, z_top, entry_feed, TrochoidPart::kEntry, p0);
      const double per_turn = kTwoPi * R * tan_a;
      const int turns = std::max(1, int(std::ceil((z_top - z) / per_turn - 1e-9)));
      for (int t = 1; t <= turns; ++t)
        em.circle(sx, sy, g.sigma * kTwoPi, z_top - (z_top - z) * t / turns, entry_feed,
                  TrochoidPart::kEntry);
      break;
    }
    case TrochoidEntry::kRamp: {
      const double ramp_len = std::min(g.length, s.tool_diameter);
      const double fx = sx + ramp_len * g.ux, fy = sy + ramp_len * g.uy;
      double zc = z_top;
      bool forward = true;
      while (zc > z + 1e-12) {
        const double drop = ramp_len * tan_a;
        const double tx = forward ? fx : sx, ty = forward ? fy : sy;
        if (zc - drop >= z) {
          zc -= drop;
          em.line(tx, ty, zc, entry_feed, TrochoidPart::kEntry);
        } else {
          const double frac = (zc - z) / drop;
          const double ax = em.pos()[kX] + (tx - em.pos()[kX]) * frac;
          const double ay = em.pos()[kY] + (ty - em.pos()[kY]) * frac;
          zc = z;
          em.line(ax, ay, z, entry_feed, TrochoidPart::kEntry);
          em.line(tx, ty, z, entry_feed, TrochoidPart::kEntry);
        }
        forward = !forward;
      }
      em.line(sx, sy, z, entry_feed, TrochoidPart::kEntry);
      em.circle(mx, my, g.sigma * kPi, z, entry_feed, TrochoidPart::kEntry, p0);
      break;
    }
    case TrochoidEntry::kPlunge:
      em.line(sx, sy, z, entry_feed, TrochoidPart::kEntry);
      em.circle(mx, my, g.sigma * kPi, z, entry_feed, TrochoidPart::kEntry, p0);
      break;
  }
}

// The feeds of a cycle's moves [mm/min]: programmed, entry and air (TrochoidOptions).
struct CycleFeeds {
  double feed, entry, air;
};

CycleFeeds cycle_feeds(const ResolvedBlock& in, const TrochoidOptions& o) {
  return {in.feed, in.feed * o.entry_feed_factor, o.air_feed > 0 ? o.air_feed : in.feed * o.air_feed_factor};
}

// The part of the loops a piece between two break points belongs to, and its feed: the start
// circle at the entry feed, the air stretches at the air feed, the rest at the programmed feed.
// One rule for the expansion and for its time estimate, so that the two cannot disagree.
std::pair<TrochoidPart, double> piece_part(const SlotGeometry& g, const std::vector<std::pair<double, double>>& air,
                                           double mid, const CycleFeeds& f) {
  std::pair<TrochoidPart, double> p{TrochoidPart::kLoops, f.feed};
  if (mid < g.phi_accel) p = {TrochoidPart::kStartCircle, f.entry};  // finishes the entry: cuts the helix's last wedge or the plunge's ring
  else if (mid > g.phi_end_circle) p.first = TrochoidPart::kEndCircle;
  for (auto [lo, hi] : air)
    if (mid > lo && mid < hi) p = {TrochoidPart::kAir, f.air};
  return p;
}

// The loops of one pass, piece by piece between the break points.
void write_loops(LoopWriter& lw, const SlotGeometry& g, const std::vector<double>& cuts,
                 const std::vector<std::pair<double, double>>& air, double z, const CycleFeeds& feeds) {
  for (std::size_t i = 0; i + 1 < cuts.size(); ++i) {
    const double a = cuts[i], b = cuts[i + 1], mid = 0.5 * (a + b);
    const auto [part, f] = piece_part(g, air, mid, feeds);
    const bool pure = mid < g.phi_accel || mid > g.phi_end_circle;
    lw.piece(a, b, z, f, part, pure);
  }
}

// Length of the loop path from phase a to b along the chords LoopWriter::piece writes as G1 (an
// arc fitted instead is at least as long as the chord it replaces, and so is the true curve).
double chord_length(const SlotGeometry& g, double a, double b, double dphi) {
  const int n = chord_count(a, b, dphi);
  double len = 0, px, py;
  g.point(a, px, py);
  for (int k = 1; k <= n; ++k) {
    double x, y;
    g.point(k == n ? b : a + (b - a) * k / n, x, y);
    len += std::hypot(x - px, y - py);
    px = x;
    py = y;
  }
  return len;
}

}  // namespace

namespace {

// Emitter::circle writes a circle of radius rho as chords of at most theta = sqrt(8 tol / rho);
// a chord is 2 rho sin(theta/2) = rho theta (1 - theta^2/24 + ...) >= (1 - tol / (3 rho)) of its arc.
double chord_factor(double rho, double tol) { return 1.0 - tol / (3.0 * rho); }

// Length of write_entry's path from z_top down to z [mm], in closed form: the lead-in half circle
// has the radius R/2 (its ends S and p0 are R apart, p0 on the wall at phase pi/2); the helix's
// turns are circles of radius R, each dropping (z_top - z) / turns; the ramp drops at the entry
// angle a, so its zig-zag is (z_top - z) / sin(a) long and its way back to S is left out. Circles
// count as their chords (chord_factor), so the length is never more than the expansion's.
double entry_length(const SlotGeometry& g, TrochoidEntry entry, double z_top, double z, double tan_a, double tol) {
  const double R = g.loop_radius, lead_in = 0.5 * kPi * R * chord_factor(0.5 * R, tol), drop = z_top - z;
  switch (entry) {
    case TrochoidEntry::kHelix: {
      const int turns = std::max(1, int(std::ceil(drop / (kTwoPi * R * tan_a) - 1e-9)));
      return lead_in + turns * std::hypot(kTwoPi * R, drop / turns) * chord_factor(R, tol);
    }
    case TrochoidEntry::kRamp: return lead_in + drop / std::sin(std::atan(tan_a));
    case TrochoidEntry::kPlunge: return lead_in + drop;
  }
  return lead_in;
}

// The height each pass's entry starts from, as expand() chooses it.
double pass_top(const TrochoidSlot& s, const PassPlan& pp, int pass, double approach_clearance) {
  if (pass == 1) return s.start[2];
  return std::min(s.clearance, s.start[2] - (pass - 1) * pp.dz + approach_clearance);
}

double pass_floor(const TrochoidSlot& s, const PassPlan& pp, int pass) {
  return pass == pp.passes ? s.bottom : s.start[2] - pass * pp.dz;
}

}  // namespace

TrochoidExpander::Status TrochoidExpander::expand(const ResolvedBlock& in,
                                                  std::vector<ResolvedBlock>& out,
                                                  std::vector<TrochoidPart>* parts) const {
  if (in.motion != Motion::kTrochoidSlot) {
    out.push_back(in);
    if (parts) parts->push_back(TrochoidPart::kApproach);
    return {Status::Code::kCopied, {}};
  }
  if (std::string why = validate(in); !why.empty()) return {Status::Code::kRejected, why};

  const TrochoidSlot& s = in.slot;
  const SlotGeometry g = make_slot_geometry(s, in.spindle == Spindle::kCCW);
  const double R = g.loop_radius;
  const SteadyEngagement se = cached_steady(R, g.speed * kTwoPi, g.tool_radius);
  const PassPlan pp = plan_passes(s);
  const CycleFeeds feeds = cycle_feeds(in, opt_);
  const double feed = feeds.feed, entry_feed = feeds.entry;
  const double tan_a = std::tan(opt_.entry_angle_deg * kPi / 180.0);

  std::vector<std::pair<double, double>> air;
  const std::vector<double> cuts = loop_breaks(g, se, opt_.air_margin_deg * kPi / 180.0, air);

  Emitter em(in, out, parts, opt_.chord_tolerance, opt_.arcs);
  LoopWriter lw(g, em, opt_.chord_tolerance, opt_.arcs);
  const double sx = g.sx, sy = g.sy;
  double p0x, p0y;
  g.point(g.phase0, p0x, p0y);
  const double p0[2] = {p0x, p0y};
  for (int pass = 1; pass <= pp.passes; ++pass) {
    const double z = pass_floor(s, pp, pass), z_top = pass_top(s, pp, pass, opt_.approach_clearance);
    if (pass > 1) {
      em.rapid(em.pos()[kX], em.pos()[kY], s.clearance);
      em.rapid(sx, sy, s.clearance);
      em.rapid(sx, sy, z_top);
    }
    write_entry(em, g, s, opt_.entry, z_top, z, entry_feed, tan_a, p0);
    write_loops(lw, g, cuts, air, z, feeds);
    // Lead-out: half circle of radius R/2 from the last loop point to E, tangent to the loop.
    const double qx = em.pos()[kX], qy = em.pos()[kY];
    const double end_xy[2] = {g.ex, g.ey};
    em.circle(0.5 * (qx + g.ex), 0.5 * (qy + g.ey), g.sigma * kPi, z, feed, TrochoidPart::kExit, end_xy);
    em.rapid(g.ex, g.ey, s.clearance);
  }
  // Leave the tool where the parser's modal state expects it.
  em.rapid(in.target[kX], in.target[kY], s.clearance);
  if (in.target[kZ] != s.clearance) em.rapid(in.target[kX], in.target[kY], in.target[kZ]);
  em.finish(fmt("G275 trochoidal slot W%g D%g K%g: R=%g mm, %d pass%s", s.width, s.tool_diameter,
                s.step, R, pp.passes, pp.passes > 1 ? "es" : ""));
  return {Status::Code::kExpanded, {}};
}


namespace {

// Minutes one pass of loops takes at their feeds, along the G1 chords expand() writes.
double loop_minutes(const SlotGeometry& g, const CycleFeeds& feeds, const TrochoidOptions& o) {
  const SteadyEngagement se = cached_steady(g.loop_radius, g.speed * kTwoPi, g.tool_radius);
  std::vector<std::pair<double, double>> air;
  const std::vector<double> cuts = loop_breaks(g, se, o.air_margin_deg * kPi / 180.0, air);
  const double dphi = chord_step(g, o.chord_tolerance);
  double minutes = 0;
  for (std::size_t i = 0; i + 1 < cuts.size(); ++i)
    minutes += chord_length(g, cuts[i], cuts[i + 1], dphi) / piece_part(g, air, 0.5 * (cuts[i] + cuts[i + 1]), feeds).second;
  return minutes;
}

}  // namespace

double TrochoidExpander::feed_time_lower_bound(const ResolvedBlock& in) const {
  if (in.motion != Motion::kTrochoidSlot || !validate(in).empty()) return 0.0;
  const SlotGeometry g = make_slot_geometry(in.slot, in.spindle == Spindle::kCCW);
  const CycleFeeds feeds = cycle_feeds(in, opt_);
  const double loops = loop_minutes(g, feeds, opt_);  // every pass runs the same loops at its own depth
  const PassPlan pp = plan_passes(in.slot);
  const double tan_a = std::tan(opt_.entry_angle_deg * kPi / 180.0), tol = opt_.chord_tolerance;
  // The last loop point is E + R (cos phi u + sigma sin phi n): R from E, a half circle of radius R/2.
  const double lead_out = 0.5 * kPi * g.loop_radius * chord_factor(0.5 * g.loop_radius, tol);
  double minutes = 0;
  for (int pass = 1; pass <= pp.passes; ++pass) {
    const double z_top = pass_top(in.slot, pp, pass, opt_.approach_clearance), z = pass_floor(in.slot, pp, pass);
    minutes += loops + entry_length(g, opt_.entry, z_top, z, tan_a, tol) / feeds.entry + lead_out / feeds.feed;
  }
  return 60.0 * minutes;
}

TrochoidExpander::Status TrochoidExpander::step(const ResolvedBlock& in, const std::string& file,
                                                std::vector<ResolvedBlock>& out, Diagnostic& diag,
                                                std::vector<TrochoidPart>* parts) const {
  Status st = expand(in, out, parts);
  if (st.ok()) return st;
  diag = Diagnostic{file, in.line, 0, Severity::kError, "G275 rejected: " + st.message};
  // The parser has moved its modal position to the cycle's end: follow it without cutting.
  const std::size_t before = out.size();
  skip(in, out);
  if (parts) parts->resize(parts->size() + (out.size() - before), TrochoidPart::kApproach);
  return st;
}

}  // namespace gcpipe
