// The machine model as configured in pipeline_configs/machines/*.yaml.
//
// One immutable description of the machine (Pinocchio's Model idea), loaded once and passed by
// const reference: what the parser needs (work offsets, tool table, start pose) and the
// kinematic model with travel, velocity and acceleration limits (gcpipe/kinematics.hpp).
#pragma once

#include <map>
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
  MachineKinematics kinematics;     //!< chain, offsets, travel and drive limits
};

/// Reads a machine file's root mapping (keys: name, work_offsets, tools, initial_position,
/// kinematics, limits; any other key is rejected); throws ConfigError naming key, value, reason.
MachineConfig load_machine(const Config& machine_section);

}  // namespace gcpipe
