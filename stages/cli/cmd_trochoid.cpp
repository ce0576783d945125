// gcpipe trochoid: parse a program, expand its G275 trochoidal slot cycles, write the program.
#include <cstdio>
#include <iostream>

#include "command.hpp"
#include "commands.hpp"
#include "gcpipe/config.hpp"
#include "program_stream.hpp"
#include "trochoid.hpp"
#include "trochoid_report.hpp"
#include "write.hpp"

namespace gcpipe::cli {
namespace {

int run_trochoid(const std::vector<std::string>& argv) {
  Args args(argv, {"--config", "-o", "--png"}, {"--strict", "--progress"});
  if (!args.ok()) return usage_error(kTrochoidCommand, args.error());
  if (args.positional().size() != 1)
    return usage_error(kTrochoidCommand, "give exactly one input program (or - for stdin)");
  PipelineConfig pc = load_config_option(args.value_or("--config", ""));
  ParseOptions po = load_parse_options(pc.root.section("parse"));
  if (args.flag("--strict")) po.strict = true;
  const TrochoidExpander expander(load_trochoid_options(pc.root.section("trochoid")));
  Writer writer(load_write_options(pc.root.section("write")));
  InputFile in(args.positional()[0]);
  Parser parser(po, pc.machine, in.name());
  OutputFile out(args.value_or("-o", "-"));
  const auto png = args.value("--png");

  std::string buf;
  std::vector<ResolvedBlock> expanded;
  std::vector<TrochoidPart> parts;
  // The figure needs the whole expanded program; without --png only one block's worth is held.
  std::vector<ResolvedBlock> program;
  std::vector<TrochoidPart> program_parts;
  std::vector<std::vector<Point2>> outlines;
  double tool_diameter = 0;
  std::uint64_t cycles = 0, rejected = 0, blocks_out = 0, errors = 0;
  LineSink sink;
  sink.block = [&](const ResolvedBlock& b) {
    expanded.clear();
    parts.clear();
    Diagnostic d;
    const auto st = expander.step(b, in.name(), expanded, d, &parts);
    if (!st.ok()) {
      std::cerr << format(d) << "\n";
      writer.write_diagnostic(d, buf);
      for (const auto& e : expanded) writer.write(e, buf);
      blocks_out += expanded.size();
      ++rejected;
      ++errors;
      return !po.strict;
    }
    if (st.code == TrochoidExpander::Status::Code::kExpanded) {
      ++cycles;
      if (tool_diameter == 0) tool_diameter = b.slot.tool_diameter;
      if (png) outlines.push_back(slot_outline(b.slot));
    }
    for (const auto& e : expanded) writer.write(e, buf);
    blocks_out += expanded.size();
    if (png) {
      program.insert(program.end(), expanded.begin(), expanded.end());
      program_parts.insert(program_parts.end(), parts.begin(), parts.end());
    }
    out.write(buf);
    return true;
  };
  sink.diagnostic = [&](const Diagnostic& d) {
    if (d.severity == Severity::kError) ++errors;
    std::cerr << format(d) << "\n";
    writer.write_diagnostic(d, buf);
    return true;
  };
  std::string error;
  const bool complete = stream_program(in, parser, sink, args.flag("--progress"), error);
  out.write(buf, true);
  out.close();
  std::fprintf(stderr, "%s: %llu G275 cycles expanded, %llu rejected, %llu blocks written\n",
               in.name().c_str(), static_cast<unsigned long long>(cycles),
               static_cast<unsigned long long>(rejected), static_cast<unsigned long long>(blocks_out));
  if (png) {
    if (cycles == 0) {
      std::cerr << "gcpipe trochoid: no G275 cycle expanded, no figure written to " << *png << "\n";
    } else {
      PathAnalysisOptions ao;
      ao.tool_radius = 0.5 * tool_diameter;
      const PathAnalysis a = analyse_path(program, &program_parts, ao);
      char title[160];
      std::snprintf(title, sizeof title, "%s: tool centre path, D%g", in.name().c_str(), tool_diameter);
      write_engagement_png(*png, a, ao.tool_radius, title, outlines);
      std::fprintf(stderr, "%s: max radial engagement %.2f deg (ae %.3f mm) outside entry and start "
                   "circle, air part %.2f deg; figure %s\n", in.name().c_str(), a.max_angle * 57.29577951308232,
                   equivalent_ae(a.max_angle, ao.tool_radius), a.max_air_angle * 57.29577951308232, png->c_str());
    }
  }
  if (!complete) {
    std::cerr << "gcpipe trochoid: " << error << "\n";
    return 1;
  }
  return errors > 0 ? 3 : 0;
}

}  // namespace

constinit const Command kTrochoidCommand{
    "trochoid", "expand G275 trochoidal slot cycles into G1/G2/G3 blocks",
    "Usage: gcpipe trochoid IN.nc [--config CFG] [-o OUT.nc] [--png PATH.png] [--strict]\n"
    "\n"
    "Parses IN, replaces every G275 trochoidal slot cycle by its tool path (seed 000 eq. 6;\n"
    "stages/trochoid/README.md) and writes the program; other blocks pass through. A cycle that\n"
    "cannot be machined (slot not wider than the tool, step beyond the engagement limit, zero\n"
    "length, ...) is reported as file:line: error: reason and left out as a comment; rapids at\n"
    "the clearance plane then take the tool to the cycle's end so the program continues as\n"
    "written.\n"
    "\n"
    "  --config CFG  pipeline config (default pipeline_configs/default.yaml); section trochoid:\n"
    "  -o OUT        write to OUT instead of stdout\n"
    "  --png PATH    tool path coloured by radial engagement (holds the expanded program in memory)\n"
    "  --strict      stop at the first error\n"
    "Exit status: 0 all accepted, 3 some lines or cycles rejected, 1 stopped, 2 usage.\n",
    run_trochoid};

}  // namespace gcpipe::cli
