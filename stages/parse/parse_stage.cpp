// The parse stage in the pipeline: source lines in, resolved blocks and line diagnostics out.
#include <nlohmann/json.hpp>

#include "parse.hpp"
#include "stage.hpp"

namespace gcpipe {
namespace {

using pipeline::Emitter;

class ParseStage final : public pipeline::Stage {
 public:
  explicit ParseStage(const pipeline::StageContext& c)
      : parser_(options(c), c.config->machine, c.file), log_(*c.log) {}

  // A line may yield several blocks (a canned cycle, a subroutine call) or, inside flow control,
  // nothing until its loop or definition ends; finish() hands out what still waits.
  bool line(std::string_view text, std::size_t overlong_length, Emitter& out) override {
    return parser_.feed(text, sink(out), overlong_length);
  }
  bool finish(bool complete, Emitter& out) override { return !complete || parser_.finish(sink(out)); }
  bool block(const ResolvedBlock&, Emitter&) override { throw std::logic_error("parse reads program text"); }

  // The line accounting stands at the top of the report: lines read = emitted + rejected + skipped.
  void report(pipeline::ReportContext& r) const override {
    const ParseSummary& s = parser_.summary();
    nlohmann::ordered_json& j = *r.json;
    j["lines_read"] = s.lines_read;
    j["blocks_emitted"] = s.blocks_emitted;
    j["lines_rejected"] = s.lines_rejected;
    j["lines_deleted"] = s.lines_deleted;
    j["bytes_read"] = s.bytes_read;
    j["blocks_out"] = s.blocks_out;  // >= blocks_emitted: cycles and calls give several per line
    char buf[256];
    std::snprintf(buf, sizeof buf, "  lines:    %llu read = %llu emitted + %llu rejected + %llu skipped (block delete, subroutine bodies, flow control)\n",
                  static_cast<unsigned long long>(s.lines_read), static_cast<unsigned long long>(s.blocks_emitted),
                  static_cast<unsigned long long>(s.lines_rejected), static_cast<unsigned long long>(s.lines_deleted));
    *r.text += buf;
  }
  std::uint64_t rejected() const override { return parser_.summary().lines_rejected; }

  const Parser& parser() const { return parser_; }

 private:
  // Blocks and diagnostics to `out`; a rejected line stops the program in strict mode.
  ParseSink sink(Emitter& out) {
    return {[&out](const ResolvedBlock& b) { return out.block(b); },
            [this, &out](const Diagnostic& d) {
              log_.report(d);
              // A warning (a tool not in the table) leaves its line's blocks as they are: it goes
              // to the log (diagnostics.txt), not down the stream, which knows rejected and
              // deleted lines only.
              if (d.severity == Severity::kWarning) return true;
              const bool error = d.severity == Severity::kError;
              const bool go = out.diagnostic(d, error ? DiagnosticKind::kLineRejected : DiagnosticKind::kLineDeleted);
              return go && !(error && parser_.options().strict);
            }};
  }

  static ParseOptions options(const pipeline::StageContext& c) {
    ParseOptions o = load_parse_options(c.config->root.section("parse"));
    o.strict = o.strict || c.strict;
    return o;
  }
  Parser parser_;
  pipeline::DiagnosticLog& log_;
};

}  // namespace

pipeline::StageInfo parse_stage() {
  return {"parse", "", "ISO 6983 text to resolved blocks, with file:line:col errors", pipeline::Port::kProgram,
          pipeline::Port::kBlocks,
          [](const pipeline::StageContext& c) -> std::unique_ptr<pipeline::Stage> { return std::make_unique<ParseStage>(c); },
          "gcpipe_blocks"};
}

}  // namespace gcpipe
