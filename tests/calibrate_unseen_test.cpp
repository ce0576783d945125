// The measured-data loop judged on machines gcpipe has not seen (issue 29, items 4 and 5): drives
// from the second simulator (tests/unseen_machine, no code shared with stages/servo: sampled
// P/PI controller, moving-average feed-forward without look-ahead, rigid or two-mass plant),
// every gain and inertia drawn x0.5...x2 of the configured one, feed-forward 0...100 %, the
// velocity loop's integral corner near the position loop. Each machine runs one of the circle,
// the trochoidal slot and the five-axis move with none, one or two catalogue effects or one
// outside the catalogue, 0.2 um noise; calibrate is given the shipped config (circle_test.yaml).
//
// Scored per machine: the catalogue effect named on its axis within 15 %; nothing named on a
// clean machine; nothing named on the axis of an effect outside the catalogue. And the loop closed
// (item 5): the program compensated with the declared config and with the calibrated drives, both
// run on the machine, max cutting contour error.
//
// GCPIPE_UNSEEN_MACHINES=N runs N machines from GCPIPE_UNSEEN_FIRST (0) (the CI runs the first few; the benchmark
// script tests/bench/unseen_machines.sh runs 36 and prints the table); GCPIPE_UNSEEN_LOOP=N closes
// the loop on the first N of them.
#include <gtest/gtest.h>

#include <cstdlib>
#include <iomanip>
#include <random>
#include <regex>

#include "calibrate_test_util.hpp"
#include "compensate_program.hpp"
#include "unseen_machine/unseen_machine.hpp"
#include "write.hpp"

namespace gcpipe::calibrate {
namespace {

constexpr int kUnseenAxes[] = {kX, kY, kC};

double uniform(std::mt19937_64& rng, double lo, double hi) {
  return lo + (hi - lo) * (static_cast<double>(rng() >> 11) * 0x1.0p-53);
}

/// One catalogue effect put on the machine and what calibrate should report.
struct Truth {
  int axis = -1;
  std::string effect, key;  //!< catalogue name and its main number
  double value = 0;
};

struct Case {
  int seed = 0;
  std::string program;
  std::array<unseen::AxisMachine, kNumAxes> axes{};
  std::vector<Truth> effects;
  int outside_axis = -1;  //!< axis with an effect outside the catalogue
  std::string outside;
};

unseen::Seed002Equivalent base_of(const servo::DriveParams& p) {
  return {p.Kpp, p.Kvp, p.Kvi, p.C, p.J + p.J1, p.K_FFP};
}

/// A catalogue effect of a size a 0.2 um trace shows (several um), on `axis`.
Truth catalogue_effect(std::mt19937_64& rng, unseen::AxisMachine& m, int axis) {
  const bool rotary = axis == kC;
  std::vector<std::string> menu = {"backlash", "measurement_delay", "coulomb_friction"};
  if (!rotary) menu.push_back("scale_error");
  if (axis == kX) menu.push_back("lead_error");  // X has a ball screw (16 mm lead)
  const std::string e = menu[static_cast<std::size_t>(rng() % menu.size())];
  Truth t{axis, e, "", 0};
  if (e == "backlash") { t.key = "width"; t.value = m.backlash = uniform(rng, 0.006, 0.02); }
  if (e == "measurement_delay") { t.key = "delay"; t.value = m.measurement_delay = uniform(rng, 1.5e-3, 4e-3); }
  if (e == "scale_error") { t.key = "ppm"; t.value = m.scale_ppm = uniform(rng, 60, 150); }
  if (e == "lead_error") {
    t.key = "amplitude";
    t.value = m.lead_amp = uniform(rng, 0.003, 0.006);
    m.lead_period = 16;
    m.lead_phase = uniform(rng, -3, 3);
  }
  if (e == "coulomb_friction") {
    // A torque that would hold the position loop about 10 um off: T = e Kv Kp / g.
    t.key = "torque";
    t.value = m.coulomb = uniform(rng, 0.6, 1.5) * 0.010 / unseen::load_per_motor_rad(m) * m.Kv * m.Kp;
  }
  return t;
}

Case make_case(int seed, const compensate::Model& config) {
  Case c;
  c.seed = seed;
  const char* programs[] = {"circle", "trochoid", "five_axis"};
  c.program = programs[seed % 3];
  for (int a : kUnseenAxes) {
    const auto& p = config.drives.axes[static_cast<std::size_t>(a)];
    c.axes[static_cast<std::size_t>(a)] = unseen::draw_axis(1000 + 17 * static_cast<std::uint64_t>(seed) + static_cast<std::uint64_t>(a), base_of(p), a == kC,
                                                           a == kX ? p.lead : 0);
    c.axes[static_cast<std::size_t>(a)].measurement_delay = 0;  // a delay is an effect here, drawn below
  }
  std::mt19937_64 rng(77 + static_cast<std::uint64_t>(seed));
  const int kind = seed % 5;  // 0, 1 clean; 2 one effect; 3 two effects; 4 outside the catalogue
  // Effects go on axes the program moves: the circle and the slot move X and Y only.
  const int moving = c.program == "five_axis" ? 3 : 2;
  if (kind == 2 || kind == 3) {
    const int first = static_cast<int>(rng() % static_cast<std::uint64_t>(moving));
    const int a = kUnseenAxes[first];
    c.effects.push_back(catalogue_effect(rng, c.axes[static_cast<std::size_t>(a)], a));
    if (kind == 3) {
      const int b = kUnseenAxes[(first + 1 + static_cast<int>(rng() % static_cast<std::uint64_t>(moving - 1))) % moving];
      c.effects.push_back(catalogue_effect(rng, c.axes[static_cast<std::size_t>(b)], b));
    }
  }
  if (kind == 4) {
    c.outside_axis = kUnseenAxes[rng() % 2];  // X or Y
    auto& m = c.axes[static_cast<std::size_t>(c.outside_axis)];
    if (rng() % 2) {
      c.outside = "cogging";
      m.cogging_order = 8;
      m.cogging = 0.010 / unseen::load_per_motor_rad(m) * m.Kv * m.Kp;  // ~10 um if the loop held it statically
    } else {
      c.outside = "thermal drift";
      m.drift_rate = 0.004;  // 4 um/s
      m.drift_onset = 0.5;
    }
  }
  return c;
}

std::string program_text(const std::string& name) {
  if (name == "circle") return test::circle_program();
  if (name == "trochoid") return test::trochoid_program();
  return test::five_axis_program();
}

/// The control's commands of `program` (the configured interpolator) and the machine's response.
MeasuredTrace run_on_machine(const Case& c, const compensate::Model& config, std::span<const ResolvedBlock> program,
                             double noise, std::uint64_t seed) {
  MeasuredTrace tr = simulate_trace(config, program, {}, "unseen machine " + std::to_string(c.seed));
  std::mt19937_64 rng(seed);
  for (int a : kUnseenAxes) {
    const auto run = unseen::run_axis(c.axes[static_cast<std::size_t>(a)], tr.command[static_cast<std::size_t>(a)], tr.period);
    tr.actual[static_cast<std::size_t>(a)] = run.actual;
  }
  for (auto& axis : tr.actual)
    for (double& v : axis) v += noise > 0 ? noise * normal01(rng) : 0.0;
  return tr;
}

std::string named_on(const AxisIdentification& id) {
  std::string s;
  for (const auto& n : id.named) {
    s += (s.empty() ? "" : ", ") + n.effect;
    for (const auto& p : n.params) s += " " + p.name + "=" + std::to_string(p.value);
  }
  return s.empty() ? "-" : s;
}

double named_value(const AxisIdentification& id, const Truth& t) {
  for (const auto& n : id.named)
    if (n.effect == t.effect)
      for (const auto& p : n.params)
        if (p.name == t.key) return p.value;
  return NAN;
}

struct Score {
  int effects = 0, effects_found = 0, clean = 0, clean_silent = 0, outside = 0, outside_silent = 0;
  int false_names = 0;  //!< effects named where the machine has none, on any machine
};

/// Calibrates one case and scores it; returns the calibration.
Calibration judge(const Case& c, const compensate::Model& config, const PipelineConfig& pc, Score& score) {
  const auto program = test::parse_text(program_text(c.program), pc);
  const MeasuredTrace tr = run_on_machine(c, config, program, 2e-4, 500 + static_cast<std::uint64_t>(c.seed));
  Calibration cal = calibrate_traces({tr}, config);
  std::cout << "machine " << c.seed << " (" << c.program << "):";
  for (int a : kUnseenAxes) std::cout << " " << kAxisLetters[a] << "[" << c.axes[static_cast<std::size_t>(a)].describe() << "]";
  std::cout << "\n";
  for (int a : kUnseenAxes) {
    const auto& id = cal.axes[static_cast<std::size_t>(a)];
    std::cout << "  " << kAxisLetters[a] << ": named " << named_on(id) << (id.base.structural_mismatch ? "; mismatch: " + id.base.mismatch : "") << "\n";
  }
  if (std::getenv("GCPIPE_UNSEEN_VERBOSE"))
    for (int a : kUnseenAxes) test::print(cal.axes[static_cast<std::size_t>(a)]);
  for (int a : kUnseenAxes)
    for (const auto& n : cal.axes[static_cast<std::size_t>(a)].named)
      if (std::none_of(c.effects.begin(), c.effects.end(), [&](const Truth& t) { return t.axis == a && t.effect == n.effect; })) {
        std::cout << "  " << kAxisLetters[a] << ": " << n.effect << " named where the machine has none\n";
        ++score.false_names;
        test::print(cal.axes[static_cast<std::size_t>(a)]);
      }
  for (const auto& t : c.effects) {
    ++score.effects;
    const double v = named_value(cal.axes[static_cast<std::size_t>(t.axis)], t);
    const bool ok = std::abs(v - t.value) <= 0.15 * std::abs(t.value);
    score.effects_found += ok;
    std::cout << "  effect " << kAxisLetters[t.axis] << " " << t.effect << " " << t.key << " " << t.value << ": " << (ok ? "found " : "MISSED ") << v << "\n";
    if (!ok) test::print(cal.axes[static_cast<std::size_t>(t.axis)]);
  }
  if (c.effects.empty() && c.outside.empty()) {
    ++score.clean;
    bool silent = true;
    for (int a : kUnseenAxes) silent = silent && cal.axes[static_cast<std::size_t>(a)].named.empty();
    score.clean_silent += silent;
    std::cout << "  clean: " << (silent ? "nothing named" : "NAMED SOMETHING") << "\n";
  }
  if (!c.outside.empty()) {
    ++score.outside;
    const bool silent = cal.axes[static_cast<std::size_t>(c.outside_axis)].named.empty();
    score.outside_silent += silent;
    std::cout << "  outside (" << c.outside << " on " << kAxisLetters[c.outside_axis] << "): " << (silent ? "unidentified" : "NAMED") << "\n";
  }
  return cal;
}

int env_count(const char* name, int fallback) {
  const char* v = std::getenv(name);
  return v ? std::atoi(v) : fallback;
}

TEST(CalibrateUnseen, EffectsAreNamedAndCleanMachinesStaySilent) {
  const PipelineConfig pc = test::circle_config();
  const compensate::Model config = compensate::load_model(pc);
  const int machines = env_count("GCPIPE_UNSEEN_MACHINES", 5), first = env_count("GCPIPE_UNSEEN_FIRST", 0);
  Score s;
  for (int i = first; i < first + machines; ++i) (void)judge(make_case(i, config), config, pc, s);
  std::cout << "unseen machines: " << machines << "; effects found within 15 %: " << s.effects_found << "/" << s.effects
            << "; clean machines with nothing named: " << s.clean_silent << "/" << s.clean
            << "; outside-catalogue effects left unidentified: " << s.outside_silent << "/" << s.outside
            << "; effects named where the machine has none (any machine): " << s.false_names << "\n";
  // The targets are >= 90 % of effects found, >= 95 % of clean machines silent, effects
  // outside the catalogue left unidentified. NOT MET on the whole set (README 13: friction on
  // two-mass axes underestimated, delays off by more than 15 %). Here, on the CI's 5 machines,
  // what holds is guarded so that a change that names more or finds less fails: the scale error
  // found within 15 % (1 of the 3 effects; the two Coulomb frictions on two-mass X axes come out
  // at 36 and 56 of 70 N*m: the identified drive takes part of the friction as damping), the
  // outside effect unidentified, both clean machines silent and nothing named where the machine
  // has none (machine 1's clean two-mass Y named a 2.7 ms measurement delay until a delay had to
  // beat the drive's own lag, README 3.0).
  const bool ci_set = first == 0 && machines == 5;
  if (ci_set) {
    EXPECT_GE(s.effects_found, 1);
    EXPECT_EQ(s.outside_silent, s.outside);
    EXPECT_EQ(s.clean_silent, s.clean);
    EXPECT_EQ(s.false_names, 0);
  } else {
    std::cout << "targets: effects " << (s.effects_found >= 0.9 * s.effects ? "met" : "NOT MET") << ", clean "
              << (s.clean_silent >= 0.95 * s.clean ? "met" : "NOT MET") << ", outside "
              << (s.outside_silent >= 0.9 * s.outside ? "met" : "NOT MET") << "\n";
  }
}

// --- item 5: the loop closed on the unseen machine ---------------------------------------------

/// Max cutting contour error [mm] of `program` compensated with `model`, run on the machine.
double compensated_on_machine(const compensate::Model& model, const compensate::Model& config, const Case& c,
                              const PipelineConfig& pc, std::span<const ResolvedBlock> program) {
  const compensate::CompensateOptions options;
  const auto simulated = simulate::simulate_program(model, program, compensate::run_bounds(options));
  const auto pcomp = compensate::compensate_program(model, options, WriteOptions{}, simulated, {});
  if (pcomp.text.empty()) return NAN;
  const auto blocks = test::parse_text(pcomp.text, pc);
  const MeasuredTrace run = run_on_machine(c, config, blocks, 0, 1);
  return measured_contour_error(config, program, run).cutting_max;
}

// The target (calibrated <= 0.5 x declared where the config is off) is asserted on the CI's
// machine 0; the benchmark prints the ratio on more (README 13) without failing.
TEST(CalibrateUnseen, CalibratedCompensationBeatsTheDeclaredOneOnTheMachine) {
  const PipelineConfig pc = test::circle_config();
  const compensate::Model config = compensate::load_model(pc);
  const int machines = env_count("GCPIPE_UNSEEN_LOOP", 1), first = env_count("GCPIPE_UNSEEN_FIRST", 0);
  for (int i = first; i < first + machines; ++i) {
    const Case c = make_case(i, config);
    Score s;
    const Calibration cal = judge(c, config, pc, s);
    compensate::Model calibrated = config;
    calibrated.drives = cal.drives;
    // Rule 5's warning: calibrated_drives.yaml carries what the calibration knows it predicts
    // badly, and reads back with it (the simulate stage repeats each as a warning).
    const servo::DriveSet written = servo::load_drives(Config::from_string(drives_yaml(cal, config.drives), "calibrated_drives.yaml"));
    EXPECT_EQ(written.prediction_warnings, prediction_warnings(cal));
    for (int a : kUnseenAxes)
      if (cal.axes[static_cast<std::size_t>(a)].base.structural_mismatch) {
        const std::string letter(1, kAxisLetters[a]);
        EXPECT_TRUE(std::any_of(written.prediction_warnings.begin(), written.prediction_warnings.end(),
                                [&](const std::string& w) { return w.rfind(letter + ":", 0) == 0; }))
            << "axis " << letter << " has a structural mismatch and no warning";
      }
    for (const auto& w : written.prediction_warnings) std::cout << "  warning: " << w << "\n";
    const auto program = test::parse_text(program_text(c.program), pc);
    const double original = measured_contour_error(config, program, run_on_machine(c, config, program, 0, 1)).cutting_max;
    const double declared = compensated_on_machine(config, config, c, pc, program);
    const double with_cal = compensated_on_machine(calibrated, config, c, pc, program);
    std::cout << "closed loop, machine " << i << " (" << c.program << "): max cutting contour error on the machine: original "
              << original * 1000 << " um, compensated with the declared config " << declared * 1000
              << " um, with calibrated.yaml " << with_cal * 1000 << " um (ratio " << with_cal / declared << ")\n";
    if (machines == 1 && first == 0) EXPECT_LE(with_cal, 0.5 * declared) << "machine " << i;
  }
}

}  // namespace
}  // namespace gcpipe::calibrate

namespace gcpipe::calibrate {
namespace {

// Issue 29 item 7: on real traces sampled every 100 ms (the University of Michigan mill), nothing
// is named that fails rule 2: the 0.5 mm "lead error" that was the distance moved in one sample is
// seen and not named, and the report says what such samples cannot show.
TEST(CalibrateRealData, UmichTracesNameNothingThatIsASamplingArtefact) {
  const std::vector<MeasuredTrace> experiments = test::umich_experiments();
  if (experiments.empty()) GTEST_SKIP() << "shared data absent: " << GCPIPE_SHARED_DATA << "/traces/umich_smart_cnc_mill";
  ASSERT_EQ(experiments.size(), 6u);
  const PipelineConfig pc = test::circle_config();
  const compensate::Model config = compensate::load_model(pc);
  for (std::size_t n = 0; n < experiments.size(); ++n) {
    const std::size_t i = n + 1;
    const Calibration c = calibrate_traces({experiments[n]}, config);
    const std::string report = report_text(c);
    EXPECT_NE(report.find("are not visible at this rate"), std::string::npos);
    EXPECT_FALSE(std::regex_search(report, std::regex("\\b-?nan\\b"))) << report.substr(0, 2000);
    for (int a = 0; a < kNumAxes; ++a)
      for (const auto& n : c.axes[static_cast<std::size_t>(a)].named) {
        std::cout << "experiment " << i << " " << kAxisLetters[a] << ": named " << n.effect << "\n";
        EXPECT_NE(n.effect, "lead_error") << "experiment " << i << " axis " << kAxisLetters[a];
        EXPECT_NE(n.effect, "backlash");
        EXPECT_NE(n.effect, "measurement_delay");
        EXPECT_NE(n.effect, "feedback_delay");
      }
    std::cout << report.substr(0, report.find("gcpipe calibrate:")) << "\n";
  }
}

}  // namespace
}  // namespace gcpipe::calibrate
