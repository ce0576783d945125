#include "expression.hpp"

#include <charconv>
#include <cmath>
#include <numbers>

namespace gcpipe {

namespace {

constexpr int kMaxDepth = 64;  // bounds recursion so hostile input cannot overflow the stack
constexpr double kDeg = std::numbers::pi / 180.0;

void skip_blanks(std::string_view s, std::size_t& p) {
  while (p < s.size() && (s[p] == ' ' || s[p] == '\t')) ++p;
}

char lower(char c) { return (c >= 'A' && c <= 'Z') ? static_cast<char>(c - 'A' + 'a') : c; }

// Matches a case-insensitive keyword at p (blanks inside allowed, as LinuxCNC strips them).
bool match_word(std::string_view s, std::size_t p, std::string_view w, std::size_t& end) {
  std::size_t i = p;
  for (char c : w) {
    skip_blanks(s, i);
    if (i >= s.size() || lower(s[i]) != c) return false;
    ++i;
  }
  end = i;
  return true;
}

enum class Op { kNone, kPow, kMul, kDiv, kMod, kAdd, kSub, kEq, kNe, kGt, kGe, kLt, kLe, kAnd, kOr, kXor };

int precedence_of(Op op) {
  switch (op) {
    case Op::kPow: return 4;
    case Op::kMul: case Op::kDiv: case Op::kMod: return 3;
    case Op::kAdd: case Op::kSub: return 2;
    case Op::kEq: case Op::kNe: case Op::kGt: case Op::kGe: case Op::kLt: case Op::kLe: return 1;
    case Op::kAnd: case Op::kOr: case Op::kXor: return 0;
    case Op::kNone: return -1;
  }
  return -1;
}

Op peek_op(std::string_view s, std::size_t p, std::size_t& end) {
  skip_blanks(s, p);
  if (p >= s.size()) return Op::kNone;
  end = p + 1;
  switch (s[p]) {
    case '*':
      if (p + 1 < s.size() && s[p + 1] == '*') {
        end = p + 2;
        return Op::kPow;
      }
      return Op::kMul;
    case '/': return Op::kDiv;
    case '+': return Op::kAdd;
    case '-': return Op::kSub;
    default: break;
  }
  static const std::pair<std::string_view, Op> words[] = {
      {"mod", Op::kMod}, {"eq", Op::kEq}, {"ne", Op::kNe}, {"gt", Op::kGt}, {"ge", Op::kGe},
      {"lt", Op::kLt},   {"le", Op::kLe}, {"and", Op::kAnd}, {"or", Op::kOr}, {"xor", Op::kXor}};
  for (auto [w, op] : words)
    if (match_word(s, p, w, end)) return op;
  return Op::kNone;
}

}  // namespace

std::string normalise_parameter_name(std::string_view raw) {
  std::string out;
  for (char c : raw)
    if (c != ' ' && c != '\t') out.push_back(lower(c));
  return out;
}

bool ParameterStore::get_numbered(int n, double& v) const {
  if (n < (vacancy_ ? 0 : 1) || n > kMaxNumbered) return false;
  v = numbered_[static_cast<std::size_t>(n)];
  return true;
}
bool ParameterStore::get_named(const std::string& name, double& v) const {
  const auto& named = named_map(name);
  auto it = named.find(name);
  if (it == named.end()) return false;
  v = it->second;
  return true;
}
void ParameterStore::set_numbered(int n, double v) {
  numbered_[static_cast<std::size_t>(n)] = v;
  set_[static_cast<std::size_t>(n)] = 1;
}
void ParameterStore::set_named(const std::string& name, double v) { named_map(name)[name] = v; }

bool ParameterStore::is_offset_parameter(int n, bool fanuc) {
  if (n >= 5221 && n <= 5326) return (n - 5221) % 20 <= (fanuc ? 4 : 9);  // G54..G59, per axis
  if (fanuc) return (n >= 5081 && n <= 5085) || (n >= 5201 && n <= 5205);
  return n == 5210 || n == 5220 || (n >= 5400 && n <= 5409);
}

bool ExpressionReader::fail(std::size_t pos, std::string msg) {
  error_ = std::move(msg);
  error_pos_ = pos;
  return false;
}

bool ExpressionReader::number(std::string_view s, std::size_t& p, double& out) {
  char buf[64];
  std::size_t n = 0;
  const std::size_t start = p;
  while (p < s.size() && n < sizeof buf - 1) {
    char c = s[p];
    if ((c >= '0' && c <= '9') || c == '.') {
      buf[n++] = c;
      ++p;
    } else if (c == ' ' || c == '\t') {
      ++p;
    } else {
      break;
    }
  }
  if (n == 0 || (n == 1 && buf[0] == '.')) return fail(start, "expected a number");
  auto [e, ec] = std::from_chars(buf, buf + n, out);
  if (ec != std::errc() || e != buf + n) return fail(start, "malformed number '" + std::string(buf, n) + "'");
  vacant_ = false;
  return true;
}

bool ExpressionReader::parameter(std::string_view s, std::size_t& p, double& out, int depth) {
  // at '#'
  const std::size_t at = p;
  ++p;
  skip_blanks(s, p);
  if (p < s.size() && s[p] == '<') {
    std::size_t close = s.find('>', p);
    if (close == std::string_view::npos) return fail(at, "unterminated parameter name '#<'");
    std::string name = normalise_parameter_name(s.substr(p + 1, close - p - 1));
    p = close + 1;
    if (name.empty()) return fail(at, "empty parameter name '#<>'");
    if (!params_.get_named(name, out))
      return fail(at, "parameter #<" + name + "> is used before it is set" +
                          (ParameterStore::is_global_name(name)
                               ? std::string()
                               : std::string(" (a name without a leading '_' is local to the subroutine call that "
                                             "sets it; #<_" + name + "> would be global)")));
    vacant_ = false;
    return true;
  }
  double idx = 0;
  if (!unary(s, p, idx, depth + 1)) return false;
  const double lowest = params_.vacancy() ? 0 : 1;  // Fanuc #0: always vacant
  if (idx != std::floor(idx) || idx < lowest || idx > ParameterStore::kMaxNumbered)
    return fail(at, "parameter number " + std::to_string(idx) + " is not a whole number in " +
                        std::to_string(static_cast<int>(lowest)) + ".." + std::to_string(ParameterStore::kMaxNumbered));
  const int n = static_cast<int>(idx);
  // Fanuc #1000 and up are system variables (modal state, offsets, clock, ...): reading one as
  // vacant would silently take the wrong branch, so only those gcpipe keeps may be read.
  if (params_.vacancy() && n >= 1000 && (n < 5001 || n > 5005) && !ParameterStore::is_offset_parameter(n, true))
    return fail(at, "system variable #" + std::to_string(n) +
                        " is not modelled (gcpipe keeps #5001..#5005, the position, the G54..G59 origins #5221.., "
                        "the external offset #5201.. and the tool length in force #5081..#5085): expand it in CAM");
  // LinuxCNC's #5400..#5413 describe the loaded tool (number, offsets, diameter, angles): gcpipe's
  // tool table has only length and diameter, so none is read rather than read as 0, but for the
  // tool number #5400 and its length #5403, which compensated.nc's guard reads.
  if (!params_.vacancy() && n >= 5400 && n <= 5413 && !ParameterStore::is_offset_parameter(n, false))
    return fail(at, "parameter #" + std::to_string(n) +
                        " (LinuxCNC's data of the loaded tool) is not modelled: use the tool's values in the program");
  params_.get_numbered(n, out);
  vacant_ = params_.vacant(n);
  return true;
}

// A function call `name[arg]` at p (atan[y]/[x], exists[#<name>]); `matched` false when p does not
// start one.
bool ExpressionReader::function(std::string_view s, std::size_t& p, double& out, int depth, bool& matched) {
  matched = true;
  static const std::string_view names[] = {"abs", "acos", "asin", "atan", "cos", "exp", "fix", "fup",
                                           "round", "ln", "sin", "sqrt", "tan", "exists"};
  for (auto name : names) {
    std::size_t e = 0;
    if (!match_word(s, p, name, e)) continue;
    std::size_t q = e;
    skip_blanks(s, q);
    if (q >= s.size() || s[q] != '[') continue;
    const std::size_t fpos = p;
    p = q + 1;
    if (name == "exists") {
      // exists[#<name>]: 1 when the named parameter has been set.
      skip_blanks(s, p);
      if (p >= s.size() || s[p] != '#') return fail(p, "exists[] takes a parameter such as #<name>");
      ++p;
      skip_blanks(s, p);
      std::size_t close = s.find('>', p);
      if (p >= s.size() || s[p] != '<' || close == std::string_view::npos)
        return fail(p, "exists[] takes a named parameter #<name>");
      double dummy = 0;
      out = params_.get_named(normalise_parameter_name(s.substr(p + 1, close - p - 1)), dummy) ? 1 : 0;
      p = close + 1;
      skip_blanks(s, p);
      if (p >= s.size() || s[p] != ']') return fail(p, "missing ']' after exists[#<name>");
      ++p;
      return true;
    }
    double a = 0;
    if (!expression(s, p, a, depth + 1)) return false;
    if (name == "atan") {
      skip_blanks(s, p);
      if (p >= s.size() || s[p] != '/') return fail(p, "atan needs two arguments: atan[y]/[x]");
      ++p;
      skip_blanks(s, p);
      if (p >= s.size() || s[p] != '[') return fail(p, "atan needs two arguments: atan[y]/[x]");
      ++p;
      double b = 0;
      if (!expression(s, p, b, depth + 1)) return false;
      out = std::atan2(a, b) / kDeg;
      return true;
    }
    if (name == "abs") out = std::fabs(a);
    else if (name == "acos") out = std::acos(a) / kDeg;
    else if (name == "asin") out = std::asin(a) / kDeg;
    else if (name == "cos") out = std::cos(a * kDeg);
    else if (name == "sin") out = std::sin(a * kDeg);
    else if (name == "tan") out = std::tan(a * kDeg);
    else if (name == "exp") out = std::exp(a);
    else if (name == "fix") out = std::floor(a);
    else if (name == "fup") out = std::ceil(a);
    else if (name == "round") out = std::round(a);
    else if (name == "ln") out = std::log(a);
    else if (name == "sqrt") out = std::sqrt(a);
    if (!std::isfinite(out))
      return fail(fpos, std::string(name) + "[" + std::to_string(a) + "] is not a finite number");
    return true;
  }
  matched = false;
  return true;
}

bool ExpressionReader::unary(std::string_view s, std::size_t& p, double& out, int depth) {
  if (depth > kMaxDepth) return fail(p, "expression nested too deeply");
  skip_blanks(s, p);
  if (p >= s.size()) return fail(p, "expression ends too early");
  const char c = s[p];
  if (c == '[') {
    ++p;
    if (!expression(s, p, out, depth + 1)) return false;
    return true;
  }
  if (c == '-' || c == '+') {
    ++p;
    if (!unary(s, p, out, depth + 1)) return false;
    if (c == '-') out = -out;  // a sign keeps vacancy: X-#1 with #1 vacant is no X word, as X#1
    return true;
  }
  if (c == '#') return parameter(s, p, out, depth);
  if ((c >= '0' && c <= '9') || c == '.') return number(s, p, out);
  // Functions: name [arg] (atan takes [y]/[x]).
  bool matched = false;
  if (!function(s, p, out, depth, matched)) return false;
  if (matched) {
    vacant_ = false;  // its arguments' vacancy is not the value's
    return true;
  }
  return fail(p, std::string("unexpected '") + c + "' in expression");
}

bool ExpressionReader::binary(std::string_view s, std::size_t& p, double& out, int min_prec, int depth) {
  if (depth > kMaxDepth) return fail(p, "expression nested too deeply");
  if (!unary(s, p, out, depth + 1)) return false;
  bool out_vacant = vacant_;
  for (;;) {
    std::size_t end = 0;
    Op op = peek_op(s, p, end);
    int prec = precedence_of(op);
    if (op == Op::kNone || prec < min_prec) {
      vacant_ = out_vacant;
      return true;
    }
    const std::size_t op_pos = p;
    p = end;
    double rhs = 0;
    // ** is right-associative; the others left-associative.
    if (!binary(s, p, rhs, op == Op::kPow ? prec : prec + 1, depth + 1)) return false;
    const bool rhs_vacant = vacant_;
    // Fanuc: vacant reads 0 in arithmetic and in GT GE LT LE, but EQ and NE tell it from 0.
    const bool lhs_vacant = out_vacant, both_values = !lhs_vacant && !rhs_vacant;
    out_vacant = false;
    switch (op) {
      case Op::kPow: out = std::pow(out, rhs); break;
      case Op::kMul: out *= rhs; break;
      case Op::kDiv:
        if (rhs == 0) return fail(op_pos, "division by zero in expression");
        out /= rhs;
        break;
      case Op::kMod:
        if (rhs == 0) return fail(op_pos, "MOD by zero in expression");
        out = std::fmod(out, rhs);
        if (out < 0) out += std::fabs(rhs);  // LinuxCNC returns a non-negative remainder
        break;
      case Op::kAdd: out += rhs; break;
      case Op::kSub: out -= rhs; break;
      case Op::kEq: out = both_values ? out == rhs : lhs_vacant == rhs_vacant; break;
      case Op::kNe: out = both_values ? out != rhs : lhs_vacant != rhs_vacant; break;
      case Op::kGt: out = out > rhs; break;
      case Op::kGe: out = out >= rhs; break;
      case Op::kLt: out = out < rhs; break;
      case Op::kLe: out = out <= rhs; break;
      case Op::kAnd: out = (out != 0) && (rhs != 0); break;
      case Op::kOr: out = (out != 0) || (rhs != 0); break;
      case Op::kXor: out = (out != 0) != (rhs != 0); break;
      case Op::kNone: break;
    }
    if (!std::isfinite(out)) return fail(op_pos, "expression result is not a finite number (overflow)");
  }
}

bool ExpressionReader::expression(std::string_view s, std::size_t& p, double& out, int depth) {
  // after '['
  if (!binary(s, p, out, 0, depth)) return false;
  skip_blanks(s, p);
  if (p >= s.size() || s[p] != ']') return fail(p, "missing ']' in expression");
  ++p;
  return true;
}

bool ExpressionReader::read_value(std::string_view line, std::size_t& pos, double& out) {
  return unary(line, pos, out, 0);
}

bool ExpressionReader::read_expression(std::string_view line, std::size_t& pos, double& out) {
  return binary(line, pos, out, 0, 0);
}

bool ExpressionReader::read_target(std::string_view s, std::size_t& p, Assignment& t) {
  const std::size_t at = p;
  skip_blanks(s, p);
  if (p < s.size() && s[p] == '<') {
    std::size_t close = s.find('>', p);
    if (close == std::string_view::npos) return fail(at, "unterminated parameter name '#<'");
    t.named = true;
    t.name = normalise_parameter_name(s.substr(p + 1, close - p - 1));
    p = close + 1;
    if (t.name.empty()) return fail(at, "empty parameter name '#<>'");
    return true;
  }
  double idx = 0;
  if (!unary(s, p, idx, 1)) return false;
  if (idx == 0 && params_.vacancy()) return fail(at, "#0 is the vacant variable: it cannot be set (use it to clear one: #1 = #0)");
  if (idx != std::floor(idx) || idx < 1 || idx > ParameterStore::kMaxNumbered)
    return fail(at, "parameter number " + std::to_string(idx) + " is not a whole number in 1.." +
                        std::to_string(ParameterStore::kMaxNumbered));
  t.named = false;
  t.number = static_cast<int>(idx);
  return true;
}

}  // namespace gcpipe
