// The compensation report: report.json's "compensation" object and the readable summary printed
// by `gcpipe batch` and written to report.txt.
#pragma once

#include <string>

#include <nlohmann/json_fwd.hpp>
#include <utility>
#include <vector>

#include "compensate.hpp"
#include "local_slowdown.hpp"
#include "circle.hpp"
#include "servo.hpp"

namespace gcpipe::compensate {

struct ReportInput {
  const Model* model = nullptr;
  const Nominal* nominal = nullptr;
  const Evaluation* before = nullptr;    //!< the original program, simulated
  const simulate::SlowedBaseline* slowed = nullptr;  //!< the original slowed to the compensated
                                                     //!< cycle time (null when not compensated)
  const Evaluation* feedforward = nullptr;  //!< the original on the control with the drives' model
                                            //!< inverse as feed-forward, no learning (or null)
  double feedforward_over_limit = 0;       //!< the feed-forward's largest acceleration / an axis's limit
  const LocalSlowdown* slowdown = nullptr;  //!< where the compensation's plan is slower than the control's
  const Evaluation* after = nullptr;     //!< the written compensated program, re-parsed and
                                         //!< simulated (null when not compensated)
  const Result* result = nullptr;
  servo::BestKffp best_kffp;             //!< seed 002 eq. (20)
  double best_kffp_omega = 0;            //!< [rad/s] angular velocity it was computed for
  std::string best_kffp_note;            //!< why there is no recommendation
  /// Per segment in which C turns: its C speed [rad/s] and the Best K_FFP there.
  std::vector<std::pair<std::size_t, std::pair<double, servo::BestKffp>>> segment_kffp;
};

/// The "compensation" JSON object (no trailing newline): contour error before/after per program
/// and per segment, per-axis following errors, travel margins, iterations, linearisation, K_FFP.
nlohmann::ordered_json report_json(const ReportInput& in);

/// Where the original's feed was clamped to an axis's speed bound (blocks, lines, the block
/// clamped most), one sentence; empty when nowhere.
std::string feed_clamp_note(const interpolate::InterpolateStats& s);

/// Readable summary, a few lines, each starting with two spaces.
std::string report_text(const ReportInput& in);

/// report_text's lines per segment, appended to `s`: a canned cycle's pecks as one line, no
/// reduction factor below the 0.1 um compensated.nc is written with.
void segment_lines(const ReportInput& in, std::string& s);

/// Where the cutting contour error came down less than tenfold (issue 12's target), what limits
/// it: the limit that held the learning back where the largest error is, the floor of the
/// points' joint-linear motion, or the learning's stall; empty when tenfold was reached.
std::string reduction_limited_by(const ReportInput& in);

}  // namespace gcpipe::compensate
