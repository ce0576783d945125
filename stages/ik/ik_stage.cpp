#include "ik_stage.hpp"

#include <bit>
#include <cmath>
#include <stdexcept>

#include <nlohmann/json.hpp>

namespace gcpipe {

namespace {

IkOptions options_of(const pipeline::StageContext& c) {
  IkOptions o = load_ik_options(c.config->root.section("ik"));
  if (c.ik_tool_vector) o.resolve_orientation = IkInputMode::kToolVector;
  return o;
}

double distance(const Vec3& a, const Vec3& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

nlohmann::ordered_json axes_json(const Axes& a) { return nlohmann::ordered_json(std::vector<double>(a.begin(), a.end())); }

nlohmann::ordered_json neural_json(const IkSummary& s, const Axes& tolerance) {
  Axes rms{};
  for (std::size_t i = 0; i < kNumAxes; ++i)
    rms[i] = s.neural_points ? std::sqrt(s.neural_sum_sq_diff[i] / static_cast<double>(s.neural_points)) : 0.0;
  return {{"points", s.neural_points},
          {"units", "mm (X Y Z), deg (A C)"},
          {"tolerance", axes_json(tolerance)},
          {"max_abs_diff", axes_json(s.neural_max_abs_diff)},
          {"rms_diff", axes_json(rms)}};
}

nlohmann::ordered_json summary_json(const IkSummary& s, bool neural, const Axes& tolerance) {
  nlohmann::ordered_json flags = nlohmann::ordered_json::object();
  for (int bit = 0; bit < 16; ++bit)
    if (s.flag_counts[bit] != 0) flags[ik_flags_to_string(1u << bit)] = s.flag_counts[bit];
  return {{"points", s.points},
          {"ok", s.ok},
          {"degraded", s.degraded},
          {"failed", s.failed},
          {"first_failed_line", s.first_failed_line},
          {"flags", flags},
          {"outside_envelope_informational", s.envelope_flag_only},
          {"neural", neural ? neural_json(s, tolerance) : nlohmann::ordered_json(nullptr)}};
}

IkTelemetry telemetry_of(const IkPoint& p) {
  IkTelemetry t;
  t.line = p.line;
  t.joints = p.joints;
  t.neural_joints = p.neural_joints;
  t.has_neural = p.has_neural;
  t.status = static_cast<std::uint8_t>(p.status);
  t.flags = p.flags;
  return t;
}

}  // namespace

std::optional<neural::NeuralIk> load_ik_model_for(const IkOptions& options, const std::string& path,
                                                  const std::string& machine) {
  if (path.empty()) return load_ik_model(options, machine);
  std::optional<neural::NeuralIk> model(neural::NeuralIk::load(path));
  // A model learns one machine's geometry; on another machine it would be confidently wrong.
  if (model->provenance().machine != machine)
    throw std::runtime_error(path + ": the model was trained for machine '" + model->provenance().machine +
                             "', the config is for '" + machine + "': train one with gcpipe train-ik --config <this config>");
  return model;
}

IkPipelineStage::IkPipelineStage(const pipeline::StageContext& c)
    : kin_(c.config->machine.kinematics),
      model_(load_ik_model_for(options_of(c), c.ik_model, c.config->machine.name)),
      stage_(kin_, options_of(c), c.config->machine.initial_position, model_ ? &*model_ : nullptr),
      neural_asked_(!c.ik_model.empty()) {
  sampler_.s.tolerance = stage_.options().neural_tolerance;
}

// A program whose rotary axes never move (a three-axis pocket) gives the neural IK nothing the
// analytic IK does not solve trivially: its section and figures would only be noise in the report
// ("neural_outside_envelope: 36"). They are shown when --model asks for them.
bool IkPipelineStage::neural_shown() const {
  return model_.has_value() && (rotary_moves_ || neural_asked_);
}

bool IkPipelineStage::block(const ResolvedBlock& b, pipeline::Emitter& out) {
  if (stage_.step(b, point_)) {
    if (!first_joints_) first_joints_ = point_.joints;
    rotary_moves_ = rotary_moves_ || std::abs(point_.joints[kA] - (*first_joints_)[kA]) > 1e-9 ||
                    std::abs(point_.joints[kC] - (*first_joints_)[kC]) > 1e-9;
    sampler_.add(point_, kin_, b.tool_length_active ? b.tool_length : kin_.tool_length);
    if (tap_) tap_(point_);
    if (out.wants_telemetry()) out.ik_point(telemetry_of(point_));
  }
  return out.block(b);
}

void IkPipelineStage::report(pipeline::ReportContext& r) const {
  const bool neural = neural_shown();
  IkSummary summary = stage_.summary();
  std::string text;
  if (model_ && !neural) {
    for (IkFlag f : {kIkNeuralDiverged, kIkNeuralOutsideEnvelope, kIkNeuralFailed})
      summary.flag_counts[std::countr_zero(static_cast<unsigned>(f))] = 0;
    summary.envelope_flag_only = 0;
  }
  (*r.json)["ik"] = summary_json(summary, neural, stage_.options().neural_tolerance);
  // format_summary starts each line with "ik: "; report.txt has its own column of stage names.
  text = format_summary(summary, neural);
  if (model_ && !neural) {
    const std::string why = "three-axis program (A and C do not move): the neural IK is not compared (--model compares it)";
    (*r.json)["ik"]["neural_skipped"] = why;
    text = text.substr(0, text.rfind("\nik: no neural model")) + "\nik: " + why;
  }
  std::string indented = "  ik:       ";
  for (std::size_t at = 0; at < text.size();) {
    const std::size_t end = std::min(text.find('\n', at), text.size());
    std::string_view line = std::string_view(text).substr(at, end - at);
    if (line.starts_with("ik: ")) line.remove_prefix(4);
    indented += std::string(line) + "\n";
    at = end + 1;
    if (at < text.size()) indented += "            ";
  }
  *r.text += indented;
  if (!neural || sampler_.s.index.empty() || r.dir.empty()) return;
  if (r.progress) r.progress("drawing the IK figures", 0, 0);
  plot_ik_divergence(r.dir / "plots" / "ik_divergence.png", sampler_.s, r.input_base + ": neural against analytic IK, per axis");
  plot_ik_tip_error(r.dir / "plots" / "ik_tip_error.png", sampler_.s, r.input_base + ": tool-tip error of each IK solver");
  r.files->push_back("plots/ik_divergence.png");
  r.files->push_back("plots/ik_tip_error.png");
}

void IkPipelineStage::Sampler::add(const IkPoint& p, const MachineKinematics& kin, double tool_length) {
  const std::uint64_t k = seen++;
  if (!p.has_neural) return;
  ++s.neural_points;
  if ((p.flags & kIkNeuralDiverged) != 0 && s.flagged_count++ % flag_stride == 0) {
    s.flagged.push_back(static_cast<double>(k));
    if (s.flagged.size() >= kCap) thin(s.flagged), flag_stride *= 2;
  }
  if (k % stride != 0) return;
  s.index.push_back(static_cast<double>(k));
  for (std::size_t i = 0; i < kNumAxes; ++i) s.diff[i].push_back(p.neural_joints[i] - p.joints[i]);
  s.tip_error_analytic.push_back(distance(forward_kinematics(kin, p.joints, tool_length).tip, p.pose.tip));
  s.tip_error_neural.push_back(distance(forward_kinematics(kin, p.neural_joints, tool_length).tip, p.pose.tip));
  if (s.index.size() >= kCap) {
    thin(s.index);
    for (auto& d : s.diff) thin(d);
    thin(s.tip_error_analytic);
    thin(s.tip_error_neural);
    stride *= 2;
  }
}

void IkPipelineStage::Sampler::thin(std::vector<double>& v) {
  std::size_t j = 0;
  for (std::size_t i = 0; i < v.size(); i += 2) v[j++] = v[i];
  v.resize(j);
}

pipeline::StageInfo ik_stage() {
  return {"ik", "force", "analytic and neural inverse kinematics side by side, with divergence flags",
          pipeline::Port::kBlocks, pipeline::Port::kBlocks,
          [](const pipeline::StageContext& c) -> std::unique_ptr<pipeline::Stage> {
            return std::make_unique<IkPipelineStage>(c);
          },
          "gcpipe_ik", pipeline::Telemetry::kIkPoints, "gcpipe_ik_results"};
}

}  // namespace gcpipe
