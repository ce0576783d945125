// The machine model as configured in pipeline_configs/machines/*.yaml.
//
// One immutable description of the machine (Pinocchio's Model idea), loaded once and passed by
// const reference: what the parser needs (work offsets, tool table, start pose) and the
// kinematic model with travel, velocity and acceleration limits (gcpipe/kinematics.hpp).
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>

#include "gcpipe/block.hpp"
#include "gcpipe/kinematics.hpp"

namespace gcpipe {

class Config;

/// One entry of the tool table, addressed by T (diameter) and H (length) numbers.
struct ToolEntry {
  double length = 0;    //!< gauge length [mm], used by G43 H<n>
  double diameter = 0;  //!< cutting diameter [mm], used by cycles that need it
};

struct MachineConfig {
  std::string name;                 //!< e.g. "mx330"
  std::array<Axes, 6> work_offsets{};  //!< G54..G59 origin in machine coordinates [mm, deg]
  std::map<int, ToolEntry> tools;   //!< tool table by number
  Axes initial_position{};          //!< work-coordinate position assumed before the first move
  /// Machine joints [mm, deg] where the machine stands when a program starts (home, Z up): the
  /// simulation and compensated.nc start there. Absent: at the program's first position.
  std::optional<Axes> start_position;
  /// G28 and G30 reference positions in machine coordinates (LinuxCNC #5161.., #5181..; zero,
  /// i.e. machine zero, when the machine file does not say).
  std::array<Axes, 2> reference_positions{};
  /// Where `tools` came from, for messages: empty = the machine file's `tools`, else the tool
  /// table file loaded over them.
  std::string tool_table_source;
  MachineKinematics kinematics;     //!< chain, offsets, travel and drive limits
};

/// Reads a machine file's root mapping (keys: name, work_offsets, tools, initial_position, start_position,
/// kinematics, limits; any other key is rejected); throws ConfigError naming key, value, reason.
MachineConfig load_machine(const Config& machine_section);

/// A shop's tool table: LinuxCNC's `.tbl` (`T1 P1 D10.0 Z+50.0 ;comment`: T number, Z length,
/// D diameter, other words ignored) or YAML (`tools: {1: {length: 50, diameter: 10, name: ..}}`,
/// as in a machine file), chosen by the extension (.tbl, else YAML). Lengths in mm. Throws
/// ConfigError naming file:line and what is wrong.
std::map<int, ToolEntry> load_tool_table(const std::filesystem::path& path);
/// A key of a `tools:` mapping as a tool number 1..9999; throws ConfigError naming the key.
int tool_number(const Config& tools, const std::string& key);

/// Loads `path` and merges it into `machine.tools` (its entries replace the machine file's of the
/// same number); messages then name the file.
void merge_tool_table(MachineConfig& machine, const std::filesystem::path& path);

/// "tool table t.tbl" or "the machine config's tool table (machine 'tools')", for messages.
std::string tool_table_name(const MachineConfig& machine);

}  // namespace gcpipe
