// ISO 6983 parser: scanner (words, comments, expressions) and modal resolution.
//
// Order of work for one line, chosen so that a rejected line leaves no trace:
//   1. scan the line into words (letter, value, column) and assignments, checking the syntax;
//   2. copy the modal state and resolve the block against the copy, checking the semantics;
//   3. only when everything is valid, commit the copy and the parameter assignments.
// The hot path (plain words with literal numbers) allocates nothing once the block's strings have
// grown to the longest line.
#include "parse.hpp"

#include <charconv>
#include <cmath>
#include <cstring>
#include <numbers>

#include "expression.hpp"
#include "gcpipe/config.hpp"
#include "gcpipe/number_format.hpp"

namespace gcpipe {

ParseOptions load_parse_options(const Config& c) {
  c.reject_unknown({"dialect", "decimal_point_rule", "block_delete", "strict", "max_line_length", "units",
                    "arc_centres"});
  ParseOptions o;
  o.dialect = c.choice("dialect", "fanuc", {"fanuc", "linuxcnc"}) == "fanuc" ? Dialect::kFanuc
                                                                               : Dialect::kLinuxCnc;
  o.decimal_point_increments = c.boolean("decimal_point_rule", false);
  o.block_delete = c.boolean("block_delete", true);
  o.strict = c.boolean("strict", false);
  o.max_line_length = static_cast<std::size_t>(c.integer("max_line_length", 256, 16, 65536));
  o.initial_units = c.choice("units", "mm", {"mm", "inch"}) == "mm" ? Units::kMillimetre : Units::kInch;
  o.absolute_arc_centres = c.choice("arc_centres", "incremental", {"incremental", "absolute"}) == "absolute";
  return o;
}

namespace {

constexpr double kMaxLinear = 1e5;   // [mm] |value| beyond any machine: surely a typo or overflow
constexpr double kMaxAngle = 1e5;    // [deg] allows many turns of C, rejects overflow
constexpr double kMaxFeed = 1e6;     // [mm/min] or [1/min]
constexpr double kMaxSpindle = 1e6;  // [rev/min]
constexpr double kInch = 25.4;       // [mm]

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

struct Word {
  double value = 0;
  std::uint32_t col = 0;  // 1-based, 0 = absent
  bool point = false;     // written with a decimal point (Fanuc increment rule)
  bool expr = false;      // came from an expression or parameter (never in increments)
};

struct Code {
  int code;  // G or M number x10: G43.4 -> 434
  std::uint32_t col;
};

// Modal groups (ISO 6983 / LinuxCNC numbering) used to detect two codes of one group in a block.
enum Group : int {
  kGNonModal = 0, kGMotion = 1, kGPlane = 2, kGDistance = 3, kGArcDistance = 4, kGFeedMode = 5,
  kGUnits = 6, kGCutterComp = 7, kGToolLength = 8, kGCoordSystem = 12, kGPathMode = 13,
  kGUnsupported = 99
};

int g_group(int code) {
  switch (code) {
    case 0: case 10: case 20: case 30: return kGMotion;
    case 40: case 2750: return kGNonModal;
    case 170: case 180: case 190: return kGPlane;
    case 900: case 910: return kGDistance;
    case 901: case 911: return kGArcDistance;
    case 930: case 940: return kGFeedMode;
    case 200: case 210: return kGUnits;
    case 400: return kGCutterComp;
    case 430: case 434: case 435: case 490: return kGToolLength;
    case 540: case 550: case 560: case 570: case 580: case 590: return kGCoordSystem;
    case 610: case 611: case 640: return kGPathMode;
    case 800: return kGMotion;  // G80 cancels the (canned) motion mode
    default: return kGUnsupported;
  }
}

std::string code_text(char letter, int code) {
  std::string s(1, letter);
  s += std::to_string(code / 10);
  if (code % 10) s += "." + std::to_string(code % 10);
  return s;
}

// Why a G code is not supported, in words a programmer can act on.
std::string unsupported_g(int code) {
  const std::string g = code_text('G', code);
  switch (code) {
    case 410: case 420:
      return g + " (cutter radius compensation) is not supported: post-process the tool-centre path "
                 "(CAM compensation 'computer')";
    case 100:
      return "G10 (setting offsets from the program) is not supported: put the offsets in the machine "
             "config (machine.work_offsets, machine.tools)";
    case 280: case 300: return g + " (return to reference point) is not supported: program the move";
    case 530: return "G53 (machine coordinates) is not supported: program in a G54..G59 system";
    case 920: case 921: case 922: case 923:
      return g + " (coordinate shift) is not supported: use G54..G59 from the machine config";
    case 950: return "G95 (feed per revolution) is not supported: use G94 (mm/min) or G93 (inverse time)";
    case 960: case 970: return g + " (constant surface speed) is not supported on this milling machine";
    case 330: case 331: case 760: return g + " (threading) is not supported";
    case 730: case 810: case 820: case 830: case 840: case 850: case 860: case 870: case 880:
    case 890:
      return g + " (drilling canned cycle) is not supported: expand the cycle in CAM";
    case 381: case 382: case 383: case 384: return g + " (probing) is not supported";
    case 431: return "G43.1 (dynamic tool length) is not supported: use G43 H with the tool table";
    case 591: case 592: case 593:
      return g + " is not supported: use G54..G59";
    default: return g + " is not a supported G code";
  }
}

enum MGroup : int { kMStop = 4, kMToolChange = 6, kMSpindle = 7, kMCoolant = 8, kMKins = 9, kMUnsupported = 99 };

int m_group(int code) {
  switch (code) {
    case 0: case 10: case 20: case 300: return kMStop;
    case 60: return kMToolChange;
    case 30: case 40: case 50: return kMSpindle;
    case 70: case 80: case 90: return kMCoolant;
    case 4280: case 4290: case 4300: return kMKins;
    default: return kMUnsupported;
  }
}

std::string unsupported_m(int code) {
  const std::string m = code_text('M', code);
  switch (code) {
    case 980: case 990: return m + " (subprogram call/return) is not supported: expand it in CAM";
    case 600: return "M60 (pallet change) is not supported";
    case 480: case 490: case 500: case 510: case 520: case 530:
      return m + " (override control) is not supported";
    default: return m + " is not a supported M code";
  }
}

// Plane geometry: the two in-plane axes, the normal axis, and the letters of the centre offsets.
struct PlaneAxes {
  int u, v, n;          // axis indices
  char ou, ov;          // offset letters for u and v
};

PlaneAxes plane_axes(Plane p) {
  switch (p) {
    case Plane::kXY: return {kX, kY, kZ, 'I', 'J'};
    case Plane::kZX: return {kZ, kX, kY, 'K', 'I'};
    case Plane::kYZ: return {kY, kZ, kX, 'J', 'K'};
  }
  return {kX, kY, kZ, 'I', 'J'};
}

struct ModalState {
  Motion motion = Motion::kNone;  // modal motion (G0..G3), kNone until programmed or after G80
  Plane plane = Plane::kXY;
  bool incremental = false;
  bool arc_incremental = true;  // G91.1 is the default in Fanuc and LinuxCNC
  Units units = Units::kMillimetre;
  FeedMode feed_mode = FeedMode::kUnitsPerMinute;
  double feed = 0;
  double spindle_speed = 0;
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
  Axes origin{};
  Axes position{};  // machine coordinates
  bool ended = false;
};

// Everything scanned from one line.
struct Scan {
  Word words[26];
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

}  // namespace

struct Parser::Impl {
  ParseOptions opt;
  MachineConfig machine;
  std::string file;
  ModalState st;
  ParameterStore params;
  ParseSummary summary;
  Scan sc;
  std::string skipping_sub;  // name of an unsupported o<...> sub whose body is being rejected
  std::string error;       // message of the current line's error
  std::uint32_t error_col = 0;

  Impl(ParseOptions o, MachineConfig m, std::string f) : opt(o), machine(std::move(m)), file(std::move(f)) {
    st.units = opt.initial_units;
    st.arc_incremental = !opt.absolute_arc_centres;
    st.origin = machine.work_offsets[0];
    for (int a = 0; a < kNumAxes; ++a) st.position[a] = machine.initial_position[a] + st.origin[a];
  }

  bool fail(std::uint32_t col, std::string msg) {
    error = std::move(msg);
    error_col = col;
    return false;
  }

  bool scan(std::string_view s, ResolvedBlock& b);
  bool read_number(std::string_view s, std::size_t& p, char letter, Word& w);
  bool read_code(std::string_view s, std::size_t& p, char letter, int& code, std::uint32_t col);
  bool resolve(ResolvedBlock& b, ModalState& ns);
  bool arc(const Scan& sc, ResolvedBlock& b, ModalState& ns, bool cw);
  bool slot(const Scan& sc, ResolvedBlock& b, ModalState& ns);
  double linear_value(const Word& w, Units units) const;
  double angle_value(const Word& w) const;
};

namespace {

inline void skip_blanks(std::string_view s, std::size_t& p) {
  while (p < s.size() && (s[p] == ' ' || s[p] == '\t')) ++p;
}

inline char upper(char c) { return (c >= 'a' && c <= 'z') ? static_cast<char>(c - 'a' + 'A') : c; }

void add_comment(std::string& comment, std::string_view text) {
  // Trim so that "( text )" and "(text)" read back the same after a write.
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t')) text.remove_suffix(1);
  if (text.empty()) return;
  if (!comment.empty()) comment += " | ";
  comment.append(text);
}

// A value as a message shows it: shortest exact digits, no forced point ("I2", "X0.001").
std::string show(double v) {
  std::string s;
  append_json_number(s, v);
  return s;
}

}  // namespace

// A number after a letter: optional sign, digits and at most one point, blanks allowed anywhere
// (ISO 6983 and LinuxCNC ignore spaces). Expressions and parameters take the slow path.
bool Parser::Impl::read_number(std::string_view s, std::size_t& p, char letter, Word& w) {
  skip_blanks(s, p);
  if (p < s.size() && (s[p] == '[' || s[p] == '#' ||
                       ((s[p] == '-' || s[p] == '+') && p + 1 < s.size() && (s[p + 1] == '[' || s[p + 1] == '#')) ||
                       ((s[p] | 0x20) >= 'a' && (s[p] | 0x20) <= 'z'))) {
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
    ExpressionReader er(params);
    double v = 0;
    if (!er.read_value(s, p, v)) return fail(static_cast<std::uint32_t>(er.error_pos() + 1), er.error());
    if (!std::isfinite(v))
      return fail(w.col, std::string("value of ") + letter + " is not a finite number");
    w.value = v;
    w.point = true;
    w.expr = true;
    return true;
  }
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
      continue;
    }
    if (c == '(') {
      std::size_t close = p + 1;
      while (close < s.size() && s[close] != ')') {
        if (s[close] == '(')
          return fail(static_cast<std::uint32_t>(close + 1), "comment inside a comment: '(' before the ')' of the comment opened at column " + std::to_string(col));
        ++close;
      }
      if (close >= s.size()) return fail(col, "comment opened with '(' is not closed on this line");
      add_comment(b.comment, s.substr(p + 1, close - p - 1));
      p = close + 1;
      continue;
    }
    if (c == ';') {
      add_comment(b.comment, s.substr(p + 1));
      break;
    }
    if (c == '#') {  // parameter assignment: #1 = 2, #<name> = [expr]
      ++p;
      if (sc.nassign == 8) return fail(col, "more than 8 parameter assignments on one line");
      ExpressionReader er(params);
      Assignment& a = sc.assign[sc.nassign];
      if (!er.read_target(s, p, a)) return fail(static_cast<std::uint32_t>(er.error_pos() + 1), er.error());
      skip_blanks(s, p);
      if (p >= s.size() || s[p] != '=')
        return fail(static_cast<std::uint32_t>(p + 1), "a parameter outside a word must be assigned: '#... = value'");
      ++p;
      double v = 0;
      if (!er.read_value(s, p, v)) return fail(static_cast<std::uint32_t>(er.error_pos() + 1), er.error());
      if (!std::isfinite(v)) return fail(col, "parameter value is not a finite number");
      a.value = v;
      ++sc.nassign;
      continue;
    }
    const char L = upper(c);
    if (L == 'O') {
      // Fanuc: O1234 is the program number. LinuxCNC: o<name>/o100 sub|call|if|while... are flow
      // control, which this pipeline does not execute.
      std::size_t q = p + 1;
      skip_blanks(s, q);
      if (q < s.size() && s[q] == '<') {
        std::size_t close = s.find('>', q);
        std::string name(s.substr(q, close == std::string_view::npos ? std::string_view::npos : close - q + 1));
        std::size_t k = close == std::string_view::npos ? s.size() : close + 1;
        skip_blanks(s, k);
        std::string kw;
        while (k < s.size() && ((s[k] | 0x20) >= 'a' && (s[k] | 0x20) <= 'z')) kw.push_back(static_cast<char>(s[k++] | 0x20));
        if (kw == "sub") skipping_sub = normalise_parameter_name(name);
        return fail(col, "o-word subroutines and flow control (o" + name + (kw.empty() ? "" : " " + kw) +
                             ") are not supported: expand the program in CAM" +
                             (kw == "sub" ? "; the lines up to its endsub are rejected with it" : ""));
      }
      ++p;
      Word w;
      w.col = col;
      if (!read_number(s, p, 'O', w)) return false;
      std::size_t q2 = p;
      skip_blanks(s, q2);
      {
        // "o100 sub", "o100 call", "o100 if [...]": a keyword after the number means flow control.
        std::size_t e = q2;
        while (e < s.size() && ((s[e] | 0x20) >= 'a' && (s[e] | 0x20) <= 'z')) ++e;
        std::string kw(s.substr(q2, e - q2));
        for (auto& ch : kw) ch = static_cast<char>(ch | 0x20);
        if (kw == "sub" || kw == "endsub" || kw == "call" || kw == "while" || kw == "endwhile" ||
            kw == "return" || kw == "if" || kw == "else" || kw == "elseif" || kw == "endif" ||
            kw == "do" || kw == "repeat" || kw == "endrepeat" || kw == "break" || kw == "continue")
          return fail(col, "o-word flow control (O" + show(w.value) + " " + kw +
                               ") is not supported: expand the program in CAM");
      }
      if (w.value < 0 || w.value > 99999999 || w.value != std::floor(w.value))
        return fail(col, "program number O" + show(w.value) + " is not a whole number 0..99999999");
      if (sc.program_number >= 0) return fail(col, "two program numbers on one line");
      sc.program_number = static_cast<std::int32_t>(w.value);
      continue;
    }
    if (L < 'A' || L > 'Z') {
      if (c == '/' && p > 0)
        return fail(col, "'/' (block delete) is only allowed at the start of a line");
      if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f)
        return fail(col, "unexpected byte 0x" + [&] {
          char h[4];
          std::snprintf(h, sizeof h, "%02X", static_cast<unsigned char>(c));
          return std::string(h);
        }() + " outside a comment");
      return fail(col, std::string("unexpected '") + c + "': expected a word (letter and number) or a comment");
    }
    if (!is_word_letter(L)) {
      std::string what = (L == 'B' || L == 'U' || L == 'V')
                             ? std::string("this machine has axes X Y Z A C only (no ") + L + " axis)"
                             : std::string("'") + L + "' is not a word of this dialect";
      std::size_t q = p + 1;
      std::string val;
      while (q < s.size() && val.size() < 16 && (std::isdigit(static_cast<unsigned char>(s[q])) || s[q] == '.' || s[q] == '-' || s[q] == '+')) val.push_back(s[q++]);
      return fail(col, "unknown word '" + std::string(1, L) + val + "': " + what);
    }
    ++p;
    sc.any_word = true;
    if (L == 'G' || L == 'M') {
      int code = 0;
      if (!read_code(s, p, L, code, col)) return false;
      if (L == 'G') {
        if (sc.ng == 8) return fail(col, "more than 8 G codes in one block");
        sc.g[sc.ng++] = {code, col};
      } else {
        if (sc.nm == 8) return fail(col, "more than 8 M codes in one block");
        sc.m[sc.nm++] = {code, col};
      }
      continue;
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
    if (std::isinf(w.value))
      return fail(col, std::string("value of ") + L + " overflows (more than 1.8e308)");
  }
  return true;
}

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
  const Scan& s = sc;
  // -- G codes: one per modal group, all known.
  std::uint32_t group_col[100] = {};
  int group_code[100] = {};
  int motion_code = -1;
  std::uint32_t motion_col = 0;
  bool g4 = false, g275 = false;
  for (int i = 0; i < s.ng; ++i) {
    const int code = s.g[i].code;
    const int grp = g_group(code);
    if (grp == kGUnsupported) return fail(s.g[i].col, unsupported_g(code));
    if (grp != kGNonModal) {
      if (group_col[grp] != 0)
        return fail(s.g[i].col, code_text('G', group_code[grp]) + " and " + code_text('G', code) +
                                    " in one block belong to the same modal group: keep one");
      group_col[grp] = s.g[i].col;
      group_code[grp] = code;
    } else {
      if ((code == 40 && g4) || (code == 2750 && g275))
        return fail(s.g[i].col, code_text('G', code) + " appears twice in one block");
      g4 = g4 || code == 40;
      g275 = g275 || code == 2750;
    }
    if (grp == kGMotion) {
      motion_code = code;
      motion_col = s.g[i].col;
    }
  }
  if (g4 && g275) return fail(s.g[0].col, "G4 and G275 in one block: keep one");
  if ((g4 || g275) && motion_code >= 0)
    return fail(motion_col, code_text('G', motion_code) + " and " + (g4 ? "G4" : "G275") +
                                " in one block: a dwell or cycle block cannot also set the motion mode");

  // -- M codes: at most one per group (M7 with M8 is allowed: both coolants on).
  int m_code[100] = {};
  std::uint32_t m_col[100] = {};
  bool mist = false, flood = false, coolant_off = false;
  for (int i = 0; i < s.nm; ++i) {
    const int code = s.m[i].code;
    const int grp = m_group(code);
    if (grp == kMUnsupported) return fail(s.m[i].col, unsupported_m(code));
    if (grp == kMCoolant) {
      bool& f = code == 70 ? mist : code == 80 ? flood : coolant_off;
      if (f) return fail(s.m[i].col, code_text('M', code) + " appears twice in one block");
      f = true;
      continue;
    }
    if (m_col[grp] != 0)
      return fail(s.m[i].col, code_text('M', m_code[grp]) + " and " + code_text('M', code) +
                                  " in one block belong to the same modal group: keep one");
    m_col[grp] = s.m[i].col;
    m_code[grp] = code;
  }

  // -- State changes, in the order a control executes them (LinuxCNC's "order of execution"),
  // except units, which apply to every number of the block.
  if (group_col[kGUnits]) ns.units = group_code[kGUnits] == 200 ? Units::kInch : Units::kMillimetre;
  const double unit = ns.units == Units::kInch ? kInch : 1.0;
  if (s.has('N')) {
    const Word& w = s.w('N');
    if (w.value < 0 || w.value > 99999999 || w.value != std::floor(w.value))
      return fail(w.col, "block number N" + show(w.value) + " is not a whole number 0..99999999");
  }

  if (group_col[kGFeedMode]) ns.feed_mode = group_code[kGFeedMode] == 930 ? FeedMode::kInverseTime : FeedMode::kUnitsPerMinute;
  if (s.has('F')) {
    const Word& f = s.w('F');
    if (f.value < 0) return fail(f.col, "feed F" + show(f.value) + " is negative");
    const double v = ns.feed_mode == FeedMode::kInverseTime ? f.value : f.value * unit;
    if (v > kMaxFeed) return fail(f.col, "feed F" + show(f.value) + " is out of range (at most 1000000 mm/min)");
    ns.feed = v;
  } else if (group_col[kGFeedMode] && ns.feed_mode != st.feed_mode) {
    ns.feed = 0;  // switching G93/G94 invalidates the feed: it means something else now
  }
  if (s.has('S')) {
    const Word& w = s.w('S');
    if (w.value < 0 || w.value > kMaxSpindle)
      return fail(w.col, "spindle speed S" + show(w.value) + " is out of range (0..1000000 rev/min)");
    ns.spindle_speed = w.value;
  }
  if (s.has('T')) {
    const Word& w = s.w('T');
    if (w.value < 0 || w.value > 9999 || w.value != std::floor(w.value))
      return fail(w.col, "tool number T" + show(w.value) + " is not a whole number 0..9999");
    ns.tool = static_cast<std::int32_t>(w.value);
  }
  b.tool_change = m_col[kMToolChange] != 0;
  if (b.tool_change) ns.tool_in_spindle = ns.tool;
  if (m_col[kMSpindle]) ns.spindle = m_code[kMSpindle] == 30 ? Spindle::kCW : m_code[kMSpindle] == 40 ? Spindle::kCCW : Spindle::kOff;
  if (coolant_off) ns.coolant = 0;
  if (mist) ns.coolant |= kCoolantMist;
  if (flood) ns.coolant |= kCoolantFlood;
  if (group_col[kGPlane]) ns.plane = static_cast<Plane>(group_code[kGPlane] / 10);
  if (group_col[kGToolLength]) {
    const int code = group_code[kGToolLength];
    if (code == 490) {
      if (s.has('H')) return fail(s.w('H').col, "H with G49: G49 cancels tool length compensation");
      ns.tlo_active = false;
      ns.tlo_h = 0;
      ns.tool_length = 0;
      if (opt.dialect == Dialect::kFanuc) ns.tcp = false;  // G49 ends G43.4 too (one modal group)
      ns.tool_vector_mode = false;
    } else {
      if (code == 435 && opt.dialect == Dialect::kLinuxCnc)
        return fail(group_col[kGToolLength],
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
          return fail(s.has('H') ? s.w('H').col : group_col[kGToolLength],
                      "H" + std::to_string(h) + ": tool " + std::to_string(h) +
                          " is not in the machine config's tool table (add it under machine 'tools')");
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
    }
  } else if (s.has('H')) {
    return fail(s.w('H').col, "H" + show(s.w('H').value) + " without G43, G43.4 or G43.5: H selects a tool length only with them");
  }
  if (m_col[kMKins]) {
    ns.tcp = m_code[kMKins] == 4280;  // M428 TCP on; M429/M430 joint mode
    ns.tool_vector_mode = false;      // M428 is TCP with A C programmed
  }
  if (!ns.tool_vector_mode) {
    ns.tool_vector_set = false;
    ns.tool_vector = {0, 0, 1};
  }
  if (group_col[kGCoordSystem]) {
    ns.work_offset = group_code[kGCoordSystem] / 10;
    ns.origin = machine.work_offsets[static_cast<std::size_t>(ns.work_offset - 54)];
  }
  if (group_col[kGDistance]) ns.incremental = group_code[kGDistance] == 910;
  if (group_col[kGArcDistance]) ns.arc_incremental = group_code[kGArcDistance] == 911;
  if (group_col[kGMotion]) ns.motion = motion_code == 800 ? Motion::kNone
                                       : motion_code == 0  ? Motion::kRapid
                                       : motion_code == 10 ? Motion::kLinear
                                       : motion_code == 20 ? Motion::kArcCW
                                                           : Motion::kArcCCW;
  if (m_col[kMStop]) {
    const int c = m_code[kMStop];
    b.stop = c == 0 ? ProgramStop::kStop : c == 10 ? ProgramStop::kOptionalStop
           : c == 20 ? ProgramStop::kEnd : ProgramStop::kEndRewind;
  }

  // -- Words that only some blocks may carry.
  const bool arc_mode = !g4 && !g275 && (ns.motion == Motion::kArcCW || ns.motion == Motion::kArcCCW);
  // In G43.5, I J K of a block that is not an arc are the tool axis (on arcs they stay centres).
  const bool vector_words = ns.tool_vector_mode && !arc_mode && !g4 && !g275 &&
                            (s.has('I') || s.has('J') || s.has('K'));
  if (ns.tool_vector_mode) {
    for (char L : {'A', 'C'})
      if (s.has(L))
        return fail(s.w(L).col, std::string("rotary word ") + L + show(s.w(L).value) +
                                    " in G43.5 mode: the orientation is the tool vector I J K and the "
                                    "IK chooses A and C; program I J K, or leave G43.5 (G43.4 H, G43 H, G49)");
  }
  for (char L : {'D', 'W', 'Q', 'K', 'I', 'J', 'R', 'P', 'L'}) {
    if (!s.has(L)) continue;
    if (vector_words && (L == 'I' || L == 'J' || L == 'K')) continue;
    const bool slot_word = L == 'D' || L == 'W' || L == 'Q' || L == 'K' || L == 'R' || L == 'P';
    const bool arc_word = L == 'I' || L == 'J' || L == 'K' || L == 'R' || L == 'P';
    const bool dwell_word = L == 'P' && g4;
    const bool path_word = (L == 'P' || L == 'Q') && group_col[kGPathMode] && group_code[kGPathMode] == 640;
    if ((g275 && slot_word) || (arc_mode && arc_word) || dwell_word || path_word) continue;
    std::string where = L == 'L' ? "G10, which is not supported"
                        : L == 'D' || L == 'W' || L == 'Q' ? "the G275 slot cycle"
                        : L == 'P' ? "G4 (dwell), G2/G3 (turns), G64 or G275"
                                   : "G2/G3 arcs (and K, R in G275)";
    return fail(s.w(L).col, std::string("word ") + L + show(s.w(L).value) + " has no meaning here: it is used by " + where);
  }

  // -- Lengths that are not axes (arc centres and radii, cycle parameters): the same range as
  // the axes, so no absurd value can reach the geometry or the writer.
  for (char L : {'I', 'J', 'K', 'R', 'D', 'W', 'Q'}) {
    if (!s.has(L)) continue;
    if (vector_words && (L == 'I' || L == 'J' || L == 'K')) continue;  // checked below
    const Word& w = s.w(L);
    if (std::fabs(linear_value(w, ns.units)) > kMaxLinear)
      return fail(w.col, std::string(1, L) + show(w.value) + " is out of range (|" + L + "| <= " +
                             show(kMaxLinear) + " mm)");
  }

  // -- The tool vector (G43.5): a direction, so absolute in G91 too and without units; an
  // omitted component is 0 (as on Fanuc) and a block without I J K keeps the vector in force.
  Vec3 vector = ns.tool_vector;
  if (vector_words) {
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
  }

  // -- Axis words to targets.
  Axes target = ns.position;
  std::uint8_t mask = 0;
  bool x_as_dwell = g4 && opt.dialect == Dialect::kFanuc && s.has('X');
  for (int a = 0; a < kNumAxes; ++a) {
    const char L = kAxisLetters[a];
    if (!s.has(L) || (x_as_dwell && a == kX)) continue;
    const Word& w = s.w(L);
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
  b.axis_words = mask;
  b.start = ns.position;

  if (g4) {
    if (mask != 0) {
      for (int a = 0; a < kNumAxes; ++a)
        if (mask & (1u << a)) return fail(s.w(kAxisLetters[a]).col, std::string("axis word ") + kAxisLetters[a] + " with G4: a dwell block cannot move");
    }
    double t = 0;
    if (opt.dialect == Dialect::kFanuc) {
      if (s.has('X') && s.has('P')) return fail(s.w('P').col, "G4 with both X (seconds) and P (milliseconds): keep one");
      if (s.has('X')) t = s.w('X').value;
      else if (s.has('P')) t = s.w('P').value / 1000.0;
      else return fail(s.g[0].col, "G4 needs the dwell time: X<seconds> or P<milliseconds>");
    } else {
      if (!s.has('P')) return fail(s.g[0].col, "G4 needs the dwell time: P<seconds>");
      t = s.w('P').value;
    }
    if (t < 0 || t > 1e5) return fail(s.g[0].col, "dwell time " + show(t) + " s is out of range (0..100000 s)");
    b.motion = Motion::kDwell;
    b.dwell = t;
    b.target = ns.position;
    return true;
  }
  if (g275) {
    b.target = target;
    return slot(s, b, ns);
  }

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
  if (ns.motion != Motion::kRapid) {
    const std::uint32_t col = motion_col ? motion_col : (s.has('X') ? s.w('X').col : 1);
    if (ns.feed_mode == FeedMode::kInverseTime && !s.has('F'))
      return fail(col, std::string(ns.motion == Motion::kLinear ? "G1" : ns.motion == Motion::kArcCW ? "G2" : "G3") +
                           " in inverse-time mode (G93) needs F in the same block");
    if (ns.feed <= 0)
      return fail(col, std::string(ns.motion == Motion::kLinear ? "G1" : ns.motion == Motion::kArcCW ? "G2" : "G3") +
                           " without a feed: program F (mm/min) in this block or before it");
  }
  if (ns.tool_vector_mode && !vector_words && !ns.tool_vector_set) {
    const std::uint32_t col = motion_col ? motion_col : s.has('X') ? s.w('X').col : s.has('Y') ? s.w('Y').col : 1;
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

// Centre-format and radius-format arcs, with LinuxCNC's radius tolerance (see
// ../shared/data/gcode/linuxcnc/interp_arc_tolerance/bad__README.arc-radius-tolerance).
bool Parser::Impl::arc(const Scan& s, ResolvedBlock& b, ModalState& ns, bool cw) {
  const PlaneAxes pa = plane_axes(ns.plane);
  const Axes& st0 = ns.position;
  const Axes& end = b.target;
  const double su = st0[pa.u], sv = st0[pa.v], eu = end[pa.u], ev = end[pa.v];
  const bool inch = ns.units == Units::kInch;
  const double t_abs = (inch ? 2 * 0.001 * kInch : 2 * 0.01) * std::numbers::sqrt2;  // [mm]
  const double t_rel = 0.001;
  const char gname[] = {'G', cw ? '2' : '3', 0};
  const std::uint32_t col = s.has('R') ? s.w('R').col : s.has(pa.ou) ? s.w(pa.ou).col : s.has(pa.ov) ? s.w(pa.ov).col : 1;
  int turns = 1;
  if (s.has('P')) {
    const Word& w = s.w('P');
    if (w.value < 1 || w.value > 10000 || w.value != std::floor(w.value))
      return fail(w.col, std::string(gname) + " P" + show(w.value) + ": the number of turns must be a whole number 1..10000");
    turns = static_cast<int>(w.value);
  }
  // The offset letter along the plane normal is not allowed (K in G17 etc.).
  const char normal_letter = pa.n == kZ ? 'K' : pa.n == kY ? 'J' : 'I';
  if (s.has(normal_letter))
    return fail(s.w(normal_letter).col, std::string(1, normal_letter) + " in a " + gname + " block in the " +
                                            (ns.plane == Plane::kXY ? "XY (G17)" : ns.plane == Plane::kZX ? "ZX (G18)" : "YZ (G19)") +
                                            " plane: the centre is given by " + pa.ou + " and " + pa.ov);
  double cu = 0, cv = 0;
  if (s.has('R')) {
    if (s.has(pa.ou) || s.has(pa.ov))
      return fail(col, std::string(gname) + " with both R and a centre (" + pa.ou + "/" + pa.ov + "): keep one");
    const double r = linear_value(s.w('R'), ns.units);
    const double du = eu - su, dv = ev - sv;
    const double chord = std::hypot(du, dv);
    if (chord < 1e-12)
      return fail(col, std::string(gname) + " R" + show(s.w('R').value) +
                           ": the end point equals the start point, so the radius cannot place the centre (use I/J for a full circle)");
    if (r == 0) return fail(col, std::string(gname) + " R0: the radius must not be zero");
    const double half = chord / 2;
    double h2 = r * r - half * half;
    if (h2 < 0) {
      if (half - std::fabs(r) > t_abs)
        return fail(col, std::string(gname) + " R" + show(s.w('R').value) + ": this arc cannot exist, the radius " +
                             show(std::fabs(r)) + " mm is smaller than half the distance from start to end (" +
                             show(half) + " mm)");
      h2 = 0;  // within tolerance: a half circle
    }
    // Centre to the right of start->end for CW with R > 0 (arc of at most 180 deg), else left.
    double h = std::sqrt(h2);
    if (cw == (r < 0)) h = -h;  // left side
    const double mu = (su + eu) / 2, mv = (sv + ev) / 2;
    // right-hand normal of (du, dv) is (dv, -du)
    cu = mu + h * dv / chord;
    cv = mv - h * du / chord;
    if (turns != 1) return fail(s.w('P').col, std::string(gname) + " with R and P: turns need the centre format (I/J/K)");
  } else {
    if (!s.has(pa.ou) && !s.has(pa.ov))
      return fail(col, std::string(gname) + " needs a centre (" + pa.ou + "/" + pa.ov + ") or a radius R in the " +
                           (ns.plane == Plane::kXY ? "XY" : ns.plane == Plane::kZX ? "ZX" : "YZ") + " plane");
    const double ou = s.has(pa.ou) ? linear_value(s.w(pa.ou), ns.units) : 0;
    const double ov = s.has(pa.ov) ? linear_value(s.w(pa.ov), ns.units) : 0;
    if (ns.arc_incremental) {
      cu = su + ou;
      cv = sv + ov;
    } else {
      cu = ou + ns.origin[pa.u];
      cv = ov + ns.origin[pa.v];
    }
    const double r1 = std::hypot(su - cu, sv - cv);
    const double r2 = std::hypot(eu - cu, ev - cv);
    if (r1 < 1e-9) return fail(col, std::string(gname) + ": the centre is at the start point (radius zero)");
    const double abs_err = std::fabs(r1 - r2);
    const double rel_err = abs_err / std::max(r1, r2);
    if (abs_err > 100 * t_abs || (abs_err > t_abs && rel_err > t_rel)) {
      const double k = inch ? 1 / kInch : 1;  // report in the program's units, as LinuxCNC does
      char buf[400];
      const char U = kAxisLetters[pa.u], V = kAxisLetters[pa.v];
      std::snprintf(buf, sizeof buf,
                    "%s: radius to end of arc differs from radius to start: start=(%c%.4f,%c%.4f) "
                    "center=(%c%.4f,%c%.4f) end=(%c%.4f,%c%.4f) r1=%.4f r2=%.4f abs_err=%.4g rel_err=%.4f%% "
                    "(tolerance %.4g %s, or %.4g %s and 0.1%%)",
                    gname, U, (su - ns.origin[pa.u]) * k, V, (sv - ns.origin[pa.v]) * k, U, (cu - ns.origin[pa.u]) * k, V,
                    (cv - ns.origin[pa.v]) * k, U, (eu - ns.origin[pa.u]) * k, V, (ev - ns.origin[pa.v]) * k, r1 * k, r2 * k,
                    abs_err * k, rel_err * 100, 100 * t_abs * k, inch ? "inch" : "mm", t_abs * k, inch ? "inch" : "mm");
      return fail(col, buf);
    }
  }
  b.plane = ns.plane;
  b.centre = {0, 0, 0};
  b.centre[static_cast<std::size_t>(pa.u)] = cu;
  b.centre[static_cast<std::size_t>(pa.v)] = cv;
  b.centre[static_cast<std::size_t>(pa.n)] = st0[pa.n];
  b.radius = std::hypot(su - cu, sv - cv);
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
    if (tool == 0 || it == machine.tools.end())
      return fail(col, "G275 needs the tool diameter: give D, or load a tool (T<n> M6) whose diameter is in the machine config's tool table");
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

Parser::Parser(ParseOptions options, MachineConfig machine, std::string file)
    : impl_(std::make_unique<Impl>(options, std::move(machine), std::move(file))) {}
Parser::~Parser() = default;
Parser::Parser(Parser&&) noexcept = default;
Parser& Parser::operator=(Parser&&) noexcept = default;

const ParseSummary& Parser::summary() const { return impl_->summary; }
const ParseOptions& Parser::options() const { return impl_->opt; }
bool Parser::ended() const { return impl_->st.ended; }

LineStatus Parser::parse_line(std::string_view line, ResolvedBlock& b, Diagnostic& diag,
                              std::size_t overlong_length) {
  Impl& m = *impl_;
  ++m.summary.lines_read;
  m.summary.bytes_read += (overlong_length ? overlong_length : line.size()) + 1;
  const std::uint64_t lineno = m.summary.lines_read;
  auto reject = [&](std::uint32_t col, std::string msg) {
    diag.file = m.file;
    diag.line = lineno;
    diag.column = col;
    diag.severity = Severity::kError;
    diag.message = std::move(msg);
    ++m.summary.lines_rejected;
    return LineStatus::kRejected;
  };
  if (overlong_length > 0 || line.size() > m.opt.max_line_length)
    return reject(static_cast<std::uint32_t>(m.opt.max_line_length + 1),
                  "line is " + std::to_string(overlong_length ? overlong_length : line.size()) +
                      " bytes long; the limit is " + std::to_string(m.opt.max_line_length) +
                      " (parse.max_line_length in the pipeline config)");
  std::size_t p = 0;
  skip_blanks(line, p);
  if (p < line.size() && line[p] == '/') {
    if (m.opt.block_delete) {
      diag.file = m.file;
      diag.line = lineno;
      diag.column = static_cast<std::uint32_t>(p + 1);
      diag.severity = Severity::kNote;
      diag.message = "skipped by block delete ('/' with parse.block_delete on)";
      ++m.summary.lines_deleted;
      return LineStatus::kDeleted;
    }
  }

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

  std::string_view body = line;
  std::string blanked;
  if (p < line.size() && line[p] == '/') {  // block delete off: read the block as if '/' were a blank
    blanked.assign(line);
    blanked[p] = ' ';
    body = blanked;
  }
  if (!m.skipping_sub.empty()) {
    // Inside an unsupported subroutine definition: its lines are not part of the main program.
    std::string lower;
    for (char c : body) if (c != ' ' && c != '\t') lower.push_back(static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c));
    const std::string sub = m.skipping_sub;
    if (lower.rfind("o" + sub + "endsub", 0) == 0) m.skipping_sub.clear();
    return reject(1, "inside subroutine o" + sub + ", which is not supported (see the error at its 'sub' line)");
  }
  if (!m.scan(body, b)) return reject(m.error_col, m.error);
  b.percent = m.sc.percent;
  b.program_number = m.sc.program_number;
  ModalState ns = m.st;
  if (!m.resolve(b, ns)) return reject(m.error_col, m.error);
  if (b.stop == ProgramStop::kEnd || b.stop == ProgramStop::kEndRewind) ns.ended = true;
  m.st = ns;
  for (int i = 0; i < m.sc.nassign; ++i) {
    const Assignment& a = m.sc.assign[i];
    if (a.named) m.params.set_named(a.name, a.value);
    else m.params.set_numbered(a.number, a.value);
  }
  // Publish the modal state in force.
  const ModalState& s = m.st;
  b.plane = b.motion == Motion::kArcCW || b.motion == Motion::kArcCCW ? b.plane : s.plane;
  b.feed = s.feed;
  b.feed_mode = s.feed_mode;
  b.spindle_speed = s.spindle_speed;
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
  b.work_origin = s.origin;
  b.source_units = s.units;
  if (b.motion != Motion::kArcCW && b.motion != Motion::kArcCCW) b.centre = {0, 0, 0};
  if (b.motion != Motion::kTrochoidSlot) b.slot = TrochoidSlot{};
  ++m.summary.blocks_emitted;
  return LineStatus::kBlock;
}

}  // namespace gcpipe
