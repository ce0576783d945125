// gcpipe evaluate: the measured tool-tip contour error of a real run against the program's
// nominal path, cutting and rapid moves apart.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>

#include "calibrate.hpp"
#include "simulate.hpp"
#include "gcpipe/kinematics.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "parse.hpp"

namespace gcpipe::calibrate {

namespace {

/// The program's nominal tool-tip path as the simulate stage builds it: one raw interpolated
/// tick after another, repeated points dropped, with the path index each tick has reached.
struct NominalPath {
  std::vector<Vec3> pts;                     //!< polyline for simulate::ContourSearch
  std::vector<std::uint32_t> index_of_tick;  //!< newest polyline index reached at tick n
  std::vector<std::uint32_t> block;          //!< program block of tick n
  std::vector<Axes> raw;                     //!< raw joints of tick n
  double period = 0;
};

NominalPath nominal_path(const compensate::Model& model, std::span<const ResolvedBlock> program) {
  std::size_t first = 0;
  while (first < program.size() && program[first].motion == Motion::kNone) ++first;
  if (first == program.size()) throw std::runtime_error("the program moves nothing");
  const Axes start = compensate::machine_start(model.kin, program[first], compensate::tool_length_of(model, program[first]));
  NominalPath p;
  p.period = model.interp.period;
  const auto st = compensate::run_program(model, program, start, [&](const compensate::Tick& t) {
    const Vec3 tip = forward_kinematics(model.kin, t.raw, compensate::tool_length_of(model, program[t.block])).tip;
    if (p.pts.empty() || simulate::dist3(p.pts.back(), tip) > 1e-9) p.pts.push_back(tip);  // as simulate's nominal
    p.index_of_tick.push_back(static_cast<std::uint32_t>(p.pts.size() - 1));
    p.block.push_back(t.block);
    p.raw.push_back(t.raw);
  });
  if (!st.ok) throw std::runtime_error("line " + std::to_string(st.failed_line) + ": " + st.message);
  if (p.pts.size() < 2) throw std::runtime_error("the program's tool tip does not move");
  return p;
}

/// First sample at which any commanded axis has left its first value; `size` when none does.
template <typename At>
std::size_t first_motion(std::size_t size, const At& at) {
  for (std::size_t k = 1; k < size; ++k)
    for (int a = 0; a < kNumAxes; ++a)
      if (std::abs(at(k, a) - at(0, a)) > 1e-9) return k;
  return size;
}

/// Which nominal tick a trace sample stands for: the trace's first commanded motion is the
/// program's first interpolated motion, and time runs on from there. (A run recorded on another
/// clock than the program's own, e.g. with the feed override off 100 %, is not aligned.)
struct Clock {
  std::size_t trace_start = 0, nominal_start = 0;
  double t0 = 0, period = 0;
  std::size_t tick(const MeasuredTrace& tr, std::size_t k) const {
    if (k <= trace_start) return nominal_start;
    return nominal_start + static_cast<std::size_t>(std::llround((tr.t[k] - t0) / period));
  }
};

Clock align(const NominalPath& p, const MeasuredTrace& tr) {
  Clock c;
  c.period = p.period;
  c.trace_start = first_motion(tr.size(), [&](std::size_t k, int a) { return tr.command[a][k]; });
  if (c.trace_start == tr.size()) throw std::runtime_error(tr.file + ": the commanded positions never move");
  c.trace_start -= 1;  // the last sample at rest
  c.nominal_start = first_motion(p.raw.size(), [&](std::size_t n, int a) { return p.raw[n][a]; }) - 1;
  c.t0 = tr.t[c.trace_start];
  return c;
}

void add_sample(ContourFigures& f, double& sc, double& sr, const ResolvedBlock& b, double d, double t) {
  // The simulate stage's rule: rapids position the tool and do not cut; feed moves and dwells do.
  if (b.motion == Motion::kRapid) {
    ++f.rapid_samples;
    sr += d * d;
    f.rapid_max = std::max(f.rapid_max, d);
  } else if (b.motion == Motion::kNone) {
    ++f.idle_samples;
  } else {
    ++f.cutting_samples;
    sc += d * d;
    if (d > f.cutting_max) { f.cutting_max = d; f.t_at_cutting_max = t; f.line_at_cutting_max = b.line; }
  }
}

}  // namespace

ContourFigures measured_contour_error(const compensate::Model& model, std::span<const ResolvedBlock> program,
                                      const MeasuredTrace& trace) {
  const NominalPath path = nominal_path(model, program);
  const Clock clock = align(path, trace);
  // The actual may run slightly ahead of the aligned nominal (a trace clock a little fast): the
  // search may look this far ahead, as the simulate stage does for a re-timed run.
  const auto ahead = static_cast<std::size_t>(std::ceil(0.3 / path.period));
  simulate::ContourSearch search(path.pts);
  ContourFigures f;
  double sc = 0, sr = 0;
  for (std::size_t k = 0; k < trace.size(); ++k) {
    if (k < clock.trace_start) {  // at rest before the program's first motion: not part of the run
      ++f.idle_samples;
      continue;
    }
    const std::size_t n = std::min(clock.tick(trace, k), path.block.size() - 1);
    const ResolvedBlock& b = program[path.block[n]];
    Axes j{};
    for (int a = 0; a < kNumAxes; ++a) j[a] = trace.actual[a][k];
    const Vec3 q = forward_kinematics(model.kin, j, compensate::tool_length_of(model, b)).tip;
    Vec3 nearest;
    const std::size_t limit = path.index_of_tick[std::min(n + ahead, path.index_of_tick.size() - 1)];
    add_sample(f, sc, sr, b, search.distance(q, limit, nearest), trace.t[k]);
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
    err << "usage: gcpipe evaluate --trace MEASURED.csv --program PROG.nc --config CFG [--format csv|umich|halsampler|shdr] [--columns LIST] [--period S] [--skip-bad-rows] [--json OUT.json]\n";
    return 2;
  }
  try {
    const PipelineConfig pc = load_pipeline_config(q.config);
    const compensate::Model model = compensate::load_model(pc);
    bool ok = true;
    const auto program = parse_program(q.program, pc, err, ok);
    if (!ok) return 1;
    ReadOptions o;
    if (!read_options(q.format, q.columns, q.period, q.skip_bad_rows, o, err)) return 2;
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
