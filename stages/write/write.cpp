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
// Everything the output relies on, said once after the tape start and program number.
constexpr const char* kHeader = "G17 G21 G40 G49 G54 G80 G90 G94\n";
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
      out += kHeader;
      header_done_ = true;
    }
    if (opt_.source_line_numbers && b.line > 0) line.integer('N', static_cast<long>(b.line));
  }
  const std::size_t bare = line.text.size();  // what the line holds before any word with meaning
  units_and_offset(b, line);
  path_control(b, line);
  tool_length_and_tcp(b, line);
  feed_mode_tool_spindle_coolant(b, line);
  if (!have_pos_) {
    // The position before the first block is the one the parser assumed (machine config); an axis
    // the program never commands is never written, so the output cannot move it either.
    for (int a = 0; a < kNumAxes; ++a) pos_[a] = b.start[a] - b.work_origin[a];
    have_pos_ = true;
  }
  motion(b, line);
  program_stop(b, line);
  // A block with nothing to say (blank, or a source-frame setting such as G20 or G91) keeps its
  // line, without an N, so that the output keeps the program's shape.
  if (line.text.size() == bare && b.program_number < 0) line.text.clear();
  append_comment(line.text, b.comment);
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
  out += kHeader;
  header_done_ = true;
  ResolvedBlock rest = b;
  rest.program_number = -1;
  rest.comment.clear();
  std::string tail;
  const bool ok = write(rest, tail);
  if (tail != "\n") out += tail;  // nothing else on the line: no empty line for it
  return ok;
}

void Writer::units_and_offset(const ResolvedBlock& b, Line& line) {
  if (line.inch != inch_) {
    line.word(line.inch ? "G20" : "G21");
    inch_ = line.inch;
  }
  if (b.work_offset != work_offset_) {
    static const char* const names[6] = {"G54", "G55", "G56", "G57", "G58", "G59"};
    line.word(names[std::clamp(b.work_offset - 54, 0, 5)]);
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
  if (opt_.dialect == Dialect::kLinuxCnc) {
    // Length and TCP are independent: G43 H / G49 for the length, M428 / M429 for the kinematics.
    if (b.tool_length_active != tlo_active_ || b.tool_length_offset != tlo_) {
      if (b.tool_length_active) {
        line.word("G43");
        line.integer('H', b.tool_length_offset);
      } else {
        line.word("G49");
      }
    }
    if (b.tcp != tcp_) line.word(b.tcp ? "M428" : "M429");
  } else if (b.tool_length_active != tlo_active_ || b.tool_length_offset != tlo_ || b.tcp != tcp_ ||
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
  line.number('X', line.len(t.end[0] - b.work_origin[kX]));
  line.number('Y', line.len(t.end[1] - b.work_origin[kY]));
  line.number('Z', line.len(t.bottom - b.work_origin[kZ]));
  line.number('R', line.len(t.clearance - b.work_origin[kZ]));
  line.number('W', line.len(t.width));
  line.number('K', line.len(t.step));
  if (t.depth_step > 0) line.number('Q', line.len(t.depth_step));
  line.number('D', line.len(t.tool_diameter));
  if (!t.climb) line.integer('P', -1);
  feed(b, line, true);
  // The cycle ends at the slot end on the clearance plane; the writer's position follows.
  for (int a = 0; a < kNumAxes; ++a) pos_[a] = b.target[a] - b.work_origin[a];
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

}  // namespace gcpipe
