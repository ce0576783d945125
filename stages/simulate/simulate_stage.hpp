// The simulate stage in the pipeline: collects the program (blocks pass on unchanged), and at its
// end runs the one simulation harness (simulate::simulate_program) on it. The result goes to the
// compensate stage as a product when one follows in the same process; otherwise this stage
// reports the simulation itself. Taps see every tick (the trace of `gcpipe simulate`).
#pragma once

#include <functional>
#include <memory>

#include "compensate.hpp"
#include "stage.hpp"

namespace gcpipe {

/// The product handed to the compensate stage.
struct SimulatedProgram final : pipeline::Product {
  simulate::SimulationRun run;
};

class SimulateStage final : public pipeline::Stage {
 public:
  explicit SimulateStage(const pipeline::StageContext& c);

  bool block(const ResolvedBlock& b, pipeline::Emitter& out) override;
  bool finish(bool complete, pipeline::Emitter& out) override;
  void report(pipeline::ReportContext& r) const override;
  std::string failure() const override { return failure_; }

  /// Called with every tick of the simulated run, in order.
  void on_tick(std::function<void(const simulate::Tick&)> tap) { tap_ = std::move(tap); }
  /// Only the trace and the figures of the run are wanted (`gcpipe simulate`): the run streams
  /// in bounded memory, without the nominal record the report and the compensation need.
  void trace_only() { record_nominal_ = false; }
  const compensate::Model& model() const { return model_; }
  /// The finished simulation (null before finish() or when the program was incomplete).
  const simulate::SimulationRun* run() const { return result_ ? &result_->run : nullptr; }

 private:
  /// tap_, then every tick as telemetry to `out` (a monitor listens).
  std::function<void(const simulate::Tick&)> tap_with_telemetry(pipeline::Emitter& out) const;

  compensate::Model model_;
  compensate::CompensateOptions bounds_;
  pipeline::Progress progress_;
  std::string file_;
  pipeline::DiagnosticLog& log_;
  bool reports_;  //!< no compensate stage follows, which would report the simulation
  bool record_nominal_ = true;
  BlockStore program_;
  std::string skipped_, failure_;
  std::shared_ptr<SimulatedProgram> result_;
  std::function<void(const simulate::Tick&)> tap_;
};

}  // namespace gcpipe
