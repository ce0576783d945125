// Fit of the table-table XYZAC geometry to a measured trace: which C-axis centre and A-axis pivot
// make forward kinematics of the actual joints reproduce the controller's tool position?
//
// Model (README "Fitting the geometry to the NIST trace"): path_pos = FK(joints) - o, with FK of
// gcpipe/kinematics.hpp for C centre (cx, cy, 0), A pivot (.., ay, az) and the work origin o in
// the workpiece frame; the tool length is absorbed in az and oz (the trace does not give it), and
// the height of the C centre cannot be seen by rotations about a vertical axis. The model is
// linear in the seven parameters (cx, cy, ay, az, ox, oy, oz), so the fit is one linear least
// squares solve; no start values, no iterations.
#pragma once

#include <span>

#include "gcpipe/kinematics.hpp"
#include "shdr.hpp"

namespace gcpipe {

/// Fitted geometry and how well it explains the samples.
struct KinematicFitResult {
  double c_x = 0, c_y = 0;      //!< C-axis centre in machine coordinates [mm]
  double a_y = 0, a_z = 0;      //!< A-axis pivot in machine coordinates [mm] (a_z: relative to
                                //!< the controlled tool point)
  Vec3 origin{};                //!< work origin in the workpiece frame [mm]
  std::size_t samples = 0;
  double rms = 0;               //!< RMS of |FK(joints) - origin - path_pos| [mm]
  double max = 0;               //!< largest such error [mm]
  /// The kinematic model these parameters describe (c_centre z = 0, tool length 0).
  MachineKinematics model(const MachineKinematics& base) const;
};

/// Least-squares fit of all seven parameters for the given rotation sense.
KinematicFitResult fit_table_geometry(std::span<const KinematicSample> samples,
                                      RotaryConvention convention);

/// The "before" reference: rotary axes assumed to meet at machine zero (c = a = 0), only the work
/// origin fitted (three parameters).
KinematicFitResult fit_origin_only(std::span<const KinematicSample> samples,
                                   RotaryConvention convention);

/// The alternative hypothesis: path_pos is the machine position minus a constant offset, with no
/// table rotation applied (what a control reports without tool-centre-point transformation).
/// Returns the mean offset o = joints - path_pos in `origin` and the error of that model.
KinematicFitResult fit_untransformed_offset(std::span<const KinematicSample> samples);

/// Error of a given geometry on the samples (rms and max filled, parameters copied).
KinematicFitResult evaluate_geometry(std::span<const KinematicSample> samples,
                                     const KinematicFitResult& geometry,
                                     RotaryConvention convention);

}  // namespace gcpipe
