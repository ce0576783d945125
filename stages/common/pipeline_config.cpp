#include "gcpipe/pipeline_config.hpp"

#include <cstdlib>

namespace gcpipe {

PipelineConfig load_pipeline_config(const std::filesystem::path& path) {
  PipelineConfig pc;
  pc.root = Config::load_file(path);
  // One section per stage; anything else is a typo that would otherwise be silently ignored.
  pc.root.reject_unknown({"machine", "parse", "trochoid", "write", "ik", "interpolate", "servo", "compensate", "force"});
  if (!pc.root.has("machine"))
    throw pc.root.error("machine", "missing: name the machine file, e.g. 'machine: machines/mx330.yaml'");
  const auto machine_path = pc.root.file_path("machine", "the machine file, e.g. machines/mx330.yaml");
  pc.machine_section = Config::load_file(machine_path);
  pc.machine = load_machine(pc.machine_section);
  return pc;
}

std::filesystem::path default_streaming_file() {
  return std::filesystem::path(GCPIPE_SOURCE_DIR) / "pipeline_configs" / "pipelines" / "streaming.yaml";
}

std::filesystem::path default_pipeline_config() {
  if (const char* env = std::getenv("GCPIPE_CONFIG")) return env;
  return std::filesystem::path(GCPIPE_SOURCE_DIR) / "pipeline_configs" / "default.yaml";
}

}  // namespace gcpipe
