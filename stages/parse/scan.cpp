// Scanner: one line into words (letter, value, column), G and M codes, comments and parameter
// assignments, with every syntax error at its column. The hot path (plain words with literal
// numbers) allocates nothing; expressions and parameters take the slow path.
#include <charconv>
#include <cmath>
#include <cstring>

#include "gcpipe/number_format.hpp"
#include "parse_internal.hpp"

namespace gcpipe {

namespace parse_detail {

std::string code_text(char letter, int code) {
  std::string s(1, letter);
  s += std::to_string(code / 10);
  if (code % 10) s += "." + std::to_string(code % 10);
  return s;
}

// A value as a message shows it: shortest exact digits, no forced point ("I2", "X0.001").
std::string show(double v) {
  std::string s;
  append_json_number(s, v);
  return s;
}

PlaneAxes plane_axes(Plane p) {
  switch (p) {
    case Plane::kXY: return {kX, kY, kZ, 'I', 'J'};
    case Plane::kZX: return {kZ, kX, kY, 'K', 'I'};
    case Plane::kYZ: return {kY, kZ, kX, 'J', 'K'};
  }
  return {kX, kY, kZ, 'I', 'J'};
}

}  // namespace parse_detail

using namespace parse_detail;

namespace {

// Letters that are words in this dialect. B, U, V, E, L and the others are rejected by name.
constexpr bool is_word_letter(char c) {
  switch (c) {
    case 'A': case 'C': case 'D': case 'F': case 'G': case 'H': case 'I': case 'J': case 'K':
    case 'L': case 'M': case 'N': case 'P': case 'Q': case 'R': case 'S': case 'T': case 'W': case 'X':
    case 'Y': case 'Z':
      return true;
    default:
      return false;
  }
}


void add_comment(std::string& comment, std::string_view text) {
  // Trim so that "( text )" and "(text)" read back the same after a write.
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t')) text.remove_suffix(1);
  if (text.empty()) return;
  if (!comment.empty()) comment += " | ";
  comment.append(text);
}


// What a stray byte usually means, so that a file in the wrong encoding is named as such instead
// of failing line after line on "unexpected byte 0x00": NUL bytes and a UTF-16 byte-order mark
// come from UTF-16 files, a CR inside a line from lines that end in CR only.
std::string byte_hint(char c, std::size_t p, std::string_view s) {
  const auto b = static_cast<unsigned char>(c);
  const bool bom16 = s.size() >= 2 && ((s[0] == '\xFF' && s[1] == '\xFE') || (s[0] == '\xFE' && s[1] == '\xFF'));
  if (b == 0x00 || (p == 0 && bom16))
    return ": the file looks like UTF-16 (NUL bytes, byte-order mark FF FE); save it as ASCII or UTF-8, "
           "e.g. iconv -f UTF-16 -t UTF-8 IN > OUT";
  if (b == 0x0D)
    return ": a carriage return inside the line: the file's lines end in CR only (classic Mac); convert them "
           "to LF, e.g. tr '\\r' '\\n' < IN > OUT";
  return {};
}

}  // namespace

// The slow path: a bracketed expression, a parameter or a function call as a word's value.
bool Parser::Impl::read_expression_number(std::string_view s, std::size_t& p, char letter, Word& w) {
  // Function names (sqrt[..]) start with a letter; a plain letter here is a missing value, which
  // the expression reader reports as such.
  if ((s[p] | 0x20) >= 'a' && (s[p] | 0x20) <= 'z') {
    std::size_t q = p;
    while (q < s.size() && (((s[q] | 0x20) >= 'a' && (s[q] | 0x20) <= 'z'))) ++q;
    skip_blanks(s, q);
    if (q >= s.size() || s[q] != '[')
      return fail(static_cast<std::uint32_t>(p + 1),
                  std::string("word '") + letter + "' has no value (a number must follow the letter)");
  }
  refresh_system_parameters();  // a word may read the position (#<_x>, Fanuc #5001)
  ExpressionReader er(params);
  double v = 0;
  if (!er.read_value(s, p, v)) return fail(static_cast<std::uint32_t>(er.error_pos() + 1), er.error());
  if (!std::isfinite(v))
    return fail(w.col, std::string("value of ") + letter + " is not a finite number");
  w.value = v;
  w.point = true;
  w.expr = true;
  w.vacant = er.vacant();
  return true;
}

// A number after a letter: optional sign, digits and at most one point, blanks allowed anywhere
// (ISO 6983 and LinuxCNC ignore spaces). Expressions and parameters take the slow path.
bool Parser::Impl::read_number(std::string_view s, std::size_t& p, char letter, Word& w) {
  skip_blanks(s, p);
  if (p < s.size() && (s[p] == '[' || s[p] == '#' ||
                       ((s[p] == '-' || s[p] == '+') && p + 1 < s.size() && (s[p + 1] == '[' || s[p + 1] == '#')) ||
                       ((s[p] | 0x20) >= 'a' && (s[p] | 0x20) <= 'z')))
    return read_expression_number(s, p, letter, w);
  const std::size_t start = p;
  bool neg = false;
  if (p < s.size() && (s[p] == '+' || s[p] == '-')) {
    neg = s[p] == '-';
    ++p;
    skip_blanks(s, p);
  }
  const std::size_t digits = p;
  bool point = false, blank = false;
  std::size_t ndig = 0;
  while (p < s.size()) {
    char c = s[p];
    if (c >= '0' && c <= '9') {
      ++ndig;
    } else if (c == '.') {
      if (point) return fail(static_cast<std::uint32_t>(p + 1), std::string("number after ") + letter + " has two decimal points");
      point = true;
    } else if (c == ' ' || c == '\t') {
      // A blank inside a number is allowed only if more digits follow ("X1 2.5" = X12.5).
      std::size_t q = p;
      skip_blanks(s, q);
      if (q < s.size() && ((s[q] >= '0' && s[q] <= '9') || s[q] == '.')) {
        blank = true;
        p = q;
        continue;
      }
      break;
    } else {
      break;
    }
    ++p;
  }
  if (ndig == 0) {
    if (start == p || p == digits)
      return fail(static_cast<std::uint32_t>(start + 1),
                  std::string("word '") + letter + "' has no value (a number must follow the letter)");
    return fail(static_cast<std::uint32_t>(start + 1), std::string("malformed number after ") + letter);
  }
  double v = 0;
  std::from_chars_result r;
  std::size_t len = p - digits;
  while (len > 0 && (s[digits + len - 1] == ' ' || s[digits + len - 1] == '\t')) --len;
  if (!blank) {
    r = std::from_chars(s.data() + digits, s.data() + digits + len, v);
    if (r.ec == std::errc::result_out_of_range) v = HUGE_VAL;
    else if (r.ec != std::errc() || r.ptr != s.data() + digits + len)
      return fail(static_cast<std::uint32_t>(start + 1), std::string("malformed number after ") + letter);
  } else {
    std::string buf;
    for (std::size_t i = digits; i < digits + len; ++i)
      if (s[i] != ' ' && s[i] != '\t') buf.push_back(s[i]);
    r = std::from_chars(buf.data(), buf.data() + buf.size(), v);
    if (r.ec == std::errc::result_out_of_range) v = HUGE_VAL;
    else if (r.ec != std::errc() || r.ptr != buf.data() + buf.size())
      return fail(static_cast<std::uint32_t>(start + 1), std::string("malformed number after ") + letter);
  }
  w.value = neg ? -v : v;
  w.point = point;
  w.expr = false;
  return true;
}

// G and M numbers: an integer with at most one decimal digit (G43.4), or an expression.
bool Parser::Impl::read_code(std::string_view s, std::size_t& p, char letter, int& code, std::uint32_t col) {
  Word w;
  w.col = col;
  if (!read_number(s, p, letter, w)) return false;
  if (w.vacant) {  // G#1 with #1 vacant: no code at all (Fanuc, "Null variables")
    code = -1;
    return true;
  }
  double t = w.value * 10;
  if (w.value < 0 || w.value > 9999 || std::fabs(t - std::round(t)) > 1e-6)
    return fail(col, std::string(1, letter) + show(w.value) + " is not a valid " + letter +
                         " code (a whole number, optionally with one decimal: G43.4)");
  code = static_cast<int>(std::lround(t));
  return true;
}

bool Parser::Impl::scan(std::string_view s, ResolvedBlock& b) {
  sc.ng = sc.nm = sc.nassign = 0;
  sc.percent = false;
  sc.program_number = -1;
  sc.any_word = false;
  std::memset(static_cast<void*>(sc.words), 0, sizeof sc.words);
  sc.polar_r.col = sc.polar_a.col = 0;
  std::size_t p = 0;
  skip_blanks(s, p);
  if (p < s.size() && s[p] == '%') {
    sc.percent = true;
    ++p;
    add_comment(b.comment, s.substr(p));  // "%_N_NAME" and the like: keep the text
    return true;
  }
  if (p < s.size() && s[p] == ':') {  // Fanuc's alternative program number
    ++p;
    Word w;
    w.col = static_cast<std::uint32_t>(p);
    if (!read_number(s, p, ':', w)) return false;
    if (w.value < 0 || w.value > 99999999 || w.value != std::floor(w.value))
      return fail(w.col, "program number :" + show(w.value) + " is not a whole number 0..99999999");
    sc.program_number = static_cast<std::int32_t>(w.value);
  }
  while (p < s.size()) {
    const char c = s[p];
    const std::uint32_t col = static_cast<std::uint32_t>(p + 1);
    if (c == ' ' || c == '\t') {
      ++p;
    } else if (c == '(') {
      std::size_t close = p + 1;
      while (close < s.size() && s[close] != ')') {
        if (s[close] == '(')
          return fail(static_cast<std::uint32_t>(close + 1), "comment inside a comment: '(' before the ')' of the comment opened at column " + std::to_string(col));
        ++close;
      }
      if (close >= s.size()) return fail(col, "comment opened with '(' is not closed on this line");
      if (opt.dialect == Dialect::kLinuxCnc && is_abort(s.substr(p + 1, close - p - 1)))
        return linuxcnc_abort(s.substr(p + 7, close - p - 7), col);
      add_comment(b.comment, s.substr(p + 1, close - p - 1));
      p = close + 1;
    } else if (c == ';') {
      add_comment(b.comment, s.substr(p + 1));
      break;
    } else if (c == '#') {
      if (!scan_assignment(s, p, col)) return false;
    } else if ((c == '@' || c == '^') && opt.dialect == Dialect::kLinuxCnc) {
      if (!scan_polar(s, p, col)) return false;
    } else if (upper(c) == 'O') {
      if (!scan_o_word(s, p, col)) return false;
    } else if (upper(c) < 'A' || upper(c) > 'Z' || !is_word_letter(upper(c))) {
      return reject_character(s, p, c, col);
    } else if (!scan_word(s, p, upper(c), col)) {
      return false;
    }
  }
  return true;
}

// Parameter assignment: #1 = 2, #<name> = [expr]; applied after the line, as LinuxCNC does.
bool Parser::Impl::scan_assignment(std::string_view s, std::size_t& p, std::uint32_t col) {
  ++p;
  if (sc.nassign == 8) return fail(col, "more than 8 parameter assignments on one line");
  refresh_system_parameters();
  ExpressionReader er(params);
  Assignment& a = sc.assign[sc.nassign];
  if (!er.read_target(s, p, a)) return fail(static_cast<std::uint32_t>(er.error_pos() + 1), er.error());
  skip_blanks(s, p);
  if (p >= s.size() || s[p] != '=')
    return fail(static_cast<std::uint32_t>(p + 1), "a parameter outside a word must be assigned: '#... = value'");
  ++p;
  double v = 0;
  // Fanuc Macro B writes the value as a bare expression (#1 = #2 + 3); LinuxCNC as one value.
  const bool ok = opt.dialect == Dialect::kFanuc ? er.read_expression(s, p, v) : er.read_value(s, p, v);
  if (!ok) return fail(static_cast<std::uint32_t>(er.error_pos() + 1), er.error());
  if (!std::isfinite(v)) return fail(col, "parameter value is not a finite number");
  a.value = v;
  a.vacant = er.vacant();
  if (!a.named && ParameterStore::is_offset_parameter(a.number, opt.dialect == Dialect::kFanuc))
    return fail(col, "#" + std::to_string(a.number) + " is an offset the control holds (work system origin or tool "
                     "length): gcpipe reads it but a program sets it with G10 L2 P / G43 H, not by assignment");
  if (opt.dialect == Dialect::kFanuc && !a.named && !fanuc_system_assignment(s, p, a, col)) return false;
  ++sc.nassign;
  return true;
}

// Fanuc Custom Macro B system variables a program may not simply set: #5001..#5005 are the
// position (read only); #3000 = n raises macro alarm 3000 + n with the comment that follows as
// its message, and the program stops there (0i-MF manual B-64604EN, "System variables": #3000).
bool Parser::Impl::fanuc_system_assignment(std::string_view s, std::size_t p, const Assignment& a, std::uint32_t col) {
  if (a.number >= 5001 && a.number <= 5005)
    return fail(col, "#" + std::to_string(a.number) + " is the position of the " + kAxisLetters[a.number - 5001] +
                         " axis at the end of the last block: it is read only");
  if (a.number != 3000) return true;
  if (a.value < 0 || a.value > 999 || a.value != std::floor(a.value))
    return fail(col, "#3000 = " + show(a.value) + ": the alarm number must be a whole number 0..999");
  std::string message;
  const std::size_t open = s.find('(', p), close = s.find(')', open == std::string_view::npos ? s.size() : open);
  if (open != std::string_view::npos && close != std::string_view::npos) message = std::string(s.substr(open + 1, close - open - 1));
  alarm_line = block.line;
  return fail(col, "macro alarm " + std::to_string(3000 + static_cast<int>(a.value)) +
                       (message.empty() ? std::string() : ": " + message) + " (#3000): the program stops here");
}

// LinuxCNC's `(abort, message)`: the interpreter stops the program there with the message, as a
// Fanuc #3000 alarm does (compensated.nc's guard relies on it).
bool Parser::Impl::is_abort(std::string_view comment) {
  static constexpr std::string_view kWord = "abort,";
  if (comment.size() < kWord.size()) return false;
  for (std::size_t i = 0; i < kWord.size(); ++i)
    if (static_cast<char>(std::tolower(static_cast<unsigned char>(comment[i]))) != kWord[i]) return false;
  return true;
}

bool Parser::Impl::linuxcnc_abort(std::string_view message, std::uint32_t col) {
  alarm_line = block.line;
  std::size_t b = 0;
  while (b < message.size() && message[b] == ' ') ++b;
  return fail(col, "abort: " + std::string(message.substr(b)) + " ((abort, ...)): the program stops here");
}

// Fanuc: O1234 is the program number. LinuxCNC o-word statements (o100 sub, o<name> call ...)
// never reach the scanner: flow.cpp runs them; one that does is misplaced on its line.
bool Parser::Impl::scan_o_word(std::string_view s, std::size_t& p, std::uint32_t col) {
  Statement st;
  if (read_statement(s.substr(p), st))
    return fail(col, "o-word statement (o" + st.label + " " + st.keyword +
                         ") must stand at the start of its line, alone with comments");
  std::size_t q = p + 1;
  skip_blanks(s, q);
  if (q < s.size() && s[q] == '<')
    return fail(col, "o-word o<name> without a statement: expected sub, endsub, call, return, if, elseif, "
                     "else, endif, while, endwhile, do, repeat, endrepeat, break or continue");
  ++p;
  Word w;
  w.col = col;
  if (!read_number(s, p, 'O', w)) return false;
  if (w.value < 0 || w.value > 99999999 || w.value != std::floor(w.value))
    return fail(col, "program number O" + show(w.value) + " is not a whole number 0..99999999");
  if (sc.program_number >= 0) return fail(col, "two program numbers on one line");
  sc.program_number = static_cast<std::int32_t>(w.value);
  return true;
}

bool Parser::Impl::reject_character(std::string_view s, std::size_t p, char c, std::uint32_t col) {
  const char L = upper(c);
  if (L >= 'A' && L <= 'Z') {
    std::string what = (L == 'B' || L == 'U' || L == 'V')
                           ? std::string("this machine has axes X Y Z A C only (no ") + L + " axis)"
                           : std::string("'") + L + "' is not a word of this dialect";
    std::size_t q = p + 1;
    std::string val;
    while (q < s.size() && val.size() < 16 && (std::isdigit(static_cast<unsigned char>(s[q])) || s[q] == '.' || s[q] == '-' || s[q] == '+')) val.push_back(s[q++]);
    return fail(col, "unknown word '" + std::string(1, L) + val + "': " + what);
  }
  if (c == '/' && p > 0) return fail(col, "'/' (block delete) is only allowed at the start of a line");
  if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) {
    char h[4];
    std::snprintf(h, sizeof h, "%02X", static_cast<unsigned char>(c));
    return fail(col, "unexpected byte 0x" + std::string(h) + " outside a comment" + byte_hint(c, p, s));
  }
  return fail(col, std::string("unexpected '") + c + "': expected a word (letter and number) or a comment");
}

// Inlined into scan(): it runs for every word of every line.
[[gnu::always_inline]] inline bool Parser::Impl::scan_word(std::string_view s, std::size_t& p, char L, std::uint32_t col) {
  ++p;
  sc.any_word = true;
  if (L == 'G' || L == 'M') {
    int code = 0;
    if (!read_code(s, p, L, code, col)) return false;
    if (code < 0) return true;
    if (L == 'G') {
      if (sc.ng == 8) return fail(col, "more than 8 G codes in one block");
      sc.g[sc.ng++] = {code, col};
    } else {
      if (sc.nm == 8) return fail(col, "more than 8 M codes in one block");
      sc.m[sc.nm++] = {code, col};
    }
    return true;
  }
  Word& w = sc.words[L - 'A'];
  if (w.col != 0) {
    Word again;
    again.col = col;
    std::size_t q = p;
    std::string second = "";
    if (read_number(s, q, L, again)) second = show(again.value);
    return fail(col, std::string("word ") + L + " appears twice in one block (" + L + show(w.value) +
                         " at column " + std::to_string(w.col) + ", " + L + second + " at column " +
                         std::to_string(col) + "): keep one");
  }
  w.col = col;
  if (!read_number(s, p, L, w)) return false;
  if (w.vacant) {  // X#1 with #1 vacant: as if the block had no X word (Fanuc, "Null variables")
    w = Word{};
    return true;
  }
  if (std::isinf(w.value)) return fail(col, std::string("value of ") + L + " overflows (more than 1.8e308)");
  return true;
}

// LinuxCNC's polar coordinates in the XY plane: @ distance and ^ angle from the origin (G90) or
// added to the current distance and angle (G91); either may be left out.
bool Parser::Impl::scan_polar(std::string_view s, std::size_t& p, std::uint32_t col) {
  const char c = s[p++];
  Word& w = c == '@' ? sc.polar_r : sc.polar_a;
  if (w.col != 0) return fail(col, std::string("word ") + c + " appears twice in one block: keep one");
  w.col = col;
  sc.any_word = true;
  if (!read_number(s, p, c, w)) return false;
  if (std::isinf(w.value)) return fail(col, std::string("value of ") + c + " overflows (more than 1.8e308)");
  return true;
}

// LinuxCNC's read-only named parameters for the position (#<_x> ...), in program units and
// coordinates, as real subroutines read them (helix_ac.ngc: `g0 x[#<_x> - #<r>]`), and #5420..
// #5428, the same position as numbered parameters (B U V W: 0, the machine has no such axes).
void Parser::Impl::refresh_system_parameters() {
  static const char* const names[kNumAxes] = {"_x", "_y", "_z", "_a", "_c"};
  static const int linuxcnc_numbers[kNumAxes] = {5420, 5421, 5422, 5423, 5425};
  const double unit = st.units == Units::kInch ? kInch : 1.0;
  for (int a = 0; a < kNumAxes; ++a) {
    double v = st.position[a] - st.origin[a];
    if (a < kA) v /= unit;
    params.set_named(names[a], v);
    if (opt.dialect == Dialect::kFanuc) params.set_numbered(5001 + a, v);  // Macro B #5001..#5005
    else params.set_numbered(linuxcnc_numbers[a], v);
  }
  if (opt.dialect == Dialect::kLinuxCnc) {
    // #5600/#5601: the tool changer's fault and its reason, which the control sets; a program's
    // assignment does not stay (rs274 reads 0 after `#5600 = 3`).
    params.set_numbered(5600, 0);
    params.set_numbered(5601, 0);
    refresh_linuxcnc_modes();
  }
  refresh_offset_parameters(unit);
}

// The offsets the control holds, as the program has them (G10 L2 / L20 and G43 H in force), at
// the numbers LinuxCNC's interpreter and the Fanuc 0i give them, so that a program reading them
// (compensated.nc's guard) takes the branch the control takes with the machine file's offsets.
// LinuxCNC, in the machine's unit (mm: gcpipe's machine file is metric) whatever G20 / G21 says:
// #5221 + 20 k + {0 X, 1 Y, 2 Z, 3 A, 5 C} (B U V W and the rotation R stay 0), #5220 the system
// in use (1 = G54), #5210 whether a G92 shift is applied, #5400 the tool in the spindle and #5403
// its length in the tool table. Fanuc, in the program's unit: #5221 + 20 k + {0..4} in the axis
// order X Y Z A C, #5083 the tool length in force, #5201..#5205 the external work offset (none).
void Parser::Impl::refresh_offset_parameters(double unit) {
  const bool fanuc = opt.dialect == Dialect::kFanuc;
  if (!fanuc) unit = 1.0;
  static constexpr int kLinuxCncAxis[kNumAxes] = {0, 1, 2, 3, 5};
  for (std::size_t k = 0; k < offsets.size(); ++k)
    for (int a = 0; a < kNumAxes; ++a)
      params.set_numbered(5221 + 20 * static_cast<int>(k) + (fanuc ? a : kLinuxCncAxis[a]),
                          a < kA ? offsets[k][a] / unit : offsets[k][a]);
  if (fanuc) {
    params.set_numbered(5083, st.tlo_active ? st.tool_length / unit : 0.0);
    for (int a = 0; a < kNumAxes; ++a) params.set_numbered(5201 + a, 0.0);
    return;
  }
  params.set_numbered(5220, st.work_offset - 53);
  bool shifted = false;
  for (int a = 0; a < kNumAxes; ++a) shifted = shifted || st.shift[a] != 0;
  params.set_numbered(5210, shifted && !st.shift_suspended ? 1 : 0);
  params.set_numbered(5400, st.tool_in_spindle);
  const auto tool = machine.tools.find(st.tool_in_spindle);
  params.set_numbered(5403, tool == machine.tools.end() ? 0.0 : tool->second.length);
}

namespace {

// LinuxCNC's code for a motion mode in #<_motion_mode>: the G number times ten, 800 for G80 (its
// state before any motion), 810... for a canned cycle in force.
double motion_mode_code(const parse_detail::ModalState& s) {
  if (s.cycle != 0) return s.cycle;
  switch (s.motion) {
    case Motion::kRapid: return 0;
    case Motion::kLinear: return 10;
    case Motion::kArcCW: return 20;
    case Motion::kArcCCW: return 30;
    default: return 800;
  }
}

// #<_coord_system>: 540 ... 590, then 591, 592, 593 for G59.1 ... G59.3 (work_offset 591...).
double coord_system_code(std::int32_t work_offset) { return work_offset < 100 ? 10.0 * work_offset : work_offset; }

}  // namespace

// LinuxCNC's predefined named parameters of the modal state ("Predefined Named Parameters" in its
// G-code overview), each checked against rs274 (tests/rs274_diff_test.cpp, predefined_parameters):
// booleans read 1 or 0; #<_task> is 1, as in the running control (rs274 alone reads 0: programs
// test it to skip work in a preview, and gcpipe follows the machine).
void Parser::Impl::refresh_linuxcnc_modes() {
  const auto flag = [this](const char* name, bool on) { params.set_named(name, on ? 1.0 : 0.0); };
  params.set_named("_motion_mode", motion_mode_code(st));
  params.set_named("_plane", 10.0 * static_cast<int>(st.plane));
  // 410 left, 420 right, 400 off; G41.1/G42.1 read as G41/G42, a negative diameter as the other side (rs274).
  params.set_named("_ccomp", st.comp_side == 0 ? 400 : st.comp_side > 0 ? 410 : 420);
  flag("_metric", st.units == Units::kMillimetre);
  flag("_imperial", st.units == Units::kInch);
  flag("_absolute", !st.incremental);
  flag("_incremental", st.incremental);
  flag("_inverse_time", st.feed_mode == FeedMode::kInverseTime);
  flag("_units_per_minute", st.feed_mode == FeedMode::kUnitsPerMinute && !st.per_revolution);
  flag("_units_per_rev", st.per_revolution);
  params.set_named("_coord_system", coord_system_code(st.work_offset));
  flag("_tool_offset", st.tlo_active);
  flag("_retract_r_plane", st.cycle_to_r);
  flag("_retract_old_z", !st.cycle_to_r);
  flag("_spindle_rpm_mode", true);   // G96 (constant surface speed) is not accepted
  flag("_spindle_css_mode", false);
  flag("_ijk_absolute_mode", !st.arc_incremental);
  flag("_spindle_on", st.spindle != Spindle::kOff);
  flag("_spindle_cw", st.spindle == Spindle::kCW);
  flag("_mist", (st.coolant & kCoolantMist) != 0);
  flag("_flood", (st.coolant & kCoolantFlood) != 0);
  params.set_named("_rpm", st.spindle_speed);
  // F in program units: per minute in G94 (inch/min in G20), per revolution in G95.
  params.set_named("_feed", st.per_revolution ? st.feed_per_rev / (st.units == Units::kInch ? kInch : 1.0)
                            : st.feed_mode == FeedMode::kInverseTime ? st.feed
                                                                     : st.feed / (st.units == Units::kInch ? kInch : 1.0));
  params.set_named("_current_tool", st.tool_in_spindle);
  params.set_named("_selected_tool", st.tool);
  params.set_named("_call_level", static_cast<double>(frames.size() - 1));
  params.set_named("_task", 1.0);
}

}  // namespace gcpipe
