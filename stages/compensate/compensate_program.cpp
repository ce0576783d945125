#include "compensate_program.hpp"

namespace gcpipe::compensate {

ProgramCompensation compensate_program(const Model& model, const CompensateOptions& options,
                                       const WriteOptions& write_options, const simulate::SimulationRun& run,
                                       const Progress& progress) {
  ProgramCompensation pc;
  if (!run.before) {
    pc.note = run.note;
    return pc;
  }
  if (!options.enabled) {
    pc.note = "compensate.enabled is false";
    return pc;
  }
  pc.result = compensate(model, *run.nominal, run.program, run.start, *run.before, options, progress);
  if (!pc.result->compensated) {
    pc.note = pc.result->note;
    return pc;
  }
  Writer writer(write_options);
  pc.text.reserve(pc.result->nodes.size() * 64);
  for_each_compensated_block(run.program, *pc.result, model.interp.period,
                             [&](const ResolvedBlock& b) { writer.write(b, pc.text); });
  return pc;
}

}  // namespace gcpipe::compensate
