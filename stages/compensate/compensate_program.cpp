#include "compensate_program.hpp"

namespace gcpipe::compensate {

ProgramCompensation compensate_program(const Model& model, const CompensateOptions& options,
                                       const WriteOptions& write_options, const simulate::SimulationRun& run,
                                       const Progress& progress, const TextSink& text) {
  ProgramCompensation pc;
  if (!run.before) {
    pc.note = run.note;
    return pc;
  }
  if (!options.enabled) {
    pc.note = "compensate.enabled is false";
    return pc;
  }
  // The text is written as the nodes come and handed on window by window: on a long program it
  // (tens of MB) and the nodes (56 bytes every 4 ms) are never held whole.
  Writer writer(write_options);
  std::string held;                        // written, not handed on yet
  std::vector<std::uint32_t> held_blocks;  // the source block of each of its timed points
  auto hand_on = [&] {
    if (text) text(held, held_blocks);
    else pc.text += held;
    held.clear();
    held_blocks.clear();
  };
  CompensatedBlocks blocks(run.program, model.interp.period, [&](const ResolvedBlock& b) { writer.write(b, held); });
  bool first = true;
  const NodeSink sink = [&](std::span<const Node> nodes, bool learned_so_far) {
    blocks.add(nodes);
    for (const Node& n : nodes.subspan(first ? 1 : 0)) held_blocks.push_back(n.block);  // node 0 is the start
    first = false;
    if (learned_so_far) hand_on();
  };
  pc.result = compensate(model, *run.nominal, run.program, run.start, *run.before, options, progress, sink);
  if (!pc.result->compensated) {
    pc.note = pc.result->note;
    return pc;
  }
  blocks.finish();
  hand_on();
  return pc;
}

}  // namespace gcpipe::compensate
