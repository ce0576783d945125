#include "run_report.hpp"

#include <cstdio>

#include "output_dir.hpp"

namespace gcpipe::pipeline {

nlohmann::ordered_json report_head(const std::string& input, const std::string& config, const std::string& machine,
                                   const std::vector<std::string>& stages, bool complete) {
  nlohmann::ordered_json j;
  j["input"] = input;
  j["config"] = config;
  j["machine"] = machine;
  j["stages"] = stages;
  j["complete"] = complete;
  return j;
}

std::string report_text_head(const std::string& command, const std::string& input,
                             const std::filesystem::path& outdir, const std::vector<std::string>& stages) {
  std::string chain;
  for (const auto& s : stages) chain += (chain.empty() ? "" : " -> ") + s;
  return command + ": " + input + " -> " + outdir.string() + "\n  stages:   " + chain + "\n";
}

std::vector<std::string> report_files() {
  return {"output.nc", "summary.json", "diagnostics.txt", "report.json", "report.txt"};
}

std::vector<std::string> run_outputs() {
  return {"output.nc", "compensated.nc", "report.json", "report.txt", "summary.json", "diagnostics.txt",
          "plots/toolpath.png", "plots/ballbar.png", "plots/contour_error.png", "plots/following_error.png",
          "plots/ik_divergence.png", "plots/ik_tip_error.png", "plots/trochoid_engagement.png",
          "plots/force_path.png", "plots/force_time.png", "plots/error_budget.png", "plots/spindle_prediction.png"};
}

std::string why_not_compensated(const RunReport& r) {
  if (!r.simulation_skipped.empty()) return r.simulation_skipped;
  const auto sim = r.json.find("simulation");
  if (sim != r.json.end() && sim->contains("not_compensated")) return (*sim)["not_compensated"].get<std::string>();
  if (sim != r.json.end() && sim->contains("skipped")) return (*sim)["skipped"].get<std::string>();
  return "the compensation was not run";
}

std::string write_run_report(RunReport r, const std::filesystem::path& outdir, double seconds) {
  if (!r.simulation_skipped.empty()) {
    r.json["simulation"] = {{"skipped", r.simulation_skipped}};
    r.text += "  simulate: skipped (" + r.simulation_skipped + ")\n";
  }
  if (!r.failure.empty()) r.json["failure"] = r.failure;
  if (!r.not_compensated.empty()) r.json["not_compensated"] = r.not_compensated;
  if (r.compensated) r.files.insert(r.files.begin() + 5, "compensated.nc");
  nlohmann::ordered_json summary = r.json;
  summary.erase("simulation");
  summary["seconds"] = seconds;
  r.json["outputs"] = r.files;
  r.json["seconds"] = seconds;
  r.text += "  output:   ";
  for (std::size_t i = 0; i < r.files.size(); ++i) r.text += (i == 0 ? "" : i < 6 ? ", " : "\n            ") + r.files[i];
  char buf[64];
  std::snprintf(buf, sizeof buf, "\n  time:     %.3f s\n", seconds);
  r.text += buf;
  if (!r.failure.empty()) r.text += "  failure:  " + r.failure + "\n";
  write_file_atomically(outdir / "summary.json", summary.dump() + "\n");
  write_file_atomically(outdir / "report.json", r.json.dump() + "\n");
  write_file_atomically(outdir / "report.txt", r.text);
  return r.text;
}

}  // namespace gcpipe::pipeline
