#include "commands.hpp"

namespace gcpipe::cli {

// Order: the main job first, then the stages in pipeline order, then tools.
const std::vector<Command> kCommands = {
    kBatchCommand,
    kParseCommand,
    kTrochoidCommand,
    kIkCommand,
    kSimulateCommand,
    kTrainIkCommand,
    kSynthCommand,
#ifdef GCPIPE_WITH_DDS
    kFeedCommand,
    kNodeCommand,
    kSinkCommand,
    kMonitorCommand,
#endif
};

}  // namespace gcpipe::cli
