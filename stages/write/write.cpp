#include "write.hpp"

#include <algorithm>
#include <cmath>

#include "gcpipe/config.hpp"
#include "gcpipe/number_format.hpp"

namespace gcpipe {

WriteOptions load_write_options(const Config& c) {
  c.reject_unknown({"decimals", "dialect", "source_line_numbers"});
  WriteOptions o;
  o.decimals = static_cast<int>(c.integer("decimals", -1, -1, 9));
  o.dialect = c.choice("dialect", "fanuc", {"fanuc", "linuxcnc"}) == "fanuc" ? Dialect::kFanuc
                                                                               : Dialect::kLinuxCnc;
  o.source_line_numbers = c.boolean("source_line_numbers", true);
  return o;
}

namespace {

// A comment that reads back to the same text: parentheses cannot nest in G-code comments, so a
// comment that contains them (it came from a ';' comment) is written with ';'.
void append_comment(std::string& out, const std::string& c) {
  if (c.empty()) return;
  if (!out.empty() && out.back() != ' ') out.push_back(' ');
  if (c.find_first_of("()") != std::string::npos) {
    out += "; ";
    out += c;
  } else {
    out.push_back('(');
    out += c;
    out.push_back(')');
  }
}

}  // namespace

Writer::Writer(WriteOptions options) : opt_(options) {}

void Writer::write_diagnostic(const Diagnostic& d, std::string& out) {
  // Kept within the parser's default 256-byte line limit; the full text is in diagnostics.txt.
  constexpr std::size_t kMaxComment = 250;
  std::string c = "(gcpipe: line " + std::to_string(d.line) + (d.severity == Severity::kError ? " rejected: " : ": ");
  for (char ch : d.message) c.push_back(ch == '(' ? '[' : ch == ')' ? ']' : ch);
  if (c.size() > kMaxComment) {
    c.resize(kMaxComment - 3);
    c += "...";
  }
  out += c;
  out += ")\n";
}

namespace {
// Everything the output relies on, said once after the tape start and program number: the modes
// its own words are written in (plane, units, distance, feed mode) and what the parser has
// already resolved (cutter compensation: G40, canned cycles: G80).
// With the source's frames, the work system and the tool length are the source's to state: a G54
// or G49 the source did not program would replace the control's own (the system a previous
// program left selected, a length in force) and move the part elsewhere.
constexpr const char* kHeader = "G17 G21 G40 G49 G54 G80 G90 G94\n";
constexpr const char* kSourceFramesHeader = "G17 G21 G40 G80 G90 G94\n";
}  // namespace

// One output line being built: words separated by blanks, numbers in the chosen format.
struct Writer::Line {
  std::string text;
  const WriteOptions& opt;
  bool inch;
  explicit Line(const WriteOptions& o, bool in) : opt(o), inch(in) {}
  void word(const char* w) {
    if (!text.empty()) text.push_back(' ');
    text += w;
  }
  void number(char letter, double v) {
    // Below 0.1 nm a value is arithmetic noise (a sum that should cancel), not a dimension: write
    // 0 rather than 17 digits after a run of zeros. Within the 1e-9 round-trip tolerance.
    if (std::fabs(v) < 1e-10) v = 0;
    if (!text.empty()) text.push_back(' ');
    text.push_back(letter);
    if (opt.decimals < 0) append_shortest(text, v);
    else append_fixed(text, v, opt.decimals);
  }
  void integer(char letter, long v) {
    if (!text.empty()) text.push_back(' ');
    text.push_back(letter);
    text += std::to_string(v);
  }
  // Lengths go out in the block's source units. Division, not multiplication by 1/25.4:
  // (v * 25.4) / 25.4 gives v back in most cases.
  double len(double mm) const { return inch ? mm / 25.4 : mm; }
};

bool Writer::write(const ResolvedBlock& b, std::string& out) {
  if (b.tool_vector_mode && opt_.dialect == Dialect::kLinuxCnc) return refuse(b, out);
  if (b.percent) {
    out += '%';
    out += b.comment;  // "%" lines keep their trailing text verbatim
    out += '\n';
    return true;
  }
  if (b.program_number >= 0 && !header_done_) return write_program_start(b, out);
  // Lengths go out in the block's source units: an inch program's arcs were checked against the
  // inch radius tolerance, which is looser than the metric one, and must stay valid when re-read.
  Line line(opt_, b.source_units == Units::kInch);
  if (b.program_number >= 0) {
    line.integer('O', b.program_number);  // a program number line carries no N
  } else {
    if (!header_done_) {
      // The writer's own state starts at the header's defaults, which are also the parser's.
      out += opt_.source_frames ? kSourceFramesHeader : kHeader;
      header_done_ = true;
    }
    if (opt_.source_line_numbers && b.line > 0) line.integer('N', static_cast<long>(b.line));
  }
  const std::size_t bare = line.text.size();  // what the line holds before any word with meaning
  // Back to G90 where the source is (after a G91 G28 Z0, say), so the output ends as it does.
  if (opt_.source_frames && incremental_ && !b.frame.incremental) distance(false, line);
  units_and_offset(b, line);
  path_control(b, line);
  tool_length_and_tcp(b, line);
  feed_mode_tool_spindle_coolant(b, line);
  if (!have_pos_) {
    // The position before the first block is the one the parser assumed (machine config); an axis
    // the program never commands is never written, so the output cannot move it either.
    for (int a = 0; a < kNumAxes; ++a) pos_[a] = b.start[a] - origin_of(b)[a];
    have_pos_ = true;
  }
  if (opt_.source_frames && b.frame.code != FrameCode::kNone) frame_statement(b, line);
  else motion(b, line);
  program_stop(b, line);
  // A block with nothing to say (blank, or a source-frame setting such as G20 or G91) keeps its
  // line, without an N, so that the output keeps the program's shape.
  if (line.text.size() == bare && b.program_number < 0) line.text.clear();
  append_comment(line.text, b.comment);
  out += note_;
  note_.clear();
  out += line.text;
  out += '\n';
  return true;
}

// LinuxCNC has no tool-vector TCP, and the writer knows no kinematics to turn I J K into A C:
// say so in the output rather than drop the orientation and cut the part wrong.
bool Writer::refuse(const ResolvedBlock& b, std::string& out) {
  ++refused_;
  out += "(gcpipe: line " + std::to_string(b.line) +
         " not written: G43.5 tool-vector TCP has no LinuxCNC equivalent; run it through the "
         "IK stage for A C, or write with dialect fanuc)\n";
  return false;
}

// The header (with its G80 and G94) must come before anything modal or moving on the
// program-number line, or it would cancel it: the O number and its comment go alone, the header
// follows, and the rest of the block, if it says anything, gets its own N line.
bool Writer::write_program_start(const ResolvedBlock& b, std::string& out) {
  Line line(opt_, false);
  line.integer('O', b.program_number);
  append_comment(line.text, b.comment);
  out += line.text;
  out += '\n';
  out += opt_.source_frames ? kSourceFramesHeader : kHeader;
  header_done_ = true;
  ResolvedBlock rest = b;
  rest.program_number = -1;
  rest.comment.clear();
  std::string tail;
  const bool ok = write(rest, tail);
  if (tail != "\n") out += tail;  // nothing else on the line: no empty line for it
  return ok;
}

namespace {
const char* work_system_name(std::int32_t work_offset) {
  static const char* const names[6] = {"G54", "G55", "G56", "G57", "G58", "G59"};
  return names[std::clamp(work_offset - 54, 0, 5)];
}
}  // namespace

void Writer::units_and_offset(const ResolvedBlock& b, Line& line) {
  if (line.inch != inch_) {
    line.word(line.inch ? "G20" : "G21");
    inch_ = line.inch;
  }
  if (opt_.source_frames) return work_offset(b, line);
  if (b.work_offset != work_offset_) {
    line.word(work_system_name(b.work_offset));
    work_offset_ = b.work_offset;
  }
}

// G64 [P] / G61 / G61.1 when they change: the control that runs the output blends (or stops) as
// the source asked, and a G64 P is the path tolerance the compensation planned to.
void Writer::path_control(const ResolvedBlock& b, Line& line) {
  if (b.path_mode == path_mode_ && b.path_tolerance == path_tolerance_) return;
  if (b.path_mode == PathMode::kExactStop) line.word("G61");
  else if (b.path_mode == PathMode::kExactPath) line.word("G61.1");
  else {
    line.word("G64");
    if (b.path_tolerance > 0) line.number('P', line.len(b.path_tolerance));
  }
  path_mode_ = b.path_mode;
  path_tolerance_ = b.path_tolerance;
}

void Writer::tool_length_and_tcp(const ResolvedBlock& b, Line& line) {
  // With the source's frames a G43 H / G49 goes out wherever the source has one: a G43 H1 again
  // reloads a length a G10 has changed, and a first G49 cancels the control's own length.
  const bool programmed = opt_.source_frames && b.frame.sets_tool_length;
  // The control keeps the machine position when the length changes, so Z reads anew (its table's
  // length, not the machine file's): a G91 Z after it is an increment from there.
  if (programmed || b.tool_length_active != tlo_active_ || b.tool_length != tlo_length_) known_ &= ~(1u << kZ);
  tlo_length_ = b.tool_length;
  if (opt_.dialect == Dialect::kLinuxCnc) {
    // Length and TCP are independent: G43 H / G49 for the length, M428 / M429 for the kinematics.
    if (programmed || b.tool_length_active != tlo_active_ || b.tool_length_offset != tlo_) {
      if (b.tool_length_active) {
        line.word("G43");
        line.integer('H', b.tool_length_offset);
      } else {
        line.word("G49");
      }
    }
    if (b.tcp != tcp_) line.word(b.tcp ? "M428" : "M429");
  } else if (programmed || b.tool_length_active != tlo_active_ || b.tool_length_offset != tlo_ || b.tcp != tcp_ ||
             b.tool_vector_mode != tool_vector_mode_) {
    // One modal group: G43.4 H (TCP, H0 = no length), G43.5 H (TCP with a tool vector), G43 H
    // (length only), G49 (neither).
    if (b.tool_vector_mode) {
      line.word("G43.5");
      line.integer('H', b.tool_length_active ? b.tool_length_offset : 0);
      if (!tool_vector_mode_) tool_vector_written_ = false;  // the parser starts G43.5 without a vector
    } else if (b.tcp) {
      line.word("G43.4");
      line.integer('H', b.tool_length_active ? b.tool_length_offset : 0);
    } else if (b.tool_length_active) {
      line.word("G43");
      line.integer('H', b.tool_length_offset);
    } else {
      line.word("G49");
    }
  }
  tlo_active_ = b.tool_length_active;
  tlo_ = b.tool_length_offset;
  tcp_ = b.tcp;
  tool_vector_mode_ = b.tool_vector_mode;
}

void Writer::feed_mode_tool_spindle_coolant(const ResolvedBlock& b, Line& line) {
  if (b.feed_mode != feed_mode_) {
    line.word(b.feed_mode == FeedMode::kInverseTime ? "G93" : "G94");
    feed_ = 0;  // the parser drops the feed on a mode switch: F means something else now
    feed_mode_ = b.feed_mode;
  }
  if (b.tool != tool_) {
    line.integer('T', b.tool);
    tool_ = b.tool;
  }
  if (b.tool_change) line.word("M6");
  if (b.spindle_speed != spindle_speed_) {
    line.number('S', b.spindle_speed);
    spindle_speed_ = b.spindle_speed;
  }
  if (b.spindle != spindle_) {
    line.word(b.spindle == Spindle::kCW ? "M3" : b.spindle == Spindle::kCCW ? "M4" : "M5");
    spindle_ = b.spindle;
  }
  if (b.coolant != coolant_) {
    // M9 first when a coolant goes off, then what stays on (the parser reads M9 M8 as "flood only").
    if ((coolant_ & ~b.coolant) != 0) line.word("M9");
    if (b.coolant & kCoolantMist) line.word("M7");
    if (b.coolant & kCoolantFlood) line.word("M8");
    coolant_ = b.coolant;
  }
}

// Axis words that changed (program coordinates: what the source wrote, in mm) and the ones the
// block must carry.
void Writer::axes(const ResolvedBlock& b, Line& line, std::uint8_t must) {
  if (opt_.source_frames) {
    const std::uint8_t write = axes_to_write(b, must);
    if (write == 0) return;
    // A G91 move of an axis whose position only the control knows is the increment it was.
    const bool increments = b.frame.incremental && (write & ~known_) != 0;
    distance(increments, line);
    const Axes& origin = origin_of(b);
    for (int a = 0; a < kNumAxes; ++a) {
      if (!(write & (1u << a))) continue;
      const double v = increments ? b.target[a] - b.start[a] : b.target[a] - origin[a];
      line.number(kAxisLetters[a], a < kA ? line.len(v) : v);
      pos_[a] = b.target[a] - origin[a];
    }
    if (!increments) known_ |= write;
    return;
  }
  for (int a = 0; a < kNumAxes; ++a) {
    const double prog = b.target[a] - b.work_origin[a];
    if (prog != pos_[a] || (must & (1u << a))) {
      line.number(kAxisLetters[a], a < kA ? line.len(prog) : prog);
      pos_[a] = prog;
    }
  }
}

void Writer::motion_word(Motion m, const char* text, Line& line) {
  if (!have_motion_ || motion_ != m) {
    line.word(text);
    motion_ = m;
    have_motion_ = true;
  }
}

// F is modal state like any other: written when it changes, and on every feed move in G93,
// where each block needs its own.
void Writer::feed(const ResolvedBlock& b, Line& line, bool always) {
  if (always || b.feed != feed_) {
    line.number('F', b.feed_mode == FeedMode::kInverseTime ? b.feed : line.len(b.feed));
    feed_ = b.feed;
  }
}

// G43.5 tool vector: written when it changed, on the first move after G43.5, and on a move
// without axis words (there I J K are what makes it a move). Unit components, so the shortest
// exact text (or 12 places): the coordinates' `decimals` would tilt the axis.
void Writer::tool_vector(const ResolvedBlock& b, Line& line) {
  if (!b.tool_vector_mode) return;
  if (tool_vector_written_ && b.tool_vector == tool_vector_ && b.axis_words != 0) return;
  for (int k = 0; k < 3; ++k) {
    double v = b.tool_vector[static_cast<std::size_t>(k)];
    if (std::fabs(v) < 1e-15) v = 0;
    if (!line.text.empty()) line.text.push_back(' ');
    line.text.push_back(static_cast<char>('I' + k));
    if (opt_.decimals < 0) append_shortest(line.text, v);
    else append_fixed(line.text, v, std::max(opt_.decimals, 12));
  }
  tool_vector_ = b.tool_vector;
  tool_vector_written_ = true;
}

void Writer::arc(const ResolvedBlock& b, Line& line) {
  if (b.plane != plane_) {
    line.word(b.plane == Plane::kXY ? "G17" : b.plane == Plane::kZX ? "G18" : "G19");
    plane_ = b.plane;
  }
  motion_word(b.motion, b.motion == Motion::kArcCW ? "G2" : "G3", line);
  axes(b, line, b.axis_words);
  // Centre offsets from the start, in the plane's letters (G17: I J, G18: K I, G19: J K).
  const int u = b.plane == Plane::kXY ? kX : b.plane == Plane::kZX ? kZ : kY;
  const int v = b.plane == Plane::kXY ? kY : b.plane == Plane::kZX ? kX : kZ;
  const char lu = b.plane == Plane::kXY ? 'I' : b.plane == Plane::kZX ? 'K' : 'J';
  const char lv = b.plane == Plane::kXY ? 'J' : b.plane == Plane::kZX ? 'I' : 'K';
  line.number(lu, line.len(b.centre[static_cast<std::size_t>(u)] - b.start[u]));
  line.number(lv, line.len(b.centre[static_cast<std::size_t>(v)] - b.start[v]));
  if (b.turns != 1) line.integer('P', b.turns);
  feed(b, line, b.feed_mode == FeedMode::kInverseTime);
}

void Writer::slot(const ResolvedBlock& b, Line& line) {
  line.word("G275");
  const TrochoidSlot& t = b.slot;
  const Axes& origin = origin_of(b);
  distance(false, line);
  line.number('X', line.len(t.end[0] - origin[kX]));
  line.number('Y', line.len(t.end[1] - origin[kY]));
  line.number('Z', line.len(t.bottom - origin[kZ]));
  line.number('R', line.len(t.clearance - origin[kZ]));
  line.number('W', line.len(t.width));
  line.number('K', line.len(t.step));
  if (t.depth_step > 0) line.number('Q', line.len(t.depth_step));
  line.number('D', line.len(t.tool_diameter));
  if (!t.climb) line.integer('P', -1);
  feed(b, line, true);
  // The cycle ends at the slot end on the clearance plane; the writer's position follows.
  for (int a = 0; a < kNumAxes; ++a) pos_[a] = b.target[a] - origin[a];
  known_ |= (1u << kX) | (1u << kY) | (1u << kZ);
}

void Writer::motion(const ResolvedBlock& b, Line& line) {
  const bool inverse = b.feed_mode == FeedMode::kInverseTime;
  switch (b.motion) {
    case Motion::kNone: return feed(b, line, false);
    case Motion::kRapid:
    case Motion::kLinear:
      motion_word(b.motion, b.motion == Motion::kRapid ? "G0" : "G1", line);
      axes(b, line, b.axis_words);
      tool_vector(b, line);
      return feed(b, line, b.motion == Motion::kLinear && inverse);
    case Motion::kArcCW:
    case Motion::kArcCCW: return arc(b, line);
    case Motion::kDwell:
      line.word("G4");
      line.number(opt_.dialect == Dialect::kFanuc ? 'X' : 'P', b.dwell);
      return feed(b, line, false);
    case Motion::kTrochoidSlot: return slot(b, line);
  }
}

void Writer::program_stop(const ResolvedBlock& b, Line& line) {
  switch (b.stop) {
    case ProgramStop::kNone: break;
    case ProgramStop::kStop: line.word("M0"); break;
    case ProgramStop::kOptionalStop: line.word("M1"); break;
    case ProgramStop::kEnd: line.word("M2"); break;
    case ProgramStop::kEndRewind: line.word("M30"); break;
  }
}

// ---- Source frames (WriteOptions::source_frames) ----

// Program coordinates are measured from the origin the source has in force (its G10 and G92
// included) or, for compensated.nc, from the machine file's G5x origin.
const Axes& Writer::origin_of(const ResolvedBlock& b) const {
  return opt_.source_frames ? b.frame.origin : b.work_origin;
}

// G54..G59 where the source selects one (or, should the parser change it on its own, where it
// changes): before it, the output runs in whatever system the control has selected, as the source.
void Writer::work_offset(const ResolvedBlock& b, Line& line) {
  if (b.work_offset == work_offset_ && !(b.frame.selects_work_offset && !work_offset_written_)) return;
  line.word(work_system_name(b.work_offset));
  work_offset_ = b.work_offset;
  work_offset_written_ = true;
  known_ = 0;  // the control's position reads anew in that system's origin (its own values)
}

// G90 / G91 when a line needs the other: the output is absolute but for increments from a
// position only the control knows, and the G28/G30 and Fanuc G10 words the source gave in G91.
void Writer::distance(bool incremental, Line& line) {
  if (incremental == incremental_) return;
  line.word(incremental ? "G91" : "G90");
  incremental_ = incremental;
}

// The axes a move states: those the source programmed and those that move (an expansion, cutter
// compensation). An axis that moves in neither sense stays where the control has it: a change of
// origin alone (G55, G92) must not become a move to where the parser's frame would put it.
std::uint8_t Writer::axes_to_write(const ResolvedBlock& b, std::uint8_t must) const {
  std::uint8_t write = must;
  for (int a = 0; a < kNumAxes; ++a)
    if (b.target[a] != b.start[a]) write = static_cast<std::uint8_t>(write | (1u << a));
  return write;
}

// The words of a frame statement as the source wrote them, in the block's units.
void Writer::statement_words(const ResolvedBlock& b, const Axes& values, Line& line) {
  for (int a = 0; a < kNumAxes; ++a)
    if (b.frame.words & (1u << a)) line.number(kAxisLetters[a], a < kA ? line.len(values[a]) : values[a]);
}

void Writer::frame_statement(const ResolvedBlock& b, Line& line) {
  switch (b.frame.code) {
    case FrameCode::kHome:
    case FrameCode::kHome2: reference_return(b, line); break;
    case FrameCode::kMachine: machine_move(b, line); break;
    case FrameCode::kSetOrigin:
    case FrameCode::kSetOriginHere: set_origin(b, line); break;
    case FrameCode::kShift:
      distance(false, line);
      line.word("G92");
      statement_words(b, b.frame.values, line);
      known_ |= b.frame.words;  // the position reads as the words, on the control as here
      break;
    case FrameCode::kShiftClear: line.word("G92.1"); break;
    case FrameCode::kShiftSuspend: line.word("G92.2"); break;
    case FrameCode::kShiftRestore: line.word("G92.3"); break;
    case FrameCode::kLocalShift:
      distance(false, line);
      line.word("G52");
      statement_words(b, b.frame.values, line);
      break;
    case FrameCode::kToolTable:
    case FrameCode::kToolTableHere:
    case FrameCode::kToolLength:
    case FrameCode::kToolRadius: tool_entry(b, line); break;
    case FrameCode::kNone: break;
  }
  if (b.motion == Motion::kNone) feed(b, line, false);
  for (int a = 0; a < kNumAxes; ++a) pos_[a] = b.target[a] - origin_of(b)[a];
}

// G28/G30 once, on the block that reaches the reference position, with the intermediate point as
// the source gave it (G91 increments stay increments): the control goes to its own reference
// position, which the machine file's only stands for.
void Writer::reference_return(const ResolvedBlock& b, Line& line) {
  if (b.motion == Motion::kNone || b.frame.intermediate) return;  // Fanuc G28 alone moves nothing
  const char* code = b.frame.code == FrameCode::kHome ? "G28" : "G30";
  const bool every_axis = b.frame.words == 0;  // LinuxCNC: all axes, no intermediate point
  if (every_axis && opt_.dialect == Dialect::kFanuc) {
    // Fanuc's G28 without words moves nothing: the same return, through where the tool stands.
    distance(true, line);
    line.word(code);
    for (int a = 0; a < kNumAxes; ++a) line.number(kAxisLetters[a], 0);
  } else {
    if (!every_axis) distance(b.frame.incremental, line);
    line.word(code);
    statement_words(b, b.frame.values, line);
  }
  known_ &= static_cast<std::uint8_t>(~(every_axis ? 0x1Fu : b.frame.words));
}

// G53 with its machine coordinates. LinuxCNC moves in the G0 or G1 in force; Fanuc's G53 is
// always a rapid, so a G1 G53 cannot be said there: it goes out as a move in the program's
// coordinates of the machine file, with a note.
void Writer::machine_move(const ResolvedBlock& b, Line& line) {
  if (b.motion == Motion::kNone) return feed(b, line, false);
  if (opt_.dialect == Dialect::kFanuc && b.motion == Motion::kLinear) {
    note_ += "(gcpipe: line " + std::to_string(b.line) +
             ": G1 G53 has no Fanuc equivalent, its G53 is a rapid: written in program coordinates of the machine file)\n";
    return motion(b, line);
  }
  distance(false, line);
  line.word("G53");
  motion_word(b.motion, b.motion == Motion::kRapid ? "G0" : "G1", line);
  for (int a = 0; a < kNumAxes; ++a)
    if (b.frame.words & (1u << a)) line.number(kAxisLetters[a], a < kA ? line.len(b.target[a]) : b.target[a]);
  feed(b, line, b.motion == Motion::kLinear && b.feed_mode == FeedMode::kInverseTime);
  known_ &= static_cast<std::uint8_t>(~b.frame.words);
}

// G10 L2 / L20 in place. Where the output dialect cannot say what the source said (Fanuc has no
// L20 nor P0; LinuxCNC adds no G91 words to an offset), the system's origin as the parser resolved
// it is written instead, with a note: that one holds for the machine file only.
void Writer::set_origin(const ResolvedBlock& b, Line& line) {
  const bool fanuc = opt_.dialect == Dialect::kFanuc;
  const bool here = b.frame.code == FrameCode::kSetOriginHere;
  const std::int32_t in_force = b.work_offset - 53;
  const bool resolved = fanuc ? (here || b.frame.p == 0) : b.frame.incremental;
  if (resolved) {
    note_ += "(gcpipe: line " + std::to_string(b.line) + ": " + (here ? "G10 L20" : b.frame.p == 0 ? "G10 L2 P0" : "G91 G10 L2") +
             " cannot be said in this dialect: written as the origin the machine file gives)\n";
    distance(false, line);
    line.word("G10 L2");
    line.integer('P', b.frame.p == 0 ? in_force : b.frame.p);
    // resolved holds machine coordinates of the origin: the words of G10 L2 are exactly those
    statement_words(b, b.frame.resolved, line);
  } else {
    distance(b.frame.incremental, line);
    line.word(here ? "G10 L20" : "G10 L2");
    line.integer('P', b.frame.p);
    statement_words(b, b.frame.values, line);
  }
  // A new origin for the system in force: the control's position reads anew there (its own
  // values); with L20 it reads as the words, as it does here.
  const bool active = b.frame.p == 0 || b.frame.p == in_force || !work_offset_written_;
  if (!active) return;
  if (here && !resolved) known_ |= b.frame.words;
  else known_ &= static_cast<std::uint8_t>(~b.frame.words);
}

// G10 tool entries in place: the G43 H after them must load the program's value, not the
// control's table. Across dialects, the entry's value as the parser resolved it.
void Writer::tool_entry(const ResolvedBlock& b, Line& line) {
  const bool fanuc_out = opt_.dialect == Dialect::kFanuc;
  const FrameCode code = b.frame.code;
  const bool fanuc_in = code == FrameCode::kToolLength || code == FrameCode::kToolRadius;
  const double length = b.frame.resolved[kZ], radius = b.frame.resolved[kX];
  const bool sets_length = code == FrameCode::kToolLength || (b.frame.words & (1u << kZ));
  const bool sets_radius = code == FrameCode::kToolRadius || (!fanuc_in && b.frame.has_r);
  auto entry = [&](Line& l, const char* what, char letter, double v) {
    l.word(what);
    l.integer('P', b.frame.p);
    l.number(letter, l.len(v));
  };
  if (fanuc_out == fanuc_in) {
    distance(b.frame.incremental, line);
    line.word(code == FrameCode::kToolTable ? "G10 L1" : code == FrameCode::kToolRadius ? "G10 L12" : "G10 L10");
    line.integer('P', b.frame.p);
    if (b.frame.words & (1u << kZ)) line.number('Z', line.len(b.frame.values[kZ]));
    if (b.frame.has_r) line.number('R', line.len(b.frame.r));
    return;
  }
  if (code == FrameCode::kToolTableHere || b.frame.incremental)
    note_ += "(gcpipe: line " + std::to_string(b.line) +
             ": this tool entry cannot be said in this dialect: written as the value the machine file gives)\n";
  if (fanuc_out) {
    // Fanuc sets one value a G10: the radius, if both, on a line of its own before.
    if (sets_length && sets_radius) {
      Line extra(opt_, line.inch);
      entry(extra, "G10 L12", 'R', radius);
      note_ += extra.text + "\n";
    }
    if (sets_length) entry(line, "G10 L10", 'R', length);
    else entry(line, "G10 L12", 'R', radius);
    return;
  }
  distance(false, line);
  line.word("G10 L1");
  line.integer('P', b.frame.p);
  if (sets_length) line.number('Z', line.len(length));
  if (sets_radius) line.number('R', line.len(radius));
}

}  // namespace gcpipe
