// Seed 002's synchronous circle test: the X/Y axes move the tool centre on a circle of radius
// R_W around (R_C, 0) while C turns the table at the same angular velocity omega, so the feed
// vector at the cutting point stays constant (seed 002 eqs. 1-3, Fig. 3).
//
// Analysis after eqs. 5-11, the frequency-response predictions after eqs. 12 and 18, the Best
// K_FFP of eq. (20), and the torque-saturation onset of Fig. 17/18.
#pragma once

#include <array>
#include <complex>
#include <string>

#include "interpolate.hpp"
#include "servo.hpp"

namespace gcpipe::servo {

/// Geometry and timing of one circle-test condition.
struct CircleTest {
  double R_C = 5.0;         //!< workpiece radius of curvature [mm]
  double R_W = 8.0;         //!< distance C-axis centre to centre of curvature [mm]
  double omega = 3.14159265358979323846;  //!< angular velocity of C and of the tool centre [rad/s]
  double t_start = 0.0;     //!< time at which the nominal angle omega*(t - t_start) is 0 [s]
  double c_start = 0.0;     //!< C at t_start [deg]
};

/// Seed 002 quantities at one instant. Angles [rad], lengths [mm].
struct CirclePoint {
  double alpha = 0;            //!< eq. (8): phase delay of the rotary axis
  double beta = 0;             //!< eq. (9): phase delay of the linear axes
  double alpha_minus_beta = 0; //!< eq. (10)
  double radius_decrease = 0;  //!< eq. (11) with the sign of eqs. (7)/(12): R_W - radius (> 0
                               //!< when the circle shrinks)
  double shape_error = 0;      //!< eq. (6): Delta R_C ~ eps_X = X_L - X_R
  double shape_error_exact = 0;//!< eq. (5) solved without dropping squares
  double shape_error_model = 0;//!< eq. (7) from alpha - beta and the radius decrease
};

/// Evaluates eqs. (5)-(11) for actual X, Y [mm] and C [deg] at time t [s]; the nominal angle is
/// omega * (t - t_start).
CirclePoint circle_point(const CircleTest& test, double t, double X, double Y, double C_deg);
/// Same with the nominal angle given [rad] (e.g. the raw commanded C of a program, which is
/// exactly omega t under G93): needs only R_C, R_W and c_start of `test`.
CirclePoint circle_point_at(const CircleTest& test, double nominal, double X, double Y, double C_deg);

/// Averages over a window of ticks (the paper's "steady state" figures).
struct CircleSummary {
  std::size_t ticks = 0;
  double mean_alpha = 0, mean_beta = 0, mean_alpha_minus_beta = 0;  //!< [rad]
  double mean_radius_decrease = 0;     //!< [mm]
  double min_radius_decrease = 0, max_radius_decrease = 0;  //!< [mm]
  double shape_error_half_amplitude = 0;  //!< (max - min)/2 of eq. (6) [mm] (Fig. 14)
};

class CircleAnalyzer {
 public:
  explicit CircleAnalyzer(CircleTest test) : test_(test) {}
  /// Adds one tick to the summary.
  CirclePoint add(double t, double X, double Y, double C_deg);
  CircleSummary summary() const;

 private:
  CircleTest test_;
  CircleSummary s_;
  double sum_a_ = 0, sum_b_ = 0, sum_ab_ = 0, sum_dr_ = 0, min_e_ = 0, max_e_ = 0;
};

/// Frequency response of one axis from raw interpolated samples to actual position: smoothing
/// (discrete) x first-order hold sinc^2 x continuous drive.
std::complex<double> command_response(const DriveParams& p, interpolate::Smoothing smoothing,
                                      double period, double omega);

/// Prediction of the steady circle (second formulation, no time stepping).
struct CirclePrediction {
  double radius_decrease = 0;  //!< mean of R_W - radius over a period of the predicted ellipse
                               //!< [mm]; equals (1 - |G_L|) R_W when X and Y are alike
  double beta_x = 0, beta_y = 0;  //!< -arg G of each linear axis [rad] (eq. 18)
  double beta = 0;             //!< mean of eq. (9) over a period of the predicted ellipse [rad]
};
CirclePrediction predict_circle(const DriveSet& d, interpolate::Smoothing smoothing, double period,
                                const CircleTest& test);

/// Simulates the circle test from rest: raw commands X = R_C + R_W cos(w t), Y = R_W sin(w t),
/// C = w t, smoothed per axis and fed to the drives; the summary covers [settle, settle + span].
CircleSummary simulate_circle(const DriveSet& d, interpolate::Smoothing smoothing, double period,
                              const CircleTest& test, double settle, double span);

/// Rotary lag of eq. (20) in the time domain: C_in - G_R C_in for the ramp C_in = w t started
/// from rest, smoothed and driven through the model with its torque limit, averaged over
/// [settle, settle + span] [rad].
double rotary_ramp_lag(const DriveParams& c, interpolate::Smoothing smoothing, double period,
                       double omega, double settle, double span);

/// Best K_FFP (eq. 20): the K_FFP of X and of Y for which -arg G_L(jw) equals the rotary lag.
struct BestKffp {
  bool ok = false;
  std::string message;              //!< why not, when !ok
  double alpha = 0;                 //!< rotary lag used [rad]
  std::array<double, 2> K_FFP{};    //!< X, Y [%]
};
BestKffp best_kffp(const DriveSet& d, interpolate::Smoothing smoothing, double period,
                   double omega, double settle, double span, double max_kffp = 200.0);

/// Torque-saturation onset (Fig. 17/18): the commanded angular velocity w at which the peak
/// torque command of the rotary axis, started from rest by a velocity step through the
/// smoothing, reaches its torque_limit. Linear in w below the limit, so one run at `probe`
/// with the limit lifted gives it: w_sat = limit * probe / peak.
double torque_onset_omega(const DriveParams& c, interpolate::Smoothing smoothing, double period,
                          double probe = 1.0);
/// Peak torque command of that run [N*m] and whether the limit clamped it (limit in force).
struct RampTorque {
  double peak_torque = 0;
  bool saturated = false;
};
RampTorque ramp_torque(const DriveParams& c, interpolate::Smoothing smoothing, double period,
                       double omega, bool with_limit);

}  // namespace gcpipe::servo
