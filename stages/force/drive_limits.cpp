#include "drive_limits.hpp"

#include <algorithm>
#include <cmath>

namespace gcpipe::force {

namespace {

/// The interpolator's samples are not needed here, only its timing.
class DiscardSamples final : public interpolate::SampleSink {
 public:
  void sample(const Axes&) override {}
};

bool is_feed_move(const ResolvedBlock& b) {
  return b.motion == Motion::kLinear || b.motion == Motion::kArcCW || b.motion == Motion::kArcCCW;
}

/// Takes time or moves: a junction of the path lies on each side of it.
bool occupies_the_path(const ResolvedBlock& b) { return b.motion != Motion::kNone; }

/// Path acceleration [mm/s^2] at which no axis exceeds its limit: on the block, axis i moves
/// axis_travel_i per feed_length of path, so a path acceleration a asks a * travel_i / length of it.
double path_acceleration(const interpolate::InterpolateResult& r, const interpolate::InterpolateOptions& o) {
  double a = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < kNumAxes; ++i)
    if (r.axis_travel[i] > 0 && o.max_acceleration[i] > 0)
      a = std::min(a, o.max_acceleration[i] * r.feed_length / r.axis_travel[i]);
  return a;
}

BlockDrive drive_of(const ResolvedBlock& b, const interpolate::InterpolateResult& r,
                    const interpolate::InterpolateOptions& o) {
  BlockDrive d;
  d.planned = is_feed_move(b) && b.feed_mode == FeedMode::kUnitsPerMinute && r.feed_length > 0;
  if (!d.planned) return d;
  // G61 / G61.1 / G09 stop at the block's end (the interpolator holds it in position).
  d.stops = b.path_mode != PathMode::kBlend;
  d.length = r.feed_length;
  // At feed F the block takes max(60 L / F, limit_duration) (InterpolateResult): the feed whose
  // time equals the limits' is the largest that every axis runs within its velocity bound.
  if (r.limit_duration > 0) d.max_feed = 60 * r.feed_length / r.limit_duration;
  d.max_accel = path_acceleration(r, o);
  return d;
}

}  // namespace

DriveRun run_on_drives(const std::vector<ResolvedBlock>& blocks, const interpolate::InterpolateOptions& o,
                       const Axes& start) {
  DriveRun run;
  run.blocks.resize(blocks.size());
  interpolate::Interpolator interp(o, start);
  DiscardSamples sink;
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    const interpolate::InterpolateResult r = interp.add(blocks[i], sink);
    if (r.status != interpolate::InterpolateStatus::kOk) {
      run.failure = r.message;
      break;
    }
    run.cycle_time += r.duration;
    if (is_feed_move(blocks[i])) run.feed_move_time += r.duration;
    run.blocks[i] = drive_of(blocks[i], r, o);
  }
  return run;
}

double reachable_peak(double v_in, double v_out, double a, double s) {
  if (std::isinf(a)) return std::numeric_limits<double>::infinity();
  return std::sqrt(0.5 * (v_in * v_in + v_out * v_out + 2 * a * s));
}

namespace {

/// The junction speeds [mm/s] of a chain of path blocks (junction k: end of block k), each at
/// most the feed of both blocks it joins, 0 where the path stops, and then lowered so that each
/// block can go from one to the next at its acceleration (forward pass: speeding up; backward
/// pass: slowing down in time).
std::vector<double> junction_speeds(const std::vector<const ResolvedBlock*>& chain,
                                    const std::vector<const BlockDrive*>& drive) {
  const std::size_t n = chain.size();
  std::vector<double> v(n, 0.0);
  for (std::size_t k = 0; k + 1 < n; ++k)
    if (drive[k]->planned && !drive[k]->stops && drive[k + 1]->planned)
      v[k] = std::min(chain[k]->feed, chain[k + 1]->feed) / 60;
  // v[n - 1] = 0: the program ends at rest.
  auto up_to = [&](double from, std::size_t k) {
    return drive[k]->planned ? std::sqrt(from * from + 2 * drive[k]->max_accel * drive[k]->length) : 0.0;
  };
  for (std::size_t k = 0; k < n; ++k) v[k] = std::min(v[k], up_to(k == 0 ? 0.0 : v[k - 1], k));
  for (std::size_t k = n; k-- > 1;) v[k - 1] = std::min(v[k - 1], up_to(v[k], k));
  return v;
}

}  // namespace

std::vector<ResolvedBlock> limit_feeds_to_drives(std::vector<ResolvedBlock> blocks, const std::vector<BlockDrive>& drives) {
  std::vector<ResolvedBlock*> chain;
  std::vector<const BlockDrive*> drive;
  for (std::size_t i = 0; i < blocks.size() && i < drives.size(); ++i) {
    if (!occupies_the_path(blocks[i])) continue;
    if (drives[i].planned) blocks[i].feed = std::min(blocks[i].feed, drives[i].max_feed);
    chain.push_back(&blocks[i]);
    drive.push_back(&drives[i]);
  }
  const std::vector<double> v = junction_speeds({chain.begin(), chain.end()}, drive);
  for (std::size_t k = 0; k < chain.size(); ++k) {
    if (!drive[k]->planned) continue;
    const double v_in = k == 0 ? 0.0 : v[k - 1];
    chain[k]->feed = std::min(chain[k]->feed, 60 * reachable_peak(v_in, v[k], drive[k]->max_accel, drive[k]->length));
  }
  return blocks;
}

}  // namespace gcpipe::force
