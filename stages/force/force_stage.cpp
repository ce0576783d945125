// The force stage in the pipeline (between trochoid and ik, so that the compensation works on the
// program it plans): without a `force:` section in the config it hands every block on untouched
// and reports nothing. With one, it keeps the program, and at its end sweeps it through the
// stock (stages/force/README.md): report.json's `force` object and two figures. With
// `target_force` set it plans the feeds: it then holds the program back (the feed of a block
// depends on the engagement ahead of it) and emits it at the end with each feed block's F set,
// capped by what the drives allow (drive_limits.hpp). Either way the program is timed by the
// interpolate stage's Interpolator as the simulate stage runs it, before and after planning. With
// `spindle_model` (a model of gcpipe train-spindle) it predicts the spindle's power or current along
// the program as emitted, sampled on that interpolator's clock (README sec. 8b).
#include <cstdio>
#include <optional>
#include <variant>

#include <nlohmann/json.hpp>

#include "drive_limits.hpp"
#include "force_options.hpp"
#include "force_product.hpp"
#include "force_report.hpp"
#include "path_force.hpp"
#include "simulate.hpp"
#include "spindle_model.hpp"
#include "stage.hpp"

namespace gcpipe {
namespace {

using pipeline::Emitter;

constexpr const char* kDeflectionNeedsRatios =
    "not computed: Kienzle's kc1/mc give the tangential force only; the deflection needs the radial force: "
    "state material.radial_to_tangential, axial_to_tangential and ratio_source, or use a mechanistic set "
    "(stages/force/README.md sec. 1b)";

struct HeldDiagnostic {
  Diagnostic diag;
  DiagnosticKind kind;
};

class ForceStage final : public pipeline::Stage {
 public:
  explicit ForceStage(const pipeline::StageContext& c) : machine_(c.config->machine) {
    enabled_ = c.config->root.has("force");
    if (!enabled_) return;
    section_ = c.config->root.section("force");
    options_ = force::load_force_options(section_);
    planning_ = options_.target_force > 0;
    drives_ = drives_model(*c.config);
    if (!options_.spindle_model.empty()) spindle_model_ = load_spindle_model();
  }

  bool block(const ResolvedBlock& b, Emitter& out) override {
    if (!enabled_) return out.block(b);
    program_.push_back(b);
    if (planning_) {
      held_.emplace_back(program_.size() - 1);
      return true;
    }
    return out.block(b);
  }

  bool diagnostic(const Diagnostic& d, DiagnosticKind kind, Emitter& out) override {
    if (!planning_) return out.diagnostic(d, kind);
    held_.emplace_back(HeldDiagnostic{d, kind});
    return true;
  }

  bool finish(bool complete, Emitter& out) override {
    if (!enabled_ || !complete) return release(program_, out);
    if (!resolve_tool()) return release(program_, out);
    const auto moves = force::with_spindle_speed(force::moves_from_blocks(program_), options_.spindle_speed);
    force::ForceOptions o = options_;
    if (planning_ && o.sample_spacing == 0) o.sample_spacing = 0.1;  // README sec. 6
    auto stock = force::make_stock(moves, o);
    before_ = force::sweep_path(moves, o, std::move(stock));
    if (!planning_) {
      before_run_ = run_on_drives(program_);
      predict_spindle(program_);
      hand_on(before_, out);
      return true;
    }
    before_run_ = run_on_drives(program_);
    const auto by_force = force::apply_feeds(program_, moves, force::plan_feeds(moves, before_, o));
    const auto planned = force::limit_feeds_to_drives(by_force, before_run_.blocks);
    count_drive_limited(by_force, planned);
    force_only_cycle_ = run_on_drives(by_force).cycle_time;  // what the drives' caps cost
    after_run_ = run_on_drives(planned);
    const auto moves_after = force::with_spindle_speed(force::moves_from_blocks(planned), options_.spindle_speed);
    o.target_force = 0;
    auto stock_after = force::make_stock(moves_after, o);
    after_ = force::sweep_path(moves_after, o, std::move(stock_after));
    predict_spindle(planned);
    hand_on(after_, out);
    return release(planned, out);
  }

  void report(pipeline::ReportContext& r) const override {
    if (!enabled_) return;
    if (!failure_.empty()) {
      (*r.json)["force"] = {{"failure", failure_}};
      return;
    }
    (*r.json)["force"] = report_json();
    *r.text += report_line();
    if (r.dir.empty() || before_.samples.empty()) return;
    const force::PathForce& shown = planning_ ? after_ : before_;
    const std::string what = r.input_base + (planning_ ? ": force with the planned feeds" : ": cutting force");
    const bool resultant = options_.material.resultant_known();
    force::write_force_path_png(r.dir / "plots" / "force_path.png", shown, what, resultant);
    force::write_force_time_png(r.dir / "plots" / "force_time.png", shown, what, resultant);
    r.files->push_back("plots/force_path.png");
    r.files->push_back("plots/force_time.png");
    if (!spindle_.value.empty()) {
      write_spindle_figure(r.dir / "plots" / "spindle_prediction.png", r.input_base);
      r.files->push_back("plots/spindle_prediction.png");
    }
  }

  std::string failure() const override { return failure_; }

 private:
  /// The tool's diameter from the tool table when the config leaves it out.
  bool resolve_tool() {
    if (options_.tool.diameter > 0) return true;
    for (const ResolvedBlock& b : program_) {
      if (b.motion != Motion::kLinear && b.motion != Motion::kArcCW && b.motion != Motion::kArcCCW) continue;
      const auto it = machine_.tools.find(b.tool_in_spindle);
      if (it != machine_.tools.end() && it->second.diameter > 0) {
        options_.tool.diameter = it->second.diameter;
        return true;
      }
      failure_ = "force: no tool_diameter in " + section_.file() + " and tool T" + std::to_string(b.tool_in_spindle) +
                 " has no diameter in the tool table";
      return false;
    }
    return true;  // nothing cuts
  }

  /// The interpolator as the simulate stage builds it (machine limits, the `interpolate` section,
  /// Ts from servo.drives); a config without a drives file gets no acc/dec (Ts = 0).
  static simulate::Model drives_model(const PipelineConfig& pc) {
    if (pc.root.has("servo")) return simulate::load_model(pc);
    simulate::Model m;
    m.kin = pc.machine.kinematics;
    m.interp = interpolate::load_interpolate_options(pc.root.section("interpolate"));
    m.interp.max_velocity = m.kin.max_velocity;
    m.interp.max_acceleration = m.kin.max_acceleration;
    return m;
  }

  /// The interpolator's options and the machine's start for `blocks`, as the simulate stage
  /// builds them; nullopt when no block moves.
  std::optional<std::pair<interpolate::InterpolateOptions, Axes>> interpolator_for(const std::vector<ResolvedBlock>& blocks) const {
    std::size_t first = 0;
    while (first < blocks.size() && blocks[first].motion == Motion::kNone) ++first;
    if (first == blocks.size()) return std::nullopt;
    interpolate::InterpolateOptions io = drives_.interp;
    io.kinematics = &drives_.kin;
    return std::pair{io, simulate::machine_start(drives_.kin, blocks[first], simulate::tool_length_of(drives_, blocks[first]))};
  }

  /// `blocks` through the interpolator from where the simulate stage starts the machine.
  force::DriveRun run_on_drives(const std::vector<ResolvedBlock>& blocks) const {
    const auto interp = interpolator_for(blocks);
    if (!interp) return {std::vector<force::BlockDrive>(blocks.size()), 0, 0, ""};
    return force::run_on_drives(blocks, interp->first, interp->second);
  }

  /// The model of `force.spindle_model`, refused (ConfigError naming the key) when this stage
  /// cannot supply its channels or sample on its period.
  force::SpindleModel load_spindle_model() const {
    force::SpindleModel m = force::read_spindle_model(options_.spindle_model);
    const std::string file = options_.spindle_model.string();
    if (const std::string why = force::unsupplied_channels(m); !why.empty())
      throw section_.error("spindle_model", file + ": " + why);
    const double ratio = m.period / drives_.interp.period;
    if (std::abs(ratio - std::round(ratio)) > 1e-6 * ratio)
      throw section_.error("spindle_model", file + ": its sample period " + std::to_string(m.period) +
                                                " s is not a whole number of interpolation periods (" +
                                                std::to_string(drives_.interp.period) + " s)");
    return m;
  }

  /// The spindle model's quantity along `blocks` (the program as emitted) on the interpolator's clock.
  void predict_spindle(const std::vector<ResolvedBlock>& blocks) {
    if (!spindle_model_) return;
    const auto interp = interpolator_for(blocks);
    if (!interp) return;
    spindle_inputs_ = force::sample_program_inputs(blocks, interp->first, interp->second, spindle_model_->period,
                                                   options_.spindle_speed);
    if (!spindle_inputs_.failure.empty()) return;
    spindle_ = force::predict_along_program(*spindle_model_, spindle_inputs_);
  }

  nlohmann::ordered_json spindle_json() const {
    const force::SpindleModel& m = *spindle_model_;
    nlohmann::ordered_json j = {{"file", options_.spindle_model.string()}, {"quantity", m.quantity},
                                {"column", m.column}, {"unit", m.unit}, {"data", m.data},
                                {"regressors", m.regressors}, {"verify_fpe_percent", m.verify_fpe},
                                {"period_s", m.period}};
    if (!spindle_inputs_.failure.empty()) {
      j["failure"] = spindle_inputs_.failure;
      return j;
    }
    j.update({{"samples", spindle_.value.size()}, {"cutting_samples", spindle_.cutting_samples},
              {"mean_in_cutting", spindle_.mean_cutting}, {"max_in_cutting", spindle_.max_cutting},
              {"max_whole_program", spindle_.max_program},
              {"training_range", {m.output_min, m.output_max}},
              {"prediction_within_training_range", spindle_.min_program >= m.output_min && spindle_.max_program <= m.output_max},
              {"inputs_outside_training", spindle_.outside_training}});
    return j;
  }

  std::string spindle_line() const {
    if (!spindle_model_) return "";
    if (!spindle_inputs_.failure.empty()) return "  spindle model: not run (" + spindle_inputs_.failure + ")\n";
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  "  spindle %s (NNOE of %s, %s): cutting mean %.4g, max %.4g over %zu samples of %g s; "
                  "trained range %.4g..%.4g%s\n",
                  spindle_model_->quantity.c_str(), spindle_model_->column.c_str(), spindle_model_->regressors.c_str(),
                  spindle_.mean_cutting, spindle_.max_cutting, spindle_.cutting_samples, spindle_model_->period,
                  spindle_model_->output_min, spindle_model_->output_max,
                  spindle_.outside_training.empty() ? "" : "; inputs outside the training range (report.json)");
    return buf;
  }

  void write_spindle_figure(const std::filesystem::path& png, const std::string& input) const {
    const force::SpindleModel& m = *spindle_model_;
    char note[400];
    std::snprintf(note, sizeof note, "%s, verification FPE %.1f %%; %s", m.regressors.c_str(), m.verify_fpe, m.data.c_str());
    force::write_spindle_prediction_png(png, spindle_.value, spindle_inputs_.cutting, spindle_inputs_.feed, m.period,
                                        input + ": predicted spindle " + m.quantity + " (" + m.column + ")", note,
                                        m.quantity == "current" ? "current [A]" : m.column + " [as recorded]");
  }

  /// How many feed blocks the drives slowed below the force's feed, and by which rule.
  void count_drive_limited(const std::vector<ResolvedBlock>& by_force, const std::vector<ResolvedBlock>& planned) {
    for (std::size_t i = 0; i < planned.size(); ++i) {
      const double velocity_cap = std::min(by_force[i].feed, before_run_.blocks[i].max_feed);
      if (velocity_cap < by_force[i].feed) ++velocity_limited_;
      if (planned[i].feed < velocity_cap * (1 - 1e-12)) ++reach_limited_;
    }
  }

  /// The force of the program as emitted, for the compensate stage's error budget (which needs the
  /// deflection, so nothing is handed on when the radial force is not known).
  void hand_on(const force::PathForce& p, Emitter& out) const {
    if (!options_.material.resultant_known()) return;
    auto profile = std::make_shared<force::ForceProfile>();
    profile->force = p;
    out.product(profile);
  }

  /// Emits what was held back, in order, with the blocks of `blocks` (the program, or planned).
  bool release(const std::vector<ResolvedBlock>& blocks, Emitter& out) {
    bool go = true;
    for (const auto& item : held_) {
      if (const auto* i = std::get_if<std::size_t>(&item)) go = out.block(blocks[*i]) && go;
      else {
        const auto& d = std::get<HeldDiagnostic>(item);
        go = out.diagnostic(d.diag, d.kind) && go;
      }
    }
    held_.clear();
    return go;
  }

  static nlohmann::ordered_json timing_json(const force::DriveRun& run) {
    nlohmann::ordered_json j = {{"cycle_time_s", run.cycle_time}, {"feed_move_time_s", run.feed_move_time}};
    if (!run.failure.empty()) j["failure"] = run.failure;
    return j;
  }

  nlohmann::ordered_json summary(const force::PathForce& p, const force::DriveRun& run) const {
    double mean = 0, tangential = 0, power = 0, ae = 0, ap = 0;
    for (const auto& s : p.samples) {
      mean += s.mean_force, tangential += s.mean_tangential, power += s.power;
      ae = std::max(ae, s.radial_depth), ap = std::max(ap, s.axial_depth);
    }
    const double n = std::max<double>(1, static_cast<double>(p.samples.size()));
    // cutting_time_s: feed-move length / feed, as before; interpolated: the interpolate stage's time.
    nlohmann::ordered_json j = {{"samples", p.samples.size()}, {"cutting_time_s", p.cutting_time},
                                {"interpolated", timing_json(run)}};
    if (options_.material.resultant_known())
      j.update({{"max_mean_force_N", p.max_mean_force}, {"average_mean_force_N", mean / n},
                {"max_peak_force_N", p.max_peak_force}});
    j.update({{"max_mean_tangential_force_N", p.max_mean_tangential}, {"average_mean_tangential_force_N", tangential / n},
              {"max_torque_Nm", p.max_torque}, {"max_power_W", p.max_power}, {"average_power_W", power / n},
              {"max_ae_mm", ae}, {"max_ap_mm", ap}});
    if (options_.material.resultant_known()) j["max_deflection_um"] = 1e3 * p.max_deflection;
    else j["deflection"] = kDeflectionNeedsRatios;
    return j;
  }

  /// What the report says of a Kienzle material: its row, the table's copy, the stated ratios.
  nlohmann::ordered_json kienzle_json() const {
    const force::Material& m = options_.material;
    const force::KienzleGroup& g = *m.group;
    const auto& table = force::embedded_kienzle_table();
    nlohmann::ordered_json j = {{"vdi3323_group", g.group}, {"iso", g.iso}, {"description", g.material},
                                {"condition", g.condition}, {"kc1_N_mm2", g.kc1}, {"mc", g.mc}};
    if (!m.grade.empty()) j["grade"] = m.grade;
    j["table"] = {{"file", table.from}, {"sha256", table.sha256}, {"source", force::kienzle_source()}};
    if (m.ratios)
      j["ratios"] = {{"radial_to_tangential", m.ratios->radial}, {"axial_to_tangential", m.ratios->axial},
                     {"source", m.ratios->source}};
    else
      j["ratios"] = "not stated: tangential force, torque and power only";
    return j;
  }

  nlohmann::ordered_json report_json() const {
    nlohmann::ordered_json j = {{"material", options_.material.source}};
    if (options_.material.group) j["kienzle"] = kienzle_json();
    if (spindle_model_) j["spindle_model"] = spindle_json();
    j["tool"] = {{"diameter_mm", options_.tool.diameter}, {"flutes", options_.tool.flutes},
                 {"stickout_mm", options_.tool.stickout}, {"effective_diameter_mm", options_.tool.effective_diameter()}};
    j["programmed"] = summary(before_, before_run_);
    if (planning_) {
      j["planned"] = summary(after_, after_run_), j["target_force_N"] = options_.target_force;
      j["drive_limited_blocks"] = {{"velocity", velocity_limited_}, {"reach", reach_limited_}};
      j["force_only_cycle_time_s"] = force_only_cycle_;  // the force's feeds without the drives' caps
    }
    return j;
  }

  std::string report_line() const {
    char buf[480];
    if (options_.material.resultant_known())
      std::snprintf(buf, sizeof buf, "  force: max mean %.0f N, peak %.0f N, deflection %.1f um, cutting %.1f s\n",
                    before_.max_mean_force, before_.max_peak_force, 1e3 * before_.max_deflection, before_.cutting_time);
    else
      std::snprintf(buf, sizeof buf,
                    "  force: max mean tangential %.0f N, torque %.1f N m, power %.0f W, cutting %.1f s "
                    "(no deflection: radial and axial forces not stated)\n",
                    before_.max_mean_tangential, before_.max_torque, before_.max_power, before_.cutting_time);
    std::string s = buf;
    if (planning_) {
      std::snprintf(buf, sizeof buf, "  force-aware feed (target %.0f N): max mean %.0f N, peak %.0f N, cutting %.1f s\n",
                    options_.target_force, after_.max_mean_force, after_.max_peak_force, after_.cutting_time);
      s += buf;
      std::snprintf(buf, sizeof buf,
                    "  cycle (interpolator): programmed %.2f s, planned %.2f s; feed moves %.2f s -> %.2f s "
                    "(length/feed %.2f s -> %.2f s); drives lowered %zu feeds (velocity), %zu (reach), "
                    "uncapped %.2f s\n",
                    before_run_.cycle_time, after_run_.cycle_time, before_run_.feed_move_time, after_run_.feed_move_time,
                    before_.cutting_time, after_.cutting_time, velocity_limited_, reach_limited_, force_only_cycle_);
      s += buf;
    } else {
      std::snprintf(buf, sizeof buf, "  cycle (interpolator): %.2f s, feed moves %.2f s\n", before_run_.cycle_time,
                    before_run_.feed_move_time);
      s += buf;
    }
    return s + spindle_line();
  }

  MachineConfig machine_;
  bool enabled_ = false, planning_ = false;
  Config section_;
  force::ForceOptions options_;
  std::vector<ResolvedBlock> program_;
  std::vector<std::variant<std::size_t, HeldDiagnostic>> held_;
  force::PathForce before_, after_;
  simulate::Model drives_;
  force::DriveRun before_run_, after_run_;
  std::size_t velocity_limited_ = 0, reach_limited_ = 0;
  double force_only_cycle_ = 0;
  std::optional<force::SpindleModel> spindle_model_;
  force::ProgramInputs spindle_inputs_;
  force::SpindlePrediction spindle_;
  std::string failure_;
};

}  // namespace

pipeline::StageInfo force_stage() {
  return {"force", "trochoid",
          "cutting force along the path (mechanistic model on a height-field stock), deflection, force-aware feed",
          pipeline::Port::kBlocks, pipeline::Port::kBlocks,
          [](const pipeline::StageContext& c) -> std::unique_ptr<pipeline::Stage> {
            return std::make_unique<ForceStage>(c);
          },
          "gcpipe_planned"};
}

}  // namespace gcpipe
