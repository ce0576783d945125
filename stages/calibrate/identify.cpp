#include "identify.hpp"

#include <unsupported/Eigen/LevenbergMarquardt>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <limits>
#include <map>
#include <optional>

#include "axis_model.hpp"

namespace gcpipe::calibrate {

// ---------------------------------------------------------------------------------------------
// Least squares

namespace {

struct LmFunctor : Eigen::DenseFunctor<double> {
  LmFunctor(const ResidualFn& r, const Eigen::VectorXd& step, bool analytic, int n, int m, int& count)
      : DenseFunctor<double>(n, m), r_(r), step_(step), analytic_(analytic), count_(count) {}
  int operator()(const InputType& x, ValueType& f) const {
    f = r_(x, nullptr);
    ++count_;
    return 0;
  }
  int df(const InputType& x, JacobianType& j) const {
    if (analytic_) {
      (void)r_(x, &j);
      ++count_;
    } else {
      j = numeric_jacobian(r_, x, step_);
      count_ += 2 * static_cast<int>(x.size());
    }
    return 0;
  }
  const ResidualFn& r_;
  Eigen::VectorXd step_;
  bool analytic_;
  int& count_;
};

}  // namespace

Eigen::MatrixXd numeric_jacobian(const ResidualFn& r, const Eigen::VectorXd& x, const Eigen::VectorXd& step) {
  Eigen::MatrixXd j;
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    Eigen::VectorXd a = x, b = x;
    a[i] += step[i];
    b[i] -= step[i];
    const Eigen::VectorXd col = (r(a, nullptr) - r(b, nullptr)) / (2 * step[i]);
    if (j.size() == 0) j.resize(col.size(), x.size());
    j.col(i) = col;
  }
  return j;
}

LsqResult least_squares(const ResidualFn& r, const Eigen::VectorXd& x0, const Eigen::VectorXd& step,
                        bool analytic, double tau, int max_evaluations) {
  LsqResult out;
  out.x = x0;
  const Eigen::VectorXd f0 = r(x0, nullptr);
  const int m = static_cast<int>(f0.size()), n = static_cast<int>(x0.size());
  int count = 1;
  LmFunctor fn(r, step, analytic, n, m, count);
  Eigen::LevenbergMarquardt<LmFunctor> lm(fn);
  lm.setMaxfev(max_evaluations);
  lm.setXtol(1e-8);
  lm.setFtol(1e-10);
  lm.minimize(out.x);
  const Eigen::VectorXd f = r(out.x, nullptr);
  out.sse = f.squaredNorm();
  // Covariance of the estimate: s^2 (J'J)^-1, s^2 = SSE/(m - n), inflated by the correlation
  // time because neighbouring residual samples are not independent.
  Eigen::MatrixXd j;
  if (analytic) (void)r(out.x, &j);
  else j = numeric_jacobian(r, out.x, step);
  const double s2 = out.sse / std::max(1, m - n);
  out.jtj_inv = (j.transpose() * j).ldlt().solve(Eigen::MatrixXd::Identity(n, n));
  const Eigen::MatrixXd cov = out.jtj_inv * s2 * tau;
  out.sigma = cov.diagonal().cwiseMax(0).cwiseSqrt();
  out.evaluations = count;
  return out;
}

double bic(double sse, std::size_t n, double tau, int k) {
  // A fit that produced no finite residual, or scored on no samples, is no evidence at all: +inf
  // (never a NaN in a report).
  if (n == 0 || !std::isfinite(sse) || !(tau >= 1) || !std::isfinite(tau)) return std::numeric_limits<double>::infinity();
  const double ne = static_cast<double>(n) / tau;
  return ne * std::log(std::max(sse, 1e-300) / static_cast<double>(n)) + k * std::log(ne);
}

// ---------------------------------------------------------------------------------------------
// One axis

namespace {

/// Sampling periods above this [s] cannot show a drive's loop (time constants of 5-30 ms).
constexpr double kLoopVisiblePeriod = 0.01;

struct Ctx {
  const AxisSeries& s;
  const IdentifyOptions& o;
  const servo::DriveParams& config;  //!< the configured drive of the axis
  std::size_t n() const { return s.command.size(); }

  /// Prediction of the first `end` samples (plus a margin so the held last command of the
  /// truncated look-ahead does not reach the scored samples).
  std::vector<double> predict(const servo::DriveParams& p, std::size_t end, std::vector<double>* torque = nullptr) const {
    const std::size_t e = std::min(n(), end + 64);
    std::vector<double> y;
    y.reserve(e);
    if (torque) torque->clear();
    for (std::size_t i = 0; i < s.segments.size() && s.segments[i] < e; ++i) {
      const std::size_t a = s.segments[i], z = i + 1 < s.segments.size() ? std::min(e, s.segments[i + 1]) : e;
      const std::span<const double> cmd(s.command.data() + a, z - a);
      std::vector<double> tq;
      std::vector<double> part;
      try {
        part = simulate_motor(p, s.substeps, s.margin, s.period, cmd, torque ? &tq : nullptr);
      } catch (const std::exception& ex) {
        if (std::getenv("GCPIPE_CALIBRATE_DEBUG"))
          std::fprintf(stderr, "predict failed (%s): Kpp %g Kvp %g C %g Kvi %g K_FFP %g Ta %g Tp %g\n", ex.what(), p.Kpp, p.Kvp, p.C, p.Kvi, p.K_FFP, p.Ta, p.Tp);
        // A search may step to parameters that make no drive (a non-finite transition matrix):
        // a prediction 1 m off tells the least squares to step back, instead of ending the run.
        part.assign(cmd.begin(), cmd.end());
        for (double& v : part) v += 1000;
        tq.assign(cmd.size(), 0.0);
      }
      for (const auto& ef : p.effects)
        if (!is_dynamic_effect(ef.type)) apply_output_effect(ef, s.period, part);
      y.insert(y.end(), part.begin(), part.end());
      if (torque) torque->insert(torque->end(), tq.begin(), tq.end());
    }
    return y;
  }
  bool has_torque() const { return s.effort_kind == "torque" && s.effort.size() == n(); }
  /// Torque residuals in units of the position noise: one least-squares problem for both.
  double torque_weight() const { return std::max(s.noise, 1e-9) / std::max(estimate_noise(s.effort), 1e-9); }
  double torque_mse(const std::vector<double>& tq, std::size_t b, std::size_t e) const {
    double q = 0;
    for (std::size_t k = b; k < e; ++k) q += (s.effort[k] - tq[k]) * (s.effort[k] - tq[k]);
    return e > b ? q / static_cast<double>(e - b) : 0;
  }
  Eigen::VectorXd residual(const std::vector<double>& y, std::size_t b, std::size_t e) const {
    Eigen::VectorXd r(static_cast<Eigen::Index>(e - b));
    for (std::size_t k = b; k < e; ++k) r[static_cast<Eigen::Index>(k - b)] = s.actual[k] - y[k];
    return r;
  }
  double sse(const std::vector<double>& y, std::size_t b, std::size_t e) const { return residual(y, b, e).squaredNorm(); }
  double fit_sse(const std::vector<double>& y) const { return sse(y, s.begin, s.split); }
  double heldout_mse(const std::vector<double>& y) const {
    return s.split < n() ? sse(y, s.split, n()) / static_cast<double>(n() - s.split) : 0;
  }
  double tau(const std::vector<double>& y) const {
    const Eigen::VectorXd r = residual(y, s.begin, s.split);
    return correlation_time(std::span<const double>(r.data(), static_cast<std::size_t>(r.size())));
  }
  std::size_t nfit() const { return s.split - s.begin; }
  std::size_t dynamic_end() const { return std::min(s.split, s.begin + o.max_dynamic_fit); }
};

// --- declared parameters ---------------------------------------------------------------------

struct DeclaredSlot {
  const char* name;
  const char* unit;
  double servo::DriveParams::*field;
};
const std::vector<DeclaredSlot>& declared_slots() {
  // The order of base_slots() (base_model.hpp), then J. J is fitted only with a torque column:
  // the positions see it only through the ratios Kvp/J, C/J, Kvi/J (so without torque J stays
  // configured and the others are fitted relative to it); the torque sees J itself. Kvi is held
  // wherever its corner Kvi/Kvp is far below what a trace of seconds can see (seed 002 Table 1:
  // 1e-3 rad/s) and free where a drive is tuned with its integral corner near the position loop.
  static const std::vector<DeclaredSlot> s = {{"Kpp", "1/s", &servo::DriveParams::Kpp},
                                              {"Kvp", "N*m*s/rad", &servo::DriveParams::Kvp},
                                              {"C", "N*m*s/rad", &servo::DriveParams::C},
                                              {"Kvi", "N*m/rad", &servo::DriveParams::Kvi},
                                              {"K_FFP", "%", &servo::DriveParams::K_FFP},
                                              {"Ta", "s", &servo::DriveParams::Ta},
                                              {"Tp", "s", &servo::DriveParams::Tp},
                                              {"J", "kg*m^2", &servo::DriveParams::J}};
  return s;
}

/// The declared parameters a local fit moves, kept where a drive can be: feed-forward 0 ... 100 %
/// (or up to the configured value where the config sets more),
/// look-ahead 0 ... 50 ms (and what the servo's window holds at this period).
void keep_in_range(servo::DriveParams& p, double period, double configured_ffp) {
  // The ranges of base_slots (base_model.cpp), J-relative ones on this drive's J: a local fit
  // that leaves them finds a model no drive is (measured: Ta 1e-9 s on a two-mass Y, whose
  // compensation then cut 15.9 mm off the path on that machine).
  servo::DriveParams range_of = p;
  range_of.K_FFP = configured_ffp;  // the feed-forward's range opens to a higher configured value
  for (const BaseSlot& b : base_slots(range_of, false, period)) p.*(b.field) = std::clamp(p.*(b.field), b.lo, b.hi);
}

/// Fits multipliers of the free declared parameters of `start`; returns the multipliers and sigmas.
LsqResult fit_declared(const Ctx& c, const servo::DriveParams& start, const std::vector<int>& free, double tau) {
  const auto& slots = declared_slots();
  const std::size_t end = c.dynamic_end();
  const bool torque = c.has_torque();
  const double w = torque ? c.torque_weight() : 0;
  ResidualFn r = [&](const Eigen::VectorXd& x, Eigen::MatrixXd*) {
    servo::DriveParams p = start;
    for (std::size_t i = 0; i < free.size(); ++i) p.*(slots[static_cast<std::size_t>(free[i])].field) *= std::max(x[static_cast<Eigen::Index>(i)], 1e-3);
    keep_in_range(p, c.s.period, c.config.K_FFP);
    std::vector<double> tq;
    const Eigen::VectorXd rp = c.residual(c.predict(p, end, torque ? &tq : nullptr), c.s.begin, end);
    if (!torque) return rp;
    // Positions and torque in one problem, the torque in units of the position noise.
    Eigen::VectorXd both(2 * rp.size());
    both.head(rp.size()) = rp;
    for (std::size_t k = c.s.begin; k < end; ++k) both[rp.size() + static_cast<Eigen::Index>(k - c.s.begin)] = w * (c.s.effort[k] - tq[k]);
    return both;
  };
  const auto n = static_cast<Eigen::Index>(free.size());
  return least_squares(r, Eigen::VectorXd::Ones(n), Eigen::VectorXd::Constant(n, 1e-4), false, tau);
}

/// Each declared parameter with why it is held, if it is: off in `start`, J without a torque
/// signal, the velocity loop's gains when the position cannot see them. Returns the free ones.
std::vector<int> declare(const Ctx& c, AxisIdentification& id, const servo::DriveParams& start) {
  const auto& slots = declared_slots();
  std::vector<int> free;
  for (std::size_t i = 0; i < slots.size(); ++i) {
    const double from = start.*(slots[i].field);
    DeclaredParam d{slots[i].name, slots[i].unit, id.config.*(slots[i].field), from, 0, false, ""};
    const double vel_bw = (start.Kvp + start.C) / (start.J + start.J1);
    if (!(from > 0)) { d.held = true; d.why = "0 (feature off) in the identified drive: not refitted"; }
    else if (d.name == "J" && !c.has_torque()) {
      d.held = true;
      d.why = c.s.effort_kind == "current"
                  ? "current column only: J and the motor's torque constant scale together; kept at the configured value"
                  : "no torque signal in the trace: a position trace sees J only through Kvp/J, C/J, Kvi/J; kept at the configured value";
    } else if ((d.name == "Kvp" || d.name == "C") && vel_bw > 5 * start.Kpp && !c.has_torque()) {
      // A velocity loop much faster than the position loop shows in the position only as a lag
      // of about J/(Kvp + C): the same signature as a delay, so a position trace cannot tell a
      // velocity gain from a delay (and sees J only through Kvp/J anyway).
      d.held = true;
      d.why = "velocity loop (" + std::to_string(vel_bw) + " rad/s) >> position loop: seen only as a lag J/(Kvp+C), not separable from delays without a torque signal; kept";
    } else free.push_back(static_cast<int>(i));
    id.declared.push_back(d);
  }
  return free;
}

/// Keeps the refitted drive only when it pays: BIC drops by the margin on the fit samples and
/// the held-out part gets better (or, with a torque column, the held-out torque does while the
/// positions do not get worse). Otherwise the configured drive stands.
void judge_refit(const Ctx& c, AxisIdentification& id, int k, double tau) {
  std::vector<double> tq0, tq1;
  id.pred_refit = c.predict(id.refit, c.n(), c.has_torque() ? &tq1 : nullptr);
  const double b0 = bic(c.fit_sse(id.pred_declared), c.nfit(), tau, 0);
  const double b1 = bic(c.fit_sse(id.pred_refit), c.nfit(), tau, k);
  const double h0 = c.heldout_mse(id.pred_declared), h1 = c.heldout_mse(id.pred_refit);
  const bool heldout_ok = c.s.split >= c.n() || h1 < h0 * (1 - c.o.heldout_gain);
  id.refit_kept = k > 0 && b1 < b0 - c.o.bic_margin && heldout_ok;
  id.refit_note = "BIC " + std::to_string(b0) + " -> " + std::to_string(b1) + ", held-out rms " +
                  std::to_string(std::sqrt(h0)) + " -> " + std::to_string(std::sqrt(h1));
  if (c.has_torque() && k > 0) {
    // The torque can show what the positions cannot (J with the gains scaled alike): the refit
    // also pays when it lowers the held-out torque error and the positions do not get worse.
    (void)c.predict(id.config, c.n(), &tq0);
    const std::size_t b = c.s.split < c.n() ? c.s.split : c.s.begin, e = c.n();
    const double t0 = c.torque_mse(tq0, b, e), t1 = c.torque_mse(tq1, b, e);
    id.refit_note += ", held-out torque rms " + std::to_string(std::sqrt(t0)) + " -> " + std::to_string(std::sqrt(t1)) + " N*m";
    id.refit_kept = id.refit_kept || (t1 < t0 * (1 - c.o.heldout_gain) && h1 <= h0 * (1 + c.o.heldout_gain));
  }
  if (!id.refit_kept) {
    id.refit = id.config;
    id.pred_refit = id.pred_declared;
    for (auto& d : id.declared) {
      if (!d.held) { d.held = true; d.fitted = d.config; d.sigma = 0; d.why = "refit did not pay (" + id.refit_note + ")"; }
      d.excitation_held = false;  // the configured model stands: nothing for an effect to free
    }
  }
}

/// Local refit of the declared parameters from `start` (the identified base drive), with the
/// torque column in the same problem: the path for traces that carry torque, where J is free.
void refit_declared(const Ctx& c, AxisIdentification& id, const servo::DriveParams& start) {
  const auto& slots = declared_slots();
  std::vector<int> free = declare(c, id, start);
  const double tau = c.tau(id.pred_declared);
  LsqResult fit;
  // Fit, then hold every parameter the trace cannot pin down and fit the rest again: a poorly
  // determined parameter would otherwise wander along a valley. "Cannot pin down" is judged by
  // what the measurement noise allows, sigma_noise = noise sqrt((J'J)^-1_ii) on the multiplier,
  // above 25 %: that is a property of the trace's excitation, not of how wrong the start was
  // (the tau-inflated sigma of a badly fitting start would hold everything).
  const double noise = std::max(c.s.noise, 1e-9);
  for (int pass = 0; pass < 4 && !free.empty(); ++pass) {
    fit = fit_declared(c, start, free, tau);
    int worst = -1;
    double worst_rel = 0.25;
    std::string why;
    for (std::size_t i = 0; i < free.size(); ++i) {
      const auto ii = static_cast<Eigen::Index>(i);
      const double xi = fit.x[ii], rel = noise * std::sqrt(std::max(fit.jtj_inv(ii, ii), 0.0)) / std::max(xi, 1e-9);
      if (!(xi > 0.05)) {
        worst = static_cast<int>(i);
        why = "the local refit drove it to " + std::to_string(xi) + " x its start, the edge of its search: kept";
        break;
      }
      if (!std::isfinite(rel) || rel > worst_rel) {
        worst = static_cast<int>(i);
        worst_rel = std::isfinite(rel) ? rel : 1e300;
        why = "not separable in this trace (noise-limited relative sigma " + std::to_string(rel) + "): kept";
      }
    }
    if (worst < 0) break;
    // Hold only the worst one per pass: once it is fixed the others may separate well.
    DeclaredParam& d = id.declared[static_cast<std::size_t>(free[static_cast<std::size_t>(worst)])];
    d.held = true;
    d.excitation_held = true;
    d.why = why;
    free.erase(free.begin() + worst);
    if (free.empty()) fit = LsqResult{};
  }
  id.refit = start;
  for (std::size_t i = 0; i < free.size(); ++i) {
    DeclaredParam& d = id.declared[static_cast<std::size_t>(free[i])];
    const double from = start.*(slots[static_cast<std::size_t>(free[i])].field);
    d.sigma = from * fit.sigma[static_cast<Eigen::Index>(i)];
    id.refit.*(slots[static_cast<std::size_t>(free[i])].field) = from * std::max(fit.x[static_cast<Eigen::Index>(i)], 1e-3);
  }
  keep_in_range(id.refit, c.s.period, c.config.K_FFP);
  for (int slot : free) id.declared[static_cast<std::size_t>(slot)].fitted = id.refit.*(slots[static_cast<std::size_t>(slot)].field);
  judge_refit(c, id, static_cast<int>(free.size()), tau);
}

/// The base drive identified without torque (base_model.hpp) as the refit: its table becomes the
/// declared parameters, held where the trace could not pin them down.
void take_base(const Ctx& c, AxisIdentification& id) {
  const auto& slots = declared_slots();
  int k = 0;
  for (std::size_t i = 0; i < slots.size(); ++i) {
    DeclaredParam d{slots[i].name, slots[i].unit, id.config.*(slots[i].field), id.config.*(slots[i].field), 0, true, ""};
    const auto t = std::find_if(id.base.table.begin(), id.base.table.end(), [&](const BaseFitParam& b) { return b.name == d.name; });
    if (t == id.base.table.end()) {
      d.why = c.s.effort_kind == "current"
                  ? "current column only: J and the motor's torque constant scale together; kept at the configured value"
                  : "no torque signal in the trace: a position trace sees J only through Kvp/J, C/J, Kvi/J; kept at the configured value";
    } else if (t->free) {
      d.held = false;
      d.fitted = t->fitted;
      d.sigma = t->sigma;
      ++k;
    } else {
      d.why = t->why;
      d.excitation_held = true;
    }
    id.declared.push_back(d);
  }
  id.refit = id.base.params;
  judge_refit(c, id, k, c.tau(id.pred_declared));
}

}  // namespace
}  // namespace gcpipe::calibrate

namespace gcpipe::calibrate {
namespace {

// --- the catalogue --------------------------------------------------------------------------

/// A fitted candidate before scoring: the model with the effect and its parameters.
struct Trial {
  std::string effect;
  servo::DriveParams model;
  std::vector<FittedParam> params;
  bool significant = false;  //!< its size exceeds options.significance sigma
  std::vector<std::pair<double, double>> declared;  //!< free declared values, sigmas (joint fit)
  std::vector<int> free;  //!< the declared slots `declared` refers to (empty: the round's free ones)
  int refreed = 0;        //!< declared parameters the refit held that this fit frees (BIC's k)
  double seconds = 0;
};

servo::EffectSettings settings(std::string type, std::vector<std::pair<std::string, double>> v) {
  servo::EffectSettings e;
  e.type = std::move(type);
  e.values = std::move(v);
  return e;
}

const char* lin(bool rotary) { return rotary ? "deg" : "mm"; }

/// An effect acting on the position chain: fitted on the current prediction with the analytic
/// derivatives of apply_output_effect.
Trial fit_output(const Ctx& c, const servo::DriveParams& cur, const std::vector<double>& y0, double tau,
                 const std::string& type, const std::vector<std::string>& names, const Eigen::VectorXd& x0) {
  const std::size_t b = c.s.begin, e = c.s.split;
  auto make = [&](const Eigen::VectorXd& x) {
    std::vector<std::pair<std::string, double>> v;
    for (std::size_t i = 0; i < names.size(); ++i) v.emplace_back(names[i], x[static_cast<Eigen::Index>(i)]);
    return settings(type, v);
  };
  ResidualFn r = [&](const Eigen::VectorXd& x, Eigen::MatrixXd* jac) {
    std::vector<double> y(y0.begin(), y0.begin() + static_cast<std::ptrdiff_t>(e));
    std::vector<std::vector<double>> d;
    apply_output_effect(make(x), c.s.period, y, jac ? &d : nullptr);
    if (jac) {
      jac->resize(static_cast<Eigen::Index>(e - b), x.size());
      for (Eigen::Index i = 0; i < x.size(); ++i)
        for (std::size_t k = b; k < e; ++k) (*jac)(static_cast<Eigen::Index>(k - b), i) = -d[static_cast<std::size_t>(i)][k];
    }
    return c.residual(y, b, e);
  };
  const LsqResult f = least_squares(r, x0, Eigen::VectorXd::Constant(x0.size(), 1e-7), true, tau);
  Trial t;
  t.effect = type;
  t.model = cur;
  t.model.effects.push_back(make(f.x));
  for (std::size_t i = 0; i < names.size(); ++i)
    t.params.push_back({names[i], "", f.x[static_cast<Eigen::Index>(i)], f.sigma[static_cast<Eigen::Index>(i)]});
  t.significant = std::abs(f.x[0]) > c.o.significance * f.sigma[0];
  return t;
}

/// Best value of a scalar on a grid by the fit SSE of the output effect (start of the LM).
double grid_start(const Ctx& c, const std::vector<double>& y0, const std::string& type, const std::string& name,
                  const std::vector<double>& grid) {
  double best = grid.front(), best_sse = std::numeric_limits<double>::infinity();
  for (double g : grid) {
    std::vector<double> y(y0.begin(), y0.begin() + static_cast<std::ptrdiff_t>(c.s.split));
    apply_output_effect(settings(type, {{name, g}}), c.s.period, y);
    const double s = c.fit_sse(y);
    if (s < best_sse) { best_sse = s; best = g; }
  }
  return best;
}

std::vector<double> geometric(double lo, double hi, int n) {
  std::vector<double> g;
  for (int i = 0; i < n; ++i) g.push_back(lo * std::pow(hi / lo, i / double(n - 1)));
  return g;
}

Trial fit_backlash(const Ctx& c, const servo::DriveParams& cur, const std::vector<double>& y0, double tau) {
  const bool rot = cur.rotary;
  const double w0 = grid_start(c, y0, "backlash", "width", geometric(rot ? 2e-4 : 2e-4, rot ? 0.2 : 0.2, 40));
  Trial t = fit_output(c, cur, y0, tau, "backlash", {"width"}, Eigen::VectorXd::Constant(1, w0));
  t.params[0].unit = lin(rot);
  return t;
}

/// A constant offset between the logged actual and the model (a misplaced reference mark or an
/// encoder offset): not in the list, but without it such an offset would be pushed onto
/// scale_error or a gain. Linear; LM from the mean residual.
Trial fit_offset(const Ctx& c, const servo::DriveParams& cur, const std::vector<double>& y0, double tau) {
  const Eigen::VectorXd r = c.residual(y0, c.s.begin, c.s.split);
  Trial t = fit_output(c, cur, y0, tau, "offset", {"value"}, Eigen::VectorXd::Constant(1, r.mean()));
  t.params[0].unit = lin(cur.rotary);
  return t;
}

Trial fit_scale(const Ctx& c, const servo::DriveParams& cur, const std::vector<double>& y0, double tau) {
  Trial t = fit_output(c, cur, y0, tau, "scale_error", {"ppm"}, Eigen::VectorXd::Zero(1));
  t.params[0].unit = "ppm";
  return t;
}

Trial fit_measurement_delay(const Ctx& c, const servo::DriveParams& cur, const std::vector<double>& y0, double tau) {
  std::vector<double> grid;
  for (double d = 0.25e-3; d <= 0.02 + 1e-12; d += 0.25e-3) grid.push_back(d);
  const double d0 = grid_start(c, y0, "measurement_delay", "delay", grid);
  Trial t = fit_output(c, cur, y0, tau, "measurement_delay", {"delay"}, Eigen::VectorXd::Constant(1, d0));
  t.params[0].unit = "s";
  return t;
}

/// Lead error: for each pitch of a grid the amplitude and phase are linear (a sin, a cos), so
/// the start is the pitch with the best linear fit; LM then refines all three.
Trial fit_lead(const Ctx& c, const servo::DriveParams& cur, const std::vector<double>& y0, double tau) {
  const std::size_t b = c.s.begin, e = c.s.split;
  const auto [lo, hi] = std::minmax_element(y0.begin() + static_cast<std::ptrdiff_t>(b), y0.begin() + static_cast<std::ptrdiff_t>(e));
  const double range = *hi - *lo;
  const double pmax = std::min(cur.rotary ? 360.0 : 100.0, range / 1.5);
  const double pmin = cur.rotary ? 0.5 : 0.5;
  double best_sse = std::numeric_limits<double>::infinity();
  Eigen::Vector3d x0(0, pmax, 0);
  const Eigen::VectorXd r = c.residual(y0, b, e);
  for (double p : geometric(pmin, std::max(pmax, pmin * 1.01), 300)) {
    Eigen::MatrixXd A(r.size(), 2);
    for (std::size_t k = b; k < e; ++k) {
      const double arg = 2 * M_PI * y0[k] / p;
      A(static_cast<Eigen::Index>(k - b), 0) = std::sin(arg);
      A(static_cast<Eigen::Index>(k - b), 1) = std::cos(arg);
    }
    const Eigen::Vector2d q = (A.transpose() * A).ldlt().solve(A.transpose() * r);
    const double s = (r - A * q).squaredNorm();
    if (s < best_sse) { best_sse = s; x0 = {std::hypot(q[0], q[1]), p, std::atan2(q[1], q[0]) * 180 / M_PI}; }
  }
  Trial t = fit_output(c, cur, y0, tau, "lead_error", {"amplitude", "period", "phase"}, x0);
  t.params[0].unit = lin(cur.rotary);
  t.params[1].unit = lin(cur.rotary);
  t.params[2].unit = "deg";
  // One sign and phase convention for the report: amplitude >= 0, phase in (-180, 180].
  auto& ef = t.model.effects.back();
  double a = ef.values[0].second, ph = ef.values[2].second;
  if (a < 0) { a = -a; ph += 180; }
  ph = std::remainder(ph, 360.0);
  ef.values[0].second = a; ef.values[2].second = ph;
  t.params[0].value = a; t.params[2].value = ph;
  return t;
}

}  // namespace
}  // namespace gcpipe::calibrate

namespace gcpipe::calibrate {
namespace {

/// Coulomb friction T tanh(w/band) with the registry's band (0.01 rad/s: a sign function at
/// feed speeds; the band is not identifiable from positions at 1 ms). The start comes from the
/// linear sensitivity of the prediction to a small torque; LM (central differences through a
/// new simulation each) refines it.
Trial fit_friction(const Ctx& c, const servo::DriveParams& cur, const std::vector<double>& y0, double tau) {
  const std::size_t b = c.s.begin, e = c.dynamic_end();
  auto with = [&](double T) {
    servo::DriveParams p = cur;
    p.effects.insert(p.effects.begin(), settings("coulomb_friction", {{"torque", std::max(T, 0.0)}, {"velocity_band", 0.01}}));
    return p;
  };
  // Torque giving a 1 um (1e-3 deg) steady lag: T / (Kvp Kpp) * load_per_rad = 1e-3.
  const double T0 = 1e-3 * cur.Kvp * cur.Kpp / cur.load_per_motor_rad();
  const Eigen::VectorXd s = (c.residual(y0, b, e) - c.residual(c.predict(with(T0), e), b, e)) / T0;
  const double Tinit = std::max(s.dot(c.residual(y0, b, e)) / std::max(s.squaredNorm(), 1e-300), 0.0);
  ResidualFn r = [&](const Eigen::VectorXd& x, Eigen::MatrixXd*) { return c.residual(c.predict(with(x[0]), e), b, e); };
  const LsqResult f = least_squares(r, Eigen::VectorXd::Constant(1, Tinit), Eigen::VectorXd::Constant(1, 0.02 * std::max(Tinit, T0)), false, tau);
  Trial t;
  t.effect = "coulomb_friction";
  t.model = with(f.x[0]);
  t.params = {{"torque", "N*m", std::max(f.x[0], 0.0), f.sigma[0]}, {"velocity_band", "rad/s", 0.01, 0}};
  t.significant = f.x[0] > c.o.significance * f.sigma[0];
  return t;
}

/// Minimum of a function over integers in [lo, hi] assumed unimodal near the coarse optimum:
/// a doubling scan, then a ternary search; returns the argmin and the values around it.
template <class F>
int integer_argmin(F&& f, int lo, int hi, std::map<int, double>& cache) {
  auto val = [&](int n) {
    auto it = cache.find(n);
    if (it != cache.end()) return it->second;
    return cache[n] = f(n);
  };
  int best = lo;
  for (int n = lo; n <= hi; n *= 2)
    if (val(n) < val(best)) best = n;
  int a = std::max(lo, best / 2), z = std::min(hi, best * 2);
  while (z - a > 2) {
    const int m1 = a + (z - a) / 3, m2 = z - (z - a) / 3;
    if (val(m1) <= val(m2)) z = m2; else a = m1;
  }
  for (int n = a; n <= z; ++n)
    if (val(n) < val(best)) best = n;
  return best;
}

/// A parabola through (n-1, n, n+1) of a SSE curve: the fractional minimum and its sigma
/// (SSE ~ SSE_min + (x - x0)^2 J'J, cov = tau s^2 / J'J).
std::pair<double, double> parabola(const std::map<int, double>& v, int n, double s2tau) {
  if (!v.count(n - 1) || !v.count(n + 1)) return {double(n), 0.5};
  const double a = v.at(n - 1), b = v.at(n), d = v.at(n + 1);
  const double curv = a - 2 * b + d;  // second difference = 2 J'J
  if (!(curv > 0)) return {double(n), 0.5};
  return {n + 0.5 * (a - d) / curv, std::sqrt(s2tau / (curv / 2))};
}


/// Torque limit: golden-section search on the limit as a fraction of the model's peak torque
/// (a limit above the peak changes nothing, so only 0.2 ... 1 of it is searched).
Trial fit_torque_limit(const Ctx& c, const servo::DriveParams& cur, double tau) {
  const std::size_t b = c.s.begin, e = c.dynamic_end();
  std::vector<double> tq;
  simulate_motor(cur, c.s.substeps, c.s.margin, c.s.period, std::span<const double>(c.s.command.data(), std::min(c.n(), e + 64)), &tq);
  double peak = 0;
  for (double v : tq) peak = std::max(peak, std::abs(v));
  auto with = [&](double L) { servo::DriveParams p = cur; p.torque_limit = L; return p; };
  auto f = [&](double q) { return c.sse(c.predict(with(q * peak), e), b, e); };
  double lo = 0.2, hi = 1.0;
  const double g = (std::sqrt(5.0) - 1) / 2;
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo), f1 = f(x1), f2 = f(x2);
  for (int i = 0; i < 18; ++i) {
    if (f1 <= f2) { hi = x2; x2 = x1; f2 = f1; x1 = hi - g * (hi - lo); f1 = f(x1); }
    else { lo = x1; x1 = x2; f1 = f2; x2 = lo + g * (hi - lo); f2 = f(x2); }
  }
  const double q = 0.5 * (lo + hi), dq = 0.01;
  const double fa = f(q - dq), fb = f(q), fc = f(q + dq);
  const double curv = (fa - 2 * fb + fc) / (dq * dq);
  const double sig = curv > 0 ? std::sqrt(fb / static_cast<double>(e - b) * tau / (curv / 2)) * peak : peak;
  Trial t;
  t.effect = "torque_limit";
  t.model = with(q * peak);
  t.params = {{"torque_limit", "N*m", q * peak, sig}};
  t.significant = q < 0.98 && (1 - q) * peak > c.o.significance * sig;
  return t;
}

}  // namespace
}  // namespace gcpipe::calibrate

namespace gcpipe::calibrate {
namespace {

/// Which continuous numbers of a trial's effect the joint fit moves (feedback_delay is held on
/// its sub-step grid; the friction band is fixed).
std::vector<std::string> continuous_keys(const std::string& effect) {
  if (effect == "backlash") return {"width"};
  if (effect == "lead_error") return {"amplitude", "period", "phase"};
  if (effect == "scale_error") return {"ppm"};
  if (effect == "offset") return {"value"};
  if (effect == "measurement_delay" || effect == "feedback_delay") return effect == "feedback_delay" ? std::vector<std::string>{} : std::vector<std::string>{"delay"};
  if (effect == "coulomb_friction") return {"torque"};
  if (effect == "torque_limit") return {"torque_limit"};
  return {};
}

double* effect_value(servo::DriveParams& p, const std::string& effect, const std::string& key) {
  if (effect == "torque_limit") return &p.torque_limit;
  for (auto& e : p.effects)
    if (e.type == effect)
      for (auto& [k, v] : e.values)
        if (k == key) return &v;
  return nullptr;
}

/// One continuous number of a model's effect: (effect type, key).
using Ref = std::pair<std::string, std::string>;

/// Joint LM over the free declared parameters and the given effect numbers of `model`; returns
/// the fit (x = declared values then effect values) and updates `model`; nullopt when LM found
/// nothing better than the start.
std::optional<LsqResult> joint_fit(const Ctx& c, servo::DriveParams& model, const std::vector<int>& free,
                                   const std::vector<Ref>& refs, bool dynamic, double tau,
                                   int max_evaluations = 200, std::size_t end = 0) {
  const auto& slots = declared_slots();
  const std::size_t nd = free.size(), n = nd + refs.size();
  if (n == 0) return std::nullopt;
  const std::size_t b = c.s.begin, e = end > 0 ? end : dynamic ? c.dynamic_end() : c.s.split;
  Eigen::VectorXd x0(static_cast<Eigen::Index>(n)), step(static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < nd; ++i) x0[static_cast<Eigen::Index>(i)] = model.*(slots[static_cast<std::size_t>(free[i])].field);
  for (std::size_t i = 0; i < refs.size(); ++i) x0[static_cast<Eigen::Index>(nd + i)] = *effect_value(model, refs[i].first, refs[i].second);
  for (Eigen::Index i = 0; i < x0.size(); ++i) step[i] = 1e-4 * std::max(std::abs(x0[i]), 1e-3);
  auto build = [&](const Eigen::VectorXd& x) {
    servo::DriveParams p = model;
    for (std::size_t i = 0; i < nd; ++i) p.*(slots[static_cast<std::size_t>(free[i])].field) = std::max(x[static_cast<Eigen::Index>(i)], 1e-9);
    keep_in_range(p, c.s.period, c.config.K_FFP);
    for (std::size_t i = 0; i < refs.size(); ++i) *effect_value(p, refs[i].first, refs[i].second) = x[static_cast<Eigen::Index>(nd + i)];
    return p;
  };
  ResidualFn r = [&](const Eigen::VectorXd& x, Eigen::MatrixXd*) { return c.residual(c.predict(build(x), e), b, e); };
  LsqResult f = least_squares(r, x0, step, false, tau, max_evaluations);
  if (!(f.sse < r(x0, nullptr).squaredNorm())) return std::nullopt;
  model = build(f.x);
  return f;
}

/// Coulomb friction jointly with the declared parameters through its sensitivity: with the
/// velocity signs fixed, the loop is linear, so y(T) = y(0) + T S with S = (y(T1) - y(0)) / T1
/// from two simulations. LM then runs on the exact (fast) path of the declared parameters plus
/// T S, and S is taken again at the result (twice): a few RK4 runs instead of hundreds.
std::optional<LsqResult> friction_polish(const Ctx& c, Trial& t, const std::vector<int>& free, double tau) {
  const auto& slots = declared_slots();
  const std::size_t nd = free.size(), b = c.s.begin, e = c.dynamic_end();
  std::optional<LsqResult> out;
  for (int pass = 0; pass < 2; ++pass) {
    double* Tp = effect_value(t.model, "coulomb_friction", "torque");
    const double T1 = std::max(*Tp, 1e-3 * t.model.Kvp * t.model.Kpp / t.model.load_per_motor_rad());
    servo::DriveParams bare = t.model, one = t.model;
    std::erase_if(bare.effects, [](const auto& ef) { return ef.type == "coulomb_friction"; });
    *effect_value(one, "coulomb_friction", "torque") = T1;
    const std::vector<double> y0 = c.predict(bare, e), y1 = c.predict(one, e);
    Eigen::VectorXd S(static_cast<Eigen::Index>(e - b));
    for (std::size_t k = b; k < e; ++k) S[static_cast<Eigen::Index>(k - b)] = (y1[k] - y0[k]) / T1;
    Eigen::VectorXd x0(static_cast<Eigen::Index>(nd + 1)), step(static_cast<Eigen::Index>(nd + 1));
    for (std::size_t i = 0; i < nd; ++i) x0[static_cast<Eigen::Index>(i)] = bare.*(slots[static_cast<std::size_t>(free[i])].field);
    x0[static_cast<Eigen::Index>(nd)] = *Tp;
    for (Eigen::Index i = 0; i < x0.size(); ++i) step[i] = 1e-4 * std::max(std::abs(x0[i]), 1e-3);
    auto declared_model = [&](const Eigen::VectorXd& x) {
      servo::DriveParams p = bare;
      for (std::size_t i = 0; i < nd; ++i) p.*(slots[static_cast<std::size_t>(free[i])].field) = std::max(x[static_cast<Eigen::Index>(i)], 1e-9);
      keep_in_range(p, c.s.period, c.config.K_FFP);
      return p;
    };
    ResidualFn r = [&](const Eigen::VectorXd& x, Eigen::MatrixXd*) {
      return Eigen::VectorXd(c.residual(c.predict(declared_model(x), e), b, e) - x[static_cast<Eigen::Index>(nd)] * S);
    };
    LsqResult f = least_squares(r, x0, step, false, tau);
    servo::DriveParams next = t.model;
    for (std::size_t i = 0; i < nd; ++i) next.*(slots[static_cast<std::size_t>(free[i])].field) = std::max(f.x[static_cast<Eigen::Index>(i)], 1e-9);
    keep_in_range(next, c.s.period, c.config.K_FFP);
    *effect_value(next, "coulomb_friction", "torque") = std::max(f.x[static_cast<Eigen::Index>(nd)], 0.0);
    if (!(c.sse(c.predict(next, e), b, e) < c.sse(c.predict(t.model, e), b, e))) break;
    t.model = next;
    out = f;
  }
  return out;
}

std::pair<double, double> parabola(const std::map<int, double>& v, int n, double s2tau);

/// Feedback delay: a profile over whole sub-steps (the simulator's resolution). At each delay of
/// a coarse grid the declared gains are refitted with it (a delay inside the loop and a lower
/// Kpp or more averaging look alike at low frequency, so a delay scored on fixed gains is
/// biased); the best grid point is refined by a scan of its neighbours with those gains and a
/// parabola gives the fractional value and its sigma.
Trial fit_feedback_delay(const Ctx& c, const servo::DriveParams& base, double tau, const std::vector<int>& free) {
  const std::size_t b = c.s.begin, e = std::min(c.dynamic_end(), c.s.begin + 10000);
  const double h = c.s.period / c.s.substeps;
  auto with = [&](const servo::DriveParams& from, int n) {
    servo::DriveParams p = from;
    std::erase_if(p.effects, [](const auto& ef) { return ef.type == "feedback_delay"; });
    p.effects.insert(p.effects.begin(), settings("feedback_delay", {{"delay", n * h}}));
    return p;
  };
  // The profile P(n) = min over the free gains of the SSE at a delay of n sub-steps, each point
  // a short LM from the configured gains; cached.
  struct Point { double sse; servo::DriveParams model; std::optional<LsqResult> fit; };
  std::map<int, Point> prof;
  auto P = [&](int n) -> const Point& {
    auto it = prof.find(n);
    if (it != prof.end()) return it->second;
    servo::DriveParams m = with(base, n);
    auto f = joint_fit(c, m, free, {}, true, tau, 8, e);
    const double sse = c.sse(c.predict(m, e), b, e);
    return prof.emplace(n, Point{sse, m, f}).first->second;
  };
  const int per_ms = static_cast<int>(std::lround(1e-3 / h));
  const int grid[] = {per_ms / 2, per_ms, 2 * per_ms, 4 * per_ms, 8 * per_ms};
  int gi = 0;
  for (int i = 1; i < 5; ++i)
    if (P(std::max(1, grid[i])).sse < P(std::max(1, grid[gi])).sse) gi = i;
  // Golden-section search on whole sub-steps between the grid neighbours of the best point.
  int lo = std::max(1, gi > 0 ? grid[gi - 1] : 1), hi = gi < 4 ? grid[gi + 1] : grid[4];
  while (hi - lo > 2) {
    const int m1 = lo + static_cast<int>(std::lround(0.382 * (hi - lo))), m2 = lo + static_cast<int>(std::lround(0.618 * (hi - lo)));
    if (m1 == m2) break;
    if (P(m1).sse <= P(m2).sse) hi = m2; else lo = m1;
  }
  int best = lo;
  for (int n = lo; n <= hi; ++n)
    if (P(n).sse < P(best).sse) best = n;
  std::map<int, double> v;
  for (int n = std::max(1, best - 1); n <= best + 1; ++n) v[n] = P(n).sse;
  const auto [frac, sig] = parabola(v, best, v[best] / static_cast<double>(e - b) * tau);
  const Point& pt = P(best);
  Trial t;
  t.effect = "feedback_delay";
  t.model = pt.model;  // the simulator holds whole sub-steps
  t.params = {{"delay", "s", frac * h, sig * h}};
  t.significant = frac * h > c.o.significance * sig * h;
  if (pt.fit)
    for (std::size_t i = 0; i < free.size(); ++i) t.declared.emplace_back(pt.fit->x[static_cast<Eigen::Index>(i)], pt.fit->sigma[static_cast<Eigen::Index>(i)]);
  return t;
}

void take_joint_fit(const Ctx& c, Trial& t, const std::vector<int>& free, const std::vector<Ref>& refs, const LsqResult& fit);

/// Torque limit jointly with the gains, then, when the limit is significant, also with the
/// declared parameters the refit held as not separable (`refree`): the refit was done without
/// the limit, and on saturated stretches the loop's gains do not act, so it bent some of them
/// (Ta and C to nothing on the trochoid) and then held them; with the limit in the model they
/// may be well determined. Each stays free only when this fit pins it down by the refit's own
/// rule (noise-limited relative sigma <= 25 %, not bent below 5 % of its start), the worst
/// dropped one at a time. (Only for a significant limit: on an axis without one the extra
/// re-simulated fits would cost the time of a whole round on long traces.)
void torque_limit_polish(const Ctx& c, Trial& t, const std::vector<int>& free, std::vector<int> refree,
                         const std::vector<Ref>& refs, double tau) {
  const auto& slots = declared_slots();
  if (auto f = joint_fit(c, t.model, free, refs, true, tau)) take_joint_fit(c, t, free, refs, *f);
  if (refree.empty() || !t.significant) return;
  const servo::DriveParams start = t.model;
  const std::size_t e = c.dynamic_end();
  const double noise = std::max(c.s.noise, 1e-9), sse0 = c.sse(c.predict(start, e), c.s.begin, e);
  while (!refree.empty()) {
    std::vector<int> all = free;
    all.insert(all.end(), refree.begin(), refree.end());
    servo::DriveParams m = start;
    const auto f = joint_fit(c, m, all, refs, true, tau);
    if (!f || !(c.sse(c.predict(m, e), c.s.begin, e) < sse0)) return;  // nothing better with them free
    int worst = -1;
    double worst_rel = 0.25;
    for (std::size_t i = free.size(); i < all.size(); ++i) {
      const auto ii = static_cast<Eigen::Index>(i);
      const double x = f->x[ii], x0 = start.*(slots[static_cast<std::size_t>(all[i])].field);
      const double rel = noise * std::sqrt(std::max(f->jtj_inv(ii, ii), 0.0)) / std::max(x, 1e-12);
      if (!(x > 0.05 * x0) || !std::isfinite(rel) || rel > worst_rel) { worst = static_cast<int>(i - free.size()); worst_rel = std::isfinite(rel) ? std::max(rel, worst_rel) : 1e300; }
    }
    if (worst >= 0) { refree.erase(refree.begin() + worst); continue; }
    t.model = m;
    t.refreed = static_cast<int>(refree.size());
    return take_joint_fit(c, t, all, refs, *f);
  }
}

/// After a joint fit: a declared slot the fit cannot pin down any more (the identified drive had
/// used it to mimic the effect: Kvi 1600 +- 62000 beside a scale error) makes the covariance of
/// everything, the effect's size included, meaningless. Such a slot is held at its configured
/// value when that costs at most 9 noise variances (3 sigma), the rest refitted, the worst first.
void prune_loose_declared(const Ctx& c, Trial& t, const std::vector<Ref>& refs, double tau) {
  const auto& slots = declared_slots();
  const double noise2 = std::max(c.s.noise * c.s.noise, 1e-18);
  for (int pass = 0; pass < 3 && !t.free.empty(); ++pass) {
    int worst = -1;
    double worst_rel = 0.25;
    for (std::size_t i = 0; i < t.free.size() && i < t.declared.size(); ++i) {
      const double v = t.declared[i].first, sg = t.declared[i].second;
      const double rel = std::isfinite(sg) ? sg / std::max(std::abs(v), 1e-12) : 1e300;
      if (rel > worst_rel) { worst_rel = rel; worst = static_cast<int>(i); }
    }
    if (worst < 0) return;
    std::vector<int> fewer = t.free;
    const int slot = fewer[static_cast<std::size_t>(worst)];
    fewer.erase(fewer.begin() + worst);
    servo::DriveParams m = t.model;
    m.*(slots[static_cast<std::size_t>(slot)].field) = c.config.*(slots[static_cast<std::size_t>(slot)].field);
    const auto f = joint_fit(c, m, fewer, refs, true, tau);
    const double sse_now = c.fit_sse(c.predict(t.model, c.s.split)), sse_held = c.fit_sse(c.predict(m, c.s.split));
    if (!f || (sse_held - sse_now) / (noise2 * tau) > 9) return;
    t.model = m;
    take_joint_fit(c, t, fewer, refs, *f);
  }
}

/// Friction jointly with the gains from two starts: the identified drive, and the same with its
/// integral action and damping at their configured values. Identified without the catalogue, a
/// drive bends its integral action to hold the axis against a friction it does not know (a
/// corner near the position loop: measured Kvi 6600 against 0.2 on a trochoid with 36 N*m), and
/// a joint fit from there stays in that valley; from the second start it finds the friction.
void friction_from_two_starts(const Ctx& c, Trial& t, const std::vector<int>& free, const std::vector<Ref>& refs, double tau) {
  Trial other = t;
  other.model.Kvi = c.config.Kvi;
  other.model.C = c.config.C;
  const auto fa = friction_polish(c, t, free, tau);
  const auto fb = friction_polish(c, other, free, tau);
  const std::size_t e = c.dynamic_end();
  const bool second = fb && c.sse(c.predict(other.model, e), c.s.begin, e) < c.sse(c.predict(t.model, e), c.s.begin, e);
  if (second) {
    t = std::move(other);
    take_joint_fit(c, t, free, refs, *fb);
  } else if (fa) {
    take_joint_fit(c, t, free, refs, *fa);
  }
}

/// Joint LM over the free declared parameters and the trial effect's continuous numbers, from
/// the trial's own fit: an effect fitted on a model whose gains were refitted without it is
/// biased (the gains absorb part of it), so the two are refitted together before scoring.
/// Output effects need only the drive's exact path per evaluation; friction goes through its
/// sensitivity; feedback_delay is profiled with the gains; torque_limit may free more (below).
void joint_polish(const Ctx& c, Trial& t, const std::vector<int>& free, const std::vector<int>& refree, double tau) {
  std::vector<Ref> refs;
  for (const auto& k : continuous_keys(t.effect)) refs.emplace_back(t.effect, k);
  if (t.effect == "feedback_delay") return;  // profiled with the gains in fit_feedback_delay
  if (t.effect == "torque_limit") return torque_limit_polish(c, t, free, refree, refs, tau);
  if (t.effect == "coulomb_friction") return friction_from_two_starts(c, t, free, refs, tau);
  // Two starts here too: the identified drive (which may have bent to mimic the effect: a scale
  // error on a trochoid is matched to the noise by more feed-forward and damping) and the
  // configured gains with the effect's own fit.
  // The second start only when the first stops short of the noise: it doubles the cost of the
  // output effects, the bulk of a long trace's time.
  Trial other = t;
  for (int slot : free) other.model.*(declared_slots()[static_cast<std::size_t>(slot)].field) = c.config.*(declared_slots()[static_cast<std::size_t>(slot)].field);
  // On the fit window (<= max_dynamic_fit samples), as the re-simulated effects: with the gains
  // free every evaluation is a new simulation, and on the 10-minute benchmark the whole fit part
  // (420 000 samples) tripled the calibration's CPU time (187 s against the 60 s it must keep).
  const auto fa = joint_fit(c, t.model, free, refs, true, tau);
  const double fit_mse = c.fit_sse(c.predict(t.model, c.s.split)) / static_cast<double>(c.nfit());
  const bool at_noise = fit_mse <= 1.5 * c.s.noise * c.s.noise;
  const auto fb = at_noise ? std::optional<LsqResult>{} : joint_fit(c, other.model, free, refs, true, tau);
  const bool second = fb && c.fit_sse(c.predict(other.model, c.s.split)) < c.fit_sse(c.predict(t.model, c.s.split));
  if (second) {
    t = std::move(other);
    take_joint_fit(c, t, free, refs, *fb);
  } else if (fa) {
    take_joint_fit(c, t, free, refs, *fa);
  } else {
    return;
  }
  prune_loose_declared(c, t, refs, tau);
}

/// The trial's declared values, effect numbers and significance from a joint fit over `free`.
void take_joint_fit(const Ctx& c, Trial& t, const std::vector<int>& free, const std::vector<Ref>& refs, const LsqResult& fit) {
  t.free = free;
  const std::size_t nd = free.size();
  t.declared.clear();
  for (std::size_t i = 0; i < nd; ++i) t.declared.emplace_back(fit.x[static_cast<Eigen::Index>(i)], fit.sigma[static_cast<Eigen::Index>(i)]);
  for (std::size_t i = 0; i < refs.size(); ++i)
    for (auto& p : t.params)
      if (p.name == refs[i].second) { p.value = fit.x[static_cast<Eigen::Index>(nd + i)]; p.sigma = fit.sigma[static_cast<Eigen::Index>(nd + i)]; }
  const auto& size = t.params.front();
  if (t.effect == "torque_limit") {
    // Significant when the limit lies clearly below the torque the model asks for without it.
    std::vector<double> tq;
    servo::DriveParams free_model = t.model;
    free_model.torque_limit = 0;
    simulate_motor(free_model, c.s.substeps, c.s.margin, c.s.period, std::span<const double>(c.s.command.data(), c.s.split), &tq);
    double peak = 0;
    for (double v : tq) peak = std::max(peak, std::abs(v));
    t.significant = peak - size.value > c.o.significance * size.sigma && size.value < 0.98 * peak;
  } else {
    t.significant = std::abs(size.value) > c.o.significance * size.sigma;
  }
}

int parameter_count(const Trial& t) {
  int k = 0;
  for (const auto& p : t.params) k += p.sigma > 0 || p.name != "velocity_band";
  return k + t.refreed;
}

/// Fits every catalogue effect not yet named on the axis, on the current model.
std::vector<Trial> fit_catalogue(const Ctx& c, const servo::DriveParams& cur, const std::vector<double>& y0,
                                 double tau, const std::vector<std::string>& named, const servo::DriveParams& config,
                                 const std::vector<int>& free) {
  // Re-simulated effects start from the configured gains, not the refitted ones: the refit, done
  // without the effect, may have bent the gains to mimic it (a delay looks like a lower Kpp, a
  // torque limit like less feed-forward); the joint polish then refits the gains with the effect.
  servo::DriveParams base = cur;
  for (const auto& slot : declared_slots()) base.*(slot.field) = config.*(slot.field);
  const std::vector<double> ybase = c.predict(base, c.n());
  // At a sampling period that cannot show a drive's loop (UMich: 100 ms) only the slow effects
  // are tried; the others are not visible there (and their fits only diverge).
  const bool drive = cur.model == servo::DriveModel::kDrive && c.s.period <= kLoopVisiblePeriod;
  const bool fast = c.s.period <= kLoopVisiblePeriod;
  auto open = [&](const char* e) {
    const std::string name = e;
    const bool slow_effect = name == "lead_error" || name == "scale_error" || name == "offset";
    return (fast || slow_effect) && std::find(named.begin(), named.end(), e) == named.end();
  };
  std::vector<Trial> out;
  std::vector<double> secs;
  auto clock = std::chrono::steady_clock::now();
  auto lap = [&] { const auto now = std::chrono::steady_clock::now(); secs.push_back(std::chrono::duration<double>(now - clock).count()); clock = now; };
  if (open("backlash")) { out.push_back(fit_backlash(c, cur, y0, tau)); lap(); out.back().seconds = secs.back(); }
  if (open("lead_error")) { out.push_back(fit_lead(c, cur, y0, tau)); lap(); out.back().seconds = secs.back(); }
  if (open("scale_error")) { out.push_back(fit_scale(c, cur, y0, tau)); lap(); out.back().seconds = secs.back(); }
  if (open("offset")) { out.push_back(fit_offset(c, cur, y0, tau)); lap(); out.back().seconds = secs.back(); }
  if (open("measurement_delay")) { out.push_back(fit_measurement_delay(c, cur, y0, tau)); lap(); out.back().seconds = secs.back(); }
  if (drive && open("coulomb_friction")) { out.push_back(fit_friction(c, cur, y0, tau)); lap(); out.back().seconds = secs.back(); }
  if (drive && open("feedback_delay")) { out.push_back(fit_feedback_delay(c, base, tau, free)); lap(); out.back().seconds = secs.back(); }
  if (drive && open("torque_limit") && cur.Kvp > 0) {
    // From the configured gains (unbiased by the refit) and from the refitted ones (which may
    // have bent to mimic part of the limit, but start much closer when the configuration is
    // off): the better start goes on, since only the best re-simulated trial gets polished.
    Trial from_base = fit_torque_limit(c, base, tau), from_refit = fit_torque_limit(c, cur, tau);
    const std::size_t e = c.dynamic_end();
    const bool refit_better = c.sse(c.predict(from_refit.model, e), c.s.begin, e) < c.sse(c.predict(from_base.model, e), c.s.begin, e);
    out.push_back(refit_better ? std::move(from_refit) : std::move(from_base));
    lap();
    out.back().seconds = secs.back();
  }
  return out;
}

/// After an effect is named: every named effect's numbers and the free declared parameters
/// refitted together (an effect fitted before the next one was known carries part of it), and
/// their sigmas taken from this fit with the correlation time of its own residual.
void repolish(const Ctx& c, AxisIdentification& id, const std::vector<int>& free) {
  std::vector<Ref> refs;
  bool dynamic = false;
  for (const auto& n : id.named) {
    for (const auto& k : continuous_keys(n.effect)) refs.emplace_back(n.effect, k);
    dynamic = dynamic || is_dynamic_effect(n.effect) || n.effect == "torque_limit";
  }
  if (id.named.size() < 2) return;  // the single effect was just fitted jointly
  servo::DriveParams m = id.calibrated;
  const double tau_old = c.tau(id.pred_calibrated);
  const auto f = joint_fit(c, m, free, refs, dynamic, tau_old, dynamic ? 40 : 200);
  if (!f) return;
  const std::vector<double> y = c.predict(m, c.n());
  if (!(c.fit_sse(y) < c.fit_sse(id.pred_calibrated))) return;
  id.calibrated = m;
  id.pred_calibrated = y;
  // Sigmas with the new residual's correlation time (the fit was weighted with the old one).
  const double scale = std::sqrt(c.tau(y) / tau_old);
  for (std::size_t i = 0; i < free.size(); ++i) {
    id.declared[static_cast<std::size_t>(free[i])].fitted = m.*(declared_slots()[static_cast<std::size_t>(free[i])].field);
    id.declared[static_cast<std::size_t>(free[i])].sigma = scale * f->sigma[static_cast<Eigen::Index>(i)];
  }
  for (std::size_t i = 0; i < refs.size(); ++i)
    for (auto& n : id.named)
      if (n.effect == refs[i].first)
        for (auto& p : n.params)
          if (p.name == refs[i].second) { p.value = f->x[static_cast<Eigen::Index>(free.size() + i)]; p.sigma = scale * f->sigma[static_cast<Eigen::Index>(free.size() + i)]; }
}

bool resimulated(const std::string& effect) { return is_dynamic_effect(effect) || effect == "torque_limit"; }

/// Joint polish: every output effect (cheap: the drive's exact path per evaluation) and the
/// re-simulated effect that explains most on its own (a few RK4 runs per parameter).
void polish_trials(const Ctx& c, std::vector<Trial>& trials, const std::vector<int>& free, const std::vector<int>& refree, double tau) {
  std::vector<std::pair<double, std::size_t>> order;
  for (std::size_t i = 0; i < trials.size(); ++i) {
    const std::size_t e = resimulated(trials[i].effect) ? c.dynamic_end() : c.s.split;
    order.emplace_back(c.sse(c.predict(trials[i].model, c.s.split), c.s.begin, e) / static_cast<double>(e - c.s.begin), i);
  }
  std::sort(order.begin(), order.end());
  bool dynamic_done = false;
  for (const auto& [mse, i] : order) {
    const bool dyn = resimulated(trials[i].effect);
    if (dyn && dynamic_done) continue;
    dynamic_done = dynamic_done || dyn;
    const auto t0 = std::chrono::steady_clock::now();
    joint_polish(c, trials[i], free, refree, tau);
    trials[i].seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
}

/// What a round knows before scoring: the current prediction, its BIC and held-out mean square.
struct RoundStart {
  const std::vector<double>& y0;
  double tau, b0, h0, noise2;
  int k, round;
  bool at_noise = false;  //!< the start's fit mean square is already at the noise
};

/// Why a fitted effect cannot be the machine's: a parameter outside the range the servo registry
/// accepts (a negative width or delay, a log that leads the motion): such a fit only mops up
/// what the model lacks elsewhere. Empty when every parameter is in range.
std::string outside_physical_range(const Trial& t) {
  for (const auto& type : servo::effect_types()) {
    if (t.effect != type.name) continue;
    for (const auto& p : t.params)
      for (const auto& key : type.keys)
        if (p.name == key.name && p.name != "phase" && (p.value < key.min || p.value > key.max))  // a phase wraps
          return p.name + " = " + std::to_string(p.value) + " is outside its physical range [" + std::to_string(key.min) +
                 ", " + std::to_string(key.max) + "]";
  }
  return "";
}

double param_of(const Trial& t, const std::string& name) {
  for (const auto& p : t.params)
    if (p.name == name) return p.value;
  return 0;
}

/// Median speed of the commands over the samples where the axis moves [mm/s or deg/s].
double typical_speed(const Ctx& c) {
  std::vector<double> v;
  for (std::size_t k = c.s.begin + 1; k < c.s.split; ++k) {
    const double d = std::abs(c.s.command[k] - c.s.command[k - 1]) / c.s.period;
    if (d > 1e-6) v.push_back(d);
  }
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

/// Refits an output effect's numbers alone on [from, to) of the fit part (the drive as in `t`).
Trial refit_on(const Ctx& c, const Trial& t, std::size_t from, std::size_t to) {
  AxisSeries part = c.s;
  part.begin = from;
  part.split = to;
  const Ctx sub{part, c.o, c.config};
  servo::DriveParams bare = t.model;
  std::erase_if(bare.effects, [&](const servo::EffectSettings& e) { return e.type == t.effect; });
  const std::vector<double> y0 = sub.predict(bare, to);
  std::vector<std::string> names;
  Eigen::VectorXd x0(static_cast<Eigen::Index>(t.params.size()));
  for (std::size_t i = 0; i < t.params.size(); ++i) {
    names.push_back(t.params[i].name);
    x0[static_cast<Eigen::Index>(i)] = t.params[i].value;
  }
  const Eigen::VectorXd r = sub.residual(y0, from, to);
  return fit_output(sub, bare, y0, correlation_time(std::span<const double>(r.data(), static_cast<std::size_t>(r.size()))), t.effect, names, x0);
}

/// Rule 2 of issue 29 beyond the criterion: why a candidate that passes the statistics is still
/// not the machine's ("seen, not named: ..."), or "" when it is real. Physical bounds for the
/// machine file (a lead error's period is the screw's lead or a harmonic of it, amplitudes and
/// plays of at most 0.1 mm, delays of 1.5 samples ... 20 ms); not a sampling artefact (a periodic
/// signature must span 10 samples or more at the trace's feed); and, for the errors of the
/// position chain, the same size on both halves of the fit part.
std::string not_a_real_effect(const Ctx& c, const Trial& t) {
  const std::string seen = "seen, not named: ";
  const bool rotary = c.config.rotary;
  if (c.s.period > kLoopVisiblePeriod && t.effect != "scale_error" && t.effect != "offset" && t.effect != "lead_error")
    return seen + "samples every " + std::to_string(c.s.period * 1000) + " ms cannot show " + t.effect +
           " (a drive's loop, reversals and delays act within milliseconds)";
  const char* unit = rotary ? " deg" : " mm";
  if (t.effect == "measurement_delay" || t.effect == "feedback_delay") {
    const double d = param_of(t, "delay");
    if (d < 1.5 * c.s.period)
      return seen + "a delay of " + std::to_string(d * 1000) + " ms is under 1.5 sample periods: not told apart from the drive's own sampling lag";
    // Where the velocity loop is seen only as a lag J/(Kvp + C) (its gain held at the config,
    // base_model.cpp), a velocity gain at half the configured one adds that lag again: a delay
    // within it cannot be told from a mis-declared gain (measured: 1.6 ms named beside a scale
    // error on seed 002's Y, whose configured Kvp is 20 % low).
    const double J = c.config.J + c.config.J1, vel_bw = (c.config.Kvp + c.config.C) / J;
    const double lag = vel_bw > 5 * c.config.Kpp ? 1.0 / vel_bw : 0.0;
    if (d < 1.5 * c.s.period + lag)
      return seen + "a delay of " + std::to_string(d * 1000) + " ms is within 1.5 sample periods plus the velocity loop's lag (" +
             std::to_string(lag * 1000) + " ms, which a velocity gain off by x0.5 adds again): not told apart from a mis-declared gain";
    if (d > (t.effect == "feedback_delay" ? 0.01 : 0.02))
      return seen + "a delay of " + std::to_string(d * 1000) + " ms is beyond what a drive or an encoder channel has (" +
             (t.effect == "feedback_delay" ? "10" : "20") + " ms)";
  }
  if (t.effect == "backlash" && param_of(t, "width") > 0.1) return seen + "a play of " + std::to_string(param_of(t, "width")) + unit + " is beyond 0.1" + unit;
  if (t.effect == "lead_error") {
    const double period = param_of(t, "period"), amp = param_of(t, "amplitude");
    if (amp > 0.05) return seen + "an amplitude of " + std::to_string(amp) + unit + " is beyond 0.05" + unit;
    const double pitch = rotary ? 360.0 : c.config.lead * 1000;
    if (!(pitch > 0)) return seen + "a periodic error of " + std::to_string(period) + " mm, but the axis declares no ball screw (lead 0): not a lead error";
    const double n = pitch / period;
    if (std::abs(n - std::round(n)) > 0.05 * std::max(1.0, std::round(n)) || std::round(n) < 1 || std::round(n) > (rotary ? 360 : 4))
      return seen + "its period " + std::to_string(period) + unit + " is not the declared " + (rotary ? "revolution" : "screw lead") + " (" +
             std::to_string(pitch) + unit + ") or a harmonic of it";
    const double v = typical_speed(c);
    if (v > 0 && period / v < 10 * c.s.period)
      return seen + "its period passes in " + std::to_string(period / v / c.s.period) + " samples at the trace's typical feed: a sampling artefact cannot be ruled out";
  }
  if (t.effect == "backlash" || t.effect == "lead_error" || t.effect == "scale_error" || t.effect == "offset" || t.effect == "measurement_delay") {
    const std::size_t mid = c.s.begin + (c.s.split - c.s.begin) / 2;
    const Trial a = refit_on(c, t, c.s.begin, mid), b = refit_on(c, t, mid, c.s.split);
    const FittedParam &pa = a.params.front(), &pb = b.params.front();
    const double diff = std::abs(pa.value - pb.value), sd = std::hypot(pa.sigma, pb.sigma);
    const bool same_size = diff <= std::max(3 * sd, 0.15 * std::abs(t.params.front().value));
    if (!a.significant || !b.significant || !same_size)
      return seen + "on the two halves of the fit part its " + pa.name + " is " + std::to_string(pa.value) + " +- " + std::to_string(pa.sigma) +
             " and " + std::to_string(pb.value) + " +- " + std::to_string(pb.sigma) + ": it does not hold on both";
  }
  return "";
}

/// Rule 1's evidence: the BIC drop from `y0` (k0 parameters) to `y1` (k1) on the fit samples up
/// to `end`, both scored with N_eff = N / tau of the candidate's own residual. The round's
/// starting residual is the effect itself when the effect is what the model lacks (a scale
/// error's ramp has a correlation time of thousands of samples), so its tau would count a
/// whole trace as a handful of samples; the residual the better model leaves is the honest
/// measure of how many independent samples the comparison rests on.
double bic_drop(const Ctx& c, const std::vector<double>& y0, const std::vector<double>& y1, std::size_t end, int k0, int k1) {
  const std::size_t b = c.s.begin, n = end - b;
  const Eigen::VectorXd r1 = c.residual(y1, b, end);
  const double tau = correlation_time(std::span<const double>(r1.data(), static_cast<std::size_t>(r1.size())));
  return bic(c.sse(y0, b, end), n, tau, k0) - bic(r1.squaredNorm(), n, tau, k1);
}

/// Rule 2 when the round starts at the noise (a refit that reached it): a 2 % relative gain is
/// then out of reach by construction. With d = y1 - y0 on the held-out samples, the held-out
/// gain SSE0 - SSE1 = 2 r1.d + |d|^2 has mean |d|^2 and sd 2 sigma |d| when y1 is right: the
/// held-out part must agree with the candidate, a gain not below |d|^2 - 3 sd. Where the two
/// models differ little on the held-out part it cannot veto (the fit part's BIC decides); where
/// they differ much, the candidate must deliver most of what it predicts.
bool heldout_agrees(const Ctx& c, const std::vector<double>& y0, const std::vector<double>& y1) {
  const std::size_t b = c.s.split, e = c.n();
  if (e <= b) return true;
  double d2 = 0;
  for (std::size_t k = b; k < e; ++k) d2 += (y1[k] - y0[k]) * (y1[k] - y0[k]);
  const double gain = c.sse(y0, b, e) - c.sse(y1, b, e);
  return gain >= d2 - 3 * 2 * c.s.noise * std::sqrt(d2);
}

/// Rule 2's halves for the re-simulated effects (refitting them on each half would cost a whole
/// round): the fitted model must beat the round's start by the BIC on each half of the fit part
/// on its own, N_eff from that half's residual. A loop delay that only fits a stretch of the trace
/// (measured: 1.8 +- 0.5 ms named on a clean Y at a BIC drop of 10.8) fails it.
std::string not_on_both_halves(const Ctx& c, const std::vector<double>& y0, const std::vector<double>& y1, int k0, int k1) {
  const std::size_t mid = c.s.begin + (c.s.split - c.s.begin) / 2;
  const std::pair<std::size_t, std::size_t> halves[] = {{c.s.begin, mid}, {mid, c.s.split}};
  for (const auto& [b, e] : halves) {
    const Eigen::VectorXd r1 = c.residual(y1, b, e);
    const double tau = correlation_time(std::span<const double>(r1.data(), static_cast<std::size_t>(r1.size())));
    const double drop = bic(c.sse(y0, b, e), e - b, tau, k0) - bic(r1.squaredNorm(), e - b, tau, k1);
    if (!(drop > 0))
      return "seen, not named: on the " + std::string(b == c.s.begin ? "first" : "second") + " half of the fit part its BIC drop is " +
             std::to_string(drop) + ": it does not hold on both halves";
  }
  return "";
}

/// Rule 2 for a delay (measurement or loop): a drive can lag its response by itself, by a
/// feed-forward averaged over past commands (a lag of half the window), a slower velocity loop
/// (J/(Kvp + C)) or less feed-forward (a following error v (1 - K_FFP)/Kpp, the same as v d at
/// constant speed). The identified base came from starts spread over the config's range and may
/// have missed the lag a delay then fills (tests/unseen_machine: 17 of 23 false names were
/// delays). So the delay must beat a rival: the drive without it, every base slot free (the
/// velocity loop too), fitted from starts that carry the delay's lag in each of those ways. The
/// delay is named only when it beats that rival by the BIC margin (N_eff from its own residual)
/// and on the held-out part; otherwise it is "seen, not named" with the rival's figures.
std::string a_drive_lag_explains_the_delay(const Ctx& c, const AxisIdentification& id, const Trial& t, const RoundStart& r,
                                            const std::vector<double>& y) {
  const double d = param_of(t, "delay");
  servo::DriveParams without = t.model;
  std::erase_if(without.effects, [&](const servo::EffectSettings& e) { return e.type == t.effect; });
  const std::vector<BaseSlot> slots = base_slots(c.config, false, c.s.period);
  const auto range_of = [&](const char* name) {
    const auto it = std::find_if(slots.begin(), slots.end(), [&](const BaseSlot& b) { return std::string(b.name) == name; });
    return std::pair{it->lo, it->hi};
  };
  std::vector<servo::DriveParams> starts{without};
  for (const servo::DriveParams& from : {without, id.base.params}) {
    servo::DriveParams lag = from;  // the feed-forward lagging by d more
    const auto [tp_lo, tp_hi] = range_of("Tp");
    lag.Tp = std::clamp(from.Tp - d, tp_lo, tp_hi);
    starts.push_back(lag);
    servo::DriveParams slow = from;  // the velocity loop's lag J/(Kvp + C) longer by d
    const double J = from.J + from.J1, vel_lag = J / std::max(from.Kvp + from.C, 1e-12);
    const auto [kvp_lo, kvp_hi] = range_of("Kvp");
    slow.Kvp = std::clamp(J / (vel_lag + d) - from.C, kvp_lo, kvp_hi);
    starts.push_back(slow);
    servo::DriveParams less = from;  // less feed-forward: (1 - K_FFP) / Kpp longer by d
    less.K_FFP = std::max(0.0, from.K_FFP - 100 * from.Kpp * d);
    starts.push_back(less);
  }
  const std::size_t fit_end = c.dynamic_end(), screen_end = std::min(fit_end, c.s.begin + 15000);
  const RivalBase rival = fit_rival_base(c.s, c.config, starts, [&](const servo::DriveParams& p, std::size_t end) { return c.predict(p, end); },
                                         screen_end, fit_end, true);
  const std::vector<double> yr = c.predict(rival.params, c.n());
  int declared_free = 0;
  for (const auto& dp : id.declared) declared_free += !dp.held;
  const int k_rival = r.k - declared_free + rival.free_slots, k_delay = r.k + parameter_count(t);
  const double evidence = bic_drop(c, yr, y, c.s.split, k_rival, k_delay);
  const double h_rival = c.heldout_mse(yr), h_delay = c.heldout_mse(y);
  // The held-out part vetoes only a rival clearly better there: where both are near the noise,
  // a true 2 ms delay on seed 002's X (five-axis move) beats the rival by 73.6 in BIC and the two
  // differ by 0.03 % in held-out rms, which the held-out part cannot resolve.
  const bool rival_better_heldout = c.s.split < c.n() && h_rival < h_delay * (1 - c.o.heldout_gain);
  if (std::getenv("GCPIPE_CALIBRATE_DEBUG"))
    std::fprintf(stderr, "delay %.3f ms against the drive's own lag: evidence %.1f, held-out rms %.4g (rival) vs %.4g, rival Kpp %.4g Kvp %.4g K_FFP %.4g Ta %.4g Tp %.4g\n",
                 d * 1000, evidence, std::sqrt(h_rival) * 1000, std::sqrt(h_delay) * 1000, rival.params.Kpp, rival.params.Kvp, rival.params.K_FFP,
                 rival.params.Ta, rival.params.Tp);
  if (evidence > c.o.bic_margin && !rival_better_heldout) return "";
  const char* unit = c.config.rotary ? " mdeg" : " um";
  return "seen, not named: the drive without it, refitted with its own lag free (feed-forward timing, velocity loop, "
         "feed-forward gain), predicts as well: BIC drop of the delay against it " + std::to_string(evidence) +
         ", held-out rms " + std::to_string(std::sqrt(h_rival) * 1000) + unit + " against " + std::to_string(std::sqrt(h_delay) * 1000) + unit +
         ": a lag of the drive, not a delay";
}

/// Scores one trial against the round's start; fills `y` with its full prediction when it was
/// computed (re-simulated effects on long traces are screened on their fit window first).
CandidateScore score_trial(const Ctx& c, const Trial& t, const RoundStart& r, std::vector<double>& y) {
  CandidateScore s;
  s.round = r.round;
  s.effect = t.effect;
  s.params = t.params;
  s.seconds = t.seconds;
  const int k1 = r.k + parameter_count(t);
  const std::size_t we = c.dynamic_end();
  if (resimulated(t.effect) && we < c.s.split) {
    const std::vector<double> yw = c.predict(t.model, we);
    const double bw0 = bic(c.sse(r.y0, c.s.begin, we), we - c.s.begin, r.tau, r.k);
    const double bw1 = bic(c.sse(yw, c.s.begin, we), we - c.s.begin, r.tau, k1);
    if (!(bic_drop(c, r.y0, yw, we, r.k, k1) > c.o.bic_margin)) {
      s.criterion_before = bw0;
      s.criterion_after = bw1;
      s.heldout_before = s.heldout_after = r.h0;
      s.reason = "BIC does not drop by the margin on the first " + std::to_string(we - c.s.begin) + " samples (screened there)";
      return s;
    }
  }
  y = c.predict(t.model, c.n());
  s.criterion_before = r.b0;
  s.criterion_after = bic(c.fit_sse(y), c.nfit(), r.tau, k1);
  s.evidence = bic_drop(c, r.y0, y, c.s.split, r.k, k1);
  s.heldout_before = r.h0;
  s.heldout_after = c.heldout_mse(y);
  const bool crit = s.evidence > c.o.bic_margin;
  const bool held = c.s.split >= c.n() || s.heldout_after < r.h0 * (1 - c.o.heldout_gain) ||
                    (r.at_noise && heldout_agrees(c, r.y0, y));
  const double excess = r.h0 - r.noise2;
  // At the noise the "excess above the noise" is below what the noise estimate resolves (its
  // MAD-based sigma is good to about 1 %), so rule 4 has nothing to measure there.
  const bool bulk = c.s.split >= c.n() || !(excess > 0) || r.at_noise || (r.h0 - s.heldout_after) >= c.o.excess_explained * excess;
  std::string unphysical = outside_physical_range(t);
  if (unphysical.empty() && crit && held && t.significant && bulk) unphysical = not_a_real_effect(c, t);
  if (unphysical.empty() && crit && held && t.significant && bulk && resimulated(t.effect)) unphysical = not_on_both_halves(c, r.y0, y, r.k, k1);
  if (!std::isfinite(s.criterion_after) || !std::isfinite(s.evidence) || !std::isfinite(s.heldout_after)) {
    // Reported as failed, its numbers as the round's start: never a NaN in a report.
    s.reason = "failed: its fit gave no finite criterion (a diverged or empty fit)";
    s.criterion_after = s.criterion_before;
    s.evidence = 0;
    s.heldout_after = r.h0;
    for (auto& p : s.params)
      if (!std::isfinite(p.value) || !std::isfinite(p.sigma)) p.value = p.sigma = 0;
    return s;
  }
  s.reason = !crit ? "BIC does not drop by the margin"
             : !held ? "does not hold on the held-out part"
             : !t.significant ? "size below the significance threshold"
             : !bulk ? "explains too little of the residual above the noise"
             : !unphysical.empty() ? unphysical
             : "named";
  s.named = crit && held && t.significant && bulk && unphysical.empty();
  return s;
}

/// Names candidate `at` (its trial `t`, prediction `y`): the others of the round that passed
/// are marked as beaten, the model and declared values move on, everything is refitted jointly.
void accept(const Ctx& c, AxisIdentification& id, std::size_t start, std::size_t at, Trial& t,
            std::vector<double>&& y, const std::vector<int>& free, int& k) {
  for (std::size_t i = start; i < id.candidates.size(); ++i)
    if (i != at && id.candidates[i].named) {
      id.candidates[i].named = false;
      id.candidates[i].reason = "passes, but " + id.candidates[at].effect + " scores better in this round";
    }
  id.named.push_back(id.candidates[at]);
  id.calibrated = t.model;
  const std::vector<int>& slots = t.free.empty() ? free : t.free;
  for (int f : free)
    if (!t.free.empty() && std::find(t.free.begin(), t.free.end(), f) == t.free.end()) {
      // Loose once the effect is in the model (prune_loose_declared): back at its configured value.
      DeclaredParam& d = id.declared[static_cast<std::size_t>(f)];
      d.held = true;
      d.fitted = t.model.*(declared_slots()[static_cast<std::size_t>(f)].field);
      d.sigma = 0;
      d.why = "not separable once " + t.effect + " is in the model: kept at the configured value";
    }
  for (std::size_t i = 0; i < t.declared.size() && i < slots.size(); ++i) {
    DeclaredParam& d = id.declared[static_cast<std::size_t>(slots[i])];
    if (d.held) { d.held = d.excitation_held = false; d.why.clear(); }  // separable with the effect
    d.fitted = t.model.*(declared_slots()[static_cast<std::size_t>(slots[i])].field);  // as the model holds it (clamped)
    d.sigma = t.declared[i].second;
  }
  id.pred_calibrated = std::move(y);
  k += parameter_count(t);
  std::vector<int> now_free;  // the round's free slots and any the effect made separable
  for (std::size_t i = 0; i < id.declared.size(); ++i)
    if (!id.declared[i].held) now_free.push_back(static_cast<int>(i));
  repolish(c, id, now_free);
}

/// One greedy round: scores every candidate and names the best that passes; false when none.
/// `k` counts the parameters fitted so far (the BIC penalty of the current model).
bool greedy_round(const Ctx& c, AxisIdentification& id, int round, int& k) {
  const std::vector<double> y0 = id.pred_calibrated;
  // Nothing left to explain: when the residual is already at the measurement noise, no effect
  // can lower the held-out mean square by heldout_gain, so the round is not run...
  const double noise2 = c.s.noise * c.s.noise;
  const bool at_noise = noise2 > 0 && c.fit_sse(y0) / static_cast<double>(c.nfit()) <= noise2 / (1 - c.o.heldout_gain);
  // ...except right after a refit of the gains: fitted without the catalogue, the gains may have
  // bent to mimic an effect down to the noise (a loop delay is extra feed-forward Kpp*d at low
  // frequency). Each effect, fitted jointly with the gains, is then tested against that refit,
  // rules 2 and 4 read at the noise (heldout_agrees; no excess to explain). Only when the refit
  // saw every fit sample: on a long trace it is fitted on its window, and a candidate refitted
  // with the gains on the whole fit part would win by the gains' own gain from the samples the
  // refit never saw (about k * N_fit / N_window sigma^2: 28 sigma^2 for 4 gains on the 10-minute
  // benchmark, where it named a 0.08 ms measurement delay on a clean Z).
  const bool refit_saw_all = c.dynamic_end() >= c.s.split;
  if (at_noise && !(round == 1 && id.refit_kept && refit_saw_all)) return false;
  const double tau = c.tau(y0);
  const RoundStart r{y0, tau, bic(c.fit_sse(y0), c.nfit(), tau, k), c.heldout_mse(y0), noise2, k, round, at_noise};
  std::vector<std::string> named;
  for (const auto& n : id.named) named.push_back(n.effect);
  std::vector<int> free;
  for (std::size_t i = 0; i < id.declared.size(); ++i)
    if (!id.declared[i].held) free.push_back(static_cast<int>(i));
  std::vector<int> refree;  // held by the refit for want of excitation: a torque limit may free them
  for (std::size_t i = 0; i < id.declared.size(); ++i)
    if (id.declared[i].held && id.declared[i].excitation_held) refree.push_back(static_cast<int>(i));
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<Trial> trials = fit_catalogue(c, id.calibrated, y0, tau, named, id.config, free);
  const auto t1 = std::chrono::steady_clock::now();
  polish_trials(c, trials, free, refree, tau);
  if (std::getenv("GCPIPE_CALIBRATE_DEBUG")) {
    std::fprintf(stderr, "round %d: catalogue %.2f s, polish %.2f s:", round, std::chrono::duration<double>(t1 - t0).count(),
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count());
    for (const auto& t : trials) std::fprintf(stderr, " %s %.2f", t.effect.c_str(), t.seconds);
    std::fprintf(stderr, "\n");
  }
  int best = -1;
  std::vector<double> best_pred, y;
  const std::size_t start = id.candidates.size();
  for (std::size_t i = 0; i < trials.size(); ++i) {
    CandidateScore s = score_trial(c, trials[i], r, y);
    if (s.named && (s.effect == "measurement_delay" || s.effect == "feedback_delay")) {
      const std::string why = a_drive_lag_explains_the_delay(c, id, trials[i], r, y);
      if (!why.empty()) { s.named = false; s.reason = why; }
    }
    if (s.named && id.base.structural_mismatch) {
      // The drive has a structure the cascade lacks (base_model.hpp): an effect is named only
      // when it closes that gap, the model then within reach of the FIR on the held-out part;
      // one that fills part of it would name a cause the machine does not have.
      // Or when it explains at least 90 % of what the model lacked beyond the FIR (a loop delay
      // that takes a 146 um held-out rms to 16.5 um against the FIR's 3 um is the cause, the
      // rest a second one).
      const double noise2 = c.s.noise * c.s.noise, fir = std::max(id.base.fir.heldout_mse - noise2, 0.0);
      const BaseFitOptions limits;
      const double gap_before = r.h0 - noise2 - fir, gap_after = s.heldout_after - noise2 - fir;
      const bool closes = gap_after <= (limits.mismatch_ratio - 1) * fir || (gap_before > 0 && gap_after <= 0.1 * gap_before);
      if (!closes) {
        s.named = false;
        s.reason = "seen, not named: " + id.base.mismatch + ", and with it the held-out rms is still " +
                   std::to_string(std::sqrt(s.heldout_after) * 1000) + (c.config.rotary ? " mdeg" : " um");
      }
    }
    if (s.named && (best < 0 || s.criterion_after < id.candidates[start + static_cast<std::size_t>(best)].criterion_after)) {
      best = static_cast<int>(i);
      best_pred = std::move(y);
    }
    id.candidates.push_back(std::move(s));
  }
  if (best < 0) return false;
  accept(c, id, start, start + static_cast<std::size_t>(best), trials[static_cast<std::size_t>(best)], std::move(best_pred), free, k);
  return true;
}

/// True when every number of every effect of `p` lies in the range the servo registry accepts.
bool effects_in_range(const servo::DriveParams& p) {
  for (const auto& e : p.effects)
    for (const auto& type : servo::effect_types())
      if (e.type == type.name)
        for (const auto& [k, v] : e.values)
          for (const auto& key : type.keys)
            if (k == key.name && k != "phase" && (!std::isfinite(v) || v < key.min || v > key.max)) return false;
  return true;
}

/// Issue 29 rule 3: a declared value whose relative sigma exceeds 30 % (judged against the scale
/// at which it matters where its zero is physical: base_model.hpp relative_sigma), or that sits
/// on the edge of its physical range, is not written: the calibrated drive keeps the configured
/// value, the other free values and the named effects are refitted with it held, and the report
/// says why. A linearised sigma can be large along a valley of correlated values while the value
/// itself is pinned: when holding it costs more than 9 noise variances (3 sigma) the fitted value
/// is written and the report says that instead.
void write_only_identified(const Ctx& c, AxisIdentification& id) {
  const auto slots = base_slots(id.calibrated, true, c.s.period);
  const auto& dslots = declared_slots();
  std::vector<Ref> refs;
  bool dynamic = false;
  for (const auto& n : id.named) {
    for (const auto& k : continuous_keys(n.effect)) refs.emplace_back(n.effect, k);
    dynamic = dynamic || resimulated(n.effect);
  }
  const double noise2 = std::max(c.s.noise * c.s.noise, 1e-18);
  for (std::size_t i = 0; i < id.declared.size(); ++i) {
    DeclaredParam& d = id.declared[i];
    if (d.held) continue;
    const auto slot = std::find_if(slots.begin(), slots.end(), [&](const BaseSlot& b) { return d.name == b.name; });
    if (slot == slots.end()) continue;
    const double rel = relative_sigma(*slot, id.calibrated, d.fitted, d.sigma);
    const bool at_edge = !slot->zero_is_value && (d.fitted <= slot->lo * 1.0001 || d.fitted >= slot->hi * 0.9999);
    if (std::isfinite(rel) && rel <= 0.3 && !at_edge) continue;
    const std::string what = at_edge ? "fitted on the edge of its physical range (" + std::to_string(d.fitted) + ")"
                                     : "relative sigma " + (std::isfinite(rel) ? std::to_string(static_cast<int>(std::lround(100 * rel))) + " %" : std::string("unbounded")) +
                                           " > 30 % (" + std::to_string(d.fitted) + " +- " + std::to_string(d.sigma) + ")";
    std::vector<int> rest;
    for (std::size_t j = 0; j < id.declared.size(); ++j)
      if (j != i && !id.declared[j].held) rest.push_back(static_cast<int>(j));
    servo::DriveParams m = id.calibrated;
    m.*(slot->field) = d.config;
    servo::DriveParams refit = m;
    (void)joint_fit(c, refit, rest, refs, dynamic, c.tau(id.pred_calibrated), dynamic ? 40 : 200);
    // The refit may move a named effect out of what a machine has (a delay below zero): then the
    // value alone goes back to the config and nothing else moves.
    if (effects_in_range(refit)) m = refit;
    const std::vector<double> y = c.predict(m, c.n());
    const double cost = (c.fit_sse(y) - c.fit_sse(id.pred_calibrated)) / (noise2 * c.tau(id.pred_calibrated));
    if (cost > 9 && !at_edge) {
      d.why = what + ", but holding it at the configured value costs " + std::to_string(static_cast<int>(cost)) +
              " noise variances: the linearised sigma follows a valley of correlated values; written";
      continue;
    }
    d.held = true;
    d.why = what + ": not written, configured value kept (the rest refitted with it held)";
    d.fitted = d.config;
    d.sigma = 0;
    id.calibrated = m;
    id.pred_calibrated = y;
    for (int j : rest) id.declared[static_cast<std::size_t>(j)].fitted = m.*(dslots[static_cast<std::size_t>(j)].field);
    for (const auto& [effect, key] : refs)
      for (auto& n : id.named)
        if (n.effect == effect)
          for (auto& p : n.params)
            if (p.name == key) p.value = *effect_value(m, effect, key);
  }
}

bool moves(const std::vector<double>& c) {
  if (c.empty()) return false;
  const auto [lo, hi] = std::minmax_element(c.begin(), c.end());
  return *hi - *lo > 1e-6;
}

}  // namespace
}  // namespace gcpipe::calibrate

namespace gcpipe::calibrate {

AxisIdentification identify_axis(const AxisSeries& s, const servo::DriveParams& config,
                                 const IdentifyOptions& options) {
  const Ctx c{s, options, config};
  AxisIdentification id;
  id.axis = s.axis;
  id.config = id.refit = id.calibrated = config;
  id.noise = s.noise;
  id.pred_declared = c.predict(config, c.n());
  id.pred_refit = id.pred_calibrated = id.pred_declared;
  id.moving = moves(s.command) && s.split > s.begin + 100;
  if (!id.moving) {
    id.refit_note = "the axis does not move in this trace: nothing to identify";
    return id;
  }
  if (config.model != servo::DriveModel::kDrive) {
    // The simulator passes commands of an ideal axis straight through, effects included, so an
    // effect found there could not be written back into a model: the residual is reported (and
    // left to the NNOE fallback), nothing is named.
    id.refit_note = "ideal axis in the config (no drive parameters): its residual is reported and an NNOE fitted on it, but "
                    "nothing can be written for it; give the axis drives in the config (servo.drives) to use what is found here";
    return id;
  }
  if (s.period > kLoopVisiblePeriod) {
    // A drive's loop acts within 5-30 ms: a trace sampled slower shows none of it (the UMich
    // mill's 100 ms), so the configured drive stands and only slow effects are looked for.
    id.refit_note = "samples every " + std::to_string(s.period * 1000) + " ms: the drive's loop is not visible at this rate; the configured drive stands";
    for (const auto& slot : declared_slots())
      id.declared.push_back({slot.name, slot.unit, config.*(slot.field), config.*(slot.field), 0, true, "not visible at this sampling rate: kept"});
    int k = 0;
    for (int round = 1; round <= options.max_rounds; ++round)
      if (!greedy_round(c, id, round, k)) break;
    return id;
  }
  const auto t0 = std::chrono::steady_clock::now();
  const auto lap = [&](const char* what) {
    if (std::getenv("GCPIPE_CALIBRATE_DEBUG"))
      std::fprintf(stderr, "axis %d: %s at %.2f s\n", s.axis, what, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  };
  id.base = identify_base(s, config, [&](const servo::DriveParams& p, std::size_t end) { return c.predict(p, end); });
  lap("base identified");
  if (c.has_torque()) {
    refit_declared(c, id, id.base.params);
  } else {
    take_base(c, id);
  }
  id.calibrated = id.refit;
  id.pred_calibrated = id.pred_refit;
  int k = 0;
  for (const auto& d : id.declared) k += !d.held;
  for (int round = 1; round <= options.max_rounds; ++round)
    if (!greedy_round(c, id, round, k)) break;
  lap("effects selected");
  write_only_identified(c, id);
  lap("written values checked");
  if (c.has_torque()) {
    std::vector<double> t0, t1;
    (void)c.predict(id.config, c.n(), &t0);
    (void)c.predict(id.calibrated, c.n(), &t1);
    const std::size_t b = s.split < c.n() ? s.split : s.begin;
    id.torque_rms_config = std::sqrt(c.torque_mse(t0, b, c.n()));
    id.torque_rms_calibrated = std::sqrt(c.torque_mse(t1, b, c.n()));
  }
  return id;
}



}  // namespace gcpipe::calibrate
