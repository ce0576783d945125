#include <charconv>
#include <cmath>
#include <iostream>

#include "command.hpp"

namespace gcpipe::cli {

Args::Args(const std::vector<std::string>& args, std::initializer_list<std::string_view> with_value,
           std::initializer_list<std::string_view> flags) {
  auto in = [](std::initializer_list<std::string_view> l, std::string_view s) {
    for (auto x : l)
      if (x == s) return true;
    return false;
  };
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "-h" || a == "--help") {
      help_ = true;
    } else if (a.size() > 1 && a[0] == '-' && !(a.size() > 1 && (std::isdigit(static_cast<unsigned char>(a[1])) || a[1] == '.'))) {
      std::string name = a, val;
      bool inline_val = false;
      if (auto eq = a.find('='); eq != std::string::npos) {
        name = a.substr(0, eq);
        val = a.substr(eq + 1);
        inline_val = true;
      }
      if (in(with_value, name)) {
        if (!inline_val) {
          if (i + 1 >= args.size()) {
            error_ = "option " + name + " needs a value";
            return;
          }
          val = args[++i];
        }
        values_.emplace_back(name, val);
      } else if (in(flags, name) && !inline_val) {
        flags_.push_back(name);
      } else {
        std::string known;
        for (auto x : with_value) known += " " + std::string(x) + " <value>";
        for (auto x : flags) known += " " + std::string(x);
        error_ = "unknown option '" + a + "' (accepted:" + known + ")";
        return;
      }
    } else {
      positional_.push_back(a);
    }
  }
}

bool Args::flag(std::string_view name) const {
  for (const auto& f : flags_)
    if (f == name) return true;
  return false;
}

std::optional<std::string> Args::value(std::string_view name) const {
  std::optional<std::string> out;
  for (const auto& [k, v] : values_)
    if (k == name) out = v;  // the last one wins, as in most shells' tools
  return out;
}

std::string Args::value_or(std::string_view name, std::string fallback) const {
  auto v = value(name);
  return v ? *v : fallback;
}

double Args::number_or(std::string_view name, double fallback) {
  auto v = value(name);
  if (!v) return fallback;
  double d = 0;
  auto [p, ec] = std::from_chars(v->data(), v->data() + v->size(), d);
  if (ec != std::errc() || p != v->data() + v->size() || !std::isfinite(d)) {
    error_ = "option " + std::string(name) + ": '" + *v + "' is not a number";
    return fallback;
  }
  return d;
}

int usage_error(const Command& cmd, const std::string& message) {
  std::cerr << "gcpipe " << cmd.name << ": " << message << "\n"
            << "Try 'gcpipe " << cmd.name << " --help'.\n";
  return 2;
}

}  // namespace gcpipe::cli
