#include "umich_force.hpp"

#include <cmath>
#include <fstream>
#include <map>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include "gcpipe/split_fields.hpp"

namespace gcpipe::force {

namespace {

std::size_t column(const std::map<std::string, std::size_t>& header, const std::string& name, const std::string& file) {
  const auto it = header.find(name);
  if (it == header.end()) throw std::runtime_error(file + ": no column '" + name + "' (not a UMich mill trace)");
  return it->second;
}

double number(const std::vector<std::string>& row, std::size_t i, const std::string& file, std::size_t line) {
  try {
    return std::stod(row.at(i));
  } catch (const std::exception&) {
    throw std::runtime_error(file + ":" + std::to_string(line) + ": column " + std::to_string(i + 1) + " is not a number");
  }
}

double mean_of(const std::vector<double>& x) { return std::accumulate(x.begin(), x.end(), 0.0) / static_cast<double>(x.size()); }
double stdev_of(const std::vector<double>& x) {
  const double m = mean_of(x);
  double q = 0;
  for (double v : x) q += (v - m) * (v - m);
  return std::max(std::sqrt(q / static_cast<double>(x.size())), 1e-12);
}

}  // namespace

UmichRun read_umich_run(const std::filesystem::path& csv) {
  const std::string file = csv.string();
  std::ifstream in(csv);
  if (!in) throw std::runtime_error(file + ": cannot be read");
  std::string line;
  std::getline(in, line);
  std::map<std::string, std::size_t> header;
  const auto names = split_fields(line, ',');
  for (std::size_t i = 0; i < names.size(); ++i) header[names[i]] = i;
  const std::size_t vx = column(header, "X1_CommandVelocity", file), vy = column(header, "Y1_CommandVelocity", file),
                    vz = column(header, "Z1_CommandVelocity", file), s = column(header, "S1_CommandVelocity", file),
                    p = column(header, "S1_OutputPower", file), c = column(header, "S1_CurrentFeedback", file),
                    proc = column(header, "Machining_Process", file);
  UmichRun r;
  r.file = file;
  for (std::size_t n = 2; std::getline(in, line); ++n) {
    const auto row = split_fields(line, ',');
    if (row.size() < names.size() - 1) throw std::runtime_error(file + ":" + std::to_string(n) + ": short row");
    const double x = number(row, vx, file, n), y = number(row, vy, file, n), z = number(row, vz, file, n);
    r.feed.push_back(std::sqrt(x * x + y * y + z * z));
    r.spindle.push_back(number(row, s, file, n));
    r.cutting.push_back(row.at(proc).rfind("Layer", 0) == 0 ? 1.0 : 0.0);
    r.power.push_back(number(row, p, file, n));
    r.current.push_back(number(row, c, file, n));
  }
  return r;
}

UmichRun concatenate(const std::vector<UmichRun>& runs) {
  UmichRun out;
  for (const UmichRun& r : runs) {
    out.file += (out.file.empty() ? "" : " + ") + std::filesystem::path(r.file).filename().string();
    for (auto [to, from] : {std::pair{&out.feed, &r.feed}, {&out.spindle, &r.spindle}, {&out.cutting, &r.cutting},
                            {&out.power, &r.power}, {&out.current, &r.current}})
      to->insert(to->end(), from->begin(), from->end());
  }
  return out;
}

std::vector<StructureScore> compare_on_umich(const UmichRun& fit, const UmichRun& verify, bool use_current,
                                             const calibrate::NnoeOptions& options, int hidden) {
  const std::vector<double>& y_fit = use_current ? fit.current : fit.power;
  const std::vector<double>& y_ver = use_current ? verify.current : verify.power;
  calibrate::NnoeModel norm;
  norm.y_offset = mean_of(y_fit);
  norm.y_scale = stdev_of(y_fit);
  norm.u_offset = {mean_of(fit.feed), mean_of(fit.spindle), mean_of(fit.cutting)};
  norm.u_scale = {stdev_of(fit.feed), stdev_of(fit.spindle), stdev_of(fit.cutting)};
  const calibrate::Channels u_fit{fit.feed, fit.spindle, fit.cutting}, u_ver{verify.feed, verify.spindle, verify.cutting};
  std::vector<calibrate::NnoeStructure> structures;
  for (auto st : table1_structures(hidden)) {
    // Table 1's lags of the feed and of the depth; the spindle speed gets the feed's, the cutting
    // flag stands where the depth of cut stood.
    st.channel_lags = {st.channel_lags[0], st.channel_lags[0], st.channel_lags[1]};
    structures.push_back(st);
  }
  // The ablation that says whether the feed matters at all: the first structure without it.
  structures.push_back(structures.front());
  structures.back().channel_lags[0] = 0;
  std::vector<StructureScore> out;
  for (const auto& st : structures) {
    StructureScore s;
    s.structure = st;
    s.regressors = regressor_text(st, {use_current ? "I" : "P", "f", "S", "cut"});
    s.model = calibrate::train_nnoe(st, y_fit, u_fit, 2, y_fit.size(), options, norm);
    s.training_fpe = 100 * s.model.fpe;
    s.verification_fpe = 100 * calibrate::nnoe_fpe(s.model, y_ver, u_ver, 2, y_ver.size());
    out.push_back(std::move(s));
  }
  return out;
}

}  // namespace gcpipe::force
