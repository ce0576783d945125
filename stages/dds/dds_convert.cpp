#include "dds_convert.hpp"

#include <algorithm>

namespace gcpipe::dds {

namespace {

template <std::size_t N>
void copy_array(const std::array<double, N>& from, std::array<double, N>& to) {
  std::copy(from.begin(), from.end(), to.begin());
}

bool fail(std::string* why, const char* field, unsigned value) {
  if (why != nullptr) *why = std::string("field '") + field + "' holds " + std::to_string(value) +
                             ", which is not a valid value";
  return false;
}

bool motion_from(std::uint8_t v, Motion& m) {
  if (v > static_cast<std::uint8_t>(Motion::kTrochoidSlot)) return false;
  m = static_cast<Motion>(v);
  return true;
}
bool plane_from(std::uint8_t v, Plane& p) {
  if (v != 17 && v != 18 && v != 19) return false;
  p = static_cast<Plane>(v);
  return true;
}
bool feed_mode_from(std::uint8_t v, FeedMode& f) {
  if (v != 93 && v != 94) return false;
  f = static_cast<FeedMode>(v);
  return true;
}
bool path_mode_from(std::uint8_t v, PathMode& m) {
  if (v > 2) return false;
  m = static_cast<PathMode>(v);
  return true;
}
bool spindle_from(std::uint8_t v, Spindle& s) {
  if (v != 3 && v != 4 && v != 5) return false;
  s = static_cast<Spindle>(v);
  return true;
}
bool units_from(std::uint8_t v, Units& u) {
  if (v != 20 && v != 21) return false;
  u = static_cast<Units>(v);
  return true;
}
bool stop_from(std::uint8_t v, ProgramStop& s) {
  if (v > static_cast<std::uint8_t>(ProgramStop::kEndRewind)) return false;
  s = static_cast<ProgramStop>(v);
  return true;
}

bool frame_code_from(std::uint8_t v, FrameCode& c) {
  if (v > static_cast<std::uint8_t>(FrameCode::kToolRadius)) return false;
  c = static_cast<FrameCode>(v);
  return true;
}

void frame_to_msg(const SourceFrame& f, msg::SourceFrame& o) {
  copy_array(f.origin, o.origin());
  o.code(static_cast<std::uint8_t>(f.code));
  o.words(f.words);
  o.incremental(f.incremental);
  o.intermediate(f.intermediate);
  o.selects_work_offset(f.selects_work_offset);
  o.sets_tool_length(f.sets_tool_length);
  o.has_r(f.has_r);
  o.p(f.p);
  copy_array(f.values, o.values());
  o.r(f.r);
  copy_array(f.resolved, o.resolved());
}

void frame_from_msg(const msg::SourceFrame& i, SourceFrame& f) {
  copy_array(i.origin(), f.origin);
  f.words = i.words();
  f.incremental = i.incremental();
  f.intermediate = i.intermediate();
  f.selects_work_offset = i.selects_work_offset();
  f.sets_tool_length = i.sets_tool_length();
  f.has_r = i.has_r();
  f.p = i.p();
  copy_array(i.values(), f.values);
  f.r = i.r();
  copy_array(i.resolved(), f.resolved);
}

}  // namespace

void to_msg(const ResolvedBlock& b, msg::Block& o) {
  o.line(b.line);
  o.text(b.text);
  o.comment(b.comment);
  o.motion(static_cast<std::uint8_t>(b.motion));
  copy_array(b.start, o.start());
  copy_array(b.target, o.target());
  o.axis_words(b.axis_words);
  o.plane(static_cast<std::uint8_t>(b.plane));
  copy_array(b.centre, o.centre());
  o.radius(b.radius);
  o.turns(b.turns);
  o.feed(b.feed);
  o.feed_mode(static_cast<std::uint8_t>(b.feed_mode));
  o.dwell(b.dwell);
  o.spindle_speed(b.spindle_speed);
  o.path_tolerance(b.path_tolerance);
  o.path_mode(static_cast<std::uint8_t>(b.path_mode));
  o.spindle(static_cast<std::uint8_t>(b.spindle));
  o.tool(b.tool);
  o.tool_in_spindle(b.tool_in_spindle);
  o.tool_length_offset(b.tool_length_offset);
  o.tool_length(b.tool_length);
  o.tool_length_active(b.tool_length_active);
  o.tcp(b.tcp);
  copy_array(b.tool_vector, o.tool_vector());
  o.tool_vector_mode(b.tool_vector_mode);
  o.coolant(b.coolant);
  o.work_offset(b.work_offset);
  copy_array(b.work_origin, o.work_origin());
  o.source_units(static_cast<std::uint8_t>(b.source_units));
  o.tool_change(b.tool_change);
  o.stop(static_cast<std::uint8_t>(b.stop));
  o.program_number(b.program_number);
  o.percent(b.percent);
  msg::TrochoidSlot& s = o.slot();
  copy_array(b.slot.start, s.start());
  copy_array(b.slot.end, s.end());
  s.bottom(b.slot.bottom);
  s.clearance(b.slot.clearance);
  s.width(b.slot.width);
  s.step(b.slot.step);
  s.depth_step(b.slot.depth_step);
  s.tool_diameter(b.slot.tool_diameter);
  s.climb(b.slot.climb);
  frame_to_msg(b.frame, o.frame());
}

bool from_msg(const msg::Block& i, ResolvedBlock& b, std::string* why) {
  if (!motion_from(i.motion(), b.motion)) return fail(why, "motion", i.motion());
  if (!plane_from(i.plane(), b.plane)) return fail(why, "plane", i.plane());
  if (!feed_mode_from(i.feed_mode(), b.feed_mode)) return fail(why, "feed_mode", i.feed_mode());
  if (!spindle_from(i.spindle(), b.spindle)) return fail(why, "spindle", i.spindle());
  if (!path_mode_from(i.path_mode(), b.path_mode)) return fail(why, "path_mode", i.path_mode());
  if (!units_from(i.source_units(), b.source_units))
    return fail(why, "source_units", i.source_units());
  if (!stop_from(i.stop(), b.stop)) return fail(why, "stop", i.stop());
  if (i.coolant() > (kCoolantMist | kCoolantFlood)) return fail(why, "coolant", i.coolant());
  if (i.axis_words() >= (1u << kNumAxes)) return fail(why, "axis_words", i.axis_words());
  if (!frame_code_from(i.frame().code(), b.frame.code)) return fail(why, "frame.code", i.frame().code());
  if (i.frame().words() >= (1u << kNumAxes)) return fail(why, "frame.words", i.frame().words());
  b.line = i.line();
  b.text = i.text();
  b.comment = i.comment();
  copy_array(i.start(), b.start);
  copy_array(i.target(), b.target);
  b.axis_words = i.axis_words();
  copy_array(i.centre(), b.centre);
  b.radius = i.radius();
  b.turns = i.turns();
  b.feed = i.feed();
  b.dwell = i.dwell();
  b.spindle_speed = i.spindle_speed();
  b.path_tolerance = i.path_tolerance();
  b.tool = i.tool();
  b.tool_in_spindle = i.tool_in_spindle();
  b.tool_length_offset = i.tool_length_offset();
  b.tool_length = i.tool_length();
  b.tool_length_active = i.tool_length_active();
  b.tcp = i.tcp();
  copy_array(i.tool_vector(), b.tool_vector);
  b.tool_vector_mode = i.tool_vector_mode();
  b.coolant = i.coolant();
  b.work_offset = i.work_offset();
  copy_array(i.work_origin(), b.work_origin);
  b.tool_change = i.tool_change();
  b.program_number = i.program_number();
  b.percent = i.percent();
  const msg::TrochoidSlot& s = i.slot();
  copy_array(s.start(), b.slot.start);
  copy_array(s.end(), b.slot.end);
  b.slot.bottom = s.bottom();
  b.slot.clearance = s.clearance();
  b.slot.width = s.width();
  b.slot.step = s.step();
  b.slot.depth_step = s.depth_step();
  b.slot.tool_diameter = s.tool_diameter();
  b.slot.climb = s.climb();
  frame_from_msg(i.frame(), b.frame);
  return true;
}

DiagnosticKind kind_of(LineStatus status) {
  return status == LineStatus::kDeleted ? DiagnosticKind::kLineDeleted
                                        : DiagnosticKind::kLineRejected;
}

void to_msg(const Diagnostic& d, DiagnosticKind kind, msg::LineDiagnostic& o) {
  o.file(d.file);
  o.line(d.line);
  o.column(d.column);
  o.severity(static_cast<std::uint8_t>(d.severity));
  o.message(d.message);
  o.line_status(static_cast<std::uint8_t>(kind));
}

bool from_msg(const msg::LineDiagnostic& i, Diagnostic& d, DiagnosticKind& kind, std::string* why) {
  if (i.severity() > static_cast<std::uint8_t>(Severity::kError))
    return fail(why, "severity", i.severity());
  if (i.line_status() < static_cast<std::uint8_t>(DiagnosticKind::kLineRejected) ||
      i.line_status() > static_cast<std::uint8_t>(DiagnosticKind::kBlockRejected))
    return fail(why, "line_status", i.line_status());
  d.file = i.file();
  d.line = i.line();
  d.column = i.column();
  d.severity = static_cast<Severity>(i.severity());
  d.message = i.message();
  kind = static_cast<DiagnosticKind>(i.line_status());
  return true;
}

void to_msg(const ParseSummary& s, msg::ParseCounts& o) {
  o.lines_read(s.lines_read);
  o.blocks_emitted(s.blocks_emitted);
  o.lines_rejected(s.lines_rejected);
  o.lines_deleted(s.lines_deleted);
  o.bytes_read(s.bytes_read);
}

void to_msg(const IkTelemetry& p, msg::IkResult& o) {
  o.line(p.line);
  std::copy(p.joints.begin(), p.joints.end(), o.joints().begin());
  std::copy(p.neural_joints.begin(), p.neural_joints.end(), o.neural_joints().begin());
  o.has_neural(p.has_neural);
  o.status(p.status);
  o.flags(p.flags);
}

void to_msg(const SampleTelemetry& s, msg::AxisSample& o) {
  o.tick(s.tick);
  o.time(s.time);
  o.line(s.line);
  std::copy(s.command.begin(), s.command.end(), o.command().begin());
  std::copy(s.actual.begin(), s.actual.end(), o.actual().begin());
  std::copy(s.tip.begin(), s.tip.end(), o.tip().begin());
  o.contour(s.contour);
  o.saturated(s.saturated);
}

ParseSummary from_msg(const msg::ParseCounts& i) {
  ParseSummary s;
  s.lines_read = i.lines_read();
  s.blocks_emitted = i.blocks_emitted();
  s.lines_rejected = i.lines_rejected();
  s.lines_deleted = i.lines_deleted();
  s.bytes_read = i.bytes_read();
  return s;
}

void BatchArrivals::count(DiagnosticKind kind) {
  switch (kind) {
    case DiagnosticKind::kLineRejected: ++lines_rejected; break;
    case DiagnosticKind::kLineDeleted: ++lines_deleted; break;
    case DiagnosticKind::kBlockRejected: ++blocks_rejected; break;
  }
}

BatchTotals totals_of(const msg::BlockBatch& m) {
  BatchTotals t;
  t.summary = from_msg(m.summary());
  t.blocks_sent = m.blocks_sent();
  t.diagnostics_sent = m.diagnostics_sent();
  t.blocks_rejected = m.blocks_rejected();
  t.stopped = m.stopped();
  return t;
}

void set_totals(const BatchTotals& t, msg::BlockBatch& m) {
  to_msg(t.summary, m.summary());
  m.blocks_sent(t.blocks_sent);
  m.diagnostics_sent(t.diagnostics_sent);
  m.blocks_rejected(t.blocks_rejected);
  m.stopped(t.stopped);
}

std::string second_writer_error(const std::string& edge) {
  return "a second writer on " + edge +
         " sends this program too: the stage before runs twice on this DDS domain (two pipelines "
         "on one domain, or a node started by hand beside the launcher's); give each pipeline its "
         "own domain (pipeline.domain, --domain)";
}

std::string check_counts(const BatchTotals& sent, const BatchArrivals& got) {
  std::string problems;
  auto add = [&problems](const std::string& p) {
    if (!problems.empty()) problems += "; ";
    problems += p;
  };
  auto n = [](std::uint64_t v) { return std::to_string(v); };
  const ParseSummary& s = sent.summary;
  if (got.blocks != sent.blocks_sent)
    add("received " + n(got.blocks) + " blocks but the upstream sent " + n(sent.blocks_sent));
  if (got.diagnostics() != sent.diagnostics_sent)
    add("received " + n(got.diagnostics()) + " diagnostics but the upstream sent " +
        n(sent.diagnostics_sent));
  if (got.blocks_rejected != sent.blocks_rejected)
    add("received " + n(got.blocks_rejected) + " rejected-block diagnostics but the stages "
        "rejected " + n(sent.blocks_rejected) + " blocks");
  if (s.blocks_emitted + s.lines_rejected + s.lines_deleted != s.lines_read)
    add("the parser's counts do not add up: " + n(s.blocks_emitted) + " blocks + " +
        n(s.lines_rejected) + " rejected + " + n(s.lines_deleted) + " deleted != " +
        n(s.lines_read) + " lines read");
  // A stage after the parser that stops in strict mode drops the parser's later diagnostics.
  const bool partial = sent.stopped;
  auto mismatch = [partial](std::uint64_t received, std::uint64_t parsed) {
    return partial ? received > parsed : received != parsed;
  };
  if (mismatch(got.lines_rejected, s.lines_rejected))
    add("received " + n(got.lines_rejected) + " rejected-line diagnostics but the parser "
        "rejected " + n(s.lines_rejected) + " lines");
  if (mismatch(got.lines_deleted, s.lines_deleted))
    add("received " + n(got.lines_deleted) + " block-delete diagnostics but the parser "
        "deleted " + n(s.lines_deleted) + " lines");
  return problems;
}

}  // namespace gcpipe::dds
