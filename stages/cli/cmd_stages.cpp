// gcpipe stages: the registered stages in pipeline order, with their edges.
#include <cstdio>

#include "commands.hpp"
#include "stage.hpp"

namespace gcpipe::cli {

int run_stages() {
  std::printf("%-11s %-11s %-8s %-8s %s\n", "stage", "upstream", "in", "out", "what it does");
  for (const pipeline::StageInfo& s : pipeline::registry())
    std::printf("%-11s %-11s %-8s %-8s %s\n", s.name, *s.upstream ? s.upstream : "-", pipeline::to_string(s.input),
                pipeline::to_string(s.output), s.summary);
  std::printf("\nbatch runs them all; trochoid = parse..write, ik = parse..ik, simulate = parse..simulate.\n");
  return 0;
}

}  // namespace gcpipe::cli
