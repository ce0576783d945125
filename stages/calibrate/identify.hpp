// Identification of one axis from a measured trace, in the order of issue #13:
//   1. refit of the declared drive parameters that the trace can separate (position-only traces
//      see the loop only through Kvp/J, C/J, Kvi/J: J and Kvi stay at their configured values);
//   2. greedy forward selection over the catalogue of named effects, every candidate fitted by
//      Levenberg-Marquardt (Eigen unsupported) and scored with BIC on the same fit samples;
//      a candidate is named when BIC drops by more than `bic_margin` AND the held-out part of the
//      trace (never used by any fit) gets better by at least `heldout_gain`.
// Method, derivations and the choice of BIC: README.md beside this file.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "base_model.hpp"
#include "servo.hpp"

namespace gcpipe::calibrate {

/// The measured data of one axis and how it is split.
struct AxisSeries {
  int axis = 0;
  double period = 0.001;
  int substeps = 8;
  double margin = 0.9;
  std::vector<double> command, actual;  //!< [mm or deg]
  std::size_t begin = 1;                //!< first sample scored (sample 0 is the rest state)
  std::size_t split = 0;                //!< [begin, split) fit, [split, N) held out
  /// Starts of separately recorded traces joined in this series (first is 0): the drive is put
  /// at rest at each start, so no transient is invented across the join.
  std::vector<std::size_t> segments{0};
  double noise = 0;                     //!< measurement noise estimate [mm or deg]
  /// Measured motor torque [N*m] or current [A] per sample (empty: the trace has none).
  std::vector<double> effort;
  std::string effort_kind;              //!< "torque", "current" or ""
};

struct IdentifyOptions {
  double bic_margin = 10;        //!< Kass & Raftery: a BIC drop above 10 is very strong evidence
  double heldout_gain = 0.02;    //!< the held-out mean square must fall by at least this fraction
  std::size_t max_dynamic_fit = 60000;  //!< samples used while fitting re-simulated effects
  int max_rounds = 3;            //!< greedy rounds per axis
  double significance = 3;       //!< a named effect's size must exceed this many sigma
  /// A named effect must explain at least this fraction of the held-out mean square above the
  /// noise: a physical effect accounts for the bulk of what it causes; one that only mops up
  /// part of an unknown residual would be a misleading name (that part goes to the NNOE).
  double excess_explained = 0.3;
};

/// One fitted number with its 1-sigma from the fit covariance.
struct FittedParam {
  std::string name, unit;
  double value = 0, sigma = 0;
};

/// One declared drive parameter after the refit.
struct DeclaredParam {
  std::string name, unit;
  double config = 0, fitted = 0, sigma = 0;
  bool held = false;   //!< kept at the configured value
  std::string why;     //!< why held
  /// Held only because the refit, done without any effect, could not pin it down: a candidate
  /// that changes the motion (a torque limit) may make it separable again.
  bool excitation_held = false;
};

/// One catalogue candidate as scored in one greedy round.
struct CandidateScore {
  int round = 0;
  std::string effect;
  std::vector<FittedParam> params;
  double criterion_before = 0, criterion_after = 0;    //!< BIC on the fit samples (round's tau)
  /// BIC drop with N_eff from the candidate's own residual: the gate of rule 1 (README 3.3).
  double evidence = 0;
  double heldout_before = 0, heldout_after = 0;        //!< mean square on held-out samples
  bool named = false;
  std::string reason;  //!< why named or not
  double seconds = 0;  //!< CPU time of its fit (wall clock of one thread)
};


struct AxisIdentification {
  int axis = 0;
  bool moving = false;
  servo::DriveParams config, refit, calibrated;
  bool refit_kept = false;
  std::string refit_note;
  std::vector<DeclaredParam> declared;
  BaseIdentification base;                 //!< the drive identified before any effect (README 3.1)
  std::vector<CandidateScore> candidates;  //!< every candidate of every round
  std::vector<CandidateScore> named;       //!< the named effects, in order
  std::vector<double> pred_declared, pred_refit, pred_calibrated;  //!< whole trace
  double noise = 0;
  /// With a torque column: the torque's rms prediction error [N*m] of the configured and the
  /// calibrated model on the held-out samples (0 without one).
  double torque_rms_config = 0, torque_rms_calibrated = 0;
};


/// Runs steps 1 and 2 on one axis. `config` is the configured drive of that axis.
AxisIdentification identify_axis(const AxisSeries& s, const servo::DriveParams& config,
                                 const IdentifyOptions& options);

// --- building blocks, exposed for the tests ---

/// Result of a least-squares fit.
struct LsqResult {
  Eigen::VectorXd x;
  Eigen::VectorXd sigma;  //!< sqrt(diag(cov)), cov = tau s^2 (J'J)^-1
  Eigen::MatrixXd jtj_inv;  //!< (J'J)^-1 at the solution (what the data can separate)
  double sse = 0;
  int evaluations = 0;
};
/// Residual r(x) over the fit samples; when `jac` is not null, also its Jacobian dr/dx
/// (m x n); a problem without analytic derivatives leaves it empty and central differences
/// with steps `step` are used.
using ResidualFn = std::function<Eigen::VectorXd(const Eigen::VectorXd& x, Eigen::MatrixXd* jac)>;
/// Levenberg-Marquardt (Eigen's unsupported module) from x0; tau is the residual's correlation
/// time in samples (variance inflation of the covariance).
LsqResult least_squares(const ResidualFn& r, const Eigen::VectorXd& x0, const Eigen::VectorXd& step,
                        bool analytic, double tau, int max_evaluations = 200);
/// Central-difference Jacobian of r at x.
Eigen::MatrixXd numeric_jacobian(const ResidualFn& r, const Eigen::VectorXd& x, const Eigen::VectorXd& step);

/// BIC = N_eff ln(SSE/N) + k ln(N_eff), N_eff = N / tau.
double bic(double sse, std::size_t n, double tau, int k);

}  // namespace gcpipe::calibrate
