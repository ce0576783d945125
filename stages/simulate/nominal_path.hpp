// Internal to stages/simulate: the nominal tool-tip polyline of a recorded run.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "simulate.hpp"

namespace gcpipe::simulate {

/// The nominal tool-tip path as a polyline without repeated points, and the polyline index of
/// every tick, so that the contour error can be searched near the previous match (a dwell or a
/// stop adds many identical points that would otherwise stall the search).
struct NominalPath {
  std::vector<Vec3> pts;
  std::vector<std::uint32_t> index_of_tick;
};

NominalPath nominal_path(const Model& model, const Nominal& nom, std::span<const ResolvedBlock> program);

}  // namespace gcpipe::simulate
