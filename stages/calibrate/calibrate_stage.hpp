// The calibrate stage in the pipeline (stages/pipeline/stage.hpp): its input is the text lines of
// measured traces (Port::kProgram: text lines; here they are trace rows, not G-code), its result is
// the calibration, handed on as a Product and written by report() (calibration.json,
// calibrated.yaml, report.txt, plots/). Nothing travels on an edge after it (Port::kNone).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "calibrate.hpp"
#include "stage.hpp"

namespace gcpipe::calibrate {

/// What the stage hands on in one process: the whole calibration.
struct CalibrationProduct final : pipeline::Product {
  Calibration calibration;
};

class CalibrateStage final : public pipeline::Stage {
 public:
  /// Loads the drive model of the context's config (throws ConfigError as every stage does).
  explicit CalibrateStage(const pipeline::StageContext& context);
  /// How the trace text is read (format, column map, period, skip_bad_rows).
  void set_read_options(ReadOptions options) { options_ = std::move(options); }
  void set_plots(bool plots) { plots_ = plots; }
  /// Starts the next trace of the same machine; lines before any call belong to context.file.
  /// With several traces the last one is the held-out part.
  void begin_trace(const std::string& name) { texts_.emplace_back(name, std::string()); }

  bool line(std::string_view text, std::size_t overlong_length, pipeline::Emitter& out) override;
  /// Never called: the stage reads text lines, not blocks.
  bool block(const ResolvedBlock& block, pipeline::Emitter& out) override;
  bool finish(bool complete, pipeline::Emitter& out) override;
  void report(pipeline::ReportContext& r) const override;
  std::string failure() const override { return failure_; }
  /// Rows dropped (--skip-bad-rows) or left outside the longest gap-free stretch.
  std::uint64_t rejected() const override { return rejected_; }
  /// The calibration once finish() succeeded, else nullptr.
  const Calibration* calibration() const { return result_ ? &result_->calibration : nullptr; }

 private:
  bool read_traces(std::vector<MeasuredTrace>& traces);

  pipeline::StageContext context_;
  compensate::Model model_;
  ReadOptions options_;
  bool plots_ = true;
  std::vector<std::pair<std::string, std::string>> texts_;  // (name, rows) per trace
  std::shared_ptr<CalibrationProduct> result_;
  std::string failure_;
  std::uint64_t rejected_ = 0;
};

}  // namespace gcpipe::calibrate

namespace gcpipe {
pipeline::StageInfo calibrate_stage();
}  // namespace gcpipe
