#include "force_nnoe_process.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <random>

namespace gcpipe::force {

namespace {

/// Piecewise-constant levels: a new uniform level in [lo, hi] every uniform [smin, smax] of `s`.
struct StepSignal {
  double lo, hi, smin, smax;
  std::vector<double> at, level;  // breakpoints and levels
  double value(double s, std::mt19937_64& rng) {
    while (at.empty() || s >= at.back()) {
      std::uniform_real_distribution<double> len(smin, smax), lev(lo, hi);
      at.push_back((at.empty() ? 0.0 : at.back()) + len(rng));
      level.push_back(lev(rng));
    }
    const auto i = static_cast<std::size_t>(std::upper_bound(at.begin(), at.end(), s) - at.begin());
    return level[i];
  }
};

/// Mean |F| of a full slot of depth a at feed f (Altintas' closed form, force_model.hpp).
double slot_force(const ForceProcess& p, double feed, double depth) {
  const Cut cut{p.flutes, feed / (p.flutes * p.spindle), depth, 0.0, std::numbers::pi};
  return mean_force_closed_form(p.coefficients, cut).norm();
}

double mean_of(const std::vector<double>& x) { return std::accumulate(x.begin(), x.end(), 0.0) / static_cast<double>(x.size()); }
double stdev_of(const std::vector<double>& x) {
  const double m = mean_of(x);
  double q = 0;
  for (double v : x) q += (v - m) * (v - m);
  return std::sqrt(q / static_cast<double>(x.size()));
}

}  // namespace

ForceSeries simulate_force_process(const ForceProcess& p, std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  StepSignal feed_cmd{p.feed_min, p.feed_max, p.feed_hold_min, p.feed_hold_max, {}, {}};
  StepSignal profile{p.depth_min, p.depth_max, p.depth_step_min, p.depth_step_max, {}, {}};
  ForceSeries s;
  const double kf = 1 - std::exp(-p.period / p.tau_feed), kF = 1 - std::exp(-p.period / p.tau_force);
  double feed = feed_cmd.value(0, rng), x = 0, force = -1;
  const int window = 16;  // points over the front half of the tool
  for (std::size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * p.period;
    const double command = feed_cmd.value(t, rng);
    double felt = 0;  // depth under the front half of the tool
    for (int i = 0; i < window; ++i) felt += profile.value(x + (i + 0.5) / window * 0.5 * p.diameter, rng) / window;
    const double target = slot_force(p, feed, felt);
    force = force < 0 ? target : force + kF * (target - force);
    s.feed.push_back(command);
    s.depth.push_back(profile.value(x + 0.5 * p.diameter, rng));  // what the front edge enters
    s.clean.push_back(force);
    feed += kf * (command - feed);  // the drive follows the command of this sample
    x += feed / 60 * p.period;
  }
  std::normal_distribution<double> noise(0, p.noise * mean_of(s.clean));
  for (double v : s.clean) s.force.push_back(v + noise(rng));
  return s;
}

std::vector<StructureScore> compare_structures(const ForceSeries& train, const ForceSeries& verify,
                                               const std::vector<calibrate::NnoeStructure>& structures,
                                               const calibrate::NnoeOptions& options) {
  // Seed 003 standardises the signals (mean and standard deviation) before training.
  calibrate::NnoeModel norm;
  norm.y_offset = mean_of(train.force);
  norm.y_scale = stdev_of(train.force);
  norm.u_offset = {mean_of(train.feed), mean_of(train.depth)};
  norm.u_scale = {stdev_of(train.feed), stdev_of(train.depth)};
  const calibrate::Channels u_train{train.feed, train.depth}, u_verify{verify.feed, verify.depth};
  std::vector<StructureScore> out;
  for (const auto& st : structures) {
    StructureScore s;
    s.structure = st;
    s.regressors = regressor_text(st);
    s.model = calibrate::train_nnoe(st, train.force, u_train, 2, train.force.size(), options, norm);
    s.training_fpe = 100 * s.model.fpe;
    s.verification_fpe = 100 * calibrate::nnoe_fpe(s.model, verify.force, u_verify, 2, verify.force.size());
    out.push_back(std::move(s));
  }
  return out;
}

}  // namespace gcpipe::force
