// gcpipe simulate: parse -> trochoid -> ik -> simulate, the axis trace as CSV. The figures it
// prints are the simulate stage's, the same harness and contour metric as batch's report.json.
#include <charconv>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <numbers>
#include <sstream>

#include "circle.hpp"
#include "gcpipe/chunked_worker.hpp"
#include "commands.hpp"
#include "program_run.hpp"
#include "simulate_stage.hpp"
#include "trace.hpp"

namespace gcpipe::cli {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

void append_num(std::string& s, double v) {
  char buf[64];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, 9);
  (void)ec;
  s.append(buf, end);
}

// The per-tick report: tip and contour error, and seed 002's circle-test columns with --circle.
class TickReport {
 public:
  TickReport(const std::string& path, std::optional<servo::CircleTest> circle) : out_(path), circle_(circle) {
    buf_ = "t,tip_x,tip_y,tip_z,contour_error";
    if (circle_) buf_ += ",alpha,beta,alpha_minus_beta,radius_decrease,shape_error";
    buf_ += '\n';
  }
  void add(const simulate::Tick& t, double period) {
    if (circle_ && !started_) circle_->c_start = t.raw[kC];
    started_ = true;
    append_num(buf_, static_cast<double>(t.n) * period);
    for (double v : t.tip) buf_ += ',', append_num(buf_, v);
    buf_ += ',';
    append_num(buf_, t.contour);
    if (circle_) {
      const auto c = servo::circle_point_at(*circle_, (t.raw[kC] - circle_->c_start) * kDeg, t.actual[kX],
                                            t.actual[kY], t.actual[kC]);
      for (double v : {c.alpha, c.beta, c.alpha_minus_beta, c.radius_decrease, c.shape_error}) buf_ += ',', append_num(buf_, v);
    }
    buf_ += '\n';
    out_.write(buf_);
  }
  void commit() {
    out_.write(buf_, true);
    out_.commit();
  }

 private:
  pipeline::AtomicFile out_;
  std::optional<servo::CircleTest> circle_;
  std::string buf_;
  bool started_ = false;
};

// The trace formatted and written on a second thread: shortest round-trip doubles and the kernel's
// page cache cost about half as much as the simulation itself, and on two cores the two run side
// by side (gcpipe/chunked_worker.hpp: the simulation waits when the writer is four chunks of 1024
// rows behind). The bytes are those of append_trace_row, row by row (TraceRowFormatter).
class BackgroundTrace {
 public:
  explicit BackgroundTrace(const std::string& path)
      : file_(path), buf_(std::string(kTraceHeader) + "\n"),
        rows_(1024, 4, [this](const std::vector<TraceRow>& rows) { write(rows); }) {
    buf_.reserve((1u << 20) + 64 * 1024);  // AtomicFile writes at 1 MiB: the buffer never grows
  }

  void add(double t, const Axes& command, const Axes& actual) { rows_.push(TraceRow{t, command, actual}); }
  /// Writes what is left and renames the file to its final name; rethrows a write error.
  void commit() {
    rows_.finish();  // the writer thread has ended: buf_ and file_ are this thread's again
    file_.write(buf_, true);
    file_.commit();
  }

 private:
  void write(const std::vector<TraceRow>& rows) {
    for (const TraceRow& r : rows) {
      format_.append(buf_, r);
      buf_ += '\n';
    }
    file_.write(buf_);
  }

  pipeline::AtomicFile file_;
  std::string buf_;
  TraceRowFormatter format_;
  ChunkedWorker<TraceRow> rows_;  // last: its thread writes into the members above
};

std::optional<servo::CircleTest> parse_circle(const std::string& text) {
  if (text.empty()) return std::nullopt;
  servo::CircleTest t;
  char comma = 0;
  std::istringstream s(text);
  if (!(s >> t.R_C >> comma >> t.R_W) || comma != ',' || !(t.R_W > 0))
    throw std::invalid_argument("--circle takes R_C,R_W in mm, e.g. --circle 5,8");
  return t;
}

void print_summary(const std::string& name, const compensate::Model& m, const simulate::SimulationRun* run) {
  if (run == nullptr || !run->before) return;
  const auto& ev = *run->before;
  std::fprintf(stderr, "%s: %llu ticks (%.3f s at %.4g s), max contour error %.4f um (cutting moves, tool tip, workpiece frame)\n",
               name.c_str(), static_cast<unsigned long long>(ev.stats.ticks),
               ev.stats.ticks ? static_cast<double>(ev.stats.ticks - 1) * m.interp.period : 0.0, m.interp.period,
               ev.contour.max * 1e3);
  for (int i = 0; i < kNumAxes; ++i) {
    const auto k = static_cast<std::size_t>(i);
    std::fprintf(stderr, "  %c: max |command - actual| %.4f %s, torque-limited ticks %llu\n", kAxisLetters[i],
                 ev.axes.max_following[k], i >= kA ? "deg" : "mm", static_cast<unsigned long long>(ev.axes.saturated_ticks[k]));
  }
}

}  // namespace

int run_simulate(const SimulateArgs& a) {
  pipeline::install_stop_handlers();
  std::optional<servo::CircleTest> circle;
  try {
    circle = parse_circle(a.circle);
  } catch (const std::invalid_argument& e) {
    std::cerr << "gcpipe simulate: " << e.what() << "\n";
    return 2;
  }
  PrintedLog log;
  ProgramRun run(a, {"simulate"}, log);
  auto& sim = dynamic_cast<SimulateStage&>(*run.pipeline().stage("simulate"));
  sim.trace_only();
  BackgroundTrace trace(a.output);
  std::unique_ptr<TickReport> report;
  if (!a.report.empty()) report = std::make_unique<TickReport>(a.report, circle);
  const double period = sim.model().interp.period;
  sim.on_tick([&](const simulate::Tick& t) {
    trace.add(static_cast<double>(t.n) * period, t.command, t.actual);
    if (report) report->add(t, period);
  });
  const bool complete = run.run();
  if (pipeline::stop_requested()) return exit_status(complete, "", 0);
  const std::string failure = run.pipeline().failure();
  if (failure.empty()) {  // a program the machine cannot run gets no trace that looks like one
    trace.commit();
    if (report) report->commit();
  }
  print_summary(run.input_name(), sim.model(), sim.run());
  if (!complete) std::cerr << "gcpipe simulate: " << run.error() << "\n";
  else if (!failure.empty()) std::cerr << "gcpipe simulate: " << failure << "\n";
  return exit_status(complete, failure, run.pipeline().rejected());
}

}  // namespace gcpipe::cli
