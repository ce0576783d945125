#include "gcpipe/double_chars.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cstdint>
#include <cstring>
#include <utility>

namespace gcpipe {

namespace {

using u128 = unsigned __int128;

// The search needs 10^j for j = 0 .. 38 (all that 128 bits hold: doubles down to 2^-70 need up
// to 10^23), each shifted left until its top bit is bit 127. Exact, so that every product below
// is exact and no error analysis of a rounded table is needed.
constexpr int kMaxPow10 = 38;
struct Pow10 {
  std::uint64_t hi, lo;  //!< 10^j << (127 - log2)
  int log2;              //!< floor(log2(10^j))
};
constexpr std::array<Pow10, kMaxPow10 + 1> kPow10 = [] {
  std::array<Pow10, kMaxPow10 + 1> t{};
  u128 p = 1;
  for (int j = 0; j <= kMaxPow10; ++j, p *= 10) {
    u128 g = p;
    int shift = 0;
    while ((g >> 127) == 0) g <<= 1, ++shift;
    t[static_cast<std::size_t>(j)] = {static_cast<std::uint64_t>(g >> 64), static_cast<std::uint64_t>(g), 127 - shift};
  }
  return t;
}();

// The binary exponents q (v = c 2^q, c < 2^53) of the fast path: v below 2^53 (above it every
// double is an integer, and fixed notation would have to spell the exact integer out), and
// 10^-k within the table.
constexpr int kMinQ = -122, kMaxQ = 0;

// floor(log10(2^q)) and floor(log10(3/4 2^q)) (Ryu's and Schubfach's constants: log10(2) and
// log10(3/4) in 22-bit fixed point), checked exactly over the fast path's range below.
constexpr int floor_log10_pow2(int q) { return (q * 1262611) >> 22; }
constexpr int floor_log10_three_quarters_pow2(int q) { return (q * 1262611 - 524031) >> 22; }

constexpr u128 pow_u128(u128 base, int n) {
  u128 r = 1;
  while (n-- > 0) r *= base;
  return r;
}

// For q <= 0 and k = -j: 10^k <= f 2^q < 10^(k+1) with f = num/den  <=>  den 2^-q <= num 10^j and
// num 10^(j-1) < den 2^-q; all within 128 bits for q >= kMinQ.
constexpr bool floor_logs_are_exact() {
  for (int q = kMinQ; q <= kMaxQ; ++q) {
    const u128 two = pow_u128(2, -q);
    const int j = -floor_log10_pow2(q), j34 = -floor_log10_three_quarters_pow2(q);
    if (j < 0 || j > kMaxPow10 || j34 < 0 || j34 > kMaxPow10) return false;
    if (!(two <= pow_u128(10, j) && (j == 0 || pow_u128(10, j - 1) < two))) return false;
    if (!(4 * two <= 3 * pow_u128(10, j34) && (j34 == 0 || 3 * pow_u128(10, j34 - 1) < 4 * two))) return false;
  }
  return true;
}
static_assert(floor_logs_are_exact());

// floor(g cp / 2^128), its lowest bit set when the product is not a multiple of 2^128: rounding
// to odd keeps whether a bound was exact, which the comparisons below need.
std::uint64_t round_to_odd(const Pow10& g, std::uint64_t cp) {
  const u128 x = static_cast<u128>(g.lo) * cp;
  const u128 y = static_cast<u128>(g.hi) * cp + static_cast<std::uint64_t>(x >> 64);
  const bool inexact = (static_cast<std::uint64_t>(y) | static_cast<std::uint64_t>(x)) != 0;
  return static_cast<std::uint64_t>(y >> 64) | static_cast<std::uint64_t>(inexact);
}

struct Decimal {
  std::uint64_t digits;  //!< without trailing zeros
  int exponent;          //!< value = digits 10^exponent
};

// Schubfach: v = c 2^q rounds from the interval between the midpoints to its neighbours. Scaled
// by 4 10^-k (k chosen so that the interval is 1 to 10 units of 10^k wide), at most one multiple
// of 10^(k+1) lies inside (then it is the shortest), else the nearest multiple of 10^k inside is.
// Ties (exactly halfway) round to the even digit, as std::to_chars's Ryu does.
Decimal shortest_decimal(std::uint64_t c, int q, bool lower_closer) {
  const bool even = c % 2 == 0;
  const int k = lower_closer ? floor_log10_three_quarters_pow2(q) : floor_log10_pow2(q);
  const Pow10& g = kPow10[static_cast<std::size_t>(-k)];
  const int h = q + g.log2 + 1;  // 1 .. 4: 4 c 2^q 10^-k = g (4 c << h) / 2^128
  const std::uint64_t vbl = round_to_odd(g, (4 * c - 2 + lower_closer) << h);
  const std::uint64_t vb = round_to_odd(g, (4 * c) << h);
  const std::uint64_t vbr = round_to_odd(g, (4 * c + 2) << h);
  const std::uint64_t lower = vbl + !even, upper = vbr - !even;  // an odd c excludes the ends
  const std::uint64_t s = vb / 4;
  if (s >= 10) {
    const std::uint64_t sp = s / 10;
    const bool up_inside = lower <= 40 * sp, wp_inside = 40 * sp + 40 <= upper;
    if (up_inside != wp_inside) return {sp + wp_inside, k + 1};
  }
  const bool u_inside = lower <= 4 * s, w_inside = 4 * s + 4 <= upper;
  if (u_inside != w_inside) return {s + w_inside, k};
  const std::uint64_t mid = 4 * s + 2;
  const bool round_up = vb > mid || (vb == mid && (s & 1) != 0);
  return {s + round_up, k};
}

Decimal without_trailing_zeros(Decimal d) {
  while (d.digits % 10 == 0) d.digits /= 10, ++d.exponent;
  return d;
}

int digit_count(std::uint64_t d) {  // d >= 1
  constexpr std::array<std::uint64_t, 20> kPowers = [] {
    std::array<std::uint64_t, 20> p{};
    p[0] = 1;
    for (std::size_t i = 1; i < p.size(); ++i) p[i] = p[i - 1] * 10;
    return p;
  }();
  const int t = (std::bit_width(d) * 1233) >> 12;  // floor or floor + 1 of log10(d), 1233 / 4096 ~ log10(2)
  return t + (d >= kPowers[static_cast<std::size_t>(t)]);
}

constexpr std::array<char, 200> kPairs = [] {
  std::array<char, 200> p{};
  for (std::size_t i = 0; i < 100; ++i) p[2 * i] = static_cast<char>('0' + i / 10), p[2 * i + 1] = static_cast<char>('0' + i % 10);
  return p;
}();

void write_pair(char* out, std::uint32_t v) { std::memcpy(out, &kPairs[2 * v], 2); }  // v < 100

// The 8 digits of v < 10^8 side by side in one 64-bit word: two lanes of 4 digits, split into
// four lanes of 2 (/ 100 as * 10486 >> 20, exact below 10^4), then eight of 1 (/ 10 as * 103 >> 10,
// exact below 100), '0' added to each byte; the lanes never carry into each other. Stored as
// little-endian bytes, first digit first (every v < 10^8 checked against the pairs below once).
void write_8_digits(char* out, std::uint32_t v) {
  if constexpr (std::endian::native != std::endian::little) {
    const std::uint32_t hi = v / 10000, lo = v % 10000;
    write_pair(out, hi / 100), write_pair(out + 2, hi % 100), write_pair(out + 4, lo / 100), write_pair(out + 6, lo % 100);
    return;
  }
  std::uint64_t x = (v / 10000) | (static_cast<std::uint64_t>(v % 10000) << 32);
  const std::uint64_t hundreds = ((x * 10486) >> 20) & 0x0000007F0000007FULL;
  x = hundreds | ((x - hundreds * 100) << 16);
  const std::uint64_t tens = ((x * 103) >> 10) & 0x000F000F000F000FULL;
  x = tens | ((x - tens * 10) << 8);
  x += 0x3030303030303030ULL;
  std::memcpy(out, &x, 8);
}

// The last n digits of d, zero-padded, into out[0 .. n): 8 at a time in 32-bit arithmetic, then
// two at a time, from the right.
void write_digits(char* out, std::uint64_t d, int n) {
  char* p = out + n;
  for (; n > 8; n -= 8, p -= 8, d /= 100000000) write_8_digits(p - 8, static_cast<std::uint32_t>(d % 100000000));
  auto r = static_cast<std::uint32_t>(d);
  for (; n >= 2; n -= 2, p -= 2, r /= 100) write_pair(p - 2, r % 100);
  if (n == 1) p[-1] = static_cast<char>('0' + r % 10);
}

// The 17 digits of d < 10^17, zero-padded, into out[0 .. 17): three pieces of fixed size, no
// loop whose count depends on d (a mispredicted branch per number).
void write_17_digits(char* out, std::uint64_t d) {
  const std::uint64_t high = d / 100000000;
  out[0] = static_cast<char>('0' + high / 100000000);
  write_8_digits(out + 1, static_cast<std::uint32_t>(high % 100000000));
  write_8_digits(out + 9, static_cast<std::uint32_t>(d % 100000000));
}

// std::to_chars's plain form: fixed unless scientific is shorter (fixed wins a tie); scientific
// as printf's %e, the exponent with a sign and at least two digits. The text is put together in
// a scratch buffer by copies of fixed size (a copy that goes too far is overwritten by the next,
// or lies beyond the end), then copied out whole: no copy or loop of a length known only at run
// time.
char* write_decimal(char* out, bool negative, Decimal d) {
  char digits[48];  // the 17 digits, then room for copies of 17 from any digit
  write_17_digits(digits, d.digits);
  const int n = digit_count(d.digits);
  const char* f = digits + 17 - n;  // the first significant digit
  const int e = d.exponent, sci_exp = e + n - 1, whole = n + e;  // whole: digits before the point
  const int abs_exp = sci_exp < 0 ? -sci_exp : sci_exp;
  const int sci_len = n + (n > 1) + 2 + (abs_exp >= 100 ? 3 : 2);
  const int fixed_len = e >= 0 ? n + e : whole > 0 ? n + 1 : 2 - e;
  char text[64];
  text[0] = '-';
  char* p = text + negative;
  if (fixed_len <= sci_len) {
    if (e >= 0) {  // an integer: the digits, then zeros (fewer than 6, or scientific is shorter)
      std::memcpy(p, f, 17);
      std::memset(p + n, '0', 8);
      p += n + e;
    } else if (whole > 0) {  // the point among the digits
      std::memcpy(p, f, 17);
      p[whole] = '.';
      std::memcpy(p + whole + 1, f + whole, 17);
      p += n + 1;
    } else {  // "0.", up to 3 zeros (or scientific is shorter), the digits
      std::memcpy(p, "0.0000", 6);
      std::memcpy(p + 2 - whole, f, 17);
      p += 2 - e;
    }
  } else {
    p[0] = f[0], p[1] = '.';
    std::memcpy(p + 2, f + 1, 16);
    p += n > 1 ? n + 1 : 1;
    *p++ = 'e';
    *p++ = sci_exp < 0 ? '-' : '+';
    if (abs_exp >= 100) *p++ = static_cast<char>('0' + abs_exp / 100);
    write_pair(p, static_cast<std::uint32_t>(abs_exp % 100));
    p += 2;
  }
  std::memcpy(out, text, kShortestDoubleChars);
  return out + (p - text);
}

}  // namespace

char* write_shortest(char* first, double v) {
  const auto bits = std::bit_cast<std::uint64_t>(v);
  const std::uint64_t fraction = bits & ((std::uint64_t{1} << 52) - 1);
  const int biased = static_cast<int>((bits >> 52) & 0x7ff);
  const int q = biased - 1075;
  if (biased == 0 || q < kMinQ || q > kMaxQ) return std::to_chars(first, first + kShortestDoubleChars, v).ptr;
  const bool negative = bits >> 63;
  const std::uint64_t c = fraction | (std::uint64_t{1} << 52);
  if (q > -53 && (c & ((std::uint64_t{1} << -q) - 1)) == 0)  // an integer: its digits are exact
    return write_decimal(first, negative, without_trailing_zeros({c >> -q, 0}));
  const bool lower_closer = fraction == 0 && biased > 1;  // a power of 2: the neighbour below is nearer
  return write_decimal(first, negative, without_trailing_zeros(shortest_decimal(c, q, lower_closer)));
}

namespace {

constexpr std::array<std::uint64_t, 10> kPowersOf10 = {1, 10, 100, 1000, 10000, 100000, 1000000, 10000000, 100000000,
                                                       1000000000};

// `units` of 10^-Decimals as "whole.fraction": with the count of decimals known at compile time
// the division and remainder by 10^Decimals are multiplications and the fraction's digits a fixed
// sequence (the trace's time column takes 6).
template <int Decimals>
char* write_units(char* first, std::uint64_t units) {
  constexpr std::uint64_t kScale = kPowersOf10[Decimals];
  const std::uint64_t whole = units / kScale;
  const int n_whole = whole == 0 ? 1 : digit_count(whole);
  write_digits(first, whole, n_whole);
  first += n_whole;
  if constexpr (Decimals == 0) return first;
  *first++ = '.';
  write_digits(first, units % kScale, Decimals);
  return first + Decimals;
}

template <std::size_t... D>
constexpr std::array<char* (*)(char*, std::uint64_t), sizeof...(D)> write_units_table(std::index_sequence<D...>) {
  return {&write_units<static_cast<int>(D)>...};
}
constexpr auto kWriteUnits = write_units_table(std::make_index_sequence<kPowersOf10.size()>());

}  // namespace

// |v| 10^decimals = c 10^decimals 2^q exactly, in 128 bits (c 10^9 < 2^83), shifted right by -q
// and rounded to nearest, ties to even (a tie is an exact binary fraction such as 2^-7 =
// 0.0078125); the rounded integer must fit in 64 bits.
char* write_fixed(char* first, char* last, double v, int decimals) {
  const auto bits = std::bit_cast<std::uint64_t>(v);
  const int biased = static_cast<int>((bits >> 52) & 0x7ff);
  const int shift = 1075 - biased;  // -q
  constexpr int kMaxShift = 100;    // beyond it the value rounds to 0: left to std::to_chars
  constexpr std::ptrdiff_t kRoom = 1 + 20 + 1 + 9;  // sign, 64-bit integer part, point, decimals
  const auto general = [&] { return std::to_chars(first, last, v, std::chars_format::fixed, decimals).ptr; };
  if (biased == 0 || shift < 0 || shift > kMaxShift || decimals < 0 || decimals > 9 || last - first < kRoom)
    return general();
  const std::uint64_t c = (bits & ((std::uint64_t{1} << 52) - 1)) | (std::uint64_t{1} << 52);
  const std::uint64_t scale = kPowersOf10[static_cast<std::size_t>(decimals)];
  const u128 n = static_cast<u128>(c) * scale;
  u128 units = n >> shift;
  if (shift > 0) {
    const u128 rest = n & ((u128{1} << shift) - 1), half = u128{1} << (shift - 1);
    units += rest > half || (rest == half && (units & 1) != 0);
  }
  if ((units >> 64) != 0) return general();
  if (bits >> 63) *first++ = '-';
  return kWriteUnits[static_cast<std::size_t>(decimals)](first, static_cast<std::uint64_t>(units));
}

}  // namespace gcpipe
