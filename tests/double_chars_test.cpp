// write_shortest and write_fixed against std::to_chars, byte for byte, on edge cases and millions
// of doubles. GCPIPE_DOUBLE_CHARS_DRAWS=<n> sets how many random doubles each kind draws (default
// 2 000 000).
#include <gtest/gtest.h>

#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <random>
#include <string>
#include <string_view>

#include "gcpipe/double_chars.hpp"

using namespace gcpipe;

namespace {

std::size_t draws() {
  const char* env = std::getenv("GCPIPE_DOUBLE_CHARS_DRAWS");
  return env != nullptr ? std::strtoull(env, nullptr, 10) : 2'000'000;
}

// decimals < 0: the shortest form (write_shortest), else fixed with that many (write_fixed).
std::string_view reference(double v, int decimals, char (&buf)[400]) {
  const auto r = decimals < 0 ? std::to_chars(buf, buf + sizeof buf, v)
                              : std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, decimals);
  return {buf, static_cast<std::size_t>(r.ptr - buf)};
}

std::string_view ours(double v, int decimals, char (&buf)[400]) {
  const char* end = decimals < 0 ? write_shortest(buf, v) : write_fixed(buf, buf + sizeof buf, v, decimals);
  return {buf, static_cast<std::size_t>(end - buf)};
}

// Counts the doubles whose text differs; the first few are reported with their bits.
class Comparison {
 public:
  explicit Comparison(int decimals = -1) : decimals_(decimals) {}
  void check(double v) {
    char a[400], b[400];
    ++checked_;
    const auto want = reference(v, decimals_, a), got = ours(v, decimals_, b);
    if (want == got) return;
    if (++failed_ <= 10)
      ADD_FAILURE() << "bits 0x" << std::hex << std::bit_cast<std::uint64_t>(v) << std::dec << ", decimals "
                    << decimals_ << ": std::to_chars '" << want << "', ours '" << got << "'";
  }
  void check_with_neighbours(double v) {
    double up = v, down = v;
    check(v);
    for (int i = 0; i < 4; ++i) {
      up = std::nextafter(up, std::numeric_limits<double>::infinity());
      down = std::nextafter(down, -std::numeric_limits<double>::infinity());
      check(up), check(down), check(-up), check(-down);
    }
  }
  std::size_t checked() const { return checked_; }
  std::size_t failed() const { return failed_; }

 private:
  int decimals_;
  std::size_t checked_ = 0, failed_ = 0;
};

}  // namespace

TEST(ShortestDouble, WritesTheBytesOfToCharsOnEdgeCases) {
  Comparison c;
  const double inf = std::numeric_limits<double>::infinity();
  for (double v : {0.0, -0.0, inf, -inf, std::numeric_limits<double>::quiet_NaN(), 5e-324, 2.2250738585072014e-308,
                   1.7976931348623157e308, 0.1, 0.2, 0.3, 1.0 / 3.0, 2.0 / 3.0, 1e-5, 1e-4, 1.5e-4, 1e-3, 0.5,
                   123456.0, 100000.0, 1e15, 1e16, 9007199254740991.0, 9007199254740992.0, 4503599627370496.5,
                   10.0, 9.999999999999998, 1e23, 5e-5, 1.2345678901234567e-7, 299792458.0, 3.141592653589793})
    c.check_with_neighbours(v);
  for (int e = -1074; e <= 1023; ++e) c.check_with_neighbours(std::ldexp(1.0, e));  // lower boundary nearer
  for (int e = -30; e <= 30; ++e) c.check_with_neighbours(std::pow(10.0, e));       // fixed/scientific turns
  for (int e = -30; e <= 30; ++e) c.check_with_neighbours(5 * std::pow(10.0, e));
  EXPECT_EQ(c.failed(), 0u) << "of " << c.checked();
}

TEST(ShortestDouble, WritesTheBytesOfToCharsOnRandomBits) {
  std::mt19937_64 rng(20261125);
  Comparison c;
  for (std::size_t i = 0; i < draws(); ++i) c.check(std::bit_cast<double>(rng()));
  EXPECT_EQ(c.failed(), 0u) << "of " << c.checked();
}

// Uniform over the binary exponents of the fast path and a little beyond (2^-80 .. 2^60).
TEST(ShortestDouble, WritesTheBytesOfToCharsOnRandomMagnitudes) {
  std::mt19937_64 rng(7);
  std::uniform_int_distribution<std::uint64_t> biased(1023 - 80, 1023 + 60);
  Comparison c;
  for (std::size_t i = 0; i < draws(); ++i)
    c.check(std::bit_cast<double>((rng() & ((std::uint64_t{1} << 52) - 1)) | biased(rng) << 52 | (rng() & 1) << 63));
  EXPECT_EQ(c.failed(), 0u) << "of " << c.checked();
}

// Doubles nearest to short decimals (few digits, trailing zeros, halfway cases of the search) and
// the coordinates of a trace (circles of a few mm, following errors of a few um).
TEST(ShortestDouble, WritesTheBytesOfToCharsOnShortDecimalsAndCoordinates) {
  std::mt19937_64 rng(11);
  std::uniform_int_distribution<int> digits(1, 17), scale(0, 25);
  std::uniform_real_distribution<double> angle(0, 6.283185307179586), radius(0.1, 500);
  Comparison c;
  for (std::size_t i = 0; i < draws(); ++i) {
    const auto d = digits(rng);
    const double m = static_cast<double>(rng() % static_cast<std::uint64_t>(std::pow(10.0, d)));
    c.check(m / std::pow(10.0, scale(rng)));
    const double r = radius(rng), a = angle(rng);
    c.check(r * std::cos(a)), c.check(r * std::sin(a) - 1e-3 * std::cos(3 * a));
  }
  EXPECT_EQ(c.failed(), 0u) << "of " << c.checked();
}

// Ties (exact binary fractions halfway between two outputs, 2^-7 = 0.0078125 at 6 decimals), the
// trace's times (k ms), and random doubles of every magnitude the fast path takes and beyond.
TEST(FixedDouble, WritesTheBytesOfToCharsWithEveryPrecision) {
  std::mt19937_64 rng(5);
  std::uniform_int_distribution<std::uint64_t> biased(1023 - 110, 1023 + 70);
  std::uniform_int_distribution<int> bits(1, 30);
  const std::size_t n = draws() / 10;
  for (int decimals = 0; decimals <= 10; ++decimals) {
    Comparison c(decimals);
    for (double v : {0.0, -0.0, 0.5, 1.5, 2.5, -2.5, 0.0078125, 0.0000005, 1e-7, 1.0 / 3.0, 9.9999995, 1e19, 1.8e19, 1e300,
                     5e-324, std::numeric_limits<double>::infinity(), std::numeric_limits<double>::quiet_NaN()})
      c.check_with_neighbours(v);
    for (std::size_t i = 0; i < n; ++i) {
      c.check(static_cast<double>(rng() % (std::uint64_t{1} << bits(rng))) / static_cast<double>(std::uint64_t{1} << bits(rng)));
      c.check(static_cast<double>(rng() % 1'000'000'000) * 0.001);
      c.check(std::bit_cast<double>((rng() & ((std::uint64_t{1} << 52) - 1)) | biased(rng) << 52 | (rng() & 1) << 63));
    }
    EXPECT_EQ(c.failed(), 0u) << "of " << c.checked() << " with " << decimals << " decimals";
  }
}

// Every block of 8 digits is written by one routine (8 digits side by side in a 64-bit word): the
// low 8 digits of integers of 9 to 16 digits swept through [0, 10^8) in steps of 37, in the shortest
// form and fixed with 0 decimals (the sweep checked every block once, outside the tests).
TEST(ShortestDouble, WritesEveryBlockOfEightDigits) {
  std::mt19937_64 rng(8);
  Comparison shortest, fixed(0);
  for (std::uint64_t low = 0; low < 100'000'000; low += 37) {
    const auto v = static_cast<double>((rng() % 90'000'000 + 1) * 100'000'000 + low);  // exact: < 2^53
    shortest.check(v), fixed.check(v), shortest.check(-v);
  }
  EXPECT_EQ(shortest.failed(), 0u) << "of " << shortest.checked();
  EXPECT_EQ(fixed.failed(), 0u) << "of " << fixed.checked();
}
