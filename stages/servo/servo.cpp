#include "servo.hpp"

#include <Eigen/Dense>
#include <unsupported/Eigen/MatrixFunctions>

#include <algorithm>
#include <bit>
#include <cmath>
#include <numbers>
#include <sstream>

#include "gcpipe/config.hpp"

namespace gcpipe::servo {

namespace {

constexpr double kPi = std::numbers::pi;

std::string axis_name(int i) { return std::string(1, kAxisLetters[i]); }

// Indices of the augmented state z = [theta, w, I, f, r, v, u]: the four physical states and the
// three inputs (ramp position r, its slope v, look-ahead velocity u), so that one matrix
// exponential covers both the plant and the piecewise-linear inputs exactly.
enum : int { kTheta = 0, kW = 1, kI = 2, kF = 3, kR = 4, kV = 5, kU = 6 };
using Mat7 = Eigen::Matrix<double, 7, 7>;
using Mat47 = Eigen::Matrix<double, 4, 7>;
using Vec7 = Eigen::Matrix<double, 7, 1>;
using Vec4 = Eigen::Matrix<double, 4, 1>;

}  // namespace

double EffectSettings::get(std::string_view name, double fallback) const {
  for (const auto& [k, v] : values)
    if (k == name) return v;
  return fallback;
}

const std::vector<double>& EffectSettings::list(std::string_view name) const {
  static const std::vector<double> kNone;
  for (const auto& [k, v] : lists)
    if (k == name) return v;
  return kNone;
}

double DriveParams::r() const {
  if (rotary) return 1.0;
  return lead > 0 ? lead / (2 * kPi) : 1.0;
}

double DriveParams::load_per_motor_rad() const {
  return rotary ? 180.0 / kPi : r() * 1000.0;
}

// ---------------------------------------------------------------------------------------------
// Effects

namespace {

/// Play operator: the table stays put until the motor has taken up half the gap on either side.
class Backlash final : public AxisEffect {
 public:
  std::unique_ptr<AxisEffect> clone() const override { return std::make_unique<Backlash>(*this); }
  explicit Backlash(double half_gap) : half_(half_gap) {}
  std::string_view name() const override { return "backlash"; }
  double transmit(double x) override {
    y_ = std::clamp(y_, x - half_, x + half_);
    return y_;
  }
  void reset(double theta) override { y_ = theta; }

 private:
  double half_;
  double y_ = 0;
};

/// Coulomb friction regularised with tanh so the integrator never sees a discontinuity; below
/// `band` the model is viscous-like, which is where real stick-slip needs an identified model.
class CoulombFriction final : public AxisEffect {
 public:
  std::unique_ptr<AxisEffect> clone() const override { return std::make_unique<CoulombFriction>(*this); }
  CoulombFriction(double torque, double band) : torque_(torque), band_(band) {}
  std::string_view name() const override { return "coulomb_friction"; }
  double load_torque(double, double w) const override {
    // tanh(x) rounds to +-1 in double beyond |x| = 19.06: skip the libm call at feed speeds
    // (it dominated the calibration's friction fits), same result bit for bit.
    const double x = w / band_;
    if (x > 20) return torque_;
    if (x < -20) return -torque_;
    return torque_ * std::tanh(x);
  }

 private:
  double torque_, band_;
};

/// Position feedback sampled once per sub-step and used `n` sub-steps later.
class FeedbackDelay final : public AxisEffect {
 public:
  std::unique_ptr<AxisEffect> clone() const override { return std::make_unique<FeedbackDelay>(*this); }
  explicit FeedbackDelay(std::size_t n) : buf_(n + 1, 0.0) {}
  std::string_view name() const override { return "feedback_delay"; }
  bool alters_feedback() const override { return buf_.size() > 1; }
  double feedback(double theta) override {
    buf_[head_] = theta;
    head_ = (head_ + 1) % buf_.size();
    return buf_[head_];  // oldest sample
  }
  void reset(double theta) override { std::fill(buf_.begin(), buf_.end(), theta); }

 private:
  std::vector<double> buf_;
  std::size_t head_ = 0;
};

/// Periodic lead error of the screw: table = x + a sin(2 pi x / p + phase).
class LeadError final : public AxisEffect {
 public:
  std::unique_ptr<AxisEffect> clone() const override { return std::make_unique<LeadError>(*this); }
  LeadError(double amp, double period, double phase) : a_(amp), k_(2 * kPi / period), ph_(phase) {}
  std::string_view name() const override { return "lead_error"; }
  double transmit(double x) override { return x + a_ * std::sin(k_ * x + ph_); }

 private:
  double a_, k_, ph_;
};

/// Constant geometric offset of the axis (e.g. a misplaced reference mark).
class Offset final : public AxisEffect {
 public:
  std::unique_ptr<AxisEffect> clone() const override { return std::make_unique<Offset>(*this); }
  explicit Offset(double v) : v_(v) {}
  std::string_view name() const override { return "offset"; }
  double transmit(double x) override { return x + v_; }

 private:
  double v_;
};

/// Scale (pitch) error of the screw or encoder in ppm, about the machine zero: x (1 + s 1e-6).
class ScaleError final : public AxisEffect {
 public:
  std::unique_ptr<AxisEffect> clone() const override { return std::make_unique<ScaleError>(*this); }
  explicit ScaleError(double ppm) : f_(1 + ppm * 1e-6) {}
  std::string_view name() const override { return "scale_error"; }
  double transmit(double x) override { return x * f_; }

 private:
  double f_;
};

/// The logged actual channel lags the motion by `delay` (sampling of the drive's position
/// register against the command): out(t) = in(t - delay), linear interpolation between the
/// sub-step samples. It changes what is recorded, not what the loop sees, so it sits in the
/// position chain (put it last) and never in feedback().
class MeasurementDelay final : public AxisEffect {
 public:
  std::unique_ptr<AxisEffect> clone() const override { return std::make_unique<MeasurementDelay>(*this); }
  explicit MeasurementDelay(double substeps_delay)
      : n_(static_cast<std::size_t>(std::floor(substeps_delay))),
        frac_(substeps_delay - std::floor(substeps_delay)),
        buf_(static_cast<std::size_t>(std::floor(substeps_delay)) + 2, 0.0) {}
  std::string_view name() const override { return "measurement_delay"; }
  double transmit(double x) override {
    head_ = (head_ + 1) % buf_.size();
    buf_[head_] = x;
    const std::size_t sz = buf_.size();
    const double a = buf_[(head_ + sz - n_) % sz];      // n_ sub-steps ago
    const double b = buf_[(head_ + sz - n_ - 1) % sz];  // n_ + 1 sub-steps ago
    return (1 - frac_) * a + frac_ * b;
  }
  void reset(double theta) override { std::fill(buf_.begin(), buf_.end(), theta); }

 private:
  std::size_t n_;
  double frac_;
  std::vector<double> buf_;
  std::size_t head_ = 0;
};

std::unique_ptr<AxisEffect> make_scale_error(const EffectSettings& s, const EffectContext&) {
  return std::make_unique<ScaleError>(s.get("ppm", 0));
}
std::unique_ptr<AxisEffect> make_measurement_delay(const EffectSettings& s, const EffectContext& c) {
  return std::make_unique<MeasurementDelay>(std::max(0.0, s.get("delay", 0) / c.substep));
}
std::unique_ptr<AxisEffect> make_backlash(const EffectSettings& s, const EffectContext& c) {
  return std::make_unique<Backlash>(0.5 * s.get("width", 0) / c.load_per_motor_rad);
}
std::unique_ptr<AxisEffect> make_friction(const EffectSettings& s, const EffectContext&) {
  return std::make_unique<CoulombFriction>(s.get("torque", 0), s.get("velocity_band", 0.01));
}
std::unique_ptr<AxisEffect> make_delay(const EffectSettings& s, const EffectContext& c) {
  const double n = std::round(s.get("delay", 0) / c.substep);
  return std::make_unique<FeedbackDelay>(static_cast<std::size_t>(std::max(0.0, n)));
}
std::unique_ptr<AxisEffect> make_lead_error(const EffectSettings& s, const EffectContext& c) {
  const double period = s.get("period", 0);
  if (!(period > 0)) throw ConfigError("effect lead_error: 'period' must be > 0, got " + std::to_string(period));
  return std::make_unique<LeadError>(s.get("amplitude", 0) / c.load_per_motor_rad,
                                     period / c.load_per_motor_rad,
                                     s.get("phase", 0) * kPi / 180.0);
}
std::unique_ptr<AxisEffect> make_offset(const EffectSettings& s, const EffectContext& c) {
  return std::make_unique<Offset>(s.get("value", 0) / c.load_per_motor_rad);
}

}  // namespace

std::unique_ptr<AxisEffect> make_nnoe(const EffectSettings& s, const EffectContext& ctx);  // nnoe_effect.cpp

const std::vector<EffectType>& effect_types() {
  static const std::vector<EffectType> types = {
      {"backlash", "lost motion between motor and table (play operator)",
       {{"width", "mm|deg", 0.0, 0.0, 10.0}}, &make_backlash},
      {"coulomb_friction", "friction torque T*tanh(w/band) opposing the motor",
       {{"torque", "N*m", 0.0, 0.0, 1e5}, {"velocity_band", "rad/s", 0.01, 1e-6, 100.0}},
       &make_friction},
      {"feedback_delay", "position feedback seen by the loop this much later",
       {{"delay", "s", 0.0, 0.0, 0.1}}, &make_delay},
      {"lead_error", "cyclic error a*sin(2*pi*x/period + phase) of the screw or encoder",
       {{"amplitude", "mm|deg", 0.0, 0.0, 1.0},
        {"period", "mm|deg", 0.0, 1e-6, 1e4},
        {"phase", "deg", 0.0, -360.0, 360.0}},
       &make_lead_error},
      {"offset", "constant geometric offset of the axis",
       {{"value", "mm|deg", 0.0, -100.0, 100.0}}, &make_offset},
      {"scale_error", "scale (pitch) error x*(1 + ppm*1e-6) about machine zero",
       {{"ppm", "ppm", 0.0, -1e4, 1e4}}, &make_scale_error},
      {"measurement_delay", "the logged actual position lags the motion (not in the loop)",
       {{"delay", "s", 0.0, 0.0, 0.1}}, &make_measurement_delay},
      {"nnoe", "seed 003 NNOE correction fitted by gcpipe calibrate (output only, not in the loop)",
       {{"period", "s", 0.0, 1e-6, 1.0},
        {"decimation", "", 1.0, 1.0, 1000.0},
        {"na", "", 1.0, 1.0, 16.0},
        {"nb", "", 1.0, 1.0, 16.0},
        {"hidden", "", 1.0, 1.0, 256.0},
        {"y_scale", "mm|deg", 1.0, 1e-15, 1e6},
        {"y_offset", "mm|deg", 0.0, -1e6, 1e6}},
       &make_nnoe,
       {"u_scale", "u_offset", "weights"}},
  };
  return types;
}

std::unique_ptr<AxisEffect> make_effect(const EffectSettings& s, const EffectContext& ctx) {
  for (const auto& t : effect_types())
    if (s.type == t.name) return t.create(s, ctx);
  std::string known;
  for (const auto& t : effect_types()) known += std::string(known.empty() ? "" : ", ") + t.name;
  throw ConfigError("unknown effect '" + s.type + "' (known: " + known + ")");
}

// ---------------------------------------------------------------------------------------------
// Config

namespace {

DriveParams load_axis(const Config& a, int axis) {
  DriveParams p;
  p.rotary = axis == kA || axis == kC;
  a.reject_unknown({"model", "J", "J1", "C", "Kpp", "Kvp", "Kvi", "K_FFP", "Ta", "Tp", "Ts", "lead",
                    "torque_limit", "effects"});
  p.model = a.choice("model", "drive", {"drive", "ideal"}) == "ideal" ? DriveModel::kIdeal
                                                                      : DriveModel::kDrive;
  p.J = a.number("J", p.J, "kg*m^2", 1e-9, 1e4);
  p.J1 = a.number("J1", p.J1, "kg*m^2", 0, 1e4);
  p.C = a.number("C", p.C, "N*m*s/rad", 0, 1e6);
  p.Kpp = a.number("Kpp", p.Kpp, "1/s", 1e-3, 1e4);
  p.Kvp = a.number("Kvp", p.Kvp, "N*m*s/rad", 1e-6, 1e7);
  p.Kvi = a.number("Kvi", p.Kvi, "N*m/rad", 0, 1e9);
  p.K_FFP = a.number("K_FFP", p.K_FFP, "%", 0, 200);
  p.Ta = a.number("Ta", p.Ta, "s", 0, 1);
  p.Tp = a.number("Tp", p.Tp, "s", -0.06, 1);
  p.Ts = a.number("Ts", p.Ts, "s", 0, 2);
  p.lead = a.number("lead", p.lead, "m", 0, 1);
  if (p.rotary && p.lead > 0) throw a.error("lead", "a rotary axis (" + axis_name(axis) + ") has no ball-screw lead; remove the key");
  p.torque_limit = a.number("torque_limit", p.torque_limit, "N*m", 0, 1e6);
  const Config effects = a.section("effects");
  for (const auto& name : effects.keys()) {
    const EffectType* type = nullptr;
    for (const auto& t : effect_types())
      if (name == t.name) type = &t;
    if (type == nullptr) {
      std::string known;
      for (const auto& t : effect_types()) known += std::string(known.empty() ? "" : ", ") + t.name;
      throw effects.error(name, "unknown effect on axis " + axis_name(axis) + " (known: " + known + ")");
    }
    const Config e = effects.section(name);
    EffectSettings s;
    s.type = name;
    for (const auto& k : e.keys()) {
      bool ok = false;
      for (const auto& key : type->keys) ok = ok || k == key.name;
      for (const char* key : type->list_keys) ok = ok || k == key;
      if (!ok) {
        std::string known;
        for (const auto& key : type->keys) known += std::string(known.empty() ? "" : ", ") + key.name;
        for (const char* key : type->list_keys) known += std::string(", ") + key;
        throw e.error(k, "unknown key for effect " + name + " (accepted: " + known + ")");
      }
    }
    for (const auto& key : type->keys) {
      std::string unit = key.unit;
      if (unit == "mm|deg") unit = p.rotary ? "deg" : "mm";
      s.values.emplace_back(key.name, e.number(key.name, key.fallback, unit, key.min, key.max));
    }
    for (const char* key : type->list_keys) {
      if (!e.has(key)) throw e.error(key, "required: a sequence of numbers (written by gcpipe calibrate)");
      s.lists.emplace_back(key, e.numbers(key, 0, "", -1e300, 1e300));
    }
    if ((name == "lead_error" || name == "nnoe") && !e.has("period"))
      throw e.error("period", name == "nnoe" ? std::string("required: the sampling period [s] the model was fitted at")
                                             : "required: the pitch of the cyclic error in " + std::string(p.rotary ? "deg" : "mm"));
    p.effects.push_back(std::move(s));
  }
  return p;
}

}  // namespace

DriveSet load_drives(const Config& root) {
  root.reject_unknown({"substeps", "saturation_margin", "axes", "prediction_warnings"});
  DriveSet d;
  if (root.has("prediction_warnings")) d.prediction_warnings = root.strings("prediction_warnings");
  d.substeps = static_cast<int>(root.integer("substeps", d.substeps, 1, 1000));
  d.saturation_margin = root.number("saturation_margin", d.saturation_margin, "", 0.1, 1.0);
  const Config axes = root.section("axes");
  axes.reject_unknown({"X", "Y", "Z", "A", "C"});
  for (int i = 0; i < kNumAxes; ++i) {
    const std::string n = axis_name(i);
    if (axes.has(n)) {
      d.axes[static_cast<std::size_t>(i)] = load_axis(axes.section(n), i);
    } else {
      DriveParams p;
      p.rotary = i == kA || i == kC;
      p.model = DriveModel::kIdeal;
      d.axes[static_cast<std::size_t>(i)] = p;
    }
  }
  return d;
}

// ---------------------------------------------------------------------------------------------
// One axis

namespace {
// The effects of a drive, copied by cloning them: a drive is copied with its state.
struct EffectList : std::vector<std::unique_ptr<AxisEffect>> {
  EffectList() = default;
  EffectList(EffectList&&) noexcept = default;
  EffectList& operator=(EffectList&&) noexcept = default;
  EffectList(const EffectList& other) {
    reserve(other.size());
    for (const auto& e : other) push_back(e->clone());
  }
  EffectList& operator=(const EffectList& other) {
    EffectList copy(other);
    swap(copy);
    return *this;
  }
};
}  // namespace

struct AxisDrive::Impl {
  DriveParams p;
  double T = 0.001;        // period [s]
  int substeps = 8;
  double margin = 0.9;
  double lpm = 1;          // load units per motor rad
  double Jt = 1, k = 1;    // total inertia, K_FFP as a fraction
  double limit = 0;        // torque limit, +inf when none
  int m = 0;               // whole periods of Tp (negative: the feed-forward lags the command)
  double phi = 0;          // fraction of a period left over of Tp
  // Segment velocities of the last periods [motor rad/s], past[(past_head + k - 1) % size] the one
  // k periods ago: a negative Tp reads them (a drive that averages its feed-forward over a window
  // without look-ahead lags the command by half the window; README "Feed-forward timing").
  static constexpr int kPast = 64;
  std::array<double, kPast> past{};
  int past_head = 0;
  int win = 2;
  bool ideal = false;
  bool force_rk4 = false;
  bool feedback_altered = false;
  Mat47 M;                 // exact transition over a period (top four rows)
  Vec4 g;                  // effect of the mid-period switch of u (phi > 0)
  // state (motor side, theta absolute)
  double theta = 0, w = 0, I = 0, f = 0, out = 0, tau = 0;
  /// The last step of the linear path when it left the state as it found it (an axis at rest):
  /// the same commands give the same result again. `valid` is false otherwise.
  struct Rest {
    bool enabled = true;  //!< off: every step worked out (repeat_rests(), for the test)
    bool valid = false;
    std::array<std::uint64_t, 4> commands{};  //!< bits of c[0], c[1] and of the feed-forward's u1, u2
    AxisState result;
  } rest;
  EffectList effects;
  EffectList outputs;  // output-only corrections, after the chain

  /// Velocity of segment j of the command [motor rad/s]: j = 0 this period's, j > 0 ahead in the
  /// window, j < 0 the one -j periods ago.
  double segment(std::span<const double> c, int j, double inv) const {
    if (j >= 0) return (c[static_cast<std::size_t>(j) + 1] - c[static_cast<std::size_t>(j)]) * inv / T;
    return past[static_cast<std::size_t>((past_head - j - 1) % kPast)];
  }
  void remember(double v) {
    past_head = (past_head + kPast - 1) % kPast;
    past[static_cast<std::size_t>(past_head)] = v;
  }

  // The position at the end of the period [load units] with the output-only corrections.
  double corrected(double position, std::span<const double> c) {
    for (const auto& ef : outputs) position += ef->correction(c);
    return position;
  }

  double vcmd(double e_pos, double f_, double u) const {
    return p.Kpp * e_pos + (p.Ta > 0 ? f_ : k * u);
  }
  double torque_cmd(double e_pos, double w_, double I_, double f_, double u) const {
    return p.Kvp * (vcmd(e_pos, f_, u) - w_) + p.Kvi * I_;
  }

  Mat7 system_matrix() const {
    Mat7 A = Mat7::Zero();
    Eigen::Matrix<double, 1, 7> a = Eigen::Matrix<double, 1, 7>::Zero();  // v_cmd row
    a(kTheta) = -p.Kpp;
    a(kR) = p.Kpp;
    if (p.Ta > 0) a(kF) = 1; else a(kU) = k;
    Eigen::Matrix<double, 1, 7> t = p.Kvp * a;  // torque row
    t(kW) -= p.Kvp;
    t(kI) += p.Kvi;
    A(kTheta, kW) = 1;
    A.row(kW) = t / Jt;
    A(kW, kW) -= p.C / Jt;
    A.row(kI) = a;
    A(kI, kW) -= 1;
    if (p.Ta > 0) {
      A(kF, kU) = k / p.Ta;
      A(kF, kF) = -1 / p.Ta;
    }
    A(kR, kV) = 1;
    return A;
  }

  // RK4 over [t0, t0 + h] with the ramp r = r0 + v t, constant u; returns whether the torque
  // command exceeded the limit at any stage.
  bool rk4(double& th, double& ww, double& ii, double& ff, double r0, double v, double u, double t0,
           double h, double fb_offset) const {
    bool sat = false;
    auto deriv = [&](double t, double th_, double w_, double i_, double f_, double* d) {
      // The loop sees feedback = theta + fb_offset (fb_offset != 0 only with a delay effect,
      // where it is held over the sub-step).
      const double e = r0 + v * t - (th_ + fb_offset);
      const double vc = vcmd(e, f_, u);
      double tq = p.Kvp * (vc - w_) + p.Kvi * i_;
      bool s = false;
      if (tq > limit) { tq = limit; s = true; }
      if (tq < -limit) { tq = -limit; s = true; }
      sat = sat || s;
      double load = 0;
      for (const auto& ef : effects) load += ef->load_torque(th_, w_);
      d[0] = w_;
      d[1] = (tq - p.C * w_ - load) / Jt;
      // Conditional integration: a saturated drive stops integrating (anti-windup).
      d[2] = s ? 0.0 : vc - w_;
      d[3] = p.Ta > 0 ? (k * u - f_) / p.Ta : 0.0;
    };
    double k1[4], k2[4], k3[4], k4[4];
    deriv(t0, th, ww, ii, ff, k1);
    deriv(t0 + h / 2, th + h / 2 * k1[0], ww + h / 2 * k1[1], ii + h / 2 * k1[2], ff + h / 2 * k1[3], k2);
    deriv(t0 + h / 2, th + h / 2 * k2[0], ww + h / 2 * k2[1], ii + h / 2 * k2[2], ff + h / 2 * k2[3], k3);
    deriv(t0 + h, th + h * k3[0], ww + h * k3[1], ii + h * k3[2], ff + h * k3[3], k4);
    th += h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]);
    ww += h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]);
    ii += h / 6 * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2]);
    ff += h / 6 * (k1[3] + 2 * k2[3] + 2 * k3[3] + k4[3]);
    return sat;
  }

  // The nonlinear path: sub-steps aligned with the look-ahead switch inside the period.
  bool step_rk4(double c0, double v, double u1, double u2) {
    bool sat = false;
    const double h1 = (1 - phi) * T;
    const double pieces[2][2] = {{0, h1}, {h1, T}};
    double th = theta - c0;  // shifted so that r starts at 0: keeps the error digits
    for (int piece = 0; piece < (phi > 0 ? 2 : 1); ++piece) {
      const double a = pieces[piece][0], b = piece == 0 && phi == 0 ? T : pieces[piece][1];
      const int n = std::max(1, static_cast<int>(std::lround(substeps * (b - a) / T)));
      const double h = (b - a) / n;
      const double u = piece == 0 ? u1 : u2;
      for (int i = 0; i < n; ++i) {
        const double t = a + i * h;
        double fb_offset = 0;
        if (feedback_altered) {
          double fb = th + c0;
          for (const auto& ef : effects) fb = ef->feedback(fb);
          fb_offset = fb - (th + c0);
        }
        sat = rk4(th, w, I, f, 0.0, v, u, t, h, fb_offset) || sat;
        double pos = th + c0;
        for (const auto& ef : effects) pos = ef->transmit(pos);
        out = pos;
      }
    }
    theta = th + c0;
    if (effects.empty()) out = theta;
    const double e = v * T - th;
    tau = std::clamp(torque_cmd(e, w, I, f, phi > 0 ? u2 : u1), -limit, limit);
    return sat;
  }
};

AxisDrive::AxisDrive(const DriveParams& p, double period, int substeps, double margin)
    : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.p = p;
  s.T = period;
  s.substeps = substeps;
  s.margin = margin;
  s.lpm = p.load_per_motor_rad();
  s.Jt = p.J + p.J1;
  s.k = p.K_FFP / 100.0;
  s.limit = p.torque_limit > 0 ? p.torque_limit : std::numeric_limits<double>::infinity();
  s.ideal = p.model == DriveModel::kIdeal;
  if (!(period > 0) || !std::isfinite(period))
    throw ConfigError("servo: period " + std::to_string(period) + " s must be > 0");
  EffectContext ctx;
  ctx.load_per_motor_rad = s.lpm;
  ctx.period = period;
  ctx.substep = period / substeps;
  for (const auto& e : p.effects) {
    auto effect = make_effect(e, ctx);
    (effect->output_only() ? s.outputs : s.effects).push_back(std::move(effect));
  }
  int lookahead = 0;
  for (const auto& e : s.outputs) lookahead = std::max(lookahead, e->lookahead());
  if (s.ideal) {
    s.effects.clear();  // an ideal axis is its command: only a fitted correction applies
    s.win = 2 + lookahead;
    return;
  }
  if (!(s.Jt > 0)) throw ConfigError("servo: J + J1 must be > 0");
  const double q = p.Tp / period;
  s.m = static_cast<int>(std::floor(q + 1e-9));
  s.phi = q - s.m;
  if (s.phi < 1e-9) s.phi = 0;
  if (s.phi > 1 - 1e-9) { s.m += 1; s.phi = 0; }
  s.win = std::max(2, s.m + 2 + (s.phi > 0 ? 1 : 0));
  if (s.win > 64) throw ConfigError("servo: Tp = " + std::to_string(p.Tp) + " s needs more than 62 periods of look-ahead");
  if (s.m < -Impl::kPast) throw ConfigError("servo: Tp = " + std::to_string(p.Tp) + " s lags the command by more than " + std::to_string(Impl::kPast) + " periods");
  s.win = std::max(s.win, 2 + lookahead);
  for (const auto& e : s.effects) s.feedback_altered = s.feedback_altered || e->alters_feedback();

  const Mat7 A = s.system_matrix();
  if (s.phi > 0) {
    const Mat7 Pa = (A * ((1 - s.phi) * period)).exp();
    const Mat7 Pb = (A * (s.phi * period)).exp();
    const Mat7 P = Pb * Pa;
    s.M = P.topRows<4>();
    s.g = Pb.block<4, 1>(0, kU);
  } else {
    const Mat7 P = (A * period).exp();
    s.M = P.topRows<4>();
    s.g.setZero();
  }
  if (!s.M.allFinite()) throw ConfigError("servo: the drive parameters give a non-finite transition matrix");
}

AxisDrive::~AxisDrive() = default;
AxisDrive::AxisDrive(AxisDrive&&) noexcept = default;
AxisDrive& AxisDrive::operator=(AxisDrive&&) noexcept = default;
AxisDrive::AxisDrive(const AxisDrive& other) : impl_(std::make_unique<Impl>(*other.impl_)) {}
AxisDrive& AxisDrive::operator=(const AxisDrive& other) {
  if (this != &other) impl_ = std::make_unique<Impl>(*other.impl_);
  return *this;
}

int AxisDrive::window() const { return impl_->win; }
const DriveParams& AxisDrive::params() const { return impl_->p; }
void AxisDrive::force_rk4(bool on) { impl_->force_rk4 = on; }

void AxisDrive::repeat_rests(bool on) {
  impl_->rest.enabled = on;
  impl_->rest.valid = false;
}

void AxisDrive::reset(double position) {
  Impl& s = *impl_;
  s.theta = position / s.lpm;
  s.w = s.I = s.f = s.tau = 0;
  s.past.fill(0.0);
  s.out = s.theta;
  s.rest.valid = false;
  for (auto& e : s.effects) e->reset(s.theta);
  for (auto& e : s.outputs) e->reset(s.theta);
  // Rest means the position chain is settled too: run it once so offsets show from tick 0.
  double pos = s.theta;
  for (auto& e : s.effects) pos = e->transmit(pos);
  s.out = pos;
}

AxisState AxisDrive::step(std::span<const double> c) {
  Impl& s = *impl_;
  if (s.ideal) return {s.corrected(c[1], c), (c[1] - c[0]) / s.T, 0.0, false};
  const double inv = 1.0 / s.lpm;
  const double c0 = c[0] * inv;
  const double v = (c[1] - c[0]) * inv / s.T;
  const double u1 = s.segment(c, s.m, inv);
  const double u2 = s.phi > 0 ? s.segment(c, s.m + 1, inv) : u1;
  s.remember(v);

  bool sat = false;
  if (s.effects.empty() && !s.force_rk4) {
    // An axis at rest (the bench's A and C, a settled Z): the step is a function of the state and
    // these four commands only, so when neither changed its result is the last one, bit for bit.
    const std::array<std::uint64_t, 4> commands{
        std::bit_cast<std::uint64_t>(c[0]), std::bit_cast<std::uint64_t>(c[1]), std::bit_cast<std::uint64_t>(u1),
        std::bit_cast<std::uint64_t>(u2)};
    if (s.rest.valid && s.rest.commands == commands) return s.rest.result;
    const double th0 = s.theta - c0;
    Vec7 z;
    z << th0, s.w, s.I, s.f, 0.0, v, u1;
    Vec4 x = s.M * z;
    if (s.phi > 0) x += s.g * (u2 - u1);
    const double tau0 = s.p.Kvp * (s.vcmd(-th0, s.f, u1) - s.w) + s.p.Kvi * s.I;
    const double tau1 = s.p.Kvp * (s.vcmd(v * s.T - x(0), x(3), u2) - x(1)) + s.p.Kvi * x(2);
    const double guard = s.margin * s.limit;
    if (std::abs(tau0) <= guard && std::abs(tau1) <= guard) {
      const std::array<double, 4> before{s.theta, s.w, s.I, s.f};
      s.theta = x(0) + c0;
      s.w = x(1);
      s.I = x(2);
      s.f = x(3);
      s.tau = tau1;
      s.out = s.theta;
      const AxisState result{s.corrected(s.out * s.lpm, c), s.w * s.lpm, s.tau, false};
      const std::array<double, 4> after{s.theta, s.w, s.I, s.f};
      s.rest.valid = s.rest.enabled && s.outputs.empty() && std::bit_cast<std::array<std::uint64_t, 4>>(before) ==
                                              std::bit_cast<std::array<std::uint64_t, 4>>(after);
      s.rest.commands = commands;
      s.rest.result = result;
      return result;
    }
  }
  s.rest.valid = false;
  sat = s.step_rk4(c0, v, u1, u2);
  return {s.corrected(s.out * s.lpm, c), s.w * s.lpm, s.tau, sat};
}

// ---------------------------------------------------------------------------------------------
// Five axes

ServoSimulator::ServoSimulator(const DriveSet& d, double period) : period_(period) {
  for (int i = 0; i < kNumAxes; ++i) {
    drives_.emplace_back(d.axes[static_cast<std::size_t>(i)], period, d.substeps, d.saturation_margin);
    window_ = std::max(window_, static_cast<std::size_t>(drives_.back().window()));
  }
  for (auto& r : ring_) r.assign(2 * window_, 0.0);
}

ServoSimulator::~ServoSimulator() = default;

void ServoSimulator::put(const Axes& c) {
  const std::size_t pos = (head_ + size_) % window_;
  for (std::size_t a = 0; a < kNumAxes; ++a) {
    ring_[a][pos] = c[a];
    ring_[a][pos + window_] = c[a];
  }
  ++size_;
  last_ = c;
}

ServoSample ServoSimulator::reset(const Axes& position, double t0) {
  for (int i = 0; i < kNumAxes; ++i) drives_[static_cast<std::size_t>(i)].reset(position[static_cast<std::size_t>(i)]);
  head_ = 0;
  size_ = 0;
  put(position);
  pending_ = 0;
  tick_ = 0;
  t0_ = t0;
  ServoSample s;
  s.t = t0;
  s.command = position;
  s.actual = position;
  return s;
}

bool ServoSimulator::step(ServoSample& out) {
  out.saturated = 0;
  for (std::size_t a = 0; a < kNumAxes; ++a) {
    AxisDrive& d = drives_[a];
    const double* w = ring_[a].data() + head_;
    const AxisState st = d.step(std::span<const double>(w, static_cast<std::size_t>(d.window())));
    out.actual[a] = st.position;
    out.torque[a] = st.torque;
    out.command[a] = w[1];
    if (st.saturated) out.saturated = static_cast<std::uint8_t>(out.saturated | (1u << a));
  }
  ++tick_;
  out.t = t0_ + static_cast<double>(tick_) * period_;
  head_ = head_ + 1 == window_ ? 0 : head_ + 1;
  --size_;
  --pending_;
  return true;
}

bool ServoSimulator::push(const Axes& command, ServoSample& out) {
  put(command);
  ++pending_;
  if (size_ < window_) return false;
  return step(out);
}

bool ServoSimulator::flush(ServoSample& out) {
  if (pending_ == 0) return false;
  const Axes held = last_;
  while (size_ < window_) put(held);
  return step(out);
}

// ---------------------------------------------------------------------------------------------
// Frequency response

std::complex<double> drive_response_s(const DriveParams& p, std::complex<double> s) {
  if (p.model == DriveModel::kIdeal) return 1.0;
  const double Jt = p.J + p.J1;
  const std::complex<double> Kc = p.Kvp + p.Kvi / s;          // PI velocity controller
  const std::complex<double> Gv = Kc / (Jt * s + p.C + Kc);  // velocity loop w / v_cmd
  std::complex<double> F = (p.K_FFP / 100.0) * std::exp(s * p.Tp) * s;
  if (p.Ta > 0) F /= (1.0 + p.Ta * s);
  return Gv * (p.Kpp + F) / (s + p.Kpp * Gv);
}

std::complex<double> drive_response(const DriveParams& p, double omega) {
  return drive_response_s(p, {0.0, omega});
}

double first_order_hold_gain(double omega, double period) {
  const double x = omega * period / 2;
  if (std::abs(x) < 1e-12) return 1.0;
  const double s = std::sin(x) / x;
  return s * s;
}

double ramp_lag_time(const DriveParams& p) {
  if (p.model == DriveModel::kIdeal) return 0.0;
  const double gv0 = p.Kvp / (p.Kvp + p.C);
  return (1 - p.K_FFP / 100.0 * gv0) / (p.Kpp * gv0);
}

}  // namespace gcpipe::servo
