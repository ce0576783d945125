// Cutter radius compensation (G41/G42 on, G40 off) in the XY plane, LinuxCNC dialect (Fanuc below).
//
// The behaviour is LinuxCNC's, as its interpreter shows it (rs274 -g, see the README section and
// tests/rs274_diff_test.cpp), not its code:
//  - the first XY move after G41/G42 is the entry move: a straight line from where the tool
//    stands to the programmed end offset by the radius, perpendicular to the move; it must be
//    longer than the radius;
//  - a move's compensated end is known only when the next XY move is read (one-move
//    look-behind), so the parser holds the move, and every block read after it, until then;
//  - a convex (outside) corner gets an arc of the tool radius about the programmed corner;
//  - a concave (inside) corner ends one move and starts the next at the intersection of their
//    offset paths (line/line, line/arc, arc/arc); a move that the intersection would make run
//    backwards cannot be cut without gouging: an error;
//  - corners that turn by at most 0.05 rad are joined as they are, without arc or intersection;
//  - an arc whose offset radius would not be positive is an error;
//  - G40 (and M2/M30): the held move ends at its offset end; the next move goes from there
//    straight to its programmed end.
//
// In the Fanuc dialect the same machinery runs Fanuc's cutter compensation C (0i-MF / 30i
// operator's manual, Type A start-up and cancel, parameter SUP = 0); only these rules differ
// (fanuc_corner), alpha being the angle between the two moves on the workpiece side:
//  - start-up (Type A): the entry move ends at the programmed end offset perpendicular to the
//    START direction of the next move, i.e. where the next move's offset path starts; an arc as
//    the start-up (or cancel) block is alarm PS0034; no minimum length;
//  - inner corner (alpha >= 180 deg): the intersection of the offset paths, as LinuxCNC's
//    concave corner (concave_corner, with its gouging check);
//  - outer obtuse corner (90 <= alpha < 180): no corner arc; the tool goes to the intersection X
//    of the two lines offset from the tangents at the corner (for two lines: of the offset lines).
//    A line's end or start moves to X along itself; an arc ends (starts) at its own offset end
//    (start) and a straight move joins it to X;
//  - outer acute corner (alpha < 90): P1 = corner + r n1 + r t1, P2 = corner + r n2 - r t2
//    (n the offset normals, t1 the held move's unit direction at its end, t2 the next move's at
//    its start): the tool goes on to P1, straight to P2, then on along the next offset path;
//  - a straight-through corner (turn within 1e-6 rad) joins as it is;
//  - G40 (Type A): as LinuxCNC, from the held move's offset end straight to the programmed end.
// Everything here works in machine coordinates [mm], so units and work offsets do not matter.
#include <cmath>
#include <cstdio>
#include <numbers>

#include "parse_internal.hpp"

namespace gcpipe {

using namespace parse_detail;

namespace {

// rs274 joins moves whose directions differ by 0.04996 rad without a corner and puts an arc on a
// convex corner of 0.0599 rad: LinuxCNC's threshold for a corner is 0.05 rad.
constexpr double kSmoothCorner = 0.05;
// Fanuc has no such threshold: a corner is straight through only within rounding of the
// programmed numbers (at r = 10 mm a 1e-6 rad corner is 5e-6 mm).
constexpr double kFanucStraight = 1e-6;
constexpr double kEps = 1e-9;  // [mm] or [rad]: rounding, not geometry
constexpr double kTwoPi = 2 * std::numbers::pi;

P2 operator+(P2 a, P2 b) { return {a.x + b.x, a.y + b.y}; }
P2 operator-(P2 a, P2 b) { return {a.x - b.x, a.y - b.y}; }
P2 operator*(P2 a, double k) { return {a.x * k, a.y * k}; }
double dot(P2 a, P2 b) { return a.x * b.x + a.y * b.y; }
double cross(P2 a, P2 b) { return a.x * b.y - a.y * b.x; }
double norm(P2 a) { return std::hypot(a.x, a.y); }
P2 unit(P2 a) { return a * (1 / norm(a)); }
P2 left_normal(P2 t) { return {-t.y, t.x}; }
// The compensation plane's two axes, (u, v) = (X, Y) in G17 and (Z, X) in G18 (LinuxCNC's order
// for the XZ plane: its left side of a move along +X is -Z), and its normal.
struct PlaneAxesUV {
  int u, v, n;
};
PlaneAxesUV uv(Plane p) { return p == Plane::kZX ? PlaneAxesUV{kZ, kX, kY} : PlaneAxesUV{kX, kY, kZ}; }
template <class Point>  // Axes or Vec3 (an arc's centre)
P2 xy(const Point& a, Plane p) { return {a[uv(p).u], a[uv(p).v]}; }
template <class Point>
void set_xy(Point& a, Plane p, P2 q) {
  a[uv(p).u] = q.x;
  a[uv(p).v] = q.y;
}
std::uint8_t plane_bits(Plane p) { return static_cast<std::uint8_t>((1u << uv(p).u) | (1u << uv(p).v)); }

bool is_arc(Motion m) { return m == Motion::kArcCW || m == Motion::kArcCCW; }

// A move compensation offsets: an arc, or a straight move that changes X or Y. Z-only moves,
// dwells and blocks that move nothing wait behind the held move instead.
bool moves_in_xy(const ResolvedBlock& b) {
  if (is_arc(b.motion)) return true;
  if (b.motion != Motion::kRapid && b.motion != Motion::kLinear) return false;
  return norm(xy(b.target, b.plane) - xy(b.start, b.plane)) > kEps;
}

// Unit tangent of an arc about `c` at `p`, in the arc's direction.
P2 arc_tangent(P2 c, P2 p, bool cw) {
  const P2 r = unit(p - c);
  return cw ? P2{r.y, -r.x} : P2{-r.y, r.x};
}

// Angle swept from `a` to `p` about `c` in the arc's direction, in [0, 2 pi); a point a hair
// before `a` counts as `a`, not as a full turn.
double swept(P2 c, P2 a, P2 p, bool cw) {
  double t = std::atan2(cross(a - c, p - c), dot(a - c, p - c));
  if (cw) t = -t;
  if (t < 0) t += kTwoPi;
  return t > kTwoPi - 1e-7 ? 0 : t;
}

// How far `to` lies ahead of `from` along a move's offset path [mm, or rad in [0, 2 pi)].
double ahead(const OffsetMove& m, P2 from, P2 to) {
  return m.arc ? swept(m.centre, from, to, m.cw) : dot(to - from, m.dir);
}

// The length of what is left of a move from where the tool starts it: a full circle that no
// corner has shortened is a whole turn, not nothing.
double remaining(const OffsetMove& m) {
  if (m.full_circle && norm(m.start - m.path_start) < kEps) return kTwoPi;
  return ahead(m, m.start, m.end);
}

// The intersection nearer to `near` of a line (point, unit direction) and a circle.
bool line_circle(P2 p, P2 d, P2 c, double r, P2 near, P2& x) {
  const P2 f = p - c;
  const double b = dot(f, d), disc = b * b - (dot(f, f) - r * r);
  if (disc < 0) return false;
  const double s = std::sqrt(disc);
  const P2 x1 = p + d * (-b - s), x2 = p + d * (-b + s);
  x = norm(x1 - near) <= norm(x2 - near) ? x1 : x2;
  return true;
}

// The intersection nearer to `near` of two circles.
bool circle_circle(P2 c1, double r1, P2 c2, double r2, P2 near, P2& x) {
  const P2 d = c2 - c1;
  const double l = norm(d);
  if (l < kEps || l > r1 + r2 || l < std::fabs(r1 - r2)) return false;
  const double a = (r1 * r1 - r2 * r2 + l * l) / (2 * l);
  const double h = std::sqrt(std::max(0.0, r1 * r1 - a * a));
  const P2 m = c1 + d * (a / l), n = left_normal(d * (1 / l));
  const P2 x1 = m + n * h, x2 = m - n * h;
  x = norm(x1 - near) <= norm(x2 - near) ? x1 : x2;
  return true;
}

// Where the offset paths of two moves meet near their programmed corner. An arc's offset circle
// has its radius at the corner: the held arc's end radius, the new arc's start radius (an I J
// arc's radii may differ within the tolerance; rs274 then lands up to that difference away).
bool intersect(const OffsetMove& p, const OffsetMove& n, P2& x) {
  if (!p.arc && !n.arc) {
    const double den = cross(p.dir, n.dir);
    if (std::fabs(den) < 1e-12) return false;
    x = p.end + p.dir * (cross(n.start - p.end, n.dir) / den);
    return true;
  }
  if (!p.arc) return line_circle(p.end, p.dir, n.centre, n.radius, p.corner, x);
  if (!n.arc) return line_circle(n.start, n.dir, p.centre, p.end_radius, p.corner, x);
  return circle_circle(p.centre, p.end_radius, n.centre, n.radius, p.corner, x);
}

// A concave corner at `x` keeps both moves running forwards: the held one `p` from where it
// starts now, the new one `n` up to its offset end.
bool corner_reachable(const OffsetMove& p, const OffsetMove& n, P2 x) {
  const double p_at = ahead(p, p.start, x);
  const bool p_ok = p.entry || (p.arc ? p_at <= remaining(p) + kEps : p_at >= -kEps);
  return p_ok && ahead(n, n.start, x) <= remaining(n) + kEps;
}

// Signed curvature of a move's programmed path: + turning left (G3), - right (G2).
double curvature(const OffsetMove& m, bool at_end) {
  if (!m.arc) return 0;
  return (m.cw ? -1 : 1) / (at_end ? m.path_end_radius : m.path_radius);
}

// Outside the turn is convex: a right turn (turn < 0) with the tool on the left. An exact
// reversal has no sign: there the curvatures decide. Leaving the corner, the held move (run
// backwards) and the new one bend apart or together; if the tool's side of the one overlaps the
// other's, the cusp is a pocket the tool cuts into (concave: rs274 cuts the cusp between two G2
// bumps on their outside at the intersection), else the tool goes round it (a line turning back,
// the inside of the bumps).
//
// Not as rs274: a turn into the tool's side within 0.05 rad of a reversal (a spike narrower than
// 5.7 deg) is concave here, cut at the intersection if the moves are long enough, else an error.
// rs274 goes round its tip with an arc when a line is involved, and the tool then cuts into the
// part (measured: 1.56 mm deep with a 1 mm radius on a 177.5 deg turn).
bool corner_is_convex(int side, double turn, const OffsetMove& p, const OffsetMove& n) {
  if (std::numbers::pi - std::fabs(turn) > 1e-9) return side * turn < 0;
  // Lateral offsets leaving the corner (left of the new move's direction, per s^2/2): the new
  // move's is its curvature, the held move's run backwards its curvature negated. The tool
  // stands left of the new move and right of the reversed held one for G41, mirrored for G42.
  const double y_held = -curvature(p, true), y_new = curvature(n, false);
  return side > 0 ? !(y_held > y_new + kEps) : !(y_held < y_new - kEps);
}

const char* side_name(int side) { return side > 0 ? "G41" : "G42"; }

}  // namespace

// The column an error about the line's move points at: its first axis word or G code.
static std::uint32_t move_col(const Scan& s) {
  if (s.has('X')) return s.w('X').col;
  if (s.has('Y')) return s.w('Y').col;
  return s.ng > 0 ? s.g[0].col : 1;
}

// One line under compensation (or right after it): fills comp_next and comp_out, or fails
// leaving both to be dropped. `plain_emit`: the line's own block (or expansion) goes out as
// usual, after comp_out.
bool Parser::Impl::compensate(const ModalState& ns, bool& plain_emit) {
  comp_next = comp;
  comp_out.clear();
  plain_emit = false;
  ResolvedBlock& b = block;
  if (comp_next.pending) {
    if (ns.comp_side == 0) {  // G40, M2 or M30: the held move ends where it is offset to
      comp_next.at = comp_next.move.end;
      comp_next.off_path = true;
      finish_pending(comp_next.move.end);
      return leave_offset(b, ns, plain_emit);
    }
    if (moves_in_xy(b)) return next_move(ns, b);
    comp_next.held.push_back(b);
    return true;
  }
  if (ns.comp_side != 0 && moves_in_xy(b)) return entry_move(ns, b);
  return leave_offset(b, ns, plain_emit);
}

// The entry move: from where the tool stands to the programmed end offset perpendicular to the
// move. Held: its end moves if the corner with the next move is concave.
bool Parser::Impl::entry_move(const ModalState& ns, ResolvedBlock& b) {
  const double r = ns.comp_radius;
  const bool fanuc = opt.dialect == Dialect::kFanuc;
  comp_next.plane = ns.plane;
  if (is_arc(b.motion) && !fanuc) return entry_arc(ns, b);
  if (is_arc(b.motion))
    return fail(move_col(sc), std::string(b.motion == Motion::kArcCW ? "G2" : "G3") + " as the first move after " +
                                  side_name(ns.comp_side) + ": the entry move of cutter compensation must be a "
                                  "straight line (G0 or G1) to the contour (Fanuc alarm PS0034: no arc in the start-up block)");
  const P2 s = comp_next.off_path ? comp_next.at : xy(b.start, ns.plane), e = xy(b.target, ns.plane);
  const double len = norm(e - s);
  if (len <= r && !fanuc)  // Fanuc's Type A start-up has no minimum length
    return fail(move_col(sc), "cutter compensation entry move is " + show(len) + " mm long, not longer than the tool "
                              "radius " + show(r) + " mm: start the entry further from the contour");
  OffsetMove m;
  m.entry = true;
  m.dir = (e - s) * (1 / len);
  m.start = s;
  m.corner = e;
  m.end = e + left_normal(m.dir) * (r * ns.comp_side);
  m.path_start = m.end - m.dir * len;
  m.start_tangent = m.end_tangent = m.dir;
  comp_next.pending = true;
  comp_next.move = m;
  comp_next.block = b;
  comp_next.off_path = false;
  return true;
}

// LinuxCNC's entry arc: from where the tool stands to the programmed end moved by the radius
// along the end's radial direction u (out when the tool runs outside the arc, in when inside:
// delta = +r or -r), about a centre moved along u too, c = c0 + t u, so that it is as far from
// the start s as from the new end e + delta u (the end keeps the programmed arc's tangent):
//   |c0 + t u - s|^2 = (R + delta - t)^2  =>  t = ((R + delta)^2 - |c0 - s|^2) / (2 (u.(c0 - s) + R + delta))
// R = |e - c0|. rs274 draws exactly this arc (tests/rs274_diff_test.cpp, comp_arc_entry). Held, as
// a line entry is: its end moves if the corner with the next move is concave.
bool Parser::Impl::entry_arc(const ModalState& ns, ResolvedBlock& b) {
  const char* g = b.motion == Motion::kArcCW ? "G2" : "G3";
  if (b.turns != 1)
    return fail(move_col(sc), std::string(g) + " P" + std::to_string(b.turns) + " (several turns) as the entry move of cutter compensation is not supported");
  const P2 s = comp_next.off_path ? comp_next.at : xy(b.start, ns.plane), e = xy(b.target, ns.plane);
  const P2 c0 = xy(b.centre, ns.plane);
  const bool cw = b.motion == Motion::kArcCW;
  const double big_r = norm(e - c0), delta = (ns.comp_side > 0) == cw ? ns.comp_radius : -ns.comp_radius;
  const P2 u = unit(e - c0);
  const double den = 2 * (dot(u, c0 - s) + big_r + delta);
  const double t = std::fabs(den) > kEps ? ((big_r + delta) * (big_r + delta) - dot(c0 - s, c0 - s)) / den : 0;
  const double radius = big_r + delta - t;
  if (big_r <= kEps || std::fabs(den) <= kEps || radius <= kEps)
    return fail(move_col(sc), std::string(g) + ": radius of cutter compensation entry arc is not greater than the tool radius "
                              "(rs274's words): no arc joins the tool's position to the offset end");
  OffsetMove m;
  m.entry = m.arc = true;
  m.cw = cw;
  m.centre = c0 + u * t;
  m.radius = m.end_radius = radius;
  m.path_radius = m.path_end_radius = big_r;
  m.start = m.path_start = s;
  m.corner = e;
  m.end = e + u * delta;
  m.start_tangent = arc_tangent(m.centre, s, cw);
  m.end_tangent = arc_tangent(c0, e, cw);
  set_xy(b.centre, ns.plane, m.centre);
  comp_next.pending = true;
  comp_next.move = m;
  comp_next.block = b;
  comp_next.off_path = false;
  return true;
}

// A move's path offset by the radius to the compensation's side, before any corner moves it.
bool Parser::Impl::offset_path(const ModalState& ns, const ResolvedBlock& b, OffsetMove& m) {
  const P2 s = xy(b.start, ns.plane), e = xy(b.target, ns.plane);
  const double r = ns.comp_radius;
  m.corner = e;
  if (!is_arc(b.motion)) {
    m.dir = unit(e - s);
    const P2 off = left_normal(m.dir) * (r * ns.comp_side);
    m.path_start = m.start = s + off;
    m.end = e + off;
    m.start_tangent = m.end_tangent = m.dir;
    return true;
  }
  const char* g = b.motion == Motion::kArcCW ? "G2" : "G3";
  if (b.turns != 1)
    return fail(sc.has('P') ? sc.w('P').col : move_col(sc),
                std::string(g) + " P" + std::to_string(b.turns) + " (several turns) under cutter compensation is not supported");
  m.arc = true;
  m.full_circle = norm(e - s) < kEps;
  m.cw = b.motion == Motion::kArcCW;
  m.centre = xy(b.centre, ns.plane);
  // The tool runs outside the arc when it is left of a clockwise arc or right of a
  // counter-clockwise one, else inside, where the offset radius shrinks.
  const double grow = (ns.comp_side > 0) == m.cw ? r : -r;
  const double rs = norm(s - m.centre), re = norm(e - m.centre);
  // (re can be 0 only on an arc within the parser's radius tolerance of nothing: no direction.)
  if (std::min(rs, re) + grow <= kEps || re <= kEps)
    return fail(move_col(sc), std::string(g) + ": tool radius " + show(r) + " mm not less than arc radius " + show(rs) +
                                  " mm with " + side_name(ns.comp_side) + " (the tool runs inside this arc): it "
                                  "cannot be cut with this tool");
  // The offset path keeps the arc's centre, so its radii differ by what the programmed ones do,
  // on a radius smaller by the tool's when the tool runs inside: an arc just within the 0.1 %
  // tolerance can leave it, and output.nc (or a control) would reject the arc written. The
  // programmed arc is the one to fix, so it is rejected here, at its line.
  if (!arc_radii_agree(rs + grow, re + grow, arc_radius_tolerance(ns.units == Units::kInch))) {
    const bool inch = ns.units == Units::kInch;
    const double k = inch ? 1 / kInch : 1, diff = std::fabs(rs - re), r = std::max(rs, re);
    const char* unit = inch ? "inch" : "mm";
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  "%s: with %s the tool path's radii differ by %.4g %s, %.4f %% of its radius %.4g %s: past the "
                  "0.1 %% an arc may have (the programmed arc, %.4f %% of %.4g %s, is within it); put the arc's "
                  "end on the circle through its start",
                  g, side_name(ns.comp_side), diff * k, unit, 100 * diff / (r + grow), (r + grow) * k, unit,
                  100 * diff / r, r * k, unit);
    return fail(move_col(sc), buf);
  }
  m.radius = rs + grow;
  m.end_radius = re + grow;
  m.path_radius = rs;
  m.path_end_radius = re;
  m.path_start = m.start = m.centre + unit(s - m.centre) * (rs + grow);
  m.end = m.centre + unit(e - m.centre) * (re + grow);
  m.start_tangent = arc_tangent(m.centre, s, m.cw);
  m.end_tangent = arc_tangent(m.centre, e, m.cw);
  return true;
}

// The next XY move: the corner with the held move decides where that one ends; this one is
// held in its place.
bool Parser::Impl::next_move(const ModalState& ns, ResolvedBlock& b) {
  OffsetMove n;
  if (!offset_path(ns, b, n)) return false;
  if (opt.dialect == Dialect::kFanuc) return fanuc_corner(ns, b, n);
  const OffsetMove& p = comp_next.move;
  const double turn = std::atan2(cross(p.end_tangent, n.start_tangent), dot(p.end_tangent, n.start_tangent));
  const bool convex = corner_is_convex(ns.comp_side, turn, p, n);
  P2 held_end = p.end;
  bool arc = false;
  if (std::fabs(turn) <= kSmoothCorner) {
    n.start = p.end;
  } else if (convex) {
    arc = true;
  } else {
    if (!concave_corner(ns, n)) return false;
    held_end = n.start;
  }
  const P2 corner = p.corner;
  finish_pending(held_end);
  if (arc) {  // about the programmed corner, from the held move's offset end to this one's start
    ResolvedBlock a = b;
    a.comment.clear();
    a.stop = ProgramStop::kNone;
    // Before a G0 rs274 goes round the corner in a straight traverse (an arc is always a feed
    // move, and a G0 may have no feed to give it).
    const bool rapid = b.motion == Motion::kRapid;
    a.motion = rapid ? Motion::kRapid : ns.comp_side > 0 ? Motion::kArcCW : Motion::kArcCCW;
    a.target = a.start;
    set_xy(a.start, ns.plane, held_end);
    set_xy(a.target, ns.plane, n.start);
    a.plane = ns.plane;
    a.centre = Vec3{0, 0, 0};
    if (!rapid) {
      set_xy(a.centre, ns.plane, corner);
      a.centre[uv(ns.plane).n] = a.start[uv(ns.plane).n];
    }
    a.radius = rapid ? 0 : ns.comp_radius;
    a.turns = 1;
    a.axis_words = plane_bits(ns.plane);
    comp_out.push_back(std::move(a));
  }
  comp_next.pending = true;
  comp_next.move = n;
  comp_next.block = b;
  return true;
}

// Fanuc's corner between the held move and the next one `n` (cutter compensation C, see the top
// of the file): the points the tool passes from the held move's offset end to `n`'s offset start.
bool Parser::Impl::fanuc_corner(const ModalState& ns, ResolvedBlock& b, OffsetMove& n) {
  const OffsetMove& p = comp_next.move;
  std::vector<P2> pts;  // [held move's end, extra points..., n's start]
  const double turn = std::atan2(cross(p.end_tangent, n.start_tangent), dot(p.end_tangent, n.start_tangent));
  if (p.entry) {  // Type A start-up: perpendicular to the next move's start direction
    pts = {n.start};
  } else if (std::fabs(turn) <= kFanucStraight) {
    pts = {p.end};
  } else if (!corner_is_convex(ns.comp_side, turn, p, n)) {  // inner corner: alpha >= 180 deg
    if (!concave_corner(ns, n)) return false;
    pts = {n.start};
  } else {
    const double r = ns.comp_radius;
    const P2 t1 = p.end_tangent, t2 = n.start_tangent;
    if (std::fabs(turn) <= std::numbers::pi / 2 + kEps) {  // obtuse (alpha >= 90): the tangent lines meet
      const P2 x = p.end + t1 * (cross(n.start - p.end, t2) / cross(t1, t2));
      pts = {p.end, x, n.start};
    } else {  // acute: r on along the held move, r back before the next
      const P2 n1 = left_normal(t1) * ns.comp_side, n2 = left_normal(t2) * ns.comp_side;
      pts = {p.end, p.corner + n1 * r + t1 * r, p.corner + n2 * r - t2 * r, n.start};
    }
    // A line's own end (start) moves along it to the first (last) point.
    if (!p.arc) pts.erase(pts.begin());
    if (!n.arc) pts.pop_back();
  }
  n.start = pts.back();
  finish_pending(pts.front());
  corner_moves(b, pts);
  comp_next.pending = true;
  comp_next.move = n;
  comp_next.block = b;
  return true;
}

// Straight moves through `pts` (Fanuc's corner points), blocks of the next move's line: G0 before
// a G0, else G1 at the next move's feed.
void Parser::Impl::corner_moves(const ResolvedBlock& b, const std::vector<P2>& pts) {
  for (std::size_t i = 0; i + 1 < pts.size(); ++i) {
    if (norm(pts[i + 1] - pts[i]) <= kEps) continue;
    ResolvedBlock a = b;
    a.comment.clear();
    a.stop = ProgramStop::kNone;
    a.motion = b.motion == Motion::kRapid ? Motion::kRapid : Motion::kLinear;
    a.target = a.start;
    set_xy(a.start, Plane::kXY, pts[i]);
    set_xy(a.target, Plane::kXY, pts[i + 1]);
    a.plane = Plane::kXY;
    a.centre = Vec3{0, 0, 0};
    a.radius = 0;
    a.turns = 1;
    a.axis_words = static_cast<std::uint8_t>((1u << kX) | (1u << kY));
    comp_out.push_back(std::move(a));
  }
}

// A concave corner: both moves meet where their offset paths cross. Neither may run backwards
// to get there, or the tool would cut into the part: LinuxCNC calls that gouging.
bool Parser::Impl::concave_corner(const ModalState& ns, OffsetMove& n) {
  const OffsetMove& p = comp_next.move;
  P2 x;
  const bool met = intersect(p, n, x);
  if (!met || !corner_reachable(p, n, x))
    return fail(move_col(sc), std::string("concave corner with ") + side_name(ns.comp_side) + ": the tool (radius " +
                                  show(ns.comp_radius) + " mm) cannot reach " + (met ? "it" : "this corner") +
                                  " without gouging: a move next to it is shorter than the tool needs");
  n.start = x;
  return true;
}

// The held move ends at `end`; it goes out with the blocks held behind it, which stand there.
void Parser::Impl::finish_pending(P2 end) {
  CutterComp& c = comp_next;
  ResolvedBlock& f = c.block;
  set_xy(f.start, c.plane, c.move.start);
  set_xy(f.target, c.plane, end);
  if (c.move.arc) f.radius = norm(c.move.start - c.move.centre);
  f.axis_words = static_cast<std::uint8_t>(f.axis_words | plane_bits(c.plane));
  Axes at = f.target;
  comp_out.push_back(std::move(f));
  for (ResolvedBlock& h : c.held) {  // from where the one before left the tool (a flow-control
    h.start = at;                    // statement's block carries no position of its own)
    if (h.motion == Motion::kNone || h.motion == Motion::kDwell) h.target = at;
    set_xy(h.target, c.plane, end);
    at = h.target;
    comp_out.push_back(std::move(h));
  }
  c.held.clear();
  c.pending = false;
}

// A block while no move is held. After G40 the tool stands off the programmed path: the next
// move goes from there straight to its programmed end (an arc could not); blocks before it
// stand where the tool is.
bool Parser::Impl::leave_offset(ResolvedBlock& b, const ModalState& ns, bool& plain_emit) {
  plain_emit = true;
  CutterComp& c = comp_next;
  if (!c.off_path) return true;
  if (!moves.empty() || (ns.comp_side == 0 && (b.motion == Motion::kRapid || b.motion == Motion::kLinear))) {
    set_xy(b.start, c.plane, c.at);  // an expansion's first move starts at block.start too
    b.axis_words = static_cast<std::uint8_t>(b.axis_words | plane_bits(c.plane));
    c.off_path = false;
    return true;
  }
  if (is_arc(b.motion))
    return fail(move_col(sc), std::string(b.motion == Motion::kArcCW ? "G2" : "G3") +
                                  " as the move after G40: the move that leaves cutter compensation must be a "
                                  "straight line (G0 or G1)" +
                                  (opt.dialect == Dialect::kFanuc ? " (Fanuc alarm PS0034: no arc in the cancel block)" : ""));
  set_xy(b.start, c.plane, c.at);  // a move off the plane, a dwell, a block that moves nothing
  set_xy(b.target, c.plane, c.at);
  return true;
}

// End of input with a move still held: it ends at its offset end, as at M2.
bool Parser::Impl::flush_compensation() {
  if (!comp.pending) return !stopped;
  comp_next = comp;
  comp_out.clear();
  comp_next.at = comp_next.move.end;
  comp_next.off_path = true;
  finish_pending(comp_next.move.end);
  comp = std::move(comp_next);
  for (const ResolvedBlock& b : comp_out)
    if (!hand_out(b)) break;
  comp_out.clear();
  return !stopped;
}

}  // namespace gcpipe
