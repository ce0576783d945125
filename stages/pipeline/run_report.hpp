// The run's report files around the stages' parts: report.json, report.txt and summary.json, as
// `gcpipe batch` writes them (stages in one process) and `gcpipe report-sink` writes them from
// the parts the DDS nodes publish (`gcpipe stream`): one definition, so the two cannot drift.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace gcpipe::pipeline {

struct RunReport {
  nlohmann::ordered_json json;     //!< report_head's keys, then every stage's part in chain order
  std::string text;                //!< report_text_head's lines, then every stage's lines
  std::vector<std::string> files;  //!< report_files(), then every figure a stage drew
  std::string simulation_skipped;  //!< why batch ran no simulation ("" when it did)
  std::string failure;             //!< "stage: why" of the first stage that failed, or ""
  bool compensated = false;        //!< compensated.nc was written
  std::string not_compensated;     //!< why not, when nothing failed ("" when it was, or failed)
};

/// report.json's first keys: the input as given, the config file, the machine, the chain and
/// whether the whole program went through it.
nlohmann::ordered_json report_head(const std::string& input, const std::string& config, const std::string& machine,
                                   const std::vector<std::string>& stages, bool complete);
/// report.txt's first lines: "COMMAND: INPUT -> OUTDIR" and the chain.
std::string report_text_head(const std::string& command, const std::string& input,
                             const std::filesystem::path& outdir, const std::vector<std::string>& stages);
/// The files every run writes before the stages' figures.
std::vector<std::string> report_files();
/// Every file a run may write into its output folder (an earlier run's are removed first).
std::vector<std::string> run_outputs();

/// Why a run that did not fail wrote no compensated.nc: the simulation was skipped (a config
/// without drives) or the compensate stage declined (its report's simulation.not_compensated).
std::string why_not_compensated(const RunReport& r);

/// Writes OUTDIR/summary.json (the report without the simulation and the file list),
/// report.json and report.txt, each atomically; returns report.txt's text.
std::string write_run_report(RunReport report, const std::filesystem::path& outdir, double seconds);

}  // namespace gcpipe::pipeline
