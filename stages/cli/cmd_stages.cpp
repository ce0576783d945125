// gcpipe stages: the registered stages in pipeline order, with their edges.
#include <cstdio>

#include "commands.hpp"
#include "stage.hpp"

namespace gcpipe::cli {

int run_stages() {
  std::printf("%-11s %-11s %-8s %-8s %-19s %-19s %s\n", "stage", "upstream", "in", "out", "reads topic",
              "writes topic", "what it does");
  for (const pipeline::StageInfo& s : pipeline::registry()) {
    const bool node = *s.topic != '\0';
    std::printf("%-11s %-11s %-8s %-8s %-19s %-19s %s\n", s.name, *s.upstream ? s.upstream : "-",
                pipeline::to_string(s.input), pipeline::to_string(s.output),
                node ? pipeline::input_topic(s.name).c_str() : "-", node ? s.topic : "(no node yet)", s.summary);
  }
  std::printf("\nbatch runs them all; trochoid = parse..write, ik = parse..ik, simulate = parse..simulate.\n");
  std::printf("telemetry for monitors (gcpipe monitor TOPIC):");
  for (const pipeline::StageInfo& s : pipeline::registry())
    if (s.telemetry != pipeline::Telemetry::kNone)
      std::printf(" %s from %s (%s);", s.telemetry_topic, s.name,
                  s.telemetry == pipeline::Telemetry::kIkPoints ? "IK points and flags" : "simulated ticks, contour error");
  std::printf("\n");
  return 0;
}

}  // namespace gcpipe::cli
