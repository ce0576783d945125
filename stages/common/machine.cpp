#include "gcpipe/machine.hpp"

#include "gcpipe/config.hpp"

namespace gcpipe {

MachineConfig load_machine(const Config& m) {
  MachineConfig out;
  m.reject_unknown({"name", "work_offsets", "tools", "tool_table", "reference_positions", "initial_position",
                    "start_position", "kinematics", "limits"});
  out.name = m.string("name", "unnamed");
  if (m.has("work_offsets")) {
    Config wo = m.section("work_offsets");
    wo.reject_unknown({"G54", "G55", "G56", "G57", "G58", "G59"});
    static const char* names[6] = {"G54", "G55", "G56", "G57", "G58", "G59"};
    for (int i = 0; i < 6; ++i) {
      if (!wo.has(names[i])) continue;
      auto v = wo.numbers(names[i], kNumAxes, "mm or deg (X Y Z A C)", -1e5, 1e5);
      for (int a = 0; a < kNumAxes; ++a) out.work_offsets[static_cast<std::size_t>(i)][static_cast<std::size_t>(a)] = v[static_cast<std::size_t>(a)];
    }
  }
  if (m.has("tools")) {
    Config tools = m.section("tools");
    for (const auto& key : tools.keys()) {
      const int number = tool_number(tools, key);
      Config t = tools.section(key);
      t.reject_unknown({"length", "diameter", "name"});
      ToolEntry e;
      e.length = t.number("length", "mm", 0, 1000);
      e.diameter = t.number("diameter", "mm", 0.01, 500);
      out.tools[number] = e;
    }
  }
  if (m.has("initial_position")) {
    auto v = m.numbers("initial_position", kNumAxes, "mm or deg (X Y Z A C)", -1e5, 1e5);
    for (int a = 0; a < kNumAxes; ++a) out.initial_position[static_cast<std::size_t>(a)] = v[static_cast<std::size_t>(a)];
  }
  if (m.has("start_position")) {
    auto v = m.numbers("start_position", kNumAxes, "mm or deg (X Y Z A C), machine joints", -1e5, 1e5);
    Axes p{};
    for (int a = 0; a < kNumAxes; ++a) p[static_cast<std::size_t>(a)] = v[static_cast<std::size_t>(a)];
    out.start_position = p;
  }
  if (m.has("reference_positions")) {
    Config rp = m.section("reference_positions");
    rp.reject_unknown({"G28", "G30"});
    static const char* names[2] = {"G28", "G30"};
    for (int i = 0; i < 2; ++i) {
      if (!rp.has(names[i])) continue;
      auto v = rp.numbers(names[i], kNumAxes, "mm or deg (X Y Z A C), machine coordinates", -1e5, 1e5);
      for (int a = 0; a < kNumAxes; ++a)
        out.reference_positions[static_cast<std::size_t>(i)][static_cast<std::size_t>(a)] = v[static_cast<std::size_t>(a)];
    }
  }
  if (m.has("tool_table")) {
    // Relative to the machine file, so a config tree can be moved as a whole.
    std::filesystem::path p = m.string("tool_table", "");
    if (p.is_relative() && !m.file().empty()) p = std::filesystem::path(m.file()).parent_path() / p;
    merge_tool_table(out, p);
  }
  out.kinematics = load_kinematics(m);
  return out;
}

}  // namespace gcpipe
