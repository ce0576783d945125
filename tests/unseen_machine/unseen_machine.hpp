// A second machine simulator, for tests only: a judge for `calibrate` that shares no code, no
// structure and no integration scheme with stages/servo (seed 002). It includes nothing from
// stages/ and links Eigen only.
//
// Why a second simulator: calibrate is otherwise tested on traces made by gcpipe's own servo
// model, so a test asks gcpipe's model whether gcpipe is right. This one differs on purpose:
//   * the controller is DIGITAL: position and velocity loops run every `control_period` Tc
//     (0.25-0.5 ms typical), the torque is held (zero-order hold) between ticks;
//   * the feed-forward is a backward difference of the command samples averaged over Tff (a
//     moving average, not a first-order lag, and no look-ahead);
//   * a two-mass (motor - spring/damper - table) structure with the position loop on the table;
//   * the plant is integrated with the implicit trapezoidal rule (Tustin) on sub-steps h <= 50 us,
//     Newton iterations when friction/cogging make it nonlinear (not RK4, not a matrix exponential);
//   * two effects gcpipe has no model of: cogging torque ripple and a slow thermal drift.
//
// Units. Load side (commands, `actual`, backlash, lead/scale errors, drift): mm on linear axes,
// deg on rotary axes. Motor side: rad, rad/s, N*m, kg*m^2, SI. The load units per motor radian are
//   g = 1000 * lead / (2 pi) mm/rad  (linear, ball screw, lead [m]),
//   g = 1000 mm/rad                  (linear, lead 0: direct drive, r = 1 m/rad as in seed 002),
//   g = 180 / pi deg/rad             (rotary, direct drive; lead ignored).
// Commands are turned into motor radians theta_r = command / g; the controller works in motor
// units, so Kp, Kv, Ki, c, J have seed 002's units (Kpp [1/s], Kvp [N*m*s/rad], Kvi [N*m/rad]).
//
// Command. The samples c_k (every `period` T, at t_k = k T) are joined linearly:
//   theta_r(t) = c_k + (t - t_k)/T (c_{k+1} - c_k),  t in [t_k, t_{k+1}); held after the last.
// Feed-forward velocity of segment k: v_k = (c_{k+1} - c_k)/T (the backward difference at sample
// k+1, the segment the fine interpolation is on), averaged over n = max(1, round(Tff/T)) segments:
//   v_ff(t) = kff * (v_k + v_{k-1} + ... + v_{k-n+1}) / n      (v_j = 0 outside the command).
// With n = 1 this is the exact derivative of theta_r(t) (so kff = 1 gives ideal feed-forward).
//
// Controller, at ticks t_j = j Tc (computed then applied at once, no computation delay):
//   e_p   = theta_r(t_j) - theta_fb          theta_fb = motor angle (kCascade) or table angle
//                                            (kTwoMass: linear scale, full closed loop)
//   v_cmd = Kp e_p + v_ff(t_j)
//   e_v   = v_cmd - w_m                       w_m = motor speed at t_j (ideal speed sensor)
//   I    += Tc e_v  (skipped while the torque is limited: anti-windup)
//   tau   = clamp(Kv e_v + Ki I, +-torque_limit)   held until t_{j+1}
//
// Plant (motor side, state x):
//   kCascade  x = [theta, w]:         J dw/dt = tau - c w - T_nl(theta, w)
//   kTwoMass  x = [th_m, w_m, th_t, w_t]:
//             Jm dw_m/dt = tau - c w_m - k (th_m - th_t) - d (w_m - w_t) - T_nl(th_m, w_m)
//             Jt dw_t/dt =             k (th_m - th_t) + d (w_m - w_t)
//   T_nl = coulomb * tanh(w / 0.01 rad/s) + cogging * sin(cogging_order * theta_motor)
// (c acts on the motor in both structures; resonance w_r = sqrt(k (1/Jm + 1/Jt)), free-free.)
//
// Continuous-time limit (Tc, h -> 0; kCascade; n = 1 so v_ff = kff s theta_r), for the tests:
//   J s^2 th + c s th = (Kv + Ki/s) (Kp (th_r - th) + kff s th_r - s th)
//   H(s) = th/th_r = (Kv s + Ki)(Kp + kff s) / (J s^3 + (c + Kv) s^2 + (Kv Kp + Ki) s + Ki Kp)
//   1 - H(s)  = s (J s^2 + (c + Kv (1 - kff)) s + Ki (1 - kff)) / D(s)
// Ramp v (final value theorem, e = lim_{s->0} (1 - H) v / s):
//   Ki > 0: e = (1 - kff) v / Kp   -- v/Kp without feed-forward: the velocity integrator only
//           cancels the viscous torque; the loop is type 1 in position, type 2 only with kff = 1;
//   Ki = 0: e = v/Kp (1 + c/Kv) (kff = 0).
// The same holds for the sampled loop in steady state (w = v, tau = c v, e_v = 0 at every tick).
// kTwoMass: the ringing after a step is near the free-free resonance sqrt(k (1/Jm + 1/Jt)) when
// the velocity loop is weak (Kv / Jm << that frequency); a stiff velocity loop holds the motor
// and moves it towards sqrt(k / Jt).
//
// Integration: dx/dt = A x + B tau + f_nl(x). Implicit trapezoidal rule on sub-steps h = Tc/m:
//   (I - h/2 A) x+ = (I + h/2 A) x + h B tau + h/2 (f_nl(x) + f_nl(x+))
// Linear case: x+ = M x + N tau with M = (I - h/2 A)^-1 (I + h/2 A), N = (I - h/2 A)^-1 h B
// precomputed (Eigen LU). Nonlinear: Newton on the residual with Jacobian (I - h/2 (A + df/dx)),
// started from the linear step, to |dx| <= 1e-13 (max 20 iterations). The rule is A-stable, so
// no stiffness makes it blow up; for accuracy m is the smallest integer with
//   h <= min(50 us, 0.1 / lambda_max),
// lambda_max the fastest plant rate: |eigenvalues of A|, coulomb/(0.01 J_motor) (slope of the
// smooth friction), sqrt(order * cogging / J_motor) (cogging stiffness). `substep` overrides
// the 50 us (then h = Tc / ceil(Tc / substep)). The closed DIGITAL loop can itself be unstable
// (a real effect of sampling, not of the integration): loop_spectral_radius() says so, and
// draw_axis() only returns machines whose sampled loop decays (see there).
//
// Output (logged actual), from the loop's own position y0 = g * theta_fb on the sub-step grid:
//   y1 = play(y0)                backlash: dead band of width w, the table follows the motor
//                                only once the gap is taken up; starts centred (y1 = y0 at rest).
//                                The loop does NOT see it (semi-closed on the logged position).
//   y  = y1 + lead_amp sin(2 pi y1/lead_period + lead_phase) + scale_ppm 1e-6 y1
//           + drift_rate * max(0, t - drift_onset)
//   actual_k = y(t_k - measurement_delay), linear between sub-steps, y(0) before t = 0.
// Lead, scale and drift errors are output-only too (the loop does not correct them).
// torque_k is the torque held at t_k.
//
// Speed (measured by the printed test UnseenMachine.SpeedFigure, Release, clang, AMD EPYC, 2 cores
// shared with other builds): kCascade, Tc 0.25 ms, 50 us sub-steps, no effects: 0.2 ms CPU per
// second of 1 ms trace (the goal was <= 20 ms); kTwoMass with Coulomb friction (Newton on every
// sub-step): 7-10 ms CPU per second of trace.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace gcpipe::unseen {

enum class Structure { kCascade, kTwoMass };

struct AxisMachine {
  Structure structure = Structure::kCascade;
  bool rotary = false;
  double lead = 0;              //!< ball-screw lead [m]; 0 = direct drive (see units above)
  double J = 1;                 //!< kCascade: rigid inertia [kg*m^2]
  double c = 0;                 //!< viscous damping on the motor [N*m*s/rad]
  double Jm = 0.5, Jt = 0.5;    //!< kTwoMass: motor and table inertia [kg*m^2] (motor side)
  double k = 1e5, d = 0;        //!< kTwoMass: coupling stiffness [N*m/rad], damping [N*m*s/rad]
  double Kp = 30;               //!< position loop gain [1/s]
  double Kv = 100;              //!< velocity loop proportional gain [N*m*s/rad]
  double Ki = 0;                //!< velocity loop integral gain [N*m/rad]
  double kff = 0;               //!< velocity feed-forward fraction [0, 1]
  double Tff = 0;               //!< feed-forward moving-average length [s]
  double control_period = 0.25e-3;  //!< Tc [s]
  double measurement_delay = 0;     //!< delay of the logged actual [s]
  double torque_limit = 0;          //!< [N*m], 0 = none
  double substep = 0;               //!< largest integration sub-step [s]; 0 = 50 us
  // Effects (all 0 = off)
  double backlash = 0;          //!< play width [mm or deg]
  double coulomb = 0;           //!< Coulomb friction torque [N*m]
  double lead_amp = 0;          //!< [mm or deg]
  double lead_period = 0;       //!< [mm or deg]
  double lead_phase = 0;        //!< [rad]
  double scale_ppm = 0;         //!< [ppm]
  double cogging = 0;           //!< cogging torque amplitude [N*m]
  int cogging_order = 0;        //!< ripples per motor revolution
  double drift_rate = 0;        //!< thermal drift [mm/s or deg/s]
  double drift_onset = 0;       //!< [s] after the first sample

  std::string describe() const;
};

struct AxisRun {
  std::vector<double> actual;   //!< logged position [mm or deg], one per command sample
  std::vector<double> torque;   //!< motor torque held at each sample time [N*m]
};

/// Runs one axis from rest at command[0]; `command` in load units every `period` seconds.
/// Throws std::invalid_argument for parameters that make no machine.
AxisRun run_axis(const AxisMachine& m, std::span<const double> command, double period);

/// Seed-002-convention numbers of the cascade (Kpp [1/s], Kvp [N*m*s/rad], Kvi [N*m/rad],
/// C [N*m*s/rad], J [kg*m^2], K_FFP [%]); for kTwoMass J = Jm + Jt.
struct Seed002Equivalent {
  double Kpp, Kvp, Kvi, C, J, K_FFP;
};
Seed002Equivalent equivalent(const AxisMachine& m);

/// Load units (mm or deg) per motor radian, g above.
double load_per_motor_rad(const AxisMachine& m);
/// Integration sub-step run_axis uses [s] (divides control_period).
double integration_substep(const AxisMachine& m);
/// Spectral radius of the linear part of the closed sampled loop over one control period
/// (effects, feed-forward and torque limit left out): < 1 means the digital loop is stable.
double loop_spectral_radius(const AxisMachine& m);

/// A machine drawn around `base` (seeded std::mt19937_64 and own uniforms, so the same on every
/// standard library up to libm's exp/log/sqrt rounding):
///   J (or Jm + Jt), c, Kp, Kv: base x 2^U(-1,1) (log-uniform 0.5..2);
///   then clamped: Kv/J >= 2 Kp (velocity loop at least twice the position loop; seed 002's X has
///   Kvp/J = 39 rad/s < 2 x 60, so its draws are raised) and Kv/J <= 0.5/Tc (sampled velocity
///   loop well inside its stability limit);
///   Ki = Kv * Kp * U(0.3, 1.5) (integral corner Ki/Kv near the position-loop bandwidth);
///   kff U(0,1); Tff = 1..16 ms (whole ms); Tc 0.25 or 0.5 ms; structure kCascade or kTwoMass
///   (Jm/J U(0.3,0.7), resonance log-uniform 30..120 Hz, damping ratio U(0.02,0.1));
///   measurement delay 0 or U(1, 4) ms; no torque limit, no effects.
///   Finally Kp, Kv and Ki are scaled by 0.8 (at most 40 times) until every mode of the sampled
///   loop decays at 5 1/s or faster: loop_spectral_radius <= exp(-5 Tc). (A spectral radius just
///   below 1 let lightly damped two-mass draws ring for seconds: 18 of 600 test draws were still
///   0.02-0.3 mm off after 1.5 s at rest; with the 5 1/s margin none.)
AxisMachine draw_axis(std::uint64_t seed, const Seed002Equivalent& base, bool rotary, double lead);

}  // namespace gcpipe::unseen
