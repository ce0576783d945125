// Identification of an axis's drive (its base model) from the trace, before any effect is tried,
// without trusting the configured gains (README "3.1 The base model first"):
//
//   1. a non-parametric model of the following error: e[k] = c[k] - y[k] = sum_j h_j dc[k-j],
//      j = -L ... M-1 (an FIR on the command's increments, L samples ahead for the feed-forward's
//      look-ahead). It holds for any stable linear loop with integral action in the plant (a
//      type-1 loop: 1 - H(z) has a zero at z = 1), so its held-out error is what a linear model
//      of this trace can reach: the yardstick of the structured fit;
//   2. the structured cascade of stages/servo (Kpp, Kvp, C, Kvi relative to J; K_FFP; Ta; and J
//      itself only with a torque column) fitted from several starts spread over the physical
//      range, every parameter free over that range, zero included for the feed-forward, the
//      velocity loop's integral action and the damping;
//   3. a structural mismatch is reported when the structured model stays clearly above the FIR
//      on the held-out samples: the cascade cannot reach what a linear model of the trace reaches.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "servo.hpp"

namespace gcpipe::calibrate {

struct AxisSeries;

/// The FIR model of the following error, fitted on [begin, fit_end) and evaluated everywhere.
struct FollowingErrorFir {
  int leads = 0, taps = 0;            //!< samples ahead of the command, samples behind
  std::vector<double> prediction;     //!< predicted actual position, every sample
  double fit_mse = 0, heldout_mse = 0;
};

/// Fits the FIR by ridge-regularised least squares; the Gram matrix is the autocorrelation of the
/// command increments (Toeplitz), so a fit costs O(N (L+M)) plus one (L+M)^2 solve.
FollowingErrorFir fit_following_error_fir(const AxisSeries& s, std::size_t fit_end);

/// One base parameter: how it is searched and how its uncertainty is judged.
struct BaseSlot {
  const char* name;
  const char* unit;
  double servo::DriveParams::*field;
  bool log_scale;        //!< searched in log (strictly positive) or linear (zero is a value)
  double lo, hi;         //!< physical range, natural units (J-relative ones scaled at run time)
  bool zero_is_value;    //!< 0 (or the log floor) means "not present", a physical value
};

/// The base parameters of `config` in search order, with their ranges for this drive (the
/// look-ahead within what the servo's window holds at the sampling `period`).
std::vector<BaseSlot> base_slots(const servo::DriveParams& config, bool with_torque, double period);

/// sigma / max(|value|, scale): for a parameter whose zero is physical (no feed-forward, no
/// integral action) a relative sigma against the value itself would call a well-determined zero
/// unknown, so it is judged against the scale at which the parameter starts to matter.
double relative_sigma(const BaseSlot& slot, const servo::DriveParams& p, double value, double sigma);

struct BaseFitParam {
  std::string name, unit;
  double config = 0, fitted = 0, sigma = 0, relative_sigma = 0;
  bool free = false;          //!< fitted (not held)
  std::string why;            //!< why held, when held
};

struct BaseIdentification {
  servo::DriveParams params;              //!< the identified base model (effects of the config kept)
  std::vector<BaseFitParam> table;        //!< every base slot, in base_slots order
  int starts = 0, evaluations = 0;
  double fit_mse = 0, heldout_mse = 0;    //!< of the structured model
  FollowingErrorFir fir;
  bool structural_mismatch = false;
  std::string mismatch;                   //!< what the mismatch is, in figures
};

/// Prediction of the first `end` samples (plus margin) of the axis by a model.
using AxisPredictor = std::function<std::vector<double>(const servo::DriveParams& p, std::size_t end)>;

struct BaseFitOptions {
  std::size_t screen_samples = 15000;  //!< samples each start is screened and first fitted on
  std::size_t fit_samples = 60000;     //!< samples the best start is polished on
  int polished_starts = 3;             //!< starts that get a full LM after screening
  double hold_relative_sigma = 0.25;   //!< noise-limited relative sigma above which a slot is held
  double mismatch_ratio = 1.5;         //!< structured held-out excess / FIR excess above it: mismatch
};

/// A drive without the candidate effect, fitted to rival it: LM over every base slot (the
/// velocity loop's Kvp and C included when `free_velocity_loop`, whatever the configured ratio of
/// the loops) from each of `starts` on [s.begin, screen_end), the best polished on
/// [s.begin, fit_end). `free_slots` returns how many slots it fitted (BIC's k).
struct RivalBase {
  servo::DriveParams params;
  int free_slots = 0;
  int evaluations = 0;
};
RivalBase fit_rival_base(const AxisSeries& s, const servo::DriveParams& config, const std::vector<servo::DriveParams>& starts,
                         const AxisPredictor& predict, std::size_t screen_end, std::size_t fit_end, bool free_velocity_loop);

/// Identifies the base model of one axis (see the file comment). `predict` runs a model on the
/// axis's commands; `tau` is the residual's correlation time (covariance inflation).
BaseIdentification identify_base(const AxisSeries& s, const servo::DriveParams& config, const AxisPredictor& predict,
                                 const BaseFitOptions& options = {});

}  // namespace gcpipe::calibrate
