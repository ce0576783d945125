// The simulation section of the report (report.json "simulation", report.txt lines) and its
// figures, for a simulated program and, when there is one, its compensated program. Shared by
// the simulate stage (alone) and the compensate stage, so both report the same way.
#pragma once

#include "compensate.hpp"
#include "local_slowdown.hpp"
#include "stage.hpp"

namespace gcpipe::compensate {

struct SimulationOutcome {
  const Model* model = nullptr;
  const simulate::SimulationRun* run = nullptr;  //!< the original program's simulation
  const Evaluation* after = nullptr;             //!< the compensated program's, or null
  const Result* result = nullptr;                //!< the compensation, or null
  const simulate::SlowedBaseline* slowed = nullptr;  //!< the sceptic's baseline, or null
  const Evaluation* feedforward = nullptr;       //!< the model-inverse feed-forward run, or null
  double feedforward_over_limit = 0;             //!< its largest acceleration / an axis's limit
  const LocalSlowdown* slowdown = nullptr;       //!< where the plan was slowed for the drives, or null
  std::uint64_t written_nodes = 0;               //!< motion blocks of compensated.nc
  std::string skipped;                           //!< why nothing was simulated
  std::string not_compensated;                   //!< why the program was deliberately not compensated
};

/// Writes "simulation" into the report, its text lines, and (with an output folder) the figures.
void report_simulation(pipeline::ReportContext& r, const SimulationOutcome& o);

}  // namespace gcpipe::compensate
