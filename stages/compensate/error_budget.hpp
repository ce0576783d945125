// Two error sources side by side (issue 15): the servo contour error of the simulated run and the
// tool deflection the cutting force causes at the same place. Each time bucket of the simulation
// takes the deflection of the force sample nearest to its nominal point (same Z level); the
// figure shows both against time, and report.json's `error_budget` which dominates how often.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "path_force.hpp"
#include "simulate.hpp"

namespace gcpipe::compensate {

struct ErrorBudget {
  std::vector<double> t;            //!< [s] simulated time of the bucket
  std::vector<double> contour_um;   //!< servo contour error
  std::vector<double> deflection_um;  //!< tool deflection under the mean force there (0: no cut)
  double matched_fraction = 0;      //!< buckets with a force sample within 1 mm
  double deflection_dominates = 0;  //!< fraction of cutting buckets where deflection > contour
};

/// `origin`: the work offset, subtracted from the force samples' machine coordinates to put them
/// in the simulation's workpiece frame.
ErrorBudget error_budget(const simulate::Series& series, const force::PathForce& force, const Vec3& origin);
nlohmann::ordered_json error_budget_json(const ErrorBudget& b);
void plot_error_budget(const std::filesystem::path& png, const ErrorBudget& b, const std::string& title);

}  // namespace gcpipe::compensate
