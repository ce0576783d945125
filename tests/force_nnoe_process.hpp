// Seed 003 on the force model, as the tests reproduce its Table 1 (stages/force/README.md sec. 7):
// the data are the mechanistic model's (force_model.hpp) on a slot whose floor depth changes along
// the path, run as a dynamic process: the feed drive lags the command (first order, tau_f), the
// depth the tool feels is the mean of the profile over its front half (so a depth step enters over
// D/2 of travel), the force sensor and per-revolution averaging lag (first order, tau_F), and white
// noise is added at the output (the output-error assumption). Test data, not the product: the
// product's NNOE is the spindle model of gcpipe train-spindle (spindle_model.hpp).
#pragma once

#include <cstdint>
#include <vector>

#include "force_model.hpp"
#include "nnoe_force.hpp"

namespace gcpipe::force {

struct ForceProcess {
  CuttingCoefficients coefficients = material_coefficients("al7075");
  double diameter = 25;       //!< seed 003's cutters [mm]
  int flutes = 4;
  double spindle = 1000;      //!< s0 of seed 003 [rev/min]
  double period = 0.1;        //!< sample period [s]
  double tau_feed = 0.15;     //!< feed-drive lag [s]
  double tau_force = 0.1;     //!< sensor and averaging lag [s]
  double noise = 0.02;        //!< output noise, fraction of the series' mean force
  double feed_min = 50, feed_max = 300;     //!< commanded feed range [mm/min]
  double depth_min = 2, depth_max = 8;      //!< depth-of-cut range [mm] (seed 003: a0 = 6)
  double feed_hold_min = 2, feed_hold_max = 8;   //!< time between feed changes [s]
  double depth_step_min = 5, depth_step_max = 20;  //!< length between depth changes [mm]
};

struct ForceSeries {
  std::vector<double> feed;    //!< commanded feed f(t) [mm/min]
  std::vector<double> depth;   //!< depth of cut a(t) where the tool's front edge is [mm]
  std::vector<double> force;   //!< measured mean force (with noise) [N]
  std::vector<double> clean;   //!< the same without noise [N]
};

/// `n` samples of the process with random feed and depth steps drawn from `seed`.
ForceSeries simulate_force_process(const ForceProcess& p, std::size_t n, std::uint64_t seed);

/// Trains every structure on `train` and scores it on `verify` (normalisation from `train`).
std::vector<StructureScore> compare_structures(const ForceSeries& train, const ForceSeries& verify,
                                               const std::vector<calibrate::NnoeStructure>& structures,
                                               const calibrate::NnoeOptions& options = {});

}  // namespace gcpipe::force
