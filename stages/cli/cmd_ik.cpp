// gcpipe ik: parse -> trochoid -> ik, one CSV row per solved point.
#include <iostream>

#include "commands.hpp"
#include "gcpipe/number_format.hpp"
#include "ik_stage.hpp"
#include "program_run.hpp"

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

}  // namespace

int run_ik(const IkArgs& a) {
  pipeline::install_stop_handlers();
  PrintedLog log;
  pipeline::StageContext overrides;
  overrides.ik_model = a.model;
  overrides.ik_tool_vector = a.tool_vector;
  ProgramRun run(a, {"ik"}, log, overrides);
  auto& ik = dynamic_cast<IkPipelineStage&>(*run.pipeline().stage("ik"));
  pipeline::AtomicFile out(a.output);
  std::string buf = "line,X,Y,Z,A,C,Xn,Yn,Zn,An,Cn,flags\n";
  ik.on_point([&](const IkPoint& p) {
    append_row(buf, p);
    out.write(buf);
  });
  const bool complete = run.run();
  if (pipeline::stop_requested()) return exit_status(complete, "", 0);
  out.write(buf, true);
  out.commit();
  std::cerr << format_summary(ik.solver().summary(), ik.solver().has_neural()) << "\n";
  if (!complete) std::cerr << "gcpipe ik: " << run.error() << "\n";
  const int status = exit_status(complete, "", run.pipeline().rejected());
  return status == 0 && ik.solver().summary().failed > 0 ? 4 : status;
}

}  // namespace gcpipe::cli
