// The write stage in the pipeline: resolved blocks and line diagnostics in, G-code text out.
#include <nlohmann/json.hpp>

#include "stage.hpp"
#include "write.hpp"

namespace gcpipe {
namespace {

using pipeline::Emitter;

// output.nc keeps the source's frames: it runs on the control's own work offsets, tool table and
// reference positions, as the source would (compensated.nc, which writes machine positions, does not).
WriteOptions output_options(const pipeline::StageContext& c) {
  WriteOptions o = load_write_options(c.config->root.section("write"));
  o.source_frames = true;
  return o;
}

class WriteStage final : public pipeline::Stage {
 public:
  explicit WriteStage(const pipeline::StageContext& c) : writer_(output_options(c)) {}

  bool block(const ResolvedBlock& b, Emitter& out) override {
    writer_.write(b, text_);
    ++blocks_;
    return flush(out, false);
  }
  bool diagnostic(const Diagnostic& d, DiagnosticKind, Emitter& out) override {
    writer_.write_diagnostic(d, text_);
    return flush(out, false);
  }
  bool finish(bool, Emitter& out) override { return flush(out, true); }

  void report(pipeline::ReportContext& r) const override {
    (*r.json)["blocks_written"] = blocks_;
    *r.text += "  written:  " + std::to_string(blocks_) + " blocks to output.nc\n";
  }

 private:
  // Text goes on in chunks of about 64 KiB: large enough to be cheap, small enough to stream.
  bool flush(Emitter& out, bool force) {
    if (text_.empty() || (!force && text_.size() < (64u << 10))) return true;
    return out.text(text_);
  }
  Writer writer_;
  std::string text_;
  std::uint64_t blocks_ = 0;
};

}  // namespace

pipeline::StageInfo write_stage() {
  return {"write", "trochoid", "resolved blocks to explicit, portable G-code (output.nc)", pipeline::Port::kBlocks,
          pipeline::Port::kGcode,
          [](const pipeline::StageContext& c) -> std::unique_ptr<pipeline::Stage> { return std::make_unique<WriteStage>(c); },
          "gcpipe_gcode"};
}

}  // namespace gcpipe
