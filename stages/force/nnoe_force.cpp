#include "nnoe_force.hpp"

namespace gcpipe::force {

std::vector<calibrate::NnoeStructure> table1_structures(int hidden) {
  // (na, lags of f, lags of a): first order, then two past forces with one or two past feeds and
  // depths; the last is eq. (13).
  const int rows[5][3] = {{1, 1, 1}, {2, 1, 1}, {2, 2, 1}, {2, 1, 2}, {2, 2, 2}};
  std::vector<calibrate::NnoeStructure> out;
  for (const auto& r : rows) {
    calibrate::NnoeStructure s;
    s.na = r[0];
    s.hidden = hidden;
    s.channel_lags = {r[1], r[2]};
    out.push_back(s);
  }
  return out;
}

std::string regressor_text(const calibrate::NnoeStructure& s, const std::vector<std::string>& names) {
  std::string t;
  const auto add = [&](const std::string& name, int lags) {
    for (int i = 1; i <= lags; ++i) t += (t.empty() ? "" : " ") + name + "(t-" + std::to_string(i) + ")";
  };
  add(names[0], s.na);
  for (std::size_t c = 0; c + 1 < names.size(); ++c) add(names[c + 1], s.lags(c));
  return t;
}

}  // namespace gcpipe::force
