// `gcpipe monitor`: a live view of a running pipeline that never disturbs it. It reads the
// keep-last copies of the edges (TOPIC_monitor) and the telemetry topics, so it is never one of a
// stage's readers and a frozen monitor holds nobody back (README.md beside this file).
#pragma once

#include <filesystem>
#include <iosfwd>
#include <string>
#include <vector>

#include "dds_runtime.hpp"

namespace gcpipe::dds {

/// Prints one summary line per `period` [s] about `topic`, which carries `type` (batches, items
/// and items/s, last source line, errors; IK flags or contour error and torque saturation on the
/// telemetry topics) until an end-of-program marker arrives (returns 0), the writer goes away
/// before it (1), or a stop is requested (130). Joining late is fine: it reports what the writer
/// still held, and says so. `plot` non-empty: also redraw that PNG every period with the contour
/// error of the simulated ticks (the topic must carry SampleBatch; contour_figure.hpp).
int run_monitor(Participant& participant, MessageType type, const std::string& topic,
                double period, std::ostream& out, const std::filesystem::path& plot = {});

/// One stage of a pipeline view: its output edge and, for ik and simulate, its telemetry.
struct WatchedStage {
  std::string stage;
  std::string topic;            //!< its output edge
  MessageType type{};
  std::string telemetry_topic;  //!< "" when it has none
  MessageType telemetry_type{};
};

/// The watched stages of the registered stages `nodes` (a launch plan's), in order.
std::vector<WatchedStage> watched_stages(const std::vector<std::string>& nodes);

/// `gcpipe monitor --pipeline`: every `period` [s] one line per stage (and per telemetry topic)
/// of the program the first sample belongs to, until every stage has ended it (returns 0) or
/// some writer went away before the end (1, saying which missed what), or a stop (130), or the
/// idle timeout (1). `plot`: as run_monitor's, from the simulate stage's telemetry (throws
/// std::invalid_argument when the pipeline has no simulate node).
int run_pipeline_monitor(Participant& participant, const std::string& name, const std::vector<WatchedStage>& stages,
                         double period, std::ostream& out, const std::filesystem::path& plot = {});

}  // namespace gcpipe::dds
