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

// A trochoid of n points 2 ms apart: loops that cross each other and the earlier loops.
std::vector<Vec3> trochoid(int n) {
  std::vector<Vec3> pts;
  for (int k = 0; k < n; ++k) {
    const double t = k * 0.002;
    pts.push_back({3 * std::cos(8 * t) + 0.8 * t, 3 * std::sin(8 * t), 0.01 * std::sin(t)});
  }
  return pts;
}

// The minimum over segments [lo, hi) by measuring every one of them.
double brute_force(const std::vector<Vec3>& pts, std::size_t lo, std::size_t hi, const Vec3& p) {
  double best = 1e300;
  for (std::size_t i = lo; i < hi; ++i) best = std::min(best, servo::segment_distance(pts[i], pts[i + 1], p));
  return best;
}

// Streams `pts` into a search tick by tick and checks each tick's distance of `actual(k)` against
// the brute-force minimum over the window, and that the closest point returned is that far away.
template <class Actual>
void expect_streaming_equals_brute_force(const std::vector<Vec3>& pts, Actual actual) {
  simulate::ContourSearch search;
  Vec3 c;
  for (std::size_t k = 0; k < pts.size(); ++k) {
    search.push(pts[k]);
    if (k == 0) continue;
    const Vec3 p = actual(k);
    const double fast = search.distance(p, c);
    const std::size_t lo = k > simulate::ContourSearch::kLookBack ? k - simulate::ContourSearch::kLookBack : 0;
    ASSERT_EQ(fast, brute_force(pts, lo, k, p)) << "at tick " << k;
    ASSERT_NEAR(simulate::dist3(c, p), fast, 1e-9) << "at tick " << k;
  }
}

// Turns of a circle on top of each other within the window (the simulate benchmark's case: the
// capsules of the other turns must not drop their nearest segments), the actual lagging and off
// the path by up to 1.5 mm, inside and outside, and near the centre (every turn equally near).
TEST(ContourSearch, EqualsBruteForceOnAMultiTurnCircle) {
  const double R = 10, w = 5.0;  // 50 mm/s on R 10: 2.4 turns in the 3000-point window
  std::vector<Vec3> pts;
  for (int k = 0; k < 12000; ++k) pts.push_back({R * std::cos(w * k * kT), R * std::sin(w * k * kT), 0});
  expect_streaming_equals_brute_force(pts, [&](std::size_t k) {
    const double t = static_cast<double>(k) * kT - 0.03, r = R + 1.5 * std::sin(0.7 * static_cast<double>(k) * kT);
    return Vec3{r * std::cos(w * t), r * std::sin(w * t), 0.0};
  });
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> near_centre(-0.3, 0.3);
  expect_streaming_equals_brute_force(pts, [&](std::size_t) { return Vec3{near_centre(rng), near_centre(rng), 0.0}; });
}

// A trochoid (loops that cross each other and the earlier loops) streamed tick by tick, the
// actual trailing with noise, and points far from the path.
TEST(ContourSearch, EqualsBruteForceOnATrochoidStreamed) {
  const std::vector<Vec3> pts = trochoid(9000);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, 0.3);
  expect_streaming_equals_brute_force(pts, [&](std::size_t k) {
    const Vec3& q = pts[k > 20 ? k - 20 : 0];
    return Vec3{q[0] + noise(rng), q[1] + noise(rng), q[2] + 0.1 * noise(rng)};
  });
  std::uniform_real_distribution<double> anywhere(-20, 40);
  expect_streaming_equals_brute_force(pts, [&](std::size_t) { return Vec3{anywhere(rng), anywhere(rng), anywhere(rng)}; });
}

// The box search returns the minimum over the window [limit - 3000, limit] exactly, on a
// looping path (a trochoid-like curve) with random actual points near it.
TEST(ContourSearch, EqualsBruteForceOverTheWindowOnALoopingPath) {
  const std::vector<Vec3> pts = trochoid(20000);
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

// distance_beyond(bound) on the trochoid, the actual trailing with noise: beyond the bound it is
// the least distance exactly (brute force over the window); within it, never less than the least
// and never beyond the bound. Bounds from 0 (always searched) to far above every distance.
TEST(ContourSearch, DistanceBeyondABoundIsExactBeyondItAndABoundOfTheLeastWithin) {
  const std::vector<Vec3> pts = trochoid(9000);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 0.3);
  std::size_t beyond = 0, within = 0, not_least = 0;
  for (const double bound : {0.0, 0.05, 0.2, 1e9}) {
    simulate::ContourSearch search;
    Vec3 c;
    for (std::size_t k = 0; k < pts.size(); ++k) {
      search.push(pts[k]);
      if (k == 0) continue;
      const Vec3& q = pts[k > 20 ? k - 20 : 0];
      const Vec3 p{q[0] + noise(rng), q[1] + noise(rng), q[2] + 0.1 * noise(rng)};
      const double d = search.distance_beyond(p, k, bound, c);
      const std::size_t lo = k > simulate::ContourSearch::kLookBack ? k - simulate::ContourSearch::kLookBack : 0;
      const double least = brute_force(pts, lo, k, p);
      ASSERT_NEAR(simulate::dist3(c, p), d, 1e-9) << "at tick " << k;
      if (least > bound) {
        ASSERT_EQ(d, least) << "at tick " << k << ", bound " << bound;
        ++beyond;
      } else {
        ASSERT_GE(d, least) << "at tick " << k;
        ASSERT_LE(d, bound) << "at tick " << k;
        ++within;
        not_least += d != least;
      }
    }
  }
  EXPECT_GT(beyond, 1000u);
  EXPECT_GT(within, 1000u);
  EXPECT_GT(not_least, 0u);  // the window was not searched for some: the bound is used
}

// A search that keeps its points and is rewound measures a second run exactly as a new search
// over the same points does (the compensation's learning measures every run of a window so).
TEST(ContourSearch, ARewoundSearchMeasuresAsANewOne) {
  const std::vector<Vec3> pts = trochoid(12000);
  auto actual = [&](std::size_t k, double off) {
    const Vec3& q = pts[k > 20 ? k - 20 : 0];
    return Vec3{q[0] + off * std::sin(0.01 * static_cast<double>(k)), q[1] + off, q[2]};
  };
  simulate::ContourSearch kept;
  kept.keep_all_points();
  Vec3 c1, c2;
  for (std::size_t k = 0; k < pts.size(); ++k) {  // the first run pushes the points
    kept.push(pts[k]);
    if (k > 0) kept.distance(actual(k, 0.2), c1);
  }
  kept.rewind();
  simulate::ContourSearch fresh;
  for (std::size_t k = 0; k < pts.size(); ++k) {
    fresh.push(pts[k]);
    if (k == 0) continue;
    const double a = kept.distance(actual(k, 0.05), k, c1);
    const double b = fresh.distance(actual(k, 0.05), k, c2);
    ASSERT_EQ(a, b) << "at tick " << k;
    ASSERT_EQ(c1, c2) << "at tick " << k;
  }
}

}  // namespace
