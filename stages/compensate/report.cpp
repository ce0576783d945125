#include "report.hpp"

#include <algorithm>

#include <cstdio>

#include <nlohmann/json.hpp>

namespace gcpipe::compensate {

namespace {

using Json = nlohmann::ordered_json;

Json error_json(const ErrorStats& e) {
  return {{"max_mm", e.max}, {"rms_mm", e.rms}, {"t_at_max_s", e.t_at_max}, {"line_at_max", e.line_at_max}};
}

// The whole-program keys (max_mm ... line_at_max) have always been on cutting moves; the
// `cutting` and `rapid` objects say so explicitly and give the rapids' figure apart.
Json contour_json(const Evaluation& ev) {
  Json j = error_json(ev.contour);
  j["cutting"] = {{"max_mm", ev.contour.max}, {"rms_mm", ev.contour.rms}};
  j["rapid"] = {{"max_mm", ev.rapid.max}, {"rms_mm", ev.rapid.rms}};
  return j;
}

Json per_axis(const Axes& a) {
  Json j;
  for (int i = 0; i < kNumAxes; ++i) j[std::string(1, kAxisLetters[i])] = a[static_cast<std::size_t>(i)];
  return j;
}

Json axis_stats_json(const AxisStats& a) {
  Json ticks;
  for (int i = 0; i < kNumAxes; ++i) ticks[std::string(1, kAxisLetters[i])] = a.saturated_ticks[static_cast<std::size_t>(i)];
  return {{"units", "mm (X Y Z), deg (A C)"},
          {"max_following_error", per_axis(a.max_following)},
          {"rms_following_error", per_axis(a.rms_following)},
          {"max_tracking_error", per_axis(a.max_tracking)},
          {"travel_margin", per_axis(a.travel_margin)},
          {"peak_velocity", per_axis(a.peak_velocity)},
          {"peak_acceleration", per_axis(a.peak_acceleration)},
          {"torque_limited_ticks", ticks}};
}

double ratio(double before, double after) { return after > 0 ? before / after : 0.0; }

// Where the compensation's plan is slower than the control's, and what it costs.
Json slowdown_json(const ReportInput& in, double T) {
  const LocalSlowdown& s = *in.slowdown;
  Json list = Json::array();
  for (const SlowStretch& x : s.stretches)
    list.push_back({{"first_line", x.first_line}, {"last_line", x.last_line}, {"t_begin_s", x.t_begin}, {"t_end_s", x.t_end},
                    {"speed_factor", x.factor}});
  const double planned = static_cast<double>(s.run->nominal->reference.size()) * T;
  return {{"stretches", list},
          {"cycle_time_added_s", planned - static_cast<double>(in.before->stats.ticks) * T},
          {"rounds", s.rounds},
          {"feedforward_acceleration_over_limit", s.worst_over_limit}};
}

// The configured control's cycle for the original [s]: seed 002's control runs the interpolator's
// ticks; the look-ahead control its plan with the in-position waits (the "before" run's ticks).
double control_cycle(const ReportInput& in) {
  const double T = in.model->interp.period;
  if (in.model->interp.control == interpolate::Control::kLookahead) return static_cast<double>(in.before->stats.ticks) * T;
  return static_cast<double>(in.nominal->raw.size()) * T;
}

const char* smoothing_name(interpolate::Smoothing s) {
  return s == interpolate::Smoothing::kExponential ? "exponential" : s == interpolate::Smoothing::kLinear ? "linear" : "none";
}

Json segments_json(const ReportInput& in) {
  Json list = Json::array();
  for (std::size_t k = 0; k < in.nominal->segments.size(); ++k) {
    const Segment& g = in.nominal->segments[k];
    Json j = {{"first_line", g.first_line}, {"last_line", g.last_line}, {"t_begin_s", g.t_begin}, {"t_end_s", g.t_end}};
    if (g.circle) j["circle"] = {{"radius_mm", g.circle_radius}, {"centre_mm", {g.circle_centre[0], g.circle_centre[1]}}};
    j["contour_error_before"] = error_json(in.before->per_segment[k]);
    if (in.after && k < in.after->per_segment.size()) {
      j["contour_error_after"] = error_json(in.after->per_segment[k]);
      j["max_contour_error_reduction"] = ratio(in.before->per_segment[k].max, in.after->per_segment[k].max);
    }
    list.push_back(std::move(j));
  }
  return list;
}

void add_result(Json& j, const ReportInput& in) {
  const Result& r = *in.result;
  const double T = in.model->interp.period;
  j["nodes"] = r.points;
  j["original_duration_s"] = static_cast<double>(in.nominal->raw.size()) * T;
  j["compensated_duration_s"] = static_cast<double>(r.end_tick) * T;
  j["linearisation"] = {{"splits", r.linearisation_splits},
                        {"max_deviation_mm", r.linearisation_max_deviation},
                        {"source_tcp_blocks_needing_split", r.source_blocks_needing_split},
                        {"source_joint_linear_deviation_mm", r.source_joint_linear_deviation}};
  Json iterations = Json::array();
  for (const Iteration& it : r.iterations) {
    Json i = {{"index", it.index}, {"max_contour_mm", it.max_contour}, {"rms_contour_mm", it.rms_contour},
              {"gain", it.gain}, {"accepted", it.accepted}};
    if (!it.accepted) i["rejected_because"] = it.rejected_because;
    iterations.push_back(std::move(i));
  }
  j["iterations"] = std::move(iterations);
  // How much the learning replayed: by windows, a window's machine time per iteration it needs.
  j["learning"] = {{"windows", r.windows.size()},
                   {"simulated_machine_s", static_cast<double>(r.learning_ticks) * T},
                   {"most_iterations_of_a_window", r.windows.empty() ? 0 : std::max_element(r.windows.begin(), r.windows.end(), [](const auto& a, const auto& b) { return a.iterations < b.iterations; })->iterations}};
}

Json kffp_json(const ReportInput& in) {
  if (!in.best_kffp.ok)
    return {{"note", in.best_kffp_note.empty() ? in.best_kffp.message : in.best_kffp_note}};
  return {{"omega_rad_s", in.best_kffp_omega}, {"rotary_lag_rad", in.best_kffp.alpha},
          {"X_percent", in.best_kffp.K_FFP[0]}, {"Y_percent", in.best_kffp.K_FFP[1]}};
}

Json kffp_per_segment_json(const ReportInput& in) {
  Json list = Json::array();
  for (const auto& [seg, v] : in.segment_kffp) {
    Json j = {{"first_line", in.nominal->segments[seg].first_line}, {"omega_rad_s", v.first}};
    if (v.second.ok) {
      j["X_percent"] = v.second.K_FFP[0];
      j["Y_percent"] = v.second.K_FFP[1];
    } else {
      j["note"] = v.second.message;
    }
    list.push_back(std::move(j));
  }
  return list;
}

// A feed above an axis's speed bound is clamped as a control clamps it; the report says where.
Json feed_clamp_json(const interpolate::InterpolateStats& s) {
  return {{"blocks", s.velocity_limited_blocks},
          {"first_line", s.first_clamped_line},
          {"last_line", s.last_clamped_line},
          {"most_clamped", {{"line", s.most_clamped_line},
                            {s.most_clamped_inverse_time ? "programmed_feed_per_min" : "programmed_feed_mm_min", s.most_clamped_feed},
                            {"feed_percent", 100 * s.most_clamped_factor}}}};
}

}  // namespace

std::string feed_clamp_note(const interpolate::InterpolateStats& s) {
  if (s.velocity_limited_blocks == 0) return {};
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "%llu blocks (lines %llu-%llu) programmed faster than an axis's speed bound run at the bound, as the "
                "control clamps them; line %llu the most: F%.6g %s run at %.0f %% of it",
                static_cast<unsigned long long>(s.velocity_limited_blocks),
                static_cast<unsigned long long>(s.first_clamped_line), static_cast<unsigned long long>(s.last_clamped_line),
                static_cast<unsigned long long>(s.most_clamped_line), s.most_clamped_feed,
                s.most_clamped_inverse_time ? "(G93, 1/min)" : "mm/min", 100 * s.most_clamped_factor);
  return buf;
}

nlohmann::ordered_json report_json(const ReportInput& in) {
  Json j;
  j["model"] = {{"period_s", in.model->interp.period}, {"smoothing", smoothing_name(in.model->interp.smoothing)}};
  j["compensated"] = in.result && in.result->compensated && in.after;
  j["note"] = in.result ? in.result->note : std::string();
  const double T = in.model->interp.period;
  j["control"] = in.model->interp.control == interpolate::Control::kLookahead ? "lookahead" : "after_interpolation";
  j["cycle_time_before_s"] = control_cycle(in);
  // The original as a look-ahead control runs it to compensate.path_tolerance: the reference.
  if (!in.nominal->reference.empty())
    j["cycle_time_planned_s"] = static_cast<double>(in.nominal->reference.size()) * T;
  if (in.result && in.result->points > 0 && in.after)
    j["cycle_time_after_s"] = static_cast<double>(in.result->end_tick) * T;
  if (in.nominal->stats.interp.velocity_limited_blocks > 0) j["feed_clamped"] = feed_clamp_json(in.nominal->stats.interp);
  j["contour_error_before"] = contour_json(*in.before);
  if (in.feedforward) {
    j["contour_error_feedforward"] = contour_json(*in.feedforward);
    // The feed-forward is the model inverse unbounded: where it asks more acceleration than an
    // axis has, the learning (which keeps the limits) cannot take it as it is.
    j["feedforward_acceleration_over_limit"] = in.feedforward_over_limit;
  }
  if (in.after && in.feedforward)
    j["max_contour_error_reduction_over_feedforward"] = ratio(in.feedforward->contour.max, in.after->contour.max);
  if (in.after && in.result && in.result->points > 0)
    j["cycle_time_ratio"] = static_cast<double>(in.result->end_tick) * T / control_cycle(in);
  if (in.slowdown != nullptr && in.slowdown->run) j["slowed_for_drive_limits"] = slowdown_json(in, T);
  if (in.model->interp.control == interpolate::Control::kLookahead)
    j["in_position"] = {{"checks", in.nominal->in_position_checks},
                        {"wait_s", static_cast<double>(in.nominal->in_position_ticks) * T},
                        {"waits_cut_at_2s", in.nominal->in_position_capped}};
  if (in.after) {
    j["contour_error_after"] = contour_json(*in.after);
    j["max_contour_error_reduction"] = ratio(in.before->contour.max, in.after->contour.max);
    if (const std::string why = reduction_limited_by(in); !why.empty()) j["reduction_limited_by"] = why;
  }
  if (in.slowed != nullptr) {
    const simulate::SlowedBaseline& b = *in.slowed;
    j["slowed_original"] = b.ok ? Json{{"feed_factor", b.feed_factor},
                                       {"cycle_time_s", b.cycle_time},
                                       {"contour_error", {{"max_mm", b.contour.max}, {"rms_mm", b.contour.rms}}}}
                                : Json{{"note", b.note}};
  }
  Json ideal = Json::array();
  for (int i = 0; i < kNumAxes; ++i)
    if (in.model->drives.axes[static_cast<std::size_t>(i)].model == servo::DriveModel::kIdeal)
      ideal.push_back(std::string(1, kAxisLetters[i]));
  j["ideal_axes"] = std::move(ideal);  // actual = command by assumption: their zeros are not measured
  j["axes_before"] = axis_stats_json(in.before->axes);
  if (in.after) j["axes_after"] = axis_stats_json(in.after->axes);
  j["segments"] = segments_json(in);
  if (in.result) add_result(j, in);
  j["best_kffp"] = kffp_json(in);
  j["best_kffp_per_segment"] = kffp_per_segment_json(in);
  return j;
}

namespace {

// Issue 12's target for the cutting contour error: at least tenfold lower.
constexpr double kTargetReduction = 10.0;

}  // namespace

std::string reduction_limited_by(const ReportInput& in) {
  if (in.result == nullptr || in.after == nullptr || !in.result->compensated) return {};
  const double before = in.before->contour.max, after = in.after->contour.max;
  if (!(after > 0) || before >= kTargetReduction * after) return {};
  const Result& r = *in.result;
  char buf[400];
  // The limits are kept per second of the compensated clock and the decisions are blended over
  // +-0.1 s, so the second of the largest error and its two neighbours are the ones to ask.
  const auto w = static_cast<std::size_t>(std::max(0.0, in.after->contour.t_at_max));
  for (std::size_t k : {w, w + 1, w == 0 ? w : w - 1}) {
    if (auto it = r.window_limits.find(k); it != r.window_limits.end()) {
      std::snprintf(buf, sizeof buf, "the learning was held back where the largest error is (t %.3f s) by a limit: %s",
                    in.after->contour.t_at_max, it->second.c_str());
      return buf;
    }
  }
  if (after < 2 * r.linearisation_max_deviation) {
    std::snprintf(buf, sizeof buf,
                  "the error after (%.2f um) is at the floor of the points' joint-linear motion, which stays within "
                  "compensate.linearisation_tolerance of the path (worst %.2f um); the error before is only %.2f um",
                  after * 1e3, r.linearisation_max_deviation * 1e3, before * 1e3);
    return buf;
  }
  // The iterations of the window that learned that time, not of the longest-learning window.
  const LearningWindow* window = r.window_at(in.after->contour.t_at_max);
  const std::size_t iterations = window ? static_cast<std::size_t>(window->iterations) : r.iterations.size();
  if (window && window->out_of_iterations) {
    std::snprintf(buf, sizeof buf,
                  "no limit was broken near the largest error (t %.3f s); the learning was still gaining there when "
                  "compensate.max_iterations (%zu after the start) ran out",
                  in.after->contour.t_at_max, iterations > 0 ? iterations - 1 : 0);
    return buf;
  }
  std::snprintf(buf, sizeof buf,
                "no limit was broken near the largest error (t %.3f s); the learning stopped gaining there after %zu "
                "iterations",
                in.after->contour.t_at_max, iterations);
  return buf;
}

namespace {

bool has_motion(const Nominal& nom, std::initializer_list<Motion> motions) {
  for (std::size_t i = 0; i < nom.brief.size(); ++i)
    if (std::find(motions.begin(), motions.end(), nom.brief[i].motion) != motions.end()) return true;
  return false;
}

bool has_cutting_moves(const Nominal& nom) {
  return has_motion(nom, {Motion::kLinear, Motion::kArcCW, Motion::kArcCCW});
}

// The contour error before and after, with the reduction. A program without a cutting move has no
// contour error to state: "0.00 um" would read as a measured figure.
void contour_lines(const ReportInput& in, std::string& s) {
  char buf[400];
  if (!has_cutting_moves(*in.nominal)) {
    s += "  contour error: none to measure, the program has no cutting moves (G1, G2, G3)\n";
    return;
  }
  const ErrorStats& b = in.before->contour;
  std::snprintf(buf, sizeof buf, "  contour error before: max %.2f um (line %llu, t %.3f s), RMS %.2f um\n", b.max * 1e3,
                static_cast<unsigned long long>(b.line_at_max), b.t_at_max, b.rms * 1e3);
  s += buf;
  if (in.after) {
    const ErrorStats& a = in.after->contour;
    std::snprintf(buf, sizeof buf, "  contour error after:  max %.2f um (line %llu, t %.3f s), RMS %.2f um: max down %.1fx\n",
                  a.max * 1e3, static_cast<unsigned long long>(a.line_at_max), a.t_at_max, a.rms * 1e3, ratio(b.max, a.max));
    s += buf;
  }
  if (in.feedforward) {
    const ErrorStats& f = in.feedforward->contour;
    std::snprintf(buf, sizeof buf, "  feed-forward (model inverse, no learning): max %.2f um (line %llu), RMS %.2f um", f.max * 1e3,
                  static_cast<unsigned long long>(f.line_at_max), f.rms * 1e3);
    s += buf;
    if (in.feedforward_over_limit > 1.0) {
      std::snprintf(buf, sizeof buf, ", asking up to %.2fx an axis's acceleration limit", in.feedforward_over_limit);
      s += buf;
    }
    if (in.after) {
      std::snprintf(buf, sizeof buf, "; after is %.1fx below it", ratio(f.max, in.after->contour.max));
      s += buf;
    }
    s += "\n";
  }
}

// Where the drives' limits made the compensation slow the plan: the first stretches, the time.
void slowdown_lines(const ReportInput& in, std::string& s) {
  if (in.slowdown == nullptr || !in.slowdown->run) return;
  const LocalSlowdown& sd = *in.slowdown;
  const double T = in.model->interp.period;
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "  slowed where the drives' limits forbid the pre-compensation at the control's speed: %zu stretches, "
                "+%.3f s%s\n",
                sd.stretches.size(),
                static_cast<double>(sd.run->nominal->reference.size()) * T - static_cast<double>(in.before->stats.ticks) * T,
                sd.worst_over_limit > 1.0 ? " (the model inverse still asks more than an axis has in places)" : "");
  s += buf;
  for (std::size_t k = 0; k < sd.stretches.size() && k < 5; ++k) {
    const SlowStretch& x = sd.stretches[k];
    std::snprintf(buf, sizeof buf, "    lines %llu-%llu (t %.2f-%.2f s): speed x%.2f\n", static_cast<unsigned long long>(x.first_line),
                  static_cast<unsigned long long>(x.last_line), x.t_begin, x.t_end, x.factor);
    s += buf;
  }
  if (sd.stretches.size() > 5) s += "    ... (report.json simulation.slowed_for_drive_limits has them all)\n";
}

// The compensation's note, the slowed-original baseline, the rapids, the cycle times.
void outcome_lines(const ReportInput& in, std::string& s) {
  char buf[400];
  if (const std::string clamp = feed_clamp_note(in.nominal->stats.interp); !clamp.empty()) s += "  feed clamped: " + clamp + "\n";
  if (in.result && !in.result->note.empty()) s += "  compensation: " + in.result->note + "\n";
  if (const std::string why = reduction_limited_by(in); !why.empty()) s += "  below 10x: " + why + "\n";
  if (in.slowed != nullptr && in.slowed->ok) {
    std::snprintf(buf, sizeof buf,
                  "  baseline: the original with feeds x%.3f runs %.3f s: max %.2f um, RMS %.2f um (cutting moves)\n",
                  in.slowed->feed_factor, in.slowed->cycle_time, in.slowed->contour.max * 1e3, in.slowed->contour.rms * 1e3);
    s += buf;
  }
  if (!has_motion(*in.nominal, {Motion::kRapid})) {
    s += "  rapids (G0): none in the program";
  } else {
    std::snprintf(buf, sizeof buf, "  rapids (G0, not cutting): max %.2f um before", in.before->rapid.max * 1e3);
    s += buf;
    if (in.after) {
      std::snprintf(buf, sizeof buf, ", %.2f um after", in.after->rapid.max * 1e3);
      s += buf;
    }
  }
  s += "\n";
  const bool lookahead = in.model->interp.control == interpolate::Control::kLookahead;
  if (in.result && in.result->points > 0 && in.after && lookahead) {
    const double after = static_cast<double>(in.result->end_tick) * in.model->interp.period;
    std::snprintf(buf, sizeof buf,
                  "  compensated program runs %.3f s, %.3fx the look-ahead control's %.3f s for the original (%llu "
                  "in-position checks waited %.3f s)\n",
                  after, after / control_cycle(in), control_cycle(in),
                  static_cast<unsigned long long>(in.nominal->in_position_checks),
                  static_cast<double>(in.nominal->in_position_ticks) * in.model->interp.period);
    s += buf;
    slowdown_lines(in, s);
  } else if (in.result && in.result->points > 0 && in.after) {
    std::snprintf(buf, sizeof buf,
                  "  compensated program runs %.3f s (original %.3f s as the control runs it, %.3f s planned to "
                  "compensate.path_tolerance)\n",
                  static_cast<double>(in.result->end_tick) * in.model->interp.period,
                  control_cycle(in),
                  static_cast<double>(in.nominal->reference.size()) * in.model->interp.period);
    s += buf;
  }
}

// Following error and travel margin per axis.
void axis_lines(const ReportInput& in, std::string& s) {
  char buf[400];
  s += "  following error max (command - actual), before";
  s += in.after ? " / after:" : ":";
  std::string ideal;
  for (int i = 0; i < kNumAxes; ++i) {
    const auto k = static_cast<std::size_t>(i);
    // An ideal drive (model: ideal) follows its command exactly by assumption: "0" would read as
    // a measured figure.
    if (in.model->drives.axes[k].model == servo::DriveModel::kIdeal) {
      ideal += std::string(ideal.empty() ? "" : " ") + kAxisLetters[i];
      continue;
    }
    if (in.after)
      std::snprintf(buf, sizeof buf, " %c %.4g/%.4g", kAxisLetters[i], in.before->axes.max_following[k], in.after->axes.max_following[k]);
    else
      std::snprintf(buf, sizeof buf, " %c %.4g", kAxisLetters[i], in.before->axes.max_following[k]);
    s += buf;
  }
  s += " (mm, deg)";
  if (!ideal.empty()) s += "; " + ideal + " ideal (model: ideal, actual = command)";
  s += "\n  travel margin min:";
  const AxisStats& m = in.after ? in.after->axes : in.before->axes;
  for (int i = 0; i < kNumAxes; ++i) {
    std::snprintf(buf, sizeof buf, " %c %.4g", kAxisLetters[i], m.travel_margin[static_cast<std::size_t>(i)]);
    s += buf;
  }
  s += " (mm, deg)\n";
}

// Seed 002 eq. (20): Best K_FFP for the program and per circle segment.
void kffp_lines(const ReportInput& in, std::string& s) {
  char buf[400];
  if (in.best_kffp.ok) {
    std::snprintf(buf, sizeof buf, "  Best K_FFP (seed 002 eq. 20) at w = %.3f rad/s: X %.1f %%, Y %.1f %% (recommendation)\n",
                  in.best_kffp_omega, in.best_kffp.K_FFP[0], in.best_kffp.K_FFP[1]);
    s += buf;
  } else {
    s += "  Best K_FFP: " + (in.best_kffp_note.empty() ? in.best_kffp.message : in.best_kffp_note) + "\n";
  }
  for (const auto& [seg, v] : in.segment_kffp) {
    const Segment& g = in.nominal->segments[seg];
    if (v.second.ok)
      std::snprintf(buf, sizeof buf, "    lines %llu-%llu, C at %.3f rad/s: Best K_FFP X %.1f %%, Y %.1f %%\n",
                    static_cast<unsigned long long>(g.first_line), static_cast<unsigned long long>(g.last_line), v.first,
                    v.second.K_FFP[0], v.second.K_FFP[1]);
    else
      std::snprintf(buf, sizeof buf, "    lines %llu-%llu, C at %.3f rad/s: no Best K_FFP (%s)\n",
                    static_cast<unsigned long long>(g.first_line), static_cast<unsigned long long>(g.last_line), v.first,
                    v.second.message.substr(0, 200).c_str());
    s += buf;
  }
}

}  // namespace

std::string report_text(const ReportInput& in) {
  std::string s;
  contour_lines(in, s);
  outcome_lines(in, s);
  segment_lines(in, s);
  axis_lines(in, s);
  kffp_lines(in, s);
  return s;
}

// Per segment between dwells or stops. Segments of the same source lines one after the other (the
// pecks of a canned cycle: each retract is a rapid, so each peck a segment) are one line. A
// reduction is given only where the error after is at least the 0.1 um compensated.nc is written
// with: 0.00 um after 847 um before is no factor of 431113 but an error below what the program can
// say; a segment with no error of that size before or after (a peck's retract) is not listed.
void segment_lines(const ReportInput& in, std::string& s) {
  constexpr double kShown = 0.1e-3;  // [mm] the written program's resolution
  const std::size_t n = in.nominal->segments.size();
  char buf[400];
  for (std::size_t k = 0; k < n;) {
    const Segment& g = in.nominal->segments[k];
    double before = 0, after = 0;
    std::size_t j = k;
    for (; j < n && in.nominal->segments[j].first_line == g.first_line && in.nominal->segments[j].last_line == g.last_line; ++j) {
      before = std::max(before, in.before->per_segment[j].max);
      if (in.after && j < in.after->per_segment.size()) after = std::max(after, in.after->per_segment[j].max);
    }
    const std::size_t merged = j - k;
    const double t_end = in.nominal->segments[j - 1].t_end;
    k = j;
    if (before < kShown && after < kShown) continue;
    char count[40] = "";
    if (merged > 1) std::snprintf(count, sizeof count, ", %zu segments", merged);
    int w = std::snprintf(buf, sizeof buf, "    lines %llu-%llu (t %.2f-%.2f s%s)%s: max %.2f um", static_cast<unsigned long long>(g.first_line),
                          static_cast<unsigned long long>(g.last_line), g.t_begin, t_end, count, g.circle ? ", circle" : "", before * 1e3);
    if (in.after && after >= kShown)
      std::snprintf(buf + w, sizeof buf - static_cast<std::size_t>(w), " -> %.2f um (%.1fx)", after * 1e3, ratio(before, after));
    else if (in.after)
      std::snprintf(buf + w, sizeof buf - static_cast<std::size_t>(w), " -> %.2f um (below the 0.1 um it is written with)", after * 1e3);
    s += buf;
    s += '\n';
  }
}

}  // namespace gcpipe::compensate
