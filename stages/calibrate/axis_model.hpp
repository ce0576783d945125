// One axis of the configured machine replayed against a measured trace. The commands of the trace
// are what the drives received (after the control's interpolation and smoothing), so they go
// straight into servo::AxisDrive, tick by tick, exactly as servo::ServoSimulator feeds them.
//
// Effects split in two kinds:
//   dynamic  (coulomb_friction, feedback_delay, torque_limit): change the motor motion, so the
//            drive is simulated again with them;
//   output   (backlash, lead_error, scale_error, measurement_delay, offset): act on the position
//            chain after the motor and never reach the loop (semi-closed loop), so they are
//            applied to one simulated motor trajectory. apply_output_effect() is our own
//            formulation of them, tested against the servo registry's classes.
#pragma once

#include <span>
#include <string>
#include <vector>

#include "servo.hpp"

namespace gcpipe::calibrate {

/// True for effects that change the motor motion and so need a new simulation.
bool is_dynamic_effect(const std::string& type);

/// Simulates one axis on the commands (load units) with the dynamic effects of `p` only; returns
/// the motor position in load units per tick (y[0] = c[0], at rest).
std::vector<double> simulate_motor(const servo::DriveParams& p, int substeps, double margin,
                                   double period, std::span<const double> command,
                                   std::vector<double>* torque = nullptr);

/// Applies one output effect in place to a load-unit position series sampled every `period`.
/// `dydp` (when not null) receives the derivative of the output with respect to each of the
/// effect's fitted parameters (order of fitted_parameters()), one vector per parameter.
void apply_output_effect(const servo::EffectSettings& e, double period, std::vector<double>& y,
                         std::vector<std::vector<double>>* dydp = nullptr);

/// Measurement noise of a position series [same unit]: the third difference of a smooth motion
/// sampled at ~1 ms is below a nanometre, so what is left is noise: sigma = MAD(D3 y)/0.6745
/// / sqrt(20) (D3 = [1 -3 3 -1], variance 20 sigma^2 for white noise).
double estimate_noise(std::span<const double> y);

/// Correlation time of a residual in samples: 1 + 2 sum rho_k up to the first k with rho_k <= 0
/// (at most 2000 lags), at least 1. N / tau is the number of effectively independent samples,
/// used by the information criterion and the parameter covariance.
double correlation_time(std::span<const double> r);

}  // namespace gcpipe::calibrate
