// Identification on traces from gcpipe's own simulator: the right effect on the right axis with
// its parameters within 10 %, the calibrated prediction within 2x the noise, no effect named on
// clean traces, two effects found together. The configured drive parameters are off by +-20 %.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <sstream>

#include "axis_model.hpp"
#include "calibrate_test_util.hpp"
#include "identify.hpp"

namespace gcpipe::calibrate {
namespace {

using test::Scenario;

constexpr double kNoise = 2e-4;  // mm (deg on A, C): the traces' noise

/// One catalogued effect on one axis of a "true" machine: it must be the only effect named, on
/// that axis, each parameter within 10 %, and the calibrated prediction within 2x the noise.
void check_single(Scenario sc, int axis, const servo::EffectSettings& e, double torque_limit = 0) {
  if (torque_limit > 0) sc.machine.drives.axes[static_cast<std::size_t>(axis)].torque_limit = torque_limit;
  else sc.machine.drives.axes[static_cast<std::size_t>(axis)].effects.push_back(e);
  const auto ids = test::identify_all(sc, 7);
  const std::string name = torque_limit > 0 ? "torque_limit" : e.type;
  test::expect_named(ids, axis, {name});
  const auto& id = ids[static_cast<std::size_t>(axis)];
  // Torques are seen only relative to the inertia (the configured J is 20 % off, and a position
  // trace cannot see J): the identified torque is the true one times J_config / J_true.
  const auto& cfg = sc.config.drives.axes[static_cast<std::size_t>(axis)];
  const auto& tru = sc.machine.drives.axes[static_cast<std::size_t>(axis)];
  const double j_ratio = (cfg.J + cfg.J1) / (tru.J + tru.J1);
  if (torque_limit > 0) EXPECT_NEAR(test::param(id, name, "torque_limit"), torque_limit * j_ratio, 0.1 * torque_limit * j_ratio);
  for (auto [k, v] : e.values) {
    if (k == "phase" || k == "velocity_band") continue;  // phase: wraps; band: fixed by design
    if (k == "torque") v *= j_ratio;
    EXPECT_NEAR(test::param(id, name, k), v, 0.1 * std::abs(v)) << name << "." << k;
  }
  for (const auto& i : ids)
    if (i.moving) EXPECT_LE(test::calibrated_rms(sc, 7, i), 2 * kNoise) << "axis " << kAxisLetters[i.axis];
  test::print(id);
}

TEST(CalibrateIdentify, BacklashOnYCircle) {
  check_single(test::circle_scenario(), kY, test::effect("backlash", {{"width", 0.010}}));
}
TEST(CalibrateIdentify, CoulombFrictionOnXCircle) {
  check_single(test::circle_scenario(), kX, test::effect("coulomb_friction", {{"torque", 30}, {"velocity_band", 0.01}}));
}
TEST(CalibrateIdentify, LeadErrorOnXCircle) {
  check_single(test::circle_scenario(), kX, test::effect("lead_error", {{"amplitude", 0.003}, {"period", 16}, {"phase", 30}}));
}
TEST(CalibrateIdentify, FeedbackDelayOnYTrochoid) {
  check_single(test::trochoid_scenario(), kY, test::effect("feedback_delay", {{"delay", 0.003}}));
}
TEST(CalibrateIdentify, MeasurementDelayOnXTrochoid) {
  check_single(test::trochoid_scenario(), kX, test::effect("measurement_delay", {{"delay", 0.002}}));
}
TEST(CalibrateIdentify, ScaleErrorOnYFiveAxis) {
  check_single(test::five_axis_scenario(), kY, test::effect("scale_error", {{"ppm", 80}}));
}
TEST(CalibrateIdentify, RotaryBacklashOnCFiveAxis) {
  check_single(test::five_axis_scenario(), kC, test::effect("backlash", {{"width", 0.01}}));
}
TEST(CalibrateIdentify, TorqueLimitOnCFiveAxis) {
  check_single(test::five_axis_scenario(), kC, {}, 75.0);
}

}  // namespace
}  // namespace gcpipe::calibrate
