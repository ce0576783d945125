#include "mlp.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace gcpipe::neural {

double uniform01(std::mt19937_64& rng) {
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

double uniform(std::mt19937_64& rng, double lo, double hi) {
  return lo + (hi - lo) * uniform01(rng);
}

std::uint64_t uniform_index(std::mt19937_64& rng, std::uint64_t n) {
  // Reject the top partial block of the 64-bit range so every index is equally likely.
  const std::uint64_t limit = std::numeric_limits<std::uint64_t>::max() -
                              std::numeric_limits<std::uint64_t>::max() % n;
  std::uint64_t r = rng();
  while (r >= limit) r = rng();
  return r % n;
}

void tanh_in_place(Eigen::Ref<Eigen::MatrixXd> z) {
  auto a = z.array();
  a = 1.0 - 2.0 / ((2.0 * a.max(-20.0).min(20.0)).exp() + 1.0);
}

Mlp::Mlp(std::vector<int> layer_sizes) : sizes_(std::move(layer_sizes)) {
  if (sizes_.size() < 2)
    throw std::invalid_argument("Mlp: need at least an input and an output layer, got " +
                                std::to_string(sizes_.size()) + " layer size(s)");
  for (std::size_t i = 0; i < sizes_.size(); ++i)
    if (sizes_[i] < 1)
      throw std::invalid_argument("Mlp: layer " + std::to_string(i) + " has " +
                                  std::to_string(sizes_[i]) + " units; must be >= 1");
  Eigen::Index offset = 0;
  for (int l = 0; l < layer_count(); ++l) {
    weight_offset_.push_back(offset);
    offset += static_cast<Eigen::Index>(sizes_[l + 1]) * sizes_[l];
    bias_offset_.push_back(offset);
    offset += sizes_[l + 1];
  }
  theta_ = Eigen::VectorXd::Zero(offset);
}

void Mlp::set_parameters(const Eigen::VectorXd& theta) {
  if (theta.size() != theta_.size())
    throw std::invalid_argument("Mlp: " + std::to_string(theta.size()) +
                                " parameters given, the network has " +
                                std::to_string(theta_.size()));
  theta_ = theta;
}

void Mlp::initialise(std::mt19937_64& rng) {
  for (int l = 0; l < layer_count(); ++l) {
    const double limit = std::sqrt(6.0 / (sizes_[l] + sizes_[l + 1]));
    const Eigen::Index n = static_cast<Eigen::Index>(sizes_[l + 1]) * sizes_[l];
    for (Eigen::Index i = 0; i < n; ++i) theta_[weight_offset_[l] + i] = uniform(rng, -limit, limit);
    theta_.segment(bias_offset_[l], sizes_[l + 1]).setZero();
  }
}

Eigen::Map<const Eigen::MatrixXd> Mlp::weight(int layer) const {
  return {theta_.data() + weight_offset_[layer], sizes_[layer + 1], sizes_[layer]};
}

Eigen::Map<const Eigen::VectorXd> Mlp::bias(int layer) const {
  return {theta_.data() + bias_offset_[layer], sizes_[layer + 1]};
}

void Mlp::forward_all(const Eigen::Ref<const Eigen::MatrixXd>& x,
                      std::vector<Eigen::MatrixXd>& activations) const {
  activations.resize(layer_count());
  for (int l = 0; l < layer_count(); ++l) {
    Eigen::MatrixXd& z = activations[l];
    if (l == 0)
      z.noalias() = weight(l) * x;
    else
      z.noalias() = weight(l) * activations[l - 1];
    z.colwise() += bias(l);
    if (l + 1 < layer_count()) tanh_in_place(z);
  }
}

void Mlp::forward(const Eigen::Ref<const Eigen::MatrixXd>& x, Eigen::MatrixXd& y,
                  MlpWorkspace& workspace) const {
  if (x.rows() != input_size())
    throw std::invalid_argument("Mlp::forward: input has " + std::to_string(x.rows()) +
                                " rows, the network takes " + std::to_string(input_size()));
  const int hidden = layer_count() - 1;
  workspace.activations.resize(std::max(hidden, 0));
  for (int l = 0; l < layer_count(); ++l) {
    Eigen::MatrixXd& z = (l == hidden) ? y : workspace.activations[l];
    if (l == 0)
      z.noalias() = weight(l) * x;
    else
      z.noalias() = weight(l) * workspace.activations[l - 1];
    z.colwise() += bias(l);
    if (l < hidden) tanh_in_place(z);
  }
}

Eigen::MatrixXd Mlp::forward(const Eigen::Ref<const Eigen::MatrixXd>& x) const {
  MlpWorkspace workspace;
  Eigen::MatrixXd y;
  forward(x, y, workspace);
  return y;
}

double Mlp::sse_gradient(const Eigen::Ref<const Eigen::MatrixXd>& x,
                         const Eigen::Ref<const Eigen::MatrixXd>& targets,
                         Eigen::VectorXd& gradient) const {
  std::vector<Eigen::MatrixXd> a;
  forward_all(x, a);
  const int last = layer_count() - 1;
  Eigen::MatrixXd delta = a[last] - targets;  // e = net - t
  const double sse = delta.squaredNorm();
  delta *= 2.0;                               // dS/d net
  gradient.resize(theta_.size());
  for (int l = last; l >= 0; --l) {
    Eigen::Map<Eigen::MatrixXd> weight_gradient(gradient.data() + weight_offset_[l],
                                                sizes_[l + 1], sizes_[l]);
    if (l == 0)
      weight_gradient.noalias() = delta * x.transpose();
    else
      weight_gradient.noalias() = delta * a[l - 1].transpose();
    gradient.segment(bias_offset_[l], sizes_[l + 1]) = delta.rowwise().sum();
    if (l > 0) {
      Eigen::MatrixXd back = weight(l).transpose() * delta;
      delta = back.array() * (1.0 - a[l - 1].array().square());
    }
  }
  return sse;
}

void Mlp::output_jacobian_t(const Eigen::Ref<const Eigen::MatrixXd>& x, Eigen::MatrixXd& jt) const {
  std::vector<Eigen::MatrixXd> a;
  forward_all(x, a);
  const Eigen::Index n = x.cols();
  const int outputs = output_size();
  const int last = layer_count() - 1;
  jt.setZero(theta_.size(), n * outputs);
  auto layer_input = [&](int l) -> const Eigen::Ref<const Eigen::MatrixXd> {
    if (l == 0) return x;
    return a[l - 1];
  };
  for (int o = 0; o < outputs; ++o) {
    // Output layer: d net_o / d W(i, j) = [i == o] a_j, d net_o / d b(i) = [i == o].
    {
      const auto in = layer_input(last);
      for (Eigen::Index s = 0; s < n; ++s) {
        const Eigen::Index c = s * outputs + o;
        for (int j = 0; j < sizes_[last]; ++j)
          jt(weight_offset_[last] + static_cast<Eigen::Index>(j) * outputs + o, c) = in(j, s);
        jt(bias_offset_[last] + o, c) = 1.0;
      }
    }
    if (last == 0) continue;
    // Unit error at output o, pulled back through the tanh layers.
    Eigen::MatrixXd delta =
        (weight(last).row(o).transpose() * Eigen::RowVectorXd::Ones(n)).array() *
        (1.0 - a[last - 1].array().square());
    for (int l = last - 1; l >= 0; --l) {
      const auto in = layer_input(l);
      const int units = sizes_[l + 1];
      for (Eigen::Index s = 0; s < n; ++s) {
        const Eigen::Index c = s * outputs + o;
        for (int j = 0; j < sizes_[l]; ++j)
          jt.col(c).segment(weight_offset_[l] + static_cast<Eigen::Index>(j) * units, units) =
              delta.col(s) * in(j, s);
        jt.col(c).segment(bias_offset_[l], units) = delta.col(s);
      }
      if (l > 0) {
        Eigen::MatrixXd back = weight(l).transpose() * delta;
        delta = back.array() * (1.0 - a[l - 1].array().square());
      }
    }
  }
}

float tanh_float(float x) {
  // Eigen 3.4's generic_fast_tanh_float (non-FMA clamp), written as plain scalar code so that the
  // compiler's vectorised loop body and its scalar tail do identical arithmetic.
  const float c = 7.90531110763549805f;
  const float xc = x < -c ? -c : (x > c ? c : x);
  const float x2 = xc * xc;
  float p = x2 * -2.76076847742355e-16f + 2.00018790482477e-13f;
  p = x2 * p + -8.60467152213735e-11f;
  p = x2 * p + 5.12229709037114e-08f;
  p = x2 * p + 1.48572235717979e-05f;
  p = x2 * p + 6.37261928875436e-04f;
  p = x2 * p + 4.89352455891786e-03f;
  p = xc * p;
  float q = x2 * 1.19825839466702e-06f + 1.18534705686654e-04f;
  q = x2 * q + 2.26843463243900e-03f;
  q = x2 * q + 4.89352518554385e-03f;
  const float t = p / q;
  return (x < 4e-4f && x > -4e-4f) ? x : t;
}

MlpInference::MlpInference(const Mlp& net) : sizes_(net.layer_sizes()) {
  for (int l = 0; l < net.layer_count(); ++l) {
    const auto w = net.weight(l);
    std::vector<float> rows(static_cast<std::size_t>(w.size()));
    for (Eigen::Index i = 0; i < w.rows(); ++i)
      for (Eigen::Index j = 0; j < w.cols(); ++j)
        rows[static_cast<std::size_t>(i * w.cols() + j)] = static_cast<float>(w(i, j));
    weights_.push_back(std::move(rows));
    const auto b = net.bias(l);
    biases_.emplace_back(b.size());
    for (Eigen::Index i = 0; i < b.size(); ++i) biases_.back()[static_cast<std::size_t>(i)] = static_cast<float>(b[i]);
  }
}

namespace {

/// z[i * n + s] = act(b_i + sum_j W(i, j) x[j * n + s]), summed in j order for every sample.
/// Large batches run row by row over all samples (long contiguous loops the compiler vectorises);
/// small ones keep each sum in a register (row-wise loops of one or two samples stall on store
/// forwarding). Both do, for every sample, t = b_i, then t = t + W(i, j) x_j for j = 0, 1, ...:
/// the same float operations in the same order, so a sample's result never depends on the batch.
void dense_layer(const float* __restrict w, const float* __restrict b, int outputs, int inputs,
                 const float* __restrict x, float* __restrict z, std::size_t n, bool squash) {
  if (n < 8) {
    for (std::size_t s = 0; s < n; ++s)
      for (int i = 0; i < outputs; ++i) {
        float acc = b[i];
        for (int j = 0; j < inputs; ++j)
          acc += w[i * inputs + j] * x[static_cast<std::size_t>(j) * n + s];
        z[static_cast<std::size_t>(i) * n + s] = squash ? tanh_float(acc) : acc;
      }
    return;
  }
  for (int i = 0; i < outputs; ++i) {
    float* __restrict zi = z + static_cast<std::size_t>(i) * n;
    const float bi = b[i];
    for (std::size_t s = 0; s < n; ++s) zi[s] = bi;
    for (int j = 0; j < inputs; ++j) {
      const float wij = w[i * inputs + j];
      const float* __restrict xj = x + static_cast<std::size_t>(j) * n;
      for (std::size_t s = 0; s < n; ++s) zi[s] += wij * xj[s];
    }
    if (squash)
      for (std::size_t s = 0; s < n; ++s) zi[s] = tanh_float(zi[s]);
  }
}

}  // namespace

void MlpInference::forward(const float* x, std::size_t n, std::vector<float>& y,
                           Workspace& workspace) const {
  const int layers = static_cast<int>(weights_.size());
  const float* in = x;
  for (int l = 0; l < layers; ++l) {
    const bool last = l + 1 == layers;
    std::vector<float>& out = last ? y : (l % 2 == 0 ? workspace.a : workspace.b);
    out.resize(static_cast<std::size_t>(sizes_[l + 1]) * n);
    dense_layer(weights_[l].data(), biases_[l].data(), sizes_[l + 1], sizes_[l], in, out.data(), n,
                !last);
    in = out.data();
  }
}

MlpSingle::MlpSingle(const Mlp& net) : inputs_(net.input_size()) {
  if (net.layer_count() != 2 || net.output_size() != 1)
    throw std::invalid_argument("MlpSingle: needs one hidden layer and one output");
  const auto W1 = net.weight(0), W2 = net.weight(1);
  const auto b1 = net.bias(0);
  const int hidden = static_cast<int>(W1.rows());
  padded_ = (hidden + 7) / 8 * 8;  // padding units have zero weights: tanh(0) * 0 adds nothing
  const auto P = static_cast<std::size_t>(padded_);
  w1_.assign(static_cast<std::size_t>(inputs_) * P, 0.0f);
  b1_.assign(P, 0.0f);
  w2_.assign(P, 0.0f);
  z_.assign(P, 0.0f);
  for (int h = 0; h < hidden; ++h) {
    for (int j = 0; j < inputs_; ++j) w1_[static_cast<std::size_t>(j) * P + static_cast<std::size_t>(h)] = static_cast<float>(W1(h, j));
    b1_[static_cast<std::size_t>(h)] = static_cast<float>(b1[h]);
    w2_[static_cast<std::size_t>(h)] = static_cast<float>(W2(0, h));
  }
  b2_ = static_cast<float>(net.bias(1)[0]);
}

float MlpSingle::operator()(const float* x) const {
  const auto P = static_cast<std::size_t>(padded_);
  float* __restrict z = z_.data();
  const float* __restrict b1 = b1_.data();
  for (std::size_t h = 0; h < P; ++h) z[h] = b1[h];
  for (int j = 0; j < inputs_; ++j) {
    const float xj = x[j];
    const float* __restrict w = w1_.data() + static_cast<std::size_t>(j) * P;
    for (std::size_t h = 0; h < P; ++h) z[h] += w[h] * xj;
  }
  for (std::size_t h = 0; h < P; ++h) z[h] = tanh_float(z[h]);
  // Eight partial sums, one per lane: a vector accumulator without reassociating a float sum.
  float lane[8] = {};
  const float* __restrict w2 = w2_.data();
  for (std::size_t h = 0; h < P; h += 8)
    for (std::size_t l = 0; l < 8; ++l) lane[l] += w2[h + l] * z[h + l];
  return b2_ + (((lane[0] + lane[4]) + (lane[1] + lane[5])) + ((lane[2] + lane[6]) + (lane[3] + lane[7])));
}

double mean_squared_error(const Mlp& net, const Dataset& data) {
  if (data.size() == 0) return 0;
  const Eigen::MatrixXd y = net.forward(data.inputs);
  return (y - data.targets).squaredNorm() / static_cast<double>(data.targets.size());
}

namespace {

void check_dataset(const Mlp& net, const Dataset& data, const char* which) {
  if (data.inputs.size() == 0 && data.targets.size() == 0) return;  // an absent (empty) set
  if (data.inputs.rows() != net.input_size() || data.targets.rows() != net.output_size() ||
      data.inputs.cols() != data.targets.cols())
    throw std::invalid_argument(std::string("training: ") + which + " set is " +
                                std::to_string(data.inputs.rows()) + "x" +
                                std::to_string(data.inputs.cols()) + " inputs, " +
                                std::to_string(data.targets.rows()) + "x" +
                                std::to_string(data.targets.cols()) + " targets; the network is " +
                                std::to_string(net.input_size()) + " -> " +
                                std::to_string(net.output_size()));
  if (!data.inputs.allFinite() || !data.targets.allFinite())
    throw std::invalid_argument(std::string("training: ") + which +
                                " set contains NaN or infinite values");
}

/// Gauss-Newton quantities over the whole set: lower triangle of R = J'J, g = J'e, and
/// S = sum e^2 / 2, with e = t - net.
double accumulate_normal_equations(const Mlp& net, const Dataset& data, Eigen::Index block_size,
                                   Eigen::MatrixXd& jtj, Eigen::VectorXd& jte) {
  const Eigen::Index p = net.parameter_count();
  jtj.setZero(p, p);
  jte.setZero(p);
  double half_sse = 0;
  Eigen::MatrixXd jt;
  MlpWorkspace workspace;
  Eigen::MatrixXd y;
  for (Eigen::Index start = 0; start < data.size(); start += block_size) {
    const Eigen::Index count = std::min(block_size, data.size() - start);
    const auto x = data.inputs.middleCols(start, count);
    net.forward(x, y, workspace);
    const Eigen::MatrixXd e = data.targets.middleCols(start, count) - y;
    half_sse += 0.5 * e.squaredNorm();
    net.output_jacobian_t(x, jt);
    jtj.selfadjointView<Eigen::Lower>().rankUpdate(jt);
    // Column s*outputs + o of jt pairs with e(o, s): the column-major order of e.
    jte.noalias() += jt * Eigen::Map<const Eigen::VectorXd>(e.data(), e.size());
  }
  return half_sse;
}

double half_sse(const Mlp& net, const Dataset& data) {
  return 0.5 * mean_squared_error(net, data) * static_cast<double>(data.targets.size());
}

}  // namespace

TrainingResult levenberg_marquardt(Eigen::VectorXd& theta, const LevenbergMarquardtProblem& problem,
                                   const LevenbergMarquardtOptions& options, const ProgressCallback& progress) {
  Eigen::MatrixXd jtj;
  Eigen::VectorXd g;
  double s = problem.normal_equations(theta, jtj, g);
  double lambda = options.initial_damping * jtj.diagonal().maxCoeff();
  if (!(lambda > 0)) lambda = options.initial_damping;

  TrainingResult result;
  Eigen::VectorXd best = theta;
  double best_validation = problem.validation_mse ? problem.validation_mse(theta) : s * 2 / problem.count;
  int fails = 0;
  result.stop_reason = "max iterations";
  Eigen::MatrixXd damped;
  Eigen::LLT<Eigen::MatrixXd, Eigen::Lower> cholesky;

  int iteration = 0;
  while (iteration < options.max_iterations) {
    bool accepted = false;
    while (!accepted) {
      if (lambda > options.max_damping) break;
      damped = jtj;
      damped.diagonal().array() += lambda;
      cholesky.compute(damped);
      if (cholesky.info() != Eigen::Success) {  // only possible through rounding; damp harder
        lambda *= 2;
        continue;
      }
      const Eigen::VectorXd step = cholesky.solve(g);
      const double predicted =
          step.dot(g) - 0.5 * step.dot(jtj.selfadjointView<Eigen::Lower>() * step);
      const Eigen::VectorXd trial = theta + step;
      const double s_new = problem.half_sse(trial);
      const double rho = predicted > 0 ? (s - s_new) / predicted : -1.0;
      if (rho > 0.75) lambda *= 0.5;
      if (rho < 0.25) lambda *= 2.0;
      if (rho > 1e-4 && std::isfinite(s_new)) {
        theta = trial;
        accepted = true;
      }
    }
    if (!accepted) {
      result.stop_reason = "damping exceeded max_damping (no further decrease)";
      break;
    }
    ++iteration;
    s = problem.normal_equations(theta, jtj, g);
    const double training_mse = 2 * s / problem.count;
    const double validation_mse = problem.validation_mse ? problem.validation_mse(theta) : training_mse;
    if (validation_mse < best_validation * (1 - options.min_relative_improvement)) {
      best_validation = validation_mse;
      best = theta;
      result.best_iteration = iteration;
      fails = 0;
    } else {
      ++fails;
    }
    if (progress) progress({iteration, training_mse, validation_mse, lambda});
    if (fails >= options.max_validation_fails) {
      result.stop_reason = "validation stopped improving";
      break;
    }
  }
  result.iterations = iteration;
  theta = best;
  return result;
}

TrainingResult train_levenberg_marquardt(Mlp& net, const Dataset& training,
                                         const Dataset& validation,
                                         const LevenbergMarquardtOptions& options,
                                         const ProgressCallback& progress) {
  check_dataset(net, training, "training");
  check_dataset(net, validation, "validation");
  if (training.size() == 0) throw std::invalid_argument("training: empty training set");
  // The static network as an LM problem: J from back-propagation, block by block.
  Mlp trial = net;
  LevenbergMarquardtProblem problem;
  problem.count = static_cast<double>(training.targets.size());
  problem.normal_equations = [&](const Eigen::VectorXd& theta, Eigen::MatrixXd& jtj, Eigen::VectorXd& jte) {
    trial.set_parameters(theta);
    return accumulate_normal_equations(trial, training, options.block_size, jtj, jte);
  };
  problem.half_sse = [&](const Eigen::VectorXd& theta) {
    trial.set_parameters(theta);
    return half_sse(trial, training);
  };
  if (validation.size() > 0)
    problem.validation_mse = [&](const Eigen::VectorXd& theta) {
      trial.set_parameters(theta);
      return mean_squared_error(trial, validation);
    };
  Eigen::VectorXd theta = net.parameters();
  TrainingResult result = levenberg_marquardt(theta, problem, options, progress);
  net.set_parameters(theta);
  result.training_mse = mean_squared_error(net, training);
  result.validation_mse = validation.size() > 0 ? mean_squared_error(net, validation) : result.training_mse;
  return result;
}

TrainingResult train_gradient_descent(Mlp& net, const Dataset& training, const Dataset& validation,
                                      const GradientDescentOptions& options,
                                      const ProgressCallback& progress) {
  check_dataset(net, training, "training");
  check_dataset(net, validation, "validation");
  if (training.size() == 0) throw std::invalid_argument("training: empty training set");
  if (!(options.momentum >= 0 && options.momentum < 1))
    throw std::invalid_argument("training: momentum " + std::to_string(options.momentum) +
                                " outside [0, 1)");
  const bool use_validation = validation.size() > 0;
  const double count = static_cast<double>(training.targets.size());

  TrainingResult result;
  result.stop_reason = "max epochs";
  Eigen::VectorXd best = net.parameters();
  double best_validation = use_validation ? mean_squared_error(net, validation)
                                          : mean_squared_error(net, training);
  int fails = 0;
  Eigen::VectorXd velocity = Eigen::VectorXd::Zero(net.parameter_count());
  Eigen::VectorXd gradient;
  int epoch = 0;
  while (epoch < options.max_epochs) {
    const double sse = net.sse_gradient(training.inputs, training.targets, gradient);
    velocity = options.momentum * velocity -
               (1 - options.momentum) * options.learning_rate * (0.5 * gradient / count);
    net.set_parameters(net.parameters() + velocity);
    ++epoch;
    const double validation_mse =
        use_validation ? mean_squared_error(net, validation) : sse / count;
    if (!std::isfinite(validation_mse)) {
      result.stop_reason = "diverged (non-finite error)";
      break;
    }
    if (validation_mse < best_validation) {
      best_validation = validation_mse;
      best = net.parameters();
      result.best_iteration = epoch;
      fails = 0;
    } else {
      ++fails;
    }
    if (progress) progress({epoch, sse / count, validation_mse, 0.0});
    if (fails >= options.max_validation_fails) {
      result.stop_reason = "validation stopped improving";
      break;
    }
  }
  result.iterations = epoch;
  net.set_parameters(best);
  result.training_mse = mean_squared_error(net, training);
  result.validation_mse = use_validation ? mean_squared_error(net, validation) : result.training_mse;
  return result;
}

}  // namespace gcpipe::neural
