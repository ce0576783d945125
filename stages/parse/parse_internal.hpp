// Internals of the parser shared by its source files (not part of the stage's interface):
//   parse.cpp     the public Parser, one line's life (scan, resolve, commit, publish);
//   scan.cpp      words, comments, numbers and expressions of one line;
//   resolve.cpp   modal resolution of a scanned line, in named steps;
//   motion.cpp    arcs, G53, G28/G30, G92/G52 and the G275 slot;
//   cycles.cpp    canned drilling cycles expanded into plain moves;
//   flow.cpp      LinuxCNC o-word subroutines and flow control (the only part that buffers).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <set>
#include <numbers>
#include <string>
#include <string_view>
#include <vector>

#include "expression.hpp"
#include "gcpipe/stop.hpp"
#include "parse.hpp"

namespace gcpipe {

namespace parse_detail {
struct CycleGeometry;  // cycles.cpp: the resolved numbers of one canned-cycle block

constexpr double kMaxLinear = 1e5;   // [mm] |value| beyond any machine: surely a typo or overflow
constexpr double kMaxAngle = 1e5;    // [deg] allows many turns of C, rejects overflow
// [mm/min] or [1/min]: inverse-time F of a very short segment and inch "rapid feeds" of posts
// (F99999 inch/min) exceed 1e6; beyond 1e8 a feed is an overflow, not a feed.
constexpr double kMaxFeed = 1e8;
constexpr double kMaxSpindle = 1e6;  // [rev/min]
constexpr double kInch = 25.4;       // [mm]

/// LinuxCNC's absolute radius tolerance of a centre-format arc [mm] in the program's units.
inline double arc_radius_tolerance(bool inch) { return (inch ? 2 * 0.001 * kInch : 2 * 0.01) * std::numbers::sqrt2; }
/// Whether an arc's start and end radii agree as LinuxCNC asks (motion.cpp, offset_centre): the
/// one check for programmed arcs and for the offset paths cutter compensation makes of them.
inline bool arc_radii_agree(double r1, double r2, double t_abs) {
  const double abs_err = std::fabs(r1 - r2);
  return !(abs_err > 100 * t_abs || (abs_err > t_abs && abs_err / std::max(r1, r2) > 0.001));
}

struct Word {
  double value = 0;
  std::uint32_t col = 0;  // 1-based, 0 = absent
  bool point = false;     // written with a decimal point (Fanuc increment rule)
  bool expr = false;      // came from an expression or parameter (never in increments)
  bool vacant = false;    // Fanuc: a vacant variable (X#1, #1 never set): the word is left out
};

struct Code {
  int code;  // G or M number x10: G43.4 -> 434
  std::uint32_t col;
};

// Modal groups (ISO 6983 / LinuxCNC numbering) used to detect two codes of one group in a block.
enum Group : int {
  kGNonModal = 0, kGMotion = 1, kGPlane = 2, kGDistance = 3, kGArcDistance = 4, kGFeedMode = 5,
  kGUnits = 6, kGCutterComp = 7, kGToolLength = 8, kGCycleCancel = 9, kGCycleReturn = 10,
  kGExactStopOnce = 11,  // Fanuc G09: group 00 there, apart here so it may share a block with G10..G92
  kGCoordSystem = 12, kGPathMode = 13, kGLookAhead = 14, kGSpindleMode = 15, kGUnsupported = 99
};

// Why a code is what it is: the parser's words for "G81" in messages.
std::string code_text(char letter, int code);
std::string show(double v);  // a value as a message shows it: shortest exact digits
// Inline: the scanner calls it between every two words, from several files.
inline void skip_blanks(std::string_view s, std::size_t& p) {
  while (p < s.size() && (s[p] == ' ' || s[p] == '\t')) ++p;
}
inline char upper(char c) { return (c >= 'a' && c <= 'z') ? static_cast<char>(c - 'a' + 'A') : c; }

// Plane geometry: the two in-plane axes, the normal axis, and the letters of the centre offsets.
struct PlaneAxes {
  int u, v, n;  // axis indices
  char ou, ov;  // offset letters for u and v
};
PlaneAxes plane_axes(Plane p);

struct ModalState {
  Motion motion = Motion::kNone;  // modal motion (G0..G3), kNone until programmed or after G80
  int cycle = 0;                  // canned cycle in force (G81 -> 810), 0 = none
  // Fanuc: the group 01 mode (G00..G03) a canned cycle began in; the cycle (group 09) does not
  // change it, so G80 brings it back (LinuxCNC's G80 is itself a motion mode: no move after it).
  Motion motion_before_cycle = Motion::kNone;
  // Fanuc M29 S: rigid tapping; the next G84/G74 taps with the spindle driven by the control (no
  // M3/M4 needed before it) until G80 or a group 01 code ends the cycle.
  bool rigid_tap = false;
  bool cycle_to_r = false;        // G99: retract to R (else G98: to the initial level)
  double cycle_initial = 0;       // initial level along the drilling axis [mm, machine]
  Word cycle_r, cycle_z, cycle_q, cycle_p;  // sticky cycle words, as programmed
  Plane plane = Plane::kXY;
  bool incremental = false;
  bool arc_incremental = true;  // G91.1 is the default in Fanuc and LinuxCNC
  Units units = Units::kMillimetre;
  FeedMode feed_mode = FeedMode::kUnitsPerMinute;
  double feed = 0;               // mm/min (G94, G95: F x S) or 1/min (G93)
  bool per_revolution = false;   // G95: F is mm per spindle revolution
  double feed_per_rev = 0;       // G95's F [mm/rev]
  double spindle_speed = 0;
  double path_tolerance = 0;     // G64 P [mm]; 0 after G64 without P, G61 or G61.1
  PathMode path_mode = PathMode::kBlend;  // G64 / G61 / G61.1
  Spindle spindle = Spindle::kOff;
  std::int32_t tool = 0;
  std::int32_t tool_in_spindle = 0;
  std::int32_t tlo_h = 0;
  double tool_length = 0;
  bool tlo_active = false;
  bool tcp = false;
  bool tool_vector_mode = false;  // G43.5: orientation programmed as I J K
  bool tool_vector_set = false;   // a vector has been programmed since G43.5 began
  Vec3 tool_vector{0, 0, 1};      // unit, workpiece frame
  std::uint8_t coolant = 0;
  std::int32_t work_offset = 54;
  Axes work_origin{};  // origin of the G5x system (published with each block)
  Axes shift{};        // G92 / G52 shift added to the G5x origin
  bool shift_suspended = false;  // G92.2: the shift is kept but not applied
  Axes origin{};       // origin program values are measured from: the program's G5x origin + shift
  Axes position{};     // machine coordinates
  // Cutter radius compensation (G41/G42, cutter.cpp: LinuxCNC's geometry, or Fanuc's): +1 the tool left of
  // the path (G41), -1 right (G42), 0 off (G40); the radius is latched when it is turned on.
  int comp_side = 0;
  double comp_radius = 0;  // [mm]
  bool ended = false;
};

// The modal state LinuxCNC's M70/M73 save and M72 restores (its manual, "M70 Save Modal State"):
// units, distance and arc-distance modes, plane, feed mode and F, spindle speed and direction,
// coolant, path mode, cycle return level, work coordinate system; not the motion mode, not the tool.
struct SavedModes {
  Units units = Units::kMillimetre;
  bool incremental = false, arc_incremental = true;
  Plane plane = Plane::kXY;
  FeedMode feed_mode = FeedMode::kUnitsPerMinute;
  bool per_revolution = false;
  double feed = 0, feed_per_rev = 0, spindle_speed = 0, path_tolerance = 0;
  Spindle spindle = Spindle::kOff;
  std::uint8_t coolant = 0;
  PathMode path_mode = PathMode::kBlend;
  bool cycle_to_r = false;
  std::int32_t work_offset = 54;
};

// Everything scanned from one line.
struct Scan {
  Word words[26];
  Word polar_r, polar_a;  // LinuxCNC polar coordinates: @ distance, ^ angle [deg]
  Code g[8];
  int ng = 0;
  Code m[8];
  int nm = 0;
  Assignment assign[8];
  int nassign = 0;
  bool percent = false;
  std::int32_t program_number = -1;
  bool any_word = false;

  const Word& w(char letter) const { return words[letter - 'A']; }
  bool has(char letter) const { return words[letter - 'A'].col != 0; }
};

// The G and M codes of one block sorted by modal group (step 1 of resolve).
struct BlockCodes {
  static constexpr int kGroups = 16;  // G groups 0..14, M groups 4..11: small, zeroed per line
  std::uint32_t group_col[kGroups] = {};
  int group_code[kGroups] = {};
  int motion_code = -1;  // G0 G1 G2 G3 or a cycle
  std::uint32_t motion_col = 0;
  bool g4 = false, g275 = false;
  bool g331 = false;  // LinuxCNC G33.1 rigid tapping (its own block's move; see rigid_tap)
  int non_modal = 0;  // G10 G28 G30 G53 G92 G92.1 G92.2 G92.3 G52 (x10), 0 = none
  std::uint32_t non_modal_col = 0;
  int m_code[kGroups] = {};
  std::uint32_t m_col[kGroups] = {};
  bool mist = false, flood = false, coolant_off = false;
  bool has(int group) const { return group_col[group] != 0; }
};

// One move of a block that expands into several (a canned cycle, G28 through its intermediate
// point); published as a block of its own carrying the source line.
struct Move {
  Motion motion = Motion::kRapid;
  Axes target{};
  double dwell = 0;
  int spindle = -1;  // -1: the modal spindle; else a Spindle value for this move (G84 reversal)
  bool stop = false;  // a program stop after this move (G88: the operator retracts by hand)
  double feed = -1;   // >= 0: this move's own feed [mm/min] (G33.1: K x S), else the modal F
};

// What an arc block needs to place its centre, shared by the two formats.
struct ArcGeometry {
  PlaneAxes pa;
  double su, sv, eu, ev;  // start and end in the plane [mm]
  double t_abs;           // LinuxCNC's absolute radius tolerance in the block's units [mm]
  bool inch;
  char gname[3];
  std::uint32_t col;
};

// A point in the XY plane, the plane cutter compensation works in.
struct P2 {
  double x = 0, y = 0;
};

// One programmed move's path offset by the tool radius (cutter compensation, cutter.cpp). Its
// start and end move with the corners: a concave corner cuts both moves at the intersection.
struct OffsetMove {
  bool arc = false, cw = false;
  bool full_circle = false;  // arc: it ends where it starts
  bool entry = false;  // the entry move: it starts where the tool stands, off the offset path
  P2 path_start;       // where the offset path starts (before a corner moves `start`)
  P2 start;            // where the tool starts this move
  P2 end;              // the offset end point (before the corner with the next move moves it)
  P2 corner;           // the programmed end: the corner with the next move
  P2 centre;           // arc: the programmed centre
  double radius = 0;      // arc: the offset radius at the start
  double end_radius = 0;  // arc: at the end (the programmed radii differ within tolerance)
  double path_radius = 0, path_end_radius = 0;  // arc: the programmed radii, start and end
  P2 dir;              // line: unit direction
  P2 start_tangent, end_tangent;  // unit tangents of the programmed move
};

// What compensation holds back: the move whose end waits for the next move (LinuxCNC's one-move
// look-behind) and the blocks read after it, which must come out after it.
struct CutterComp {
  bool pending = false;
  OffsetMove move;
  ResolvedBlock block;              // the pending move's block, as resolved
  std::vector<ResolvedBlock> held;  // blocks after it that do not move in XY
  bool off_path = false;  // after G40 (or before an entry): the tool stands at `at`, not at the
  P2 at;                  // programmed XY, until the next move
  // The plane compensation runs in, set at its entry (no plane change while it is on): XY, or in
  // LinuxCNC ZX, whose points are (Z, X) as rs274 reads that plane.
  Plane plane = Plane::kXY;
};

// A line kept for flow control: a subroutine body, or a loop's lines to run again.
struct SourceLine {
  std::string text;
  std::uint64_t number = 0;
  std::size_t overlong = 0;
};

// An open if / while / do / repeat of one frame.
struct Control {
  enum Kind : std::uint8_t { kIf, kWhile, kDo, kRepeat } kind = kIf;
  std::string label;
  std::uint64_t start = 0;  // index (main: line number) of the opening statement
  bool taken = false;       // if: a branch has run
  std::uint64_t passes = 0;
  std::int64_t remaining = 0;  // repeat
};

struct Subroutine {
  std::uint64_t line = 0;      // line of its `sub` statement
  std::uint64_t end_line = 0;  // line of its `endsub`, 0 while the definition is still open
  std::vector<SourceLine> body;
};

// Why lines are being passed over without running.
enum class Skip : std::uint8_t { kNone, kBranch, kToEndif, kToLoopEnd, kSubDefinition, kToLabel };

struct Frame {
  const Subroutine* sub = nullptr;  // nullptr: the main program
  std::string label;                // the subroutine's label
  std::uint64_t pc = 0;             // main: next line number; sub: index into body
  std::uint64_t call_line = 0;      // where it was called from
  std::vector<Control> controls;
  Skip skip = Skip::kNone;
  std::string skip_label;
  std::uint64_t skip_from = 0;  // line that started the skip (for notes)
  long goto_target = -1;        // Fanuc GOTO n: the N number looked for
  std::array<double, 30> saved_args{};                 // caller's #1..#30
  bool local_scope = false;  // an o-word call: its named parameters are its own (LinuxCNC)
  long repeats = 1;  // Fanuc M98 L: runs of the body still to go, this one included
  std::optional<SavedModes> autorestore;  // LinuxCNC M73: restored when this call returns
  // A Fanuc M98 whose subprogram is not defined yet: the call waits, the lines after it too.
  std::string pending_call;
  long pending_repeats = 0;
  std::uint64_t pending_line = 0;
};

// A parsed o-word statement: `o100 if [#1 gt 2]`, `o<name> call [1] [2]`.
struct Statement {
  std::string label;    // "100" or "<name>", normalised
  std::string keyword;  // sub endsub call return if elseif else endif while endwhile do repeat
                        // endrepeat break continue
  std::size_t rest = 0; // position after the keyword (condition, arguments)
  std::uint32_t col = 1;
  std::size_t target = 0;  // Fanuc IF [..] GOTO n / THEN ...: where n or the statement starts
};

}  // namespace parse_detail

struct Parser::Impl {
  using ModalState = parse_detail::ModalState;
  using SavedModes = parse_detail::SavedModes;
  using Scan = parse_detail::Scan;
  using Word = parse_detail::Word;
  using BlockCodes = parse_detail::BlockCodes;

  ParseOptions opt;
  MachineConfig machine;
  std::string file;
  ModalState st;
  ParameterStore params;
  ParseSummary summary;
  Scan sc;
  std::string error;  // message of the current line's error
  std::uint32_t error_col = 0;
  std::string warning;  // the current line's warning (a tool not in the table), empty: none
  std::uint32_t warning_col = 0;
  int warning_tool = 0;
  std::set<int> warned_tools;  // tools warned about already: once each
  // G54..G59 origins as the program has them (G10 L2/L20 change them); blocks publish the
  // machine file's, so targets stay in the frame every later stage and the writer know.
  std::array<Axes, 6> offsets{};
  std::vector<parse_detail::Move> moves;  // expansion of the current line, empty for one block
  ResolvedBlock block;                    // the block being resolved (reused: no allocation)
  bool exact_stop_once = false;           // G09 in the line: its blocks stop exactly at their end
  double dwell_first = -1;                // LinuxCNC G4 beside a move: its time [s], else < 0
  ResolvedBlock expanded;                 // one move of an expansion
  parse_detail::CutterComp comp;          // cutter compensation's held moves (cutter.cpp)
  parse_detail::CutterComp comp_next;     // the same after the current line, until it commits
  std::vector<ResolvedBlock> comp_out;    // blocks the current line hands out under compensation
  const ParseSink* sink = nullptr;
  bool stopped = false;  // the sink asked to stop
  std::uint64_t alarm_line = 0;  // a Fanuc #3000 alarm stopped the program on this line (0: none)

  // -- flow control (flow.cpp)
  std::deque<parse_detail::SourceLine> window;  // main-program lines kept for loops and waits
  std::uint64_t window_first = 1;                // line number of window.front()
  std::vector<parse_detail::Frame> frames;       // frames[0] is the main program
  std::map<std::string, parse_detail::Subroutine> subs;
  std::string defining;                          // label of the sub being collected, or empty
  // Fanuc subprograms (O2000 ... M99 after the main program's M30): where each starts, and
  // whether the main program's end has been read (then an O number starts a subprogram).
  std::map<std::uint64_t, std::string> fanuc_starts;
  bool main_end_read = false;
  bool macro_mode = false;  // a Fanuc program with # variables: lines are kept for GOTO
  struct FanucCall {
    std::string label;  // "O" + number, empty: none
    long repeats = 1;
    bool ret = false;   // M99
  } fanuc;
  bool input_done = false;
  // The program end that ran (M2, M30, or the '%' that closes the tape): nothing after it runs,
  // and each later line is reported as not run (Fanuc subprograms after M30 are still collected).
  std::uint64_t end_line = 0;  // 0: not ended
  const char* end_word = "";
  // The tape: a '%' line before any code opens it, the next closes it (known as lines arrive,
  // since a LinuxCNC call searches forward for its definition only up to there, as rs274 does).
  bool code_read = false;           // a line with code outside comments has been read
  std::uint64_t tape_close_line = 0;  // the first '%' line after code (0: none yet)
  bool abort_requested = false;  // an expansion failed: run_ready unwinds it after the step
  struct Owner {
    std::uint64_t line = 0;  // the newest main-program line run (0: none open)
    bool error = false;
    bool blocks = false;
    std::uint64_t steps = 0;  // lines run on its behalf (bounded: no input may hang)
    std::uint64_t jumps = 0;  // GOTOs back on its behalf (bounded like loop passes)
  } owner;
  std::uint64_t classified = 0;  // every line up to this one is counted in the summary

  Impl(ParseOptions o, MachineConfig m, std::string f);

  bool fail(std::uint32_t col, std::string msg) {
    error = std::move(msg);
    error_col = col;
    return false;
  }

  // -- one line (parse.cpp)
  enum class Outcome : std::uint8_t { kBlocks, kRejected, kDeleted };
  Outcome run_line(std::string_view line, std::uint64_t lineno, std::size_t overlong, std::string& why,
                   std::uint32_t& col);
  void reset_block(std::string_view line, std::uint64_t lineno);
  void commit(ModalState& ns);
  void publish(ResolvedBlock& b) const { publish(b, st); }
  void publish(ResolvedBlock& b, const ModalState& s) const;
  bool emit(const ResolvedBlock& b);
  bool hand_out(const ResolvedBlock& b);
  void hand_out_compensated();
  bool emit_moves();
  bool emit_dwell_first();
  bool emit_diagnostic(std::uint64_t line, std::uint32_t col, Severity sev, std::string msg);

  // -- scan.cpp
  bool scan(std::string_view s, ResolvedBlock& b);
  bool scan_o_word(std::string_view s, std::size_t& p, std::uint32_t col);
  bool scan_assignment(std::string_view s, std::size_t& p, std::uint32_t col);
  bool scan_word(std::string_view s, std::size_t& p, char L, std::uint32_t col);
  bool scan_polar(std::string_view s, std::size_t& p, std::uint32_t col);
  bool polar_target(const ModalState& ns, Axes& target, std::uint8_t& mask);
  double polar_distance(const ModalState& ns, const Axes& from) const;
  void polar_point(const ModalState& ns, const Axes& from, Axes& to) const;
  bool polar_words() const { return sc.polar_r.col != 0 || sc.polar_a.col != 0; }
  bool reject_character(std::string_view s, std::size_t p, char c, std::uint32_t col);
  bool read_number(std::string_view s, std::size_t& p, char letter, Word& w);
  bool read_expression_number(std::string_view s, std::size_t& p, char letter, Word& w);
  bool read_code(std::string_view s, std::size_t& p, char letter, int& code, std::uint32_t col);
  void refresh_system_parameters();
  void refresh_linuxcnc_modes();
  bool set_tool_number(const BlockCodes& c, ModalState& ns);
  void note_warning(std::uint32_t col, std::string message);
  bool entry_arc(const ModalState& ns, ResolvedBlock& b);
  bool save_restore_modes(const BlockCodes& c, ModalState& ns);
  bool rigid_tap(ResolvedBlock& b, ModalState& ns, const Axes& target, std::uint8_t mask);
  void restore_modes(const SavedModes& m, ModalState& ns);
  std::optional<SavedModes> saved_modes;  // LinuxCNC M70's state, until M71 invalidates it
  void refresh_offset_parameters(double unit);
  static bool is_abort(std::string_view comment);
  bool linuxcnc_abort(std::string_view message, std::uint32_t col);
  bool fanuc_system_assignment(std::string_view s, std::size_t p, const Assignment& a, std::uint32_t col);

  // -- resolve.cpp
  bool resolve(ResolvedBlock& b, ModalState& ns);
  bool sort_g_codes(BlockCodes& c);
  Motion motion_after_g80(const ModalState& ns) const;
  bool sort_m_codes(BlockCodes& c);
  bool check_block_number();
  bool apply_feed_speed_tool(const BlockCodes& c, ModalState& ns, ResolvedBlock& b);
  bool apply_tool_length(const BlockCodes& c, ModalState& ns);
  std::string unknown_tool(int tool, const char* what) const;
  void warn_unknown_tool(int tool, std::uint32_t col);
  bool emit_warning(std::uint64_t line);
  bool apply_modes(const BlockCodes& c, ModalState& ns, ResolvedBlock& b);
  bool apply_cutter_comp(const BlockCodes& c, ModalState& ns);
  bool comp_radius(const BlockCodes& c, const ModalState& ns, double& radius);
  bool check_under_comp(const BlockCodes& c, const ModalState& ns);
  bool check_word_use(const BlockCodes& c, const ModalState& ns, bool vector_words);
  bool check_lengths(bool vector_words, const ModalState& ns);
  bool read_tool_vector(Vec3& vector);
  bool axis_targets(const BlockCodes& c, const ModalState& ns, Axes& target, std::uint8_t& mask);
  bool dwell(ResolvedBlock& b, const ModalState& ns);
  bool dwell_time(double& t);
  bool dwell_with_move(std::uint8_t mask) const;
  bool dwell_before_move(const ModalState& ns);
  bool move(const BlockCodes& c, ResolvedBlock& b, ModalState& ns, const Axes& target, std::uint8_t mask,
            bool vector_words, const Vec3& vector);
  bool check_feed(const BlockCodes& c, const ModalState& ns);
  bool check_feed_per_revolution(std::uint32_t col, const ModalState& ns);
  double linear_value(const Word& w, Units units) const;
  double angle_value(const Word& w) const;

  // -- motion.cpp
  bool arc(const Scan& sc, ResolvedBlock& b, ModalState& ns, bool cw);
  bool slot(const Scan& sc, ResolvedBlock& b, ModalState& ns);
  bool radius_centre(const parse_detail::ArcGeometry& g, bool cw, const ModalState& ns, double& cu, double& cv);
  bool offset_centre(const parse_detail::ArcGeometry& g, const ModalState& ns, double& cu, double& cv);
  bool non_modal(const BlockCodes& c, ResolvedBlock& b, ModalState& ns, std::uint8_t mask);
  bool machine_move(const BlockCodes& c, ResolvedBlock& b, ModalState& ns, std::uint8_t mask);
  bool reference_return(const BlockCodes& c, ResolvedBlock& b, ModalState& ns, std::uint8_t mask);
  bool coordinate_shift(const BlockCodes& c, ModalState& ns, std::uint8_t mask);
  void update_origin(ModalState& ns) const;
  bool set_offsets(const BlockCodes& c, ResolvedBlock& b, ModalState& ns, std::uint8_t mask);
  bool set_tool_entry(const BlockCodes& c, ResolvedBlock& b, ModalState& ns, std::uint8_t mask);
  void note_frame(const BlockCodes& c, ResolvedBlock& b, const ModalState& ns, std::uint8_t mask) const;

  // -- cutter.cpp
  bool comp_involved(const ModalState& ns) const {
    return ns.comp_side != 0 || st.comp_side != 0 || comp.pending || comp.off_path;
  }
  bool compensate(const ModalState& ns, bool& plain_emit);
  bool entry_move(const ModalState& ns, ResolvedBlock& b);
  bool next_move(const ModalState& ns, ResolvedBlock& b);
  bool offset_path(const ModalState& ns, const ResolvedBlock& b, parse_detail::OffsetMove& m);
  bool join(const ModalState& ns, parse_detail::OffsetMove& n, const ResolvedBlock& b);
  bool concave_corner(const ModalState& ns, parse_detail::OffsetMove& n);
  bool fanuc_corner(const ModalState& ns, ResolvedBlock& b, parse_detail::OffsetMove& n);
  void corner_moves(const ResolvedBlock& b, const std::vector<parse_detail::P2>& pts);
  void finish_pending(parse_detail::P2 end);
  bool leave_offset(ResolvedBlock& b, const ModalState& ns, bool& plain_emit);
  bool flush_compensation();

  // -- cycles.cpp
  bool cycle(const BlockCodes& c, ResolvedBlock& b, ModalState& ns, std::uint8_t mask);
  bool cycle_levels_of(ModalState& ns, parse_detail::CycleGeometry& g, const std::string& name, std::uint32_t col);
  bool cycle_words(ModalState& ns, parse_detail::CycleGeometry& g, const std::string& name, std::uint32_t col);
  void drill_holes(ResolvedBlock& b, ModalState& ns, parse_detail::CycleGeometry& g, std::uint8_t mask);
  bool cycle_size_ok(const ModalState& ns, const parse_detail::CycleGeometry& g, const std::string& name,
                     std::uint32_t col);
  void next_hole(const ModalState& ns, const parse_detail::CycleGeometry& g, std::uint8_t mask, const Axes& pos,
                 Axes& hole) const;

  // -- flow.cpp
  bool feed(std::string_view line, std::size_t overlong);
  bool finish();
  bool skip_after_alarm(std::uint64_t n);
  bool run_ready();
  bool step(parse_detail::Frame& f, const parse_detail::SourceLine& l);
  bool statement(parse_detail::Frame& f, const parse_detail::SourceLine& l, const parse_detail::Statement& s);
  bool statement_skipping(parse_detail::Frame& f, const parse_detail::SourceLine& l,
                          const parse_detail::Statement& s, bool& consumed);
  bool call(parse_detail::Frame& f, const parse_detail::SourceLine& l, const parse_detail::Statement& s,
            bool& waiting);
  bool do_return(std::size_t level);
  bool condition(const parse_detail::SourceLine& l, const parse_detail::Statement& s, double& v);
  bool loop_end(parse_detail::Frame& f, const parse_detail::SourceLine& l, const parse_detail::Statement& s);
  double enclosing_repeats() const;
  bool repeat_fits(const parse_detail::SourceLine& l, const parse_detail::Statement& s, double count);
  bool loop_open(parse_detail::Frame& f, const parse_detail::SourceLine& l, const parse_detail::Statement& s);
  bool next_pass(parse_detail::Frame& f, parse_detail::Control& ctl, const parse_detail::SourceLine& l,
                 const parse_detail::Statement& s);
  void skip_to_loop_end(parse_detail::Frame& f, const parse_detail::Statement& s, std::uint64_t from);
  bool flow_error(const parse_detail::SourceLine& l, std::uint32_t col, std::string msg);
  bool run_plain(const parse_detail::SourceLine& l, bool first_visit);
  void collect_definition(const parse_detail::SourceLine& l);
  void open_owner(std::uint64_t line);
  void note_program_end(ModalState& ns);
  void note_tape_marks(std::string_view line, std::uint64_t n);
  void stop_after_end();
  bool note_after_end(const parse_detail::SourceLine& l, bool first);
  bool collected_here(const std::string& label, std::uint64_t line) const;
  bool close_owner();
  bool note_skipped(const parse_detail::SourceLine& l, const parse_detail::Frame& f);
  void trim_window();
  bool abort_expansion();
  void unwind_expansion();
  const parse_detail::SourceLine* line_at(const parse_detail::Frame& f, std::uint64_t pc) const;
  bool idle() const;
  void note_macro_program(std::string_view line);
  bool fanuc_line_to_keep(std::string_view line) const;
  bool fanuc_subprogram_start(std::string_view line, std::string& label) const;
  bool fanuc_call(parse_detail::Frame& f, const parse_detail::SourceLine& l);
  bool try_pending_call(parse_detail::Frame& f);
  bool definition_may_follow() const;
  bool push_subprogram(const std::string& label, long repeats, std::uint64_t line);
  bool read_fanuc_call(const BlockCodes& c);
  bool macro_statement(parse_detail::Frame& f, const parse_detail::SourceLine& l, const parse_detail::Statement& s);
  bool go_to(parse_detail::Frame& f, const parse_detail::SourceLine& l, const parse_detail::Statement& s, long n);
};

namespace parse_detail {
/// Reads an o-word statement (`o100 while [...]`); false when the line is not one (a Fanuc
/// program number `O1234` is not). Blanks and case as LinuxCNC reads them.
bool read_statement(std::string_view line, Statement& s);
/// Reads a Fanuc Custom Macro B statement: WHILE [..] DO m, END m, IF [..] GOTO n,
/// IF [..] THEN ..., GOTO n (after an optional N number); mapped onto the o-word keywords
/// (while/endwhile with label "DO m") or goto / ifgoto / ifthen.
bool read_macro(std::string_view line, Statement& s);
/// The N number a line starts with, -1 if none.
long sequence_number(std::string_view line);
}  // namespace parse_detail

}  // namespace gcpipe
