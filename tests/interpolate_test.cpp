// Interpolator: block timing (G94, G93, rapids, dwell, velocity limits), arc geometry in all three
// planes with turns and helices, sample-clock continuity, and the smoothers against their
// frequency responses.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "gcpipe/config.hpp"
#include "interpolate.hpp"

using namespace gcpipe;
using namespace gcpipe::interpolate;

namespace {

constexpr double kPi = std::numbers::pi;

struct Collect : SampleSink {
  std::vector<Axes> s;
  void sample(const Axes& c) override { s.push_back(c); }
};

InterpolateOptions raw_options() {
  InterpolateOptions o;
  o.smoothing = Smoothing::kNone;
  return o;
}

ResolvedBlock block(Motion m, const Axes& target, double feed = 600) {
  ResolvedBlock b;
  b.motion = m;
  b.target = target;
  b.feed = feed;
  b.line = 1;
  return b;
}

}  // namespace

TEST(Interpolate, LinearFeedSetsDurationAndPathIsStraight) {
  Interpolator ip(raw_options(), Axes{});
  Collect c;
  // 30 x 40 mm = 50 mm at 600 mm/min = 5 s = 5000 samples.
  const auto r = ip.add(block(Motion::kLinear, {30, 40, 0, 0, 0}), c);
  ASSERT_EQ(r.status, InterpolateStatus::kOk);
  EXPECT_NEAR(r.duration, 5.0, 1e-12);
  ASSERT_EQ(c.s.size(), 5000u);
  EXPECT_NEAR(c.s[999][kX], 6.0, 1e-9);
  EXPECT_NEAR(c.s[999][kY], 8.0, 1e-9);
  EXPECT_EQ(c.s.back()[kX], 30.0);
}

// One block cannot run past the machine-time bound: it is refused before its first sample, so a
// feed of 0.001 mm/min or an arc of thousands of turns costs nothing, whatever it would run.
TEST(Interpolate, BlockPastTheMachineTimeBoundIsRefusedBeforeItsFirstSample) {
  InterpolateOptions o = raw_options();
  o.max_time = 10;
  Interpolator ip(o, Axes{});
  Collect c;
  ASSERT_EQ(ip.add(block(Motion::kLinear, {50, 0, 0, 0, 0}, 600), c).status, InterpolateStatus::kOk);  // 5 s
  const std::size_t before = c.s.size();
  const auto r = ip.add(block(Motion::kLinear, {100, 0, 0, 0, 0}, 0.001), c);  // 3e6 s
  EXPECT_EQ(r.status, InterpolateStatus::kTooLong);
  EXPECT_EQ(c.s.size(), before);
  EXPECT_NE(r.message.find("past the bound of 10 s"), std::string::npos) << r.message;
  ResolvedBlock d = block(Motion::kDwell, {0, 0, 0, 0, 0});
  d.dwell = 6;  // 5 s + 6 s > 10 s
  EXPECT_EQ(ip.add(d, c).status, InterpolateStatus::kTooLong);
}

TEST(Interpolate, InverseTimeRapidAndDwell) {
  Interpolator ip(raw_options(), Axes{});
  Collect c;
  ResolvedBlock b = block(Motion::kLinear, {10, 0, 0, 0, 90}, 120);  // G93 F120: 0.5 s
  b.feed_mode = FeedMode::kInverseTime;
  EXPECT_NEAR(ip.add(b, c).duration, 0.5, 1e-12);
  // Rapid: X 100 mm at 500 mm/s = 0.2 s, C 720 deg at 3600 deg/s = 0.2 s, Z 50 mm = 0.1 s.
  EXPECT_NEAR(ip.add(block(Motion::kRapid, {110, 0, 50, 0, 810}), c).duration, 0.2, 1e-12);
  ResolvedBlock d = block(Motion::kDwell, {0, 0, 0, 0, 0});
  d.dwell = 0.25;
  const std::size_t before = c.s.size();
  EXPECT_NEAR(ip.add(d, c).duration, 0.25, 1e-12);
  EXPECT_EQ(c.s.size() - before, 250u);
  EXPECT_EQ(c.s.back()[kX], 110.0);  // the dwell holds the position, not its target field
}

TEST(Interpolate, RotaryOnlyG94FeedIsDegreesPerMinuteAndVelocityLimitLengthensBlocks) {
  InterpolateOptions o = raw_options();
  o.max_velocity = {10, 500, 500, 3600, 3600};
  Interpolator ip(o, Axes{});
  Collect c;
  EXPECT_NEAR(ip.add(block(Motion::kLinear, {0, 0, 0, 0, 90}, 5400), c).duration, 1.0, 1e-12);
  const auto r = ip.add(block(Motion::kLinear, {20, 0, 0, 0, 90}, 6000), c);  // 100 mm/s asked
  EXPECT_TRUE(r.velocity_limited);
  EXPECT_NEAR(r.duration, 2.0, 1e-12);
  EXPECT_EQ(ip.stats().velocity_limited_blocks, 1u);
}

TEST(Interpolate, ArcsInAllPlanesWithTurnsAndHelix) {
  struct Case { Plane plane; int a, b, n; };
  for (Case k : {Case{Plane::kXY, kX, kY, kZ}, Case{Plane::kZX, kZ, kX, kY}, Case{Plane::kYZ, kY, kZ, kX}}) {
    for (Motion m : {Motion::kArcCCW, Motion::kArcCW}) {
      Axes start{};
      start[static_cast<std::size_t>(k.a)] = 10;  // on the circle of radius 10 around the origin
      Interpolator ip(raw_options(), start);
      Collect c;
      // Two full turns plus 4 mm of helix in exactly 2 s.
      ResolvedBlock b = block(m, start, 60 * std::hypot(2 * kPi * 10 * 2, 4.0) / 2);
      b.plane = k.plane;
      b.turns = 2;
      b.target[static_cast<std::size_t>(k.n)] = 4;  // helix: 4 mm along the normal
      const auto r = ip.add(b, c);
      ASSERT_EQ(r.status, InterpolateStatus::kOk);
      EXPECT_NEAR(r.duration, 2.0, 1e-12);
      for (const Axes& p : c.s)
        EXPECT_NEAR(std::hypot(p[static_cast<std::size_t>(k.a)], p[static_cast<std::size_t>(k.b)]), 10, 1e-9);
      // A quarter of the first turn: CCW goes to +b, CW to -b (right-handed about the normal).
      const Axes& q = c.s[c.s.size() / 8 - 1];
      EXPECT_NEAR(q[static_cast<std::size_t>(k.b)], m == Motion::kArcCCW ? 10 : -10, 1e-6);
      EXPECT_NEAR(q[static_cast<std::size_t>(k.n)], 0.5, 1e-6);
      EXPECT_EQ(c.s.back(), b.target);
    }
  }
}

TEST(Interpolate, BlockBoundariesBetweenSamplesLeaveNoVelocityGlitch) {
  Interpolator ip(raw_options(), Axes{});
  Collect c;
  // Three collinear blocks of 0.3337 mm at 60 mm/min: ends fall between samples.
  for (int i = 1; i <= 3; ++i) ip.add(block(Motion::kLinear, {0.3337 * i, 0, 0, 0, 0}, 60), c);
  for (std::size_t i = 1; i < c.s.size(); ++i) EXPECT_NEAR(c.s[i][kX] - c.s[i - 1][kX], 0.001, 1e-12) << i;
}

TEST(Interpolate, RejectsWhatItCannotRun) {
  Interpolator ip(raw_options(), Axes{});
  Collect c;
  EXPECT_EQ(ip.add(block(Motion::kLinear, {1, 0, 0, 0, 0}, 0), c).status, InterpolateStatus::kInvalid);
  EXPECT_EQ(ip.add(block(Motion::kTrochoidSlot, {1, 0, 0, 0, 0}), c).status, InterpolateStatus::kUnsupported);
  EXPECT_TRUE(c.s.empty());
}

// A velocity step through the smoothers: linear acc/dec reaches full speed after exactly Ts with
// constant acceleration v/Ts; exponential starts at v/Ts and decays with time constant Ts.
TEST(Interpolate, SmoothersShapeAVelocityStep) {
  const double T = 0.001, Ts = 0.064, v = 10;
  for (Smoothing k : {Smoothing::kLinear, Smoothing::kExponential}) {
    InterpolateOptions o;
    o.smoothing = k;
    o.smoothing_time = {Ts, Ts, Ts, Ts, Ts};
    Interpolator ip(o, Axes{});
    Collect c;
    ip.add(block(Motion::kLinear, {v, 0, 0, 0, 0}, v * 60), c);  // 1 s at v mm/s
    ip.finish(c);
    EXPECT_NEAR(c.s.back()[kX], v, 1e-9);
    const double v32 = (c.s[32][kX] - c.s[31][kX]) / T;
    if (k == Smoothing::kLinear) {
      EXPECT_NEAR(v32, v * 32.5 / 64, 0.2);
      EXPECT_NEAR((c.s[100][kX] - c.s[99][kX]) / T, v, 1e-9);
    } else {
      EXPECT_NEAR(v32, v * (1 - std::exp(-32.0 * T / Ts)), 0.1);
    }
    EXPECT_NEAR(ip.stats().peak_acceleration[kX], v / Ts, 0.02 * v / Ts);
  }
}

// G61 (exact stop) holds each block's end until every axis's smoothed command is within
// in_position of it; G64 goes on at once and rounds the corner by the smoothing's lag. A 20 mm
// square at F3000 with Ts 32 ms: G61 passes within in_position of every corner, G64 stays about
// v*Ts = 1.6 mm away (well beyond it), and G61's stops cost time. The hold is counted in the block's
// duration. Checked the second way: the hold of one block is the exponential's settling time,
// Ts ln(v Ts / in_position) give or take a sample.
TEST(Interpolate, ExactStopHoldsEveryCornerUntilInPosition) {
  const double Ts = 0.032, in_position = 0.01, v = 50;  // [s, mm, mm/s]
  const std::vector<Axes> corners = {{20, 0, 0, 0, 0}, {20, 20, 0, 0, 0}, {0, 20, 0, 0, 0}, {0, 0, 0, 0, 0}};
  auto run = [&](PathMode mode, double& duration) {
    InterpolateOptions o;
    o.smoothing = Smoothing::kExponential;
    o.smoothing_time = {Ts, Ts, Ts, Ts, Ts};
    o.in_position = in_position;
    Interpolator ip(o, Axes{});
    Collect c;
    duration = 0;
    for (const Axes& corner : corners) {
      ResolvedBlock b = block(Motion::kLinear, corner, v * 60);
      b.path_mode = mode;
      const auto r = ip.add(b, c);
      EXPECT_EQ(r.status, InterpolateStatus::kOk);
      duration += r.duration;
    }
    ip.finish(c);
    std::vector<double> nearest;
    for (std::size_t k = 0; k + 1 < corners.size(); ++k) {  // the three corners the path turns at
      double d = 1e9;
      for (const Axes& x : c.s) d = std::min(d, std::hypot(x[kX] - corners[k][kX], x[kY] - corners[k][kY]));
      nearest.push_back(d);
    }
    return nearest;
  };
  double blend_time = 0, stop_time = 0;
  const auto blend = run(PathMode::kBlend, blend_time);
  const auto stop = run(PathMode::kExactStop, stop_time);
  for (std::size_t k = 0; k < stop.size(); ++k) {
    EXPECT_LE(stop[k], in_position) << "corner " << k;
    EXPECT_GT(blend[k], 50 * in_position) << "corner " << k;
  }
  EXPECT_NEAR(blend_time, 4 * 20 / v, 1e-9);
  const double hold = Ts * std::log(v * Ts / in_position);  // one corner's settling, about 0.26 s
  EXPECT_NEAR(stop_time - blend_time, 4 * hold, 4 * 0.002);
  double exact_path_time = 0;
  const auto exact_path = run(PathMode::kExactPath, exact_path_time);  // G61.1: modelled as G61
  EXPECT_EQ(exact_path, stop);
  EXPECT_EQ(exact_path_time, stop_time);
}

// Second formulation of the smoothers: a sampled sinusoid through the filter has the gain and
// phase of smoothing_response().
TEST(Interpolate, SmoothingResponseMatchesFilteredSinusoid) {
  const double T = 0.001, Ts = 0.05, w = 20;
  for (Smoothing k : {Smoothing::kLinear, Smoothing::kExponential}) {
    AxisSmoother sm(k, Ts, T, 0);
    const auto g = smoothing_response(k, Ts, T, w);
    double max_err = 0;
    for (int n = 0; n < 5000; ++n) {
      const double y = sm.filter(std::sin(w * n * T));
      if (n > 3000) max_err = std::max(max_err, std::abs(y - std::abs(g) * std::sin(w * n * T + std::arg(g))));
    }
    EXPECT_LT(max_err, 1e-9) << static_cast<int>(k);
  }
}

TEST(Interpolate, ConfigRejectsUnknownKeys) {
  EXPECT_THROW(load_interpolate_options(Config::from_string("periode: 0.001")), ConfigError);
  EXPECT_THROW(load_interpolate_options(Config::from_string("smoothing: cubic")), ConfigError);
  // Limits belong to the machine file, not here.
  EXPECT_THROW(load_interpolate_options(Config::from_string("max_velocity: [1, 2, 3, 4, 5]")), ConfigError);
  const auto o = load_interpolate_options(Config::from_string("period: 0.002\nsmoothing: linear"));
  EXPECT_EQ(o.period, 0.002);
  EXPECT_EQ(o.smoothing, Smoothing::kLinear);
}

// An arc whose end points are inside the travel but whose middle is not: the per-sample check
// catches it and names the block's line.
TEST(Interpolate, TravelViolationsBetweenProgrammedPointsAreCounted) {
  InterpolateOptions o = raw_options();
  o.travel_max = {1e9, 5, 1e9, 1e9, 1e9};  // Y <= 5 mm
  Interpolator ip(o, Axes{10, 0, 0, 0, 0});
  Collect c;
  ResolvedBlock b = block(Motion::kArcCCW, {-10, 0, 0, 0, 0}, 6000);  // half circle through Y = 10
  b.line = 7;
  ASSERT_EQ(ip.add(b, c).status, InterpolateStatus::kOk);
  EXPECT_GT(ip.stats().travel_violations[kY], 0u);
  EXPECT_EQ(ip.stats().travel_violations[kX], 0u);
  EXPECT_EQ(ip.stats().first_violation_line, 7u);
}

// Arc samples come from a rotation recurrence re-anchored every 64 samples; over a long helix
// (10 turns, 62,832 samples) every sample must stay on the exact circle and at the exact angle.
TEST(Interpolate, ArcRecurrenceStaysOnTheExactCircle) {
  Interpolator ip(raw_options(), Axes{10, 0, 0, 0, 0});
  ResolvedBlock b = block(Motion::kArcCCW, Axes{10, 0, -5, 0, 0}, 100);  // 10 x 2 pi 10 mm at 100 mm/min
  b.centre = {0, 0, 0};
  b.radius = 10;
  b.turns = 11;  // end = start: a full circle, plus 10 more turns
  b.start = Axes{10, 0, 0, 0, 0};
  Collect c;
  ASSERT_EQ(ip.add(b, c).status, InterpolateStatus::kOk);
  ASSERT_GT(c.s.size(), 60000u);
  // On the circle, and advancing by the same angle every period: drift of the recurrence would
  // show as a jump at each exact re-anchor (every 64 samples).
  double worst_radius = 0, worst_step = 0;
  const double step = std::atan2(c.s[1][kY], c.s[1][kX]) - std::atan2(c.s[0][kY], c.s[0][kX]);  // exact anchor pair
  for (std::size_t k = 0; k < c.s.size(); ++k) {
    const Axes& p = c.s[k];
    worst_radius = std::max(worst_radius, std::abs(std::hypot(p[kX], p[kY]) - 10));
    if (k == 0) continue;
    double d = std::atan2(p[kY], p[kX]) - std::atan2(c.s[k - 1][kY], c.s[k - 1][kX]);
    if (d < -kPi) d += 2 * kPi;
    worst_step = std::max(worst_step, std::abs(d - step) * 10);  // as arc length [mm]
  }
  EXPECT_LT(worst_radius, 1e-9);
  EXPECT_LT(worst_step, 1e-9);
}
