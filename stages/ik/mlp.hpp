// A small dense multilayer perceptron in Eigen: tanh hidden layers, linear output layer (the
// structure of seed 003 eq. (2); seed 000 eq. (7) uses the logistic sigmoid, which is the same
// function class: tanh(y) = 2 sigma(2y) - 1). Batched forward pass (matrix x matrix), exact
// gradients and per-sample Jacobians by back-propagation, and two trainers:
//   - Levenberg-Marquardt (seed 003 eqs. (6)-(10)) for nets of a few hundred weights,
//   - batch gradient descent with momentum (what seed 000 used, Table 5 rates), kept to reproduce
//     the paper's baseline.
// Everything is deterministic for a seed: one caller-owned std::mt19937_64, our own conversions
// of its output to doubles (std::uniform_real_distribution is implementation-defined), no threads.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <random>
#include <string>
#include <vector>

namespace gcpipe::neural {

/// Uniform double in [0, 1) from the top 53 bits of one draw: identical on every platform.
double uniform01(std::mt19937_64& rng);
/// Uniform double in [lo, hi).
double uniform(std::mt19937_64& rng, double lo, double hi);
/// Uniform integer in [0, n) by rejection (no modulo bias); n > 0.
std::uint64_t uniform_index(std::mt19937_64& rng, std::uint64_t n);

/// tanh evaluated as 1 - 2 / (exp(2x) + 1) on whole arrays so Eigen vectorises it (Eigen 3.4 has
/// no vectorised double tanh). Absolute error below 4e-16 (measured 3.3e-16 on [-30, 30]), which
/// is what matters for a weighted sum; the argument is clamped to |x| <= 20, where tanh already
/// rounds to +-1 in double. Used in training; inference uses MlpInference.
void tanh_in_place(Eigen::Ref<Eigen::MatrixXd> z);

/// Reusable buffers for the forward pass, so that repeated calls allocate nothing.
struct MlpWorkspace {
  std::vector<Eigen::MatrixXd> activations;  //!< per hidden layer: units x batch
};

/// Dense feed-forward network. Parameters live in one flat vector, layer by layer: the weight
/// matrix W_l (outputs x inputs, column-major) followed by the bias b_l.
class Mlp {
 public:
  Mlp() = default;
  /// `layer_sizes` from input to output, e.g. {5, 25, 11, 1}; at least two entries, all >= 1.
  /// Throws std::invalid_argument otherwise. Parameters start at zero (see initialise).
  explicit Mlp(std::vector<int> layer_sizes);

  const std::vector<int>& layer_sizes() const { return sizes_; }
  int input_size() const { return sizes_.front(); }
  int output_size() const { return sizes_.back(); }
  int layer_count() const { return static_cast<int>(sizes_.size()) - 1; }  //!< weight layers
  Eigen::Index parameter_count() const { return theta_.size(); }

  const Eigen::VectorXd& parameters() const { return theta_; }
  /// Replaces all parameters; throws std::invalid_argument on a size mismatch.
  void set_parameters(const Eigen::VectorXd& theta);

  /// Glorot-uniform weights, U(-sqrt(6/(fan_in+fan_out)), +...), zero biases: keeps tanh units
  /// out of saturation for inputs normalised to [-1, 1].
  void initialise(std::mt19937_64& rng);

  /// y = net(x) for a batch: x is inputs x N, y becomes outputs x N.
  void forward(const Eigen::Ref<const Eigen::MatrixXd>& x, Eigen::MatrixXd& y,
               MlpWorkspace& workspace) const;
  Eigen::MatrixXd forward(const Eigen::Ref<const Eigen::MatrixXd>& x) const;

  /// Sum of squared errors S = sum (net(x) - t)^2 over the batch and all outputs, and its gradient
  /// dS/dtheta by back-propagation (matrix form over the batch).
  double sse_gradient(const Eigen::Ref<const Eigen::MatrixXd>& x,
                      const Eigen::Ref<const Eigen::MatrixXd>& targets,
                      Eigen::VectorXd& gradient) const;

  /// Transposed Jacobian of the outputs: column s*outputs + o holds d net_o(x_s) / dtheta
  /// (parameter_count rows), obtained by back-propagating a unit error from output o for each
  /// sample. `jt` is resized to parameter_count x (N * outputs).
  void output_jacobian_t(const Eigen::Ref<const Eigen::MatrixXd>& x, Eigen::MatrixXd& jt) const;

  /// Weight matrix W_l (outputs x inputs of layer l) and bias b_l, views into parameters().
  Eigen::Map<const Eigen::MatrixXd> weight(int layer) const;
  Eigen::Map<const Eigen::VectorXd> bias(int layer) const;

 private:
  /// Forward pass keeping every layer's output (activations[l] = output of layer l, with
  /// activations[layer_count-1] the linear network output).
  void forward_all(const Eigen::Ref<const Eigen::MatrixXd>& x,
                   std::vector<Eigen::MatrixXd>& activations) const;

  std::vector<int> sizes_;
  std::vector<Eigen::Index> weight_offset_;
  std::vector<Eigen::Index> bias_offset_;
  Eigen::VectorXd theta_;
};

/// Single-precision copy of an Mlp for inference. Float doubles the SIMD width and allows a cheap
/// vectorised tanh (a rational approximation, Eigen's coefficients; error a few float ulp): the
/// forward pass of a 5-25-11-1 net is several times faster than in double. The rounding
/// (relative 6e-8 per weight and input) changes a normalised output by ~1e-7, far below the
/// trained nets' errors; the tests bound the difference to the double forward pass.
///
/// Every sample goes through exactly the same sequence of float operations whatever the batch
/// size or its position in the batch (plain loops over samples, no GEMM kernels, the same tanh
/// code in the vector body and the scalar tail): a pose gives bit-identical joints whether it is
/// predicted alone or in a batch, so batch and streaming runs of the IK stage print the same text.
class MlpInference {
 public:
  MlpInference() = default;
  explicit MlpInference(const Mlp& net);

  int input_size() const { return sizes_.empty() ? 0 : sizes_.front(); }
  int output_size() const { return sizes_.empty() ? 0 : sizes_.back(); }

  /// Ping-pong activation buffers so repeated calls allocate nothing.
  struct Workspace {
    std::vector<float> a, b;
  };
  /// Batch of n samples in feature-major order: x[j * n + s] = normalised input j of sample s;
  /// y is resized to outputs * n, y[o * n + s].
  void forward(const float* x, std::size_t n, std::vector<float>& y, Workspace& workspace) const;

 private:
  std::vector<int> sizes_;
  std::vector<std::vector<float>> weights_;  //!< per layer, row-major outputs x inputs
  std::vector<std::vector<float>> biases_;
};

/// The float tanh of MlpInference (rational approximation, clamped at |x| = 7.905, x itself for
/// |x| < 4e-4).
float tanh_float(float x);

/// One sample at a time through a net of one tanh layer and one linear output (seed 003's eq. 2),
/// in float: the hidden layer is one loop over units that the compiler vectorises (weights stored
/// input-major, units padded to a multiple of 8), the same tanh as MlpInference. For recurrent use
/// (the NNOE's parallel run), where each step needs the previous step's output and a batch cannot
/// be formed. Allocates nothing per call.
class MlpSingle {
 public:
  /// Throws std::invalid_argument unless `net` has one hidden layer and one output.
  explicit MlpSingle(const Mlp& net);
  int input_size() const { return inputs_; }
  float operator()(const float* x) const;

 private:
  int inputs_ = 0, padded_ = 0;
  std::vector<float> w1_;  //!< [j * padded_ + h]
  std::vector<float> b1_, w2_;
  float b2_ = 0;
  mutable std::vector<float> z_;
};

/// Training data: one sample per column, inputs and targets already normalised.
struct Dataset {
  Eigen::MatrixXd inputs;   //!< inputs x N
  Eigen::MatrixXd targets;  //!< outputs x N
  Eigen::Index size() const { return inputs.cols(); }
};

/// Mean squared error over all samples and outputs: sum (net(x) - t)^2 / (N * outputs).
double mean_squared_error(const Mlp& net, const Dataset& data);

/// One line of training progress (iteration, training MSE, validation MSE, damping or rate).
struct TrainingProgress {
  int iteration = 0;
  double training_mse = 0;
  double validation_mse = 0;
  double damping = 0;  //!< LM lambda; 0 for gradient descent
};
using ProgressCallback = std::function<void(const TrainingProgress&)>;

/// Why and where training stopped. The network is left at the best-validation parameters.
struct TrainingResult {
  int iterations = 0;             //!< iterations (LM) or epochs (gradient descent) run
  int best_iteration = 0;         //!< iteration whose parameters were kept
  double training_mse = 0;        //!< at the kept parameters
  double validation_mse = 0;      //!< at the kept parameters
  std::string stop_reason;        //!< "max iterations", "validation stopped improving", ...
};

/// Levenberg-Marquardt as in seed 003 (Fletcher's ratio rule). With S(theta) = sum e^2 / 2,
/// J = d net / d theta, R = J'J and g = J'e (e = t - net):
///   step  s = (R + lambda I)^-1 g                                    (seed 003 eq. 7)
///   ratio rho = (S(theta) - S(theta + s)) / (S(theta) - L(theta + s)),
///         L(theta + s) = S(theta) - s'g + s'Rs / 2                   (eqs. 8-10)
///   rho > 0.75: lambda /= 2;  rho < 0.25: lambda *= 2;  the step is taken when rho > 1e-4,
///   otherwise lambda grows and the step is recomputed from the same R and g.
/// lambda starts at initial_damping * max diag(R) so the first steps are short gradient steps
/// whatever the data scale. J'J is accumulated block by block (rank updates), never storing J.
struct LevenbergMarquardtOptions {
  int max_iterations = 200;            //!< accepted steps
  double initial_damping = 1e-3;       //!< tau: lambda_0 = tau * max diag(J'J)
  double max_damping = 1e12;           //!< stop when lambda exceeds this (no progress possible)
  int max_validation_fails = 20;       //!< stop after this many iterations without a new best
  double min_relative_improvement = 1e-9;  //!< a new best must beat the old one by this fraction
  Eigen::Index block_size = 256;       //!< samples per Jacobian block
};

/// The same Levenberg-Marquardt on any least-squares problem, for models whose Jacobian is not
/// the static network's (the NNOE of stages/calibrate differentiates through its recurrence).
/// S = sum e^2 / 2 over `count` residuals; normal_equations fills the lower triangle of J'J and
/// J'e (e = target - output) at theta and returns S; half_sse returns S at a trial theta;
/// validation_mse (optional) decides which iterate is kept, as for the network.
struct LevenbergMarquardtProblem {
  double count = 1;
  std::function<double(const Eigen::VectorXd&, Eigen::MatrixXd&, Eigen::VectorXd&)> normal_equations;
  std::function<double(const Eigen::VectorXd&)> half_sse;
  std::function<double(const Eigen::VectorXd&)> validation_mse;
};

/// Runs the LM above on `problem` from `theta`; theta ends at the kept iterate. The result's
/// training/validation MSE fields are left for the caller.
TrainingResult levenberg_marquardt(Eigen::VectorXd& theta, const LevenbergMarquardtProblem& problem,
                                   const LevenbergMarquardtOptions& options,
                                   const ProgressCallback& progress = {});

TrainingResult train_levenberg_marquardt(Mlp& net, const Dataset& training,
                                         const Dataset& validation,
                                         const LevenbergMarquardtOptions& options,
                                         const ProgressCallback& progress = {});

/// Full-batch gradient descent with momentum, MATLAB traingdm's update:
///   v = mu v - (1 - mu) eta dMSE/dtheta,  theta += v
/// with MSE the mean over samples and outputs; early stopping on the validation set.
struct GradientDescentOptions {
  int max_epochs = 1000;          //!< MATLAB's default
  double learning_rate = 0.1;     //!< eta
  double momentum = 0.9;          //!< mu in [0, 1)
  int max_validation_fails = 6;   //!< MATLAB's default max_fail
};

TrainingResult train_gradient_descent(Mlp& net, const Dataset& training, const Dataset& validation,
                                      const GradientDescentOptions& options,
                                      const ProgressCallback& progress = {});

}  // namespace gcpipe::neural
