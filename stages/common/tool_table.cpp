// Tool tables from files: LinuxCNC's .tbl text format and a YAML mapping like the machine file's.
#include <cmath>
#include <fstream>
#include <sstream>

#include "gcpipe/config.hpp"
#include "gcpipe/machine.hpp"

namespace gcpipe {

namespace {

[[noreturn]] void table_error(const std::filesystem::path& path, std::size_t line, const std::string& what) {
  throw ConfigError(path.string() + ":" + std::to_string(line) + ": tool table: " + what);
}

// One .tbl line: words letter+number separated by blanks, ';' starts a comment. LinuxCNC writes
// T P X Y Z A B C U V W D I J Q; gcpipe uses T (number), Z (length) and D (diameter).
void read_tbl_line(const std::filesystem::path& path, std::size_t n, std::string_view text,
                   std::map<int, ToolEntry>& out) {
  if (const auto semi = text.find(';'); semi != std::string_view::npos) text = text.substr(0, semi);
  std::istringstream in{std::string(text)};
  std::string word;
  int tool = -1;
  ToolEntry e;
  bool any = false;
  while (in >> word) {
    any = true;
    const char L = static_cast<char>(word[0] & ~0x20);
    double v = 0;
    std::size_t used = 0;
    try {
      v = std::stod(word.substr(1), &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (word.size() < 2 || used != word.size() - 1 || !std::isfinite(v))
      table_error(path, n, "'" + word + "' is not a letter followed by a number");
    if (L == 'T') {
      if (v < 1 || v > 9999 || v != std::floor(v)) table_error(path, n, "tool number " + word + " is not a whole number 1..9999");
      tool = static_cast<int>(v);
    } else if (L == 'Z') {
      if (std::fabs(v) > 1000) table_error(path, n, "length " + word + " is out of range (|Z| <= 1000 mm)");
      e.length = v;
    } else if (L == 'D') {
      if (v < 0 || v > 500) table_error(path, n, "diameter " + word + " is out of range (0..500 mm)");
      e.diameter = v;
    } else if (std::string_view("PXYABCUVWIJQ").find(L) == std::string_view::npos) {
      table_error(path, n, "unknown word '" + word + "' (LinuxCNC tool tables have T P X Y Z A B C U V W D I J Q)");
    }
  }
  if (!any) return;
  if (tool < 0) table_error(path, n, "the line has no T number");
  if (out.count(tool)) table_error(path, n, "tool T" + std::to_string(tool) + " appears twice");
  out[tool] = e;
}

std::map<int, ToolEntry> load_tbl(const std::filesystem::path& path) {
  std::ifstream f(path);
  if (!f) throw ConfigError(path.string() + ": cannot read the tool table");
  std::map<int, ToolEntry> out;
  std::string line;
  for (std::size_t n = 1; std::getline(f, line); ++n) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    read_tbl_line(path, n, line, out);
  }
  return out;
}

std::map<int, ToolEntry> load_yaml_table(const std::filesystem::path& path) {
  const Config root = Config::load_file(path);
  root.reject_unknown({"tools"});
  std::map<int, ToolEntry> out;
  const Config tools = root.section("tools");
  for (const auto& key : tools.keys()) {
    const int number = tool_number(tools, key);
    const Config t = tools.section(key);
    t.reject_unknown({"length", "diameter", "name"});
    ToolEntry e;
    e.length = t.number("length", "mm", -1000, 1000);
    e.diameter = t.number("diameter", 0, "mm", 0, 500);
    out[number] = e;
  }
  return out;
}

}  // namespace

int tool_number(const Config& tools, const std::string& key) {
  int number = 0;
  try {
    std::size_t used = 0;
    number = std::stoi(key, &used);
    if (used != key.size() || number < 1 || number > 9999) throw std::invalid_argument(key);
  } catch (const std::exception&) {
    throw tools.error(key, "tool numbers are whole numbers from 1 to 9999");
  }
  return number;
}

std::map<int, ToolEntry> load_tool_table(const std::filesystem::path& path) {
  return path.extension() == ".tbl" ? load_tbl(path) : load_yaml_table(path);
}

void merge_tool_table(MachineConfig& machine, const std::filesystem::path& path) {
  for (const auto& [n, e] : load_tool_table(path)) machine.tools[n] = e;
  machine.tool_table_source = path.string();
}

std::string tool_table_name(const MachineConfig& machine) {
  return machine.tool_table_source.empty() ? "the machine config's tool table (machine 'tools')"
                                           : "tool table " + machine.tool_table_source;
}

}  // namespace gcpipe
