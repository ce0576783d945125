#include "force_options.hpp"

#include <algorithm>
#include <stdexcept>

#include "gcpipe/config.hpp"

namespace gcpipe::force {

namespace {

std::string list_of(const std::vector<int>& groups) {
  std::string s;
  for (std::size_t i = 0; i < groups.size(); ++i) s += (i == 0 ? "" : i + 1 == groups.size() ? " or " : ", ") + std::to_string(groups[i]);
  return s;
}

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

Material mechanistic_material(const CuttingCoefficients& k) {
  Material m;
  m.law = k;
  m.source = k.source;
  return m;
}

Material load_named_material(const Config& c) {
  const std::string material = c.choice("material", "al7075", {"al7075", "custom"});
  if (material != "custom") {
    for (const char* key : {"coefficients", "source"})
      if (c.has(key)) throw c.error(key, "only with material: custom");
    return mechanistic_material(material_coefficients(material));
  }
  if (!c.has("coefficients")) throw c.error("material", "custom needs coefficients: [Ktc, Krc, Kac, Kte, Kre, Kae]");
  const auto k = c.numbers("coefficients", 6, "N/mm^2 or N/mm", -1e5, 1e5);
  if (k[0] <= 0) throw c.error("coefficients", "Ktc must be > 0");
  return mechanistic_material({k[0], k[1], k[2], k[3], k[4], k[5], c.string("source", "")});
}

/// The VDI 3323 group named by `vdi3323_group`, by `grade` (and `condition`) or by both, which
/// must then agree (README sec. 1b: the grade-to-group mapping of the table's PROVENANCE.md).
int vdi3323_group_of(const Config& m) {
  if (m.has("condition") && !m.has("grade")) throw m.error("condition", "only with grade");
  std::vector<int> by_grade;
  if (m.has("grade")) {
    try {
      by_grade = grade_groups(m.string("grade", ""), m.string("condition", ""));
    } catch (const std::invalid_argument& e) {
      throw m.error("grade", e.what());
    }
  }
  if (!m.has("vdi3323_group")) {
    if (by_grade.empty()) throw m.error("vdi3323_group", "needed (or a grade: C45, 1045, 42CrMo4, 4140, 1018, 316L, H13)");
    if (by_grade.size() > 1)
      throw m.error("grade", "is in groups " + list_of(by_grade) + " by its strength: give vdi3323_group (stages/force/README.md sec. 1b)");
    return by_grade.front();
  }
  const int group = static_cast<int>(m.integer("vdi3323_group", 0, 1, 99));
  if (!by_grade.empty() && std::find(by_grade.begin(), by_grade.end(), group) == by_grade.end())
    throw m.error("vdi3323_group", std::to_string(group) + " does not match the grade, which is in group(s) " + list_of(by_grade));
  return group;
}

/// Fr/Ft and Fa/Ft with their source, both or none.
std::optional<ForceRatios> load_ratios(const Config& m) {
  const bool radial = m.has("radial_to_tangential"), axial = m.has("axial_to_tangential");
  if (!radial && !axial) {
    if (m.has("ratio_source")) throw m.error("ratio_source", "only with radial_to_tangential and axial_to_tangential");
    return std::nullopt;
  }
  if (!radial || !axial) throw m.error(radial ? "axial_to_tangential" : "radial_to_tangential", "needed with the other ratio");
  ForceRatios r;
  r.radial = m.number("radial_to_tangential", "", 0.01, 3);
  r.axial = m.number("axial_to_tangential", "", -3, 3);
  r.source = m.string("ratio_source", "");
  if (r.source.empty()) throw m.error("ratio_source", "needed: where the ratios come from (it goes into the report)");
  return r;
}

/// `material: {vdi3323_group: N, grade: .., condition: .., radial_to_tangential: .., ...}`.
Material load_kienzle_material(const Config& c) {
  for (const char* key : {"coefficients", "source"})
    if (c.has(key)) throw c.error(key, "only with material: custom");
  const Config m = c.section("material");
  m.reject_unknown({"vdi3323_group", "grade", "condition", "radial_to_tangential", "axial_to_tangential", "ratio_source"});
  const int number = vdi3323_group_of(m);
  Material out;
  try {
    out.group = kienzle_group(number);
  } catch (const std::invalid_argument& e) {
    throw m.error("vdi3323_group", e.what());
  }
  if (m.has("grade")) out.grade = m.string("grade", "") + (m.has("condition") ? " " + m.string("condition", "") : "");
  out.ratios = load_ratios(m);
  out.law = kienzle_law(out.group->kc1, out.group->mc, out.ratios ? &*out.ratios : nullptr);
  out.source = out.group->describe() + "; " + kienzle_source();
  return out;
}

Material load_material(const Config& c) {
  return c.is_mapping("material") ? load_kienzle_material(c) : load_named_material(c);
}

}  // namespace

ForceOptions load_force_options(const Config& c) {
  c.reject_unknown({"material", "coefficients", "source", "tool_diameter", "flutes", "flute_length",
                    "stickout", "modulus", "effective_diameter_factor", "spindle_speed", "stock", "cell", "sample_spacing",
                    "target_force", "peak_force", "max_feed_factor", "min_feed", "spindle_model"});
  ForceOptions o;
  o.tool = load_tool(c);
  o.material = load_material(c);
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
  // The planner holds the resultant force: without radial and axial forces there is none.
  for (const char* key : {"target_force", "peak_force"})
    if (c.has(key) && c.number(key, 0, "N", 0, 1e6) > 0 && !o.material.resultant_known())
      throw c.error(key, "needs the radial and axial forces, which Kienzle's kc1/mc do not give: state "
                         "material.radial_to_tangential, axial_to_tangential and ratio_source (stages/force/README.md sec. 1b)");
  o.max_feed_factor = c.number("max_feed_factor", o.max_feed_factor, "", 1, 100);
  o.min_feed = c.number("min_feed", o.min_feed, "mm/min", 0.001, 1e5);
  if (c.has("spindle_model")) o.spindle_model = c.file_path("spindle_model", "a spindle model file of gcpipe train-spindle");
  return o;
}

}  // namespace gcpipe::force
