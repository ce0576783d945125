#include "spindle_model.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "gcpipe/config.hpp"
#include "gcpipe/number_format.hpp"

namespace gcpipe::force {

namespace {

constexpr const char* kFormat = "gcpipe spindle NNOE 1";
constexpr double kUmichPeriod = 0.1;  // the runs' 100 ms samples (../shared/data/PROVENANCE.md)
constexpr std::size_t kTable1Rows = 5;  // compare_on_umich's rows before the ablation

// The data set does not state the unit of the spindle's power or of its commanded velocity. The
// velocity is 0 or 53.3 in every fit run and is read as rev/s (3200 rev/min): an assumption, written
// into the model as the channel's unit (stages/force/README.md sec. 8b). The current is in A.
constexpr const char* kPowerUnit = "unit not stated by the data set (S1_OutputPower as recorded)";
constexpr const char* kUmichData =
    "University of Michigan SMART mill runs (CC0): wax, low load; no force or depth of cut recorded";

SpindleChannel channel(std::string name, std::string unit, const std::vector<double>& x) {
  const auto [lo, hi] = std::minmax_element(x.begin(), x.end());
  return {std::move(name), std::move(unit), x.empty() ? 0 : *lo, x.empty() ? 0 : *hi};
}

std::vector<std::string> names_of(const std::vector<std::filesystem::path>& files) {
  std::vector<std::string> out;
  for (const auto& f : files) out.push_back(f.filename().string());
  return out;
}

UmichRun read_runs(const std::vector<std::filesystem::path>& files) {
  std::vector<UmichRun> runs;
  for (const auto& f : files) runs.push_back(read_umich_run(f));
  return concatenate(runs);
}

std::size_t lowest_verification_fpe(const std::vector<StructureScore>& table) {
  std::size_t best = 0;
  for (std::size_t i = 1; i < std::min(kTable1Rows, table.size()); ++i)
    if (table[i].verification_fpe < table[best].verification_fpe) best = i;
  return best;
}

// --- the model file ------------------------------------------------------------------------

std::string quoted(const std::string& s) {
  std::string out;
  append_json_string(out, s);  // a JSON string is a YAML double-quoted scalar
  return out;
}

std::string number_text(double v) {
  std::string out;
  append_json_number(out, v);
  return out;
}

template <class T, class F>
std::string list_text(const std::vector<T>& xs, F text) {
  std::string out = "[";
  for (std::size_t i = 0; i < xs.size(); ++i) out += (i ? ", " : "") + text(xs[i]);
  return out + "]";
}

std::string numbers_text(const std::vector<double>& xs) { return list_text(xs, number_text); }
std::string strings_text(const std::vector<std::string>& xs) { return list_text(xs, quoted); }

std::vector<std::string> channel_names(const std::vector<SpindleChannel>& cs) {
  std::vector<std::string> out;
  for (const auto& c : cs) out.push_back(c.name);
  return out;
}

std::vector<std::string> channel_units(const std::vector<SpindleChannel>& cs) {
  std::vector<std::string> out;
  for (const auto& c : cs) out.push_back(c.unit);
  return out;
}

template <class F>
std::vector<double> channel_field(const std::vector<SpindleChannel>& cs, F field) {
  std::vector<double> out;
  for (const auto& c : cs) out.push_back(field(c));
  return out;
}

std::string nnoe_yaml(const calibrate::NnoeModel& n) {
  const auto& w = n.net.parameters();
  std::vector<double> lags;
  for (int l : n.structure.channel_lags) lags.push_back(l);
  return "nnoe:\n  na: " + std::to_string(n.structure.na) + "\n  hidden: " + std::to_string(n.structure.hidden) +
         "\n  channel_lags: " + numbers_text(lags) + "\n  y_offset: " + number_text(n.y_offset) +
         "\n  y_scale: " + number_text(n.y_scale) + "\n  u_offset: " + numbers_text(n.u_offset) +
         "\n  u_scale: " + numbers_text(n.u_scale) +
         "\n  weights: " + numbers_text(std::vector<double>(w.data(), w.data() + w.size())) + "\n";
}

calibrate::NnoeModel read_nnoe(const Config& s, std::size_t channels) {
  constexpr double kAny = 1e300;
  calibrate::NnoeModel n;
  s.reject_unknown({"na", "hidden", "channel_lags", "y_offset", "y_scale", "u_offset", "u_scale", "weights"});
  n.structure.na = static_cast<int>(s.integer("na", 1, 1, 16));
  n.structure.hidden = static_cast<int>(s.integer("hidden", 1, 1, 1024));
  for (double l : s.numbers("channel_lags", channels, "", 0, 16)) n.structure.channel_lags.push_back(static_cast<int>(l));
  n.y_offset = s.number("y_offset", "", -kAny, kAny);
  n.y_scale = s.number("y_scale", "", 1e-300, kAny);
  n.u_offset = s.numbers("u_offset", channels, "", -kAny, kAny);
  n.u_scale = s.numbers("u_scale", channels, "", 1e-300, kAny);
  int inputs = n.structure.na;
  for (int l : n.structure.channel_lags) inputs += l;
  n.net = neural::Mlp({inputs, n.structure.hidden, 1});
  const std::vector<double> w = s.numbers("weights", 0, "", -kAny, kAny);
  if (static_cast<Eigen::Index>(w.size()) != n.net.parameter_count())
    throw s.error("weights", "has " + std::to_string(w.size()) + " numbers; the structure " + n.structure.text() +
                                 " needs " + std::to_string(n.net.parameter_count()));
  n.net.set_parameters(Eigen::Map<const Eigen::VectorXd>(w.data(), static_cast<Eigen::Index>(w.size())));
  return n;
}

std::vector<SpindleChannel> read_channels(const Config& c) {
  const auto names = c.strings("channels");
  const auto units = c.strings("channel_units");
  const auto lo = c.numbers("channel_min", names.size(), "", -1e300, 1e300);
  const auto hi = c.numbers("channel_max", names.size(), "", -1e300, 1e300);
  if (units.size() != names.size())
    throw c.error("channel_units", "has " + std::to_string(units.size()) + " units for " + std::to_string(names.size()) +
                                       " channels");
  std::vector<SpindleChannel> out;
  for (std::size_t i = 0; i < names.size(); ++i) out.push_back({names[i], units[i], lo[i], hi[i]});
  return out;
}

}  // namespace

calibrate::Channels umich_channels(const UmichRun& run) { return {run.feed, run.spindle, run.cutting}; }

const std::vector<double>& measured(const UmichRun& run, const SpindleModel& m) {
  return m.quantity == "current" ? run.current : run.power;
}

SpindleTraining train_spindle_model(const std::vector<std::filesystem::path>& fit,
                                    const std::vector<std::filesystem::path>& verify,
                                    const SpindleTrainingOptions& options) {
  SpindleTraining t;
  t.fit = read_runs(fit);
  t.verify = read_runs(verify);
  const bool current = options.quantity == "current";
  t.table = compare_on_umich(t.fit, t.verify, current, options.nnoe, options.hidden);
  t.chosen = lowest_verification_fpe(t.table);
  const StructureScore& best = t.table[t.chosen];
  SpindleModel& m = t.model;
  m.quantity = current ? "current" : "power";
  m.column = current ? "S1_CurrentFeedback" : "S1_OutputPower";
  m.unit = current ? "A" : kPowerUnit;
  m.data = kUmichData;
  m.period = kUmichPeriod;
  m.channels = {channel("feed", "mm/s", t.fit.feed), channel("spindle", "rev/s", t.fit.spindle),
                channel("cutting", "flag", t.fit.cutting)};
  const auto& y = current ? t.fit.current : t.fit.power;
  const auto [lo, hi] = std::minmax_element(y.begin(), y.end());
  m.output_min = *lo, m.output_max = *hi;
  m.fit_runs = names_of(fit);
  m.verify_runs = names_of(verify);
  m.regressors = best.regressors;
  m.fit_fpe = best.training_fpe;
  m.verify_fpe = best.verification_fpe;
  m.nnoe = best.model;
  m.nnoe.candidates.clear();
  return t;
}

std::vector<double> predict_spindle(const SpindleModel& m, const calibrate::Channels& inputs) {
  return inputs.empty() ? std::vector<double>{} : calibrate::nnoe_simulate(m.nnoe, inputs, inputs.front().size());
}

std::string spindle_model_yaml(const SpindleModel& m) {
  std::string y = "# Seed 003's NNOE on the spindle, written by gcpipe train-spindle (stages/force/README.md sec. 8b).\n";
  y += "format: " + quoted(kFormat) + "\nquantity: " + m.quantity + "\ncolumn: " + quoted(m.column) +
       "\nunit: " + quoted(m.unit) + "\ndata: " + quoted(m.data) + "\nperiod: " + number_text(m.period) +
       "  # s\nchannels: " + strings_text(channel_names(m.channels)) +
       "\nchannel_units: " + strings_text(channel_units(m.channels)) +
       "\nchannel_min: " + numbers_text(channel_field(m.channels, [](const SpindleChannel& c) { return c.min; })) +
       "\nchannel_max: " + numbers_text(channel_field(m.channels, [](const SpindleChannel& c) { return c.max; })) +
       "\noutput_range: " + numbers_text({m.output_min, m.output_max}) + "\nfit_runs: " + strings_text(m.fit_runs) +
       "\nverify_runs: " + strings_text(m.verify_runs) + "\nregressors: " + quoted(m.regressors) +
       "\nfit_fpe_percent: " + number_text(m.fit_fpe) + "\nverify_fpe_percent: " + number_text(m.verify_fpe) + "\n";
  return y + nnoe_yaml(m.nnoe);
}

SpindleModel read_spindle_model(const std::filesystem::path& file) {
  const Config c = Config::load_file(file);
  c.reject_unknown({"format", "quantity", "column", "unit", "data", "period", "channels", "channel_units", "channel_min",
                    "channel_max", "output_range", "fit_runs", "verify_runs", "regressors", "fit_fpe_percent",
                    "verify_fpe_percent", "nnoe"});
  if (c.string("format", "") != kFormat)
    throw c.error("format", std::string("not a spindle model file of gcpipe train-spindle (expected \"") + kFormat + "\")");
  SpindleModel m;
  m.quantity = c.choice("quantity", "", {"power", "current"});
  m.column = c.string("column", "");
  m.unit = c.string("unit", "");
  m.data = c.string("data", "");
  m.period = c.number("period", "s", 1e-6, 3600);
  m.channels = read_channels(c);
  const auto range = c.numbers("output_range", 2, "", -1e300, 1e300);
  m.output_min = range[0], m.output_max = range[1];
  m.fit_runs = c.has("fit_runs") ? c.strings("fit_runs") : std::vector<std::string>{};
  m.verify_runs = c.has("verify_runs") ? c.strings("verify_runs") : std::vector<std::string>{};
  m.regressors = c.string("regressors", "");
  m.fit_fpe = c.number("fit_fpe_percent", 0, "%", 0, 1e300);
  m.verify_fpe = c.number("verify_fpe_percent", 0, "%", 0, 1e300);
  m.nnoe = read_nnoe(c.section("nnoe"), m.channels.size());
  return m;
}

namespace {

/// Factor from what the force stage samples (feed mm/s, spindle rev/min, cutting flag) to the
/// channel's unit; 0 when it cannot.
double supply_factor(const SpindleChannel& c) {
  if (c.name == "feed") return c.unit == "mm/s" ? 1.0 : c.unit == "mm/min" ? 60.0 : 0.0;
  if (c.name == "spindle") return c.unit == "rev/min" ? 1.0 : c.unit == "rev/s" ? 1.0 / 60 : 0.0;
  if (c.name == "cutting") return c.unit == "flag" ? 1.0 : 0.0;
  return 0;
}

const std::vector<double>& sampled(const ProgramInputs& in, const std::string& name) {
  return name == "feed" ? in.feed : name == "spindle" ? in.spindle : in.cutting;
}

/// "spindle: 0..66.67 rev/s against 0..53.3 trained (91 % of the samples outside)", or "" when
/// inside. The runs record three significant digits (3200 rev/min is written 53.3 rev/s), so the
/// range is widened by 0.1 % of its larger end.
std::string outside_text(const SpindleChannel& c, const std::vector<double>& x) {
  const double tol = 1e-3 * std::max(std::abs(c.min), std::abs(c.max));
  std::size_t below = 0, above = 0;
  double lo = c.min, hi = c.max;
  for (double v : x) {
    below += v < c.min - tol ? 1 : 0, above += v > c.max + tol ? 1 : 0;
    lo = std::min(lo, v), hi = std::max(hi, v);
  }
  if (below + above == 0) return "";
  char buf[200];
  std::snprintf(buf, sizeof buf, "%s: %.4g..%.4g %s against %.4g..%.4g trained (%.1f %% of the samples outside)",
                c.name.c_str(), lo, hi, c.unit.c_str(), c.min, c.max,
                100.0 * static_cast<double>(below + above) / static_cast<double>(x.size()));
  return buf;
}

}  // namespace

std::string unsupplied_channels(const SpindleModel& m) {
  std::string why;
  for (const SpindleChannel& c : m.channels)
    if (supply_factor(c) == 0)
      why += (why.empty() ? "" : "; ") + std::string("channel '") + c.name + "' in '" + c.unit + "'";
  if (why.empty()) return "";
  return why + ": the force stage supplies only feed [mm/s or mm/min], spindle [rev/s or rev/min] and cutting [flag]";
}

SpindlePrediction predict_along_program(const SpindleModel& m, const ProgramInputs& in) {
  std::vector<std::vector<double>> converted;
  SpindlePrediction p;
  for (const SpindleChannel& c : m.channels) {
    const double k = supply_factor(c);
    converted.emplace_back();
    for (double v : sampled(in, c.name)) converted.back().push_back(k * v);
    const std::string outside = outside_text(c, converted.back());
    if (!outside.empty()) p.outside_training.push_back(outside);
  }
  p.value = predict_spindle(m, calibrate::Channels(converted.begin(), converted.end()));
  double sum = 0;
  for (std::size_t k = 0; k < p.value.size(); ++k) {
    p.min_program = k == 0 ? p.value[k] : std::min(p.min_program, p.value[k]);
    p.max_program = k == 0 ? p.value[k] : std::max(p.max_program, p.value[k]);
    if (in.cutting[k] == 0) continue;
    sum += p.value[k];
    p.max_cutting = p.cutting_samples++ == 0 ? p.value[k] : std::max(p.max_cutting, p.value[k]);
  }
  p.mean_cutting = p.cutting_samples ? sum / static_cast<double>(p.cutting_samples) : 0;
  return p;
}

}  // namespace gcpipe::force
