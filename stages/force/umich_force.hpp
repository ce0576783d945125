// Seed 003's NNOE on real data: the University of Michigan mill runs (../shared/data/traces/
// umich_smart_cnc_mill/, PROVENANCE.md there; wax, 100 ms samples) carry the spindle's output
// power and current beside the commanded axis velocities. No force was measured and the depth of
// cut is not recorded, so the model here is: spindle power from the path feed, the spindle speed
// and whether a cutting layer is running (Machining_Process "Layer ..."), trained on some
// experiments and verified on the others (README sec. 8 says what it shows).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "nnoe_force.hpp"

namespace gcpipe::force {

struct UmichRun {
  std::string file;
  std::vector<double> feed;     //!< commanded path speed |(vx, vy, vz)| [mm/s]
  std::vector<double> spindle;  //!< commanded spindle speed S1_CommandVelocity (file's unit)
  std::vector<double> cutting;  //!< 1 while Machining_Process is a "Layer ..." pass, else 0
  std::vector<double> power;    //!< S1_OutputPower (file's unit)
  std::vector<double> current;  //!< S1_CurrentFeedback [A]
};

/// Reads one experiment CSV; throws std::runtime_error naming the file and a missing column.
UmichRun read_umich_run(const std::filesystem::path& csv);

/// Runs one after the other as one series (the seams are a few samples of a wrong history).
UmichRun concatenate(const std::vector<UmichRun>& runs);

/// Table-1-style comparison on power (`use_current` false) or current: structures over the three
/// channels (feed, spindle, cutting), trained on `fit`, FPE on `verify` [% of the fit variance];
/// a sixth row is the first structure without the feed (does the feed explain anything?). Each
/// structure has `hidden` tanh units.
std::vector<StructureScore> compare_on_umich(const UmichRun& fit, const UmichRun& verify, bool use_current,
                                             const calibrate::NnoeOptions& options = {}, int hidden = 8);

}  // namespace gcpipe::force
