// Number formatting shared by the writer, the JSON output and the reports.
#pragma once

#include <string>

namespace gcpipe {

/// Appends `v` with the fewest digits that read back to exactly the same double ("12.3", not
/// "12.300000000000001"); integers keep a trailing point ("12.") so that a Fanuc control with the
/// decimal-point rule reads millimetres, not increments. -0 is written as "0.".
void append_shortest(std::string& out, double v);

/// Appends `v` rounded to `decimals` places, trailing zeros dropped, the point always kept.
void append_fixed(std::string& out, double v, int decimals);

/// Appends `v` as a JSON number (shortest round trip, no trailing point).
void append_json_number(std::string& out, double v);

/// Appends `s` as a JSON string literal with escapes.
void append_json_string(std::string& out, const std::string& s);

}  // namespace gcpipe
