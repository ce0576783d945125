// The DDS commands from the plugin gcpipe_dds_commands.so beside the executable, loaded only when
// one of them runs, so that no other command pays Fast DDS's start-up (stages/cli/CMakeLists.txt).
#include <dlfcn.h>

#include <filesystem>
#include <stdexcept>
#include <string>

#include "commands.hpp"

namespace gcpipe::cli {

int run_dds_command(const char* name, const void* args) {
  const auto plugin = std::filesystem::read_symlink("/proc/self/exe").parent_path() / "gcpipe_dds_commands.so";
  void* lib = dlopen(plugin.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (lib == nullptr) throw std::runtime_error(std::string("cannot load the DDS commands: ") + dlerror());
  using Command = int (*)(const char*, const void*);
  const auto command = reinterpret_cast<Command>(dlsym(lib, "gcpipe_dds_command"));
  if (command == nullptr) throw std::runtime_error(plugin.string() + ": no gcpipe_dds_command");
  return command(name, args);
}

}  // namespace gcpipe::cli
