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

  bool line(std::string_view text, std::size_t overlong_length, Emitter& out) override {
    const LineStatus st = parser_.parse_line(text, block_, diag_, overlong_length);
    if (st == LineStatus::kBlock) return out.block(block_);
    log_.report(diag_);
    const bool go = out.diagnostic(diag_, st == LineStatus::kDeleted ? DiagnosticKind::kLineDeleted
                                                                      : DiagnosticKind::kLineRejected);
    return go && !(st == LineStatus::kRejected && parser_.options().strict);
  }
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
    char buf[200];
    std::snprintf(buf, sizeof buf, "  lines:    %llu read = %llu emitted + %llu rejected + %llu skipped (block delete)\n",
                  static_cast<unsigned long long>(s.lines_read), static_cast<unsigned long long>(s.blocks_emitted),
                  static_cast<unsigned long long>(s.lines_rejected), static_cast<unsigned long long>(s.lines_deleted));
    *r.text += buf;
  }
  std::uint64_t rejected() const override { return parser_.summary().lines_rejected; }

  const Parser& parser() const { return parser_; }

 private:
  static ParseOptions options(const pipeline::StageContext& c) {
    ParseOptions o = load_parse_options(c.config->root.section("parse"));
    o.strict = o.strict || c.strict;
    return o;
  }
  Parser parser_;
  pipeline::DiagnosticLog& log_;
  ResolvedBlock block_;
  Diagnostic diag_;
};

}  // namespace

pipeline::StageInfo parse_stage() {
  return {"parse", "", "ISO 6983 text to resolved blocks, with file:line:col errors", pipeline::Port::kProgram,
          pipeline::Port::kBlocks,
          [](const pipeline::StageContext& c) -> std::unique_ptr<pipeline::Stage> { return std::make_unique<ParseStage>(c); },
          "gcpipe_blocks"};
}

}  // namespace gcpipe
