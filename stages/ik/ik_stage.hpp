// The IK stage in the pipeline: every block's end point solved by the analytic IK and, when a
// model is configured, the neural IK beside it, with status and flags. Blocks pass on unchanged;
// the points go to the summary, the figures and any tap (`gcpipe ik --csv`).
#pragma once

#include <functional>
#include <optional>

#include "ik.hpp"
#include "ik_plots.hpp"
#include "neural_ik.hpp"
#include "stage.hpp"

namespace gcpipe {

class IkPipelineStage final : public pipeline::Stage {
 public:
  explicit IkPipelineStage(const pipeline::StageContext& c);

  bool block(const ResolvedBlock& b, pipeline::Emitter& out) override;
  void report(pipeline::ReportContext& r) const override;

  /// Called with every solved point, in program order.
  void on_point(std::function<void(const IkPoint&)> tap) { tap_ = std::move(tap); }
  const IkStage& solver() const { return stage_; }

 private:
  /// IK points kept for the figures: every `stride`-th, the stride doubling whenever the store
  /// fills, so that a long program keeps an even sample in bounded memory; the flagged points'
  /// marks likewise (issue 12: the marks of a two-hour program's 96,000 flagged points were kept
  /// whole). kCap as the simulation's figure series: more points than a figure has pixels.
  struct Sampler {
    IkSeries s;
    std::uint64_t seen = 0, stride = 1, flag_stride = 1;
    static constexpr std::size_t kCap = 20000;
    void add(const IkPoint& p, const MachineKinematics& kin, double tool_length);
    static void thin(std::vector<double>& v);
  };

  MachineKinematics kin_;
  std::optional<neural::NeuralIk> model_;
  IkStage stage_;
  Sampler sampler_;
  IkPoint point_;
  bool neural_asked_ = false;  // --model given: the neural comparison is wanted, whatever the program
  bool rotary_moves_ = false;  // A or C moves somewhere in the program
  std::optional<Axes> first_joints_;
  bool neural_shown() const;
  std::function<void(const IkPoint&)> tap_;
};

/// The neural IK model a run uses: `path` when given (checked to be trained for `machine`), else
/// the ik section's `model`, else none.
std::optional<neural::NeuralIk> load_ik_model_for(const IkOptions& options, const std::string& path,
                                                  const std::string& machine);

}  // namespace gcpipe
