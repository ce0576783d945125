// LinuxCNC o-word subroutines and flow control: sub/endsub/call/return, if/elseif/else/endif,
// while/endwhile, do/while, repeat/endrepeat, break, continue; numbered (o100) and named
// (o<name>) labels.
//
// How lines are kept (the only buffering in the parser):
//  - A plain program never stores a line: while no structure is open the line runs at once.
//  - Subroutine definitions are collected as their lines arrive (so a call may come before the
//    definition, as in LinuxCNC), and the main program passes over them without running them.
//  - Main-program lines are kept in `window` from the oldest open loop (to run again) or from a
//    call that waits for a definition further down; lines before that are dropped.
//  - All of it is bounded by parse.max_buffered_lines (an error past it), each loop by
//    parse.max_loop_passes, the lines run on behalf of one source line by 1000 times that, and
//    the call depth by max_call_depth: no input can hang or exhaust memory.
//
// Counting: each line is counted once, when the main program first runs it or passes over it.
// The newest line the main program has run is the "owner": the blocks and the first error of
// everything run on its behalf (a call's body, a loop's later passes) are its own. An error inside
// an expansion abandons that expansion (the call returns, the loop ends), as LinuxCNC would stop
// the program, and rejects the owner with the failing line's place in the diagnostic.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include "parse_internal.hpp"

namespace gcpipe {

using namespace parse_detail;

namespace parse_detail {

bool read_statement(std::string_view line, Statement& s) {
  std::size_t p = 0;
  skip_blanks(line, p);
  if (p >= line.size() || (line[p] | 0x20) != 'o') return false;
  s.col = static_cast<std::uint32_t>(p + 1);
  ++p;
  skip_blanks(line, p);
  s.label.clear();
  if (p < line.size() && line[p] == '<') {
    const std::size_t close = line.find('>', p);
    if (close == std::string_view::npos) return false;
    s.label = "<" + normalise_parameter_name(line.substr(p + 1, close - p - 1)) + ">";
    p = close + 1;
  } else {
    while (p < line.size() && ((line[p] >= '0' && line[p] <= '9') || line[p] == ' ' || line[p] == '\t'))
      if (line[p++] != ' ' && line[p - 1] != '\t') s.label.push_back(line[p - 1]);
    if (s.label.empty()) return false;
    s.label.erase(0, std::min(s.label.find_first_not_of('0'), s.label.size() - 1));  // o010 = o10
  }
  skip_blanks(line, p);
  s.keyword.clear();
  while (p < line.size() && (line[p] | 0x20) >= 'a' && (line[p] | 0x20) <= 'z')
    s.keyword.push_back(static_cast<char>(line[p++] | 0x20));
  s.rest = p;
  static const char* const words[] = {"sub", "endsub", "call", "return", "if", "elseif", "else", "endif",
                                      "while", "endwhile", "do", "repeat", "endrepeat", "break", "continue"};
  for (const char* w : words)
    if (s.keyword == w) return true;
  return false;
}

namespace {

bool keyword_at(std::string_view s, std::size_t& p, std::string_view kw) {
  std::size_t q = p;
  skip_blanks(s, q);
  if (s.size() - q < kw.size()) return false;
  for (std::size_t i = 0; i < kw.size(); ++i)
    if ((s[q + i] | 0x20) != kw[i]) return false;
  p = q + kw.size();
  return true;
}

bool whole_number(std::string_view s, std::size_t& p, long& v) {
  skip_blanks(s, p);
  int digits = 0;
  v = 0;
  while (p < s.size() && s[p] >= '0' && s[p] <= '9' && digits < 9) v = v * 10 + (s[p++] - '0'), ++digits;
  return digits > 0;
}

// Past the bracketed condition at p ('['), nesting counted.
bool skip_brackets(std::string_view s, std::size_t& p) {
  skip_blanks(s, p);
  if (p >= s.size() || s[p] != '[') return false;
  int depth = 0;
  for (; p < s.size(); ++p) {
    if (s[p] == '[') ++depth;
    if (s[p] == ']' && --depth == 0) {
      ++p;
      return true;
    }
  }
  return false;
}

}  // namespace

long sequence_number(std::string_view line) {
  std::size_t p = 0;
  skip_blanks(line, p);
  if (p >= line.size() || (line[p] | 0x20) != 'n') return -1;
  ++p;
  long v = 0;
  return whole_number(line, p, v) ? v : -1;
}

bool read_macro(std::string_view line, Statement& s) {
  std::size_t p = 0;
  skip_blanks(line, p);
  if (p < line.size() && (line[p] | 0x20) == 'n') {
    ++p;
    long n = 0;
    if (!whole_number(line, p, n)) return false;
  }
  skip_blanks(line, p);
  s.col = static_cast<std::uint32_t>(p + 1);
  long m = 0;
  if (keyword_at(line, p, "while")) {
    skip_blanks(line, p);
    s.rest = p;
    if (!skip_brackets(line, p) || !keyword_at(line, p, "do") || !whole_number(line, p, m)) return false;
    s.keyword = "while";
    s.label = "DO" + std::to_string(m);
    return true;
  }
  if (keyword_at(line, p, "end")) {
    if (!whole_number(line, p, m)) return false;
    s.keyword = "endwhile";
    s.label = "DO" + std::to_string(m);
    return true;
  }
  s.label.clear();
  if (keyword_at(line, p, "goto")) {
    s.keyword = "goto";
    s.target = p;
    return true;
  }
  if (!keyword_at(line, p, "if")) return false;
  skip_blanks(line, p);
  s.rest = p;
  if (!skip_brackets(line, p)) return false;
  if (keyword_at(line, p, "goto")) s.keyword = "ifgoto";
  else if (keyword_at(line, p, "then")) s.keyword = "ifthen";
  else return false;
  s.target = p;
  return true;
}

}  // namespace parse_detail

namespace {

// The hot path's test: an o-word statement starts with 'o' (read_statement says if it is one).
bool maybe_statement(std::string_view line) {
  std::size_t p = 0;
  skip_blanks(line, p);
  if (p >= line.size() || (line[p] | 0x20) != 'o') return false;
  Statement s;
  return read_statement(line, s);
}

std::string olabel(const std::string& label) {
  return label.empty() ? std::string("GOTO") : label[0] == 'O' || label[0] == 'D' ? label : "o" + label;
}

// Whether the line holds M<code> outside comments (M2, M02 and M002 alike): read at the time a
// line arrives, before it runs, to find Fanuc subprograms.
bool has_m_code(std::string_view line, int code) {
  for (std::size_t p = 0; p < line.size(); ++p) {
    const char c = line[p];
    if (c == '(') {
      const std::size_t close = line.find(')', p);
      if (close == std::string_view::npos) return false;
      p = close;
    } else if (c == ';') {
      return false;
    } else if ((c | 0x20) == 'm') {
      std::size_t q = p + 1;
      skip_blanks(line, q);
      int v = 0, digits = 0;
      while (q < line.size() && line[q] >= '0' && line[q] <= '9' && digits < 6) v = v * 10 + (line[q++] - '0'), ++digits;
      if (digits > 0 && v == code && (q >= line.size() || line[q] != '.')) return true;
    }
  }
  return false;
}

bool is_loop(Control::Kind k) { return k != Control::kIf; }

// A '%' tape marker: after the program end it is still written out (it moves nothing), so that the
// output keeps the tape's frame.
bool percent_line(std::string_view line) {
  std::size_t p = 0;
  skip_blanks(line, p);
  return p < line.size() && line[p] == '%';
}

// Whether the line holds anything but blanks and comments.
bool has_code(std::string_view line) {
  for (std::size_t p = 0; p < line.size(); ++p) {
    const char c = line[p];
    if (c == ';') return false;
    if (c == '(') {
      p = line.find(')', p);
      if (p == std::string_view::npos) return false;
    } else if (c != ' ' && c != '\t' && c != '\r') {
      return true;
    }
  }
  return false;
}

}  // namespace

// A Fanuc macro program (# variables, IF/GOTO/WHILE) keeps its lines: GOTO may jump back.
void Parser::Impl::note_macro_program(std::string_view line) {
  if (line.find('#') != std::string_view::npos) {
    macro_mode = true;
    return;
  }
  // Only IF, WHILE, END and GOTO start a macro statement: look no further on other lines.
  std::size_t p = 0;
  skip_blanks(line, p);
  if (p < line.size() && (line[p] | 0x20) == 'n') {
    ++p;
    while (p < line.size() && ((line[p] >= '0' && line[p] <= '9') || line[p] == ' ')) ++p;
  }
  if (p >= line.size()) return;
  const char c = static_cast<char>(line[p] | 0x20);
  const bool go = c == 'g' && p + 1 < line.size() && (line[p + 1] | 0x20) == 'o';
  Statement macro;
  if ((c == 'i' || c == 'w' || c == 'e' || go) && read_macro(line, macro)) macro_mode = true;
}

// A Fanuc line that starts a subprogram goes to collect_definition, not the hot path.
bool Parser::Impl::fanuc_line_to_keep(std::string_view line) const {
  if (opt.dialect != Dialect::kFanuc || !(st.ended || main_end_read)) return false;
  std::string label;
  return fanuc_subprogram_start(line, label);
}

bool Parser::Impl::idle() const {
  const Frame& f = frames[0];
  return frames.size() == 1 && f.controls.empty() && f.skip == Skip::kNone && window.empty() &&
         defining.empty() && owner.line == 0 && f.pending_call.empty() && !macro_mode;
}

// Fanuc: after the main program's M30/M2, a line `O2000` (or `:2000`) starts a subprogram that
// runs to its M99.
bool Parser::Impl::fanuc_subprogram_start(std::string_view line, std::string& label) const {
  if (opt.dialect != Dialect::kFanuc || !(st.ended || main_end_read)) return false;
  std::size_t p = 0;
  skip_blanks(line, p);
  if (p >= line.size() || ((line[p] | 0x20) != 'o' && line[p] != ':')) return false;
  ++p;
  skip_blanks(line, p);
  long v = 0;
  int digits = 0;
  while (p < line.size() && line[p] >= '0' && line[p] <= '9' && digits < 9) v = v * 10 + (line[p++] - '0'), ++digits;
  if (digits == 0) return false;
  skip_blanks(line, p);
  if (p < line.size() && line[p] != '(' && line[p] != ';') return false;  // an O number alone
  label = "O" + std::to_string(v);
  return true;
}

const SourceLine* Parser::Impl::line_at(const Frame& f, std::uint64_t pc) const {
  if (f.sub != nullptr) return pc < f.sub->body.size() ? &f.sub->body[pc] : nullptr;
  if (pc < window_first || pc - window_first >= window.size()) return nullptr;
  return &window[pc - window_first];
}

bool Parser::Impl::feed(std::string_view line, std::size_t overlong) {
  ++summary.lines_read;
  summary.bytes_read += (overlong ? overlong : line.size()) + 1;
  const std::uint64_t n = summary.lines_read;
  if (n == 1 && line.substr(0, 3) == "\xEF\xBB\xBF") line.remove_prefix(3);  // UTF-8 byte-order mark
  if (tape_close_line == 0) note_tape_marks(line, n);
  if (alarm_line != 0) return skip_after_alarm(n);
  if (opt.dialect == Dialect::kFanuc && !macro_mode) note_macro_program(line);
  if (idle() && end_line == 0 && frames[0].pc == n && !maybe_statement(line) && !fanuc_line_to_keep(line)) {
    // The hot path: nothing open, the line runs at once and is counted.
    open_owner(n);
    std::string why;
    std::uint32_t col = 0;
    const Outcome o = run_line(line, n, overlong, why, col);
    if (o == Outcome::kDeleted) {
      owner.line = 0;
      ++summary.lines_deleted;
      classified = n;
      frames[0].pc = n + 1;
      return emit_diagnostic(n, col, Severity::kNote, why);
    }
    if (o == Outcome::kRejected) {
      owner.error = true;
      emit_diagnostic(n, col, Severity::kError, why);
    }
    frames[0].pc = n + 1;
    if (o == Outcome::kBlocks && (fanuc.ret || !fanuc.label.empty())) {
      window_first = n + 1;
      fanuc_call(frames[0], SourceLine{std::string(line), n, overlong});
      if (!run_ready()) return false;
      trim_window();
      return !stopped;
    }
    return close_owner();
  }
  SourceLine l{std::string(line), n, overlong};
  collect_definition(l);
  if (window.empty()) window_first = n;
  window.push_back(std::move(l));
  if (!run_ready()) return false;
  trim_window();
  return !stopped;
}

// A '%' line before any code opens the tape; the first one after code closes it.
void Parser::Impl::note_tape_marks(std::string_view line, std::uint64_t n) {
  if (percent_line(line)) {
    if (code_read) tape_close_line = n;
    return;
  }
  code_read = code_read || has_code(line);
}

// Subroutine definitions are taken as their lines arrive, before the main program reaches them.
// LinuxCNC's ends at the tape's closing '%': rs274 searches no further for a definition ("Failed
// to find sub ... before EOF"), while Fanuc subprograms follow M30 and may follow a '%'.
void Parser::Impl::collect_definition(const SourceLine& l) {
  if (opt.dialect == Dialect::kLinuxCnc && tape_close_line != 0 && defining.empty()) return;
  std::string label;
  if (!defining.empty() && defining[0] == 'O') {  // a Fanuc subprogram runs to its M99
    Subroutine& sub = subs[defining];
    if (sub.body.size() < opt.max_buffered_lines) sub.body.push_back(l);
    if (has_m_code(l.text, 99)) {
      sub.end_line = l.number;
      defining.clear();
    }
    return;
  }
  if (fanuc_subprogram_start(l.text, label)) {
    if (subs.count(label) != 0) return;  // defined twice: the second is passed over as main code
    defining = label;
    subs[label].line = l.number;
    fanuc_starts[l.number] = label;
    return;
  }
  if (opt.dialect == Dialect::kFanuc && defining.empty() && (has_m_code(l.text, 30) || has_m_code(l.text, 2)))
    main_end_read = true;
  Statement s;
  const bool stmt = read_statement(l.text, s);
  if (!defining.empty()) {
    Subroutine& sub = subs[defining];
    if (stmt && s.keyword == "endsub" && s.label == defining) {
      sub.end_line = l.number;
      defining.clear();
    } else if (sub.body.size() < opt.max_buffered_lines) {
      sub.body.push_back(l);
    }
    return;
  }
  if (stmt && s.keyword == "sub" && subs.count(s.label) == 0) {
    defining = s.label;
    subs[s.label].line = l.number;
  }
}

void Parser::Impl::open_owner(std::uint64_t line) {
  owner = Owner{};
  owner.line = line;
}

// Counts the owner line once: rejected if anything on its behalf failed, else emitted.
bool Parser::Impl::close_owner() {
  if (owner.line == 0) return !stopped;
  if (owner.error) ++summary.lines_rejected;
  else ++summary.blocks_emitted;
  classified = owner.line;
  owner = Owner{};
  return !stopped;
}

// The program has ended (M2 or M30 inside a call or a loop too): the calls return and the loops
// close without running on, as the control stops there. Definitions keep being collected.
void Parser::Impl::stop_after_end() {
  while (frames.size() > 1) {
    frames.back().repeats = 1;
    do_return(frames.size() - 1);
  }
  Frame& m = frames[0];
  m.controls.clear();
  m.pending_call.clear();
  if (m.skip != Skip::kSubDefinition) m.skip = Skip::kNone;
}

// Whether the definition of `label` starts at this line (after a LinuxCNC tape's closing '%' none
// is collected: such a `sub` line is only a line after the end).
bool Parser::Impl::collected_here(const std::string& label, std::uint64_t line) const {
  const auto it = subs.find(label);
  return it != subs.end() && it->second.line == line;
}

// A line after the program end: read and accounted for, never run (rs274 stops reading there).
bool Parser::Impl::note_after_end(const SourceLine& l, bool first) {
  ++frames[0].pc;
  if (!first) return true;
  ++summary.lines_deleted;
  ++summary.lines_not_run;
  classified = l.number;
  return emit_diagnostic(l.number, 1, Severity::kNote,
                         std::string("not run: after the program end (") + end_word + " at line " +
                             std::to_string(end_line) + ")") || true;
}

bool Parser::Impl::note_skipped(const SourceLine& l, const Frame& f) {
  ++summary.lines_deleted;
  ++summary.lines_not_run;
  classified = l.number;
  std::string why;
  switch (f.skip) {
    case Skip::kSubDefinition:
      why = "not run here: part of the definition of subroutine " + olabel(f.skip_label) + " (it runs where it is called)";
      break;
    case Skip::kToLabel:
      why = "not run: jumped over by GOTO " + std::to_string(f.goto_target) + " (line " + std::to_string(f.skip_from) + ")";
      break;
    case Skip::kBranch: case Skip::kToEndif:
      why = "not run: in a branch of " + olabel(f.skip_label) + " if (line " + std::to_string(f.skip_from) + ") not taken";
      break;
    default:
      why = "not run: after the end of loop " + olabel(f.skip_label) + " (line " + std::to_string(f.skip_from) + ")";
      break;
  }
  return emit_diagnostic(l.number, 1, Severity::kNote, why);
}

// Runs what can run: stops at the end of the input read so far, or at a call that waits for its
// definition.
bool Parser::Impl::run_ready() {
  if (abort_requested) unwind_expansion();
  while (!stopped) {
    if (end_line != 0) stop_after_end();
    Frame& f = frames.back();
    if (!f.pending_call.empty()) {
      const bool ran = try_pending_call(f);
      if (abort_requested) unwind_expansion();
      if (!ran) break;  // the subprogram is further down: wait for it
      continue;
    }
    const SourceLine* l = line_at(f, f.pc);
    if (l == nullptr) {
      if (f.sub == nullptr) {
        close_owner();  // everything on the newest line's behalf has run
        break;          // wait for the next line
      }
      do_return(frames.size() - 1);  // the body ran off its end: endsub is implied
      continue;
    }
    if (f.sub == nullptr && l->number != owner.line && l->number > classified && !close_owner()) return false;
    const bool go_on = step(f, *l);  // `f` may be gone after this
    if (abort_requested) unwind_expansion();
    if (!go_on) break;  // waiting
  }
  return !stopped;
}

// One line of a frame. Returns false when the frame must wait for more input.
bool Parser::Impl::step(Frame& f, const SourceLine& l) {
  const bool first = f.sub == nullptr && l.number > classified && l.number != owner.line;
  if (f.sub == nullptr && (fanuc_starts.count(l.number) != 0 || (f.skip == Skip::kSubDefinition && f.skip_label[0] == 'O'))) {
    // A Fanuc subprogram met where it stands: passed over to its M99, as the definition.
    if (f.skip == Skip::kNone) {
      f.skip = Skip::kSubDefinition;
      f.skip_label = fanuc_starts[l.number];
      f.skip_from = l.number;
    }
    if (first && !note_skipped(l, f)) return true;
    if (subs[f.skip_label].end_line == l.number) f.skip = Skip::kNone;
    ++f.pc;
    return true;
  }
  Statement s;
  const bool stmt = read_statement(l.text, s);
  const bool macro = !stmt && opt.dialect == Dialect::kFanuc && read_macro(l.text, s);
  if (f.skip == Skip::kToLabel) {  // a forward GOTO: lines pass until the N number
    if (sequence_number(l.text) != f.goto_target) {
      if (first && !note_skipped(l, f)) return true;
      ++f.pc;
      return true;
    }
    f.skip = Skip::kNone;
  }
  if (f.skip != Skip::kNone) {
    bool consumed = false;
    if ((stmt || macro) && s.label == f.skip_label && !statement_skipping(f, l, s, consumed)) return true;
    if (!consumed) {
      if (first && !note_skipped(l, f)) return true;
      ++f.pc;
      return true;
    }
  }
  if (f.sub == nullptr && end_line != 0 && !(stmt && s.keyword == "sub" && collected_here(s.label, l.number)) &&
      !percent_line(l.text))
    return note_after_end(l, first);
  if (first) open_owner(l.number);
  // Lines run on behalf of one source line never return to the reader's per-line check of a
  // stop request: poll it here (every 4096 lines, well under a millisecond of work).
  if ((owner.steps & 0xfff) == 0) throw_if_stop_requested();
  if (++owner.steps > opt.max_loop_passes * 1000) {
    flow_error(l, 1, "more than " + std::to_string(opt.max_loop_passes * 1000) +
                         " lines run for one source line (nested loops or recursion): the expansion was stopped; "
                         "check the loop conditions or raise parse.max_loop_passes");
    return true;
  }
  if (macro && s.label.empty()) return macro_statement(f, l, s);
  if (!stmt && !macro) return run_plain(l, first);
  if (s.keyword == "sub" && f.sub == nullptr) {
    // A definition met where it stands: passed over, it ran when collected.
    owner = Owner{};
    f.skip = Skip::kSubDefinition;
    f.skip_label = s.label;
    f.skip_from = l.number;
    if (first && !note_skipped(l, f)) return true;
    ++f.pc;
    return true;
  }
  return statement(f, l, s);
}

// A line that is not a statement: scanned and resolved as usual.
bool Parser::Impl::run_plain(const SourceLine& l, bool first) {
  std::string why;
  std::uint32_t col = 0;
  const Outcome o = run_line(l.text, l.number, l.overlong, why, col);
  ++frames.back().pc;
  if (o == Outcome::kBlocks && (fanuc.ret || !fanuc.label.empty())) {
    fanuc_call(frames.back(), l);
  }
  if (o == Outcome::kDeleted) {
    if (first) {
      owner = Owner{};
      ++summary.lines_deleted;
      classified = l.number;
      return emit_diagnostic(l.number, col, Severity::kNote, why);
    }
    return true;
  }
  if (o == Outcome::kRejected) {
    if (first) {
      owner.error = true;
      emit_diagnostic(l.number, col, Severity::kError, why);
    } else {
      flow_error(l, col, why);
    }
  }
  return true;
}

// An error while running on the owner's behalf: reported with the failing line's place, the
// owner rejected, the expansion abandoned. On the owner's own first run it is a plain rejection.
bool Parser::Impl::flow_error(const SourceLine& l, std::uint32_t col, std::string msg) {
  const bool expansion = frames.size() > 1 || l.number != owner.line;
  if (owner.error) {
    abort_expansion();
    return false;
  }
  owner.error = true;
  if (expansion)
    msg += frames.size() > 1 ? " (in subroutine " + olabel(frames.back().label) + " called at line " +
                                   std::to_string(frames[1].call_line) + "; the call was abandoned)"
                             : " (on a later pass of the loop ending at line " + std::to_string(owner.line) +
                                   "; the loop was stopped)";
  emit_diagnostic(l.number, col, Severity::kError, msg);
  if (expansion) abort_expansion();
  return false;
}

// Asks run_ready to abandon the expansion once the statement at hand is done with its frame
// (unwinding here would pull frames and the program counter from under the caller).
bool Parser::Impl::abort_expansion() {
  abort_requested = true;
  return false;
}

// Unwinds every call, and stops the main-program loop whose end line is the owner.
void Parser::Impl::unwind_expansion() {
  abort_requested = false;
  while (frames.size() > 1) {
    frames.back().repeats = 1;
    do_return(frames.size() - 1);
  }
  Frame& m = frames[0];
  const SourceLine* end = line_at(m, owner.line);
  Statement s;
  if (end == nullptr || !(read_statement(end->text, s) || (opt.dialect == Dialect::kFanuc && read_macro(end->text, s))))
    return;
  if (s.keyword == "goto" || s.keyword == "ifgoto") {  // a GOTO back: go on after it
    m.skip = Skip::kNone;
    m.pc = owner.line + 1;
    return;
  }
  for (std::size_t i = m.controls.size(); i-- > 0;) {
    if (m.controls[i].label != s.label || !is_loop(m.controls[i].kind)) continue;
    m.controls.resize(i);
    m.skip = Skip::kNone;
    m.pc = owner.line + 1;
    return;
  }
}

bool Parser::Impl::condition(const SourceLine& l, const Statement& s, double& v) {
  std::string_view text = l.text;
  std::size_t p = s.rest;
  skip_blanks(text, p);
  if (p >= text.size() || text[p] != '[')
    return flow_error(l, static_cast<std::uint32_t>(p + 1), olabel(s.label) + " " + s.keyword + " needs a condition in brackets: [expression]");
  refresh_system_parameters();
  ExpressionReader er(params);
  if (!er.read_value(text, p, v)) return flow_error(l, static_cast<std::uint32_t>(er.error_pos() + 1), er.error());
  return true;
}

// A statement met while lines are being passed over; `consumed` when it ends the skip.
bool Parser::Impl::statement_skipping(Frame& f, const SourceLine& l, const Statement& s, bool& consumed) {
  const std::string& k = s.keyword;
  consumed = false;
  switch (f.skip) {
    case Skip::kBranch:
      if (k == "elseif" || k == "else" || k == "endif") consumed = true;
      break;
    case Skip::kToEndif: consumed = k == "endif"; break;
    case Skip::kToLoopEnd: consumed = k == "endwhile" || k == "endrepeat" || k == "while"; break;
    case Skip::kSubDefinition:
      if (k == "endsub") {
        const bool first = l.number > classified;
        if (first && !note_skipped(l, f)) return false;
        f.skip = Skip::kNone;
        ++f.pc;
        return false;
      }
      break;
    default: break;
  }
  return true;
}

bool Parser::Impl::statement(Frame& f, const SourceLine& l, const Statement& s) {
  const bool first = f.sub == nullptr && owner.line == l.number && !owner.blocks && !owner.error;
  const Skip was = f.skip;
  f.skip = Skip::kNone;
  const std::string& k = s.keyword;
  const std::uint64_t here = f.pc;
  bool ok = true;
  auto top = [&]() -> Control* { return f.controls.empty() ? nullptr : &f.controls.back(); };
  if (k == "if") {
    double v = 0;
    if (!condition(l, s, v)) v = 0;
    f.controls.push_back({Control::kIf, s.label, here, v != 0});
    if (v == 0) {
      f.skip = Skip::kBranch;
      f.skip_label = s.label;
      f.skip_from = l.number;
    }
    ++f.pc;
  } else if (k == "elseif" || k == "else") {
    Control* c = top();
    if (c == nullptr || c->kind != Control::kIf || c->label != s.label) {
      ok = flow_error(l, s.col, olabel(s.label) + " " + k + " without an open " + olabel(s.label) + " if");
      ++f.pc;
    } else if (was == Skip::kBranch && !c->taken) {
      double v = 1;
      if (k == "elseif" && !condition(l, s, v)) v = 0;
      c->taken = v != 0;
      if (v == 0) {
        f.skip = Skip::kBranch;
        f.skip_label = s.label;
      }
      ++f.pc;
    } else {
      f.skip = Skip::kToEndif;  // the branch that ran ends here
      f.skip_label = s.label;
      ++f.pc;
    }
  } else if (k == "endif") {
    Control* c = top();
    if (c == nullptr || c->kind != Control::kIf || c->label != s.label)
      ok = flow_error(l, s.col, olabel(s.label) + " endif without an open " + olabel(s.label) + " if");
    else
      f.controls.pop_back();
    ++f.pc;
  } else if (k == "while" || k == "endwhile" || k == "do" || k == "repeat" || k == "endrepeat" ||
             k == "break" || k == "continue") {
    if (was == Skip::kToLoopEnd) ++f.pc;  // the end of a loop that was left: go on after it
    else ok = loop_end(f, l, s);
  } else if (k == "call") {
    bool waiting = false;
    ok = call(f, l, s, waiting);
    if (waiting) return false;
  } else if (k == "return" || k == "endsub") {
    if (f.sub == nullptr) {
      ok = flow_error(l, s.col, olabel(s.label) + " " + k + " outside a subroutine");
      ++f.pc;
    } else {
      do_return(frames.size() - 1);
      return true;
    }
  } else {  // "sub" inside a subroutine body
    ok = flow_error(l, s.col, olabel(s.label) + " sub inside subroutine " + olabel(f.label) + ": definitions cannot nest");
    ++f.pc;
  }
  if (first && ok && !owner.error) {
    // The statement line itself: a block that moves nothing, so the output keeps the line.
    reset_block(l.text, l.number);
    publish(block);
    emit(block);
  }
  return true;
}

void Parser::Impl::skip_to_loop_end(Frame& f, const Statement& s, std::uint64_t from) {
  f.skip = Skip::kToLoopEnd;
  f.skip_label = s.label;
  f.skip_from = from;
}

// Counts a pass; past parse.max_loop_passes the loop is stopped with an error.
bool Parser::Impl::next_pass(Frame& f, Control& ctl, const SourceLine& l, const Statement& s) {
  if (++ctl.passes < opt.max_loop_passes) return true;
  const std::uint64_t start = ctl.start;
  f.controls.pop_back();
  ++f.pc;
  flow_error(l, s.col, "loop " + olabel(s.label) + " (from line " + std::to_string(start) + ") ran " +
                           std::to_string(opt.max_loop_passes) +
                           " passes and was stopped: check its condition, or raise parse.max_loop_passes");
  return false;
}

// The passes still to run of every repeat open around the line at hand (o-word repeats and
// M98 L counts, in every frame): a repeat opened here runs its count that many times over.
double Parser::Impl::enclosing_repeats() const {
  double product = 1;
  for (const Frame& fr : frames) {
    product *= static_cast<double>(std::max<long>(fr.repeats, 1));
    for (const Control& c : fr.controls)
      if (c.kind == Control::kRepeat) product *= static_cast<double>(std::max<std::int64_t>(c.remaining, 1));
  }
  return product;
}

// A repeat whose passes, times those of the repeats around it, pass the bound on lines run for
// one source line is refused before its first pass: otherwise 1000 x 1000 x 1000 nested repeats
// write a gigabyte of blocks before the bound stops them.
bool Parser::Impl::repeat_fits(const SourceLine& l, const Statement& s, double count) {
  const double around = enclosing_repeats();
  const double bound = static_cast<double>(opt.max_loop_passes) * 1000;
  if (std::floor(count) * around <= bound) return true;
  char n[160];
  std::snprintf(n, sizeof n, "%.0f passes (%.0f inside repeats that run %.0f times), more than 1000 x parse.max_loop_passes (%.0f)",
                std::floor(count) * around, std::floor(count), around, bound);
  flow_error(l, s.col, "repeat " + olabel(s.label) + " would run " + n +
                           ": it was not run; lower the counts or raise parse.max_loop_passes");
  return false;
}

// do / repeat / while, and the `while` that closes a do.
bool Parser::Impl::loop_open(Frame& f, const SourceLine& l, const Statement& s) {
  const std::string& k = s.keyword;
  const std::uint64_t here = f.pc;
  Control* c = f.controls.empty() ? nullptr : &f.controls.back();
  double v = 0;
  if (k == "do") {
    f.controls.push_back({Control::kDo, s.label, here});
  } else if (k == "repeat") {
    if (!condition(l, s, v)) v = 0;
    if (!repeat_fits(l, s, v)) v = 0;
    f.controls.push_back({Control::kRepeat, s.label, here, false, 0, static_cast<std::int64_t>(std::floor(v))});
    if (f.controls.back().remaining <= 0) {
      f.controls.pop_back();
      skip_to_loop_end(f, s, l.number);
    }
  } else if (c != nullptr && c->kind == Control::kDo && c->label == s.label) {
    if (!condition(l, s, v)) v = 0;
    if (v != 0 && next_pass(f, *c, l, s)) {
      f.pc = c->start + 1;
      return true;
    }
    if (!f.controls.empty() && f.controls.back().kind == Control::kDo && f.controls.back().label == s.label)
      f.controls.pop_back();
  } else {
    // A while met again from its endwhile tests its condition again; else a new loop opens.
    const bool again = c != nullptr && c->kind == Control::kWhile && c->label == s.label && c->start == here;
    if (!again) f.controls.push_back({Control::kWhile, s.label, here});
    if (!condition(l, s, v)) v = 0;
    if (v == 0) {
      f.controls.pop_back();
      skip_to_loop_end(f, s, l.number);
    }
  }
  f.pc = here + 1;
  return true;
}

// endwhile, endrepeat, break, continue: act on the innermost open loop of that label.
bool Parser::Impl::loop_end(Frame& f, const SourceLine& l, const Statement& s) {
  const std::string& k = s.keyword;
  if (k == "do" || k == "repeat" || k == "while") return loop_open(f, l, s);
  std::size_t i = f.controls.size();
  while (i-- > 0)
    if (f.controls[i].label == s.label && is_loop(f.controls[i].kind)) break;
  if (i == static_cast<std::size_t>(-1)) {
    ++f.pc;
    return flow_error(l, s.col, olabel(s.label) + " " + k + " without an open " + olabel(s.label) + " loop");
  }
  f.controls.resize(i + 1);
  Control& ctl = f.controls.back();
  if (k == "break") {
    f.controls.pop_back();
    skip_to_loop_end(f, s, l.number);
    ++f.pc;
    return true;
  }
  if (k == "endwhile" || (k == "continue" && ctl.kind == Control::kWhile)) {
    if (ctl.kind != Control::kWhile) {
      ++f.pc;
      return flow_error(l, s.col, olabel(s.label) + " endwhile closes a " + (ctl.kind == Control::kDo ? "do" : "repeat") + " loop");
    }
    if (next_pass(f, ctl, l, s)) f.pc = ctl.start;  // the while line tests the condition again
    return true;
  }
  // endrepeat, or continue in a do / repeat loop.
  if (ctl.kind == Control::kRepeat && --ctl.remaining <= 0) {
    f.controls.pop_back();
    if (k == "continue") skip_to_loop_end(f, s, l.number);
    ++f.pc;
    return true;
  }
  if (next_pass(f, ctl, l, s)) f.pc = ctl.start + 1;
  return true;
}

// o<name> call [arg] ...: #1..#30 take the arguments in the subroutine and are restored after,
// and the call has named parameters of its own (#<_name> stays global), as in LinuxCNC. A call to
// a subroutine defined further down waits for its definition, from the main program and from
// inside a subroutine alike: rs274 searches the file forward for it in both.
bool Parser::Impl::call(Frame& f, const SourceLine& l, const Statement& s, bool& waiting) {
  auto it = subs.find(s.label);
  if (it == subs.end() || it->second.end_line == 0) {
    if (definition_may_follow()) {
      waiting = true;
      return true;
    }
    ++f.pc;
    return flow_error(l, s.col, olabel(s.label) + " call: no subroutine " + olabel(s.label) +
                                    (input_done ? " is defined in this file"
                                                : " is defined within parse.max_buffered_lines lines after the call") +
                                    " (gcpipe does not search subroutine files): define it in the program");
  }
  if (frames.size() > static_cast<std::size_t>(opt.max_call_depth)) {
    ++f.pc;
    return flow_error(l, s.col, olabel(s.label) + " call: calls nested deeper than " +
                                    std::to_string(opt.max_call_depth) + " (runaway recursion?)");
  }
  std::array<double, 30> args{};
  std::string_view text = l.text;
  std::size_t p = s.rest;
  refresh_system_parameters();
  ExpressionReader er(params);
  for (std::size_t n = 0;; ++n) {
    skip_blanks(text, p);
    if (p >= text.size() || text[p] != '[') break;
    if (n == args.size()) {
      ++f.pc;
      return flow_error(l, static_cast<std::uint32_t>(p + 1), "more than 30 arguments in a call");
    }
    if (!er.read_value(text, p, args[n])) {
      ++f.pc;
      return flow_error(l, static_cast<std::uint32_t>(er.error_pos() + 1), er.error());
    }
  }
  ++f.pc;  // returns to the line after the call (before push_back: `f` may move)
  Frame callee;
  callee.sub = &it->second;
  callee.label = s.label;
  callee.call_line = l.number;
  for (int n = 0; n < 30; ++n) {
    params.get_numbered(n + 1, callee.saved_args[static_cast<std::size_t>(n)]);
    params.set_numbered(n + 1, args[static_cast<std::size_t>(n)]);
  }
  callee.local_scope = true;
  params.enter_call();  // after the arguments: they are read in the caller's scope
  frames.push_back(std::move(callee));
  return true;
}

bool Parser::Impl::do_return(std::size_t level) {
  Frame& f = frames[level];
  if (f.repeats > 1) {  // Fanuc M98 L: the body runs again
    --f.repeats;
    f.pc = 0;
    return true;
  }
  for (int n = 0; n < 30; ++n) params.set_numbered(n + 1, f.saved_args[static_cast<std::size_t>(n)]);
  if (f.local_scope) params.leave_call();
  if (f.autorestore) restore_modes(*f.autorestore, st);  // LinuxCNC M73: the caller's modes come back
  frames.pop_back();
  return true;
}

// Drops main-program lines nothing can come back to, and bounds what is kept.
void Parser::Impl::trim_window() {
  const Frame& m = frames[0];
  std::uint64_t keep = m.pc;
  for (const Control& c : m.controls)
    if (is_loop(c.kind)) keep = std::min(keep, c.start);
  if (owner.line != 0) keep = std::min(keep, owner.line);  // abort_expansion reads its statement
  // A macro program keeps half the buffer behind the line running, for GOTO back.
  if (macro_mode) keep = std::min(keep, m.pc > opt.max_buffered_lines / 2 ? m.pc - opt.max_buffered_lines / 2 : 0);
  while (!window.empty() && window_first < keep) {
    window.pop_front();
    ++window_first;
  }
  if (window.size() <= opt.max_buffered_lines) return;
  // Past the bound: the oldest open loop gives up repeating (its end will say so).
  Frame& mm = frames[0];
  for (std::size_t i = 0; i < mm.controls.size(); ++i) {
    if (!is_loop(mm.controls[i].kind)) continue;
    const SourceLine* start = line_at(mm, mm.controls[i].start);
    if (start != nullptr && owner.line != 0 && !owner.error) {
      owner.error = true;
      emit_diagnostic(start->number, 1, Severity::kError,
                      "loop " + olabel(mm.controls[i].label) + " is longer than parse.max_buffered_lines (" +
                          std::to_string(opt.max_buffered_lines) + " lines): it runs once; shorten it or raise the limit");
    }
    mm.controls.erase(mm.controls.begin() + static_cast<std::ptrdiff_t>(i));
    break;
  }
}

// Fanuc IF [..] GOTO n, IF [..] THEN #i = ..., GOTO n.
bool Parser::Impl::macro_statement(Frame& f, const SourceLine& l, const Statement& s) {
  const bool first = f.sub == nullptr && owner.line == l.number && !owner.blocks && !owner.error;
  double v = 1;
  const bool ok = s.keyword == "goto" || condition(l, s, v);
  if (s.keyword == "ifthen" && ok && v != 0) {
    // The statement after THEN runs as a line of its own, at its columns.
    std::string rest(l.text);
    for (std::size_t i = 0; i < s.target && i < rest.size(); ++i) rest[i] = ' ';
    return run_plain(SourceLine{rest, l.number, l.overlong}, first);
  }
  if (first && ok) {  // the statement line itself: a block that moves nothing
    reset_block(l.text, l.number);
    publish(block);
    emit(block);
  }
  if (!ok || v == 0 || s.keyword == "ifthen") {
    ++f.pc;
    return true;
  }
  std::size_t p = s.target;
  double n = 0;
  refresh_system_parameters();
  ExpressionReader er(params);
  skip_blanks(l.text, p);
  if (!er.read_value(l.text, p, n)) {
    ++f.pc;
    return flow_error(l, static_cast<std::uint32_t>(er.error_pos() + 1), er.error()) || true;
  }
  return go_to(f, l, s, std::lround(n));
}

// GOTO n: Fanuc looks forward from the block first, then from the program's start. Back is
// within the lines kept (half of parse.max_buffered_lines); forward waits for the line to come.
bool Parser::Impl::go_to(Frame& f, const SourceLine& l, const Statement& s, long n) {
  if (n < 1 || n > 99999) {
    ++f.pc;
    return flow_error(l, s.col, "GOTO " + std::to_string(n) + ": the target must be a sequence number N1..N99999") || true;
  }
  const std::uint64_t last = f.sub != nullptr ? f.sub->body.size() : window_first + window.size();
  const std::uint64_t begin = f.sub != nullptr ? 0 : window_first;
  for (std::uint64_t pass = 0; pass < 2; ++pass)
    for (std::uint64_t i = pass == 0 ? f.pc + 1 : begin; i < (pass == 0 ? last : f.pc + 1); ++i) {
      const SourceLine* t = line_at(f, i);
      if (t == nullptr || sequence_number(t->text) != n) continue;
      if (i <= f.pc && ++owner.jumps > opt.max_loop_passes) {
        ++f.pc;
        return flow_error(l, s.col, "GOTO " + std::to_string(n) + " jumped back " + std::to_string(opt.max_loop_passes) +
                                        " times and was stopped: check the IF condition, or raise parse.max_loop_passes") || true;
      }
      f.pc = i;
      return true;
    }
  ++f.pc;
  if (f.sub == nullptr && !input_done) {
    f.skip = Skip::kToLabel;
    f.goto_target = n;
    f.skip_from = l.number;
    return true;
  }
  return flow_error(l, s.col, "GOTO " + std::to_string(n) + ": no block N" + std::to_string(n) +
                                  (f.sub ? " in this subprogram" : " ahead, nor within the lines kept behind (half of parse.max_buffered_lines)")) || true;
}

// After a block with M98 or M99 has run (its other words first, as a Fanuc control does).
bool Parser::Impl::fanuc_call(Frame& f, const SourceLine& l) {
  if (fanuc.ret) {
    if (f.sub == nullptr)
      return flow_error(l, 1, "M99 in the main program would run it again without end: end the program with M30");
    do_return(frames.size() - 1);
    return true;
  }
  f.pending_call = fanuc.label;
  f.pending_repeats = fanuc.repeats;
  f.pending_line = l.number;
  return true;
}

// Whether a subroutine not defined yet may still come: input not done and room in the buffer.
// A call waits for it from any level (a subprogram may call one defined after itself, as Fanuc
// finds the O number anywhere in memory and rs274 searches forward); the lines read meanwhile
// are kept in the window until the call returns.
bool Parser::Impl::definition_may_follow() const {
  return !input_done && window.size() < opt.max_buffered_lines;
}

// The call waits while its subprogram may still come; else it runs or fails.
bool Parser::Impl::try_pending_call(Frame& f) {
  auto it = subs.find(f.pending_call);
  const bool defined = it != subs.end() && it->second.end_line != 0;
  if (!defined && definition_may_follow()) return false;
  const std::string label = f.pending_call;
  const long repeats = f.pending_repeats;
  const std::uint64_t line = f.pending_line;
  f.pending_call.clear();
  const SourceLine at{std::string(), line, 0};
  if (!defined)
    return flow_error(at, 1, "M98: subprogram " + label + " is not defined in this file" +
                                 (input_done ? "" : " within parse.max_buffered_lines lines") +
                                 " (gcpipe reads one file): add it after M30, ending with M99") || true;
  if (frames.size() > static_cast<std::size_t>(opt.max_call_depth))
    return flow_error(at, 1, "M98 P" + label.substr(1) + ": calls nested deeper than " +
                                 std::to_string(opt.max_call_depth) + " (runaway recursion?)") || true;
  return push_subprogram(label, repeats, line);
}

bool Parser::Impl::push_subprogram(const std::string& label, long repeats, std::uint64_t line) {
  Frame callee;
  callee.sub = &subs[label];
  callee.label = label;
  callee.call_line = line;
  callee.repeats = repeats;
  for (int n = 0; n < 30; ++n) params.get_numbered(n + 1, callee.saved_args[static_cast<std::size_t>(n)]);
  frames.push_back(std::move(callee));
  return true;
}

// After a #3000 alarm the control has stopped: every later line is passed over, with a note.
bool Parser::Impl::skip_after_alarm(std::uint64_t n) {
  ++summary.lines_deleted;
  ++summary.lines_not_run;
  classified = n;
  frames[0].pc = n + 1;
  return emit_diagnostic(n, 1, Severity::kNote,
                         std::string("not run: the program stopped at the ") +
                             (opt.dialect == Dialect::kFanuc ? "macro alarm (#3000)" : "(abort, ...)") + " of line " +
                             std::to_string(alarm_line));
}

bool Parser::Impl::finish() {
  input_done = true;
  run_ready();
  flush_compensation();  // a move still held (no G40 or program end) ends at its offset end
  close_owner();
  Frame& m = frames[0];
  if (alarm_line != 0) {  // the program stopped at an alarm: what it left open never ran on
    m.controls.clear();
    m.skip = Skip::kNone;
  }
  // What never closed: reported on its opening line, which is counted as rejected instead.
  auto unclosed = [&](std::uint64_t line, const std::string& what, bool was_skipped) {
    if (was_skipped) --summary.lines_deleted, --summary.lines_not_run;
    else --summary.blocks_emitted;
    ++summary.lines_rejected;
    emit_diagnostic(line, 1, Severity::kError, what);
  };
  if (m.skip == Skip::kToLabel)
    unclosed(m.skip_from, "GOTO " + std::to_string(m.goto_target) + ": no block N" + std::to_string(m.goto_target) +
                              " follows it in the program", false);
  if (m.skip == Skip::kSubDefinition)
    unclosed(m.skip_from, olabel(m.skip_label) + " sub has no " + olabel(m.skip_label) + " endsub before the end of the program", true);
  // A loop whose condition failed at once is passed over to its end, with no control open.
  const bool loop_open = std::any_of(m.controls.begin(), m.controls.end(),
                                     [&](const Control& c) { return c.label == m.skip_label; });
  if (m.skip == Skip::kToLoopEnd && !loop_open)
    unclosed(m.skip_from, olabel(m.skip_label) + " loop has no end before the end of the program", false);
  for (const Control& c : m.controls)
    unclosed(c.start, olabel(c.label) + (c.kind == Control::kIf ? " if has no endif" : " loop has no end") +
                          " before the end of the program", false);
  m.controls.clear();
  window.clear();
  return !stopped;
}

}  // namespace gcpipe
