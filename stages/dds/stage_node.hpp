// The one DDS node: any registered stage (stages/pipeline/stage.hpp) between its input and output
// topics. What the stage's ports say decides the wire types:
//
//   input  program -> msg::ProgramChunk (lines, from `gcpipe feed`)
//          blocks  -> msg::BlockBatch   (blocks and line diagnostics, in line order)
//   output blocks  -> msg::BlockBatch   (cut into batches of about batch_bytes)
//          gcode   -> msg::GcodeChunk   (whole lines, chunks of about batch_bytes)
//
// Around the stage the node does what every edge needs: programs told apart by id, replayed
// programs skipped, sequence numbers checked, strict stops, and an end-of-program marker whose
// counts the next node checks (dds_convert.hpp, check_counts). The stage runs exactly as in
// `gcpipe batch`, one stage object per program, so the bytes are batch mode's. Beside its edge a
// node publishes the stage's telemetry for monitors (ik, simulate: IkBatch, SampleBatch on keep-
// last monitor topics) and, at each program's end, the stage's part of the report
// (ReportFragment on gcpipe_report: report.json keys, report.txt lines, figures, diagnostics).
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "gcpipe/pipeline_config.hpp"

namespace gcpipe::dds {

class Participant;

struct StageNodeOptions {
  std::string stage;                    //!< a registered stage with a node (dds::edges)
  std::size_t batch_bytes = 128 * 1024;  //!< publish a batch or chunk once it holds this much [bytes]
  bool forever = false;                 //!< serve programs until SIGINT/SIGTERM
  bool strict = false;                  //!< stop each program at its first rejected line or cycle
  std::string input_topic, output_topic;
  /// Readers of the output to wait for and keep; -1: the participant's (--subscribers); 0: none
  /// (nobody in the pipeline reads this edge: publish at once). The stages of a group share a
  /// participant, each with its own count.
  int subscribers = -1;
  /// The whole pipeline's stages (the launcher's file), so that a stage knows what later nodes
  /// report (StageContext::pipeline_stages); empty: this stage alone.
  std::vector<std::string> pipeline_stages;
  /// Figures are drawn into this folder at each program's end (`gcpipe stream`'s OUTDIR, on
  /// this host); empty: none.
  std::filesystem::path report_dir;
  /// Readers of gcpipe_report (a report sink) to wait for before the report part is published,
  /// and to be acknowledged by; 0: publish for whoever listens, never wait.
  int report_readers = 0;
  /// The only program this node takes (`gcpipe stream` gives its feed's id to every process of
  /// its pipeline); another program on the input topic, another pipeline's on a shared domain,
  /// is refused and named once. 0: every program.
  std::uint64_t program_id = 0;
};

class StageNode {
 public:
  /// Throws when the stage is unknown or its ports have no wire type.
  StageNode(Participant& participant, const PipelineConfig& config, StageNodeOptions options);
  ~StageNode();
  /// Runs until one program ended (or, with `forever`, until stopped). 0 when every program
  /// arrived whole with consistent counts, was processed and acknowledged downstream; else 1.
  int run();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gcpipe::dds
