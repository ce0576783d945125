#include "ik.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "gcpipe/config.hpp"
#include "neural_ik.hpp"

namespace gcpipe {

const char* to_string(IkInputMode m) {
  switch (m) {
    case IkInputMode::kTcpAngles: return "tcp_angles";
    case IkInputMode::kToolVector: return "tool_vector";
    case IkInputMode::kMachineAxes: return "machine_axes";
  }
  return "?";
}

IkOptions load_ik_options(const Config& s) {
  s.reject_unknown({"resolve_orientation", "neural_tolerance", "downstream", "model"});
  IkOptions o;
  o.resolve_orientation =
      s.choice("resolve_orientation", "programmed", {"programmed", "tool_vector"}) == "tool_vector"
          ? IkInputMode::kToolVector
          : IkInputMode::kTcpAngles;
  if (s.has("neural_tolerance")) {
    const auto v = s.numbers("neural_tolerance", kNumAxes, "mm or deg (X Y Z A C)", 1e-9, 1e3);
    for (int a = 0; a < kNumAxes; ++a)
      o.neural_tolerance[static_cast<std::size_t>(a)] = v[static_cast<std::size_t>(a)];
  }
  o.downstream = s.choice("downstream", "analytic", {"analytic", "neural"}) == "neural"
                     ? IkDownstream::kNeural
                     : IkDownstream::kAnalytic;
  if (s.has("model")) {
    const std::string rel = s.string("model", "");
    if (rel.empty()) throw s.error("model", "is empty: name a model file written by gcpipe train-ik, or drop the key");
    o.model = s.resolve(rel);
    if (!std::filesystem::is_regular_file(o.model))
      throw s.error("model", "'" + rel + "': no such file (" + o.model.string() +
                                 "; the path is relative to the config file)");
  }
  return o;
}

std::optional<neural::NeuralIk> load_ik_model(const IkOptions& o, const std::string& machine_name) {
  if (o.model.empty()) return std::nullopt;
  std::optional<neural::NeuralIk> model;
  try {
    model.emplace(neural::NeuralIk::load(o.model));
  } catch (const std::exception& e) {
    throw ConfigError(std::string("ik.model: ") + e.what());
  }
  if (model->provenance().machine != machine_name)
    throw ConfigError("ik.model: " + o.model.string() + " was trained for machine '" +
                      model->provenance().machine + "', the config is for '" + machine_name +
                      "': train one with gcpipe train-ik --config <this config>");
  return model;
}

IkStage::IkStage(const MachineKinematics& model, IkOptions options, Axes initial_joints,
                 const neural::NeuralIk* neural)
    : model_(model), options_(options), neural_(neural), previous_(initial_joints) {}

bool IkStage::input_from_block(const ResolvedBlock& b, IkInput& in) const {
  switch (b.motion) {
    case Motion::kRapid:
    case Motion::kLinear:
    case Motion::kArcCW:
    case Motion::kArcCCW:
      break;
    default:
      return false;  // no end point of its own (G4, a state change, an unexpanded G275)
  }
  in.line = b.line;
  in.tool_length = b.tool_length_active ? b.tool_length : model_.tool_length;
  in.axes = b.target;
  if (!b.tcp) {
    in.mode = IkInputMode::kMachineAxes;
    return true;
  }
  in.tip = {b.target[kX], b.target[kY], b.target[kZ]};
  if (b.tool_vector_mode) {
    // G43.5: the program gives the tool axis, not A C; the IK chooses them (the block's A C
    // are only the state carried over from before and mean nothing here).
    in.mode = IkInputMode::kToolVector;
    in.tool_vector = b.tool_vector;
  } else if (options_.resolve_orientation == IkInputMode::kToolVector) {
    in.mode = IkInputMode::kToolVector;
    in.tool_vector = tool_axis(model_, b.target[kA], b.target[kC]);
  } else {
    in.mode = IkInputMode::kTcpAngles;
  }
  return true;
}

IkPoint IkStage::solve(const IkInput& in) {
  IkPoint p;
  p.line = in.line;
  p.mode = in.mode;
  IkResult r;
  switch (in.mode) {
    case IkInputMode::kTcpAngles:
      r = inverse_kinematics_ac(model_, in.tip, in.axes[kA], in.axes[kC], in.tool_length);
      p.pose = {in.tip, tool_axis(model_, in.axes[kA], in.axes[kC])};
      break;
    case IkInputMode::kToolVector:
      p.pose = {in.tip, in.tool_vector};
      r = inverse_kinematics(model_, p.pose, previous_, in.tool_length);
      break;
    case IkInputMode::kMachineAxes: {
      r.joints = in.axes;
      bool finite = true;
      for (double v : in.axes) finite = finite && std::isfinite(v);
      if (!finite) {
        r.status = IkStatus::kFailed;
        r.flags = kIkUnreachable;
      } else if (joints_outside_travel(model_, in.axes) != 0) {
        r.status = IkStatus::kFailed;
        r.flags = kIkTravelLimit;
      }
      p.pose = forward_kinematics(model_, in.axes, in.tool_length);
      break;
    }
  }
  p.joints = r.joints;
  p.status = r.status;
  p.flags = r.flags;
  if (neural_ != nullptr && (r.flags & kIkUnreachable) == 0) run_neural(p, in.tool_length);
  // A failed point does not become the reference for the next one only if it is unusable: an
  // out-of-travel answer is still the continuous one, an unreachable input has no joints.
  if ((p.flags & kIkUnreachable) == 0) previous_ = p.joints;
  account(p);
  return p;
}

bool IkStage::step(const ResolvedBlock& block, IkPoint& out) {
  IkInput in;
  if (!input_from_block(block, in)) return false;
  out = solve(in);
  return true;
}

void IkStage::run_neural(IkPoint& p, double tool_length) const {
  // With the tool along the C axis (the analytic IK held C, or machine axes at A = 0 as in every
  // three-axis program) every C is a right answer and the neural C net's is as arbitrary: a C
  // half a turn away puts the machine's X Y elsewhere for the same tool pose (tens of mm), a
  // difference of choice, not of accuracy. There the position nets are compared at the analytic
  // A C, and the point is marked outside the rotary nets' envelope.
  const Vec3& u = p.pose.axis;
  const double tilt_deg = std::atan2(std::hypot(u[0], u[1]), u[2]) * 180.0 / std::numbers::pi;
  const bool c_undefined = (p.flags & kIkCKeptAtSingularity) != 0 ||
                           (p.mode == IkInputMode::kMachineAxes && tilt_deg <= model_.c_hold_tilt);
  neural::NeuralIkPrediction n =
      p.mode == IkInputMode::kTcpAngles || c_undefined
          ? neural_->predict_linear(p.pose, tool_length, p.joints[kA], p.joints[kC])
          : neural_->predict(p.pose, tool_length, p.joints);
  // Whether the inputs really left the training envelope, before the C bit is added for the
  // undefined-C case: that case is a fact about the pose, not a doubt about the nets, so it is
  // flagged but does not degrade the point (a three-axis program would be all "degraded").
  const bool really_outside = n.outside_envelope != 0;
  if (c_undefined) n.outside_envelope |= static_cast<neural::EnvelopeBits>(1u << kC);
  p.has_neural = true;
  p.neural_joints = n.joints;
  std::uint32_t flags = 0;
  if (!n.finite) {
    flags |= kIkNeuralFailed;
  } else {
    for (int a = 0; a < kNumAxes; ++a) {
      const auto i = static_cast<std::size_t>(a);
      if (!(std::abs(n.joints[i] - p.joints[i]) <= options_.neural_tolerance[i]))
        flags |= kIkNeuralDiverged;
    }
  }
  if (n.outside_envelope != 0) flags |= kIkNeuralOutsideEnvelope;
  p.flags |= flags;
  const std::uint32_t degrading = really_outside ? flags : flags & ~static_cast<std::uint32_t>(kIkNeuralOutsideEnvelope);
  if (degrading != 0 && p.status == IkStatus::kOk) p.status = IkStatus::kDegraded;
}

void IkStage::account(const IkPoint& p) {
  IkSummary& s = summary_;
  ++s.points;
  switch (p.status) {
    case IkStatus::kOk: ++s.ok; break;
    case IkStatus::kDegraded: ++s.degraded; break;
    case IkStatus::kFailed:
      ++s.failed;
      if (s.first_failed_line == 0) s.first_failed_line = p.line;
      break;
  }
  for (int bit = 0; bit < 16; ++bit)
    if (p.flags & (1u << bit)) ++s.flag_counts[bit];
  if ((p.flags & kIkNeuralOutsideEnvelope) != 0 && p.status == IkStatus::kOk) ++s.envelope_flag_only;
  if (p.has_neural && (p.flags & kIkNeuralFailed) == 0) {
    ++s.neural_points;
    for (std::size_t a = 0; a < kNumAxes; ++a) {
      const double d = std::abs(p.neural_joints[a] - p.joints[a]);
      s.neural_max_abs_diff[a] = std::max(s.neural_max_abs_diff[a], d);
      s.neural_sum_sq_diff[a] += d * d;
    }
  }
}

std::string format_summary(const IkSummary& s, bool with_neural) {
  char buf[512];
  std::string out;
  std::snprintf(buf, sizeof buf, "ik: %llu points: %llu ok, %llu degraded, %llu failed",
                static_cast<unsigned long long>(s.points), static_cast<unsigned long long>(s.ok),
                static_cast<unsigned long long>(s.degraded),
                static_cast<unsigned long long>(s.failed));
  out += buf;
  if (s.failed > 0) {
    std::snprintf(buf, sizeof buf, " (first failed at line %llu)",
                  static_cast<unsigned long long>(s.first_failed_line));
    out += buf;
  }
  for (int bit = 0; bit < 16; ++bit) {
    if (s.flag_counts[bit] == 0) continue;
    std::snprintf(buf, sizeof buf, "\nik: flag %s: %llu",
                  ik_flags_to_string(1u << bit).c_str(),
                  static_cast<unsigned long long>(s.flag_counts[bit]));
    out += buf;
    if ((1u << bit) == kIkNeuralOutsideEnvelope && s.envelope_flag_only > 0) {
      std::snprintf(buf, sizeof buf, " (%llu of them ok: the tool is along C there, any C is right and the neural C "
                    "is not compared; the flag only informs)",
                    static_cast<unsigned long long>(s.envelope_flag_only));
      out += buf;
    }
  }
  if (!with_neural) {
    out += "\nik: no neural model given (--model): neural columns empty";
    return out;
  }
  std::snprintf(buf, sizeof buf, "\nik: neural on %llu points", 
                static_cast<unsigned long long>(s.neural_points));
  out += buf;
  if (s.neural_points == 0) return out;
  for (int a = 0; a < kNumAxes; ++a) {
    const auto i = static_cast<std::size_t>(a);
    std::snprintf(buf, sizeof buf, "\nik: neural - analytic %c: max |d| %.6g, rms %.6g %s",
                  kAxisLetters[a], s.neural_max_abs_diff[i],
                  std::sqrt(s.neural_sum_sq_diff[i] / static_cast<double>(s.neural_points)),
                  a < kA ? "mm" : "deg");
    out += buf;
  }
  return out;
}

}  // namespace gcpipe
