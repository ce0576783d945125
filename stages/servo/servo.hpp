// Stage `servo`: per-axis feed-drive model after seed 002 (Suzuki et al., IJAT 2019), Fig. 11 and
// Fig. 18, parameters of Table 1.
//
// One axis (all quantities on the motor side, [rad]):
//
//   r(t)  position command: the interpolator's samples joined linearly (first-order hold)
//   u(t)  = dr/dt (t + Tp): the command velocity read Tp ahead (Pre-Control, Fig. 10(b)); a
//           negative Tp reads it behind (a drive that averages its feed-forward without look-ahead)
//   f     Ta df/dt = K_FFP/100 * u - f   (averaging of the feed-forward, first order)
//   v_cmd = Kpp (r - theta) + f           (P position loop plus feed-forward)
//   tau   = Kvp (v_cmd - w) + Kvi I,  dI/dt = v_cmd - w   (PI velocity loop, torque command)
//   tau_m = clamp(tau, +-torque_limit)                      (Fig. 18: DD-motor saturation)
//   (J + J1) dw/dt = tau_m - C w - tau_effects(theta, w),  dtheta/dt = w
//
// Load position = theta * r (linear axes, r = lead/2pi [m/rad]) or theta (rotary), passed
// through the position effects (backlash, lead error, offset). The linear part is discretised
// exactly (matrix exponential of the system augmented with the piecewise-linear inputs); ticks in
// which the torque nears its limit, and axes with effects, are integrated with classical RK4 on
// sub-steps instead. Derivation and convergence figures: stages/servo/README.md.
#pragma once

#include <array>
#include <complex>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "gcpipe/block.hpp"

namespace gcpipe {
class Config;
}

namespace gcpipe::servo {

enum class DriveModel : std::uint8_t {
  kDrive,  //!< the feed-drive model above
  kIdeal,  //!< actual = command (axes the source gives no parameters for)
};

/// Settings of one pluggable effect as read from the config: its type and named numbers in the
/// units documented in the README (load-side mm or deg, N*m, s).
struct EffectSettings {
  std::string type;                                   //!< registry name, e.g. "backlash"
  std::vector<std::pair<std::string, double>> values; //!< name -> value
  std::vector<std::pair<std::string, std::vector<double>>> lists = {};  //!< name -> sequence (nnoe weights)
  double get(std::string_view name, double fallback) const;
  /// The sequence `name`, empty when absent.
  const std::vector<double>& list(std::string_view name) const;
};

/// Parameters of one axis, named like seed 002 Table 1. Linear axes: load units mm, rotary: deg.
struct DriveParams {
  DriveModel model = DriveModel::kDrive;
  bool rotary = false;          //!< set from the axis letter (A, C)
  double J = 5.0;               //!< equivalent inertia of the mechanism [kg*m^2]
  double J1 = 0.0;              //!< load inertia [kg*m^2]
  double C = 5.0;               //!< viscous damping [N*m*s/rad]
  double Kpp = 60.0;            //!< position proportional gain [1/s]
  double Kvp = 4700.0;          //!< velocity proportional gain [N*m*s/rad]
  double Kvi = 0.274;           //!< velocity integral gain [N*m/rad] (tau_I = Kvi * integral)
  double K_FFP = 100.0;         //!< Pre-Control feed-forward coefficient [%]
  double Ta = 0.015;            //!< feed-forward averaging time constant [s]
  double Tp = 0.005;            //!< feed-forward preceding (look-ahead) time [s]; < 0: lag
  double Ts = 0.064;            //!< smoothing time constant after interpolation [s] (used by
                                //!< the interpolator; kept here because Table 1 lists it)
  double lead = 0.0;            //!< ball-screw lead [m]; 0: direct drive, r = 1 m/rad (Table 1 Y)
  double torque_limit = 0.0;    //!< motor torque limit [N*m]; 0: none
  std::vector<EffectSettings> effects;  //!< applied in this order (position chain)

  /// Transformation coefficient r [m/rad] (linear) or 1 (rotary).
  double r() const;
  /// Load units (mm or deg) per motor radian.
  double load_per_motor_rad() const;
};

/// All five axes, X Y Z A C.
struct DriveSet {
  std::array<DriveParams, kNumAxes> axes{};
  int substeps = 8;                 //!< RK4 sub-steps per period on the nonlinear path
  double saturation_margin = 0.9;   //!< exact step is redone with RK4 when |tau| at either end
                                    //!< of a period exceeds this fraction of the limit
  /// What the calibration that wrote this file knows its model gets wrong (an axis whose
  /// prediction error stays well above the noise, a structural mismatch): a pipeline that
  /// simulates or compensates with these drives repeats each as a warning.
  std::vector<std::string> prediction_warnings;
};

/// Reads a drives file (pipeline_configs/drives/*.yaml, root mapping); unknown keys rejected;
/// throws ConfigError naming axis, key, value and the limit.
DriveSet load_drives(const Config& root);

// ---------------------------------------------------------------------------------------------
// Effects

/// Per-axis state handed to effects: how to turn load units into motor radians.
struct EffectContext {
  double load_per_motor_rad = 1;  //!< mm or deg per motor rad
  double period = 0.001;          //!< interpolation period [s]
  double substep = 0.001;         //!< integration sub-step on the nonlinear path [s]
};

/// A per-axis effect that can be switched on from the config without touching the core loop.
/// All positions are motor radians; the core calls the hooks in the documented places only.
class AxisEffect {
 public:
  virtual ~AxisEffect() = default;
  virtual std::string_view name() const = 0;
  /// A copy with the same state (a drive is copied with its effects: a run's state is copied
  /// where the compensation learns a window from it).
  virtual std::unique_ptr<AxisEffect> clone() const = 0;
  /// Extra torque opposing the motor [N*m] at motor angle theta [rad] and speed w [rad/s].
  /// Called inside the integrator, so it must not change state.
  virtual double load_torque(double theta, double w) const {
    (void)theta;
    (void)w;
    return 0;
  }
  /// Position chain, motor to table: maps the upstream position [rad] to the downstream one.
  /// Called once at the end of every sub-step, may keep state (backlash).
  virtual double transmit(double upstream) { return upstream; }
  /// True when the effect changes what the position loop sees (then feedback() is sampled once
  /// per sub-step and held, like a real sampled position loop).
  virtual bool alters_feedback() const { return false; }
  /// Position the loop sees, given the motor angle [rad]. Called once per sub-step start.
  virtual double feedback(double theta) { return theta; }
  /// Puts the effect at rest at motor angle theta [rad].
  virtual void reset(double theta) { (void)theta; }

  /// Output-only effects are a correction fitted on the measured output (the NNOE): they never
  /// enter the loop or the integration, so the drive keeps its exact step and adds correction()
  /// to the position at the end of every period.
  virtual bool output_only() const { return false; }
  /// Command samples after this tick's that correction() needs to see.
  virtual int lookahead() const { return 0; }
  /// Correction of this tick's position [load units: mm or deg]; `window` holds the commands in
  /// load units, window[0] the previous tick's, window[1] this tick's, then lookahead() more.
  virtual double correction(std::span<const double> window) {
    (void)window;
    return 0;
  }
};

using EffectFactory = std::unique_ptr<AxisEffect> (*)(const EffectSettings&, const EffectContext&);

/// One registered effect type: its config name, the keys it accepts (unit, default, range are
/// checked by load_drives) and its factory.
struct EffectKey {
  const char* name;
  const char* unit;
  double fallback;
  double min;
  double max;
};
struct EffectType {
  const char* name;
  const char* summary;
  std::vector<EffectKey> keys;
  EffectFactory create;
  std::vector<const char*> list_keys = {};  //!< required sequences of numbers (nnoe weights)
};

/// Registry of effect types (backlash, coulomb_friction, feedback_delay, lead_error, offset,
/// scale_error, measurement_delay, nnoe).
const std::vector<EffectType>& effect_types();
/// Builds an effect from its settings; throws ConfigError for an unknown type.
std::unique_ptr<AxisEffect> make_effect(const EffectSettings& s, const EffectContext& ctx);

// ---------------------------------------------------------------------------------------------
// One axis

/// State of an axis at the end of a period.
struct AxisState {
  double position = 0;   //!< actual load position after effects [mm or deg]
  double velocity = 0;   //!< motor speed converted to load units [mm/s or deg/s]
  double torque = 0;     //!< motor torque after the limit [N*m]
  bool saturated = false;//!< the torque command exceeded the limit in this period
};

class AxisDrive {
 public:
  /// Throws ConfigError for parameters that make no model (non-positive inertia, ...).
  AxisDrive(const DriveParams& p, double period, int substeps, double saturation_margin);
  ~AxisDrive();
  AxisDrive(AxisDrive&&) noexcept;
  AxisDrive& operator=(AxisDrive&&) noexcept;
  /// The same drive in the same state, its effects cloned.
  AxisDrive(const AxisDrive& other);
  AxisDrive& operator=(const AxisDrive& other);

  /// Number of command samples step() needs: c[0] at the start of the period, c[1] at its end,
  /// the rest ahead for the Tp look-ahead (a negative Tp reads the drive's own history instead).
  int window() const;
  /// At rest at `position` [mm or deg].
  void reset(double position);
  /// Advances one period; `commands` has window() samples [mm or deg].
  AxisState step(std::span<const double> commands);
  /// Forces the RK4 path everywhere (for the convergence test and the exact-vs-RK4 check).
  void force_rk4(bool on);
  /// On by default: a step that left the state as it was and gets the same commands again returns
  /// its result without working it out (an axis at rest). Off only to test that this changes no bit.
  void repeat_rests(bool on);
  const DriveParams& params() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// ---------------------------------------------------------------------------------------------
// Five axes with look-ahead buffering

/// One tick of the simulation.
struct ServoSample {
  double t = 0;          //!< [s]
  Axes command{};        //!< commanded positions [mm, deg]
  Axes actual{};         //!< actual positions [mm, deg]
  Axes torque{};         //!< motor torque [N*m] (0 for ideal axes)
  std::uint8_t saturated = 0;  //!< bit i: axis i torque-limited in this tick
};

/// Streams commands through the five drives. Each pushed command is the position at the next
/// tick; the look-ahead delays the output by a few ticks, flush() drains it holding the last
/// command.
class ServoSimulator {
 public:
  ServoSimulator(const DriveSet& drives, double period);
  ~ServoSimulator();
  /// At rest at `position`, time t0; returns the tick for t0.
  ServoSample reset(const Axes& position, double t0 = 0);
  /// Adds the command for the next tick; true when `out` holds a finished tick.
  bool push(const Axes& command, ServoSample& out);
  /// After the last push: true while ticks remain; each call fills one.
  bool flush(ServoSample& out);
  double period() const { return period_; }
  AxisDrive& axis(int i) { return drives_[static_cast<std::size_t>(i)]; }

 private:
  bool step(ServoSample& out);
  void put(const Axes& command);
  std::vector<AxisDrive> drives_;
  double period_;
  std::size_t window_ = 2;
  // Command samples per axis in a mirrored ring: sample j is stored at j and j + window_, so
  // every look-ahead window is one contiguous span without copying or modulo per element.
  std::array<std::vector<double>, kNumAxes> ring_;
  std::size_t head_ = 0, size_ = 0;
  std::size_t pending_ = 0;  // pushed commands not yet simulated
  Axes last_{};
  std::uint64_t tick_ = 0;
  double t0_ = 0;
};

// ---------------------------------------------------------------------------------------------
// Frequency response (the second formulation used by the validation)

/// Closed-loop response theta/r of the continuous model (no saturation, no effects) at s = j*omega,
/// including the look-ahead e^{s Tp} and the averaging 1/(1 + Ta s).
std::complex<double> drive_response(const DriveParams& p, double omega);
/// Same for a general complex s (used for the ramp lag).
std::complex<double> drive_response_s(const DriveParams& p, std::complex<double> s);
/// Fundamental gain of joining samples of period T linearly: sinc^2(omega T / 2) (real).
double first_order_hold_gain(double omega, double period);
/// Quasi-steady lag time of the drive for a ramp command [s] with the velocity integrator
/// neglected (valid while t << Kvp/Kvi): (1 - K_FFP/100 * Gv0) / (Kpp * Gv0),
/// Gv0 = Kvp / (Kvp + C).
double ramp_lag_time(const DriveParams& p);

}  // namespace gcpipe::servo
