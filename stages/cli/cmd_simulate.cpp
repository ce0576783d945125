// gcpipe simulate: program -> parse -> interpolate -> feed-drive model -> axis trace CSV.
#include <cmath>
#include <cstdio>
#include <deque>
#include <iostream>
#include <numbers>
#include <optional>
#include <sstream>

#include "circle.hpp"
#include "command.hpp"
#include "compensate.hpp"
#include "commands.hpp"
#include "contour.hpp"
#include "gcpipe/config.hpp"
#include "gcpipe/kinematics.hpp"
#include "interpolate.hpp"
#include "program_stream.hpp"
#include "servo.hpp"
#include "trace.hpp"

namespace gcpipe::cli {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

void append_num(std::string& s, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  s += buf;
}

/// Everything downstream of the parser, driven one sample at a time.
struct Simulation final : interpolate::SampleSink {
  servo::ServoSimulator sim;
  const MachineKinematics& kin;
  OutputFile& trace;
  OutputFile* report;
  std::optional<servo::CircleTest> circle;
  std::string trace_buf, report_buf;
  // Raw path samples not yet matched with a servo tick, with the tool length in force when they
  // were interpolated: the actual tip of that tick is computed with the same length, so a G49 or
  // an H change does not show up as a contour error of the length difference.
  struct Nominal {
    Axes joints;
    double tool_length;
  };
  std::deque<Nominal> raw;
  servo::ContourTracker contour;
  double tool_length = 0;
  // summary
  std::uint64_t ticks = 0;
  double max_contour = 0;
  Axes max_following{}, peak_torque{};
  std::array<std::uint64_t, kNumAxes> saturated_ticks{};

  Simulation(const servo::DriveSet& d, double period, const MachineKinematics& k, OutputFile& t,
             OutputFile* r)
      : sim(d, period), kin(k), trace(t), report(r) {}

  Vec3 tip(const Axes& j) const { return forward_kinematics(kin, j, tool_length).tip; }
  Vec3 tip(const Axes& j, double length) const { return forward_kinematics(kin, j, length).tip; }

  void start(const Axes& position) {
    trace_buf = std::string(kTraceHeader) + "\n";
    if (report) {
      report_buf = "t,tip_x,tip_y,tip_z,contour_error";
      if (circle) report_buf += ",alpha,beta,alpha_minus_beta,radius_decrease,shape_error";
      report_buf += "\n";
    }
    raw.push_back({position, tool_length});
    contour.add_nominal(tip(position));
    tick(sim.reset(position, 0.0));
  }
  void raw_sample(const Axes& r) override {
    raw.push_back({r, tool_length});
    contour.add_nominal(tip(r));
  }
  void sample(const Axes& command) override {
    servo::ServoSample out;
    if (sim.push(command, out)) tick(out);
  }
  void drain() {
    servo::ServoSample out;
    while (sim.flush(out)) tick(out);
    trace.write(trace_buf, true);
    if (report) report->write(report_buf, true);
  }
  void tick(const servo::ServoSample& s) {
    const Axes nominal = raw.front().joints;
    const double length = raw.front().tool_length;
    raw.pop_front();
    ++ticks;
    TraceRow row{s.t, s.command, s.actual};
    trace_buf += format_trace_row(row);
    trace_buf += '\n';
    trace.write(trace_buf);
    for (std::size_t i = 0; i < kNumAxes; ++i) {
      max_following[i] = std::max(max_following[i], std::abs(s.command[i] - s.actual[i]));
      peak_torque[i] = std::max(peak_torque[i], std::abs(s.torque[i]));
      if (s.saturated & (1u << i)) ++saturated_ticks[i];
    }
    const Vec3 p = tip(s.actual, length);
    const double e = contour.distance(p);
    max_contour = std::max(max_contour, e);
    if (!report) return;
    append_num(report_buf, s.t);
    for (double v : p) {
      report_buf += ',';
      append_num(report_buf, v);
    }
    report_buf += ',';
    append_num(report_buf, e);
    if (circle) {
      const auto c = servo::circle_point_at(*circle, (nominal[kC] - circle->c_start) * kDeg,
                                            s.actual[kX], s.actual[kY], s.actual[kC]);
      for (double v : {c.alpha, c.beta, c.alpha_minus_beta, c.radius_decrease, c.shape_error}) {
        report_buf += ',';
        append_num(report_buf, v);
      }
    }
    report_buf += '\n';
    report->write(report_buf);
  }
};

int run_simulate(const std::vector<std::string>& argv) {
  Args args(argv, {"--config", "-o", "--report", "--circle"}, {"--strict", "--progress"});
  if (!args.ok()) return usage_error(kSimulateCommand, args.error());
  if (args.positional().size() != 1)
    return usage_error(kSimulateCommand, "give exactly one input program (or - for stdin)");
  if (!args.value("-o")) return usage_error(kSimulateCommand, "give the trace file with -o trace.csv");

  PipelineConfig pc = load_config_option(args.value_or("--config", ""));
  ParseOptions po = load_parse_options(pc.root.section("parse"));
  if (args.flag("--strict")) po.strict = true;
  // The same model the batch job compensates against (machine limits, interpolate section,
  // drives file with Ts per axis).
  const compensate::Model model = compensate::load_model(pc);
  const servo::DriveSet& drives = model.drives;
  interpolate::InterpolateOptions io = model.interp;
  const MachineKinematics& kin = model.kin;

  std::optional<servo::CircleTest> circle;
  if (const auto c = args.value("--circle")) {
    servo::CircleTest t;
    char comma = 0;
    std::istringstream s(*c);
    if (!(s >> t.R_C >> comma >> t.R_W) || comma != ',' || !(t.R_W > 0))
      return usage_error(kSimulateCommand, "--circle takes R_C,R_W in mm, e.g. --circle 5,8");
    circle = t;
  }

  InputFile in(args.positional()[0]);
  Parser parser(po, pc.machine, in.name());
  OutputFile trace(*args.value("-o"));
  std::optional<OutputFile> report;
  if (const auto r = args.value("--report")) report.emplace(*r);
  Simulation simulation(drives, io.period, kin, trace, report ? &*report : nullptr);
  simulation.circle = circle;
  // TCP blocks are interpolated in the workpiece frame and turned into joints per tick; G94
  // feed of joint moves that turn A or C is along the tool-tip path (stages/interpolate/README.md).
  io.kinematics = &kin;

  std::optional<interpolate::Interpolator> interp;
  std::uint64_t errors = 0;
  std::string stop_reason;
  LineSink sink;
  sink.block = [&](const ResolvedBlock& b) {
    simulation.tool_length = b.tool_length_active ? b.tool_length : kin.tool_length;
    if (!interp) {
      if (b.motion == Motion::kNone) return true;
      const Axes start = compensate::machine_start(kin, b, simulation.tool_length);
      interp.emplace(io, start);
      if (circle) {
        circle->c_start = start[kC];
        simulation.circle = circle;
      }
      simulation.start(start);
    }
    const auto r = interp->add(b, simulation);
    if (r.status != interpolate::InterpolateStatus::kOk) {
      Diagnostic d;
      d.file = in.name();
      d.line = b.line;
      d.column = 1;
      d.message = r.message;
      std::cerr << format(d) << "\n";
      stop_reason = "the machine would stop at this block";
      return false;
    }
    return true;
  };
  sink.diagnostic = print_diagnostics(errors);
  std::string error;
  const bool complete = stream_program(in, parser, sink, args.flag("--progress"), error);
  if (interp) {
    interp->finish(simulation);
    simulation.drain();
  } else {
    std::string empty = std::string(kTraceHeader) + "\n";
    trace.write(empty, true);
  }
  trace.close();
  if (report) report->close();

  std::fprintf(stderr, "%s: %llu ticks (%.3f s at %.4g s), max contour error %.4f um (tool tip, workpiece frame)\n",
               in.name().c_str(), static_cast<unsigned long long>(simulation.ticks),
               simulation.ticks ? static_cast<double>(simulation.ticks - 1) * io.period : 0.0, io.period,
               simulation.max_contour * 1e3);
  for (int i = 0; i < kNumAxes; ++i) {
    const auto k = static_cast<std::size_t>(i);
    std::fprintf(stderr, "  %c: max |command - actual| %.4f %s, peak torque %.1f N*m, torque-limited ticks %llu\n",
                 kAxisLetters[i], simulation.max_following[k], i >= kA ? "deg" : "mm", simulation.peak_torque[k],
                 static_cast<unsigned long long>(simulation.saturated_ticks[k]));
  }
  if (interp && interp->stats().velocity_limited_blocks)
    std::fprintf(stderr, "  %llu blocks slowed to respect axis velocity/acceleration limits\n",
                 static_cast<unsigned long long>(interp->stats().velocity_limited_blocks));
  bool out_of_travel = false;
  if (interp) {
    for (int i = 0; i < kNumAxes; ++i) {
      const auto n = interp->stats().travel_violations[static_cast<std::size_t>(i)];
      if (n == 0) continue;
      out_of_travel = true;
      std::fprintf(stderr, "%s:%llu: error: axis %c leaves its travel [%g, %g] in %llu samples (first from this block on)\n",
                   in.name().c_str(), static_cast<unsigned long long>(interp->stats().first_violation_line),
                   kAxisLetters[i], kin.travel[static_cast<std::size_t>(i)].min, kin.travel[static_cast<std::size_t>(i)].max,
                   static_cast<unsigned long long>(n));
    }
    const auto& st = interp->stats();
    if (st.ik_failed_samples) {
      out_of_travel = true;
      std::fprintf(stderr, "%s:%llu: error: tool-centre-point motion has no joint solution within travel in %llu samples (%llu without any finite solution; first in this block)\n",
                   in.name().c_str(), static_cast<unsigned long long>(st.first_ik_failure_line),
                   static_cast<unsigned long long>(st.ik_failed_samples),
                   static_cast<unsigned long long>(st.ik_unreachable_samples));
    }
  }
  if (!complete || !stop_reason.empty()) {
    std::cerr << "gcpipe simulate: " << (stop_reason.empty() ? error : stop_reason) << "\n";
    return 1;
  }
  return errors > 0 || out_of_travel ? 3 : 0;
}

}  // namespace

constinit const Command kSimulateCommand{
    "simulate", "predict the axis motion of a program (interpolator + feed-drive model)",
    "Usage: gcpipe simulate IN.nc --config CFG -o trace.csv [--report R.csv] [--circle R_C,R_W]\n"
    "\n"
    "Interpolates the program at the config's period, smooths each axis (acc/dec after\n"
    "interpolation, Ts from the drives file) and runs the feed-drive model of seed 002 on every\n"
    "axis. The trace has one row per tick: t,X_cmd,Y_cmd,Z_cmd,A_cmd,C_cmd,X,Y,Z,A,C (s, mm, deg).\n"
    "\n"
    "  --config CFG     pipeline config with 'interpolate' and 'servo: {drives: ...}' sections\n"
    "                   (e.g. pipeline_configs/circle_test.yaml)\n"
    "  -o trace.csv     the axis trace (- for stdout)\n"
    "  --report R.csv   per tick: t, actual tool tip in the workpiece frame [mm] and its contour\n"
    "                   error (distance to the nominal tool-tip path) [mm]\n"
    "  --circle R_C,R_W add seed 002's circle-test columns to the report: alpha, beta,\n"
    "                   alpha_minus_beta [rad] (eqs. 8-10), radius_decrease, shape_error [mm]\n"
    "                   (eqs. 11, 6); the nominal angle is the raw commanded C\n"
    "  --strict         stop at the first rejected line\n"
    "  --progress       progress on stderr\n"
    "Tool-centre-point blocks (G43.4, M428, G43.5) move the tool tip along the programmed path\n"
    "in the workpiece frame; joints come from the machine's inverse kinematics every tick.\n"
    "Exit status: 0 ok, 3 some lines rejected or an axis left its travel, 1 stopped (strict, I/O, or a block the machine\n"
    "cannot run), 2 usage.\n",
    run_simulate};

}  // namespace gcpipe::cli
