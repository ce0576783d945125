// The servo's `nnoe` effect (stages/servo/nnoe_effect.cpp, streaming, inside the drive) against
// the calibrate stage's NnoeModel::simulate (offline, over a whole series): the same correction
// on every sample, on an ideal axis and on a drive; and its config errors.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "calibrate.hpp"
#include "gcpipe/config.hpp"
#include "nnoe.hpp"
#include "servo.hpp"

using namespace gcpipe;

namespace {

constexpr double kT = 0.001;

// A smooth command (three sines, mm) of n samples.
std::vector<double> command_series(std::size_t n) {
  std::vector<double> c(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * kT;
    c[k] = 5 * std::sin(2 * M_PI * 0.7 * t) + 0.8 * std::sin(2 * M_PI * 3.1 * t + 1) + 0.1 * std::sin(2 * M_PI * 17 * t);
  }
  return c;
}

// A stable NNOE with random weights, scaled like calibrate scales a residual of a few um.
calibrate::NnoeModel random_model(const std::vector<double>& v, const std::vector<double>& a) {
  calibrate::NnoeModel m;
  m.structure = {2, 2, 8, {}};
  m.net = neural::Mlp({2 + 2 * 2, 8, 1});
  std::mt19937_64 rng(5);
  m.net.initialise(rng);
  m.net.set_parameters(0.4 * m.net.parameters());  // small recurrent gain: a stable model
  m.y_scale = 3e-3;
  m.y_offset = 1e-4;
  double vs = 0, as = 0;
  for (std::size_t k = 0; k < v.size(); ++k) vs += v[k] * v[k], as += a[k] * a[k];
  m.u_scale = {std::sqrt(vs / static_cast<double>(v.size())), std::sqrt(as / static_cast<double>(a.size()))};
  m.u_offset = {0.5, -2.0};
  m.decimation = 4;
  return m;
}

// Positions of one axis replayed tick by tick, the window padded at the end with the last
// command as ServoSimulator::flush does (the calibrate stage's simulate_motor does the same).
std::vector<double> replay(const servo::DriveParams& p, const std::vector<double>& c) {
  servo::AxisDrive d(p, kT, 8, 0.9);
  const auto w = static_cast<std::size_t>(d.window());
  std::vector<double> padded(c);
  padded.resize(c.size() + w, c.back());
  d.reset(c[0]);
  std::vector<double> y(c.size(), c[0]);
  for (std::size_t k = 1; k < c.size(); ++k) y[k] = d.step(std::span<const double>(padded.data() + k - 1, w)).position;
  return y;
}

void expect_streaming_equals_offline(servo::DriveParams p) {
  const auto c = command_series(6000);
  std::vector<double> v, a;
  calibrate::differentiate(c, kT, v, a);
  const calibrate::NnoeModel m = random_model(v, a);
  const std::vector<double> offline = m.simulate(v, a);
  const std::vector<double> without = replay(p, c);
  p.effects.push_back(calibrate::nnoe_effect(m, kT));
  const std::vector<double> with = replay(p, c);
  double worst = 0, size = 0;
  // The offline series ends with v = a = 0 (one-sided); the drive holds the last command. Both
  // agree until the last blocks.
  for (std::size_t k = 1; k + 20 < c.size(); ++k) {
    worst = std::max(worst, std::abs((with[k] - without[k]) - offline[k]));
    size = std::max(size, std::abs(offline[k] - m.y_offset));
  }
  EXPECT_GT(size, 1e-4) << "the model should move: a test of a constant proves nothing";
  EXPECT_LT(worst, 1e-12) << "largest difference streaming - offline [mm]";
}

TEST(NnoeEffect, StreamingOnAnIdealAxisEqualsTheOfflineModel) {
  servo::DriveParams p;
  p.model = servo::DriveModel::kIdeal;
  expect_streaming_equals_offline(p);
}

TEST(NnoeEffect, StreamingOnADriveEqualsTheOfflineModelAndLeavesTheLoopAlone) {
  expect_streaming_equals_offline(servo::DriveParams{});
}

std::string drives_with(const std::string& nnoe) {
  return "axes:\n  X:\n    effects:\n      nnoe: {" + nnoe + "}\n";
}

std::string load_error(const std::string& yaml) {
  try {
    const servo::DriveSet d = servo::load_drives(Config::from_string(yaml, "drives.yaml"));
    servo::AxisDrive drive(d.axes[0], kT, 8, 0.9);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(NnoeEffect, ConfigErrorsSayWhatIsWrong) {
  const std::string ok = "period: 0.001, decimation: 1, na: 1, nb: 1, hidden: 1, y_scale: 1, y_offset: 0, u_scale: [1, 1], u_offset: [0, 0], ";
  EXPECT_EQ(load_error(drives_with(ok + "weights: [0, 0, 0, 0, 0, 0]")), "");
  const std::string few = load_error(drives_with(ok + "weights: [0, 0]"));
  EXPECT_NE(few.find("'weights' has 2 numbers"), std::string::npos) << few;
  EXPECT_NE(few.find("needs 6"), std::string::npos) << few;
  const std::string missing = load_error(drives_with("period: 0.001, u_scale: [1, 1], u_offset: [0, 0]"));
  EXPECT_NE(missing.find("weights"), std::string::npos) << missing;
  EXPECT_NE(missing.find("required"), std::string::npos) << missing;
  std::string rate = ok + "weights: [0, 0, 0, 0, 0, 0]";
  rate.replace(rate.find("0.001"), 5, "0.002");
  const std::string other = load_error(drives_with(rate));
  EXPECT_NE(other.find("fitted on samples every 0.002"), std::string::npos) << other;
}

}  // namespace
