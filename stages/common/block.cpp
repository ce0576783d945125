#include "gcpipe/block.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace gcpipe {

const char* to_string(Motion m) {
  switch (m) {
    case Motion::kNone: return "none";
    case Motion::kRapid: return "rapid";
    case Motion::kLinear: return "linear";
    case Motion::kArcCW: return "arc_cw";
    case Motion::kArcCCW: return "arc_ccw";
    case Motion::kDwell: return "dwell";
    case Motion::kTrochoidSlot: return "trochoid_slot";
  }
  return "?";
}

namespace {

struct Comparer {
  double tol;
  std::string* why;
  bool ok = true;

  void num(const char* name, double a, double b) {
    if (!ok) return;
    if (a == b) return;
    double scale = std::max({1.0, std::fabs(a), std::fabs(b)});
    if (std::fabs(a - b) <= tol * scale) return;
    fail(name, a, b);
  }
  template <class T>
  void eq(const char* name, const T& a, const T& b) {
    if (!ok || a == b) return;
    if (why) {
      std::ostringstream s;
      s << name << " differs";
      *why = s.str();
    }
    ok = false;
  }
  void fail(const char* name, double a, double b) {
    if (why) {
      std::ostringstream s;
      s.precision(17);
      s << name << ": " << a << " vs " << b;
      *why = s.str();
    }
    ok = false;
  }
  void vec(const char* name, const double* a, const double* b, int n) {
    for (int i = 0; i < n; ++i) num(name, a[i], b[i]);
  }
};

}  // namespace

bool same_meaning(const ResolvedBlock& a, const ResolvedBlock& b, double tol, std::string* why) {
  Comparer c{tol, why};
  c.eq("motion", a.motion, b.motion);
  c.vec("start", a.start.data(), b.start.data(), kNumAxes);
  c.vec("target", a.target.data(), b.target.data(), kNumAxes);
  const bool arc = a.motion == Motion::kArcCW || a.motion == Motion::kArcCCW;
  if (arc) {
    c.eq("plane", a.plane, b.plane);
    c.vec("centre", a.centre.data(), b.centre.data(), 3);
    c.num("radius", a.radius, b.radius);
    c.eq("turns", a.turns, b.turns);
  }
  c.num("feed", a.feed, b.feed);
  c.eq("feed_mode", a.feed_mode, b.feed_mode);
  c.num("dwell", a.dwell, b.dwell);
  c.num("spindle_speed", a.spindle_speed, b.spindle_speed);
  c.num("path_tolerance", a.path_tolerance, b.path_tolerance);
  c.eq("path_mode", a.path_mode, b.path_mode);
  c.eq("spindle", a.spindle, b.spindle);
  c.eq("tool", a.tool, b.tool);
  c.eq("tool_in_spindle", a.tool_in_spindle, b.tool_in_spindle);
  c.eq("tool_length_active", a.tool_length_active, b.tool_length_active);
  c.num("tool_length", a.tool_length, b.tool_length);
  c.eq("tcp", a.tcp, b.tcp);
  c.eq("tool_vector_mode", a.tool_vector_mode, b.tool_vector_mode);
  if (a.tool_vector_mode) c.vec("tool_vector", a.tool_vector.data(), b.tool_vector.data(), 3);
  c.eq("coolant", a.coolant, b.coolant);
  c.eq("work_offset", a.work_offset, b.work_offset);
  c.vec("work_origin", a.work_origin.data(), b.work_origin.data(), kNumAxes);
  c.eq("tool_change", a.tool_change, b.tool_change);
  c.eq("stop", a.stop, b.stop);
  c.eq("comment", a.comment, b.comment);
  if (a.motion == Motion::kTrochoidSlot) {
    c.vec("slot.start", a.slot.start.data(), b.slot.start.data(), 3);
    c.vec("slot.end", a.slot.end.data(), b.slot.end.data(), 3);
    c.num("slot.bottom", a.slot.bottom, b.slot.bottom);
    c.num("slot.clearance", a.slot.clearance, b.slot.clearance);
    c.num("slot.width", a.slot.width, b.slot.width);
    c.num("slot.step", a.slot.step, b.slot.step);
    c.num("slot.depth_step", a.slot.depth_step, b.slot.depth_step);
    c.num("slot.tool_diameter", a.slot.tool_diameter, b.slot.tool_diameter);
    c.eq("slot.climb", a.slot.climb, b.slot.climb);
  }
  return c.ok;
}

}  // namespace gcpipe

#include "gcpipe/number_format.hpp"

namespace gcpipe {

namespace {
const char* plane_name(Plane p) { return p == Plane::kXY ? "XY" : p == Plane::kZX ? "ZX" : "YZ"; }
}  // namespace

namespace {

/// One JSON object's fields, appended to `o` in order.
struct JsonFields {
  std::string& o;
  void key(const char* k) {
    if (o.back() != '{') o.push_back(',');
    o.push_back('"');
    o += k;
    o += "\":";
  }
  void num(const char* k, double v) {
    key(k);
    append_json_number(o, v);
  }
  void arr(const char* k, const double* v, int n) {
    key(k);
    o.push_back('[');
    for (int i = 0; i < n; ++i) {
      if (i) o.push_back(',');
      append_json_number(o, v[i]);
    }
    o.push_back(']');
  }
  void text(const char* k, const char* v) {  // a fixed name: no escaping needed
    key(k);
    o.push_back('"');
    o += v;
    o.push_back('"');
  }
  void flag(const char* k, bool v) {
    key(k);
    o += v ? "true" : "false";
  }
};

void append_slot_json(JsonFields& f, const TrochoidSlot& t) {
  f.key("slot");
  f.o.push_back('{');
  f.arr("start", t.start.data(), 3);
  f.arr("end", t.end.data(), 3);
  f.num("bottom", t.bottom);
  f.num("clearance", t.clearance);
  f.num("width", t.width);
  f.num("step", t.step);
  f.num("depth_step", t.depth_step);
  f.num("tool_diameter", t.tool_diameter);
  f.flag("climb", t.climb);
  f.o.push_back('}');
}

/// The line, its text and the move: what the block does.
void append_motion_json(JsonFields& f, const ResolvedBlock& b) {
  f.num("line", static_cast<double>(b.line));
  f.key("text");
  append_json_string(f.o, b.text);
  if (!b.comment.empty()) {
    f.key("comment");
    append_json_string(f.o, b.comment);
  }
  f.text("motion", to_string(b.motion));
  f.arr("start", b.start.data(), kNumAxes);
  f.arr("target", b.target.data(), kNumAxes);
  if (b.motion == Motion::kArcCW || b.motion == Motion::kArcCCW) {
    f.text("plane", plane_name(b.plane));
    f.arr("centre", b.centre.data(), 3);
    f.num("radius", b.radius);
    f.num("turns", b.turns);
  }
  if (b.motion == Motion::kDwell) f.num("dwell", b.dwell);
  if (b.motion == Motion::kTrochoidSlot) append_slot_json(f, b.slot);
}

/// The modal state in force for it, and what the line ends with (tool change, stop, %).
void append_modal_json(JsonFields& f, const ResolvedBlock& b) {
  f.num("feed", b.feed);
  f.text("feed_mode", b.feed_mode == FeedMode::kInverseTime ? "G93" : "G94");
  f.num("spindle_speed", b.spindle_speed);
  // Only where the program sets them (G64 P, G61, G61.1), so that other programs' JSON is unchanged.
  if (b.path_tolerance > 0) f.num("path_tolerance", b.path_tolerance);
  if (b.path_mode != PathMode::kBlend) f.text("path_mode", b.path_mode == PathMode::kExactStop ? "G61" : "G61.1");
  f.text("spindle", b.spindle == Spindle::kCW ? "M3" : b.spindle == Spindle::kCCW ? "M4" : "M5");
  f.num("tool", b.tool);
  f.num("tool_in_spindle", b.tool_in_spindle);
  f.num("tool_length_offset", b.tool_length_offset);
  f.num("tool_length", b.tool_length);
  f.flag("tool_length_active", b.tool_length_active);
  f.flag("tcp", b.tcp);
  if (b.tool_vector_mode) {  // only in G43.5 mode, so that other programs' JSON is unchanged
    f.flag("tool_vector_mode", true);
    f.arr("tool_vector", b.tool_vector.data(), 3);
  }
  f.num("coolant", b.coolant);
  f.num("work_offset", b.work_offset);
  f.arr("work_origin", b.work_origin.data(), kNumAxes);
  f.text("source_units", b.source_units == Units::kInch ? "inch" : "mm");
  if (b.tool_change) f.flag("tool_change", true);
  if (b.stop != ProgramStop::kNone)
    f.text("stop", b.stop == ProgramStop::kStop           ? "M0"
                   : b.stop == ProgramStop::kOptionalStop ? "M1"
                   : b.stop == ProgramStop::kEnd          ? "M2"
                                                          : "M30");
  if (b.program_number >= 0) f.num("program_number", b.program_number);
  if (b.percent) f.flag("percent", true);
}

}  // namespace

void append_json(std::string& o, const ResolvedBlock& b) {
  JsonFields f{o};
  o.push_back('{');
  append_motion_json(f, b);
  append_modal_json(f, b);
  o.push_back('}');
}

}  // namespace gcpipe
