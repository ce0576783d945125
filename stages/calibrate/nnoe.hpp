// The fallback for what no named effect explains: seed 003's neural output-error model (Haber et
// al., eqs. 1-12). One tanh hidden layer, linear output (eq. 2), regressors of the model's own
// past outputs and of past inputs (eq. 12, parallel identification), trained on the output-error
// criterion (eq. 4) by the Levenberg-Marquardt of stages/ik/mlp.cpp (eqs. 6-10, the rho
// acceptance ratio) with the Jacobian taken through the recurrence, regressor structure chosen
// by the final prediction error as in its Table 1.
//
// One implementation for every use: the regressor holds na past model outputs and, per input
// channel, its own number of past inputs (train_nnoe, nnoe_simulate on any channels). Two uses:
// - calibrate: the output is the residual r = measured - calibrated prediction of one axis, the
//   inputs the commanded velocity and acceleration (what excites a structural mode or a friction
//   the catalogue lacks); y = model + NNOE(velocity, acceleration) (fit_nnoe).
// - force (stages/force/nnoe_force.hpp): seed 003's own case, the mean cutting force from past
//   feed and depth of cut (eq. 13), its Table 1 structures compared by FPE.
#pragma once

#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "mlp.hpp"

namespace gcpipe::calibrate {

struct NnoeStructure {
  int na = 2;      //!< past model outputs r^(t-1..t-na)
  int nb = 2;      //!< past inputs per channel u(t-1..t-nb), unless channel_lags is given
  int hidden = 6;  //!< tanh units
  std::vector<int> channel_lags;  //!< past inputs of each channel (empty: nb for every channel)
  int lags(std::size_t channel) const { return channel_lags.empty() ? nb : channel_lags[channel]; }
  std::string text() const;  //!< "na=2 nb=2 hidden=6", or "na=2 nb=[2,1] hidden=12"
};

/// Input series, one span per channel, all as long as the output series.
using Channels = std::vector<std::span<const double>>;

struct NnoeModel {
  NnoeStructure structure;
  neural::Mlp net;
  double y_scale = 1;       //!< output normalisation (residual: mm or deg; force: N)
  double y_offset = 0;      //!< output centre: the network sees (y - y_offset) / y_scale
  std::vector<double> u_scale = {1, 1};   //!< per channel (calibrate: velocity, acceleration)
  std::vector<double> u_offset = {0, 0};  //!< per channel centre
  int decimation = 1;       //!< the model steps every `decimation` samples (about 4 ms)
  double fpe = 0;           //!< final prediction error (normalised units) of the chosen structure
  double explained_fraction = 0;  //!< 1 - MSE(r - r^) / MSE(r) on the held-out samples
  std::vector<std::pair<NnoeStructure, double>> candidates;  //!< every structure tried and its FPE
  /// Runs the model in parallel (output-error) mode over whole series: r^ per sample (linear
  /// between the model's steps).
  std::vector<double> simulate(std::span<const double> velocity, std::span<const double> accel) const;
};

struct NnoeOptions {
  std::size_t max_train = 20000;  //!< training samples (the first of the fit part)
  int max_iterations = 60;        //!< LM iterations of the output-error training
  std::uint64_t seed = 1;
};

/// Trains one structure on y[b, e) from the channels (series-parallel start, then the output-error
/// criterion by LM through the recurrence); scales and offsets as given in `norm` (its net and
/// structure are ignored). m.fpe: Akaike's FPE = V (N + d) / (N - d), V the simulated mean square
/// error in normalised units (so a fraction of the output variance when y_scale is its stdev).
NnoeModel train_nnoe(const NnoeStructure& structure, std::span<const double> y, const Channels& u, std::size_t b,
                     std::size_t e, const NnoeOptions& options, const NnoeModel& norm);

/// Runs the model in parallel (output-error) mode over [0, end): y^ per sample, the first
/// max(na, lags) samples 0 + offset. Each step is one evaluation of eq. (2).
std::vector<double> nnoe_simulate(const NnoeModel& m, const Channels& u, std::size_t end);

/// FPE of the model's parallel run on samples [b, e) of y: V (N + d) / (N - d) in normalised units.
double nnoe_fpe(const NnoeModel& m, std::span<const double> y, const Channels& u, std::size_t b, std::size_t e);

/// Fits the NNOE on residual samples [begin, split) and scores it on [split, N). nullopt when
/// there are too few samples.
std::optional<NnoeModel> fit_nnoe(std::span<const double> residual, std::span<const double> velocity,
                                  std::span<const double> accel, std::size_t begin, std::size_t split,
                                  double period, const NnoeOptions& options = {});

/// The output-error criterion S = sum (r/y_scale - r^)^2 / 2 over [b, e) of `m` at parameters
/// `theta` (normalised units, the series already at the model's step), and when `jtj`/`jte` are
/// given the Gauss-Newton terms of its recurrent Jacobian (exposed so the tests can check the
/// Jacobian against finite differences).
double nnoe_output_error(const NnoeModel& m, std::span<const double> r, std::span<const double> v,
                         std::span<const double> a, std::size_t b, std::size_t e, const Eigen::VectorXd& theta,
                         Eigen::MatrixXd* jtj, Eigen::VectorXd* jte);

/// Velocity and acceleration of a position series by central differences [unit/s, unit/s^2].
void differentiate(std::span<const double> y, double period, std::vector<double>& v, std::vector<double>& a);

}  // namespace gcpipe::calibrate
