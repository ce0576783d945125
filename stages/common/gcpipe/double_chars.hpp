// Text of doubles, the bytes of std::to_chars, faster: the trace writes one double per column per
// tick, and std::to_chars was most of `gcpipe simulate`'s trace writer.
#pragma once

#include <cstddef>

namespace gcpipe {

/// Room write_shortest needs: "-2.2250738585072014e-308" is the longest text (24 characters).
inline constexpr std::size_t kShortestDoubleChars = 24;

/// Writes the text `std::to_chars(first, first + kShortestDoubleChars, v)` writes (the shortest
/// that reads back to v; fixed unless scientific is shorter) and returns its end. Like
/// std::to_chars it may also write anything after the text, within kShortestDoubleChars.
/// Doubles of magnitude 2^-70 .. 2^53 (every coordinate of a trace) take a Schubfach-style
/// shortest search (R. Giulietti, "The Schubfach way to render doubles", 2020) with exact 128-bit
/// powers of ten, about a third of std::to_chars's instructions; all others (0, subnormals, huge,
/// inf, nan) are handed to std::to_chars itself.
char* write_shortest(char* first, double v);

/// Writes what `std::to_chars(first, last, v, std::chars_format::fixed, decimals).ptr` points
/// to (rounded to nearest, ties to even). For 0 <= decimals <= 9, |v| 10^decimals < 2^64 and at
/// least 31 characters of room, exact 128-bit integer arithmetic instead of std::to_chars's
/// general path; anything else is std::to_chars's own.
char* write_fixed(char* first, char* last, double v, int decimals);

}  // namespace gcpipe
