// The list of subcommands. To add one: define `constinit const Command kFooCommand` in
// cmd_foo.cpp, declare it here and list it in commands.cpp.
#pragma once

#include <vector>

#include "command.hpp"

namespace gcpipe::cli {

extern const Command kBatchCommand;
extern const Command kParseCommand;
extern const Command kSynthCommand;
extern const Command kTrainIkCommand;  // cmd_train_ik.cpp
extern const Command kIkCommand;       // cmd_ik.cpp
#ifdef GCPIPE_WITH_DDS
extern const Command kFeedCommand;     // cmd_dds.cpp
extern const Command kNodeCommand;     // cmd_dds.cpp
extern const Command kSinkCommand;     // cmd_dds.cpp
extern const Command kMonitorCommand;  // cmd_dds.cpp
#endif

extern const Command kSimulateCommand;  // cmd_simulate.cpp
extern const Command kTrochoidCommand;  // cmd_trochoid.cpp
extern const std::vector<Command> kCommands;

}  // namespace gcpipe::cli
