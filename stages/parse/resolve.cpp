// Modal resolution of one scanned line, in the order a control executes a block (LinuxCNC's
// "order of execution"), each step a function: sort the codes by modal group, feed/speed/tool,
// tool length, modes, word checks, axis targets, then the block's action (dwell, a non-modal
// code, a cycle, a move). Every step works on a copy of the modal state (`ns`), committed only
// when the whole line is valid.
#include <cmath>
#include <numbers>

#include "parse_internal.hpp"

// The steps of resolve() are separate functions for reading; inlined into it they cost what the
// one long function cost (called per line, their call overhead was ~20 % of the parse).
#define GCPIPE_STEP [[gnu::always_inline]] inline

namespace gcpipe {

using namespace parse_detail;

namespace {

bool is_cycle(int code) {
  switch (code) {
    case 730: case 740: case 760: case 810: case 820: case 830: case 840: case 850: case 860:
    case 870: case 880: case 890:
      return true;
    default:
      return false;
  }
}

// The non-modal codes that act on their block (at most one per block).
bool is_non_modal_action(int code) {
  switch (code) {
    case 100: case 280: case 300: case 530: case 520: case 920: case 921: case 922: case 923:
      return true;
    default:
      return false;
  }
}

int g_group(int code, Dialect d) {
  switch (code) {
    case 0: case 10: case 20: case 30: return kGMotion;
    case 331: return d == Dialect::kLinuxCnc ? kGNonModal : kGUnsupported;
    case 40: case 2750: return kGNonModal;
    case 170: case 180: case 190: return kGPlane;
    case 900: case 910: return kGDistance;
    case 901: case 911: return kGArcDistance;
    case 930: case 940: case 950: return kGFeedMode;
    case 970: return kGSpindleMode;  // G97: spindle speed in rev/min, a mill's only mode
    case 200: case 210: return kGUnits;
    case 400: return kGCutterComp;
    // Compensation (cutter.cpp) has LinuxCNC's geometry in that dialect and Fanuc's cutter
    // compensation C (Type A start-up and cancel) in the Fanuc one; G41.1/G42.1 are LinuxCNC's.
    case 410: case 420: return kGCutterComp;
    case 411: case 421: return d == Dialect::kLinuxCnc ? kGCutterComp : kGUnsupported;
    case 430: case 434: case 435: case 490: return kGToolLength;
    case 540: case 550: case 560: case 570: case 580: case 590: return kGCoordSystem;
    case 610: case 611: case 640: return kGPathMode;
    case 90: return d == Dialect::kFanuc ? kGExactStopOnce : kGUnsupported;
    // G80 is group 09 on Fanuc, with the cycles; LinuxCNC files it under motion but accepts
    // `G0 G80` (G80 then yields to G0). Both: G80 may share a block with G0..G3.
    case 800: return kGCycleCancel;
    case 980: case 990: return kGCycleReturn;
    // Fanuc look-ahead modes (HPCC G05 P10000, AI contour G05.1 Q1, look-ahead G08 P1): they tune
    // the control's feed planning, not the path. In LinuxCNC G5/G5.1 are splines and G8 a lathe
    // mode, so there they stay unsupported.
    case 50: case 51: case 80: return d == Dialect::kFanuc ? kGLookAhead : kGUnsupported;
    default:
      // G76/G87/G88 are Fanuc boring cycles; in LinuxCNC G76 threads, G87/G88 do not exist.
      if (is_cycle(code) && (d == Dialect::kFanuc || (code != 760 && code != 870 && code != 880)))
        return kGCycleCancel;
      if (is_non_modal_action(code)) return kGNonModal;
      return kGUnsupported;
  }
}

// Why a G code is not supported, in words a programmer can act on.
std::string unsupported_g(int code, Dialect d) {
  const std::string g = code_text('G', code);
  switch (code) {
    case 411: case 421:
      return g + " (LinuxCNC dynamic cutter compensation) is not Fanuc G-code: parse with dialect linuxcnc";
    case 960: return "G96 (constant surface speed) is not supported on this milling machine: program G97 S (rev/min)";
    case 330: case 331: return g + " (threading) is not supported";
    case 760:
      return d == Dialect::kLinuxCnc
                 ? "G76 in LinuxCNC is the lathe threading cycle: not supported on this milling machine"
                 : g + " is not a supported G code";
    case 870: case 880: return g + " is a Fanuc boring cycle, not LinuxCNC G-code: parse the program with dialect fanuc";
    case 381: case 382: case 383: case 384: return g + " (probing) is not supported";
    case 431: return "G43.1 (dynamic tool length) is not supported: use G43 H with the tool table";
    case 50: case 51: case 52:
      return d == Dialect::kLinuxCnc && code != 520
                 ? g + " (LinuxCNC spline) is not supported: output lines and arcs from CAM"
                 : g + " is not a supported G code";
    case 80: return "G8 (LinuxCNC lathe radius mode) is not supported on this milling machine";
    case 90:
      return "G9 (exact stop for one block) is Fanuc G-code, not LinuxCNC's: parse with dialect fanuc, or put G61 "
             "before the block and G64 after it";
    case 591: case 592: case 593: return g + " is not supported: use G54..G59";
    default: return g + " is not a supported G code";
  }
}

enum MGroup : int { kMStop = 4, kMSubprogram = 5, kMToolChange = 6, kMSpindle = 7, kMCoolant = 8, kMKins = 9,
                    kMRigidTap = 10, kMState = 11, kMUnsupported = 99 };

int m_group(int code) {
  switch (code) {
    case 0: case 10: case 20: case 300: return kMStop;
    case 60: case 610: return kMToolChange;  // M61 Q: the tool in the spindle, without a change (LinuxCNC)
    case 30: case 40: case 50: return kMSpindle;
    case 70: case 80: case 90: return kMCoolant;
    case 4280: case 4290: case 4300: return kMKins;
    case 980: case 990: return kMSubprogram;
    case 290: return kMRigidTap;  // Fanuc M29: rigid tapping
    case 700: case 710: case 720: case 730: return kMState;  // LinuxCNC M70..M73: save, invalidate, restore, autorestore
    default: return kMUnsupported;
  }
}

std::string unsupported_m(int code) {
  const std::string m = code_text('M', code);
  switch (code) {
    case 980: case 990: return m + " (Fanuc subprogram call/return) is not LinuxCNC: use o-word subroutines (o100 call), or parse with dialect fanuc";
    case 600: return "M60 (pallet change) is not supported";
    case 480: case 490: case 500: case 510: case 520: case 530:
      return m + " (override control) is not supported";
    default: return m + " is not a supported M code";
  }
}

const char* motion_name(Motion m) {
  return m == Motion::kLinear ? "G1" : m == Motion::kArcCW ? "G2" : m == Motion::kArcCCW ? "G3" : "G0";
}

}  // namespace

double Parser::Impl::linear_value(const Word& w, Units units) const {
  const bool inch = units == Units::kInch;
  double v = w.value;
  if (opt.decimal_point_increments && !w.point) v *= inch ? 0.0001 : 0.001;
  return inch ? v * kInch : v;
}

double Parser::Impl::angle_value(const Word& w) const {
  return (opt.decimal_point_increments && !w.point) ? w.value * 0.001 : w.value;
}

bool Parser::Impl::resolve(ResolvedBlock& b, ModalState& ns) {
  BlockCodes c;
  if (!sort_g_codes(c) || !sort_m_codes(c)) return false;
  if (c.has(kGUnits)) ns.units = c.group_code[kGUnits] == 200 ? Units::kInch : Units::kMillimetre;
  // What the line states itself (not what it inherits), for a writer that says it again.
  b.frame.selects_work_offset = c.has(kGCoordSystem);
  b.frame.sets_tool_length = c.has(kGToolLength);
  if (!save_restore_modes(c, ns)) return false;
  if (!check_block_number() || !apply_feed_speed_tool(c, ns, b) || !apply_tool_length(c, ns)) return false;
  if (!apply_modes(c, ns, b) || !apply_cutter_comp(c, ns) || !read_fanuc_call(c)) return false;
  const bool arc_mode = !c.g4 && !c.g275 && c.non_modal == 0 && ns.cycle == 0 &&
                        (ns.motion == Motion::kArcCW || ns.motion == Motion::kArcCCW);
  // In G43.5, I J K of a block that is not an arc are the tool axis (on arcs they stay centres).
  const bool vector_words = ns.tool_vector_mode && !arc_mode && !c.g4 && !c.g275 && ns.cycle == 0 &&
                            (sc.has('I') || sc.has('J') || sc.has('K'));
  if (!check_word_use(c, ns, vector_words) || !check_lengths(vector_words, ns)) return false;
  Vec3 vector = ns.tool_vector;
  if (vector_words && !read_tool_vector(vector)) return false;
  Axes target{};
  std::uint8_t mask = 0;
  if (!axis_targets(c, ns, target, mask)) return false;
  b.axis_words = mask;
  b.start = ns.position;
  b.frame.incremental = ns.incremental;
  if (c.g4 && !dwell_with_move(mask)) return dwell(b, ns);
  if (c.g4 && !dwell_before_move(ns)) return false;
  if (c.g275) {
    b.target = target;
    return slot(sc, b, ns);
  }
  if (c.g331) return rigid_tap(b, ns, target, mask);
  if (c.non_modal != 0) return non_modal(c, b, ns, mask);
  if (ns.cycle != 0 && mask != 0) return cycle(c, b, ns, mask);
  return move(c, b, ns, target, mask, vector_words, vector);
}

// The motion mode after a G80 without G0..G3 beside it. Fanuc 0i-MF: canned cycles and G80 are
// group 09, G00..G03 group 01; G80 cancels the cycle and leaves group 01 as it was (the mode
// before the cycle, or the one in force when no cycle was), so `G80` then `Z.2` moves in it.
// LinuxCNC: G80 is in the motion group itself; rs274 rejects axis words after it ("Cannot use
// axis values without a g code that uses them").
Motion Parser::Impl::motion_after_g80(const ModalState& ns) const {
  if (opt.dialect == Dialect::kLinuxCnc) return Motion::kNone;
  return ns.cycle != 0 ? ns.motion_before_cycle : ns.motion;
}

// Step 1: G codes, one per modal group, all known; G80 beside G0..G3 is allowed (see g_group).
GCPIPE_STEP bool Parser::Impl::sort_g_codes(BlockCodes& c) {
  const Scan& s = sc;
  for (int i = 0; i < s.ng; ++i) {
    const int code = s.g[i].code;
    const int grp = g_group(code, opt.dialect);
    if (grp == kGUnsupported) return fail(s.g[i].col, unsupported_g(code, opt.dialect));
    if (grp == kGNonModal) {
      const bool action = is_non_modal_action(code);
      if ((code == 40 && c.g4) || (code == 2750 && c.g275) || (action && c.non_modal != 0))
        return fail(s.g[i].col, (action && c.non_modal != 0 ? code_text('G', c.non_modal) + " and " : std::string()) +
                                    code_text('G', code) + (action && c.non_modal != 0 ? " in one block: keep one" : " appears twice in one block"));
      c.g4 = c.g4 || code == 40;
      c.g275 = c.g275 || code == 2750;
      c.g331 = c.g331 || code == 331;
      if (action) {
        c.non_modal = code;
        c.non_modal_col = s.g[i].col;
      }
      continue;
    }
    if (c.group_col[grp] != 0)
      return fail(s.g[i].col, code_text('G', c.group_code[grp]) + " and " + code_text('G', code) +
                                  " in one block belong to the same modal group: keep one");
    c.group_col[grp] = s.g[i].col;
    c.group_code[grp] = code;
  }
  const bool cycle_code = c.has(kGCycleCancel) && c.group_code[kGCycleCancel] != 800;
  if (cycle_code && c.has(kGMotion))
    return fail(c.group_col[kGCycleCancel], code_text('G', c.group_code[kGMotion]) + " and " +
                                                code_text('G', c.group_code[kGCycleCancel]) +
                                                " in one block: both set the motion mode, keep one");
  if (c.has(kGMotion)) {
    c.motion_code = c.group_code[kGMotion];
    c.motion_col = c.group_col[kGMotion];
  } else if (cycle_code) {
    c.motion_code = c.group_code[kGCycleCancel];
    c.motion_col = c.group_col[kGCycleCancel];
  }
  if (c.g4 && c.g275) return fail(s.g[0].col, "G4 and G275 in one block: keep one");
  if (c.g331 && (c.g4 || c.g275 || c.non_modal != 0 || c.motion_code >= 0))
    return fail(s.g[0].col, "G33.1 (rigid tapping) is a move of its own: keep no other motion, dwell or G10/G28/G53/G92 beside it");
  if ((c.g4 || c.g275) && c.non_modal != 0)
    return fail(c.non_modal_col, code_text('G', c.non_modal) + " and " + (c.g4 ? "G4" : "G275") + " in one block: keep one");
  if (c.g275 && c.motion_code >= 0)
    return fail(c.motion_col, code_text('G', c.motion_code) +
                                  " and G275 in one block: a cycle block cannot also set the motion mode");
  if (c.g4 && cycle_code)
    return fail(c.motion_col, code_text('G', c.motion_code) + " and G4 in one block: keep one");
  return true;
}

// Step 2: M codes, at most one per group (M7 with M8 is allowed: both coolants on).
GCPIPE_STEP bool Parser::Impl::sort_m_codes(BlockCodes& c) {
  const Scan& s = sc;
  for (int i = 0; i < s.nm; ++i) {
    const int code = s.m[i].code;
    const int grp = m_group(code);
    if (grp == kMUnsupported || (grp == kMSubprogram && opt.dialect != Dialect::kFanuc) ||
        (code == 610 && opt.dialect != Dialect::kLinuxCnc) || (code == 290 && opt.dialect != Dialect::kFanuc) ||
        (grp == kMState && opt.dialect != Dialect::kLinuxCnc))
      return fail(s.m[i].col, unsupported_m(code));
    if (grp == kMCoolant) {
      bool& f = code == 70 ? c.mist : code == 80 ? c.flood : c.coolant_off;
      if (f) return fail(s.m[i].col, code_text('M', code) + " appears twice in one block");
      f = true;
      continue;
    }
    if (c.m_col[grp] != 0)
      return fail(s.m[i].col, code_text('M', c.m_code[grp]) + " and " + code_text('M', code) +
                                  " in one block belong to the same modal group: keep one");
    c.m_col[grp] = s.m[i].col;
    c.m_code[grp] = code;
  }
  return true;
}

// Fanuc M98 P<program> L<times> (or P<times><program, 4 digits>) and M99: flow.cpp runs them
// after the block's other words.
GCPIPE_STEP bool Parser::Impl::read_fanuc_call(const BlockCodes& c) {
  fanuc.ret = false;
  fanuc.repeats = 1;
  if (!fanuc.label.empty()) fanuc.label.clear();  // per line: no string built when unused
  if (c.m_col[kMSubprogram] == 0) return true;
  const std::uint32_t col = c.m_col[kMSubprogram];
  if (c.m_code[kMSubprogram] == 990) {
    fanuc.ret = true;
    return true;
  }
  if (!sc.has('P')) return fail(col, "M98 needs P: the subprogram number (M98 P1010, or P21010 for twice)");
  const double p = sc.w('P').value;
  if (p < 1 || p > 99999999 || p != std::floor(p))
    return fail(sc.w('P').col, "M98 P" + show(p) + ": the subprogram number must be a whole number 1..9999");
  long number = static_cast<long>(p), repeats = 1;
  if (sc.has('L')) {
    const double l = sc.w('L').value;
    if (l < 1 || l > 9999 || l != std::floor(l))
      return fail(sc.w('L').col, "M98 L" + show(l) + ": the number of runs must be a whole number 1..9999");
    repeats = static_cast<long>(l);
  } else if (number > 9999) {
    repeats = number / 10000;  // Fanuc: the digits before the last four count the runs
    number %= 10000;
  }
  fanuc.label = "O" + std::to_string(number);
  fanuc.repeats = repeats;
  return true;
}

GCPIPE_STEP bool Parser::Impl::check_block_number() {
  if (!sc.has('N')) return true;
  const Word& w = sc.w('N');
  if (w.value < 0 || w.value > 99999999 || w.value != std::floor(w.value))
    return fail(w.col, "block number N" + show(w.value) + " is not a whole number 0..99999999");
  return true;
}

// Step 3: feed mode and F, S, T and M6, spindle and coolant.
GCPIPE_STEP bool Parser::Impl::apply_feed_speed_tool(const BlockCodes& c, ModalState& ns, ResolvedBlock& b) {
  const Scan& s = sc;
  const double unit = ns.units == Units::kInch ? kInch : 1.0;
  if (c.has(kGFeedMode)) {
    const int code = c.group_code[kGFeedMode];
    ns.feed_mode = code == 930 ? FeedMode::kInverseTime : FeedMode::kUnitsPerMinute;
    ns.per_revolution = code == 950;
  }
  if (s.has('F')) {
    const Word& f = s.w('F');
    if (f.value < 0) return fail(f.col, "feed F" + show(f.value) + " is negative");
    const double v = ns.feed_mode == FeedMode::kInverseTime ? f.value : f.value * unit;
    if (v > kMaxFeed) return fail(f.col, "feed F" + show(f.value) + " is out of range (at most 100000000 mm/min or 1/min)");
    if (ns.per_revolution) {
      ns.feed_per_rev = v;
    } else {
      if (ns.feed_mode == FeedMode::kUnitsPerMinute && v > 0 && v < opt.min_feed)
        return fail(f.col, "feed F" + show(f.value) + " is below the minimum feed of " + show(opt.min_feed) +
                               " mm/min (parse.min_feed in the pipeline config): a mistyped feed would run for hours");
      ns.feed = v;
    }
  } else if (c.has(kGFeedMode) && (ns.feed_mode != st.feed_mode || ns.per_revolution != st.per_revolution)) {
    ns.feed = ns.feed_per_rev = 0;  // switching G93/G94/G95 invalidates the feed: it means something else now
  }
  if (s.has('S')) {
    const Word& w = s.w('S');
    if (w.value < 0 || w.value > kMaxSpindle)
      return fail(w.col, "spindle speed S" + show(w.value) + " is out of range (0..1000000 rev/min)");
    ns.spindle_speed = w.value;
  }
  // G95: the control moves F mm per revolution at the spindle speed in force, so the block is
  // resolved to the feed in mm/min it moves at (F x S), as G94 would say it.
  if (ns.per_revolution) {
    ns.feed = ns.feed_per_rev * ns.spindle_speed;
    // Only a block with F or S changes the product (G95 alone drops the feed): the error goes to
    // its F word, else its S.
    if (ns.feed > kMaxFeed)
      return fail(s.has('F') ? s.w('F').col : s.w('S').col,
                  "G95 feed F x S = " + show(ns.feed) + " mm/min is out of range (at most 100000000 mm/min)");
  }
  if (s.has('T')) {
    const Word& w = s.w('T');
    if (w.value < 0 || w.value > 9999 || w.value != std::floor(w.value))
      return fail(w.col, "tool number T" + show(w.value) + " is not a whole number 0..9999");
    const int t = static_cast<int>(w.value);
    if (t != 0 && !machine.tools.empty() && machine.tools.count(t) == 0) warn_unknown_tool(t, w.col);
    ns.tool = t;
  }
  if (c.m_code[kMToolChange] == 610 && !set_tool_number(c, ns)) return false;
  b.tool_change = c.m_col[kMToolChange] != 0 && c.m_code[kMToolChange] == 60;
  if (b.tool_change) ns.tool_in_spindle = ns.tool;
  if (c.m_col[kMSpindle]) {
    const int m = c.m_code[kMSpindle];
    ns.spindle = m == 30 ? Spindle::kCW : m == 40 ? Spindle::kCCW : Spindle::kOff;
  }
  if (c.coolant_off) ns.coolant = 0;
  if (c.mist) ns.coolant |= kCoolantMist;
  if (c.flood) ns.coolant |= kCoolantFlood;
  return true;
}

// Why a tool the table lacks cannot be used where its geometry (`what`: length, diameter) is.
std::string Parser::Impl::unknown_tool(int tool, const char* what) const {
  return "tool " + std::to_string(tool) + " is not in " + tool_table_name(machine) + ", so its " + what +
         " is unknown: add it to the tool table, or pass --tool-table with a shop's table that has it";
}

// A T word for a tool the table lacks is only a warning: a control loads any tool number, and
// the tool's geometry matters only where a block uses it (G43 H, G41/G42, G275), which is then
// the error. Said once per tool, after the line is accepted (run_line).
void Parser::Impl::warn_unknown_tool(int tool, std::uint32_t col) {
  if (warned_tools.count(tool) != 0) return;
  warning_col = col;
  warning = "T" + std::to_string(tool) + ": tool " + std::to_string(tool) + " is not in " + tool_table_name(machine) +
            ": the program runs, but G43 H" + std::to_string(tool) + ", cutter compensation or G275 with it will be "
            "rejected; add it to the tool table, or pass --tool-table";
  warning_tool = tool;
}

// Step 4: G43 / G43.4 / G43.5 H and G49, with each dialect's grouping of TCP.
GCPIPE_STEP bool Parser::Impl::apply_tool_length(const BlockCodes& c, ModalState& ns) {
  const Scan& s = sc;
  if (!c.has(kGToolLength)) {
    if (s.has('H'))
      return fail(s.w('H').col, "H" + show(s.w('H').value) + " without G43, G43.4 or G43.5: H selects a tool length only with them");
    return true;
  }
  const int code = c.group_code[kGToolLength];
  if (code == 490) {
    if (s.has('H')) return fail(s.w('H').col, "H with G49: G49 cancels tool length compensation");
    ns.tlo_active = false;
    ns.tlo_h = 0;
    ns.tool_length = 0;
    if (opt.dialect == Dialect::kFanuc) ns.tcp = false;  // G49 ends G43.4 too (one modal group)
    ns.tool_vector_mode = false;
    return true;
  }
  if (code == 435 && opt.dialect == Dialect::kLinuxCnc)
    return fail(c.group_col[kGToolLength],
                "G43.5 (tool centre point with the tool axis programmed as a vector I J K) does not "
                "exist in LinuxCNC: LinuxCNC has no tool-vector TCP; program A and C with M428 "
                "(TCP kinematics), or parse this program with dialect fanuc");
  int h = ns.tool_in_spindle;  // G43 without H takes the loaded tool, as LinuxCNC does
  if (s.has('H')) {
    const Word& w = s.w('H');
    if (w.value < 0 || w.value > 9999 || w.value != std::floor(w.value))
      return fail(w.col, "H" + show(w.value) + " is not a tool number 0..9999");
    h = static_cast<int>(w.value);
  }
  double len = 0;
  if (h != 0) {
    auto it = machine.tools.find(h);
    if (it == machine.tools.end())
      return fail(s.has('H') ? s.w('H').col : c.group_col[kGToolLength],
                  "H" + std::to_string(h) + ": " + unknown_tool(h, "length"));
    len = it->second.length;
  }
  ns.tlo_h = h;
  ns.tool_length = len;
  ns.tlo_active = h != 0;  // H0 means "no length", as on Fanuc
  if (code == 434 || code == 435) ns.tcp = true;
  else if (opt.dialect == Dialect::kFanuc) ns.tcp = false;  // G43 replaces G43.4
  if (code == 435) {
    // Entering G43.5 starts without a vector (the parser does not know the tool axis of the
    // current A C); staying in it (a new H) keeps the vector in force.
    if (!ns.tool_vector_mode) {
      ns.tool_vector_set = false;
      ns.tool_vector = {0, 0, 1};
    }
    ns.tool_vector_mode = true;
  } else {
    ns.tool_vector_mode = false;  // G43 and G43.4 share G43.5's modal group
  }
  return true;
}

// Step 5: kinematics switch, plane, path tolerance (G64 P), work offset, distance modes, motion
// mode, program stops.
GCPIPE_STEP bool Parser::Impl::apply_modes(const BlockCodes& c, ModalState& ns, ResolvedBlock& b) {
  if (c.m_col[kMKins]) {
    ns.tcp = c.m_code[kMKins] == 4280;  // M428 TCP on; M429/M430 joint mode
    ns.tool_vector_mode = false;        // M428 is TCP with A C programmed
  }
  if (!ns.tool_vector_mode) {
    ns.tool_vector_set = false;
    ns.tool_vector = {0, 0, 1};
  }
  if (c.has(kGPlane)) ns.plane = static_cast<Plane>(c.group_code[kGPlane] / 10);
  // G64 P: the path tolerance a look-ahead control blends corners within (LinuxCNC's naive-CAM Q
  // is read and not used). G64 without P, G61 (exact stop) and G61.1 (exact path) give none:
  // the planner then takes compensate.path_tolerance. G61 and G61.1 stop at every block end (the
  // interpolator holds until every axis is in position).
  // G09 (Fanuc, non-modal): this line's blocks stop as in G61; the mode in force stays.
  exact_stop_once = c.has(kGExactStopOnce);
  if (c.has(kGPathMode)) {
    const int code = c.group_code[kGPathMode];
    ns.path_mode = code == 610 ? PathMode::kExactStop : code == 611 ? PathMode::kExactPath : PathMode::kBlend;
    ns.path_tolerance = 0;
    if (c.group_code[kGPathMode] == 640 && sc.has('P')) {
      const Word& p = sc.w('P');
      const double mm = p.value * (ns.units == Units::kInch ? kInch : 1.0);
      // LinuxCNC takes any P; one inch bounds it far beyond any tolerance a program means.
      if (p.value < 0 || mm > kInch) return fail(p.col, "G64 P" + show(p.value) + " is not a path tolerance of 0 to 25.4 mm");
      ns.path_tolerance = mm;  // P0: none (LinuxCNC: best speed)
    }
  }
  if (c.has(kGCoordSystem)) {
    ns.work_offset = c.group_code[kGCoordSystem] / 10;
    ns.work_origin = machine.work_offsets[static_cast<std::size_t>(ns.work_offset - 54)];
    update_origin(ns);
  }
  if (c.has(kGDistance)) ns.incremental = c.group_code[kGDistance] == 910;
  if (c.has(kGArcDistance)) ns.arc_incremental = c.group_code[kGArcDistance] == 911;
  if (c.has(kGCycleReturn)) ns.cycle_to_r = c.group_code[kGCycleReturn] == 990;
  const bool cancel = c.has(kGCycleCancel) && c.group_code[kGCycleCancel] == 800;
  if (cancel || (c.motion_code >= 0 && !is_cycle(c.motion_code))) ns.rigid_tap = false;  // the 0i-MF's end of rigid mode
  if (c.m_col[kMRigidTap]) ns.rigid_tap = true;
  if (cancel) {
    if (!c.has(kGMotion)) ns.motion = motion_after_g80(ns);  // before the cycle is forgotten
    ns.cycle = 0;
    // Fanuc's G80 also clears the cycle data (R, Z, Q, P); LinuxCNC keeps them sticky.
    if (opt.dialect == Dialect::kFanuc) ns.cycle_r = ns.cycle_z = ns.cycle_q = ns.cycle_p = Word{};
  }
  if (c.motion_code >= 0) {
    const int m = c.motion_code;
    if (is_cycle(m)) {
      // The initial level is where the drilling axis stands when a series of cycles begins.
      if (ns.cycle == 0) {
        ns.cycle_initial = ns.position[plane_axes(ns.plane).n];
        ns.motion_before_cycle = ns.motion;
      }
      ns.cycle = m;
      ns.motion = Motion::kNone;
    } else {
      ns.cycle = 0;
      ns.motion = m == 0 ? Motion::kRapid : m == 10 ? Motion::kLinear : m == 20 ? Motion::kArcCW : Motion::kArcCCW;
    }
  }
  if (c.m_col[kMStop]) {
    const int m = c.m_code[kMStop];
    b.stop = m == 0 ? ProgramStop::kStop : m == 10 ? ProgramStop::kOptionalStop
           : m == 20 ? ProgramStop::kEnd : ProgramStop::kEndRewind;
  }
  return true;
}

// LinuxCNC's M61 Q: the tool in the spindle is Q, nothing moves (its manual: "set current tool");
// the selected tool stays. Like T, a tool not in the table is a warning until its geometry is used
// (rs274 rejects the line: its table is the control's, the machine file's need not be).
// LinuxCNC's M70 (save the modal state), M71 (invalidate it), M72 (restore it) and M73 (save it
// for the subroutine call to restore when it returns), before the line's own modal words.
bool Parser::Impl::save_restore_modes(const BlockCodes& c, ModalState& ns) {
  if (!c.m_col[kMState]) return true;
  const int code = c.m_code[kMState];
  const SavedModes now{ns.units, ns.incremental, ns.arc_incremental, ns.plane, ns.feed_mode, ns.per_revolution,
                       ns.feed, ns.feed_per_rev, ns.spindle_speed, ns.path_tolerance, ns.spindle, ns.coolant,
                       ns.path_mode, ns.cycle_to_r, ns.work_offset};
  if (code == 700) saved_modes = now;
  if (code == 710) saved_modes.reset();
  if (code == 730) {
    if (frames.size() < 2) return fail(c.m_col[kMState], "M73 outside a subroutine: it saves the state for the call to restore on return");
    frames.back().autorestore = now;
  }
  if (code == 720) {
    if (!saved_modes) return fail(c.m_col[kMState], "M72 without a state saved by M70 (or after M71 invalidated it)");
    restore_modes(*saved_modes, ns);
  }
  return true;
}

void Parser::Impl::restore_modes(const SavedModes& m, ModalState& ns) {
  ns.units = m.units;
  ns.incremental = m.incremental;
  ns.arc_incremental = m.arc_incremental;
  ns.plane = m.plane;
  ns.feed_mode = m.feed_mode;
  ns.per_revolution = m.per_revolution;
  ns.feed = m.feed;
  ns.feed_per_rev = m.feed_per_rev;
  ns.spindle_speed = m.spindle_speed;
  ns.path_tolerance = m.path_tolerance;
  ns.spindle = m.spindle;
  ns.coolant = m.coolant;
  ns.path_mode = m.path_mode;
  ns.cycle_to_r = m.cycle_to_r;
  if (ns.work_offset != m.work_offset) {
    ns.work_offset = m.work_offset;
    ns.work_origin = machine.work_offsets[static_cast<std::size_t>(ns.work_offset - 54)];
    update_origin(ns);
  }
}

// The line's warning (one a line: the first is kept), said before its blocks if the line is accepted.
void Parser::Impl::note_warning(std::uint32_t col, std::string message) {
  if (!warning.empty()) return;
  warning = std::move(message);
  warning_col = col;
  warning_tool = 0;  // no tool to mark as warned about
}

bool Parser::Impl::set_tool_number(const BlockCodes& c, ModalState& ns) {
  const std::uint32_t col = c.m_col[kMToolChange];
  if (!sc.has('Q')) return fail(col, "M61 needs Q: the number of the tool in the spindle");
  const Word& q = sc.w('Q');
  if (q.value < 0 || q.value > 9999 || q.value != std::floor(q.value))
    return fail(q.col, "M61 Q" + show(q.value) + ": Q is a tool number 0..9999");
  const int t = static_cast<int>(q.value);
  if (t != 0 && !machine.tools.empty() && machine.tools.count(t) == 0) warn_unknown_tool(t, q.col);
  ns.tool_in_spindle = t;
  return true;
}

// Step 5b: G40 / G41 / G42 / G41.1 / G42.1 (geometry in cutter.cpp), and what LinuxCNC does not
// allow while compensation is on. M2/M30 end compensation, as in LinuxCNC.
GCPIPE_STEP bool Parser::Impl::apply_cutter_comp(const BlockCodes& c, ModalState& ns) {
  if (c.has(kGCutterComp)) {
    const int code = c.group_code[kGCutterComp];
    const std::uint32_t col = c.group_col[kGCutterComp];
    if (code == 400) {
      ns.comp_side = 0;
    } else {
      if (st.comp_side != 0)
        return fail(col, code_text('G', code) + ": cutter radius compensation is already on: program G40 first");
      // LinuxCNC compensates in XY and XZ (rs274: "Cutter radius compensation allowed only in XY,
      // XZ planes"); the Fanuc dialect here in G17 only.
      if (opt.dialect == Dialect::kLinuxCnc && ns.plane == Plane::kYZ)
        return fail(col, code_text('G', code) + " in the YZ plane (G19): LinuxCNC allows cutter radius compensation only in the XY and XZ planes");
      if (opt.dialect == Dialect::kFanuc && ns.plane != Plane::kXY)
        return fail(col, code_text('G', code) + " outside the XY plane: gcpipe compensates the cutter radius in G17 only (Fanuc dialect)");
      if (ns.tcp || ns.tool_vector_mode)
        return fail(col, code_text('G', code) + " with tool centre point control (G43.4/G43.5/M428) on: not supported");
      double radius = 0;
      if (!comp_radius(c, ns, radius)) return false;
      // LinuxCNC's G41.1/G42.1 with a negative diameter compensate on the other side (rs274:
      // G42.1 D-1 offsets to the left), and with D0 follow the programmed path.
      ns.comp_side = (code == 410 || code == 411 ? 1 : -1) * (radius < 0 ? -1 : 1);
      ns.comp_radius = std::fabs(radius);
    }
  }
  if ((st.comp_side != 0 || ns.comp_side != 0) && !check_under_comp(c, ns)) return false;
  const int stop = c.m_col[kMStop] ? c.m_code[kMStop] : 0;
  if (stop == 20 || stop == 300) ns.comp_side = 0;
  return true;
}

// The radius G41/G42 use: D's tool (else the tool in the spindle) from the tool table, whose
// diameter LinuxCNC's .tbl gives as D; G41.1/G42.1 take the diameter itself in D.
bool Parser::Impl::comp_radius(const BlockCodes& c, const ModalState& ns, double& radius) {
  const int code = c.group_code[kGCutterComp];
  const std::uint32_t col = c.group_col[kGCutterComp];
  const std::string g = code_text('G', code);
  if (code == 411 || code == 421) {
    if (!sc.has('D')) return fail(col, g + " needs D: the tool diameter");
    radius = linear_value(sc.w('D'), ns.units) / 2;  // signed: see apply_cutter_comp
    return true;
  }
  int tool = ns.tool_in_spindle;
  if (sc.has('D')) {
    const Word& w = sc.w('D');
    if (w.value < 0 || w.value > 9999 || w.value != std::floor(w.value))
      return fail(w.col, g + " D" + show(w.value) + ": D is a tool number 0..9999");
    tool = static_cast<int>(w.value);
  }
  const std::uint32_t at = sc.has('D') ? sc.w('D').col : col;
  if (tool == 0) return fail(at, g + " without a tool: give D<tool number>, or load a tool (T<n> M6)");
  auto it = machine.tools.find(tool);
  if (it == machine.tools.end())
    return fail(at, g + ": " + unknown_tool(tool, "diameter"));
  if (it->second.diameter <= 0)
    return fail(at, g + ": tool " + std::to_string(tool) + " has no diameter in " + tool_table_name(machine) +
                        ": cutter compensation needs it");
  radius = it->second.diameter / 2;
  return true;
}

// What cannot run while compensation is on (LinuxCNC rejects the same): it would move the
// programmed path under the held move or change the frame the offsets are computed in.
bool Parser::Impl::check_under_comp(const BlockCodes& c, const ModalState& ns) {
  const char* why = nullptr;
  std::uint32_t col = 1;
  if (c.has(kGPlane) && c.group_code[kGPlane] != 10 * static_cast<int>(st.plane)) why = "a plane change", col = c.group_col[kGPlane];
  else if (ns.cycle != 0) why = "a canned cycle", col = c.motion_col ? c.motion_col : 1;
  else if (c.non_modal == 280 || c.non_modal == 300) why = "G28/G30", col = c.non_modal_col;
  else if (c.non_modal == 530) why = "G53", col = c.non_modal_col;
  else if (c.non_modal == 520 || (c.non_modal >= 920 && c.non_modal <= 923)) why = "a change of axis offsets (G92/G52)", col = c.non_modal_col;
  else if (c.non_modal == 100 && sc.has('L') && (sc.w('L').value == 2 || sc.w('L').value == 20))
    why = "a change of axis offsets (G10 L2/L20)", col = c.non_modal_col;
  else if (c.has(kGCoordSystem)) why = "a change of coordinate system", col = c.group_col[kGCoordSystem];
  else if (c.m_col[kMToolChange]) why = "a tool change", col = c.m_col[kMToolChange];
  else if (c.g275) why = "the G275 slot cycle", col = sc.g[0].col;
  else if (c.m_col[kMKins] || (c.has(kGToolLength) && (c.group_code[kGToolLength] == 434 || c.group_code[kGToolLength] == 435)))
    why = "tool centre point control", col = c.m_col[kMKins] ? c.m_col[kMKins] : c.group_col[kGToolLength];
  if (why == nullptr) return true;
  return fail(col, std::string("cannot use ") + why + " with cutter radius compensation on: program G40 first");
}

// Step 6: words that only some blocks may carry.
GCPIPE_STEP bool Parser::Impl::check_word_use(const BlockCodes& c, const ModalState& ns, bool vector_words) {
  const Scan& s = sc;
  if (ns.tool_vector_mode) {
    for (char L : {'A', 'C'})
      if (s.has(L))
        return fail(s.w(L).col, std::string("rotary word ") + L + show(s.w(L).value) +
                                    " in G43.5 mode: the orientation is the tool vector I J K and the "
                                    "IK chooses A and C; program I J K, or leave G43.5 (G43.4 H, G43 H, G49)");
  }
  const bool arc_mode = !c.g4 && !c.g275 && c.non_modal == 0 && ns.cycle == 0 &&
                        (ns.motion == Motion::kArcCW || ns.motion == Motion::kArcCCW);
  const bool cycle_block = ns.cycle != 0 && c.non_modal == 0 && !c.g4;
  // R of G10 is a tool radius (LinuxCNC L1/L10) or an offset value (Fanuc L10..L13); on work
  // offsets (L2/L20) it would rotate the coordinate system, which is not supported.
  const double g10_l = c.non_modal == 100 && s.has('L') ? s.w('L').value : 0;
  const bool g10_tool = opt.dialect == Dialect::kFanuc ? g10_l >= 10 && g10_l <= 13 : g10_l == 1 || g10_l == 10 || g10_l == 11;
  // R0 on a LinuxCNC G10 L2 rotates by nothing: CAM and LinuxCNC's own tests write it.
  const bool g10_no_rotation = opt.dialect == Dialect::kLinuxCnc && g10_l == 2 && s.has('R') && s.w('R').value == 0;
  if (c.non_modal == 100 && s.has('R') && opt.dialect == Dialect::kLinuxCnc && g10_l == 20)
    return fail(s.w('R').col, "R is not allowed in G10 L20 (LinuxCNC: it sets no rotation)");
  if (c.non_modal == 100 && s.has('R') && !g10_tool && !g10_no_rotation)
    return fail(s.w('R').col, "G10 with R" + show(s.w('R').value) +
                                  ": a rotated coordinate system (LinuxCNC) is not supported (R0, no rotation, is)");
  const int look = c.has(kGLookAhead) ? c.group_code[kGLookAhead] : -1;
  const bool path = c.has(kGPathMode) && c.group_code[kGPathMode] == 640;
  for (char L : {'D', 'W', 'Q', 'K', 'I', 'J', 'R', 'P', 'L'}) {
    if (!s.has(L)) continue;
    if (vector_words && (L == 'I' || L == 'J' || L == 'K')) continue;
    const bool slot_word = L == 'D' || L == 'W' || L == 'Q' || L == 'K' || L == 'R' || L == 'P';
    const bool arc_word = L == 'I' || L == 'J' || L == 'K' || L == 'R' || L == 'P';
    const bool cycle_word = L == 'R' || L == 'Q' || L == 'P' || L == 'L' ||
                            (L == 'K' && opt.dialect == Dialect::kFanuc);  // Fanuc repeats: K
    const bool g10_word = c.non_modal == 100 && (L == 'L' || L == 'P' || (L == 'R' && (g10_tool || g10_no_rotation)));
    const bool m98_word = c.m_code[kMSubprogram] == 980 && (L == 'P' || L == 'L');
    const bool m61_word = c.m_code[kMToolChange] == 610 && L == 'Q';
    const bool g331_word = c.g331 && L == 'K';
    const bool look_word = (look == 50 || look == 80) ? L == 'P' : look == 51 ? (L == 'Q' || L == 'R') : false;
    const bool comp_word = L == 'D' && c.has(kGCutterComp) && c.group_code[kGCutterComp] != 400;
    if ((c.g275 && slot_word) || comp_word || (arc_mode && arc_word) || (L == 'P' && c.g4) || (path && (L == 'P' || L == 'Q')) ||
        (cycle_block && cycle_word) || g10_word || m98_word || m61_word || g331_word || look_word)
      continue;
    std::string where = L == 'L' ? "canned cycles (repeats) and G10"
                        : L == 'D' ? "G41/G42 (tool number), G41.1/G42.1 (diameter) and the G275 slot cycle"
                        : L == 'W' ? "the G275 slot cycle"
                        : L == 'Q' ? (opt.dialect == Dialect::kLinuxCnc ? "G73/G83 (peck), G64, G275 and M61" : "G73/G83 (peck), G64 and G275")
                        : L == 'P' ? "G4 (dwell), G2/G3 (turns), canned cycles, G64 or G275"
                                   : "G2/G3 arcs, canned cycles (R) and G275 (K, R)";
    return fail(s.w(L).col, std::string("word ") + L + show(s.w(L).value) + " has no meaning here: it is used by " + where);
  }
  return true;
}

// Step 7: lengths that are not axes (arc centres and radii, cycle parameters): the same range
// as the axes, so no absurd value can reach the geometry or the writer.
GCPIPE_STEP bool Parser::Impl::check_lengths(bool vector_words, const ModalState& ns) {
  for (char L : {'I', 'J', 'K', 'R', 'D', 'W', 'Q'}) {
    if (!sc.has(L)) continue;
    if (vector_words && (L == 'I' || L == 'J' || L == 'K')) continue;  // checked in read_tool_vector
    const Word& w = sc.w(L);
    if (std::fabs(linear_value(w, ns.units)) > kMaxLinear)
      return fail(w.col, std::string(1, L) + show(w.value) + " is out of range (|" + L + "| <= " +
                             show(kMaxLinear) + " mm)");
  }
  return true;
}

// The tool vector (G43.5): a direction, so absolute in G91 too and without units; an omitted
// component is 0 (as on Fanuc) and a block without I J K keeps the vector in force.
bool Parser::Impl::read_tool_vector(Vec3& vector) {
  const Scan& s = sc;
  const std::uint32_t vcol = s.has('I') ? s.w('I').col : s.has('J') ? s.w('J').col : s.w('K').col;
  double ijk[3] = {0, 0, 0};
  for (int k = 0; k < 3; ++k) {
    const char L = static_cast<char>('I' + k);
    if (!s.has(L)) continue;
    ijk[k] = angle_value(s.w(L));  // dimensionless: only the decimal-point rule applies
    if (!std::isfinite(ijk[k]) || std::fabs(ijk[k]) > kMaxLinear)
      return fail(s.w(L).col, std::string("tool vector component ") + L + show(s.w(L).value) +
                                  " is out of range (|" + L + "| <= " + show(kMaxLinear) + ")");
  }
  const double n = std::sqrt(ijk[0] * ijk[0] + ijk[1] * ijk[1] + ijk[2] * ijk[2]);
  if (!(n >= 1e-9))
    return fail(vcol, "tool vector I" + show(ijk[0]) + " J" + show(ijk[1]) + " K" + show(ijk[2]) +
                          " has zero length (|(I, J, K)| < 1e-9): it gives no tool axis direction");
  vector = {ijk[0] / n, ijk[1] / n, ijk[2] / n};
  return true;
}

// Step 8: axis words to machine targets (G53 and G10/G92/G52 read their own axis words later,
// from `mask`; here they are range-checked like any other).
GCPIPE_STEP bool Parser::Impl::axis_targets(const BlockCodes& c, const ModalState& ns, Axes& target, std::uint8_t& mask) {
  target = ns.position;
  const bool x_as_dwell = c.g4 && opt.dialect == Dialect::kFanuc && sc.has('X');
  for (int a = 0; a < kNumAxes; ++a) {
    const char L = kAxisLetters[a];
    if (!sc.has(L) || (x_as_dwell && a == kX)) continue;
    const Word& w = sc.w(L);
    const bool rotary = a >= kA;
    const double v = rotary ? angle_value(w) : linear_value(w, ns.units);
    const double lim = rotary ? kMaxAngle : kMaxLinear;
    if (std::fabs(v) > lim)
      return fail(w.col, std::string(1, L) + show(w.value) + " is out of range (|" + L + "| <= " +
                             show(lim) + (rotary ? " deg)" : " mm)"));
    target[a] = ns.incremental ? ns.position[a] + v : v + ns.origin[a];
    // Incremental steps that are each in range can still add up to an absurd position, which the
    // writer would then have to write as one absolute word: bound the result too.
    if (std::fabs(target[a] - ns.origin[a]) > lim)
      return fail(w.col, std::string(1, L) + show(w.value) + " takes " + L + " to " + show(target[a] - ns.origin[a]) +
                             (rotary ? " deg" : " mm") + ", out of range (|" + L + "| <= " + show(lim) +
                             (rotary ? " deg)" : " mm)"));
    mask = static_cast<std::uint8_t>(mask | (1u << a));
  }
  if (sc.polar_r.col != 0 || sc.polar_a.col != 0) return polar_target(ns, target, mask);
  return true;
}

// @ ^: X and Y from a distance and an angle about the origin of the system in force; in G91 they
// are added to the current distance and angle. As in rs274, only with G17 in force before the
// block (a G17 or G18 in the same block does not count).
bool Parser::Impl::polar_target(const ModalState& ns, Axes& target, std::uint8_t& mask) {
  const std::uint32_t col = sc.polar_r.col ? sc.polar_r.col : sc.polar_a.col;
  if (st.plane != Plane::kXY)
    return fail(col, "polar coordinates (@ ^) need the G17 plane in force before this block (LinuxCNC's rule)");
  for (char L : {'X', 'Y'})
    if (sc.has(L))
      return fail(sc.w(L).col, std::string("polar coordinates (@ ^) and ") + L + " in one block: keep one way");
  // At the origin G91 @ ^ have no angle to add to; rs274 refuses the block rather than guess.
  const double x0 = ns.position[kX] - ns.origin[kX], y0 = ns.position[kY] - ns.origin[kY];
  if (ns.incremental && std::hypot(x0, y0) < 1e-12)
    return fail(col, "G91 polar coordinates (@ ^) with the tool at the origin: the angle to add to is undefined "
                     "(rs274 refuses it too); move off X0 Y0 or use G90");
  const double r = polar_distance(ns, ns.position);
  if (!(std::fabs(r) <= kMaxLinear)) return fail(col, "polar distance " + show(r) + " mm is out of range (|@| <= 100000 mm)");
  polar_point(ns, ns.position, target);
  mask = static_cast<std::uint8_t>(mask | (1u << kX) | (1u << kY));
  return true;
}

// The distance the block's @ ^ give when the tool stands at `from` [mm].
double Parser::Impl::polar_distance(const ModalState& ns, const Axes& from) const {
  const double r0 = std::hypot(from[kX] - ns.origin[kX], from[kY] - ns.origin[kY]);
  const double dr = sc.polar_r.col ? linear_value(sc.polar_r, ns.units) : 0;
  return ns.incremental ? r0 + dr : (sc.polar_r.col ? dr : r0);
}

// X and Y of the block's @ ^ seen from `from` into `to`: a canned cycle's repeats in G91 call it
// once per hole, from the hole before, so they step in distance and angle as rs274's do.
void Parser::Impl::polar_point(const ModalState& ns, const Axes& from, Axes& to) const {
  const double x0 = from[kX] - ns.origin[kX], y0 = from[kY] - ns.origin[kY];
  const double a0 = std::atan2(y0, x0) * 180 / std::numbers::pi;
  const double da = sc.polar_a.col ? angle_value(sc.polar_a) : 0;
  const double a = (ns.incremental ? a0 + da : (sc.polar_a.col ? da : a0)) * std::numbers::pi / 180;
  const double r = polar_distance(ns, from);
  to[kX] = r * std::cos(a) + ns.origin[kX];
  to[kY] = r * std::sin(a) + ns.origin[kY];
}

// LinuxCNC runs a G4 and a move written in one block (`G4 P.001 G0 X1 Y1`): rs274 dwells first
// (its order of execution puts the dwell before motion), then moves. On Fanuc X is the dwell time
// itself and G04 is a block of its own: there axis words still cannot go with it.
bool Parser::Impl::dwell_with_move(std::uint8_t mask) const {
  return mask != 0 && opt.dialect == Dialect::kLinuxCnc;
}

// The dwell of a LinuxCNC block that also moves, kept for run_line to hand out before the move.
// Not under cutter compensation or a canned cycle: the dwell would have to wait inside a held
// move or a cycle's expansion.
bool Parser::Impl::dwell_before_move(const ModalState& ns) {
  const std::uint32_t col = sc.g[0].col;
  if (ns.cycle != 0) return fail(col, "G4 with axis words while a canned cycle is in force: put the dwell on a line of its own");
  if (ns.motion == Motion::kArcCW || ns.motion == Motion::kArcCCW)
    return fail(col, "G4 with a G2/G3 move: both use P (rs274 refuses it too); put the dwell on a line of its own");
  // rs274 runs it, but ends the held move without its corner at the dwell: not reproduced. The
  // move that leaves compensation (after G40, or with it) is a plain move: there it runs.
  if (ns.comp_side != 0)
    return fail(col, "G4 with a move under cutter radius compensation: put the dwell on a line of its own");
  double t = 0;
  if (!dwell_time(t)) return false;
  dwell_first = t;
  return true;
}

// G4: Fanuc P in ms or X in s, LinuxCNC P in s. A motion code in the same block only sets the
// mode (both controls allow `G0 G4 P1`); axis words cannot go with a dwell (but see
// dwell_with_move).
bool Parser::Impl::dwell(ResolvedBlock& b, const ModalState& ns) {
  const Scan& s = sc;
  for (int a = 0; a < kNumAxes; ++a)
    if (b.axis_words & (1u << a))
      return fail(s.w(kAxisLetters[a]).col, std::string("axis word ") + kAxisLetters[a] + " with G4: a dwell block cannot move");
  double t = 0;
  if (!dwell_time(t)) return false;
  b.motion = Motion::kDwell;
  b.dwell = t;
  b.target = ns.position;
  return true;
}

// The dwell time of a G4 block [s], in the dialect's words and range.
bool Parser::Impl::dwell_time(double& t) {
  const Scan& s = sc;
  const std::uint32_t col = s.g[0].col;
  if (opt.dialect == Dialect::kFanuc) {
    if (s.has('X') && s.has('P')) return fail(s.w('P').col, "G4 with both X (seconds) and P (milliseconds): keep one");
    if (s.has('X')) t = s.w('X').value;
    else if (s.has('P')) t = s.w('P').value / 1000.0;
    else return fail(col, "G4 needs the dwell time: X<seconds> or P<milliseconds>");
  } else {
    if (!s.has('P')) return fail(col, "G4 needs the dwell time: P<seconds>");
    t = s.w('P').value;
  }
  if (t < 0 || t > 1e5) return fail(col, "dwell time " + show(t) + " s is out of range (0..100000 s)");
  return true;
}

// G95: a feed per revolution needs the revolutions: a spindle that turns, at a speed, and the
// resulting feed is held to parse.min_feed as a G94 one is.
bool Parser::Impl::check_feed_per_revolution(std::uint32_t col, const ModalState& ns) {
  const std::string what = std::string(motion_name(ns.motion)) + " in feed per revolution (G95)";
  if (ns.feed_per_rev <= 0) return fail(col, what + " without a feed: program F (mm per revolution) in this block or before it");
  if (ns.spindle == Spindle::kOff)
    return fail(col, what + " with the spindle stopped: the axes would not move; start it (M3/M4) first");
  if (ns.spindle_speed <= 0) return fail(col, what + " without a spindle speed: program S (rev/min) before it");
  if (ns.feed < opt.min_feed)
    return fail(col, what + ": F x S = " + show(ns.feed) + " mm/min is below the minimum feed of " + show(opt.min_feed) +
                         " mm/min (parse.min_feed in the pipeline config)");
  return true;
}

// G1/G2/G3 need a feed (and in G93 one in the block).
bool Parser::Impl::check_feed(const BlockCodes& c, const ModalState& ns) {
  if (ns.motion == Motion::kRapid) return true;
  const std::uint32_t col = c.motion_col ? c.motion_col : (sc.has('X') ? sc.w('X').col : 1);
  if (ns.feed_mode == FeedMode::kInverseTime && !sc.has('F'))
    return fail(col, std::string(motion_name(ns.motion)) + " in inverse-time mode (G93) needs F in the same block");
  if (ns.per_revolution) return check_feed_per_revolution(col, ns);
  // F0 programmed is not a missing F: name the word and what a feed must be.
  if (ns.feed <= 0 && sc.has('F'))
    return fail(sc.w('F').col, "F" + show(sc.w('F').value) + " is no feed: " + motion_name(ns.motion) +
                                   " needs F > 0 (mm/min; parse.min_feed is the least accepted)");
  if (ns.feed <= 0)
    return fail(col, std::string(motion_name(ns.motion)) + " without a feed: program F (mm/min) in this block or before it");
  return true;
}

// Step 9: the block's move in the modal motion mode (or no move at all).
GCPIPE_STEP bool Parser::Impl::move(const BlockCodes& c, ResolvedBlock& b, ModalState& ns, const Axes& target,
                        std::uint8_t mask, bool vector_words, const Vec3& vector) {
  const Scan& s = sc;
  const bool arc_mode = ns.motion == Motion::kArcCW || ns.motion == Motion::kArcCCW;
  const bool has_centre = s.has('I') || s.has('J') || s.has('K') || s.has('R');
  if (vector_words && ns.motion == Motion::kNone)
    return fail(s.has('I') ? s.w('I').col : s.has('J') ? s.w('J').col : s.w('K').col,
                "tool vector I J K without a motion mode: program G0 or G1 first");
  if (mask == 0 && !(arc_mode && has_centre) && !vector_words) {
    b.motion = Motion::kNone;
    b.target = ns.position;
    return true;
  }
  if (ns.motion == Motion::kNone) {
    for (int a = 0; a < kNumAxes; ++a)
      if (mask & (1u << a))
        return fail(s.w(kAxisLetters[a]).col, std::string("axis word ") + kAxisLetters[a] +
                                                  " without a motion mode: program G0, G1, G2 or G3 first");
  }
  if (!check_feed(c, ns)) return false;
  if (ns.tool_vector_mode && !vector_words && !ns.tool_vector_set) {
    const std::uint32_t col = c.motion_col ? c.motion_col : s.has('X') ? s.w('X').col : s.has('Y') ? s.w('Y').col : 1;
    return fail(col, "first move in G43.5 mode without a tool vector: program I J K (the tool axis, "
                     "tip to spindle, in the workpiece frame) in the first G0/G1 after G43.5");
  }
  b.motion = ns.motion;
  b.target = target;
  if (arc_mode) return arc(s, b, ns, ns.motion == Motion::kArcCW);
  if (vector_words) {
    ns.tool_vector = vector;
    ns.tool_vector_set = true;
  }
  ns.position = target;
  return true;
}

}  // namespace gcpipe
