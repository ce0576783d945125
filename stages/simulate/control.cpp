// The look-ahead control's run (interpolate::Control::kLookahead): its plan is the reference of
// reference.cpp (acc/dec before interpolation, corners blended within the path tolerance, exact
// stops), the drives follow it tick by tick, and where the plan stands still the control's
// in-position check holds it until the drives are there. Rules and sources:
// stages/interpolate/README.md, "Control models".
#include <algorithm>
#include <cmath>

#include "simulate.hpp"

namespace gcpipe::simulate {

namespace {

// Two reference ticks this close on every axis [mm, deg] are the plan standing still (the
// compact reference keeps 0.5 nm; a move at 1e-9 mm a tick would be 1 um/s).
constexpr double kStill = 1e-9;

bool stands_still(const Axes& a, const Axes& b) {
  for (std::size_t i = 0; i < kNumAxes; ++i)
    if (std::abs(a[i] - b[i]) > kStill) return false;
  return true;
}

bool in_position(const Axes& actual, const Axes& target, double width) {
  for (std::size_t i = 0; i < kNumAxes; ++i)
    if (std::abs(actual[i] - target[i]) > width) return false;
  return true;
}

/// The five drives fed one command a tick. Tick 0 is the rest at the start; every output
/// sample goes to `out` with its tick, in order (the drives' feed-forward reads a few ticks
/// ahead, so the newest come with later pushes or finish()).
class DriveRun {
 public:
  using Out = std::function<void(const servo::ServoSample&, std::uint64_t)>;
  DriveRun(const Model& model, const Axes& start, Out out) : sim_(model.drives, model.interp.period), out_(std::move(out)) {
    emit(sim_.reset(start, 0.0));
  }
  void push(const Axes& command) {
    servo::ServoSample s;
    if (sim_.push(command, s)) emit(s);
  }
  void finish() {
    servo::ServoSample s;
    while (sim_.flush(s)) emit(s);
  }
  /// The newest actual position handed on, and its tick.
  const Axes& actual() const { return last_.actual; }
  std::uint64_t actual_tick() const { return n_ - 1; }

 private:
  void emit(const servo::ServoSample& s) {
    last_ = s;
    out_(s, n_++);
  }
  servo::ServoSimulator sim_;
  Out out_;
  servo::ServoSample last_{};
  std::uint64_t n_ = 0;
};

/// The largest tick of a wait for in-position: a drive with backlash or friction may never get
/// within the width, and a control then raises an alarm; here the wait is cut and counted.
constexpr double kMaxWaitSeconds = 2.0;

}  // namespace

InPositionWaits add_in_position_waits(const Model& model, Nominal& nom, const Axes& start) {
  InPositionWaits w;
  const std::size_t E = nom.reference.size();
  if (E < 3) return w;
  JointSeries reference;
  ScratchArray<std::uint32_t> progress;
  DriveRun drives(model, start, [](const servo::ServoSample&, std::uint64_t) {});
  auto keep = [&](const Axes& r, std::uint32_t p) {
    reference.push_back(r);
    progress.push_back(p);
  };
  const auto cap = static_cast<std::uint64_t>(std::ceil(kMaxWaitSeconds / model.interp.period));
  keep(nom.reference[0], nom.progress[0]);
  Axes prev = nom.reference[0], r = nom.reference[1];
  for (std::size_t n = 1; n < E; ++n) {
    const Axes next = n + 1 < E ? nom.reference[n + 1] : r;
    drives.push(r);
    keep(r, nom.progress[n]);
    // The last tick of a stretch where the plan stands still (an exact stop, a dwell, the end):
    // the next motion waits until every axis is in position.
    // The drives hand a tick on a few ticks after its command (their feed-forward reads ahead):
    // the check reads the actual position of this tick or a later one, never an earlier one.
    if (stands_still(prev, r) && (n + 1 == E || !stands_still(r, next))) {
      ++w.checks;
      std::uint64_t held = 0;
      const std::uint64_t tick = reference.size() - 1;
      while ((drives.actual_tick() < tick || !in_position(drives.actual(), r, model.interp.in_position)) && held < cap) {
        drives.push(r);
        keep(r, nom.progress[n]);
        ++held;
      }
      w.ticks += held;
      w.capped += held == cap;
    }
    prev = r, r = next;
  }
  nom.reference = std::move(reference);
  nom.progress = std::move(progress);
  return w;
}

Evaluation run_commands(const Model& model, const Nominal& nom, std::span<const ResolvedBlock> program,
                        const Axes& start, std::size_t ticks, const CommandAt& command, const TickFn& on_tick) {
  RunEvaluation ev(model, nom, program, start, true);
  RunStats stats;
  const double T = model.interp.period;
  const std::size_t last_raw = nom.raw.size() - 1;
  Axes c1 = start, c2 = start;
  // Under seed 002's control the commands pass its acc/dec after interpolation first (the
  // feed-forward run of that model); the look-ahead control has none.
  std::array<interpolate::AxisSmoother, kNumAxes> smooth;
  for (std::size_t i = 0; i < kNumAxes; ++i)
    smooth[i] = interpolate::AxisSmoother(model.interp.smoothing, model.interp.smoothing_time[i], T, start[i]);
  DriveRun drives(model, start, [&](const servo::ServoSample& s, std::uint64_t n) {
    Tick t;
    t.n = n;
    const std::size_t k = std::min<std::size_t>(nom.progress[std::min<std::size_t>(n, nom.progress.size() - 1)], last_raw);
    t.raw = nom.raw[k];
    t.block = nom.block[k];
    t.command = s.command;
    t.actual = s.actual;
    t.torque = s.torque;
    t.saturated = s.saturated;
    auto& is = stats.interp;
    for (std::size_t i = 0; i < kNumAxes; ++i) {
      if (s.saturated & (1u << i)) ++stats.saturated_ticks[i];
      if (n >= 1) is.peak_velocity[i] = std::max(is.peak_velocity[i], std::abs(s.command[i] - c1[i]) / T);
      if (n >= 2) is.peak_acceleration[i] = std::max(is.peak_acceleration[i], std::abs(s.command[i] - 2 * c1[i] + c2[i]) / (T * T));
    }
    c2 = c1, c1 = s.command;
    ev.add(t, t.block, on_tick);
    stats.ticks = n + 1;
  });
  auto push = [&](const Axes& u) {
    Axes c;
    for (std::size_t i = 0; i < kNumAxes; ++i) c[i] = smooth[i].filter(u[i]);
    drives.push(c);
  };
  for (std::size_t n = 1; n < ticks; ++n) push(command(n));
  // Until the acc/dec has settled on the last command (at once without one).
  const Axes last = ticks > 1 ? command(ticks - 1) : start;
  std::size_t settle = 0;
  for (const auto& s : smooth) settle = std::max(settle, s.settle_samples());
  for (std::size_t j = 0; j < settle; ++j) push(last);
  drives.finish();
  stats.interp.samples = stats.ticks;
  return ev.finish(stats);
}

}  // namespace gcpipe::simulate
