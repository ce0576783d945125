// A pipeline config file (pipeline_configs/*.yaml): which machine, and one section per stage.
#pragma once

#include <filesystem>

#include "gcpipe/config.hpp"
#include "gcpipe/machine.hpp"

namespace gcpipe {

struct PipelineConfig {
  Config root;            //!< the whole file; stages read their own section (root.section("parse"))
  Config machine_section; //!< the machine file's root mapping
  MachineConfig machine;
};

/// Loads a pipeline config and the machine file it names (`machine:` relative to the config).
/// Throws ConfigError naming file, line, key, value and reason.
PipelineConfig load_pipeline_config(const std::filesystem::path& path);

/// The config used when none is given: pipeline_configs/default.yaml found next to the
/// executable's source tree or installed share directory.
/// pipeline_configs/pipelines/streaming.yaml of the source tree: `gcpipe stream`'s default pipeline file.
std::filesystem::path default_streaming_file();
std::filesystem::path default_pipeline_config();

}  // namespace gcpipe
