#include "force_options.hpp"

#include <stdexcept>

#include "gcpipe/config.hpp"

namespace gcpipe::force {

namespace {

ToolSpec load_tool(const Config& c) {
  ToolSpec t;
  // Absent: 0, the stage takes the diameter of the tool in the spindle from the tool table.
  t.diameter = c.has("tool_diameter") ? c.number("tool_diameter", "mm", 0.1, 200) : 0.0;
  t.flutes = static_cast<int>(c.integer("flutes", t.flutes, 1, 12));
  t.flute_length = c.number("flute_length", t.flute_length, "mm", 0.1, 500);
  t.stickout = c.number("stickout", t.stickout, "mm", 1, 1000);
  t.modulus = c.number("modulus", t.modulus, "GPa", 1, 1200);
  t.effective_diameter_factor = c.number("effective_diameter_factor", t.effective_diameter_factor, "", 0.3, 1.0);
  if (t.flute_length > t.stickout) throw c.error("flute_length", "longer than the stickout");
  return t;
}

CuttingCoefficients load_coefficients(const Config& c) {
  const std::string material = c.choice("material", "al7075", {"al7075", "custom"});
  if (material != "custom") {
    if (c.has("coefficients")) throw c.error("coefficients", "only with material: custom");
    return material_coefficients(material);
  }
  if (!c.has("coefficients")) throw c.error("material", "custom needs coefficients: [Ktc, Krc, Kac, Kte, Kre, Kae]");
  const auto k = c.numbers("coefficients", 6, "N/mm^2 or N/mm", -1e5, 1e5);
  if (k[0] <= 0) throw c.error("coefficients", "Ktc must be > 0");
  return {k[0], k[1], k[2], k[3], k[4], k[5], c.string("source", "")};
}

}  // namespace

ForceOptions load_force_options(const Config& c) {
  c.reject_unknown({"material", "coefficients", "source", "tool_diameter", "flutes", "flute_length",
                    "stickout", "modulus", "effective_diameter_factor", "spindle_speed", "stock", "cell", "sample_spacing",
                    "target_force", "peak_force", "max_feed_factor", "min_feed"});
  ForceOptions o;
  o.tool = load_tool(c);
  o.coefficients = load_coefficients(c);
  if (c.has("source") && c.string("material", "al7075") != "custom") throw c.error("source", "only with material: custom");
  o.spindle_speed = c.number("spindle_speed", o.spindle_speed, "rev/min", 0, 200000);
  if (c.has("stock")) {
    const auto s = c.numbers("stock", 5, "mm", -1e5, 1e5);
    if (!(s[2] > s[0] && s[3] > s[1])) throw c.error("stock", "needs xmin < xmax and ymin < ymax");
    for (int i = 0; i < 5; ++i) o.stock[static_cast<std::size_t>(i)] = s[static_cast<std::size_t>(i)];
  }
  o.cell = c.number("cell", o.cell, "mm", 0.001, 5);
  o.sample_spacing = c.number("sample_spacing", o.sample_spacing, "mm", 0, 100);
  o.target_force = c.number("target_force", o.target_force, "N", 0, 1e6);
  o.peak_force = c.number("peak_force", o.peak_force, "N", 0, 1e6);
  if (o.peak_force > 0 && o.peak_force < o.target_force) throw c.error("peak_force", "below target_force");
  o.max_feed_factor = c.number("max_feed_factor", o.max_feed_factor, "", 1, 100);
  o.min_feed = c.number("min_feed", o.min_feed, "mm/min", 0.001, 1e5);
  return o;
}

}  // namespace gcpipe::force
