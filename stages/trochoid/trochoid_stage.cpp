// The trochoid stage in the pipeline: every G275 cycle expanded into its tool path, every other
// block copied; a cycle that cannot be machined is rejected at its line and replaced by skip moves.
#include <cmath>
#include <cstdio>
#include <string>

#include <nlohmann/json.hpp>

#include "parse.hpp"
#include "stage.hpp"
#include "trochoid.hpp"
#include "trochoid_report.hpp"

namespace gcpipe {
namespace {

using pipeline::Emitter;

class TrochoidStage final : public pipeline::Stage {
 public:
  explicit TrochoidStage(const pipeline::StageContext& c)
      : expander_(load_trochoid_options(c.config->root.section("trochoid"))), file_(c.file), log_(*c.log),
        strict_(c.strict || load_parse_options(c.config->root.section("parse")).strict),
        max_machine_time_(max_machine_time_of(*c.config)) {}

  bool block(const ResolvedBlock& b, Emitter& out) override {
    expanded_.clear();
    parts_.clear();
    if (b.motion == Motion::kTrochoidSlot && past_machine_time(b)) return refuse(b, out);
    const auto st = expander_.step(b, file_, expanded_, diag_, &parts_);
    bool go = true;
    if (!st.ok()) {
      ++cycles_rejected_;
      log_.report(diag_);
      go = out.diagnostic(diag_, DiagnosticKind::kBlockRejected);
    } else if (st.code == TrochoidExpander::Status::Code::kExpanded) {
      keep_for_figure(b);
    }
    for (const ResolvedBlock& e : expanded_) go = out.block(e) && go;
    return go && !(strict_ && !st.ok());
  }

  void report(pipeline::ReportContext& r) const override {
    double max_engagement = 0, max_ae = 0;
    if (cycles_ > 0 && analysed()) draw_engagement(r, max_engagement, max_ae);
    (*r.json)["trochoid"] = {{"cycles_expanded", cycles_},
                             {"cycles_rejected", cycles_rejected_},
                             {"max_engagement_deg", max_engagement},
                             {"max_ae_mm", max_ae}};
    if (!analysed()) (*r.json)["trochoid"]["engagement_not_analysed"] = not_analysed_reason();
    if (cycles_ + cycles_rejected_ == 0) return;
    if (!analysed()) {
      *r.text += "  trochoid: " + std::to_string(cycles_) + " G275 cycles expanded, " +
                 std::to_string(cycles_rejected_) + " rejected; " + not_analysed_reason() + "\n";
      return;
    }
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "  trochoid: %llu G275 cycles expanded, %llu rejected; max radial engagement %.1f deg (ae %.3f mm)\n",
                  static_cast<unsigned long long>(cycles_), static_cast<unsigned long long>(cycles_rejected_),
                  max_engagement, max_ae);
    *r.text += buf;
  }
  std::uint64_t rejected() const override { return cycles_rejected_; }
  std::string failure() const override { return failure_; }

 private:
  // The bound the simulation and compensation stop at (compensate.max_machine_time, read with
  // the same default and range as stages/compensate): a program the cycles alone take past it is
  // refused before they are expanded, not after minutes of expansion, engagement analysis and
  // simulation.
  static double max_machine_time_of(const PipelineConfig& config) {
    return config.root.section("compensate").number("max_machine_time", 3600, "s", 1, 1e6);
  }

  // Adds the cycle's lower-bound time to the program's; true when the sum is past the bound.
  bool past_machine_time(const ResolvedBlock& cycle) {
    if (!failure_.empty()) return true;  // the program is refused already: no later cycle is expanded
    cycle_seconds_ += expander_.feed_time_lower_bound(cycle);
    return cycle_seconds_ > max_machine_time_;
  }

  // The cycle is not expanded: skip moves keep the rest of the program where it expects to be,
  // its line is rejected, and the first such cycle makes the program fail with the reason.
  bool refuse(const ResolvedBlock& cycle, Emitter& out) {
    ++cycles_rejected_;
    char msg[400];
    std::snprintf(msg, sizeof msg,
                  "G275 not expanded: the G275 cycles up to this line take at least %.0f s at their feeds, more than "
                  "compensate.max_machine_time (%.0f s); the program is refused before its cycles are expanded: "
                  "split it, or raise compensate.max_machine_time in the pipeline config",
                  cycle_seconds_, max_machine_time_);
    diag_ = Diagnostic{file_, cycle.line, 0, Severity::kError, msg};
    if (failure_.empty()) failure_ = file_ + ":" + std::to_string(cycle.line) + ": " + msg;
    log_.report(diag_);
    bool go = out.diagnostic(diag_, DiagnosticKind::kBlockRejected);
    expander_.skip(cycle, expanded_);
    for (const ResolvedBlock& e : expanded_) go = out.block(e) && go;
    return go && !strict_;
  }

  // Only the expanded cycles are kept (for the engagement figure), never the whole program.
  void keep_for_figure(const ResolvedBlock& cycle) {
    ++cycles_;
    expanded_blocks_ += expanded_.size();
    if (too_many_for_report_ || expanded_blocks_ > expander_.options().max_report_blocks) {
      too_many_for_report_ = true;  // memory and report time stay bounded: nothing more is kept
      release_figure();
      return;
    }
    if (tool_diameter_ == 0) tool_diameter_ = cycle.slot.tool_diameter;
    outlines_.push_back(slot_outline(cycle.slot));
    figure_blocks_.insert(figure_blocks_.end(), expanded_.begin(), expanded_.end());
    figure_parts_.insert(figure_parts_.end(), parts_.begin(), parts_.end());
  }

  void release_figure() {
    std::vector<ResolvedBlock>().swap(figure_blocks_);
    std::vector<TrochoidPart>().swap(figure_parts_);
    std::vector<std::vector<Point2>>().swap(outlines_);
  }

  // A refused program is not analysed either: its figure would show a part of it.
  bool analysed() const { return !too_many_for_report_ && failure_.empty(); }

  std::string not_analysed_reason() const {
    if (!failure_.empty()) return "engagement not analysed and not drawn: the program is refused (" + failure_ + ")";
    return "engagement not analysed and not drawn: the G275 cycles expand into " + std::to_string(expanded_blocks_) +
           " blocks, more than trochoid.max_report_blocks (" + std::to_string(expander_.options().max_report_blocks) +
           "); raise it to analyse them (the time grows with the square of cycles cut over one another)";
  }

  void draw_engagement(pipeline::ReportContext& r, double& max_engagement, double& max_ae) const {
    PathAnalysisOptions ao;
    ao.tool_radius = 0.5 * tool_diameter_;
    const PathAnalysis a = analyse_path(figure_blocks_, &figure_parts_, ao);
    max_engagement = a.max_angle * 180 / 3.14159265358979323846;
    max_ae = equivalent_ae(a.max_angle, ao.tool_radius);
    if (r.dir.empty()) return;
    if (r.progress) r.progress("drawing the trochoid engagement figure", 0, 0);
    char title[200];
    std::snprintf(title, sizeof title, "%s: G275 tool centre path, D%g mm", r.input_base.c_str(), tool_diameter_);
    write_engagement_png(r.dir / "plots" / "trochoid_engagement.png", a, ao.tool_radius, title, outlines_);
    r.files->push_back("plots/trochoid_engagement.png");
  }

  TrochoidExpander expander_;
  std::string file_;
  pipeline::DiagnosticLog& log_;
  bool strict_;
  double max_machine_time_;   //!< [s] compensate.max_machine_time
  double cycle_seconds_ = 0;  //!< [s] lower bound of the program's G275 cycles so far
  std::string failure_;
  std::vector<ResolvedBlock> expanded_;
  std::vector<TrochoidPart> parts_;
  Diagnostic diag_;
  std::uint64_t cycles_ = 0, cycles_rejected_ = 0;
  double tool_diameter_ = 0;
  std::uint64_t expanded_blocks_ = 0;
  bool too_many_for_report_ = false;
  std::vector<ResolvedBlock> figure_blocks_;
  std::vector<TrochoidPart> figure_parts_;
  std::vector<std::vector<Point2>> outlines_;
};

}  // namespace

pipeline::StageInfo trochoid_stage() {
  return {"trochoid", "parse", "G275 trochoidal slot cycles expanded into G1/G2/G3 tool paths (seed 000 eq. 6)",
          pipeline::Port::kBlocks, pipeline::Port::kBlocks,
          [](const pipeline::StageContext& c) -> std::unique_ptr<pipeline::Stage> {
            return std::make_unique<TrochoidStage>(c);
          },
          "gcpipe_toolpath"};
}

}  // namespace gcpipe
