#include "spindle_inputs.hpp"

#include <algorithm>
#include <cmath>

namespace gcpipe::force {

namespace {

bool is_cutting_motion(const ResolvedBlock& b) {
  return b.motion == Motion::kLinear || b.motion == Motion::kArcCW || b.motion == Motion::kArcCCW;
}

/// Keeps every `stride`-th commanded sample (the model's clock on the interpolator's) with the
/// spindle state of the block that emitted it.
class EveryNthSample final : public interpolate::SampleSink {
 public:
  EveryNthSample(std::size_t stride, double spindle_rpm, const Axes& start, double tick, ProgramInputs& out)
      : stride_(stride), spindle_rpm_(spindle_rpm), tick_(tick), previous_(start), out_(out) {}

  /// The block whose samples follow (the interpolator emits them inside add()).
  void running(const ResolvedBlock& b) {
    const bool turning = b.spindle != Spindle::kOff && b.spindle_speed > 0;
    spindle_ = turning ? (spindle_rpm_ > 0 ? spindle_rpm_ : b.spindle_speed) : 0.0;
    cutting_ = turning && is_cutting_motion(b) ? 1.0 : 0.0;
  }

  // The interpolator's first sample is at t = one tick (t = 0 is the start, not emitted), so
  // sample n * stride is at t = n * the model's period. The feed there is the commanded path speed
  // over the last tick, as a control logs its commanded velocity at the sampling instant (the
  // UMich runs' X1/Y1/Z1_CommandVelocity), so that no sample mixes a rapid into a cutting move.
  void sample(const Axes& command) override {
    const Axes before = previous_;
    previous_ = command;
    if (++n_ % stride_ != 0) return;
    const double dx = command[kX] - before[kX], dy = command[kY] - before[kY], dz = command[kZ] - before[kZ];
    out_.feed.push_back(std::sqrt(dx * dx + dy * dy + dz * dz) / tick_);
    out_.spindle.push_back(spindle_);
    out_.cutting.push_back(cutting_);
  }

 private:
  std::size_t stride_, n_ = 0;
  double spindle_rpm_, tick_, spindle_ = 0, cutting_ = 0;
  Axes previous_;
  ProgramInputs& out_;
};

}  // namespace

ProgramInputs sample_program_inputs(const std::vector<ResolvedBlock>& blocks, const interpolate::InterpolateOptions& o,
                                    const Axes& start, double period, double spindle_rpm) {
  const auto stride = static_cast<std::size_t>(std::max(1.0, std::round(period / o.period)));
  ProgramInputs in;
  in.period = static_cast<double>(stride) * o.period;
  EveryNthSample sink(stride, spindle_rpm, start, o.period, in);
  interpolate::Interpolator interp(o, start);
  for (const ResolvedBlock& b : blocks) {
    sink.running(b);
    const interpolate::InterpolateResult r = interp.add(b, sink);
    if (r.status != interpolate::InterpolateStatus::kOk) {
      in.failure = r.message;
      return in;
    }
  }
  interp.finish(sink);  // the settling after the last block, at its spindle state
  return in;
}

}  // namespace gcpipe::force
