// The look-ahead control (interpolate.control: lookahead, stages/interpolate/README.md "Control
// models"): exact stops with an in-position check at every rapid's end and at G61 blocks, feed
// corners blended within the path tolerance without stopping, commands within the axes' limits,
// and the compensation on the control's own clock. The judges are the programmed geometry, worked
// in this file, and the drives' simulated actual positions (not the planner's own figures).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "chain_inverse.hpp"
#include "compensate.hpp"
#include "compensate_program.hpp"
#include "gcpipe/config.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "parse.hpp"
#include "parse_helpers.hpp"
#include "unseen_machine/unseen_machine.hpp"
#include "write.hpp"

namespace gcpipe::compensate {
namespace {

namespace fs = std::filesystem;

std::vector<ResolvedBlock> parse_text(const std::string& text, const PipelineConfig& pc) {
  const test::Parsed parsed = test::parse_text(text, {}, pc.machine, "test.nc");
  for (const Diagnostic& d : parsed.diags)
    if (d.severity == Severity::kError) ADD_FAILURE() << format(d);
  return parsed.blocks;
}

PipelineConfig default_config() {
  return load_pipeline_config(fs::path(GCPIPE_SOURCE_DIR) / "pipeline_configs" / "default.yaml");
}

// Two rapids meeting at X20 Y0 and ending at X20 Y10, then feed moves with a 90 degree corner at
// X40 Y10 (`corner`: G64 or G61 for the block that ends there).
std::string program_text(const std::string& corner) {
  return "G21 G17 G90 G94\nG0 X0. Y0. Z0.\nG0 X20.\nG0 Y10.\n" + corner + " G1 X40. F3000.\nG64 G1 Y30.\nG1 X20.\nM30\n";
}

struct ControlRun {
  PipelineConfig pc = default_config();
  Model model = load_model(pc);
  std::vector<ResolvedBlock> program;
  simulate::SimulationRun run;
  std::vector<Tick> ticks;
  explicit ControlRun(const std::string& corner) {
    program = parse_text(program_text(corner), pc);
    run = simulate::simulate_program(model, program, run_bounds(CompensateOptions{}), [&](const Tick& t) { ticks.push_back(t); });
  }
};

double point_segment(double px, double py, double ax, double ay, double bx, double by) {
  const double dx = bx - ax, dy = by - ay;
  const double s = std::clamp(((px - ax) * dx + (py - ay) * dy) / (dx * dx + dy * dy), 0.0, 1.0);
  return std::hypot(px - ax - s * dx, py - ay - s * dy);
}

// The ticks at which the control's command stands at (x, y) (within 1e-9 mm): the last of them.
std::size_t last_tick_at(const std::vector<Tick>& ticks, double x, double y, std::size_t& count) {
  count = 0;
  std::size_t last = 0;
  for (std::size_t n = 0; n < ticks.size(); ++n)
    if (std::abs(ticks[n].command[kX] - x) < 1e-9 && std::abs(ticks[n].command[kY] - y) < 1e-9) last = n, ++count;
  return last;
}

// Some tick of the stretch where the command stands still (its last tick `last`, `count` long)
// has every axis's actual within `width` of the command: the in-position check passed there.
bool in_position_before_moving_on(const std::vector<Tick>& ticks, std::size_t last, std::size_t count, double width) {
  for (std::size_t n = last + 1 - count; n <= last; ++n) {
    bool all = true;
    for (std::size_t i = 0; i < kNumAxes; ++i) all = all && std::abs(ticks[n].actual[i] - ticks[n].command[i]) <= width;
    if (all) return true;
  }
  return false;
}

TEST(LookaheadControl, TheDefaultMachineRunsIt) {
  const Model model = load_model(default_config());
  EXPECT_EQ(model.interp.control, interpolate::Control::kLookahead);
  EXPECT_EQ(model.interp.smoothing, interpolate::Smoothing::kNone);
}

// At the end of each rapid the command stands still, and the next motion starts only once every
// axis's simulated actual position is within interpolate.in_position of it.
TEST(LookaheadControl, EveryRapidEndsWithAStopInPosition) {
  const ControlRun r("G64");
  ASSERT_TRUE(r.run.before) << r.run.note;
  const double width = r.model.interp.in_position;
  for (const auto& [x, y] : {std::pair{20.0, 0.0}, std::pair{20.0, 10.0}}) {
    std::size_t count = 0;
    const std::size_t n = last_tick_at(r.ticks, x, y, count);
    EXPECT_GE(count, 4u) << "the plan does not stand still at X" << x << " Y" << y;
    EXPECT_TRUE(in_position_before_moving_on(r.ticks, n, count, width))
        << "the motion after X" << x << " Y" << y << " starts before every axis is in position";
  }
}

// A feed corner in G64 without P is blended within interpolate.path_tolerance (the programmed
// geometry judges) and passed without stopping; in G61 it is an exact stop in position.
TEST(LookaheadControl, FeedCornersBlendWithinTheToleranceAndStopInG61) {
  const ControlRun blend("G64"), stop("G61");
  ASSERT_TRUE(blend.run.before && stop.run.before);
  const double tol = blend.model.interp.path_tolerance, T = blend.model.interp.period;
  double worst = 0, slowest_near_corner = 1e9;
  for (std::size_t n = 1; n < blend.ticks.size(); ++n) {
    const Axes& c = blend.ticks[n].command;
    if (c[kY] < 10 - 1e-9 || c[kX] < 20 - 1e-9) continue;  // on the feed moves
    const double d = std::min({point_segment(c[kX], c[kY], 20, 10, 40, 10), point_segment(c[kX], c[kY], 40, 10, 40, 30),
                               point_segment(c[kX], c[kY], 40, 30, 20, 30)});
    worst = std::max(worst, d);
    if (std::hypot(c[kX] - 40, c[kY] - 10) < 0.5) {
      const Axes& p = blend.ticks[n - 1].command;
      slowest_near_corner = std::min(slowest_near_corner, std::hypot(c[kX] - p[kX], c[kY] - p[kY]) / T);
    }
  }
  EXPECT_LE(worst, tol * 1.05) << "the blend leaves the programmed corner by more than the tolerance";
  EXPECT_GT(worst, 1e-4) << "the G64 corner was not blended";
  EXPECT_GT(slowest_near_corner, 1.0) << "mm/s: the G64 corner was stopped at";
  std::size_t count = 0;
  const std::size_t n = last_tick_at(stop.ticks, 40, 10, count);
  EXPECT_GE(count, 4u) << "the G61 corner is not an exact stop";
  EXPECT_TRUE(in_position_before_moving_on(stop.ticks, n, count, stop.model.interp.in_position));
}

// The commands the drives get stay within every axis's velocity and acceleration limit (measured
// on the ticks: first and second differences).
TEST(LookaheadControl, CommandsStayWithinTheAxisLimits) {
  const ControlRun r("G64");
  ASSERT_TRUE(r.run.before);
  const double T = r.model.interp.period;
  for (std::size_t n = 2; n < r.ticks.size(); ++n)
    for (std::size_t i = 0; i < kNumAxes; ++i) {
      const double v = std::abs(r.ticks[n].command[i] - r.ticks[n - 1].command[i]) / T;
      const double a = std::abs(r.ticks[n].command[i] - 2 * r.ticks[n - 1].command[i] + r.ticks[n - 2].command[i]) / (T * T);
      ASSERT_LE(v, r.model.kin.max_velocity[i] * (1 + 1e-6)) << "axis " << kAxisLetters[i] << " tick " << n;
      ASSERT_LE(a, r.model.kin.max_acceleration[i] * (1 + 1e-6)) << "axis " << kAxisLetters[i] << " tick " << n;
    }
}

TEST(LookaheadControl, ConfigRejectsAnAccDecAfterInterpolationWithIt) {
  const fs::path p = fs::temp_directory_path() / "gcpipe_lookahead_smoothing.yaml";
  {
    std::ofstream f(p);
    f << "period: 0.001\ncontrol: lookahead\nsmoothing: exponential\n";
  }
  EXPECT_THROW(interpolate::load_interpolate_options(Config::load_file(p)), ConfigError);
  fs::remove(p);
}

// The compensated program keeps the control's timing (issue 31 item 3: at most 1.02 times its
// cycle), and the model-inverse feed-forward, run on the control's clock, is measured beside it.
TEST(LookaheadControl, TheCompensationKeepsTheControlsCycle) {
  ControlRun r("G64");
  ASSERT_TRUE(r.run.before);
  CompensateOptions opt;
  opt.node_period = r.model.interp.period;
  opt.slowed_baseline = false;
  const ProgramCompensation pc = compensate_program(r.model, opt, WriteOptions{}, r.run, {});
  ASSERT_TRUE(pc.result && pc.result->compensated) << pc.note;
  const double T = r.model.interp.period;
  const double control = static_cast<double>(r.run.before->stats.ticks) * T;
  const double compensated = static_cast<double>(pc.result->end_tick) * T;
  EXPECT_LE(compensated, 1.02 * control);
  EXPECT_GE(compensated, 0.98 * control);
  const Evaluation ff = feedforward_run(r.model, *r.run.nominal, r.program, r.run.start).eval;
  EXPECT_NEAR(static_cast<double>(ff.stats.ticks) * T, control, 0.01 * control);
  // The drives' model inverse on the control's own clock brings the error down by itself (X of
  // seed 002 lags by its slow velocity loop; the inverse leads it by that).
  std::printf("contour error before %.2f um, feed-forward %.2f um\n", r.run.before->contour.max * 1e3, ff.contour.max * 1e3);
  EXPECT_LT(ff.contour.max, 0.5 * r.run.before->contour.max);
}

}  // namespace
}  // namespace gcpipe::compensate

namespace gcpipe::compensate {
namespace {

// The X and Y drives of seed 002 rebuilt in the second simulator (tests/unseen_machine: a sampled
// controller at 0.25 ms, moving-average feed-forward without look-ahead, implicit trapezoidal
// integration, no code shared with stages/servo), with the drives file's own numbers.
unseen::AxisMachine unseen_twin(const servo::DriveParams& p, double lead) {
  unseen::AxisMachine m;
  m.lead = lead;
  m.J = p.J + p.J1;
  m.c = p.C;
  m.Kp = p.Kpp;
  m.Kv = p.Kvp;
  m.Ki = p.Kvi;
  m.kff = p.K_FFP / 100;
  m.Tff = 0.001;
  return m;
}

// Distance of (x, y) to the programmed path of kUnseenProgram: X0->X10 on Y0, the full circle of
// radius 10 about (10, 10) from (10, 0), and back along Y0 (the same line).
double to_program(double x, double y) {
  return std::min(point_segment(x, y, 0, 0, 10, 0), std::abs(std::hypot(x - 10, y - 10) - 10));
}

const char* kUnseenProgram = "G21 G17 G90 G94\nG0 X0. Y0. Z0.\nG1 X10. F3000.\nG2 X10. Y0. I0. J10.\nG1 X0.\nM30\n";

// Largest and RMS distance of the unseen machine's X Y to the programmed path when it is fed
// `command` (one row a tick).
std::pair<double, double> unseen_contour(const std::array<unseen::AxisMachine, 2>& xy, const std::vector<Axes>& command,
                                         double T) {
  std::array<std::vector<double>, 2> c;
  for (const Axes& a : command) c[0].push_back(a[kX]), c[1].push_back(a[kY]);
  const auto x = unseen::run_axis(xy[0], c[0], T).actual, y = unseen::run_axis(xy[1], c[1], T).actual;
  double worst = 0, sum_sq = 0;
  for (std::size_t n = 0; n < x.size(); ++n) {
    const double e = to_program(x[n], y[n]);
    worst = std::max(worst, e);
    sum_sq += e * e;
  }
  return {worst, std::sqrt(sum_sq / static_cast<double>(std::max<std::size_t>(1, x.size())))};
}

// A line into an arc that starts back along it (a reversal at X10 Y0): the corner rule bounds the
// blend's jump, but the speed smoothing fills the dip at the corner from both sides; the plan's
// acceleration check slows it until X stays within its limit (it asked 7237 mm/s^2 of 5050).
TEST(LookaheadControl, AReversalStaysWithinTheAccelerationLimit) {
  const PipelineConfig pc = default_config();
  const Model model = load_model(pc);
  const auto program = parse_text(kUnseenProgram, pc);
  std::vector<Axes> c;
  const auto run = simulate::simulate_program(model, program, run_bounds(CompensateOptions{}),
                                              [&](const Tick& t) { c.push_back(t.command); });
  ASSERT_TRUE(run.before) << run.note;
  const double T = model.interp.period;
  double worst = 0;
  for (std::size_t n = 2; n < c.size(); ++n)
    for (std::size_t i = 0; i < kNumAxes; ++i)
      if (model.kin.max_acceleration[i] > 0)
        worst = std::max(worst, std::abs(c[n][i] - 2 * c[n - 1][i] + c[n - 2][i]) / (T * T) / model.kin.max_acceleration[i]);
  EXPECT_LE(worst, 1.0 + 1e-6) << "of the acceleration limit";
  EXPECT_GT(worst, 0.05) << "the program did not accelerate at all";
}

// The judge independent of the model the compensation learned on: the control's plan and the
// compensated program, both run on the unseen twin of the X Y drives (a machine built otherwise
// with the drives file's numbers). What of the compensation carries over to it.
TEST(LookaheadControl, TheCompensationHoldsOnTheUnseenMachine) {
  const PipelineConfig pc = default_config();
  const Model model = load_model(pc);
  const auto program = parse_text(kUnseenProgram, pc);
  const auto run = simulate::simulate_program(model, program, run_bounds(CompensateOptions{}));
  ASSERT_TRUE(run.before) << run.note;
  CompensateOptions opt;
  opt.node_period = model.interp.period;
  opt.slowed_baseline = false;
  const ProgramCompensation comp = compensate_program(model, opt, WriteOptions{}, run, {});
  ASSERT_TRUE(comp.result && comp.result->compensated) << comp.note;
  // compensated.nc as written, read back and interpolated by the control: its commands per tick.
  const auto blocks = parse_text(comp.text, pc);
  std::vector<Axes> after;
  simulate::run_program(model, blocks, run.start, [&](const Tick& t) { after.push_back(t.command); });
  std::vector<Axes> before;
  for (std::size_t n = 0; n < run.nominal->reference.size(); ++n) before.push_back(run.nominal->reference[n]);
  const auto& d = model.drives.axes;
  const std::array<unseen::AxisMachine, 2> xy{unseen_twin(d[kX], 0.016), unseen_twin(d[kY], 0.0)};
  const double T = model.interp.period;
  const auto [max_before, rms_before] = unseen_contour(xy, before, T);
  const auto [max_after, rms_after] = unseen_contour(xy, after, T);
  std::printf("unseen machine: contour error before max %.2f um RMS %.2f um, after max %.2f um RMS %.2f um; "
              "gcpipe's model before max %.2f um\n",
              max_before * 1e3, rms_before * 1e3, max_after * 1e3, rms_after * 1e3, run.before->contour.max * 1e3);
  RecordProperty("unseen_max_before_um", std::to_string(max_before * 1e3));
  RecordProperty("unseen_max_after_um", std::to_string(max_after * 1e3));
  // The twin is a twin: the control's own run shows the same largest error on both machines.
  EXPECT_NEAR(max_before, run.before->contour.max, 0.1 * run.before->contour.max);
  // Measured: max 104.4 -> 70.1 um, RMS 49.6 -> 21.4 um. On gcpipe's own model the same
  // compensated program has max 78.2 um, RMS 16.2 um (its feed-forward start had 14.6 um, but
  // broke X's acceleration limit where the program stops, and the learning fell back towards the
  // plan there: stages/compensate/README.md "The judge on the unseen machine"). The unseen
  // machine confirms the figures of gcpipe's model, the good and the bad.
  EXPECT_LT(rms_after, 0.6 * rms_before);
  EXPECT_LT(max_after, 0.8 * max_before);
}

}  // namespace
}  // namespace gcpipe::compensate
