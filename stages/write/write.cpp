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

bool Writer::write(const ResolvedBlock& b, std::string& out) {
  if (b.tool_vector_mode && opt_.dialect == Dialect::kLinuxCnc) {
    // LinuxCNC has no tool-vector TCP, and the writer knows no kinematics to turn I J K into A C:
    // say so in the output rather than drop the orientation and cut the part wrong.
    ++refused_;
    out += "(gcpipe: line " + std::to_string(b.line) +
           " not written: G43.5 tool-vector TCP has no LinuxCNC equivalent; run it through the "
           "IK stage for A C, or write with dialect fanuc)\n";
    return false;
  }
  std::string line;
  auto word = [&](const char* w) {
    if (!line.empty()) line.push_back(' ');
    line += w;
  };
  // Lengths go out in the block's source units: an inch program's arcs were checked against the
  // inch radius tolerance, which is looser than the metric one, and must stay valid when re-read.
  const bool inch = b.source_units == Units::kInch;
  // Division, not multiplication by 1/25.4: (v * 25.4) / 25.4 gives v back in most cases.
  auto len = [inch](double mm) { return inch ? mm / 25.4 : mm; };
  auto num = [&](char letter, double v) {
    // Below 0.1 nm a value is arithmetic noise (a sum that should cancel), not a dimension: write
    // 0 rather than 17 digits after a run of zeros. Within the 1e-9 round-trip tolerance.
    if (std::fabs(v) < 1e-10) v = 0;
    if (!line.empty()) line.push_back(' ');
    line.push_back(letter);
    if (opt_.decimals < 0) append_shortest(line, v);
    else append_fixed(line, v, opt_.decimals);
  };
  auto integer = [&](char letter, long v) {
    if (!line.empty()) line.push_back(' ');
    line.push_back(letter);
    line += std::to_string(v);
  };

  if (b.percent) {
    out += '%';
    out += b.comment;  // "%" lines keep their trailing text verbatim
    out += '\n';
    return true;
  }
  if (b.program_number >= 0 && !header_done_) {
    // The header (with its G80 and G94) must come before anything modal or moving on the
    // program-number line, or it would cancel it: the O number and its comment go alone, the
    // header follows, and the rest of the block, if it says anything, gets its own N line.
    integer('O', b.program_number);
    append_comment(line, b.comment);
    out += line;
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
  if (b.program_number >= 0) {
    integer('O', b.program_number);  // a program number line carries no N
  } else {
    if (!header_done_) {
      // Everything the output relies on, said once after the tape start and program number. The
      // writer's own state starts at these defaults, which are also the parser's.
      out += kHeader;
      header_done_ = true;
    }
    if (opt_.source_line_numbers && b.line > 0) integer('N', static_cast<long>(b.line));
  }
  const std::size_t bare = line.size();  // what the line holds before any word with meaning

  if (inch != inch_) {
    word(inch ? "G20" : "G21");
    inch_ = inch;
  }
  if (b.work_offset != work_offset_) {
    word(b.work_offset == 54 ? "G54" : b.work_offset == 55 ? "G55" : b.work_offset == 56 ? "G56"
         : b.work_offset == 57 ? "G57" : b.work_offset == 58 ? "G58" : "G59");
    work_offset_ = b.work_offset;
  }
  if (opt_.dialect == Dialect::kLinuxCnc) {
    // Length and TCP are independent: G43 H / G49 for the length, M428 / M429 for the kinematics.
    if (b.tool_length_active != tlo_active_ || b.tool_length_offset != tlo_) {
      if (b.tool_length_active) {
        word("G43");
        integer('H', b.tool_length_offset);
      } else {
        word("G49");
      }
    }
    if (b.tcp != tcp_) word(b.tcp ? "M428" : "M429");
  } else if (b.tool_length_active != tlo_active_ || b.tool_length_offset != tlo_ || b.tcp != tcp_ ||
             b.tool_vector_mode != tool_vector_mode_) {
    // One modal group: G43.4 H (TCP, H0 = no length), G43.5 H (TCP with a tool vector), G43 H
    // (length only), G49 (neither).
    if (b.tool_vector_mode) {
      word("G43.5");
      integer('H', b.tool_length_active ? b.tool_length_offset : 0);
      if (!tool_vector_mode_) tool_vector_written_ = false;  // the parser starts G43.5 without a vector
    } else if (b.tcp) {
      word("G43.4");
      integer('H', b.tool_length_active ? b.tool_length_offset : 0);
    } else if (b.tool_length_active) {
      word("G43");
      integer('H', b.tool_length_offset);
    } else {
      word("G49");
    }
  }
  tlo_active_ = b.tool_length_active;
  tlo_ = b.tool_length_offset;
  tcp_ = b.tcp;
  tool_vector_mode_ = b.tool_vector_mode;
  if (b.feed_mode != feed_mode_) {
    word(b.feed_mode == FeedMode::kInverseTime ? "G93" : "G94");
    feed_ = 0;  // the parser drops the feed on a mode switch: F means something else now
    feed_mode_ = b.feed_mode;
  }
  if (b.tool != tool_) {
    integer('T', b.tool);
    tool_ = b.tool;
  }
  if (b.tool_change) word("M6");
  if (b.spindle_speed != spindle_speed_) {
    num('S', b.spindle_speed);
    spindle_speed_ = b.spindle_speed;
  }
  if (b.spindle != spindle_) {
    word(b.spindle == Spindle::kCW ? "M3" : b.spindle == Spindle::kCCW ? "M4" : "M5");
    spindle_ = b.spindle;
  }
  if (b.coolant != coolant_) {
    // M9 first when a coolant goes off, then what stays on (the parser reads M9 M8 as "flood only").
    if ((coolant_ & ~b.coolant) != 0) word("M9");
    if (b.coolant & kCoolantMist) word("M7");
    if (b.coolant & kCoolantFlood) word("M8");
    coolant_ = b.coolant;
  }

  // Program coordinates: what the source wrote, in mm.
  Axes prog{};
  for (int a = 0; a < kNumAxes; ++a) prog[a] = b.target[a] - b.work_origin[a];
  if (!have_pos_) {
    // The position before the first block is the one the parser assumed (machine config); an axis
    // the program never commands is never written, so the output cannot move it either.
    for (int a = 0; a < kNumAxes; ++a) pos_[a] = b.start[a] - b.work_origin[a];
    have_pos_ = true;
  }
  auto axes = [&](std::uint8_t must) {
    for (int a = 0; a < kNumAxes; ++a) {
      if (prog[a] != pos_[a] || (must & (1u << a))) {
        num(kAxisLetters[a], a < kA ? len(prog[a]) : prog[a]);
        pos_[a] = prog[a];
      }
    }
  };
  auto motion_word = [&](Motion m, const char* text) {
    if (!have_motion_ || motion_ != m) {
      word(text);
      motion_ = m;
      have_motion_ = true;
    }
  };
  // F is modal state like any other: written when it changes, and on every feed move in G93,
  // where each block needs its own.
  auto feed = [&](bool always) {
    if (always || b.feed != feed_) {
      num('F', b.feed_mode == FeedMode::kInverseTime ? b.feed : len(b.feed));
      feed_ = b.feed;
    }
  };
  // G43.5 tool vector: written when it changed, on the first move after G43.5, and on a move
  // without axis words (there I J K are what makes it a move). Unit components, so the
  // shortest exact text (or 12 places): the coordinates' `decimals` would tilt the axis.
  auto tool_vector = [&] {
    if (!b.tool_vector_mode) return;
    if (tool_vector_written_ && b.tool_vector == tool_vector_ && b.axis_words != 0) return;
    for (int k = 0; k < 3; ++k) {
      double v = b.tool_vector[static_cast<std::size_t>(k)];
      if (std::fabs(v) < 1e-15) v = 0;
      if (!line.empty()) line.push_back(' ');
      line.push_back(static_cast<char>('I' + k));
      if (opt_.decimals < 0) append_shortest(line, v);
      else append_fixed(line, v, std::max(opt_.decimals, 12));
    }
    tool_vector_ = b.tool_vector;
    tool_vector_written_ = true;
  };
  const bool inverse = b.feed_mode == FeedMode::kInverseTime;
  switch (b.motion) {
    case Motion::kNone:
      feed(false);
      break;
    case Motion::kRapid:
      motion_word(Motion::kRapid, "G0");
      axes(b.axis_words);
      tool_vector();
      feed(false);
      break;
    case Motion::kLinear:
      motion_word(Motion::kLinear, "G1");
      axes(b.axis_words);
      tool_vector();
      feed(inverse);
      break;
    case Motion::kArcCW:
    case Motion::kArcCCW: {
      if (b.plane != plane_) {
        word(b.plane == Plane::kXY ? "G17" : b.plane == Plane::kZX ? "G18" : "G19");
        plane_ = b.plane;
      }
      motion_word(b.motion, b.motion == Motion::kArcCW ? "G2" : "G3");
      axes(b.axis_words);
      // Centre offsets from the start, in the plane's letters (G17: I J, G18: K I, G19: J K).
      const int u = b.plane == Plane::kXY ? kX : b.plane == Plane::kZX ? kZ : kY;
      const int v = b.plane == Plane::kXY ? kY : b.plane == Plane::kZX ? kX : kZ;
      const char lu = b.plane == Plane::kXY ? 'I' : b.plane == Plane::kZX ? 'K' : 'J';
      const char lv = b.plane == Plane::kXY ? 'J' : b.plane == Plane::kZX ? 'I' : 'K';
      num(lu, len(b.centre[static_cast<std::size_t>(u)] - b.start[u]));
      num(lv, len(b.centre[static_cast<std::size_t>(v)] - b.start[v]));
      if (b.turns != 1) integer('P', b.turns);
      feed(inverse);
      break;
    }
    case Motion::kDwell:
      word("G4");
      num(opt_.dialect == Dialect::kFanuc ? 'X' : 'P', b.dwell);
      feed(false);
      break;
    case Motion::kTrochoidSlot: {
      word("G275");
      const TrochoidSlot& t = b.slot;
      num('X', len(t.end[0] - b.work_origin[kX]));
      num('Y', len(t.end[1] - b.work_origin[kY]));
      num('Z', len(t.bottom - b.work_origin[kZ]));
      num('R', len(t.clearance - b.work_origin[kZ]));
      num('W', len(t.width));
      num('K', len(t.step));
      if (t.depth_step > 0) num('Q', len(t.depth_step));
      num('D', len(t.tool_diameter));
      if (!t.climb) integer('P', -1);
      feed(true);
      // The cycle ends at the slot end on the clearance plane; the writer's position follows.
      pos_ = prog;
      break;
    }
  }
  switch (b.stop) {
    case ProgramStop::kNone: break;
    case ProgramStop::kStop: word("M0"); break;
    case ProgramStop::kOptionalStop: word("M1"); break;
    case ProgramStop::kEnd: word("M2"); break;
    case ProgramStop::kEndRewind: word("M30"); break;
  }
  // A block with nothing to say (blank, or a source-frame setting such as G20 or G91) keeps its
  // line, without an N, so that the output keeps the program's shape.
  if (line.size() == bare && b.program_number < 0) line.clear();
  append_comment(line, b.comment);
  out += line;
  out += '\n';
  return true;
}

}  // namespace gcpipe
