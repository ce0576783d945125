// gcpipe evaluate: the measured tool-tip contour error of a real run against the program's
// nominal path, cutting and rapid moves apart.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>
#include <nlohmann/json.hpp>

#include "calibrate.hpp"
#include "contour.hpp"
#include "gcpipe/kinematics.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "parse.hpp"

namespace gcpipe::calibrate {

namespace {

struct NominalPath {
  std::vector<Vec3> tip;
  std::vector<std::uint32_t> block;
};

NominalPath nominal_path(const compensate::Model& model, std::span<const ResolvedBlock> program) {
  std::size_t first = 0;
  while (first < program.size() && program[first].motion == Motion::kNone) ++first;
  if (first == program.size()) throw std::runtime_error("the program moves nothing");
  const Axes start = compensate::machine_start(model.kin, program[first], compensate::tool_length_of(model, program[first]));
  NominalPath p;
  const auto st = compensate::run_program(model, program, start, [&](const compensate::Tick& t) {
    const Vec3 tip = forward_kinematics(model.kin, t.raw, compensate::tool_length_of(model, program[t.block])).tip;
    if (!p.tip.empty() && tip == p.tip.back()) return;  // dwells add nothing to the path
    p.tip.push_back(tip);
    p.block.push_back(t.block);
  });
  if (!st.ok) throw std::runtime_error("line " + std::to_string(st.failed_line) + ": " + st.message);
  return p;
}

/// Nearest segment to `q` among [from, from + window), and a few behind; returns its index.
std::size_t nearest(const NominalPath& p, const Vec3& q, std::size_t from, std::size_t window, double& dist) {
  const std::size_t lo = from > 50 ? from - 50 : 0, hi = std::min(p.tip.size() - 1, from + window);
  std::size_t best = lo;
  dist = std::numeric_limits<double>::infinity();
  for (std::size_t i = lo; i < std::max(hi, lo + 1) && i + 1 < p.tip.size(); ++i) {
    const double d = servo::segment_distance(p.tip[i], p.tip[i + 1], q);
    if (d < dist) { dist = d; best = i; }
  }
  if (p.tip.size() == 1) dist = std::sqrt(std::pow(q[0] - p.tip[0][0], 2) + std::pow(q[1] - p.tip[0][1], 2) + std::pow(q[2] - p.tip[0][2], 2));
  return best;
}

}  // namespace

ContourFigures measured_contour_error(const compensate::Model& model, std::span<const ResolvedBlock> program,
                                      const MeasuredTrace& trace) {
  const NominalPath path = nominal_path(model, program);
  ContourFigures f;
  double sc = 0, sr = 0;
  std::size_t at = 0;
  for (std::size_t k = 0; k < trace.size(); ++k) {
    Axes j{};
    for (int a = 0; a < kNumAxes; ++a) j[a] = trace.actual[a][k];
    // The tool tip with the tool length in force where the run was one sample ago (G43 H..):
    // the measured joints alone do not say which tool is in the spindle.
    const double tool = compensate::tool_length_of(model, program[path.block[at]]);
    const Vec3 q = forward_kinematics(model.kin, j, tool).tip;
    double d = 0;
    // The first sample searches the whole path (where the run starts); afterwards the match
    // moves forward with the run, so a path passing close by elsewhere is never taken.
    at = nearest(path, q, k == 0 ? 0 : at, k == 0 ? path.tip.size() : 2000, d);
    const Motion m = program[path.block[at]].motion;
    if (m == Motion::kRapid) {
      ++f.rapid_samples;
      sr += d * d;
      f.rapid_max = std::max(f.rapid_max, d);
    } else {
      ++f.cutting_samples;
      sc += d * d;
      if (d > f.cutting_max) { f.cutting_max = d; f.t_at_cutting_max = trace.t[k]; f.line_at_cutting_max = program[path.block[at]].line; }
    }
  }
  f.cutting_rms = std::sqrt(sc / static_cast<double>(std::max<std::size_t>(1, f.cutting_samples)));
  f.rapid_rms = std::sqrt(sr / static_cast<double>(std::max<std::size_t>(1, f.rapid_samples)));
  return f;
}

namespace {

std::vector<ResolvedBlock> parse_program(const std::string& path, const PipelineConfig& pc, std::ostream& err, bool& ok) {
  std::ifstream in(path);
  std::vector<ResolvedBlock> out;
  if (!in) { err << path << ": cannot open the program\n"; ok = false; return out; }
  Parser parser(load_parse_options(pc.root.section("parse")), pc.machine, path);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  int shown = 0;
  feed_text(parser, text,
            {[&out](const ResolvedBlock& b) {
               out.push_back(b);
               return true;
             },
             [&](const Diagnostic& d) {
               if (d.severity == Severity::kError && shown++ < 20) err << format(d) << "\n";
               return true;
             }});
  return out;
}

}  // namespace

int run_evaluate(const EvaluateRequest& q, std::ostream& out, std::ostream& err) {
  if (q.trace.empty() || q.program.empty() || q.config.empty()) {
    err << "usage: gcpipe evaluate --trace MEASURED.csv --program PROG.nc --config CFG [--format csv|umich] [--skip-bad-rows] [--json OUT.json]\n";
    return 2;
  }
  try {
    const PipelineConfig pc = load_pipeline_config(q.config);
    const compensate::Model model = compensate::load_model(pc);
    bool ok = true;
    const auto program = parse_program(q.program, pc, err, ok);
    if (!ok) return 1;
    ReadOptions o;
    o.skip_bad_rows = q.skip_bad_rows;
    if (q.format) o.format = parse_format(*q.format);
    ReadResult r = read_trace_file(q.trace, o);
    for (std::size_t i = 0; i < r.diagnostics.size() && i < 20; ++i) err << format(r.diagnostics[i]) << "\n";
    if (!r.trace) { err << q.trace << ": trace rejected\n"; return 1; }
    const ContourFigures f = measured_contour_error(model, program, *r.trace);
    out << q.trace << ": measured contour error against " << q.program << "\n"
        << "  cutting (G1 G2 G3): max " << f.cutting_max * 1000 << " um at t = " << f.t_at_cutting_max << " s (line "
        << f.line_at_cutting_max << "), rms " << f.cutting_rms * 1000 << " um over " << f.cutting_samples << " samples\n"
        << "  rapid (G0): max " << f.rapid_max * 1000 << " um, rms " << f.rapid_rms * 1000 << " um over " << f.rapid_samples << " samples\n";
    if (q.json) {
      nlohmann::json j = {{"trace", q.trace}, {"program", q.program},
                          {"cutting", {{"max_um", f.cutting_max * 1000}, {"rms_um", f.cutting_rms * 1000}, {"samples", f.cutting_samples}, {"t_at_max_s", f.t_at_cutting_max}, {"line_at_max", f.line_at_cutting_max}}},
                          {"rapid", {{"max_um", f.rapid_max * 1000}, {"rms_um", f.rapid_rms * 1000}, {"samples", f.rapid_samples}}}};
      std::ofstream(*q.json + ".part") << j.dump(2) << "\n";
      std::filesystem::rename(*q.json + ".part", *q.json);
    }
    return r.trace->rows_skipped > 0 || r.trace->rows_unused > 0 ? 3 : 0;
  } catch (const std::exception& e) {
    err << "gcpipe evaluate: " << e.what() << "\n";
    return 1;
  }
}

}  // namespace gcpipe::calibrate
