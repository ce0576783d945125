// Geometry of moves that are more than a target: arcs (centre and radius formats with LinuxCNC's
// tolerance), machine-coordinate moves (G53), returns through an intermediate point to the
// machine file's reference positions (G28/G30), coordinate shifts (G92 family, G52), offsets set
// from the program (G10), and the G275 slot.
#include <cmath>

#include "parse_internal.hpp"

namespace gcpipe {

using namespace parse_detail;

namespace {

const char* plane_name(Plane p) {
  return p == Plane::kXY ? "XY (G17)" : p == Plane::kZX ? "ZX (G18)" : "YZ (G19)";
}

}  // namespace

// Radius format: the centre on the side R's sign asks for, LinuxCNC's tolerance for a radius a
// hair shorter than half the chord.
bool Parser::Impl::radius_centre(const ArcGeometry& g, bool cw, const ModalState& ns, double& cu, double& cv) {
  Impl& m = *this;
  const Scan& s = sc;
  if (s.has(g.pa.ou) || s.has(g.pa.ov))
    return m.fail(g.col, std::string(g.gname) + " with both R and a centre (" + g.pa.ou + "/" + g.pa.ov + "): keep one");
  const double r = m.linear_value(s.w('R'), ns.units);
  const double du = g.eu - g.su, dv = g.ev - g.sv;
  const double chord = std::hypot(du, dv);
  if (chord < 1e-12)
    return m.fail(g.col, std::string(g.gname) + " R" + show(s.w('R').value) +
                             ": the end point equals the start point, so the radius cannot place the centre (use I/J for a full circle)");
  if (r == 0) return m.fail(g.col, std::string(g.gname) + " R0: the radius must not be zero");
  const double half = chord / 2;
  double h2 = r * r - half * half;
  if (h2 < 0) {
    if (half - std::fabs(r) > g.t_abs)
      return m.fail(g.col, std::string(g.gname) + " R" + show(s.w('R').value) + ": this arc cannot exist, the radius " +
                               show(std::fabs(r)) + " mm is smaller than half the distance from start to end (" +
                               show(half) + " mm)");
    h2 = 0;  // within tolerance: a half circle
  }
  // Centre to the right of start->end for CW with R > 0 (arc of at most 180 deg), else left.
  double h = std::sqrt(h2);
  if (cw == (r < 0)) h = -h;  // left side
  const double mu = (g.su + g.eu) / 2, mv = (g.sv + g.ev) / 2;
  cu = mu + h * dv / chord;  // right-hand normal of (du, dv) is (dv, -du)
  cv = mv - h * du / chord;
  return true;
}

// Centre format: I J K incremental or absolute, and the start and end radii must agree within
// LinuxCNC's tolerance; the message is LinuxCNC's, in the program's units.
bool Parser::Impl::offset_centre(const ArcGeometry& g, const ModalState& ns, double& cu, double& cv) {
  Impl& m = *this;
  const Scan& s = sc;
  const PlaneAxes& pa = g.pa;
  if (!s.has(pa.ou) && !s.has(pa.ov))
    return m.fail(g.col, std::string(g.gname) + " needs a centre (" + pa.ou + "/" + pa.ov + ") or a radius R in the " +
                             (ns.plane == Plane::kXY ? "XY" : ns.plane == Plane::kZX ? "ZX" : "YZ") + " plane");
  const double ou = s.has(pa.ou) ? m.linear_value(s.w(pa.ou), ns.units) : 0;
  const double ov = s.has(pa.ov) ? m.linear_value(s.w(pa.ov), ns.units) : 0;
  cu = ns.arc_incremental ? g.su + ou : ou + ns.origin[pa.u];
  cv = ns.arc_incremental ? g.sv + ov : ov + ns.origin[pa.v];
  const double r1 = std::hypot(g.su - cu, g.sv - cv);
  const double r2 = std::hypot(g.eu - cu, g.ev - cv);
  if (r1 < 1e-9) return m.fail(g.col, std::string(g.gname) + ": the centre is at the start point (radius zero)");
  if (!arc_radii_agree(r1, r2, g.t_abs)) {
    const double abs_err = std::fabs(r1 - r2);
    const double rel_err = abs_err / std::max(r1, r2);
    const double k = g.inch ? 1 / kInch : 1;  // report in the program's units, as LinuxCNC does
    const double ou0 = ns.origin[pa.u], ov0 = ns.origin[pa.v];
    char buf[400];
    const char U = kAxisLetters[pa.u], V = kAxisLetters[pa.v];
    std::snprintf(buf, sizeof buf,
                  "%s: radius to end of arc differs from radius to start: start=(%c%.4f,%c%.4f) "
                  "center=(%c%.4f,%c%.4f) end=(%c%.4f,%c%.4f) r1=%.4f r2=%.4f abs_err=%.4g rel_err=%.4f%% "
                  "(tolerance %.4g %s, or %.4g %s and 0.1%%)",
                  g.gname, U, (g.su - ou0) * k, V, (g.sv - ov0) * k, U, (cu - ou0) * k, V, (cv - ov0) * k, U,
                  (g.eu - ou0) * k, V, (g.ev - ov0) * k, r1 * k, r2 * k, abs_err * k, rel_err * 100,
                  100 * g.t_abs * k, g.inch ? "inch" : "mm", g.t_abs * k, g.inch ? "inch" : "mm");
    return m.fail(g.col, buf);
  }
  return true;
}

// Centre-format and radius-format arcs, with LinuxCNC's radius tolerance (see
// ../shared/data/gcode/linuxcnc/interp_arc_tolerance/bad__README.arc-radius-tolerance).
bool Parser::Impl::arc(const Scan& s, ResolvedBlock& b, ModalState& ns, bool cw) {
  ArcGeometry g{};
  g.pa = plane_axes(ns.plane);
  const PlaneAxes& pa = g.pa;
  g.su = ns.position[pa.u];
  g.sv = ns.position[pa.v];
  g.eu = b.target[pa.u];
  g.ev = b.target[pa.v];
  g.inch = ns.units == Units::kInch;
  g.t_abs = arc_radius_tolerance(g.inch);
  g.gname[0] = 'G';
  g.gname[1] = cw ? '2' : '3';
  g.col = s.has('R') ? s.w('R').col : s.has(pa.ou) ? s.w(pa.ou).col : s.has(pa.ov) ? s.w(pa.ov).col : 1;
  int turns = 1;
  if (s.has('P')) {
    const Word& w = s.w('P');
    if (w.value < 1 || w.value > 10000 || w.value != std::floor(w.value))
      return fail(w.col, std::string(g.gname) + " P" + show(w.value) + ": the number of turns must be a whole number 1..10000");
    turns = static_cast<int>(w.value);
  }
  // The offset letter along the plane normal is not allowed (K in G17 etc.).
  const char normal_letter = pa.n == kZ ? 'K' : pa.n == kY ? 'J' : 'I';
  if (s.has(normal_letter)) {
    const std::string what = std::string(1, normal_letter) + show(s.w(normal_letter).value) + " in a " + g.gname +
                             " block in the " + plane_name(ns.plane) + " plane";
    if (!opt.ignore_arc_normal_word)
      return fail(s.w(normal_letter).col, what + ": the centre is given by " + pa.ou + " and " + pa.ov +
                                              " (Grbl ignores it: parse.ignore_arc_normal_word does too, each use reported)");
    note_warning(s.w(normal_letter).col, what + " ignored, as Grbl does (parse.ignore_arc_normal_word)");
  }
  double cu = 0, cv = 0;
  // R with P: the centre from R, then P - 1 more full turns round it (rs274's reading).
  if (s.has('R')) {
    if (!radius_centre(g, cw, ns, cu, cv)) return false;
  } else if (!offset_centre(g, ns, cu, cv)) {
    return false;
  }
  b.plane = ns.plane;
  b.centre = {0, 0, 0};
  b.centre[static_cast<std::size_t>(pa.u)] = cu;
  b.centre[static_cast<std::size_t>(pa.v)] = cv;
  b.centre[static_cast<std::size_t>(pa.n)] = ns.position[pa.n];
  b.radius = std::hypot(g.su - cu, g.sv - cv);
  b.turns = turns;
  ns.position = b.target;
  return true;
}

// G275 trochoidal slot: X Y end, Z floor, R clearance, W width, K step/rev, Q step-down,
// D tool diameter, F feed, P direction. Geometry checks belong to the trochoid stage.
bool Parser::Impl::slot(const Scan& s, ResolvedBlock& b, ModalState& ns) {
  const std::uint32_t col = s.g[0].col;
  for (char L : {'A', 'C'})
    if (s.has(L)) return fail(s.w(L).col, std::string("G275 slot cycle with ") + L + ": rotary axes cannot move in the cycle");
  if (!s.has('X') && !s.has('Y')) return fail(col, "G275 needs the slot end point: X and/or Y");
  for (char L : {'Z', 'R', 'W', 'K'})
    if (!s.has(L))
      return fail(col, std::string("G275 needs ") + L +
                           (L == 'Z' ? " (slot floor)" : L == 'R' ? " (clearance plane)" : L == 'W' ? " (slot width)" : " (step per trochoid revolution)"));
  TrochoidSlot& t = b.slot;
  t.start = {ns.position[kX], ns.position[kY], ns.position[kZ]};
  t.end = {b.target[kX], b.target[kY], ns.position[kZ]};
  t.bottom = b.target[kZ];
  const double r = linear_value(s.w('R'), ns.units);
  t.clearance = ns.incremental ? ns.position[kZ] + r : r + ns.origin[kZ];
  t.width = linear_value(s.w('W'), ns.units);
  t.step = linear_value(s.w('K'), ns.units);
  t.depth_step = s.has('Q') ? linear_value(s.w('Q'), ns.units) : 0;
  if (t.width <= 0) return fail(s.w('W').col, "G275 W" + show(s.w('W').value) + ": the slot width must be positive");
  if (t.step <= 0) return fail(s.w('K').col, "G275 K" + show(s.w('K').value) + ": the step per revolution must be positive");
  if (t.depth_step < 0) return fail(s.w('Q').col, "G275 Q" + show(s.w('Q').value) + ": the step-down must not be negative");
  if (t.clearance < t.bottom)
    return fail(s.w('R').col, "G275 R" + show(s.w('R').value) + ": the clearance plane is below the slot floor Z");
  if (s.has('D')) {
    t.tool_diameter = linear_value(s.w('D'), ns.units);
    if (t.tool_diameter <= 0) return fail(s.w('D').col, "G275 D" + show(s.w('D').value) + ": the tool diameter must be positive");
  } else {
    const int tool = ns.tool_in_spindle != 0 ? ns.tool_in_spindle : ns.tool;
    auto it = machine.tools.find(tool);
    if (tool == 0)
      return fail(col, "G275 needs the tool diameter: give D, or load a tool (T<n> M6) whose diameter is in the machine config's tool table");
    if (it == machine.tools.end()) return fail(col, "G275 needs the tool diameter: give D, or: " + unknown_tool(tool, "diameter"));
    t.tool_diameter = it->second.diameter;
  }
  t.climb = true;
  if (s.has('P')) {
    const double p = s.w('P').value;
    if (p != 1 && p != -1) return fail(s.w('P').col, "G275 P" + show(p) + ": use P1 (climb) or P-1 (conventional)");
    t.climb = p > 0;
  }
  if (ns.feed <= 0 || ns.feed_mode != FeedMode::kUnitsPerMinute)
    return fail(col, "G275 needs a feed in mm/min (G94 with F)");
  b.motion = Motion::kTrochoidSlot;
  b.target = ns.position;
  b.target[kX] = t.end[0];
  b.target[kY] = t.end[1];
  b.target[kZ] = t.clearance;
  ns.position = b.target;
  return true;
}

void Parser::Impl::update_origin(ModalState& ns) const {
  const Axes& g5x = offsets[static_cast<std::size_t>(ns.work_offset - 54)];
  for (int a = 0; a < kNumAxes; ++a) ns.origin[a] = g5x[a] + (ns.shift_suspended ? 0 : ns.shift[a]);
}

// The frame statement of the line as the source wrote it: its code and its axis words (in mm and
// degrees, no origin added), for the writer to say it again in the control's frames. G10 says
// which statement it is in set_offsets / set_tool_entry.
void Parser::Impl::note_frame(const BlockCodes& c, ResolvedBlock& b, const ModalState& ns, std::uint8_t mask) const {
  switch (c.non_modal) {
    case 530: b.frame.code = FrameCode::kMachine; break;
    case 280: b.frame.code = FrameCode::kHome; break;
    case 300: b.frame.code = FrameCode::kHome2; break;
    case 920: b.frame.code = FrameCode::kShift; break;
    case 921: b.frame.code = FrameCode::kShiftClear; break;
    case 922: b.frame.code = FrameCode::kShiftSuspend; break;
    case 923: b.frame.code = FrameCode::kShiftRestore; break;
    case 520: b.frame.code = FrameCode::kLocalShift; break;
    default: break;
  }
  b.frame.words = mask;
  for (int a = 0; a < kNumAxes; ++a)
    if (mask & (1u << a)) {
      const Word& w = sc.w(kAxisLetters[a]);
      b.frame.values[a] = a >= kA ? angle_value(w) : linear_value(w, ns.units);
    }
}

// G28 G30 G53 G52 G92 G92.1 G92.2 G92.3: non-modal codes with an action of their own.
bool Parser::Impl::non_modal(const BlockCodes& c, ResolvedBlock& b, ModalState& ns, std::uint8_t mask) {
  note_frame(c, b, ns, mask);
  switch (c.non_modal) {
    case 530: return machine_move(c, b, ns, mask);
    case 280: case 300: return reference_return(c, b, ns, mask);
    case 100:
      if (!set_offsets(c, b, ns, mask)) return false;
      b.motion = Motion::kNone;
      b.target = ns.position;
      return true;
    default: break;
  }
  if (!coordinate_shift(c, ns, mask)) return false;
  b.motion = Motion::kNone;
  b.target = ns.position;
  return true;
}

// G53: the block's axis words are machine coordinates, for this block only. LinuxCNC moves in
// the modal G0 or G1 and refuses other modes; Fanuc always moves at rapid.
bool Parser::Impl::machine_move(const BlockCodes& c, ResolvedBlock& b, ModalState& ns, std::uint8_t mask) {
  if (ns.incremental)
    return fail(c.non_modal_col, "G53 with G91: machine coordinates are absolute; program G90 before G53");
  if (ns.cycle != 0) return fail(c.non_modal_col, "G53 in a canned cycle: cancel the cycle with G80 first");
  Motion m = Motion::kRapid;
  if (opt.dialect == Dialect::kLinuxCnc) {
    if (ns.motion != Motion::kRapid && ns.motion != Motion::kLinear)
      return fail(c.non_modal_col, "G53 needs G0 or G1 in force (LinuxCNC): program G0 G53 or G1 G53");
    m = ns.motion;
  }
  b.target = ns.position;
  for (int a = 0; a < kNumAxes; ++a)
    if (mask & (1u << a)) {
      const Word& w = sc.w(kAxisLetters[a]);
      b.target[a] = a >= kA ? angle_value(w) : linear_value(w, ns.units);
    }
  if (mask == 0) {
    b.motion = Motion::kNone;
    return true;
  }
  const Motion saved = ns.motion;
  ns.motion = m;
  const bool feed_ok = check_feed(c, ns);
  ns.motion = saved;
  if (!feed_ok) return false;
  b.motion = m;
  ns.position = b.target;
  return true;
}

// G28/G30: rapid to the intermediate point (the block's axis words, in G90 or G91 as in force),
// then to the reference position of the machine file for the axes named; `G91 G28 Z0` is the
// posts' way to send Z home from where it stands. Without axis words LinuxCNC sends every axis
// home through no intermediate point; Fanuc moves nothing.
bool Parser::Impl::reference_return(const BlockCodes& c, ResolvedBlock& b, ModalState& ns, std::uint8_t mask) {
  if (ns.cycle != 0)
    return fail(c.non_modal_col, code_text('G', c.non_modal) + " in a canned cycle: cancel the cycle with G80 first");
  const Axes& ref = machine.reference_positions[c.non_modal == 280 ? 0 : 1];
  std::uint8_t home = mask;
  if (mask == 0 && opt.dialect == Dialect::kLinuxCnc) home = (1u << kNumAxes) - 1;
  if (home == 0) {
    b.motion = Motion::kNone;
    b.target = ns.position;
    return true;
  }
  Axes mid = ns.position, end = ns.position;
  for (int a = 0; a < kNumAxes; ++a) {
    if (mask & (1u << a)) {
      const Word& w = sc.w(kAxisLetters[a]);
      const double v = a >= kA ? angle_value(w) : linear_value(w, ns.units);
      mid[a] = ns.incremental ? ns.position[a] + v : v + ns.origin[a];
    }
    end[a] = (home & (1u << a)) ? ref[a] : mid[a];
  }
  // A stop at the intermediate point where the tool already is (`G91 G28 Z0`) is no move.
  if (mid != ns.position) moves.push_back({Motion::kRapid, mid});
  moves.push_back({Motion::kRapid, end});
  b.motion = Motion::kRapid;
  b.target = end;
  ns.position = end;
  return true;
}

// G92 (the current position reads as the words), G92.1 (clear), G92.2 (suspend), G92.3
// (restore), G52 (shift the origin by the words). One shift, added to the G5x origin; blocks
// keep publishing the G5x origin, so every later stage sees targets in one frame.
bool Parser::Impl::coordinate_shift(const BlockCodes& c, ModalState& ns, std::uint8_t mask) {
  const int code = c.non_modal;
  if ((code == 920 || code == 520) && mask == 0)
    return fail(c.non_modal_col, code_text('G', code) + " needs at least one axis word (the new position or shift)");
  if (code == 921) ns.shift = Axes{};
  ns.shift_suspended = code == 922;
  for (int a = 0; a < kNumAxes && (code == 920 || code == 520); ++a) {
    if (!(mask & (1u << a))) continue;
    const Word& w = sc.w(kAxisLetters[a]);
    const double v = a >= kA ? angle_value(w) : linear_value(w, ns.units);
    ns.shift[a] = code == 520 ? v : ns.position[a] - offsets[static_cast<std::size_t>(ns.work_offset - 54)][a] - v;
  }
  update_origin(ns);
  return true;
}

}  // namespace gcpipe

namespace gcpipe {

// G10 L2 P (the origin of G54..G59 = the words; P0 = the system in force, LinuxCNC) and, in
// LinuxCNC, G10 L20 P (the origin such that the tool's position reads as the words). In force
// from this line on. Fanuc G91 adds the words to the origin (its manual's rule for G10 L2).
bool Parser::Impl::set_offsets(const BlockCodes& c, ResolvedBlock& b, ModalState& ns, std::uint8_t mask) {
  const Scan& s = sc;
  const std::uint32_t col = c.non_modal_col;
  if (!s.has('L')) return fail(col, "G10 needs L: L2 (work offset values) or L20 (LinuxCNC: make the position read as the values)");
  const double l = s.w('L').value;
  const bool fanuc = opt.dialect == Dialect::kFanuc;
  if (fanuc ? (l == 10 || l == 12) : (l == 1 || l == 10)) return set_tool_entry(c, b, ns, mask);
  if (l == 20 && fanuc)
    return fail(s.w('L').col, "G10 L20 on Fanuc sets the extended work offsets G54.1 P1..P48, which this machine does not have");
  if (l == 11 && !fanuc)
    return fail(s.w('L').col, "G10 L11 sets a tool entry measured in G59.3's coordinates, and this machine file has no "
                              "G59.3 origin: use G10 L10 (measured in the coordinates in force)");
  if (l != 2 && l != 20)
    return fail(s.w('L').col, "G10 L" + show(l) + " is not supported" +
                              (fanuc ? std::string(": wear offsets (L11, L13) are not modelled; tool geometry takes L10 (length) or L12 (radius)")
                                     : std::string(": tool entries take L1 or L10")) +
                              "; work offsets take L2" + (fanuc ? "" : " or L20"));
  if (!s.has('P')) return fail(col, "G10 L" + show(l) + " needs P: the work offset, 1..6 for G54..G59" + (fanuc ? "" : ", 0 for the one in force"));
  const double p = s.w('P').value;
  if (p != std::floor(p) || p < (fanuc ? 1 : 0) || p > 6)
    return fail(s.w('P').col, "G10 P" + show(p) + ": the work offset must be " + (fanuc ? "1..6" : "0..6") +
                                  " (G54..G59" + (fanuc ? "" : ", 0 = the one in force") + ")");
  const std::size_t k = p == 0 ? static_cast<std::size_t>(ns.work_offset - 54) : static_cast<std::size_t>(p - 1);
  Axes origin = offsets[k];
  for (int a = 0; a < kNumAxes; ++a) {
    if (!(mask & (1u << a))) continue;
    const Word& w = s.w(kAxisLetters[a]);
    const double v = a >= kA ? angle_value(w) : linear_value(w, ns.units);
    if (l == 20) origin[a] = ns.position[a] - v - (ns.shift_suspended ? 0 : ns.shift[a]);
    else origin[a] = fanuc && ns.incremental ? origin[a] + v : v;
  }
  offsets[k] = origin;
  update_origin(ns);
  b.frame.code = l == 20 ? FrameCode::kSetOriginHere : FrameCode::kSetOrigin;
  b.frame.incremental = fanuc && ns.incremental && l == 2;  // LinuxCNC takes G10 words absolute in G91 too
  b.frame.p = static_cast<std::int32_t>(p);
  b.frame.resolved = origin;
  return true;
}

}  // namespace gcpipe

namespace gcpipe {

// G10 tool entries, in force from this line on (a G43 after it loads the new length; the length
// in force is not reloaded by the G10 itself, as rs274 shows).
//  LinuxCNC (G10 L1 / L10, its manual): P tool number (in the table), Z length, R radius.
//    L1 sets them; L10 sets the length so that the current position, with the G5x and G92
//    offsets in force, reads as the Z word once the offset is reloaded: length = current Z
//    (program) + length in force - Z. A G10 L1 without Z or R is an error (rs274's too).
//  Fanuc (G10 L10 / L12, tool offset memory C): P offset number, R value; L10 the length
//    geometry (H), L12 the radius geometry (D); in G91 R is added to the stored value.
bool Parser::Impl::set_tool_entry(const BlockCodes& c, ResolvedBlock& b, ModalState& ns, std::uint8_t mask) {
  const Scan& s = sc;
  const bool fanuc = opt.dialect == Dialect::kFanuc;
  const int l = static_cast<int>(s.w('L').value);
  const std::string name = "G10 L" + std::to_string(l);
  if (!s.has('P')) return fail(c.non_modal_col, name + " needs P: the tool number");
  const double p = s.w('P').value;
  if (p != std::floor(p) || p < 1 || p > 9999) return fail(s.w('P').col, name + " P" + show(p) + " is not a tool number 1..9999");
  const int tool = static_cast<int>(p);
  for (int a = 0; a < kNumAxes; ++a)
    if ((mask & (1u << a)) && (fanuc || a != kZ))
      return fail(s.w(kAxisLetters[a]).col, name + ": only " + (fanuc ? "R" : "Z (length) and R (radius)") +
                                                " can be set on this machine, not " + kAxisLetters[a]);
  auto it = machine.tools.find(tool);
  if (!fanuc && it == machine.tools.end())
    return fail(s.w('P').col, name + " P" + std::to_string(tool) + ": tool " + std::to_string(tool) + " is not in " +
                                  tool_table_name(machine) + " (LinuxCNC sets entries of tools in the table only)");
  if (fanuc && !s.has('R')) return fail(c.non_modal_col, name + " needs R: the offset value");
  if (!fanuc && !(mask & (1u << kZ)) && !s.has('R'))
    return fail(c.non_modal_col, name + " without Z or R has no effect: give the length Z or the radius R");
  ToolEntry e = it == machine.tools.end() ? ToolEntry{} : it->second;
  const double r = s.has('R') ? linear_value(s.w('R'), ns.units) : 0;
  if (fanuc) {
    const double old = l == 10 ? e.length : e.diameter / 2;
    const double v = ns.incremental ? old + r : r;
    if (l == 10) e.length = v;
    else e.diameter = 2 * v;
  } else {
    if (s.has('R')) e.diameter = 2 * r;
    if (mask & (1u << kZ)) {
      const double z = linear_value(s.w('Z'), ns.units);
      const double current = ns.position[kZ] - ns.origin[kZ] + (ns.tlo_active ? ns.tool_length : 0);
      e.length = l == 1 ? z : current - z;
    }
  }
  machine.tools[tool] = e;
  b.frame.code = fanuc ? (l == 10 ? FrameCode::kToolLength : FrameCode::kToolRadius)
                       : (l == 1 ? FrameCode::kToolTable : FrameCode::kToolTableHere);
  b.frame.p = tool;
  b.frame.incremental = fanuc && ns.incremental;
  b.frame.has_r = s.has('R');
  b.frame.r = r;
  b.frame.resolved[kZ] = e.length;
  b.frame.resolved[kX] = e.diameter / 2;
  return true;
}

}  // namespace gcpipe
