#include "gcpipe/number_format.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>

namespace gcpipe {

void append_shortest(std::string& out, double v) {
  if (v == 0) v = 0;  // folds -0 into 0 so that "-0." never appears
  // G-code has no exponent, so the shortest digits are spelled out in fixed notation: 1e308 has
  // 309 digits before the point, 5e-324 has 323 zeros after it. 400 bytes hold either.
  char buf[400];
  auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed);
  if (ec != std::errc()) {  // not finite: never written by a stage, but never garbage either
    out += v != v ? "nan" : v > 0 ? "inf" : "-inf";
    return;
  }
  std::string_view s(buf, static_cast<std::size_t>(end - buf));
  out.append(s);
  if (s.find('.') == std::string_view::npos) out.push_back('.');
}

void append_fixed(std::string& out, double v, int decimals) {
  // Fixed notation of the largest double needs 309 digits before the point: size for it rather
  // than trust a return value that reports what would have been written.
  char buf[400];
  auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, decimals);
  if (ec != std::errc()) {  // cannot happen for finite v and decimals <= 9; keep the text honest
    append_shortest(out, v);
    return;
  }
  std::string_view s(buf, static_cast<std::size_t>(end - buf));
  if (s.find('.') != std::string_view::npos) {
    while (s.back() == '0') s.remove_suffix(1);
  }
  if (s == "-0." || s == "-0") s = "0.";
  out.append(s);
  if (s.find('.') == std::string_view::npos) out.push_back('.');
}

void append_json_number(std::string& out, double v) {
  if (!std::isfinite(v)) {
    out += "null";
    return;
  }
  char buf[32];
  auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
  (void)ec;
  out.append(buf, end);
}

void append_json_string(std::string& out, const std::string& s) {
  out.push_back('"');
  for (unsigned char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
      default:
        if (c < 0x20 || c >= 0x80) {  // bytes >= 0x80 read as Latin-1: JSON stays valid UTF-8
          char b[8];
          std::snprintf(b, sizeof b, "\\u%04x", c);
          out += b;
        } else {
          out.push_back(static_cast<char>(c));
        }
    }
  }
  out.push_back('"');
}

}  // namespace gcpipe
