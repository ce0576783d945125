// The write stage as a DDS node.
//
// Reads:  gcpipe_toolpath (msg::BlockBatch)  blocks and line diagnostics, in batches (from the
//                                            trochoid node; `--in gcpipe_blocks` skips it)
// Writes: gcpipe_gcode    (msg::GcodeChunk)  the written program as text, in chunks of whole
//                                            lines, the last one marked end_of_program with counts
//
// Blocks and diagnostics of a batch are merged back into batch mode's order
// (dds::for_each_in_line_order: by line, a diagnostic before the blocks of its line) and handed to
// the same Writer that `gcpipe batch` uses, so the text is byte-identical to batch mode's output.
// Before the end marker goes out, what arrived is checked against the upstream's end-marker
// totals (dds::check_counts).
// Library gcpipe_write_node keeps DDS out of gcpipe_write.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "write.hpp"

namespace gcpipe::dds {
class Participant;
}

namespace gcpipe {

struct WriteNodeOptions {
  /// Publish a text chunk once it holds this many bytes [bytes]; 1024..1048576.
  std::size_t chunk_bytes = 32 * 1024;
  /// Serve programs until SIGINT/SIGTERM instead of leaving after the first complete one.
  bool forever = false;
  std::string input_topic = "gcpipe_toolpath";  //!< BlockBatch topic read
  std::string output_topic = "gcpipe_gcode";    //!< GcodeChunk topic written
};

class WriteNode {
 public:
  WriteNode(dds::Participant& participant, WriteOptions write_options,
            WriteNodeOptions node_options);
  ~WriteNode();
  /// Runs until one program ended (or, with `forever`, until stopped). Returns 0 when every
  /// program arrived whole with consistent counts and was acknowledged downstream, else 1.
  int run();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gcpipe
