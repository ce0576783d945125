// The one contour metric (simulate::ContourSearch) against geometry worked by hand, and against a
// brute-force search over the whole window (a second, independent formulation).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "contour.hpp"
#include "simulate.hpp"

using namespace gcpipe;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kT = 0.001;

// Contour error is the distance to the path, not to the time-matched point: a point that trails
// in time on the path has (almost) none; a point off the path by d has d.
TEST(ContourSearch, TrailingOnThePathIsNotAnErrorButLeavingItIs) {
  const double R = 10, w = 2 * kPi;
  std::vector<Vec3> pts;
  for (int k = 0; k < 2000; ++k) pts.push_back({R * std::cos(w * k * kT), R * std::sin(w * k * kT), 0});
  simulate::ContourSearch on(pts), off(pts);
  double worst_on = 0, worst_off = 0, worst_time_matched = 0;
  Vec3 c;
  for (int k = 100; k < 2000; ++k) {  // the trailing point needs nominal history behind it
    const double t = k * kT, lag = 0.0505;  // 50.5 ms behind: half-way between nominal points
    const Vec3 trailing{R * std::cos(w * (t - lag)), R * std::sin(w * (t - lag)), 0};
    const Vec3 outside{(R + 0.01) * std::cos(w * (t - lag)), (R + 0.01) * std::sin(w * (t - lag)), 0};
    worst_on = std::max(worst_on, on.distance(trailing, static_cast<std::size_t>(k), c));
    worst_off = std::max(worst_off, std::abs(off.distance(outside, static_cast<std::size_t>(k), c) - 0.01));
    worst_time_matched = std::max(worst_time_matched, std::hypot(trailing[0] - pts[k][0], trailing[1] - pts[k][1]));
  }
  // The nominal path is a polyline of 1 ms chords; half-way along a chord the true circle lies
  // R (1 - cos(w T / 2)) = 4.93e-5 mm outside it.
  const double sag = R * (1 - std::cos(w * kT / 2));
  EXPECT_NEAR(worst_on, sag, 1e-8);
  EXPECT_LT(worst_off, sag + 1e-8);
  EXPECT_GT(worst_time_matched, 3.0);
}

// The box search returns the minimum over the window [limit - 3000, limit] exactly, on a
// looping path (a trochoid-like curve) with random actual points near it.
TEST(ContourSearch, EqualsBruteForceOverTheWindowOnALoopingPath) {
  std::vector<Vec3> pts;
  for (int k = 0; k < 20000; ++k) {
    const double t = k * 0.002;
    pts.push_back({3 * std::cos(8 * t) + 0.8 * t, 3 * std::sin(8 * t), 0.01 * std::sin(t)});
  }
  simulate::ContourSearch search(pts);
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 0.5);
  Vec3 c;
  for (std::size_t limit = 50; limit < pts.size(); limit += 7) {
    const std::size_t back = std::min<std::size_t>(limit, 40);
    const Vec3 p{pts[limit - back][0] + noise(rng), pts[limit - back][1] + noise(rng), pts[limit - back][2]};
    const double fast = search.distance(p, limit, c);
    const std::size_t lo = limit > simulate::ContourSearch::kLookBack ? limit - simulate::ContourSearch::kLookBack : 0;
    double brute = 1e300;
    for (std::size_t i = lo; i < limit; ++i) brute = std::min(brute, servo::segment_distance(pts[i], pts[i + 1], p));
    ASSERT_EQ(fast, brute) << "at limit " << limit;
  }
}

}  // namespace
