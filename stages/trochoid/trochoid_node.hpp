// The trochoid stage as a DDS node.
//
// Reads:  gcpipe_blocks   (msg::BlockBatch)  resolved blocks and the parser's line diagnostics
// Writes: gcpipe_toolpath (msg::BlockBatch)  the same program with every G275 cycle expanded into
//                                            its G0/G1 (or G2/G3) blocks, every other block copied,
//                                            the parser's diagnostics forwarded, and one
//                                            diagnostic (line_status 3) per rejected cycle before
//                                            the skip moves that replace it
// (topic names: TrochoidNodeOptions, `--in` / `--out`)
//
// Each block goes through TrochoidExpander::step, the very call `gcpipe batch` makes, in the
// order batch mode makes it (dds::for_each_in_line_order), so the write node downstream writes
// batch mode's bytes. One cycle may expand into tens of thousands of blocks: the output is cut
// into batches of about `batch_bytes` whatever the input batch held. The end marker states what
// this node sent and forwards the parser's line accounting; before it goes out, what arrived is
// checked against the parse node's totals (dds::check_counts). Library gcpipe_trochoid_node keeps
// DDS out of gcpipe_trochoid.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "trochoid.hpp"

namespace gcpipe::dds {
class Participant;
}

namespace gcpipe {

struct TrochoidNodeOptions {
  /// Publish a batch once its serialized size reaches this [bytes]; 1024..1048576.
  std::size_t batch_bytes = 32 * 1024;
  /// Serve programs until SIGINT/SIGTERM instead of leaving after the first complete one.
  bool forever = false;
  /// Stop each program after its first rejected line or rejected cycle, like `gcpipe batch
  /// --strict`. Also on when the upstream's batches say strict (the parse node's --strict).
  bool strict = false;
  std::string input_topic = "gcpipe_blocks";     //!< BlockBatch topic read
  std::string output_topic = "gcpipe_toolpath";  //!< BlockBatch topic written
};

class TrochoidNode {
 public:
  TrochoidNode(dds::Participant& participant, TrochoidOptions trochoid_options,
               TrochoidNodeOptions node_options);
  ~TrochoidNode();
  /// Runs until one program ended (or, with `forever`, until stopped). Returns 0 when every
  /// program arrived whole with consistent counts and was acknowledged downstream, else 1.
  int run();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gcpipe
