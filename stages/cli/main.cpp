// gcpipe: G-code stream processing for five-axis machining. main() only dispatches subcommands.
#include <cstring>
#include <iostream>

#include "command.hpp"
#include "commands.hpp"

using gcpipe::cli::Command;

namespace {

const Command* find(std::string_view name) {
  for (const Command& c : gcpipe::cli::kCommands)
    if (name == c.name) return &c;
  return nullptr;
}

void print_help() {
  std::cout << "gcpipe: G-code stream-processing pipeline for table-table five-axis machines\n\n"
               "Usage: gcpipe <command> [options]   (gcpipe <command> --help for details)\n\n"
               "Commands:\n";
  for (const Command& c : gcpipe::cli::kCommands) {
    std::cout << "  " << c.name;
    for (std::size_t i = std::strlen(c.name); i < 14; ++i) std::cout << ' ';
    std::cout << c.summary << "\n";
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0 ||
      std::strcmp(argv[1], "help") == 0) {
    print_help();
    return argc < 2 ? 2 : 0;
  }
  if (std::strcmp(argv[1], "--version") == 0) {
    std::cout << "gcpipe " << GCPIPE_VERSION << "\n";
    return 0;
  }
  const Command* cmd = find(argv[1]);
  if (cmd == nullptr) {
    std::cerr << "gcpipe: unknown command '" << argv[1] << "'. Run 'gcpipe --help' for the list.\n";
    return 2;
  }
  std::vector<std::string> args(argv + 2, argv + argc);
  for (const auto& a : args) {
    if (a == "--help" || a == "-h") {
      std::cout << cmd->usage;
      return 0;
    }
  }
  try {
    return cmd->run(args);
  } catch (const std::exception& e) {
    // Configuration and construction errors arrive here; per-line errors never throw.
    std::cerr << "gcpipe " << cmd->name << ": " << e.what() << "\n";
    return 1;
  }
}
