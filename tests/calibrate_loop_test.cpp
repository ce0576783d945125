// The closed loop of issue #13 as a test: a "machine" with a hidden effect records a trace; the
// calibration finds it; a program compensated with calibrated.yaml's model runs on that machine
// with a lower contour error than the same program compensated with the uncalibrated config.
// And gcpipe evaluate's measured contour error against compensate's own evaluation.
#include <gtest/gtest.h>

#include <sstream>

#include "calibrate_test_util.hpp"
#include "compensate_program.hpp"
#include "write.hpp"

namespace gcpipe::calibrate {
namespace {

namespace fs = std::filesystem;

/// Compensates `program` against `model`, runs the written program on `machine` and measures
/// its contour error against the original's nominal path with gcpipe evaluate's code.
ContourFigures compensated_on_machine(const compensate::Model& model, const compensate::Model& machine,
                                      const test::Scenario& sc, const SimulateTraceOptions& hidden = {}) {
  const compensate::CompensateOptions options;
  const auto simulated = simulate::simulate_program(model, sc.program, compensate::run_bounds(options));
  const auto pcomp = compensate::compensate_program(model, options, WriteOptions{}, simulated, {});
  EXPECT_FALSE(pcomp.text.empty()) << pcomp.note;
  const auto blocks = test::parse_text(pcomp.text, sc.pc);
  SimulateTraceOptions o = hidden;  // noise-free: the comparison is about the models
  const MeasuredTrace run = simulate_trace(machine, blocks, o, "compensated run");
  return measured_contour_error(machine, sc.program, run);
}

TEST(CalibrateLoop, CalibratedCompensationBeatsTheUncalibratedOneOnTheMachine) {
  test::Scenario sc = test::circle_scenario();
  sc.machine.drives.axes[kY].effects.push_back(test::effect("backlash", {{"width", 0.015}}));
  sc.machine.drives.axes[kX].effects.push_back(test::effect("coulomb_friction", {{"torque", 25}, {"velocity_band", 0.01}}));
  const Calibration c = calibrate_traces({test::trace_of(sc, 21)}, sc.config);
  compensate::Model calibrated = sc.config;
  calibrated.drives = c.drives;
  const ContourFigures before = measured_contour_error(sc.machine, sc.program, simulate_trace(sc.machine, sc.program, {}, "original run"));
  const ContourFigures uncal = compensated_on_machine(sc.config, sc.machine, sc);
  const ContourFigures cal = compensated_on_machine(calibrated, sc.machine, sc);
  std::cout << "contour error on the machine (max / rms, um): original " << before.cutting_max * 1000 << " / " << before.cutting_rms * 1000
            << ", compensated with the config " << uncal.cutting_max * 1000 << " / " << uncal.cutting_rms * 1000
            << ", compensated with calibrated.yaml " << cal.cutting_max * 1000 << " / " << cal.cutting_rms * 1000 << "\n";
  EXPECT_LT(cal.cutting_max, uncal.cutting_max);
  EXPECT_LT(cal.cutting_rms, 0.5 * uncal.cutting_rms);
}

// Issue 29 item 5's other half: when the machine is the config, calibrating must not make the
// compensation worse (calibrated <= 1.1 x declared).
TEST(CalibrateLoop, OnAMachineThatIsTheConfigTheCalibratedCompensationIsNoWorse) {
  test::Scenario sc = test::circle_scenario();
  sc.config = sc.machine;  // declared right
  const Calibration c = calibrate_traces({test::trace_of(sc, 23)}, sc.config);
  compensate::Model calibrated = sc.config;
  calibrated.drives = c.drives;
  const ContourFigures declared = compensated_on_machine(sc.config, sc.machine, sc);
  const ContourFigures cal = compensated_on_machine(calibrated, sc.machine, sc);
  std::cout << "machine = config, contour error on the machine (max, um): compensated with the config " << declared.cutting_max * 1000
            << ", with calibrated.yaml " << cal.cutting_max * 1000 << "\n";
  for (int a = 0; a < kNumAxes; ++a) EXPECT_TRUE(c.axes[static_cast<std::size_t>(a)].named.empty()) << kAxisLetters[a];
  EXPECT_LE(cal.cutting_max, 1.1 * declared.cutting_max);
}

// The same loop with an effect outside the catalogue: a 40 Hz structural mode on X that only the
// NNOE fallback models. calibrated.yaml carries it as the servo's `nnoe` effect, so the
// compensation simulates the machine with it.
TEST(CalibrateLoop, TheNnoeOfCalibratedYamlHelpsTheCompensationOfAnUnnamedEffect) {
  test::Scenario sc = test::five_axis_scenario();
  const auto machine_run = [](std::uint64_t seed, double noise) {
    SimulateTraceOptions o;
    o.noise = {noise, noise, noise, noise, noise};
    o.seed = seed;
    auto mode = std::make_shared<test::StructuralMode>();
    o.extra = [mode](const compensate::Tick& t, Axes& a) { (*mode)(t, a); };
    return o;
  };
  const Calibration c = calibrate_traces({simulate_trace(sc.machine, sc.program, machine_run(9, 2e-4))}, sc.config);
  ASSERT_TRUE(c.nnoe[kX].has_value()) << "no NNOE fitted on X";
  compensate::Model calibrated = sc.config;
  calibrated.drives = servo::load_drives(Config::from_string(drives_yaml(c, sc.config.drives), "calibrated_drives.yaml"));
  ASSERT_EQ(calibrated.drives.axes[kX].effects.back().type, "nnoe");
  const ContourFigures before = measured_contour_error(sc.machine, sc.program, simulate_trace(sc.machine, sc.program, machine_run(1, 0), "original run"));
  const ContourFigures uncal = compensated_on_machine(sc.config, sc.machine, sc, machine_run(1, 0));
  const ContourFigures cal = compensated_on_machine(calibrated, sc.machine, sc, machine_run(1, 0));
  std::cout << "structural mode on X, contour error on the machine (max / rms, um): original " << before.cutting_max * 1000
            << " / " << before.cutting_rms * 1000 << ", compensated with the config " << uncal.cutting_max * 1000 << " / "
            << uncal.cutting_rms * 1000 << ", compensated with calibrated.yaml (NNOE) " << cal.cutting_max * 1000 << " / "
            << cal.cutting_rms * 1000 << "\n";
  EXPECT_LT(cal.cutting_rms, 0.5 * uncal.cutting_rms);
  EXPECT_LT(cal.cutting_max, uncal.cutting_max);
}

TEST(CalibrateLoop, EvaluateAgreesWithTheSimulatorsOwnContourError) {
  // The measured contour error of a noise-free simulated run against compensate::evaluate's
  // contour error of the same run (a second formulation: its own nominal polyline and tracker).
  test::Scenario sc = test::circle_scenario();
  const fs::path dir = test::scratch("evaluate");
  test::write_csv(simulate_trace(sc.machine, sc.program, {}, "run"), dir / "run.csv");
  std::ofstream(dir / "circle.nc") << test::circle_program();
  std::ofstream(dir / "machine_drives.yaml") << drives_text(sc.machine.drives, "# the machine\n");
  const auto cfg = test::write_config(sc.machine.drives, dir, "machine");
  std::ostringstream out, err;
  EvaluateRequest q;
  q.trace = (dir / "run.csv").string();
  q.program = (dir / "circle.nc").string();
  q.config = cfg.string();
  q.json = (dir / "e.json").string();
  ASSERT_EQ(run_evaluate(q, out, err), 0) << err.str();
  std::cout << out.str();
  const auto j = test::read_json(dir / "e.json");
  const auto& prog = sc.program;
  std::size_t first = 0;
  while (prog[first].motion == Motion::kNone) ++first;
  const Axes start = compensate::machine_start(sc.machine.kin, prog[first], compensate::tool_length_of(sc.machine, prog[first]));
  const auto nom = compensate::build_nominal(sc.machine, prog, start);
  const auto ev = compensate::evaluate(sc.machine, nom, prog, prog, start, [](std::uint32_t i) { return i; });
  // One metric (simulate::ContourSearch) and one cutting/rapid rule: the same figures.
  EXPECT_NEAR(j["cutting"]["max_um"].get<double>(), ev.contour.max * 1000, 1e-3 * ev.contour.max * 1000 + 0.01);
  EXPECT_NEAR(j["cutting"]["rms_um"].get<double>(), ev.contour.rms * 1000, 1e-3 * ev.contour.rms * 1000 + 0.01);
  EXPECT_NEAR(j["rapid"]["max_um"].get<double>(), ev.rapid.max * 1000, 1e-3 * ev.rapid.max * 1000 + 0.01);
  EXPECT_GT(j["cutting"]["samples"].get<int>(), 1000);
  std::ostringstream e2;
  EXPECT_EQ(run_evaluate(EvaluateRequest{}, out, e2), 2);
}

TEST(CalibrateLoop, EvaluateAlignsATraceRecordedBeforeTheProgramStarted) {
  // The recording starts 2 s before the program: the samples at rest are not scored and the
  // figures are those of the run alone (the trace's first commanded motion is the program's).
  test::Scenario sc = test::circle_scenario();
  const MeasuredTrace run = simulate_trace(sc.machine, sc.program, {}, "run");
  MeasuredTrace early = run;
  const std::size_t idle = 2000;
  early.t.clear();
  for (std::size_t k = 0; k < run.size() + idle; ++k) early.t.push_back(static_cast<double>(k) * run.period);
  for (int a = 0; a < kNumAxes; ++a) {
    early.command[a].insert(early.command[a].begin(), idle, run.command[a].front());
    early.actual[a].insert(early.actual[a].begin(), idle, run.actual[a].front());
  }
  const ContourFigures f = measured_contour_error(sc.machine, sc.program, run);
  const ContourFigures g = measured_contour_error(sc.machine, sc.program, early);
  EXPECT_NEAR(g.cutting_max, f.cutting_max, 1e-9);
  EXPECT_NEAR(g.cutting_rms, f.cutting_rms, 1e-9);
  EXPECT_EQ(g.cutting_samples, f.cutting_samples);
  EXPECT_GE(g.idle_samples, idle);
  EXPECT_GT(f.cutting_max, 1e-3);  // the machine's servo lag: a contour error to measure
}

}  // namespace
}  // namespace gcpipe::calibrate
