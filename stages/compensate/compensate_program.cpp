#include "compensate_program.hpp"

namespace gcpipe::compensate {

ProgramCompensation compensate_program(const Model& model, const CompensateOptions& options,
                                       const WriteOptions& write_options,
                                       std::span<const ResolvedBlock> program, const Progress& progress) {
  ProgramCompensation pc;
  std::size_t first = 0;
  while (first < program.size() && program[first].motion == Motion::kNone) ++first;
  if (first == program.size()) {
    pc.note = "the program moves nothing";
    return pc;
  }
  pc.start = machine_start(model.kin, program[first], tool_length_of(model, program[first]));
  if (progress) progress("simulating the program (interpolator + feed drives)", 0, 1);
  pc.nominal = build_nominal(model, program, pc.start, options.reference_smoothing, options.max_machine_time);
  if (!pc.nominal->stats.ok) {
    pc.note = "line " + std::to_string(pc.nominal->stats.failed_line) + ": " + pc.nominal->stats.message;
    return pc;
  }
  pc.before = evaluate(model, *pc.nominal, program, program, pc.start, [](std::uint32_t i) { return i; });
  if (!options.enabled) {
    pc.note = "compensate.enabled is false";
    return pc;
  }
  pc.result = compensate(model, *pc.nominal, program, pc.start, *pc.before, options, progress);
  if (!pc.result->compensated) {
    pc.note = pc.result->note;
    return pc;
  }
  const std::vector<ResolvedBlock> blocks = compensated_blocks(program, *pc.result, model.interp.period);
  Writer writer(write_options);
  pc.text.reserve(blocks.size() * 64);
  for (const auto& b : blocks) writer.write(b, pc.text);
  return pc;
}

}  // namespace gcpipe::compensate
