// The parse stage as a DDS node.
//
// Reads:  gcpipe_program (msg::ProgramChunk)  program text, chunk by chunk, from `gcpipe feed`
// Writes: gcpipe_blocks  (msg::BlockBatch)    resolved blocks and line diagnostics, in batches,
//                                             the last one marked end_of_program with the counts
// (topic names: ParseNodeOptions, `--in` / `--out`)
//
// The node runs the very Parser that `gcpipe batch` runs, one line at a time in source order, so
// the stream carries exactly what batch mode hands to its writer. Library gcpipe_parse_node keeps
// DDS out of gcpipe_parse.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "gcpipe/machine.hpp"
#include "parse.hpp"

namespace gcpipe::dds {
class Participant;
}

namespace gcpipe {

struct ParseNodeOptions {
  /// Publish a batch once its serialized size reaches this [bytes]; 1024..1048576.
  std::size_t batch_bytes = 32 * 1024;
  /// Serve programs until SIGINT/SIGTERM instead of leaving after the first complete one.
  bool forever = false;
  std::string input_topic = "gcpipe_program";  //!< ProgramChunk topic read
  std::string output_topic = "gcpipe_blocks";  //!< BlockBatch topic written
};

class ParseNode {
 public:
  ParseNode(dds::Participant& participant, ParseOptions parse_options, MachineConfig machine,
            ParseNodeOptions node_options);
  ~ParseNode();
  /// Runs until one program ended (or, with `forever`, until stopped). Returns the exit status:
  /// 0 when every program arrived whole and its batches were acknowledged downstream, 1 otherwise
  /// (the reason went to stderr and into the end marker's `error`).
  int run();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gcpipe
