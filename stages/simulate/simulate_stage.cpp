#include "simulate_stage.hpp"

#include <algorithm>

#include "simulation_report.hpp"

namespace gcpipe {

SimulateStage::SimulateStage(const pipeline::StageContext& c)
    : model_(compensate::load_model(*c.config)),
      bounds_(compensate::load_compensate_options(c.config->root.section("compensate"))),
      progress_(c.progress),
      file_(c.file),
      log_(*c.log),
      reports_(std::find(c.whole_pipeline().begin(), c.whole_pipeline().end(), "compensate") == c.whole_pipeline().end()),
      program_(bounds_.max_blocks) {
  // A drives file written by gcpipe calibrate says where its model is known to predict badly;
  // whoever simulates or compensates with it is told, not left to trust the figures.
  for (const auto& w : model_.drives.prediction_warnings) {
    Diagnostic d;
    d.file = "servo.drives";
    d.line = 1;
    d.column = 1;
    d.severity = Severity::kWarning;
    d.message = "calibrated drives: " + w;
    log_.report(d);
  }
}

bool SimulateStage::block(const ResolvedBlock& b, pipeline::Emitter& out) {
  // The whole program is kept (the learning replays it), up to a bound on memory.
  if (skipped_.empty()) {
    if (program_.size() >= bounds_.max_blocks) {
      skipped_ = "the program has more than compensate.max_blocks = " + std::to_string(bounds_.max_blocks) + " blocks";
      program_.clear();
    } else {
      program_.push_back(b);
    }
  }
  return out.block(b);
}

bool SimulateStage::finish(bool complete, pipeline::Emitter& out) {
  if (!complete && skipped_.empty()) skipped_ = "the program did not arrive whole";
  if (!skipped_.empty()) {
    failure_ = "not simulated: " + skipped_;
    return true;
  }
  result_ = std::make_shared<SimulatedProgram>();
  simulate::RunBounds bounds = compensate::run_bounds(bounds_);
  bounds.record_nominal = record_nominal_;
  const auto tap = out.wants_telemetry() ? tap_with_telemetry(out) : tap_;
  result_->run = simulate::simulate_program(model_, std::move(program_), bounds, tap, progress_);
  if (!result_->run.before) failure_ = "not simulated: " + result_->run.note;
  if (result_->run.travel_line != 0) {
    // A travel violation is an error of the program at its line, like a parse error.
    Diagnostic d;
    d.file = file_;
    d.line = result_->run.travel_line;
    d.column = 1;
    d.message = result_->run.note;
    log_.report(d);
    failure_ = format(d);
  }
  out.product(result_);
  return true;
}

std::function<void(const simulate::Tick&)> SimulateStage::tap_with_telemetry(pipeline::Emitter& out) const {
  // A tick names its block by index into the program, which the simulation takes over: the
  // source lines are kept aside (8 bytes a block) for the telemetry.
  std::vector<std::uint64_t> lines(program_.size());
  for (std::size_t i = 0; i < program_.size(); ++i) lines[i] = program_[i].line;
  return [&out, lines = std::move(lines), tap = tap_, period = model_.interp.period](const simulate::Tick& t) {
    if (tap) tap(t);
    SampleTelemetry s;
    s.tick = t.n;
    s.time = static_cast<double>(t.n) * period;
    s.line = t.block < lines.size() ? lines[t.block] : 0;
    s.command = t.command;
    s.actual = t.actual;
    s.tip = t.tip;
    s.contour = t.contour;
    s.saturated = t.saturated;
    out.sample(s);
  };
}

void SimulateStage::report(pipeline::ReportContext& r) const {
  if (!reports_ || !record_nominal_) return;
  compensate::SimulationOutcome o;
  o.model = &model_;
  o.run = run();
  o.skipped = result_ ? result_->run.note : skipped_;
  compensate::report_simulation(r, o);
}

pipeline::StageInfo simulate_stage() {
  return {"simulate", "ik",
          "interpolation, acc/dec and feed drives (seed 002), forward kinematics, contour error",
          pipeline::Port::kBlocks, pipeline::Port::kBlocks,
          [](const pipeline::StageContext& c) -> std::unique_ptr<pipeline::Stage> {
            return std::make_unique<SimulateStage>(c);
          },
          "gcpipe_simulated", pipeline::Telemetry::kSamples, "gcpipe_samples"};
}

}  // namespace gcpipe
