// What the force stage hands downstream in one process: the force along the program it emitted
// (the planned one when it plans). The compensate stage puts its deflection beside the simulated
// contour error (stages/compensate/error_budget.hpp).
#pragma once

#include "path_force.hpp"
#include "stage.hpp"

namespace gcpipe::force {

struct ForceProfile final : pipeline::Product {
  PathForce force;
};

}  // namespace gcpipe::force
