// The University of Michigan mill traces (100 ms, positions quantised to 1 mm): what they can
// calibrate. Per axis, fitted on some experiments and predicted on the others:
//   velocity: v_actual(t) = g v_command(t - d), d a whole number of samples (0..3): the servo
//             lag at 100 ms sampling, where the loop dynamics themselves are not resolved;
//   current:  I = Fc sign(v) + Fv v + Ka a + I0 (Erkorkmaz & Altintas's friction model by least
//             squares): the Coulomb level Fc and viscous slope Fv are the friction the currents
//             show, Ka the inertia in current units.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "measured_trace.hpp"

namespace gcpipe::calibrate {

struct UmichAxis {
  double gain = 1, delay_s = 0;
  double v_rms_before = 0, v_rms_after = 0;   //!< [mm/s] predicted experiments; before: v_act = v_cmd
  std::array<double, 4> current{};            //!< Fc [A], Fv [A s/mm], Ka [A s^2/mm], I0 [A]
  std::array<double, 4> current_sigma{};
  double i_rms_before = 0, i_rms_after = 0;   //!< [A]; before: the mean current of the fit set
  std::size_t fit_samples = 0, predict_samples = 0;
};

/// X, Y, Z. Throws std::invalid_argument when a trace is not a UMich trace.
std::array<UmichAxis, 3> umich_analysis(const std::vector<MeasuredTrace>& fit, const std::vector<MeasuredTrace>& predict);

}  // namespace gcpipe::calibrate
