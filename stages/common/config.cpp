#include "gcpipe/config.hpp"

#include <algorithm>

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <sstream>

namespace gcpipe {

struct Config::Impl {
  YAML::Node node;   // a mapping (or null for an empty section)
  std::string file;
  std::string path;  // dotted, from the root
};

namespace {

std::string join(const std::string& path, std::string_view key) {
  return path.empty() ? std::string(key) : path + "." + std::string(key);
}

std::string where(const std::string& file, const YAML::Node& n) {
  std::ostringstream s;
  s << file;
  if (n.IsDefined() && n.Mark().line >= 0) s << ':' << n.Mark().line + 1 << ':' << n.Mark().column + 1;
  return s.str();
}

std::string shown(const YAML::Node& n) {
  if (n.IsScalar()) return "'" + n.Scalar() + "'";
  if (n.IsSequence()) return "a list";
  if (n.IsMap()) return "a mapping";
  return "nothing";
}

// yaml-cpp keeps every pair of a mapping but looks keys up in the first one, so a repeated key
// would silently lose its second value: reject it, naming both places.
// yaml-cpp shares an aliased node instead of copying it, so a file of a few lines can name 10^9
// values (each alias of an alias of ...); walking them took a minute. Every value a walk meets is
// counted, an alias each time it is used, and a file past this many is refused at once.
constexpr std::size_t kMaxConfigValues = 1000000;

void reject_duplicate_keys(const std::string& file, const YAML::Node& n, const std::string& path,
                           std::size_t& values) {
  if (++values > kMaxConfigValues)
    throw ConfigError(file + ": more than " + std::to_string(kMaxConfigValues) +
                      " values, counting each use of an alias (&anchor / *alias) as a copy: a config holds "
                      "far fewer; write the values out instead of nesting aliases");
  if (n.IsSequence())
    for (const auto& item : n) reject_duplicate_keys(file, item, path, values);
  if (!n.IsMap()) return;
  std::vector<std::pair<std::string, YAML::Node>> seen;
  for (const auto& kv : n) {
    const std::string key = kv.first.IsScalar() ? kv.first.Scalar() : std::string();
    for (const auto& [k, first] : seen)
      if (k == key)
        throw ConfigError(where(file, kv.first) + ": key '" + join(path, key) + "' appears twice (first at line " +
                          std::to_string(first.Mark().line + 1) + "): keep one of them");
    seen.emplace_back(key, kv.first);
    reject_duplicate_keys(file, kv.second, join(path, key), values);
  }
}

void reject_duplicate_keys(const std::string& file, const YAML::Node& root) {
  std::size_t values = 0;
  reject_duplicate_keys(file, root, "", values);
}

thread_local ConfigReadLog* active_log = nullptr;

std::string number_text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.15g", v);
  return buf;
}

}  // namespace

ConfigReadLog::ConfigReadLog() : outer_(active_log) { active_log = this; }
ConfigReadLog::~ConfigReadLog() { active_log = outer_; }
void ConfigReadLog::note(ConfigRead read) {
  if (active_log) active_log->reads_.push_back(std::move(read));
}

void Config::note(std::string_view key, std::string value, bool defaulted) const {
  if (active_log) ConfigReadLog::note({impl_->file, join(impl_->path, key), std::move(value), defaulted});
}

Config::Config() : impl_(std::make_shared<Impl>()) {}
Config::~Config() = default;
Config::Config(const Config&) = default;
Config& Config::operator=(const Config&) = default;
Config::Config(std::shared_ptr<const Impl> impl) : impl_(std::move(impl)) {}

Config Config::load_file(const std::filesystem::path& path) {
  auto impl = std::make_shared<Impl>();
  impl->file = path.string();
  if (std::filesystem::is_directory(path))
    throw ConfigError(path.string() + ": is a directory, not a config file (check the path given with --config)");
  try {
    impl->node = YAML::LoadFile(path.string());
    reject_duplicate_keys(impl->file, impl->node);
  } catch (const YAML::BadFile&) {
    throw ConfigError(path.string() + ": cannot open config file (check the path given with --config)");
  } catch (const YAML::Exception& e) {
    throw ConfigError(path.string() + ":" + std::to_string(e.mark.line + 1) + ":" +
                      std::to_string(e.mark.column + 1) + ": not valid YAML: " + e.msg);
  }
  if (impl->node.IsDefined() && !impl->node.IsNull() && !impl->node.IsMap())
    throw ConfigError(path.string() + ": the top level must be a mapping of keys to values");
  return Config(std::move(impl));
}

Config Config::from_string(std::string_view yaml, std::string name) {
  auto impl = std::make_shared<Impl>();
  impl->file = std::move(name);
  try {
    impl->node = YAML::Load(std::string(yaml));
    reject_duplicate_keys(impl->file, impl->node);
  } catch (const YAML::Exception& e) {
    throw ConfigError(impl->file + ":" + std::to_string(e.mark.line + 1) + ":" +
                      std::to_string(e.mark.column + 1) + ": not valid YAML: " + e.msg);
  }
  if (impl->node.IsDefined() && !impl->node.IsNull() && !impl->node.IsMap())
    throw ConfigError(impl->file + ": the top level must be a mapping of keys to values");
  return Config(std::move(impl));
}

ConfigError Config::error(std::string_view key, const std::string& reason) const {
  // Assigning to a Node obtained from operator[] of a missing key throws InvalidNode in yaml-cpp,
  // so choose the node to point at before constructing it.
  const bool present = impl_->node.IsMap() && impl_->node[std::string(key)].IsDefined();
  YAML::Node n = present ? impl_->node[std::string(key)] : impl_->node;
  return ConfigError(where(impl_->file, n) + ": key '" + join(impl_->path, key) + "': " + reason);
}

bool Config::has(std::string_view key) const {
  return impl_->node.IsMap() && impl_->node[std::string(key)].IsDefined() &&
         !impl_->node[std::string(key)].IsNull();
}

bool Config::is_mapping(std::string_view key) const {
  return has(key) && impl_->node[std::string(key)].IsMap();
}

Config Config::section(std::string_view key) const {
  auto impl = std::make_shared<Impl>();
  impl->file = impl_->file;
  impl->path = join(impl_->path, key);
  if (has(key)) {
    YAML::Node n = impl_->node[std::string(key)];
    if (!n.IsMap()) throw error(key, "expected a mapping of keys to values, found " + shown(n));
    impl->node = n;
  }
  return Config(std::move(impl));
}

std::vector<std::string> Config::keys() const {
  std::vector<std::string> out;
  if (!impl_->node.IsMap()) return out;
  for (const auto& kv : impl_->node) out.push_back(kv.first.as<std::string>());
  return out;
}

void Config::reject_unknown(std::initializer_list<std::string_view> known) const {
  for (const auto& k : keys()) {
    bool ok = false;
    for (auto kn : known) ok = ok || kn == k;
    if (!ok) {
      std::string list;
      for (auto kn : known) list += (list.empty() ? "" : ", ") + std::string(kn);
      throw error(k, "unknown key (known here: " + list + ")");
    }
  }
}

namespace {

bool parse_double(const YAML::Node& n, double& out) {
  if (!n.IsScalar()) return false;
  try {
    out = n.as<double>();
  } catch (const YAML::Exception&) {
    return false;
  }
  return true;
}

std::string range_text(double min, double max, std::string_view unit) {
  std::ostringstream s;
  s.precision(10);
  s << "[" << min << ", " << max << "]" << (unit.empty() ? "" : " ") << unit;
  return s.str();
}

}  // namespace

double Config::number(std::string_view key, double fallback, std::string_view unit, double min,
                      double max) const {
  if (!has(key)) {
    note(key, number_text(fallback), true);
    return fallback;
  }
  return number(key, unit, min, max);
}

double Config::number(std::string_view key, std::string_view unit, double min, double max) const {
  if (!has(key)) throw error(key, "required number (" + range_text(min, max, unit) + ") is missing");
  YAML::Node n = impl_->node[std::string(key)];
  double v = 0;
  if (!parse_double(n, v)) throw error(key, "value " + shown(n) + " is not a number");
  if (!std::isfinite(v)) throw error(key, "value " + shown(n) + " is not finite");
  if (v < min || v > max)
    throw error(key, "value " + shown(n) + " is outside the valid range " + range_text(min, max, unit));
  note(key, number_text(v), false);
  return v;
}

std::int64_t Config::integer(std::string_view key, std::int64_t fallback, std::int64_t min,
                             std::int64_t max) const {
  if (!has(key)) {
    note(key, std::to_string(fallback), true);
    return fallback;
  }
  YAML::Node n = impl_->node[std::string(key)];
  std::int64_t v = 0;
  try {
    v = n.as<std::int64_t>();
  } catch (const YAML::Exception&) {
    throw error(key, "value " + shown(n) + " is not a whole number");
  }
  if (v < min || v > max)
    throw error(key, "value " + shown(n) + " is outside the valid range [" + std::to_string(min) +
                         ", " + std::to_string(max) + "]");
  note(key, std::to_string(v), false);
  return v;
}

bool Config::boolean(std::string_view key, bool fallback) const {
  if (!has(key)) {
    note(key, fallback ? "true" : "false", true);
    return fallback;
  }
  YAML::Node n = impl_->node[std::string(key)];
  try {
    const bool v = n.as<bool>();
    note(key, v ? "true" : "false", false);
    return v;
  } catch (const YAML::Exception&) {
    throw error(key, "value " + shown(n) + " is not true or false");
  }
}

std::string Config::string(std::string_view key, std::string fallback) const {
  if (!has(key)) {
    note(key, fallback, true);
    return fallback;
  }
  YAML::Node n = impl_->node[std::string(key)];
  if (!n.IsScalar()) throw error(key, "expected text, found " + shown(n));
  note(key, n.Scalar(), false);
  return n.Scalar();
}

std::string Config::choice(std::string_view key, std::string fallback,
                           std::initializer_list<std::string_view> allowed) const {
  std::string v = string(key, fallback);
  for (auto a : allowed)
    if (a == v) return v;
  std::string list;
  for (auto a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
  throw error(key, "value '" + v + "' is not one of: " + list);
}

std::vector<double> Config::numbers(std::string_view key, std::size_t n, std::string_view unit,
                                    double min, double max) const {
  if (!has(key)) throw error(key, "required list of numbers is missing");
  YAML::Node node = impl_->node[std::string(key)];
  if (!node.IsSequence()) throw error(key, "expected a list of numbers, found " + shown(node));
  if (n != 0 && node.size() != n)
    throw error(key, "expected " + std::to_string(n) + " numbers, found " + std::to_string(node.size()));
  std::vector<double> out;
  for (std::size_t i = 0; i < node.size(); ++i) {
    double v = 0;
    if (!parse_double(node[i], v) || !std::isfinite(v))
      throw error(key, "element " + std::to_string(i + 1) + " (" + shown(node[i]) + ") is not a finite number");
    if (v < min || v > max)
      throw error(key, "element " + std::to_string(i + 1) + " (" + shown(node[i]) +
                           ") is outside the valid range " + range_text(min, max, unit));
    out.push_back(v);
  }
  std::string text;
  for (double v : out) text += (text.empty() ? "[" : ", ") + number_text(v);
  note(key, text.empty() ? "[]" : text + "]", false);
  return out;
}

std::vector<std::string> Config::strings(std::string_view key, const std::vector<std::string>& allowed) const {
  if (!has(key)) throw error(key, "required list of names is missing");
  YAML::Node node = impl_->node[std::string(key)];
  if (!node.IsSequence() || node.size() == 0) throw error(key, "expected a list of names, found " + shown(node));
  std::vector<std::string> out;
  for (std::size_t i = 0; i < node.size(); ++i) {
    if (!node[i].IsScalar()) throw error(key, "element " + std::to_string(i + 1) + " (" + shown(node[i]) + ") is not a name");
    const std::string v = node[i].Scalar();
    if (!allowed.empty() && std::find(allowed.begin(), allowed.end(), v) == allowed.end()) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      throw error(key, "element " + std::to_string(i + 1) + " '" + v + "' is not one of: " + list);
    }
    out.push_back(v);
  }
  std::string text;
  for (const auto& v : out) text += (text.empty() ? "[" : ", ") + v;
  note(key, text + "]", false);
  return out;
}

const std::string& Config::path() const { return impl_->path; }
const std::string& Config::file() const { return impl_->file; }

std::filesystem::path Config::file_path(std::string_view key, std::string_view what) const {
  const std::string rel = string(key, "");
  if (rel.empty()) throw error(key, "is empty: name " + std::string(what));
  const std::filesystem::path p = resolve(rel);
  if (std::filesystem::is_directory(p))
    throw error(key, "'" + rel + "' is a directory (" + p.string() + "): name " + std::string(what));
  if (!std::filesystem::is_regular_file(p))
    throw error(key, "'" + rel + "': no such file (" + p.string() + ", relative to " +
                         std::filesystem::path(impl_->file).parent_path().string() + "): name " + std::string(what));
  return p;
}

std::filesystem::path Config::dir_path(std::string_view key, std::string_view what) const {
  const std::string rel = string(key, "");
  if (rel.empty()) throw error(key, "is empty: name " + std::string(what));
  const std::filesystem::path p = resolve(rel);
  if (!std::filesystem::is_directory(p))
    throw error(key, "'" + rel + "': no such folder (" + p.string() + ", relative to " +
                         std::filesystem::path(impl_->file).parent_path().string() + "): name " + std::string(what));
  return p;
}

std::filesystem::path Config::resolve(const std::string& relative) const {
  std::filesystem::path p(relative);
  if (p.is_absolute()) return p;
  return std::filesystem::path(impl_->file).parent_path() / p;
}

}  // namespace gcpipe
