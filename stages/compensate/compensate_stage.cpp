// The compensate stage in the pipeline: the program's simulation in (from the simulate stage in
// the same process, or computed here from the blocks when this stage runs alone, as a DDS node),
// the compensated program out as G-code text, and the simulation of that text as written, read
// back by the parser, for the "after" figures.
#include <algorithm>
#include <cstdio>
#include <deque>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "chain_inverse.hpp"
#include "local_slowdown.hpp"
#include "compensate_program.hpp"
#include "error_budget.hpp"
#include "force_product.hpp"
#include "parse.hpp"
#include "simulate_stage.hpp"
#include "simulation_report.hpp"

namespace gcpipe {
namespace {

using pipeline::Emitter;

/// compensated.nc read back as it is written: each piece is parsed line by line (strict, in the
/// writer's dialect) and its motion blocks are run on the reference clock and measured at once,
/// so that neither the text nor its blocks (one a node, 472 bytes each) are ever all held. The
/// "after" figures are those of the text as written, rounding included.
class ReadBack {
 public:
  ReadBack(const ParseOptions& options, const MachineConfig& machine, const compensate::Model& model,
           const simulate::SimulationRun& run, bool work_frame)
      : parser_(options, machine, "compensated.nc"), runner_(model, run.start, 0),
        evaluation_(model, *run.nominal, run.program, run.start, true),
        checks_(model, *run.nominal, run.program, work_frame) {
    sink_.block = [this](const ResolvedBlock& b) {
      if (b.motion != Motion::kNone) run_block(b);
      return true;
    };
    sink_.diagnostic = [](const Diagnostic& d) {
      if (d.severity == Severity::kError) throw std::runtime_error("compensated.nc does not read back: " + format(d));
      return true;
    };
    on_tick_ = [this](const simulate::Tick& t) {
      const compensate::PointSource& p = source_of(t.block);
      evaluation_.add(on_reference_clock(t, p), p.block);
    };
  }

  /// The next piece of the text (whole lines), with the source of each of its motion blocks.
  void feed(std::string_view piece, const std::vector<compensate::PointSource>& points) {
    sources_.insert(sources_.end(), points.begin(), points.end());
    points_ += points.size();
    for (std::size_t pos = 0; pos < piece.size();) {
      const std::size_t end = std::min(piece.find('\n', pos), piece.size());
      feed_line(piece.substr(pos, end - pos));
      pos = end + 1;
    }
  }

  /// The figures of the whole text; throws when it does not read back as written.
  simulate::Evaluation finish() {
    parser_.finish(sink_);
    if (read_ != points_) throw does_not_read_back();
    return evaluation_.finish(runner_.finish(on_tick_));
  }

  std::uint64_t points() const { return points_; }
  const compensate::ReadBackChecks& checks() const { return checks_; }

 private:
  void feed_line(std::string_view line) {
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    parser_.feed(line, sink_);
  }

  void run_block(const ResolvedBlock& b) {
    if (read_ >= points_) throw does_not_read_back();
    checks_.add(b, sources_[read_ - first_source_]);
    // A block the machine cannot run stops the run there (as run_program does); the rest is
    // still read, to count it.
    runner_.add(b, static_cast<std::uint32_t>(read_++), on_tick_);
  }

  // A tick of the text's run on the reference clock the metric measures against. Timed points
  // follow it; a rapid the text gives as the source wrote it (a three-axis program) runs on the
  // control's own, so each block's first tick is put where its move starts on the reference
  // (its first sample is one tick after), never back before a tick already measured.
  simulate::Tick on_reference_clock(const simulate::Tick& t, const compensate::PointSource& p) {
    if (t.block != block_) {
      block_ = t.block;
      offset_ = static_cast<std::int64_t>(p.tick + 1) - static_cast<std::int64_t>(t.n);
    }
    simulate::Tick m = t;
    m.n = std::max(last_tick_, static_cast<std::uint64_t>(std::max<std::int64_t>(0, static_cast<std::int64_t>(t.n) + offset_)));
    last_tick_ = m.n;
    return m;
  }

  // The source of motion block i of the text. Ticks come in order, so the blocks before i are
  // done with.
  const compensate::PointSource& source_of(std::uint32_t i) {
    while (first_source_ < i && sources_.size() > 1) sources_.pop_front(), ++first_source_;
    return sources_[std::min<std::size_t>(i - first_source_, sources_.size() - 1)];
  }

  std::runtime_error does_not_read_back() const {
    return std::runtime_error("compensated.nc does not read back as written (" + std::to_string(read_) +
                              " motion blocks for " + std::to_string(points_) + " points)");
  }

  Parser parser_;
  ParseSink sink_;
  simulate::ProgramRunner runner_;
  simulate::RunEvaluation evaluation_;
  simulate::TickFn on_tick_;
  compensate::ReadBackChecks checks_;
  std::deque<compensate::PointSource> sources_;
  std::uint32_t block_ = 0;     // the text's motion block whose ticks come now
  std::int64_t offset_ = 0;     // its ticks on the reference clock less the run's
  std::uint64_t last_tick_ = 0; // the last tick measured, on the reference clock
  std::uint64_t first_source_ = 0;  // the text's motion block sources_.front() stands for
  std::uint64_t points_ = 0;        // timed points written so far
  std::uint64_t read_ = 0;          // motion blocks read back so far
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
        keep_going_(c.keep_going),
        collect_(std::find(c.stages.begin(), c.stages.end(), "simulate") == c.stages.end()),
        blocks_(options_.max_blocks) {
    // The look-ahead control has no acc/dec after interpolation: it runs the velocity steps of
    // the timed points' chain as they are, so points 4 ms apart would make a velocity step every
    // 4 ms (accelerations of v/T at the steps, which the learning's limits then see). A point
    // every interpolation period is the command itself.
    if (model_.interp.control == interpolate::Control::kLookahead && !c.config->root.section("compensate").has("node_period"))
      options_.node_period = model_.interp.period;
  }

  bool block(const ResolvedBlock& b, Emitter&) override {
    if (is_cutting(b)) ++cutting_blocks_;
    if (collect_ && blocks_.size() < options_.max_blocks) blocks_.push_back(b);
    else if (collect_) too_many_ = true;
    return true;
  }
  bool diagnostic(const Diagnostic& d, DiagnosticKind kind, Emitter&) override {
    if (kind == DiagnosticKind::kLineRejected || kind == DiagnosticKind::kBlockRejected) {
      if (rejected_lines_++ == 0) first_rejected_line_ = d.line;
    }
    return true;
  }
  void product(const std::shared_ptr<const pipeline::Product>& p, Emitter&) override {
    if (auto s = std::dynamic_pointer_cast<const SimulatedProgram>(p)) simulated_ = s;
    if (auto f = std::dynamic_pointer_cast<const force::ForceProfile>(p)) force_ = f;
  }

  bool finish(bool complete, Emitter& out) override {
    if (!complete) return fail("the program did not arrive whole");
    if (too_many_) return fail("the program has more than compensate.max_blocks = " + std::to_string(options_.max_blocks) + " blocks");
    not_compensated_ = reason_not_to_compensate();
    // Simulated all the same: the report shows the original's error either way, in batch and
    // in a DDS node alike.
    if (!simulated_) simulate_here();
    if (!not_compensated_.empty()) return true;  // said in the report; not a failure of the run
    if (!simulated_->run.before) return fail("not simulated: " + simulated_->run.note);
    measure_feedforward();
    slow_where_needed();
    const simulate::SimulationRun& run = slowdown_.run ? *slowdown_.run : simulated_->run;
    // compensated.nc goes out and is read back window by window as the learning commits its
    // nodes: on a long program neither the text (tens of MB) nor the nodes are held whole.
    std::optional<ReadBack> back;
    bool go = true;
    compensation_ = compensate::compensate_program(
        model_, options_, write_options_, run, progress_,
        [&](std::string& piece, const std::vector<compensate::PointSource>& points) {
          if (!back)
            back.emplace(read_back_options(), machine_, model_, run,
                         options_.work_frame && compensate::three_axis_program(run.program));
          back->feed(piece, points);
          bytes_ += piece.size();
          go = out.text(piece) && go;
        });
    if (!compensation_.result || !compensation_.result->compensated || !back)
      return fail("no compensated program: " + compensation_.note);
    after_ = back->finish();
    written_nodes_ = back->points();
    // gcpipe batch keeps no compensated.nc whose read-back fails a check (issue 30 item 5).
    const std::string refused = back->checks().failures(compensation_.envelope.envelope);
    if (!refused.empty()) return fail("compensated.nc refused, its read-back fails: " + refused);
    measure_slowed_baseline();
    return go;
  }

  void report(pipeline::ReportContext& r) const override {
    compensate::SimulationOutcome o;
    o.model = &model_;
    o.run = simulated_ ? &simulated_->run : nullptr;
    o.after = after_ ? &*after_ : nullptr;
    o.result = compensation_.result ? &*compensation_.result : nullptr;
    o.written_nodes = written_nodes_;
    o.slowed = slowed_ ? &*slowed_ : nullptr;
    o.feedforward = feedforward_ ? &feedforward_->eval : nullptr;
    if (feedforward_ && !feedforward_->over_limit.empty())
      o.feedforward_over_limit = *std::max_element(feedforward_->over_limit.begin(), feedforward_->over_limit.end());
    o.slowdown = &slowdown_;
    o.skipped = failure_;
    o.not_compensated = not_compensated_;
    compensate::report_simulation(r, o);
    report_program(r);
    report_error_budget(r);
  }
  std::string failure() const override { return failure_; }

 private:
  /// How compensated.nc states its frames and how far its points lie from the source's path
  /// (the envelope tests/rs274_compensated_test.cpp holds LinuxCNC's reading of the file to).
  void report_program(pipeline::ReportContext& r) const {
    if (!compensation_.result || !compensation_.result->compensated || !r.json->contains("simulation")) return;
    const compensate::PointEnvelope& e = compensation_.envelope;
    (*r.json)["simulation"]["compensated_program"] = {
        {"frames", e.work_frame ? "work: the source's work offsets, tool length, rapids and G28/G30/G53"
                                : "machine joints behind a guard on the control's work offsets and tool length"},
        {"start_joints", simulated_->run.start},
        {"starts_at", model_.start ? "the machine file's start_position" : "the program's first position"},
        {"envelope_mm", e.envelope},
        {"points_lifted_to_floor", e.points_clamped},
        {"bytes", bytes_},
        {"points_per_second", points_per_second()}};
    char line[240];
    std::snprintf(line, sizeof line, "  compensated.nc: %s; every point within %.4f mm of the source's path%s\n",
                  e.work_frame ? "in the source's work frame" : "machine joints behind a guard", e.envelope,
                  e.points_clamped ? ", points below a block's floor lifted to it" : "");
    *r.text += line;
    std::snprintf(line, sizeof line, "  compensated.nc: %llu bytes, %.0f points a second (the block rate a control must sustain)\n",
                  static_cast<unsigned long long>(bytes_), points_per_second());
    *r.text += line;
    const Axes& s0 = simulated_->run.start;
    std::snprintf(line, sizeof line, "  starts at X%.3f Y%.3f Z%.3f A%.3f C%.3f (machine joints: %s)\n", s0[0], s0[1], s0[2],
                  s0[3], s0[4], model_.start ? "the machine file's start_position" : "the program's first position");
    *r.text += line;
  }

  /// The motion blocks of compensated.nc a second of its cycle: the block rate a control must
  /// sustain on average (the timed points are denser where the linearisation halved them).
  double points_per_second() const {
    const double cycle = static_cast<double>(compensation_.result->end_tick) * model_.interp.period;
    return cycle > 0 ? static_cast<double>(written_nodes_) / cycle : 0.0;
  }

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

  static bool is_cutting(const ResolvedBlock& b) {
    return b.motion == Motion::kLinear || b.motion == Motion::kArcCW || b.motion == Motion::kArcCCW;
  }

  // A program the shop would not run as it is, or one with nothing to compensate, gets no
  // compensated.nc: a program with rejected lines runs without them (unless --keep-going says
  // that is meant), and one of rapids only would only be slowed (1.4x on a real post).
  std::string reason_not_to_compensate() const {
    if (!options_.enabled) return "compensate.enabled is false: the config asks for the simulation and its report only";
    if (rejected_lines_ > 0 && !keep_going_)
      return std::to_string(rejected_lines_) + (rejected_lines_ == 1 ? " line was" : " lines were") +
             " rejected (the first at line " + std::to_string(first_rejected_line_) +
             ", see diagnostics.txt): the program would run without " + (rejected_lines_ == 1 ? "it" : "them") +
             "; correct the program, or give --keep-going to compensate what was accepted";
    if (cutting_blocks_ == 0) return "the program has no cutting moves (G1, G2, G3): nothing to compensate";
    return {};
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

  // compensated.nc is parsed back strictly, in the writer's dialect. Its lines are the writer's,
  // not the input's: a timed point carries its source line's comment, which can take a line the
  // input limit let through past that limit, so the read-back takes lines up to the parser's
  // largest limit (issue 32: "line is 261 bytes long" failed the batch).
  ParseOptions read_back_options() const {
    ParseOptions po = parse_options_;
    po.max_line_length = kLargestLineLength;
    po.strict = true;
    po.dialect = write_options_.dialect;
    po.decimal_point_increments = false;
    return po;
  }

  // The control with the drives' model inverse as feed-forward and no learning: the learning's
  // fair baseline (same clock, same model).
  void measure_feedforward() {
    const simulate::Nominal& nom = *simulated_->run.nominal;
    if (nom.reference.empty()) return;
    if (progress_) progress_("simulating the original with the model-inverse feed-forward", 0, 0);
    feedforward_ = compensate::feedforward_run(model_, nom, simulated_->run.program, simulated_->run.start);
  }

  // Under the look-ahead control the compensation keeps the control's clock except where the
  // drives' limits forbid the pre-compensation at its speed: there the plan is slowed locally.
  void slow_where_needed() {
    if (!feedforward_ || !options_.enabled || !options_.slow_for_drive_limits ||
        model_.interp.control != interpolate::Control::kLookahead)
      return;
    if (progress_) progress_("slowing the plan where the drives cannot follow it", 0, 0);
    slowdown_ = compensate::slow_where_drives_cannot_follow(model_, simulated_->run, *feedforward_,
                                                            compensate::run_bounds(options_).plan,
                                                            options_.max_machine_time);
  }

  // The original slowed to the compensated program's cycle time: what a sceptic compares with.
  void measure_slowed_baseline() {
    if (!options_.slowed_baseline || !compensation_.result || compensation_.result->points == 0) return;
    if (progress_) progress_("simulating the original slowed to the compensated cycle time", 0, 0);
    const double target = static_cast<double>(compensation_.result->end_tick) * model_.interp.period;
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
  bool keep_going_;
  bool collect_;
  std::uint64_t cutting_blocks_ = 0;     // G1 G2 G3 blocks seen
  std::uint64_t rejected_lines_ = 0;     // lines rejected upstream (parse, trochoid)
  std::uint64_t first_rejected_line_ = 0;
  std::string not_compensated_;          // why the program was deliberately not compensated
  bool too_many_ = false;
  BlockStore blocks_;  // the program when no simulate stage runs in this process (a DDS node)
  std::shared_ptr<const SimulatedProgram> simulated_;
  compensate::ProgramCompensation compensation_;
  std::optional<simulate::Evaluation> after_;
  std::optional<simulate::SlowedBaseline> slowed_;
  std::optional<compensate::FeedforwardRun> feedforward_;
  compensate::LocalSlowdown slowdown_;
  std::uint64_t written_nodes_ = 0;
  std::uint64_t bytes_ = 0;  // of compensated.nc
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
