#include "local_slowdown.hpp"

#include <algorithm>
#include <cmath>

namespace gcpipe::compensate {

namespace {

// A second whose feed-forward asks at most this much of the limit is left at the control's speed:
// the learning's own check allows 1 % over it for the second difference of 1 ms samples.
constexpr double kAllowed = 1.0;

// Reference tick -> raw sample of the plan (clamped).
std::size_t raw_at(const simulate::Nominal& nom, std::size_t tick) {
  if (nom.progress.empty()) return 0;
  return std::min<std::size_t>(nom.progress[std::min(tick, nom.progress.size() - 1)], nom.raw.size() - 1);
}

/// New caps for the seconds of `over` above the limit, on `nom`'s clock.
std::vector<simulate::ReferencePlan::SpeedCap> caps_for(const simulate::Nominal& nom, const std::vector<double>& over,
                                                        double T) {
  std::vector<simulate::ReferencePlan::SpeedCap> caps;
  const auto second = static_cast<std::size_t>(std::llround(1.0 / T));
  for (std::size_t s = 0; s < over.size(); ++s) {
    if (!(over[s] > kAllowed)) continue;
    const std::size_t a = s * second > second / 2 ? s * second - second / 2 : 0;
    const std::size_t b = (s + 1) * second + second / 2;
    caps.push_back({raw_at(nom, a), raw_at(nom, b), std::clamp(0.95 / std::sqrt(over[s]), 0.2, 0.95)});
  }
  return caps;
}

SlowStretch stretch_of(const simulate::Nominal& control, const simulate::ReferencePlan::SpeedCap& c, double T) {
  SlowStretch s;
  s.first_line = control.brief[control.block[c.first]].line;
  s.last_line = control.brief[control.block[c.last]].line;
  s.factor = c.factor;
  // The control's clock where its plan reaches those raw samples.
  std::size_t n = 0;
  while (n < control.progress.size() && control.progress[n] < c.first) ++n;
  s.t_begin = static_cast<double>(n) * T;
  while (n < control.progress.size() && control.progress[n] < c.last) ++n;
  s.t_end = static_cast<double>(n) * T;
  return s;
}

}  // namespace

LocalSlowdown slow_where_drives_cannot_follow(const simulate::Model& model, const simulate::SimulationRun& control,
                                              const FeedforwardRun& ff, simulate::ReferencePlan plan,
                                              double max_machine_time, int max_rounds) {
  LocalSlowdown r;
  const double T = model.interp.period;
  std::vector<double> over = ff.over_limit;
  r.worst_over_limit = over.empty() ? 0.0 : *std::max_element(over.begin(), over.end());
  const simulate::Nominal* clock = &*control.nominal;
  for (int round = 0; round < max_rounds; ++round) {
    const std::vector<simulate::ReferencePlan::SpeedCap> more = caps_for(*clock, over, T);
    if (more.empty()) break;
    plan.caps.insert(plan.caps.end(), more.begin(), more.end());
    simulate::SimulationRun slowed = control;
    simulate::Nominal& nom = *slowed.nominal;
    simulate::plan_reference(model, plan, max_machine_time / T, nom);
    if (nom.reference_too_long || nom.reference.empty()) break;
    const simulate::InPositionWaits w = simulate::add_in_position_waits(model, nom, slowed.start);
    nom.in_position_ticks = w.ticks, nom.in_position_checks = w.checks, nom.in_position_capped = w.capped;
    ++r.rounds;
    r.run = std::move(slowed);
    clock = &*r.run->nominal;
    over = feedforward_run(model, *clock, r.run->program, r.run->start).over_limit;
    r.worst_over_limit = over.empty() ? 0.0 : *std::max_element(over.begin(), over.end());
  }
  // The stretches as the report gives them: each cap on the control's clock, overlapping caps
  // (a stretch slowed in two rounds) merged, with the lowest product of the factors in force at
  // any sample of it (they multiply where they overlap; the product changes only where one begins).
  std::vector<simulate::ReferencePlan::SpeedCap> caps = plan.caps;
  if (!r.run) return r;
  std::sort(caps.begin(), caps.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  auto product_at = [&](std::size_t g) {
    double f = 1;
    for (const auto& c : caps)
      if (c.first <= g && g <= c.last) f *= c.factor;
    return f;
  };
  std::vector<simulate::ReferencePlan::SpeedCap> merged;
  for (const auto& c : caps) {
    if (!merged.empty() && c.first <= merged.back().last) {
      merged.back().last = std::max(merged.back().last, c.last);
      merged.back().factor = std::min(merged.back().factor, product_at(c.first));
    } else {
      merged.push_back({c.first, c.last, product_at(c.first)});
    }
  }
  for (const auto& c : merged) r.stretches.push_back(stretch_of(*control.nominal, c, T));
  return r;
}

}  // namespace gcpipe::compensate
