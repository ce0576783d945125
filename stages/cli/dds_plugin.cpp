// The entry point of the plugin gcpipe_dds_commands.so: the DDS commands by name (dds_loader.cpp
// loads the plugin and calls it; stages/cli/CMakeLists.txt says why they are a plugin).
#include <string_view>

#include "commands.hpp"
#include "launcher.hpp"

extern "C" __attribute__((visibility("default"))) int gcpipe_dds_command(const char* name, const void* args) {
  using namespace gcpipe::cli;
  const std::string_view n = name;
  if (n != "launch" && n != "stream") gcpipe::dds::follow_supervisor();
  if (n == "feed") return run_feed(*static_cast<const FeedArgs*>(args));
  if (n == "node") return run_node(*static_cast<const NodeArgs*>(args));
  if (n == "sink") return run_sink(*static_cast<const SinkArgs*>(args));
  if (n == "report-sink") return run_report_sink(*static_cast<const ReportSinkArgs*>(args));
  if (n == "monitor") return run_monitor(*static_cast<const MonitorArgs*>(args));
  if (n == "launch") return run_launch(*static_cast<const LaunchArgs*>(args));
  if (n == "stream") return run_stream(*static_cast<const StreamArgs*>(args));
  if (n == "dds-clean") return run_dds_clean(*static_cast<const DdsCleanArgs*>(args));
  return 2;
}
