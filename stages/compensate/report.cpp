#include "report.hpp"

#include <cstdio>

#include "gcpipe/number_format.hpp"

namespace gcpipe::compensate {

namespace {

void num(std::string& s, double v) { append_json_number(s, v); }

void error_json(std::string& s, const ErrorStats& e) {
  s += "{\"max_mm\":";
  num(s, e.max);
  s += ",\"rms_mm\":";
  num(s, e.rms);
  s += ",\"t_at_max_s\":";
  num(s, e.t_at_max);
  s += ",\"line_at_max\":" + std::to_string(e.line_at_max) + "}";
}

void axes_json(std::string& s, const char* key, const Axes& a) {
  s += ",\"";
  s += key;
  s += "\":{";
  for (int i = 0; i < kNumAxes; ++i) {
    if (i) s += ',';
    s += '"';
    s += kAxisLetters[i];
    s += "\":";
    num(s, a[static_cast<std::size_t>(i)]);
  }
  s += '}';
}

void axis_stats_json(std::string& s, const AxisStats& a) {
  s += "{\"units\":\"mm (X Y Z), deg (A C)\"";
  axes_json(s, "max_following_error", a.max_following);
  axes_json(s, "rms_following_error", a.rms_following);
  axes_json(s, "max_tracking_error", a.max_tracking);
  axes_json(s, "travel_margin", a.travel_margin);
  axes_json(s, "peak_velocity", a.peak_velocity);
  axes_json(s, "peak_acceleration", a.peak_acceleration);
  s += ",\"torque_limited_ticks\":{";
  for (int i = 0; i < kNumAxes; ++i) {
    if (i) s += ',';
    s += '"';
    s += kAxisLetters[i];
    s += "\":" + std::to_string(a.saturated_ticks[static_cast<std::size_t>(i)]);
  }
  s += "}}";
}

double ratio(double before, double after) { return after > 0 ? before / after : 0.0; }

}  // namespace

std::string report_json(const ReportInput& in) {
  std::string s = "{\"model\":{\"period_s\":";
  num(s, in.model->interp.period);
  s += ",\"smoothing\":\"";
  s += in.model->interp.smoothing == interpolate::Smoothing::kExponential ? "exponential"
       : in.model->interp.smoothing == interpolate::Smoothing::kLinear    ? "linear"
                                                                          : "none";
  s += "\"}";
  s += ",\"compensated\":";
  s += in.result && in.result->compensated && in.after ? "true" : "false";
  s += ",\"note\":";
  append_json_string(s, in.result ? in.result->note : std::string());
  s += ",\"contour_error_before\":";
  error_json(s, in.before->contour);
  if (in.after) {
    s += ",\"contour_error_after\":";
    error_json(s, in.after->contour);
    s += ",\"max_contour_error_reduction\":";
    num(s, ratio(in.before->contour.max, in.after->contour.max));
  }
  s += ",\"axes_before\":";
  axis_stats_json(s, in.before->axes);
  if (in.after) {
    s += ",\"axes_after\":";
    axis_stats_json(s, in.after->axes);
  }
  s += ",\"segments\":[";
  for (std::size_t k = 0; k < in.nominal->segments.size(); ++k) {
    const Segment& g = in.nominal->segments[k];
    if (k) s += ',';
    s += "{\"first_line\":" + std::to_string(g.first_line) + ",\"last_line\":" + std::to_string(g.last_line) + ",\"t_begin_s\":";
    num(s, g.t_begin);
    s += ",\"t_end_s\":";
    num(s, g.t_end);
    if (g.circle) {
      s += ",\"circle\":{\"radius_mm\":";
      num(s, g.circle_radius);
      s += ",\"centre_mm\":[";
      num(s, g.circle_centre[0]);
      s += ',';
      num(s, g.circle_centre[1]);
      s += "]}";
    }
    s += ",\"contour_error_before\":";
    error_json(s, in.before->per_segment[k]);
    if (in.after && k < in.after->per_segment.size()) {
      s += ",\"contour_error_after\":";
      error_json(s, in.after->per_segment[k]);
      s += ",\"max_contour_error_reduction\":";
      num(s, ratio(in.before->per_segment[k].max, in.after->per_segment[k].max));
    }
    s += '}';
  }
  s += ']';
  if (in.result) {
    const Result& r = *in.result;
    s += ",\"nodes\":" + std::to_string(r.nodes.empty() ? 0 : r.nodes.size() - 1);
    s += ",\"original_duration_s\":";
    num(s, static_cast<double>(in.nominal->raw.size()) * in.model->interp.period);
    s += ",\"compensated_duration_s\":";
    num(s, r.nodes.empty() ? 0.0 : static_cast<double>(r.nodes.back().tick) * in.model->interp.period);
    s += ",\"linearisation\":{\"splits\":" + std::to_string(r.linearisation_splits) + ",\"max_deviation_mm\":";
    num(s, r.linearisation_max_deviation);
    s += ",\"source_tcp_blocks_needing_split\":" + std::to_string(r.source_blocks_needing_split) +
         ",\"source_joint_linear_deviation_mm\":";
    num(s, r.source_joint_linear_deviation);
    s += "},\"iterations\":[";
    for (std::size_t k = 0; k < r.iterations.size(); ++k) {
      const Iteration& it = r.iterations[k];
      if (k) s += ',';
      s += "{\"index\":" + std::to_string(it.index) + ",\"max_contour_mm\":";
      num(s, it.max_contour);
      s += ",\"rms_contour_mm\":";
      num(s, it.rms_contour);
      s += ",\"gain\":";
      num(s, it.gain);
      s += ",\"accepted\":";
      s += it.accepted ? "true" : "false";
      if (!it.accepted) {
        s += ",\"rejected_because\":";
        append_json_string(s, it.rejected_because);
      }
      s += '}';
    }
    s += ']';
  }
  s += ",\"best_kffp\":{";
  if (in.best_kffp.ok) {
    s += "\"omega_rad_s\":";
    num(s, in.best_kffp_omega);
    s += ",\"rotary_lag_rad\":";
    num(s, in.best_kffp.alpha);
    s += ",\"X_percent\":";
    num(s, in.best_kffp.K_FFP[0]);
    s += ",\"Y_percent\":";
    num(s, in.best_kffp.K_FFP[1]);
  } else {
    s += "\"note\":";
    append_json_string(s, in.best_kffp_note.empty() ? in.best_kffp.message : in.best_kffp_note);
  }
  s += "},\"best_kffp_per_segment\":[";
  for (std::size_t k = 0; k < in.segment_kffp.size(); ++k) {
    const auto& [seg, v] = in.segment_kffp[k];
    if (k) s += ',';
    s += "{\"first_line\":" + std::to_string(in.nominal->segments[seg].first_line) + ",\"omega_rad_s\":";
    num(s, v.first);
    if (v.second.ok) {
      s += ",\"X_percent\":";
      num(s, v.second.K_FFP[0]);
      s += ",\"Y_percent\":";
      num(s, v.second.K_FFP[1]);
    } else {
      s += ",\"note\":";
      append_json_string(s, v.second.message);
    }
    s += '}';
  }
  s += "]}";
  return s;
}

std::string report_text(const ReportInput& in) {
  std::string s;
  char buf[400];
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
  if (in.result && !in.result->note.empty()) s += "  compensation: " + in.result->note + "\n";
  if (in.result && !in.result->nodes.empty()) {
    std::snprintf(buf, sizeof buf, "  compensated program runs %.3f s (original %.3f s: the reference stops at corners, starts and stops)\n",
                  static_cast<double>(in.result->nodes.back().tick) * in.model->interp.period,
                  static_cast<double>(in.nominal->raw.size()) * in.model->interp.period);
    s += buf;
  }
  for (std::size_t k = 0; k < in.nominal->segments.size(); ++k) {
    const Segment& g = in.nominal->segments[k];
    const ErrorStats& e0 = in.before->per_segment[k];
    if (e0.max == 0 && (!in.after || in.after->per_segment[k].max == 0)) continue;
    int n = std::snprintf(buf, sizeof buf, "    lines %llu-%llu (t %.2f-%.2f s)%s: max %.2f um", static_cast<unsigned long long>(g.first_line),
                          static_cast<unsigned long long>(g.last_line), g.t_begin, g.t_end, g.circle ? ", circle" : "", e0.max * 1e3);
    if (in.after && k < in.after->per_segment.size())
      std::snprintf(buf + n, sizeof buf - static_cast<std::size_t>(n), " -> %.2f um (%.1fx)", in.after->per_segment[k].max * 1e3,
                    ratio(e0.max, in.after->per_segment[k].max));
    s += buf;
    s += '\n';
  }
  s += "  following error max (command - actual), before";
  s += in.after ? " / after:" : ":";
  for (int i = 0; i < kNumAxes; ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (in.after)
      std::snprintf(buf, sizeof buf, " %c %.4g/%.4g", kAxisLetters[i], in.before->axes.max_following[k], in.after->axes.max_following[k]);
    else
      std::snprintf(buf, sizeof buf, " %c %.4g", kAxisLetters[i], in.before->axes.max_following[k]);
    s += buf;
  }
  s += " (mm, deg)\n  travel margin min:";
  const AxisStats& m = in.after ? in.after->axes : in.before->axes;
  for (int i = 0; i < kNumAxes; ++i) {
    std::snprintf(buf, sizeof buf, " %c %.4g", kAxisLetters[i], m.travel_margin[static_cast<std::size_t>(i)]);
    s += buf;
  }
  s += " (mm, deg)\n";
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
  return s;
}

}  // namespace gcpipe::compensate
