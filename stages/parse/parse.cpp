// ISO 6983 parser: the public Parser and one line's life.
//
// Order of work for one line, chosen so that a rejected line leaves no trace:
//   1. scan the line into words (letter, value, column) and assignments, checking the syntax;
//   2. copy the modal state and resolve the block against the copy, checking the semantics;
//   3. only when everything is valid, commit the copy and the parameter assignments;
//   4. publish the modal state into the block (or into each move of an expansion) and emit it.
// Flow control (flow.cpp) decides which lines run and counts each line once; a plain program
// never buffers a line. The hot path (plain words with literal numbers) allocates nothing once
// the block's strings have grown to the longest line.
#include "parse.hpp"

#include <cmath>

#include "gcpipe/config.hpp"
#include "parse_internal.hpp"

namespace gcpipe {

using namespace parse_detail;

ParseOptions load_parse_options(const Config& c) {
  c.reject_unknown({"dialect", "decimal_point_rule", "block_delete", "strict", "max_line_length", "units",
                    "arc_centres", "max_buffered_lines", "max_loop_passes", "max_cycle_moves",
                    "min_feed", "boring_shift", "ignore_arc_normal_word"});
  ParseOptions o;
  o.dialect = c.choice("dialect", "fanuc", {"fanuc", "linuxcnc"}) == "fanuc" ? Dialect::kFanuc
                                                                               : Dialect::kLinuxCnc;
  o.decimal_point_increments = c.boolean("decimal_point_rule", false);
  o.block_delete = c.boolean("block_delete", true);
  o.strict = c.boolean("strict", false);
  o.max_line_length = static_cast<std::size_t>(c.integer("max_line_length", 256, 16, static_cast<std::int64_t>(kLargestLineLength)));
  o.initial_units = c.choice("units", "mm", {"mm", "inch"}) == "mm" ? Units::kMillimetre : Units::kInch;
  o.absolute_arc_centres = c.choice("arc_centres", "incremental", {"incremental", "absolute"}) == "absolute";
  o.ignore_arc_normal_word = c.boolean("ignore_arc_normal_word", false);
  o.max_buffered_lines = static_cast<std::size_t>(c.integer("max_buffered_lines", 200000, 100, 10000000));
  o.max_loop_passes = static_cast<std::uint64_t>(c.integer("max_loop_passes", 100000, 1, 100000000));
  o.max_cycle_moves = static_cast<std::uint64_t>(c.integer("max_cycle_moves", 1000000, 1000, 100000000));
  o.min_feed = c.number("min_feed", 1.0, "mm/min", 0.0, 1e6);
  const std::string shift = c.choice("boring_shift", "+first", {"+first", "-first", "+second", "-second"});
  o.boring_shift = shift == "+first" ? 0 : shift == "-first" ? 1 : shift == "+second" ? 2 : 3;
  return o;
}

Parser::Impl::Impl(ParseOptions o, MachineConfig m, std::string f)
    : opt(o), machine(std::move(m)), file(std::move(f)) {
  st.units = opt.initial_units;
  st.arc_incremental = !opt.absolute_arc_centres;
  // rs274 starts in R-plane retract (its output shows it); a Fanuc control powers up in G98.
  st.cycle_to_r = opt.dialect == Dialect::kLinuxCnc;
  offsets = machine.work_offsets;
  if (opt.dialect == Dialect::kFanuc) params.enable_vacancy();  // Macro B: #0 and unset variables are vacant
  else params.set_numbered(5599, 1);  // LinuxCNC: (DEBUG,) messages are shown until #5599 = 0
  st.work_origin = machine.work_offsets[0];
  st.origin = st.work_origin;
  for (int a = 0; a < kNumAxes; ++a) st.position[a] = machine.initial_position[a] + st.origin[a];
  frames.emplace_back();
  frames[0].pc = 1;
}

void Parser::Impl::reset_block(std::string_view line, std::uint64_t lineno) {
  ResolvedBlock& b = block;
  b.line = lineno;
  b.text.assign(line.data(), line.size());
  b.comment.clear();
  b.motion = Motion::kNone;
  b.axis_words = 0;
  b.turns = 1;
  b.radius = 0;
  b.dwell = 0;
  b.tool_change = false;
  b.stop = ProgramStop::kNone;
  b.percent = false;
  b.program_number = -1;
  b.frame = SourceFrame{};
  exact_stop_once = false;
  dwell_first = -1;
  warning.clear();
}

// Runs one line; its blocks go to the sink. A rejected or skipped line says why in `why`/`col`.
Parser::Impl::Outcome Parser::Impl::run_line(std::string_view line, std::uint64_t lineno, std::size_t overlong,
                                             std::string& why, std::uint32_t& col) {
  if (overlong > 0 || line.size() > opt.max_line_length) {
    col = static_cast<std::uint32_t>(opt.max_line_length + 1);
    why = "line is " + std::to_string(overlong ? overlong : line.size()) + " bytes long; the limit is " +
          std::to_string(opt.max_line_length) + " (parse.max_line_length in the pipeline config)";
    // A file whose lines end in CR alone (classic Mac) reads as one long line: say that, not only
    // the length, which sends the user to the wrong key.
    if (line.find('\r') != std::string_view::npos)
      why += "; the lines end in CR only (classic Mac line ends): convert them to LF, e.g. tr '\\r' '\\n' < IN > OUT";
    return Outcome::kRejected;
  }
  std::size_t p = 0;
  skip_blanks(line, p);
  const bool slash = p < line.size() && line[p] == '/';
  if (slash && opt.block_delete) {
    col = static_cast<std::uint32_t>(p + 1);
    why = "skipped by block delete ('/' with parse.block_delete on)";
    return Outcome::kDeleted;
  }
  reset_block(line, lineno);
  std::string_view body = line;
  std::string blanked;
  if (slash) {  // block delete off: read the block as if '/' were a blank
    blanked.assign(line);
    blanked[p] = ' ';
    body = blanked;
  }
  moves.clear();
  ModalState ns = st;
  if (!scan(body, block) || !resolve(block, ns)) {
    moves.clear();
    why = error;
    col = error_col;
    return Outcome::kRejected;
  }
  block.percent = sc.percent;
  block.program_number = sc.program_number;
  publish(block, ns);  // before commit: compensation holds complete blocks
  bool plain_emit = true;
  const bool compensated = comp_involved(ns);
  if (compensated && !compensate(ns, plain_emit)) {
    moves.clear();
    comp_out.clear();
    why = error;
    col = error_col;
    return Outcome::kRejected;
  }
  commit(ns);
  emit_warning(lineno);
  if (compensated) hand_out_compensated();
  if (!plain_emit) return Outcome::kBlocks;
  if (dwell_first >= 0) emit_dwell_first();
  if (moves.empty()) emit(block);
  else emit_moves();
  return Outcome::kBlocks;
}

// The line was valid under compensation: its state becomes the compensation's, and the moves it
// completed go out.
void Parser::Impl::hand_out_compensated() {
  comp = std::move(comp_next);
  for (const ResolvedBlock& b : comp_out)
    if (!hand_out(b)) break;
  comp_out.clear();
}

void Parser::Impl::commit(ModalState& ns) {
  note_program_end(ns);
  st = ns;
  for (int i = 0; i < sc.nassign; ++i) {
    const Assignment& a = sc.assign[i];
    if (a.named) params.set_named(a.name, a.value);
    else if (a.vacant) params.set_vacant(a.number);
    else params.set_numbered(a.number, a.value);
  }
}

// M2, M30, or the '%' that closes the tape (note_tape_marks): the program ends at the first of
// them, as rs274 reads a file that starts with '%'.
void Parser::Impl::note_program_end(ModalState& ns) {
  const bool stop = block.stop == ProgramStop::kEnd || block.stop == ProgramStop::kEndRewind;
  const bool closing_percent = sc.percent && tape_close_line != 0 && block.line >= tape_close_line;
  if (!stop && !closing_percent) return;
  ns.ended = true;
  if (end_line != 0) return;  // a '%' after M30 closes the tape of a program already ended
  end_line = block.line;
  end_word = closing_percent ? "%" : block.stop == ProgramStop::kEnd ? "M2" : "M30";
}

// The modal state in force after the line, into its block.
void Parser::Impl::publish(ResolvedBlock& b, const ModalState& s) const {
  b.plane = b.motion == Motion::kArcCW || b.motion == Motion::kArcCCW ? b.plane : s.plane;
  b.feed = s.feed;
  b.feed_mode = s.feed_mode;
  b.spindle_speed = s.spindle_speed;
  // A G09 block is a G61 block (no tolerance: it stops); the modes in force go on after it.
  b.path_tolerance = exact_stop_once ? 0 : s.path_tolerance;
  b.path_mode = exact_stop_once ? PathMode::kExactStop : s.path_mode;
  b.spindle = s.spindle;
  b.tool = s.tool;
  b.tool_in_spindle = s.tool_in_spindle;
  b.tool_length_offset = s.tlo_h;
  b.tool_length = s.tool_length;
  b.tool_length_active = s.tlo_active;
  b.tcp = s.tcp;
  b.tool_vector_mode = s.tool_vector_mode;
  b.tool_vector = s.tool_vector;
  b.coolant = s.coolant;
  b.work_offset = s.work_offset;
  b.work_origin = s.work_origin;
  b.frame.origin = s.origin;
  b.source_units = s.units;
  if (b.motion != Motion::kArcCW && b.motion != Motion::kArcCCW) b.centre = {0, 0, 0};
  if (b.motion != Motion::kTrochoidSlot) b.slot = TrochoidSlot{};
}

// A block in program order: behind a move that compensation holds, if there is one.
bool Parser::Impl::emit(const ResolvedBlock& b) {
  if (comp.pending) {
    comp.held.push_back(b);
    owner.blocks = true;
    return !stopped;
  }
  if (comp.off_path && b.motion == Motion::kNone) {  // after G40: it stands where the tool is
    expanded = b;
    expanded.start[kX] = expanded.target[kX] = comp.at.x;
    expanded.start[kY] = expanded.target[kY] = comp.at.y;
    return hand_out(expanded);
  }
  return hand_out(b);
}

bool Parser::Impl::hand_out(const ResolvedBlock& b) {
  ++summary.blocks_out;
  owner.blocks = true;
  if (stopped) return false;
  if (!sink->block(b)) stopped = true;
  return !stopped;
}

// An expansion: each move a plain block carrying the source line; the line's comment, tool
// change and M codes go with the first move, a program stop with the last.
bool Parser::Impl::emit_moves() {
  Axes from = block.start;
  for (std::size_t i = 0; i < moves.size(); ++i) {
    const Move& m = moves[i];
    expanded = block;
    if (i > 0) {
      expanded.comment.clear();
      expanded.tool_change = false;
      expanded.frame.selects_work_offset = expanded.frame.sets_tool_length = false;  // said with the first
    }
    if (i + 1 < moves.size()) expanded.stop = ProgramStop::kNone;
    // A G28/G30 moves through its intermediate point first: that move is said by the G28 itself.
    const FrameCode fc = expanded.frame.code;
    expanded.frame.intermediate = (fc == FrameCode::kHome || fc == FrameCode::kHome2) && i + 1 < moves.size();
    expanded.motion = m.motion;
    expanded.start = from;
    expanded.target = m.target;
    expanded.dwell = m.dwell;
    expanded.centre = {0, 0, 0};
    expanded.axis_words = 0;
    for (int a = 0; a < kNumAxes; ++a)
      if (m.target[a] != from[a]) expanded.axis_words = static_cast<std::uint8_t>(expanded.axis_words | (1u << a));
    if (m.spindle >= 0) expanded.spindle = static_cast<Spindle>(m.spindle);
    if (m.feed >= 0) expanded.feed = m.feed;
    if (m.stop) expanded.stop = ProgramStop::kStop;
    from = m.target;
    if (!emit(expanded)) return false;
  }
  moves.clear();
  return true;
}

// A LinuxCNC block with G4 and a move: the dwell first, as a block of its own carrying the line,
// with what rs274 also does before its dwell (comment, tool change, spindle, coolant); the
// move after it carries only the motion and a program stop.
bool Parser::Impl::emit_dwell_first() {
  expanded = block;
  expanded.motion = Motion::kDwell;
  expanded.dwell = dwell_first;
  expanded.target = block.start;
  expanded.axis_words = 0;
  expanded.centre = {0, 0, 0};
  expanded.stop = ProgramStop::kNone;
  block.comment.clear();
  block.tool_change = false;
  block.frame.selects_work_offset = block.frame.sets_tool_length = false;  // said with the dwell
  return emit(expanded);
}

// The accepted line's warning, before its blocks; a rejected line says only its error.
bool Parser::Impl::emit_warning(std::uint64_t line) {
  if (warning.empty()) return true;
  warned_tools.insert(warning_tool);
  return emit_diagnostic(line, warning_col, Severity::kWarning, std::move(warning));
}

bool Parser::Impl::emit_diagnostic(std::uint64_t line, std::uint32_t col, Severity sev, std::string msg) {
  Diagnostic d;
  d.file = file;
  d.line = line;
  d.column = col;
  d.severity = sev;
  d.message = std::move(msg);
  if (stopped) return false;
  if (!sink->diagnostic(d)) stopped = true;
  return !stopped;
}

Parser::Parser(ParseOptions options, MachineConfig machine, std::string file)
    : impl_(std::make_unique<Impl>(options, std::move(machine), std::move(file))) {}
Parser::~Parser() = default;
Parser::Parser(Parser&&) noexcept = default;
Parser& Parser::operator=(Parser&&) noexcept = default;

const ParseSummary& Parser::summary() const { return impl_->summary; }
const ParseOptions& Parser::options() const { return impl_->opt; }
bool Parser::ended() const { return impl_->st.ended; }

bool Parser::feed(std::string_view line, const ParseSink& sink, std::size_t overlong_length) {
  impl_->sink = &sink;
  return impl_->feed(line, overlong_length);
}

bool Parser::feed(std::string_view line, LineOutput& out, std::size_t overlong_length) {
  out.blocks.clear();
  out.diagnostics.clear();
  const ParseSink sink{[&](const ResolvedBlock& b) { out.blocks.push_back(b); return true; },
                       [&](const Diagnostic& d) { out.diagnostics.push_back(d); return true; }};
  return feed(line, sink, overlong_length);
}

bool Parser::finish(LineOutput& out) {
  out.blocks.clear();
  out.diagnostics.clear();
  const ParseSink sink{[&](const ResolvedBlock& b) { out.blocks.push_back(b); return true; },
                       [&](const Diagnostic& d) { out.diagnostics.push_back(d); return true; }};
  return finish(sink);
}

bool feed_text(Parser& parser, std::string_view text, const ParseSink& sink) {
  for (std::size_t begin = 0; begin < text.size();) {
    std::size_t end = std::min(text.find('\n', begin), text.size());
    std::string_view line = text.substr(begin, end - begin);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (!parser.feed(line, sink)) return false;
    begin = end + 1;
  }
  return parser.finish(sink);
}

bool Parser::finish(const ParseSink& sink) {
  impl_->sink = &sink;
  return impl_->finish();
}

}  // namespace gcpipe
