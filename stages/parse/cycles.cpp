// Canned cycles G73 G74 G81..G86 G89 (and the Fanuc boring cycles G76 G87 G88) expanded into
// plain moves, as LinuxCNC's interpreter expands them (checked move for move against its rs274
// in tests/rs274_diff_test.cpp) and as the Fanuc manuals describe them. In the G17 plane the drilling axis is Z, in G18 Y, in G19 X.
//
// Per repeat (L, or K on Fanuc): rapid to the hole in the plane at the current level, rapid down
// to R, the cycle's own strokes, retract to the clear level: R in G99, in G98 the higher of R and
// the level the series of cycle blocks started at (the initial level, in both dialects). If the
// drilling axis starts below R it first rapids up to R (LinuxCNC's preliminary move). G91: R is
// measured from the initial level (LinuxCNC; Fanuc: from the level at the block's start), the
// bottom from R, and the hole position step (or the polar @ ^ step) is repeated L times.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "parse_internal.hpp"

namespace gcpipe {

using namespace parse_detail;

namespace parse_detail {
// The resolved numbers of one cycle block.
struct CycleGeometry {
  PlaneAxes pa;
  int code;
  double r, bottom, clear;  // levels along the drilling axis [mm, machine]
  double q, dwell;          // peck depth [mm] and dwell [s]
  double shift[kNumAxes];   // G76/G87: the shift at the oriented spindle stop [mm]
  bool incremental;
  long repeats;
};
}  // namespace parse_detail

namespace {

// LinuxCNC's G73 chip-break retract and G83 re-approach clearance: 0.010 inch (its
// G83_RAPID_DELTA); Fanuc's parameter d, taken at the same value.
constexpr double kPeckDelta = 0.010 * kInch;  // [mm]


// Builds the moves of one hole; `pos` is where the tool stands, updated.
class HoleWriter {
 public:
  HoleWriter(std::vector<Move>& moves, Axes& pos, int n) : moves_(moves), pos_(pos), n_(n) {}
  void rapid_to(double level) { to(Motion::kRapid, level); }
  void feed_to(double level) { to(Motion::kLinear, level); }
  void rapid_in_plane(int u, double pu, int v, double pv) {
    Axes t = pos_;
    t[u] = pu;
    t[v] = pv;
    add(Motion::kRapid, t);
  }
  void dwell(double s) {
    if (s > 0) moves_.push_back({Motion::kDwell, pos_, s});
  }
  void spindle(Spindle sp) { spindle_ = static_cast<int>(sp); }
  // Fanuc G76/G87: the oriented spindle stops and the tool tip moves off the wall by the shift.
  void shift(const double (&by)[kNumAxes], double sign) {
    Axes t = pos_;
    for (int a = 0; a < kNumAxes; ++a) t[a] += sign * by[a];
    add(Motion::kRapid, t);
  }
  // G88: the spindle stops and the program stops where the tool is (a move of no length).
  void stop_here() {
    moves_.push_back({Motion::kDwell, pos_, 0, static_cast<int>(Spindle::kOff), true});
  }

 private:
  void to(Motion m, double level) {
    Axes t = pos_;
    t[n_] = level;
    add(m, t);
  }
  // A stroke that goes nowhere (R reached already) is not a move: it is left out.
  void add(Motion m, const Axes& t) {
    if (t == pos_) return;
    moves_.push_back({m, t, 0, spindle_});
    pos_ = t;
  }
  std::vector<Move>& moves_;
  Axes& pos_;
  int n_;
  int spindle_ = -1;
};

void peck(HoleWriter& h, const CycleGeometry& g, bool full_retract) {
  double depth = g.r;
  while (depth - g.q > g.bottom) {
    depth -= g.q;
    h.feed_to(depth);
    if (full_retract) {
      h.rapid_to(g.r);
      h.rapid_to(depth + kPeckDelta);
    } else {
      h.rapid_to(depth + kPeckDelta);
    }
  }
  h.feed_to(g.bottom);
  h.rapid_to(g.clear);
}

// The Fanuc boring cycles, from the 0i-MF operator's manual (B-64604EN), canned cycles section:
// "G76 fine boring": bore to the bottom, dwell P, oriented spindle stop, shift by Q (at rapid,
// away from the wall), rapid out to the clear level, shift back, spindle on again.
// Oriented spindle stop, shift by Q away from the wall, rapid to `level`, shift back, spindle on:
// how G76 and G87 move the tool past the bore's wall without marking it.
void rapid_past_the_wall(HoleWriter& h, const CycleGeometry& g, double level, Spindle spindle) {
  h.spindle(Spindle::kOff);
  h.shift(g.shift, 1);
  h.rapid_to(level);
  h.shift(g.shift, -1);
  h.spindle(spindle);
}

void fine_bore(HoleWriter& h, const CycleGeometry& g, Spindle spindle) {
  h.feed_to(g.bottom);
  h.dwell(g.dwell);
  rapid_past_the_wall(h, g, g.clear, spindle);
}

// "G87 back boring": R is below the part and the bottom Z above it. Oriented stop, shift, rapid
// down to R, shift back, spindle on (CW), bore upwards to Z, dwell P, oriented stop, shift,
// rapid up to the initial level, shift back, spindle on. Entered from the initial level.
void back_bore(HoleWriter& h, const CycleGeometry& g, Spindle spindle) {
  rapid_past_the_wall(h, g, g.r, spindle);
  h.feed_to(g.bottom);
  h.dwell(g.dwell);
  rapid_past_the_wall(h, g, g.clear, spindle);
}

// "G88 boring": bore, dwell P, spindle stop and the control stops; the operator jogs the tool
// out by hand, which has no programmed path. gcpipe stands for the jog with a rapid straight
// out to the clear level (R in G99, the initial level in G98), as the control itself moves to
// that level when the cycle is restarted; the spindle turns again from there.
void manual_retract_bore(HoleWriter& h, const CycleGeometry& g, Spindle spindle) {
  h.feed_to(g.bottom);
  h.dwell(g.dwell);
  h.spindle(Spindle::kOff);
  h.stop_here();
  h.rapid_to(g.clear);
  h.spindle(spindle);
}

// The strokes of one hole below R, ending at the clear level.
void strokes(HoleWriter& h, const CycleGeometry& g, Spindle spindle) {
  switch (g.code) {
    case 730: return peck(h, g, false);
    case 830: return peck(h, g, true);
    case 810: case 820:
      h.feed_to(g.bottom);
      h.dwell(g.code == 820 ? g.dwell : 0);
      return h.rapid_to(g.clear);
    case 850: case 890:
      h.feed_to(g.bottom);
      h.dwell(g.code == 890 ? g.dwell : 0);
      h.feed_to(g.r);
      return h.rapid_to(g.clear);
    case 860:
      // Bore, dwell, stop the spindle, rapid out, restart it.
      h.feed_to(g.bottom);
      h.dwell(g.dwell);
      h.spindle(Spindle::kOff);
      h.rapid_to(g.clear);
      return h.spindle(spindle);
    case 840: case 740: {
      // Tapping: in with the spindle as it turns, reverse at the bottom, out at feed.
      h.feed_to(g.bottom);
      h.spindle(spindle == Spindle::kCW ? Spindle::kCCW : Spindle::kCW);
      h.dwell(g.dwell);
      h.feed_to(g.r);
      h.spindle(spindle);
      return h.rapid_to(g.clear);
    }
    case 760: return fine_bore(h, g, spindle);
    case 880: return manual_retract_bore(h, g, spindle);
    default: return;
  }
}

// The spindle a cycle starts from: in Fanuc rigid tapping (M29) the control turns it as the tap
// needs, forwards for G84 and backwards for G74, whatever M3/M4 said.
Spindle tapping_spindle(const ModalState& ns) {
  if (!ns.rigid_tap) return ns.spindle;
  if (ns.cycle == 840) return Spindle::kCW;
  return ns.cycle == 740 ? Spindle::kCCW : ns.spindle;
}

// The clear level of a cycle, and the order of R and the bottom: every cycle drills towards the
// minus side of its axis from R, except G87 (back boring), which bores upwards from an R below
// the part and returns to the initial level only (0i-MF manual: G87 cannot use the R level;
// G99 is refused by the caller).
// The shift of G76/G87 from the machine's parameter (5101 RD2 RD1 as a number 0..3): + or - the
// first or second axis of the plane, by Q.
void set_boring_shift(CycleGeometry& g, double q, int rd) {
  for (double& d : g.shift) d = 0;
  g.shift[rd < 2 ? g.pa.u : g.pa.v] = rd % 2 == 0 ? q : -q;
}

// Empty when the levels are right, else why not.
std::string cycle_levels(CycleGeometry& g, const ModalState& ns) {
  const std::string name = code_text('G', g.code);
  const char axis = kAxisLetters[g.pa.n];
  if (g.code == 870) {
    if (g.bottom < g.r) return "G87: the end " + std::string(1, axis) + " is below the R plane: back boring cuts towards +" + axis;
    g.clear = ns.cycle_initial;
    if (g.clear < g.bottom) return "G87: the initial level is below the end of the bore: start the cycle above the part";
    return {};
  }
  if (g.bottom > g.r)
    return name + ": the bottom " + axis + " is above the R plane: the cycle drills towards -" + axis;
  // G98: the level the series of cycles began at, in both dialects (rs274: a G98 block after a
  // G99 block that left the tool at R still retracts to the series' start level).
  g.clear = ns.cycle_to_r ? g.r : std::max(g.r, ns.cycle_initial);
  return {};
}

}  // namespace

// A block in a canned-cycle mode with axis words: one or more holes. The checks come in the
// control's order: rotary words, the levels (R and the depth, sticky), the cycle's own words,
// the feed; then the holes.
bool Parser::Impl::cycle(const BlockCodes& c, ResolvedBlock& b, ModalState& ns, std::uint8_t mask) {
  const std::string name = code_text('G', ns.cycle);
  const std::uint32_t col = c.motion_col ? c.motion_col : 1;
  CycleGeometry g{};
  g.pa = plane_axes(ns.plane);
  g.code = ns.cycle;
  g.incremental = ns.incremental;
  for (char L : {'A', 'C'})
    if (sc.has(L)) return fail(sc.w(L).col, name + " with " + L + ": rotary axes cannot move in a canned cycle");
  // rs274 refuses them too ("Y value unspecified in xz plane canned cycle"): @ ^ give X and Y.
  if (polar_words() && ns.plane != Plane::kXY)
    return fail(sc.polar_r.col ? sc.polar_r.col : sc.polar_a.col,
                name + " with @ ^: polar coordinates place holes in the G17 plane only");
  if (!cycle_levels_of(ns, g, name, col) || !cycle_words(ns, g, name, col) || !cycle_size_ok(ns, g, name, col))
    return false;
  const Motion saved = ns.motion;
  ns.motion = Motion::kLinear;
  const bool feed_ok = check_feed(c, ns);
  ns.motion = saved;
  if (!feed_ok) return false;
  drill_holes(b, ns, g, mask);
  return true;
}

// The moves one hole of a cycle expands into, at most: the pecks of G73/G83 (2 or 3 moves each,
// as many as the depth holds Q) and a dozen fixed strokes.
namespace {
double moves_per_hole(const CycleGeometry& g) {
  constexpr double kFixedStrokes = 12;
  if (g.code != 730 && g.code != 830) return kFixedStrokes;
  const double pecks = std::ceil((g.r - g.bottom) / g.q);
  return kFixedStrokes + pecks * (g.code == 830 ? 3 : 2);
}
}  // namespace

// A block is expanded whole before its first move goes on, so its size is checked before the
// expansion: Q0.000001 over 100 mm (1e8 pecks) would otherwise take gigabytes and minutes.
bool Parser::Impl::cycle_size_ok(const ModalState& ns, const CycleGeometry& g, const std::string& name,
                                 std::uint32_t col) {
  const double moves = static_cast<double>(g.repeats) * moves_per_hole(g);
  if (moves <= static_cast<double>(opt.max_cycle_moves)) return true;
  const bool pecks = g.code == 730 || g.code == 830;
  const std::uint32_t at = pecks && ns.cycle_q.col ? ns.cycle_q.col : col;
  char n[64];
  std::snprintf(n, sizeof n, "%.3g", moves);
  return fail(at, name + " would expand into about " + n + " moves" +
                      (pecks ? " (" + show(g.r - g.bottom) + " mm deep in pecks of Q" + show(g.q) + " mm" +
                                   (g.repeats > 1 ? ", " + std::to_string(g.repeats) + " holes" : "") + ")"
                             : "") +
                      ", more than parse.max_cycle_moves (" + std::to_string(opt.max_cycle_moves) + "): " +
                      (pecks ? "raise Q, " : "") + "use fewer repeats or raise parse.max_cycle_moves");
}

// R and the depth word (sticky across cycle blocks) to the levels along the drilling axis.
bool Parser::Impl::cycle_levels_of(ModalState& ns, CycleGeometry& g, const std::string& name, std::uint32_t col) {
  const Scan& s = sc;
  const int n = g.pa.n;
  const char depth_letter = kAxisLetters[n];
  if (s.has('R')) ns.cycle_r = s.w('R');
  if (s.has(depth_letter)) ns.cycle_z = s.w(depth_letter);
  if (s.has('Q')) ns.cycle_q = s.w('Q');
  if (s.has('P')) ns.cycle_p = s.w('P');
  if (ns.cycle_r.col == 0) return fail(col, name + " needs R (the retract plane), in this block or an earlier cycle block");
  if (ns.cycle_z.col == 0)
    return fail(col, name + " needs " + depth_letter + " (the hole bottom), in this block or an earlier cycle block");
  // G91: R is measured from where the block starts on Fanuc (as before; not checked against a
  // control), from the level the series of cycles began at in rs274, which a block after a G99
  // block shows: `G91 G81 ... R-1` standing at R1 of a series begun at Z5 goes to R4, not R0.
  const double base = opt.dialect == Dialect::kLinuxCnc ? ns.cycle_initial : ns.position[n];
  const double r_word = linear_value(ns.cycle_r, ns.units);
  const double z_word = linear_value(ns.cycle_z, ns.units);
  g.r = g.incremental ? base + r_word : r_word + ns.origin[n];
  g.bottom = g.incremental ? g.r + z_word : z_word + ns.origin[n];
  if (ns.cycle == 870 && ns.cycle_to_r) return fail(col, "G87 (back boring) returns to the initial level: use G98, not G99");
  if (const std::string why = cycle_levels(g, ns); !why.empty())
    return fail(s.has(depth_letter) ? s.w(depth_letter).col : col, why);
  return true;
}

// The cycle's own words: the boring shift or peck depth Q, the dwell P, the repeats L (Fanuc K),
// and the spindle direction a tapping cycle needs.
bool Parser::Impl::cycle_words(ModalState& ns, CycleGeometry& g, const std::string& name, std::uint32_t col) {
  const Scan& s = sc;
  if (ns.cycle == 760 || ns.cycle == 870) {
    const double q = ns.cycle_q.col ? linear_value(ns.cycle_q, ns.units) : 0;
    if (!(q > 0)) return fail(ns.cycle_q.col ? ns.cycle_q.col : col, name + " needs a positive shift Q (the tool moves off the wall by Q at the bottom)");
    set_boring_shift(g, q, opt.boring_shift);
  }
  if (ns.cycle == 730 || ns.cycle == 830) {
    g.q = ns.cycle_q.col ? linear_value(ns.cycle_q, ns.units) : 0;
    if (!(g.q > 0)) return fail(ns.cycle_q.col ? ns.cycle_q.col : col, name + " needs a positive peck depth Q");
  }
  if (ns.cycle_p.col) {
    const double p = ns.cycle_p.value;
    g.dwell = opt.dialect == Dialect::kFanuc ? p / 1000.0 : p;  // Fanuc P in ms, LinuxCNC in s
    if (g.dwell < 0 || g.dwell > 1e5) return fail(ns.cycle_p.col, name + " P" + show(p) + ": the dwell is out of range (0..100000 s)");
  }
  const char rep = opt.dialect == Dialect::kFanuc && s.has('K') ? 'K' : 'L';
  g.repeats = 1;
  if (s.has(rep)) {
    const double v = s.w(rep).value;
    if (v < 0 || v > 10000 || v != std::floor(v))
      return fail(s.w(rep).col, name + " " + rep + show(v) + ": the number of repeats must be a whole number 0..10000");
    g.repeats = static_cast<long>(v);
  }
  if (ns.rigid_tap && (ns.cycle == 840 || ns.cycle == 740)) return true;  // M29: the control turns the spindle
  if (ns.cycle == 840 && ns.spindle != Spindle::kCW)
    return fail(col, "G84 (right-hand tapping) needs the spindle turning clockwise (M3) before the cycle");
  if (ns.cycle == 740 && ns.spindle != Spindle::kCCW)
    return fail(col, "G74 (left-hand tapping) needs the spindle turning counter-clockwise (M4) before the cycle");
  return true;
}

// Where the next hole is in the plane, the tool standing at `pos`: G90 the block's words (or
// where the tool is), the same hole each repeat; G91 a step per repeat. Polar words (@ ^, G17
// only) give X and Y from `pos`: in G91 each repeat adds the distance and the angle again, as
// rs274 drills a bolt circle `G91 G81 @0 ^60 L6`.
void Parser::Impl::next_hole(const ModalState& ns, const CycleGeometry& g, std::uint8_t mask, const Axes& pos,
                             Axes& hole) const {
  hole = pos;
  if (polar_words()) return polar_point(ns, pos, hole);
  for (int a : {g.pa.u, g.pa.v}) {
    if (!(mask & (1u << a))) continue;
    const double w = linear_value(sc.w(kAxisLetters[a]), ns.units);
    hole[a] = g.incremental ? pos[a] + w : w + ns.origin[a];
  }
}

// The holes' moves, repeat by repeat.
void Parser::Impl::drill_holes(ResolvedBlock& b, ModalState& ns, CycleGeometry& g, std::uint8_t mask) {
  const int u = g.pa.u, v = g.pa.v;
  Axes pos = ns.position;
  HoleWriter h(moves, pos, g.pa.n);
  if (pos[g.pa.n] < g.r && g.code != 870) h.rapid_to(g.r);  // preliminary move, once
  Axes hole{};
  for (long i = 0; i < g.repeats; ++i) {
    next_hole(ns, g, mask, pos, hole);
    h.rapid_in_plane(u, hole[u], v, hole[v]);
    if (g.code == 870) {  // R is below the part: reached shifted, by back_bore
      back_bore(h, g, ns.spindle);
      continue;
    }
    h.rapid_to(g.r);
    strokes(h, g, tapping_spindle(ns));
  }
  b.motion = moves.empty() ? Motion::kNone : moves.back().motion;
  b.target = pos;
  ns.position = pos;
}

}  // namespace gcpipe

namespace gcpipe {

using namespace parse_detail;

// LinuxCNC's G33.1 Z K: rigid tapping along Z. In at K per spindle revolution (F = K x S), the
// spindle reversed at the bottom, out again to where the tap started, the spindle as before
// (LinuxCNC's manual, "G33.1 Rigid Tapping"; rs274 states it as RIGID_TAP to the bottom). The
// spindle's overrun past both ends is the drive's, not modelled. A line after it with axis words
// alone moves in no mode (as after G80): LinuxCNC would tap again, gcpipe rejects it rather than
// move otherwise.
bool Parser::Impl::rigid_tap(ResolvedBlock& b, ModalState& ns, const Axes& target, std::uint8_t mask) {
  const std::uint32_t col = sc.g[0].col;
  if (!sc.has('K') || !(sc.w('K').value > 0)) return fail(col, "G33.1 needs K: the thread pitch (distance per revolution), > 0");
  if (!(mask & (1u << kZ))) return fail(col, "G33.1 needs Z: the depth of the hole");
  if ((mask & ~(1u << kZ)) != 0)
    return fail(col, "G33.1 with an axis other than Z: gcpipe taps along Z only (move over the hole with G0 first)");
  if (ns.spindle == Spindle::kOff || !(ns.spindle_speed > 0))
    return fail(col, "G33.1 needs the spindle turning (M3 or M4 with S) before the tap");
  if (ns.comp_side != 0) return fail(col, "cannot use G33.1 with cutter radius compensation on: program G40 first");
  const Axes start = ns.position;
  const double feed = linear_value(sc.w('K'), ns.units) * ns.spindle_speed;  // [mm/min]
  if (feed > kMaxFeed) return fail(sc.w('K').col, "G33.1 feed K x S = " + show(feed) + " mm/min is out of range");
  const int reversed = static_cast<int>(ns.spindle == Spindle::kCW ? Spindle::kCCW : Spindle::kCW);
  moves.push_back({Motion::kLinear, target, 0, -1, false, feed});
  moves.push_back({Motion::kLinear, start, 0, reversed, false, feed});
  b.motion = Motion::kLinear;
  b.target = start;
  ns.motion = Motion::kNone;
  return true;
}

}  // namespace gcpipe
