#include "compensate_program.hpp"

#include <algorithm>
#include <cstdio>
#include <map>

namespace gcpipe::compensate {

namespace {

constexpr double kGuardTolerance = 0.001;  // [mm, deg] an offset read back differs beyond this

std::string fixed(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.4f", v);
  return buf;
}

/// The work systems the program's motion blocks run in, with the machine file's origin of each:
/// compensated.nc's joints are measured from those.
std::map<std::int32_t, Axes> work_systems_used(std::span<const ResolvedBlock> program) {
  std::map<std::int32_t, Axes> used;
  for (const ResolvedBlock& b : program)
    if (b.motion != Motion::kNone) used.emplace(b.work_offset, b.work_origin);
  return used;
}

/// The tool-centre-point block that the points from `first` to the next tool change take their
/// tool length from (its IK put that length into the joints), or null when none does.
const ResolvedBlock* length_in_joints(std::span<const ResolvedBlock> program, std::size_t first) {
  for (std::size_t i = first; i < program.size(); ++i) {
    const ResolvedBlock& b = program[i];
    if (i > first && b.tool_change) break;
    if (b.motion != Motion::kNone && b.tcp && b.tool_length_active) return &b;
  }
  return nullptr;
}

// Parameter numbers of the G5x origins: #5221 + 20 k, axes X Y Z A (B) C. LinuxCNC has B at +4
// and C at +5; a Fanuc 0i numbers the axes in the control's order, X Y Z A C here: C at +4.
int origin_parameter(std::int32_t work_offset, int axis, Dialect d) {
  static constexpr int kLinuxCnc[kNumAxes] = {0, 1, 2, 3, 5};
  return 5221 + 20 * (work_offset - 54) + (d == Dialect::kFanuc ? axis : kLinuxCnc[axis]);
}

std::string origin_words(const Axes& origin) {
  std::string t;
  for (int a = 0; a < kNumAxes; ++a) t += std::string(a ? " " : "") + kAxisLetters[a] + fixed(origin[a]);
  return t;
}

// LinuxCNC: one o-if per check, `(abort, ...)` stops the program with the message. The
// parameters hold the machine's own unit, mm on a metric configuration (docs/running-compensated-programs.md).
std::string linuxcnc_check(const std::string& label, const std::string& condition, const std::string& message) {
  return "o<" + label + "> if [" + condition + "]\n(abort, gcpipe: " + message + ")\no<" + label + "> endif\n";
}

std::string differs(int parameter, double value) {
  return "[ABS[#" + std::to_string(parameter) + " - " + fixed(value) + "] GT " + fixed(kGuardTolerance) + "]";
}

std::string work_offset_guard(std::span<const ResolvedBlock> program, Dialect d) {
  std::string t;
  int alarm = 1;
  for (const auto& [system, origin] : work_systems_used(program)) {
    const std::string name = "G" + std::to_string(system);
    if (d == Dialect::kLinuxCnc) {
      std::string condition;
      for (int a = 0; a < kNumAxes; ++a) condition += (a ? " OR " : "") + differs(origin_parameter(system, a, d), origin[a]);
      t += linuxcnc_check("gcpipe_" + name, condition,
                          name + " is not " + origin_words(origin) + ", the work offset this program was computed for");
      continue;
    }
    for (int a = 0; a < kNumAxes; ++a)
      t += "IF " + differs(origin_parameter(system, a, d), origin[a]) + " THEN #3000 = " + std::to_string(alarm) + " (" +
           name + " " + kAxisLetters[a] + " IS NOT " + fixed(origin[a]) + ")\n";
    ++alarm;
  }
  if (d == Dialect::kLinuxCnc)
    return t + linuxcnc_check("gcpipe_g92", "#5210 NE 0", "a G92 offset is in force; this program was computed without one");
  // Fanuc's external work offset (#5201..#5205) shifts every system.
  for (int a = 0; a < kNumAxes; ++a)
    t += "IF " + differs(5201 + a, 0) + " THEN #3000 = 9 (EXT OFFSET " + kAxisLetters[a] + " IS NOT 0)\n";
  return t;
}

std::string tool_length_guard(const ResolvedBlock& b, Dialect d) {
  const std::string h = std::to_string(b.tool_length_offset), length = fixed(b.tool_length);
  if (d == Dialect::kLinuxCnc)
    return linuxcnc_check("gcpipe_t" + std::to_string(b.tool_in_spindle) + "_h" + h,
                          "[#5400 NE " + std::to_string(b.tool_in_spindle) + "] OR " + differs(5403, b.tool_length),
                          "tool " + std::to_string(b.tool_in_spindle) + " is not in the spindle with length " + length +
                              " mm, the length this program was computed for");
  // Fanuc: the length offset H as the control holds it, read as the compensation in force.
  return "G43 H" + h + "\nIF " + differs(5083, b.tool_length) + " THEN #3000 = 10 (H" + h + " IS NOT " + length +
         ")\nG49\n";
}

}  // namespace

/// The distance of each written point's tool tip from the program's nominal path, in order.
class EnvelopeMeter {
 public:
  EnvelopeMeter(const Model& model, const Nominal& nom, std::span<const ResolvedBlock> program)
      : nom_(nom), program_(program), meter_(model, nom, true), lead_(static_cast<std::uint64_t>(0.25 / nom.period)) {}
  double distance(const Node& n) { return distance(n.joints, n.tick, n.block); }
  double distance(const Axes& joints, std::uint64_t tick, std::uint32_t block) {
    simulate::Tick t;
    // Never backwards (the search goes forward only), and far enough ahead for a leading point.
    t.n = std::max(last_, std::min<std::uint64_t>(tick + lead_, nom_.reference.size() - 1));
    last_ = t.n;
    t.actual = joints;
    Vec3 tip, nearest;
    return meter_.distance(t, program_[block], tip, nearest);
  }

 private:
  const Nominal& nom_;
  std::span<const ResolvedBlock> program_;
  simulate::ContourMeter meter_;
  std::uint64_t lead_;
  std::uint64_t last_ = 0;
};

namespace {

/// The lowest Z of a block's move [mm, machine file frame]: its ends, and for an arc across Z
/// (G18 / G19) the bottom of its circle.
double lowest_z(const ResolvedBlock& b) {
  double z = std::min(b.start[kZ], b.target[kZ]);
  const bool arc = b.motion == Motion::kArcCW || b.motion == Motion::kArcCCW;
  if (arc && b.plane != Plane::kXY) z = std::min(z, b.centre[kZ] - b.radius);
  return z;
}

/// A three-axis point never lower than its source block goes: the learning may command Z past a
/// plunge's floor to make a lagging axis arrive in time, which on a machine is a cut below the
/// part's floor should the axis not lag as modelled. Lifted to the floor; true when it was.
bool lift_to_floor(const ResolvedBlock& b, Node& n) {
  const double floor = lowest_z(b);
  if (n.joints[kZ] >= floor) return false;
  n.joints[kZ] = floor;
  return true;
}

}  // namespace

ReadBackChecks::ReadBackChecks(const Model& model, const Nominal& nom, std::span<const ResolvedBlock> program,
                               bool work_frame)
    : program_(program), work_frame_(work_frame), meter_(std::make_unique<EnvelopeMeter>(model, nom, program)) {}

ReadBackChecks::~ReadBackChecks() = default;

void ReadBackChecks::keep(Worst& w, double value, std::uint64_t line) {
  if (value > w.value) w = {value, line};
}

void ReadBackChecks::add(const ResolvedBlock& b, const PointSource& source) {
  const ResolvedBlock& src = program_[std::min<std::size_t>(source.block, program_.size() - 1)];
  const bool timed = b.motion == Motion::kLinear && b.feed_mode == FeedMode::kInverseTime;
  if (timed) keep(farthest_, meter_->distance(b.target, source.tick, source.block), b.line);
  if (!work_frame_) return;
  if (timed) keep(below_floor_, lowest_z(src) - b.target[kZ], b.line);
  if (b.motion == Motion::kRapid || (!timed && b.motion != Motion::kDwell))
    keep(rapid_off_, dist3({b.target[kX], b.target[kY], b.target[kZ]}, {src.target[kX], src.target[kY], src.target[kZ]}),
         b.line);
}

std::string ReadBackChecks::failures(double envelope) const {
  // [mm] the text's rounding: 4 decimals of an inch are 2.54 um a word, 2.2 um over three axes
  // at half a digit each; and the measure's window, which starts at the point's move here and at
  // the point itself for the envelope (0.25 s ahead of either).
  constexpr double kRounding = 5e-3;
  std::string out;
  char msg[240];
  if (farthest_.value > envelope + kRounding) {
    std::snprintf(msg, sizeof msg, "a point of line %llu lies %.4f mm from the source's path, beyond the stated envelope %.4f mm; ",
                  static_cast<unsigned long long>(farthest_.line), farthest_.value, envelope);
    out += msg;
  }
  if (below_floor_.value > kRounding) {
    std::snprintf(msg, sizeof msg, "a point of line %llu lies %.4f mm below its source move's lowest Z; ",
                  static_cast<unsigned long long>(below_floor_.line), below_floor_.value);
    out += msg;
  }
  if (rapid_off_.value > kRounding) {
    std::snprintf(msg, sizeof msg, "the move of line %llu ends %.4f mm from where the source's does; ",
                  static_cast<unsigned long long>(rapid_off_.line), rapid_off_.value);
    out += msg;
  }
  if (!out.empty()) out.resize(out.size() - 2);
  return out;
}

std::string five_axis_guard(std::span<const ResolvedBlock> program, std::size_t first, bool program_start, Dialect d) {
  std::string t;
  const ResolvedBlock* tcp = length_in_joints(program, first);
  if (program_start)
    t += "(gcpipe guard: the points below are machine joints computed for the work offsets and tool lengths "
         "checked here; the program stops when the control's differ)\n" + work_offset_guard(program, d);
  if (tcp != nullptr) t += tool_length_guard(*tcp, d);
  return t;
}

ProgramCompensation compensate_program(const Model& model, const CompensateOptions& options,
                                       const WriteOptions& write_options, const simulate::SimulationRun& run,
                                       const Progress& progress, const TextSink& text) {
  ProgramCompensation pc;
  if (!run.before) {
    pc.note = run.note;
    return pc;
  }
  if (!options.enabled) {
    pc.note = "compensate.enabled is false";
    return pc;
  }
  // With compensate.work_frame a three-axis program stays in the source's work frame with its
  // tool length; otherwise the points are machine joints behind a guard (CompensatedFrames).
  CompensatedFrames frames;
  frames.work_frame = options.work_frame && three_axis_program(run.program);
  if (frames.work_frame) frames.as_source = moves_written_as_source(run.program);
  WriteOptions wo = write_options;
  wo.source_frames = frames.work_frame;
  // The text is written as the nodes come and handed on window by window: on a long program it
  // (tens of MB) and the nodes (56 bytes every 4 ms) are never held whole.
  Writer writer(wo);
  std::string held;                        // written, not handed on yet
  std::vector<PointSource> held_points;    // the source of each of its motion blocks
  auto hand_on = [&] {
    if (text) text(held, held_points);
    else pc.text += held;
    held.clear();
    held_points.clear();
  };
  bool program_start = true;
  if (!frames.work_frame)
    frames.section_start = [&](std::size_t block) {
      held += five_axis_guard(run.program, block, program_start, wo.dialect);
      program_start = false;
    };
  const auto emit = [&](const ResolvedBlock& b, std::size_t source, std::uint64_t tick) {
    writer.write(b, held);
    if (b.motion != Motion::kNone) held_points.push_back({static_cast<std::uint32_t>(source), tick});
  };
  CompensatedBlocks blocks(run.program, model.interp.period, emit, frames);
  pc.envelope.work_frame = frames.work_frame;
  EnvelopeMeter envelope(model, *run.nominal, run.program);
  bool first_node = true;
  std::vector<Node> written;
  const NodeSink sink = [&](std::span<const Node> nodes, bool learned_so_far) {
    written.assign(nodes.begin(), nodes.end());
    for (Node& n : std::span(written).subspan(first_node ? 1 : 0)) {  // node 0 is the start, not written
      if (frames.work_frame && frames.as_source[n.block]) continue;
      if (frames.work_frame && lift_to_floor(run.program[n.block], n)) ++pc.envelope.points_clamped;
      pc.envelope.envelope = std::max(pc.envelope.envelope, envelope.distance(n));
    }
    first_node = false;
    blocks.add(written);
    if (learned_so_far) hand_on();
  };
  pc.result = compensate(model, *run.nominal, run.program, run.start, *run.before, options, progress, sink);
  if (!pc.result->compensated) {
    pc.note = pc.result->note;
    return pc;
  }
  blocks.finish();
  hand_on();
  return pc;
}

}  // namespace gcpipe::compensate
