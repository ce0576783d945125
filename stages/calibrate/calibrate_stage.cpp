#include "calibrate_stage.hpp"

#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

namespace gcpipe::calibrate {

CalibrateStage::CalibrateStage(const pipeline::StageContext& context)
    : context_(context), model_(compensate::load_model(*context.config)) {}

bool CalibrateStage::line(std::string_view text, std::size_t overlong_length, pipeline::Emitter&) {
  (void)overlong_length;  // a cut row fails the reader's column checks with its line number
  if (texts_.empty()) begin_trace(context_.file);
  texts_.back().second.append(text).push_back('\n');
  return true;
}

bool CalibrateStage::block(const ResolvedBlock&, pipeline::Emitter&) {
  throw std::logic_error("the calibrate stage reads trace text, not blocks");
}

/// Each trace's text through the readers; every diagnostic goes to the log. False when a trace
/// was rejected or the traces do not share a period (failure_ says which).
bool CalibrateStage::read_traces(std::vector<MeasuredTrace>& traces) {
  for (auto& [name, text] : texts_) {
    std::istringstream in(std::move(text));
    ReadResult r = read_trace(in, name, options_);
    for (const auto& d : r.diagnostics) context_.log->report(d);
    if (!r.trace) {
      failure_ = name + ": trace rejected" + (options_.skip_bad_rows ? "" : " (--skip-bad-rows uses the usable rest)");
      return false;
    }
    rejected_ += r.trace->rows_skipped + r.trace->rows_unused;
    traces.push_back(std::move(*r.trace));
  }
  texts_.clear();
  if (auto why = mixed_periods(traces)) {
    failure_ = *why;
    return false;
  }
  if (traces.empty()) failure_ = "no trace lines arrived";
  return !traces.empty();
}

bool CalibrateStage::finish(bool complete, pipeline::Emitter& out) {
  if (!complete) {
    failure_ = "the trace input stopped before its end: nothing calibrated";
    return true;
  }
  std::vector<MeasuredTrace> traces;
  if (!read_traces(traces)) return true;
  try {
    auto product = std::make_shared<CalibrationProduct>();
    std::function<void(std::uint64_t, std::uint64_t)> progress;
    if (context_.progress)
      progress = [this](std::uint64_t done, std::uint64_t total) {
        context_.progress("identifying each axis's drive and effects", done, total);
      };
    product->calibration = calibrate_traces(traces, model_, {}, progress);
    result_ = product;
    out.product(result_);
  } catch (const std::exception& e) {
    failure_ = e.what();
  }
  return true;
}

void CalibrateStage::report(pipeline::ReportContext& r) const {
  if (!result_) return;
  const Calibration& c = result_->calibration;
  if (r.json) (*r.json)["calibrate"] = nlohmann::ordered_json::parse(calibration_json(c));
  if (r.text) *r.text += report_text(c);
  if (r.dir.empty()) return;
  write_outputs(c, model_, context_.config->root.file(), r.dir.string(), plots_);
  if (r.files)
    for (const char* f : {"calibration.json", "calibrated.yaml", "calibrated_drives.yaml", "report.txt"}) r.files->push_back(f);
}

}  // namespace gcpipe::calibrate

namespace gcpipe {

pipeline::StageInfo calibrate_stage() {
  return {"calibrate", "", "measured traces to named effects and a calibrated model (calibration.json, calibrated.yaml)",
          pipeline::Port::kProgram, pipeline::Port::kNone,
          [](const pipeline::StageContext& c) -> std::unique_ptr<pipeline::Stage> {
            return std::make_unique<calibrate::CalibrateStage>(c);
          }};
}

}  // namespace gcpipe
