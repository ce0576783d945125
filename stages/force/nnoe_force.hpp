// Seed 003's Table 1: the five regressor structures of its NNOE (stages/calibrate/nnoe.hpp, one
// implementation), each trained and scored by FPE. The spindle model of gcpipe train-spindle
// (umich_force.hpp, spindle_model.hpp) compares them on measured runs; the tests reproduce the
// table on the mechanistic force (tests/force_nnoe_process.hpp, README sec. 7).
#pragma once

#include <string>
#include <vector>

#include "nnoe.hpp"

namespace gcpipe::force {

/// One row of the Table 1 reproduction.
struct StructureScore {
  calibrate::NnoeStructure structure;
  std::string regressors;     //!< "F(t-1) F(t-2) f(t-1) a(t-1)"
  double training_fpe = 0;    //!< [% of the training force variance]
  double verification_fpe = 0;  //!< [% of the training force variance], on the verification series
  calibrate::NnoeModel model;
};

/// Seed 003 Table 1's five structures as read here (README sec. 7), each with `hidden` tanh units.
std::vector<calibrate::NnoeStructure> table1_structures(int hidden = 12);
/// "F(t-1) F(t-2) f(t-1) f(t-2) a(t-1)": names[0] the output's, names[1 + c] channel c's.
std::string regressor_text(const calibrate::NnoeStructure& s, const std::vector<std::string>& names = {"F", "f", "a"});

}  // namespace gcpipe::force
