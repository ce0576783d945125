// One line of a delimited table (CSV, TSV) cut into its fields.
#pragma once

#include <sstream>
#include <string>
#include <vector>

namespace gcpipe {

/// The fields of `line` separated by `sep`, empty ones kept, a trailing separator included (so
/// a row's last empty cell still counts as a column).
inline std::vector<std::string> split_fields(const std::string& line, char sep) {
  std::vector<std::string> out;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, sep)) out.push_back(cell);
  if (!line.empty() && line.back() == sep) out.emplace_back();
  return out;
}

}  // namespace gcpipe
