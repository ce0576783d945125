// The NNOE's parallel (recurrent) run in float (neural::MlpSingle): each step needs the previous
// step's output, so no batch can be formed; the speed comes from the vectorised hidden layer.
// Training and the double-precision run stay in nnoe.cpp; this is inference only, for long
// series (force prediction along a program), checked against nnoe_simulate in the tests.
#pragma once

#include <vector>

#include "nnoe.hpp"

namespace gcpipe::calibrate {

/// Same series as nnoe_simulate(m, u, end) (y^ per sample from its own past, the first lags at
/// the output's centre, held at +-20 scales), computed in float.
std::vector<double> nnoe_simulate_float(const NnoeModel& m, const Channels& u, std::size_t end);

}  // namespace gcpipe::calibrate
