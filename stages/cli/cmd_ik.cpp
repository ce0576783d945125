// gcpipe ik: parse + ik stage, one CSV row per resolved point (analytic and neural joints).
#include <stdexcept>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>

#include "command.hpp"
#include "commands.hpp"
#include "gcpipe/config.hpp"
#include "gcpipe/number_format.hpp"
#include "ik.hpp"
#include "neural_ik.hpp"
#include "program_stream.hpp"

namespace gcpipe::cli {
namespace {

void append_row(std::string& buf, const IkPoint& p) {
  buf += std::to_string(p.line);
  for (double v : p.joints) {
    buf += ',';
    append_fixed(buf, v, 6);
  }
  for (double v : p.neural_joints) {
    buf += ',';
    if (p.has_neural) append_fixed(buf, v, 6);
  }
  buf += ',';
  buf += ik_flags_to_string(p.flags);
  buf += '\n';
}

int run_ik(const std::vector<std::string>& argv) {
  Args args(argv, {"--config", "--model", "-o"}, {"--csv", "--tool-vector", "--progress"});
  if (!args.ok()) return usage_error(kIkCommand, args.error());
  if (args.positional().size() != 1)
    return usage_error(kIkCommand, "give exactly one input program (or - for stdin)");
  if (!args.flag("--csv"))
    return usage_error(kIkCommand, "--csv is the only output format so far; add --csv");
  PipelineConfig pc = load_config_option(args.value_or("--config", ""));
  ParseOptions po = load_parse_options(pc.root.section("parse"));
  IkOptions io = load_ik_options(pc.root.section("ik"));
  if (args.flag("--tool-vector")) io.resolve_orientation = IkInputMode::kToolVector;

  std::optional<neural::NeuralIk> model;
  if (const auto path = args.value("--model")) {
    model.emplace(neural::NeuralIk::load(*path));
    // A model learns one machine's geometry; on another machine it would be confidently wrong.
    if (model->provenance().machine != pc.machine.name)
      throw std::runtime_error(*path + ": the model was trained for machine '" + model->provenance().machine +
                               "', the config is for '" + pc.machine.name +
                               "': train one with gcpipe train-ik --config <this config>");
  } else {
    model = load_ik_model(io, pc.machine.name);  // the config's ik.model, if it names one
  }

  InputFile in(args.positional()[0]);
  Parser parser(po, pc.machine, in.name());
  IkStage stage(pc.machine.kinematics, io, pc.machine.initial_position,
                model ? &*model : nullptr);
  OutputFile out(args.value_or("-o", "-"));
  std::string buf = "line,X,Y,Z,A,C,Xn,Yn,Zn,An,Cn,flags\n";
  std::uint64_t errors = 0;
  LineSink sink;
  IkPoint point;
  sink.block = [&](const ResolvedBlock& b) {
    if (stage.step(b, point)) {
      append_row(buf, point);
      out.write(buf);
    }
    return true;
  };
  sink.diagnostic = print_diagnostics(errors);
  std::string error;
  const bool complete = stream_program(in, parser, sink, args.flag("--progress"), error);
  out.write(buf, true);
  out.close();
  std::cerr << format_summary(stage.summary(), stage.has_neural()) << "\n";
  if (!complete) {
    std::cerr << "gcpipe ik: " << error << "\n";
    return 1;
  }
  if (errors > 0) return 3;
  return stage.summary().failed > 0 ? 4 : 0;
}

}  // namespace

constinit const Command kIkCommand{
    "ik", "inverse kinematics of a program: analytic and neural joints with flags",
    "Usage: gcpipe ik IN.nc --csv [--config CFG] [--model MODEL] [--tool-vector] [-o OUT]\n"
    "\n"
    "Parses the program and solves every point that ends a G0/G1/G2/G3 block (its end point).\n"
    "Tool-centre-point blocks (G43.4, M428): tip X Y Z with A C as programmed; other blocks are\n"
    "machine axes and forward kinematics gives the tool path. Prints CSV:\n"
    "  line,X,Y,Z,A,C,Xn,Yn,Zn,An,Cn,flags\n"
    "analytic joints, then the neural model's (mm, deg, 6 decimals), then the flags joined by\n"
    "'|' (near_singular, c_kept, branch_switch, branch_by_limit, travel_limit, unreachable,\n"
    "neural_diverged, neural_outside_envelope, neural_failed). Without a model (--model or\n"
    "the config's ik.model) the neural columns are empty. A summary (counts per status and\n"
    "flag, neural - analytic max and RMS per axis) goes to stderr.\n"
    "\n"
    "  --csv          CSV output (required)\n"
    "  --config CFG   pipeline config (default pipeline_configs/default.yaml); its `ik` section\n"
    "                 sets resolve_orientation, neural_tolerance, downstream\n"
    "  --model MODEL  neural IK model written by `gcpipe train-ik` (default: the config's ik.model)\n"
    "  --tool-vector  TCP blocks give only their tool vector; the IK chooses A and C itself\n"
    "  --progress     progress on stderr for long inputs\n"
    "  -o OUT         write to OUT instead of stdout\n"
    "Exit status: 0 all points solved, 4 some points failed (travel/unreachable), 3 some lines\n"
    "rejected by the parser, 1 stopped, 2 usage.\n",
    run_ik};

}  // namespace gcpipe::cli
