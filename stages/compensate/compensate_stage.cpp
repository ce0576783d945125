// The compensate stage in the pipeline: the program's simulation in (from the simulate stage in
// the same process, or computed here from the blocks when this stage runs alone, as a DDS node),
// the compensated program out as G-code text, and the simulation of that text as written, read
// back by the parser, for the "after" figures.
#include <algorithm>
#include <cstdio>
#include <deque>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "compensate_program.hpp"
#include "error_budget.hpp"
#include "force_product.hpp"
#include "parse.hpp"
#include "simulate_stage.hpp"
#include "simulation_report.hpp"

namespace gcpipe {
namespace {

using pipeline::Emitter;

/// compensated.nc read back block by block as the simulation asks for them: the parser is fed
/// line by line until the next motion block comes out, so the text's blocks (one a node, 464 bytes
/// each) are never all held. Blocks are asked for in order; a few are kept behind the newest.
class ReadBack {
 public:
  ReadBack(const ParseOptions& options, const MachineConfig& machine, std::string_view text)
      : parser_(options, machine, "compensated.nc"), text_(text) {
    sink_.block = [this](const ResolvedBlock& b) {
      if (b.motion != Motion::kNone) kept_.push_back(b);
      return true;
    };
    sink_.diagnostic = [](const Diagnostic& d) {
      if (d.severity == Severity::kError) throw std::runtime_error("compensated.nc does not read back: " + format(d));
      return true;
    };
  }

  /// Motion block i of the text; throws when the text has fewer (`expected` is the number
  /// written, for the message).
  const ResolvedBlock& at(std::size_t i, std::size_t expected) {
    if (i < first_) throw std::logic_error("compensated.nc read back out of order");
    while (first_ + kept_.size() <= i)
      if (!feed_line()) throw does_not_read_back(expected);
    while (first_ + kKeptBehind < i) kept_.pop_front(), ++first_;
    return kept_[i - first_];
  }

  /// All motion blocks of the text (reads it to the end).
  std::size_t count() {
    while (feed_line()) {
    }
    return first_ + kept_.size();
  }

  std::runtime_error does_not_read_back(std::size_t expected) {
    return std::runtime_error("compensated.nc does not read back as written (" + std::to_string(count()) +
                              " motion blocks for " + std::to_string(expected) + " points)");
  }

 private:
  static constexpr std::size_t kKeptBehind = 8;

  /// Feeds the next line (or, past the last, finishes the parse once); false when nothing is left.
  bool feed_line() {
    if (pos_ >= text_.size()) {
      if (finished_) return false;
      finished_ = true;
      parser_.finish(sink_);
      return true;
    }
    const std::size_t end = std::min(text_.find('\n', pos_), text_.size());
    std::string_view line = text_.substr(pos_, end - pos_);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos_ = end + 1;
    parser_.feed(line, sink_);
    return true;
  }

  Parser parser_;
  std::string_view text_;
  std::size_t pos_ = 0;
  bool finished_ = false;
  ParseSink sink_;
  std::deque<ResolvedBlock> kept_;
  std::size_t first_ = 0;  // index of kept_.front() among the text's motion blocks
};

class CompensateStage final : public pipeline::Stage {
 public:
  explicit CompensateStage(const pipeline::StageContext& c)
      : model_(compensate::load_model(*c.config)),
        options_(compensate::load_compensate_options(c.config->root.section("compensate"))),
        write_options_(load_write_options(c.config->root.section("write"))),
        parse_options_(load_parse_options(c.config->root.section("parse"))),
        machine_(c.config->machine),
        progress_(c.progress),
        collect_(std::find(c.stages.begin(), c.stages.end(), "simulate") == c.stages.end()) {}

  bool block(const ResolvedBlock& b, Emitter&) override {
    if (collect_ && blocks_.size() < options_.max_blocks) blocks_.push_back(b);
    else if (collect_) too_many_ = true;
    return true;
  }
  bool diagnostic(const Diagnostic&, DiagnosticKind, Emitter&) override { return true; }
  void product(const std::shared_ptr<const pipeline::Product>& p, Emitter&) override {
    if (auto s = std::dynamic_pointer_cast<const SimulatedProgram>(p)) simulated_ = s;
    if (auto f = std::dynamic_pointer_cast<const force::ForceProfile>(p)) force_ = f;
  }

  bool finish(bool complete, Emitter& out) override {
    if (!complete) return fail("the program did not arrive whole");
    if (too_many_) return fail("the program has more than compensate.max_blocks = " + std::to_string(options_.max_blocks) + " blocks");
    if (!simulated_) simulate_here();
    if (!simulated_->run.before) return fail("not simulated: " + simulated_->run.note);
    compensation_ = compensate::compensate_program(model_, options_, write_options_, simulated_->run, progress_);
    if (compensation_.text.empty()) return fail("no compensated program: " + compensation_.note);
    read_back(compensation_.text);
    // The text goes out before the slowed baseline is run, which needs only the program: on a
    // long program the text (tens of MB) would otherwise be held beside that simulation.
    const bool r = out.text(compensation_.text);
    std::string().swap(compensation_.text);  // emptied by the sinks; its memory too
    measure_slowed_baseline();
    return r;
  }

  void report(pipeline::ReportContext& r) const override {
    compensate::SimulationOutcome o;
    o.model = &model_;
    o.run = simulated_ ? &simulated_->run : nullptr;
    o.after = after_ ? &*after_ : nullptr;
    o.result = compensation_.result ? &*compensation_.result : nullptr;
    o.written_nodes = written_nodes_;
    o.slowed = slowed_ ? &*slowed_ : nullptr;
    o.skipped = failure_;
    compensate::report_simulation(r, o);
    report_error_budget(r);
  }
  std::string failure() const override { return failure_; }

 private:
  /// With a force stage upstream: its deflection beside the contour error (error_budget.hpp).
  void report_error_budget(pipeline::ReportContext& r) const {
    if (!force_ || !simulated_ || !simulated_->run.before || simulated_->run.program.empty()) return;
    const Axes& w = simulated_->run.program.front().work_origin;
    const auto b = compensate::error_budget(simulated_->run.before->series, force_->force, {w[0], w[1], w[2]});
    (*r.json)["error_budget"] = compensate::error_budget_json(b);
    char line[200];
    std::snprintf(line, sizeof line, "  error budget: tool deflection above the servo contour error in %.0f %% of the cutting time\n",
                  100 * b.deflection_dominates);
    *r.text += line;
    if (r.dir.empty()) return;
    compensate::plot_error_budget(r.dir / "plots" / "error_budget.png", b,
                                  r.input_base + ": servo contour error and tool deflection");
    r.files->push_back("plots/error_budget.png");
  }

  bool fail(std::string why) {
    failure_ = std::move(why);
    return true;
  }

  void simulate_here() {
    auto s = std::make_shared<SimulatedProgram>();
    s->run = simulate::simulate_program(model_, std::move(blocks_), compensate::run_bounds(options_), {}, progress_);
    simulated_ = s;
  }

  // The "after" figures are those of the text as written, rounding included: it is parsed back
  // (strict, in the writer's dialect) and simulated on the reference clock.
  void read_back(const std::string& text) {
    if (progress_) progress_("re-reading and simulating compensated.nc", 0, 0);
    ParseOptions po = parse_options_;
    po.strict = true;
    po.dialect = write_options_.dialect;
    po.decimal_point_increments = false;
    const auto& nodes = compensation_.result->nodes;
    const std::size_t points = nodes.size() - 1;
    ReadBack back(po, machine_, text);
    const simulate::BlockSource blocks{points, [&](std::size_t i) -> const ResolvedBlock& { return back.at(i, points); }};
    const auto& run = simulated_->run;
    after_ = simulate::evaluate(
        model_, *run.nominal, run.program, blocks, run.start,
        [&nodes](std::uint32_t i) { return nodes[std::min<std::size_t>(i + 1, nodes.size() - 1)].block; }, {}, true);
    if (back.count() != points) throw back.does_not_read_back(points);
    written_nodes_ = points;
  }

  // The original slowed to the compensated program's cycle time: what a sceptic compares with.
  void measure_slowed_baseline() {
    if (!options_.slowed_baseline || !compensation_.result || compensation_.result->nodes.empty()) return;
    if (progress_) progress_("simulating the original slowed to the compensated cycle time", 0, 0);
    const double target = static_cast<double>(compensation_.result->nodes.back().tick) * model_.interp.period;
    const double at_one = static_cast<double>(simulated_->run.nominal->raw.size()) * model_.interp.period;
    slowed_ = simulate::slowed_original(model_, simulated_->run.program, target, at_one, compensate::run_bounds(options_));
  }

  std::shared_ptr<const force::ForceProfile> force_;
  compensate::Model model_;
  compensate::CompensateOptions options_;
  WriteOptions write_options_;
  ParseOptions parse_options_;
  MachineConfig machine_;
  pipeline::Progress progress_;
  bool collect_;
  bool too_many_ = false;
  std::vector<ResolvedBlock> blocks_;
  std::shared_ptr<const SimulatedProgram> simulated_;
  compensate::ProgramCompensation compensation_;
  std::optional<simulate::Evaluation> after_;
  std::optional<simulate::SlowedBaseline> slowed_;
  std::uint64_t written_nodes_ = 0;
  std::string failure_;
};

}  // namespace

pipeline::StageInfo compensate_stage() {
  return {"compensate", "simulate",
          "learning pre-compensation against the simulated machine; compensated.nc and its figures",
          pipeline::Port::kBlocks, pipeline::Port::kGcode,
          [](const pipeline::StageContext& c) -> std::unique_ptr<pipeline::Stage> {
            return std::make_unique<CompensateStage>(c);
          },
          "gcpipe_compensated"};
}

}  // namespace gcpipe
