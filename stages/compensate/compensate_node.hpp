// The compensate stage as a DDS node.
//
// Reads:  gcpipe_toolpath    (msg::BlockBatch)  the program after the trochoid node
// Writes: gcpipe_compensated (msg::GcodeChunk)  compensated.nc as text, in chunks of whole lines,
//                                               the last one marked end_of_program
//
// Compensation needs the whole program (the learning replays it), so the node collects each
// program's blocks and, at its end marker, runs compensate::compensate_program, the very call
// `gcpipe batch` makes: the text is byte-identical to batch mode's compensated.nc. A program that
// cannot be compensated (it moves nothing, runs past compensate.max_machine_time, lost input
// upstream) ends with an empty text and the reason in the end marker's error. Library
// gcpipe_compensate_node keeps DDS out of gcpipe_compensate.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "compensate.hpp"
#include "write.hpp"

namespace gcpipe::dds {
class Participant;
}

namespace gcpipe {

struct CompensateNodeOptions {
  /// Publish a text chunk once it holds this many bytes [bytes]; 1024..1048576.
  std::size_t chunk_bytes = 32 * 1024;
  /// Serve programs until SIGINT/SIGTERM instead of leaving after the first complete one.
  bool forever = false;
  std::string input_topic = "gcpipe_toolpath";      //!< BlockBatch topic read
  std::string output_topic = "gcpipe_compensated";  //!< GcodeChunk topic written
};

class CompensateNode {
 public:
  CompensateNode(dds::Participant& participant, compensate::Model model, compensate::CompensateOptions options,
                 WriteOptions write_options, CompensateNodeOptions node_options);
  ~CompensateNode();
  /// Runs until one program ended (or, with `forever`, until stopped). Returns 0 when every
  /// program arrived whole, was compensated and acknowledged downstream, else 1.
  int run();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gcpipe
