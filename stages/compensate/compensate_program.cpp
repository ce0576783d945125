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
  const std::vector<ResolvedBlock> blocks = compensated_blocks(run.program, *pc.result, model.interp.period);
  Writer writer(write_options);
  pc.text.reserve(blocks.size() * 64);
  for (const auto& b : blocks) writer.write(b, pc.text);
  return pc;
}

}  // namespace gcpipe::compensate
