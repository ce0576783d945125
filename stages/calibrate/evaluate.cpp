// gcpipe evaluate: the measured tool-tip contour error of a real run against the program's
// nominal path, cutting and rapid moves apart.
#include <algorithm>
#include <cmath>
#include <deque>
#include <fstream>
#include <iterator>
#include <sstream>
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
  std::vector<Axes> command;                 //!< smoothed commands of tick n (what the drives get)
  double period = 0;
};

/// Under the look-ahead control the machine runs the control's plan of the path: the commands,
/// blocks and the polyline index reached are those of the plan's ticks (simulate_program, the
/// plan with the compensate section's defaults), the polyline the path's own.
void on_the_plans_clock(const compensate::Model& model, std::span<const ResolvedBlock> program, NominalPath& p) {
  std::vector<std::uint32_t> raw_index = std::move(p.index_of_tick);
  p.index_of_tick.clear(), p.block.clear(), p.raw.clear(), p.command.clear();
  const simulate::SimulationRun run = simulate::simulate_program(model, program, simulate::RunBounds{});
  if (!run.before) throw std::runtime_error(run.note);
  const simulate::Nominal& nom = *run.nominal;
  for (std::size_t n = 0; n < nom.reference.size(); ++n) {
    const std::size_t k = std::min<std::size_t>(nom.progress[n], raw_index.size() - 1);
    p.index_of_tick.push_back(raw_index[k]);
    p.block.push_back(nom.block[k]);
    p.raw.push_back(nom.raw[k]);
    p.command.push_back(nom.reference[n]);
  }
}

NominalPath nominal_path(const compensate::Model& model, std::span<const ResolvedBlock> program, bool planned = true) {
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
    p.command.push_back(t.command);
  });
  if (!st.ok) throw std::runtime_error("line " + std::to_string(st.failed_line) + ": " + st.message);
  if (p.pts.size() < 2) throw std::runtime_error("the program's tool tip does not move");
  if (planned && model.interp.control == interpolate::Control::kLookahead) on_the_plans_clock(model, program, p);
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

// --- does the trace run the program? ---
//
// The nominal commands are the control model's smoothed commands (Tick::command: after the
// interpolator's acc/dec), not its raw interpolated joints (Tick::raw): a control logs what its
// drives are given (LinuxCNC's motor-pos-cmd, a Fanuc or Heidenhain "nominal position" after
// acc/dec), simulate_trace and the simulate stage's trace record Tick::command, and raw and
// smoothed differ by the acc/dec lag (tens of ms times the feed: far above any tolerance here).
//
// The rule, per trace sample k from the first commanded motion on and per axis a:
//   deviation = distance of the trace's command from the range of the nominal commands over the
//               ticks n(k) - w .. n(k) + w (n(k): the aligned tick, moved by the best shift),
//   tolerance = floor_a + q_a + 0.25 x the model's acc/dec lag |raw - command| (its largest over
//               the ticks n(k) - w - 3 Ts .. n(k) + w, Ts the axis's acc/dec time constant),
// refused at the first sample whose deviation is above its tolerance. With
//   w       = 3 ticks + one trace period: the sample instant is known to a trace period (a trace
//             sampled on another clock, or its first motion seen a sample late), and a control
//             whose acc/dec differs a little from the model's lags or leads it by a few ms;
//   floor_a = 0.05 mm / 0.05 deg: a real control's commands are not the model's to the micrometre
//             (acc/dec shape, look-ahead), a different program is off by far more;
//   q_a     = the trace's own command resolution when its values lie on a decimal grid
//             (command_resolution(): UMich logs X in whole millimetres, Y and Z in tenths), since
//             a rounded command is within one step of the true one;
//   0.25 x lag: a control whose acc/dec time constants are up to 20 % off the model's lags its
//             commands behind its raw interpolation by up to 20 % more or less: a constant lag
//             is taken up by the shift; what is left shows where the speed changes (a rapid's
//             stop, a corner) and lasts about three time constants. Measured
//             (CalibrateEvaluate.AControlWithAccDecTenPercentOffAndAnotherSampleClockPasses):
//             Ts x 0.8 / 0.9 / 1.1 / 1.2 with commands sampled half a tick late reach 0.51 / 0.26
//             / 0.25 / 0.50 of the tolerance on the circle, 0.62 / 0.30 / 0.29 / 0.69 on the
//             five-axis move; the circle at 0.3 mm more radius is refused (tolerance 0.29 mm
//             there), the circle with one turn reversed (G2 -> G3) at that line.
// The shift is the one of -S..S ticks (S = 5 ticks, two trace periods or 0.25 x the longest
// acc/dec time constant, whichever is more: the lag a control with acc/dec 20 % off adds)
// with the least mean squared deviation: a few samples, not a search for where in the program
// the trace might be. Before the comparison, an axis whose commands move (a range above its
// tolerance) in one and not in the other is refused; after it, a commanded motion (first to last
// change of any command) shorter or longer than the program's nominal by more than 5 % (at least
// 0.1 s or two trace periods) is refused.
//
// Not a tolerance: the commands of a compensated program (compensated.nc). They are not the
// original's nominal commands, not even in time (the compensation re-times moves: the circle's
// rapid runs centimetres behind the original's), so run_evaluate checks such a trace against the
// program it ran (--ran) and measures it against the original (--program).
namespace {

constexpr double kFloor = 0.05;          // [mm, deg]
constexpr double kDurationShare = 0.05;  // of the nominal duration
constexpr double kAccDecShare = 0.25;    // of the model's acc/dec lag

std::string unit_of(int a) { return a >= kA ? " deg" : " mm"; }

std::string fixed(double v, int digits) {
  std::ostringstream o;
  o.setf(std::ios::fixed);
  o.precision(digits);
  o << v;
  return o.str();
}

/// Last index at which any axis of `at` changes by more than 0.5 um from the index before.
template <typename At>
std::size_t last_motion(std::size_t size, const At& at) {
  for (std::size_t k = size; k-- > 1;)
    for (int a = 0; a < kNumAxes; ++a)
      if (std::abs(at(k, a) - at(k - 1, a)) > 5e-7) return k;
  return 0;
}

}  // namespace

double command_resolution(const std::vector<double>& v) {
  std::size_t changes = 0;
  for (std::size_t k = 1; k < v.size(); ++k) changes += std::abs(v[k] - v[k - 1]) > 1e-12 ? 1 : 0;
  if (changes < 5) return 0;  // a still axis is on every grid: nothing to read from it
  // A log rounds to a number of decimals (UMich: X to whole millimetres, Y and Z to 0.1 mm): the
  // coarsest decimal grid that (nearly) every value lies on.
  for (const double q : {1.0, 0.5, 0.1, 0.05, 0.01, 0.005, 0.001, 0.0005, 0.0001}) {
    std::size_t on = 0;
    for (double x : v) on += std::abs(x / q - std::round(x / q)) < 1e-3 ? 1 : 0;
    if (static_cast<double>(on) >= 0.99 * static_cast<double>(v.size())) return q;
  }
  return 0;
}

ProgramMatch check_trace_runs_program(const compensate::Model& model, std::span<const ResolvedBlock> program,
                                      const MeasuredTrace& trace, const std::string& program_name, bool planned) {
  const NominalPath path = nominal_path(model, program, planned);
  Clock clock = align(path, trace);
  const std::size_t N = path.command.size();
  const double T = path.period;
  const double trace_period = trace.period > 0 ? trace.period : T;
  ProgramMatch m;
  Axes base{};  // tolerance per axis
  for (int a = 0; a < kNumAxes; ++a) {
    m.resolution[a] = command_resolution(trace.command[a]);
    base[a] = kFloor + m.resolution[a];
  }
  // align() takes the first raw motion of the program; a trace's command is smoothed and, when
  // quantised, changes only once the motion has covered half a step. So the first motion of the
  // nominal commands is taken the same way: the first tick whose command has moved by more than
  // half the trace's step on some axis (first to move at all when it is not quantised).
  {
    std::size_t n = 1;
    for (bool moved = false; n < N && !moved; ++n)
      for (int a = 0; a < kNumAxes && !moved; ++a)
        moved = std::abs(path.command[n][a] - path.command[0][a]) > std::max(1e-9, 0.5 * m.resolution[a]);
    clock.nominal_start = n - 2;  // the last tick before that motion, as align()
  }
  const std::string head = trace.file + ": the commanded positions are not a run of " + program_name + ": ";
  const std::string advice = " Is this the trace of " + program_name +
                             "? Was the feed override at 100 %? Pass the program the trace ran (a run of a compensated "
                             "program: --ran COMPENSATED.nc, and the original as --program).";
  const auto trace_time_of_tick = [&](std::size_t n) {
    return clock.t0 + (static_cast<double>(n) - static_cast<double>(clock.nominal_start)) * T;
  };
  const auto line_at = [&](std::size_t n) { return program[path.block[std::min(n, N - 1)]].line; };

  // 1. The axes that move.
  for (int a = 0; a < kNumAxes; ++a) {
    const auto& c = trace.command[a];
    const auto [lo, hi] = std::minmax_element(c.begin() + static_cast<long>(clock.trace_start), c.end());
    double nlo = path.command[clock.nominal_start][a], nhi = nlo;
    for (std::size_t n = clock.nominal_start; n < N; ++n) {
      nlo = std::min(nlo, path.command[n][a]);
      nhi = std::max(nhi, path.command[n][a]);
    }
    const bool in_trace = *hi - *lo > base[a], in_program = nhi - nlo > base[a];
    if (in_trace == in_program) continue;
    m.part = ProgramMatch::Part::kAxes;
    m.axis = a;
    m.tolerance = base[a];
    std::ostringstream o;
    if (in_trace) {
      const double v0 = c[clock.trace_start];
      std::size_t k = clock.trace_start;
      while (k + 1 < c.size() && std::abs(c[k] - v0) <= base[a]) ++k;  // a range above base[a] may stay within it of v0
      m.sample = k;
      m.t = trace.t[k];
      m.trace_value = c[k];
      const std::size_t n = std::min(clock.tick(trace, k), N - 1);
      m.nominal_value = path.command[n][a];
      m.line = line_at(n);
      m.deviation = std::abs(m.trace_value - m.nominal_value);
      o << head << "axis " << kAxisLetters[a] << " moves in the trace (from t = " << fixed(m.t, 3) << " s, sample " << k
        << ": " << kAxisLetters[a] << " = " << fixed(m.trace_value, 3) << unit_of(a) << ") but not in " << program_name
        << " (nominal " << fixed(m.nominal_value, 3) << unit_of(a) << ", line " << m.line << ", over a range of "
        << fixed(nhi - nlo, 3) << unit_of(a) << ").";
    } else {
      const double v0 = path.command[clock.nominal_start][a];
      std::size_t n = clock.nominal_start;
      while (n + 1 < N && std::abs(path.command[n][a] - v0) <= base[a]) ++n;
      m.t = trace_time_of_tick(n);
      m.sample = static_cast<std::size_t>(std::lower_bound(trace.t.begin(), trace.t.end(), m.t) - trace.t.begin());
      m.nominal_value = path.command[n][a];
      m.trace_value = c[std::min(m.sample, c.size() - 1)];
      m.line = line_at(n);
      m.deviation = std::abs(m.trace_value - m.nominal_value);
      o << head << "axis " << kAxisLetters[a] << " moves in " << program_name << " (from line " << m.line << ", at t = "
        << fixed(m.t, 3) << " s of the trace, sample " << m.sample << ": nominal " << kAxisLetters[a] << " = "
        << fixed(m.nominal_value, 3) << unit_of(a) << ") but not in the trace (commanded " << fixed(m.trace_value, 3)
        << unit_of(a) << ", over a range of " << fixed(*hi - *lo, 3) << unit_of(a) << ").";
    }
    m.message = o.str() + advice;
    return m;
  }

  // 2. The best shift of a few ticks around the first-motion alignment.
  double max_ts = 0;
  for (double ts : model.interp.smoothing_time) max_ts = std::max(max_ts, ts);
  const auto S = static_cast<long>(std::max({5.0, std::ceil(2 * trace_period / T), std::ceil(kAccDecShare * max_ts / T)}));  // see above
  const std::size_t count = trace.size() - clock.trace_start;
  const std::size_t stride = std::max<std::size_t>(1, count / 20000);
  const auto nominal_at = [&](std::size_t k, long s) {  // at rest before the first motion
    const long n = static_cast<long>(clock.tick(trace, k)) + (k > clock.trace_start ? s : 0);
    return static_cast<std::size_t>(std::clamp<long>(n, 0, static_cast<long>(N) - 1));
  };
  double best = INFINITY;
  for (long s = -S; s <= S; ++s) {
    double e = 0;
    for (std::size_t k = clock.trace_start; k < trace.size(); k += stride) {
      const Axes& nom = path.command[nominal_at(k, s)];
      for (int a = 0; a < kNumAxes; ++a) e += std::pow((trace.command[a][k] - nom[a]) / base[a], 2);
    }
    if (e < best) { best = e; m.shift_ticks = s; }
  }

  // 3. Sample by sample.
  const auto w = static_cast<long>(3 + std::ceil(trace_period / T - 1e-9));
  // The largest acc/dec lag over the ticks n - w - 3 Ts .. n + w: after a change of speed the
  // lags of two acc/dec time constants part for about three of them (an exponential's tail).
  std::array<std::vector<double>, kNumAxes> lag;
  for (int a = 0; a < kNumAxes; ++a) {
    const auto back = static_cast<std::size_t>(w + std::ceil(3 * model.interp.smoothing_time[a] / T));
    const auto ahead = static_cast<std::size_t>(w);
    lag[a].assign(N, 0.0);
    std::deque<std::size_t> q;  // indices of decreasing lags in the window
    const auto lag_at = [&](std::size_t i) { return std::abs(path.raw[i][a] - path.command[i][a]); };
    std::size_t next = 0;       // next index to enter the window
    for (std::size_t n = 0; n < N; ++n) {
      for (; next < N && next <= n + ahead; ++next) {
        while (!q.empty() && lag_at(q.back()) <= lag_at(next)) q.pop_back();
        q.push_back(next);
      }
      while (q.front() + back < n) q.pop_front();
      lag[a][n] = lag_at(q.front());
    }
  }
  for (std::size_t k = clock.trace_start; k < trace.size(); ++k) {
    const std::size_t n = nominal_at(k, m.shift_ticks);
    for (int a = 0; a < kNumAxes; ++a) {
      const double v = trace.command[a][k];
      double lo = INFINITY, hi = -INFINITY;
      for (long j = static_cast<long>(n) - w; j <= static_cast<long>(n) + w; ++j) {
        const auto i = static_cast<std::size_t>(std::clamp<long>(j, 0, static_cast<long>(N) - 1));
        lo = std::min(lo, path.command[i][a]);
        hi = std::max(hi, path.command[i][a]);
      }
      const double d = std::max({0.0, lo - v, v - hi});
      const double tol = base[a] + kAccDecShare * lag[a][n];
      m.worst = std::max(m.worst, d / tol);
      if (d <= tol) continue;
      m.part = ProgramMatch::Part::kCommands;
      m.axis = a;
      m.sample = k;
      m.t = trace.t[k];
      m.trace_value = v;
      m.nominal_value = path.command[n][a];
      m.deviation = d;
      m.tolerance = tol;
      m.line = line_at(n);
      std::ostringstream o;
      o << head << "they part at t = " << fixed(m.t, 3) << " s (sample " << k << "): the trace commands "
        << kAxisLetters[a] << " = " << fixed(v, 3) << unit_of(a) << " where the program's nominal is "
        << fixed(m.nominal_value, 3) << unit_of(a) << " (line " << m.line << "), " << fixed(d, 3) << unit_of(a)
        << " outside what the program commands within " << fixed(static_cast<double>(w) * T * 1000, 0)
        << " ms of that time (tolerance " << fixed(tol, 3) << unit_of(a) << ")";
      if (static_cast<long>(clock.tick(trace, k)) + m.shift_ticks >= static_cast<long>(N))
        o << "; the program's run has ended there: the trace goes on moving";
      m.message = o.str() + "." + advice;
      return m;
    }
  }

  // 4. How long the commanded motion lasts.
  const std::size_t trace_end = last_motion(trace.size(), [&](std::size_t k, int a) { return trace.command[a][k]; });
  const std::size_t nominal_end = last_motion(N, [&](std::size_t n, int a) { return path.command[n][a]; });
  m.trace_duration = trace.t[std::max(trace_end, clock.trace_start)] - clock.t0;
  m.nominal_duration = static_cast<double>(nominal_end - std::min(nominal_end, clock.nominal_start)) * T;
  const double diff = m.trace_duration - m.nominal_duration;
  const double allowed = std::max({kDurationShare * m.nominal_duration, 0.1, 2 * trace_period});
  if (std::abs(diff) > allowed) {
    m.part = ProgramMatch::Part::kDuration;
    std::ostringstream o;
    o << head << "its commanded motion lasts " << fixed(m.trace_duration, 3) << " s, the program's nominal "
      << fixed(m.nominal_duration, 3) << " s: the trace is " << (diff < 0 ? "shorter" : "longer") << " by "
      << fixed(std::abs(diff), 3) << " s (" << fixed(100 * std::abs(diff) / std::max(m.nominal_duration, 1e-9), 1)
      << " %; allowed " << fixed(allowed, 3) << " s)" << (diff < 0 ? ", though the commands agree as far as it goes. Was the recording stopped early?" : ".")
      << advice;
    m.message = o.str();
  }
  return m;
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
    err << "usage: gcpipe evaluate --trace MEASURED.csv --program PROG.nc --config CFG [--format csv|umich|halsampler|shdr] [--columns LIST] [--period S] [--skip-bad-rows] [--ran COMPENSATED.nc] [--json OUT.json]\n";
    return 2;
  }
  try {
    const PipelineConfig pc = load_pipeline_config(q.config);
    const compensate::Model model = compensate::load_model(pc);
    bool ok = true;
    const auto program = parse_program(q.program, pc, err, ok);
    if (!ok) return 1;
    // The program the machine ran, when it is not the one measured against (its compensated.nc).
    const auto ran = q.ran ? parse_program(*q.ran, pc, err, ok) : std::vector<ResolvedBlock>{};
    if (!ok) return 1;
    ReadOptions o;
    if (!read_options(q.format, q.columns, q.period, q.skip_bad_rows, o, err)) return 2;
    ReadResult r = read_trace_file(q.trace, o);
    for (std::size_t i = 0; i < r.diagnostics.size() && i < 20; ++i) err << format(r.diagnostics[i]) << "\n";
    if (!r.trace) { err << q.trace << ": trace rejected\n"; return 1; }
    // A trace of another program would be scored against the wrong path: refused before measuring.
    if (const ProgramMatch m = q.ran ? check_trace_runs_program(model, ran, *r.trace, *q.ran, false)
                                     : check_trace_runs_program(model, program, *r.trace, q.program);
        !m.ok()) {
      err << "gcpipe evaluate: " << m.message << "\n";
      return 1;
    }
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
