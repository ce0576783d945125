#include "neural_train.hpp"

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace gcpipe::neural {

namespace {

constexpr double kDeg = 180.0 / 3.14159265358979323846;

/// Joint samples and the matching model inputs/targets (physical units), one column each.
struct RawData {
  Eigen::MatrixXd inputs;
  Eigen::MatrixXd targets;   //!< position: X Y Z rows; rotary: A, then C or (sin C, cos C)
  Eigen::MatrixXd joints;    //!< rotary: A, C [deg] (to report angle errors)
};

struct Split {
  std::vector<Eigen::Index> training, validation, test;
};

Split split_indices(Eigen::Index count, const std::array<int, 2>& sizes, std::mt19937_64& rng,
                    const char* what) {
  if (sizes[0] < 1 || sizes[1] < 0 || sizes[0] + sizes[1] > count)
    throw std::invalid_argument(std::string("neural training: ") + what + " split " +
                                std::to_string(sizes[0]) + " training + " +
                                std::to_string(sizes[1]) + " validation does not fit " +
                                std::to_string(count) + " samples");
  std::vector<Eigen::Index> order(static_cast<std::size_t>(count));
  std::iota(order.begin(), order.end(), Eigen::Index{0});
  for (std::size_t i = order.size(); i > 1; --i)  // Fisher-Yates with our own index draw
    std::swap(order[i - 1], order[uniform_index(rng, i)]);
  Split s;
  s.training.assign(order.begin(), order.begin() + sizes[0]);
  s.validation.assign(order.begin() + sizes[0], order.begin() + sizes[0] + sizes[1]);
  s.test.assign(order.begin() + sizes[0] + sizes[1], order.end());
  return s;
}

Eigen::MatrixXd columns(const Eigen::MatrixXd& m, const std::vector<Eigen::Index>& idx) {
  Eigen::MatrixXd out(m.rows(), static_cast<Eigen::Index>(idx.size()));
  for (std::size_t i = 0; i < idx.size(); ++i) out.col(static_cast<Eigen::Index>(i)) = m.col(idx[i]);
  return out;
}

/// Levels evenly spaced over [lo, hi]; `closed` includes hi.
std::vector<double> levels(double lo, double hi, int count, bool closed) {
  std::vector<double> v(static_cast<std::size_t>(count));
  if (count == 1) {
    v[0] = 0.5 * (lo + hi);
    return v;
  }
  const double step = (hi - lo) / (closed ? count - 1 : count);
  for (int i = 0; i < count; ++i) v[static_cast<std::size_t>(i)] = lo + step * i;
  return v;
}

struct JointRanges {
  std::array<AxisRange, kNumAxes> position;  //!< X Y Z A C for the position nets
  AxisRange rotary_a;                        //!< A on the branch side, |A| >= min_tilt
  AxisRange rotary_c;
};

JointRanges joint_ranges(const MachineKinematics& m, const NeuralTrainingOptions& o, int branch) {
  JointRanges r;
  for (int a = 0; a < kNumAxes; ++a) r.position[a] = m.travel[a];
  // Over a full turn the position nets see C modulo 360 (NeuralIk wraps it): sample one turn.
  if (m.travel[kC].max - m.travel[kC].min >= 360.0) r.position[kC] = {-180.0, 180.0};
  for (int a = 0; a < kNumAxes; ++a)
    if (!(r.position[a].max > r.position[a].min))
      throw std::invalid_argument(std::string("neural training: travel of axis ") +
                                  kAxisLetters[a] + " is empty");
  if (branch < 0)
    r.rotary_a = {m.travel[kA].min, std::min(-o.min_tilt, m.travel[kA].max)};
  else
    r.rotary_a = {std::max(o.min_tilt, m.travel[kA].min), m.travel[kA].max};
  if (!(r.rotary_a.max > r.rotary_a.min))
    throw std::invalid_argument("neural training: no A travel left on the " +
                                std::string(branch < 0 ? "negative" : "positive") +
                                " branch beyond min_tilt " + std::to_string(o.min_tilt) + " deg");
  r.rotary_c = r.position[kC];
  return r;
}

RawData position_data(const MachineKinematics& m, const NeuralTrainingOptions& o,
                      const JointRanges& ranges, std::mt19937_64& rng) {
  std::vector<Axes> joints;
  if (o.sampling == Sampling::kGrid) {
    if (o.position_grid_levels < 2 || o.position_grid_levels > 40)
      throw std::invalid_argument("neural training: position_grid_levels " +
                                  std::to_string(o.position_grid_levels) + " outside [2, 40]");
    std::array<std::vector<double>, kNumAxes> lv;
    for (int a = 0; a < kNumAxes; ++a)
      lv[a] = levels(ranges.position[a].min, ranges.position[a].max, o.position_grid_levels, true);
    const int n = o.position_grid_levels;
    for (int i0 = 0; i0 < n; ++i0)
      for (int i1 = 0; i1 < n; ++i1)
        for (int i2 = 0; i2 < n; ++i2)
          for (int i3 = 0; i3 < n; ++i3)
            for (int i4 = 0; i4 < n; ++i4)
              joints.push_back({lv[0][i0], lv[1][i1], lv[2][i2], lv[3][i3], lv[4][i4]});
  } else {
    if (o.position_samples < 2)
      throw std::invalid_argument("neural training: position_samples " +
                                  std::to_string(o.position_samples) + " must be >= 2");
    joints.resize(static_cast<std::size_t>(o.position_samples));
    for (Axes& j : joints)
      for (int a = 0; a < kNumAxes; ++a)
        j[a] = uniform(rng, ranges.position[a].min, ranges.position[a].max);
  }
  RawData d;
  const auto n = static_cast<Eigen::Index>(joints.size());
  d.inputs.resize(5, n);
  d.targets.resize(3, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Axes& j = joints[static_cast<std::size_t>(i)];
    const ToolPose gauge = forward_kinematics(m, j, 0.0);  // tool length 0: the gauge point
    d.inputs.col(i) << gauge.tip[0], gauge.tip[1], gauge.tip[2], j[kA], j[kC];
    d.targets.col(i) << j[kX], j[kY], j[kZ];
  }
  return d;
}

RawData rotary_data(const MachineKinematics& m, const NeuralTrainingOptions& o,
                    const JointRanges& ranges, std::mt19937_64& rng) {
  std::vector<std::pair<double, double>> ac;
  if (o.sampling == Sampling::kGrid) {
    if (o.rotary_grid_levels < 2 || o.rotary_grid_levels > 1000)
      throw std::invalid_argument("neural training: rotary_grid_levels " +
                                  std::to_string(o.rotary_grid_levels) + " outside [2, 1000]");
    const auto a_levels = levels(ranges.rotary_a.min, ranges.rotary_a.max, o.rotary_grid_levels, true);
    // C over one turn without its end: C = 180 and C = -180 are one pose with two targets.
    const bool full_turn = ranges.rotary_c.max - ranges.rotary_c.min >= 360.0;
    const auto c_levels =
        levels(ranges.rotary_c.min, ranges.rotary_c.max, o.rotary_grid_levels, !full_turn);
    for (double a : a_levels)
      for (double c : c_levels) ac.emplace_back(a, c);
  } else {
    if (o.rotary_samples < 2)
      throw std::invalid_argument("neural training: rotary_samples " +
                                  std::to_string(o.rotary_samples) + " must be >= 2");
    ac.resize(static_cast<std::size_t>(o.rotary_samples));
    for (auto& [a, c] : ac) {
      a = uniform(rng, ranges.rotary_a.min, ranges.rotary_a.max);
      c = uniform(rng, ranges.rotary_c.min, ranges.rotary_c.max);
    }
  }
  RawData d;
  const auto n = static_cast<Eigen::Index>(ac.size());
  d.inputs.resize(4, n);  // rho, Ok (A net) and Oi, Oj (C net)
  d.targets.resize(o.c_output == COutput::kSinCos ? 3 : 2, n);
  d.joints.resize(2, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto [a, c] = ac[static_cast<std::size_t>(i)];
    const Vec3 axis = tool_axis(m, a, c);
    d.inputs.col(i) << std::hypot(axis[0], axis[1]), axis[2], axis[0], axis[1];
    d.joints.col(i) << a, c;
    if (o.c_output == COutput::kSinCos)
      d.targets.col(i) << a, std::sin(c / kDeg), std::cos(c / kDeg);
    else
      d.targets.col(i) << a, c;
  }
  return d;
}

/// Normalisation ranges from the training columns (what the net has seen is its envelope);
/// `fixed` rows take the nominal sampling range instead.
void set_ranges(AxisNet& net, const Eigen::MatrixXd& train_in, const Eigen::MatrixXd& train_out) {
  net.input_min = train_in.rowwise().minCoeff();
  net.input_max = train_in.rowwise().maxCoeff();
  net.output_min = train_out.rowwise().minCoeff();
  net.output_max = train_out.rowwise().maxCoeff();
}

double rms(const Eigen::ArrayXd& e) { return e.size() ? std::sqrt(e.square().mean()) : 0.0; }

}  // namespace

int training_branch_sign(const MachineKinematics& m) {
  return m.travel[kA].max >= -m.travel[kA].min ? 1 : -1;
}

NeuralTrainingOptions preset_options(std::string_view preset) {
  NeuralTrainingOptions o;
  if (preset == "paper") {
    o.preset = "paper";
    o.sampling = Sampling::kGrid;
    o.position_grid_levels = 5;          // 5^5 = 3125 points (seed 000 §5)
    o.position_split = {1042, 1043};     // §5 text: 1042 training, 1040 test, the rest validation
    o.rotary_grid_levels = 32;           // 1024 points ~ Table 5's 341 + 341 + 341
    o.rotary_split = {341, 341};
    o.c_output = COutput::kAngle;
    o.hidden = {{{25, 11}, {22, 11}, {18, 16}, {10, 14}, {6, 12}}};  // Table 5
    o.trainer = Trainer::kGradientDescent;
    return o;
  }
  if (preset == "improved") {
    o.preset = "improved";
    return o;  // the defaults of NeuralTrainingOptions are the improved preset
  }
  throw std::invalid_argument("unknown neural training preset '" + std::string(preset) +
                              "'; use 'paper' or 'improved'");
}

namespace {

/// Errors of `net` in physical units on the samples `idx` (normalised in `d`): C as a wrapped angle.
Eigen::ArrayXd physical_errors(const AxisNet& net, int axis, const NeuralTrainingOptions& o, const RawData& rot,
                               const Eigen::MatrixXd& out, const std::vector<Eigen::Index>& idx, const Dataset& d) {
  const Eigen::MatrixXd predicted = denormalise_outputs(net, net.mlp.forward(d.inputs));
  Eigen::ArrayXd err(static_cast<Eigen::Index>(idx.size()));
  for (std::size_t i = 0; i < idx.size(); ++i) {
    const auto k = static_cast<Eigen::Index>(i);
    if (axis == kC) {
      const double c_hat = o.c_output == COutput::kSinCos ? std::atan2(predicted(0, k), predicted(1, k)) * kDeg : predicted(0, k);
      err[k] = angle_difference(c_hat, rot.joints(1, idx[i]));
    } else {
      err[k] = predicted(0, k) - out(0, idx[i]);
    }
  }
  return err;
}

/// One axis's net: its data and split, sizes and scalings, training, and its errors in physical
/// units on the validation and test sets (C as a wrapped angle). Draws from `rng` in the fixed order.
AxisNet train_axis(int axis, const RawData& pos, const RawData& rot, const Split& pos_split, const Split& rot_split,
                   const JointRanges& ranges, const NeuralTrainingOptions& o, std::mt19937_64& rng,
                   const NeuralProgressCallback& progress, AxisTrainingReport& ar) {
  const auto t_axis = std::chrono::steady_clock::now();
  const std::clock_t cpu_axis = std::clock();
  const bool position = axis <= kZ;
  const RawData& raw = position ? pos : rot;
  const Split& split = position ? pos_split : rot_split;
  Eigen::MatrixXd in, out;
  if (position) {
    in = raw.inputs;
    out = raw.targets.row(axis);
  } else if (axis == kA) {
    in = raw.inputs.topRows(2);
    out = raw.targets.row(0);
  } else {
    in = raw.inputs.bottomRows(2);
    out = raw.targets.bottomRows(raw.targets.rows() - 1);
  }
  const Eigen::MatrixXd train_in = columns(in, split.training);
  const Eigen::MatrixXd train_out = columns(out, split.training);

  AxisNet net;
  std::vector<int> sizes{static_cast<int>(in.rows())};
  sizes.insert(sizes.end(), o.hidden[axis].begin(), o.hidden[axis].end());
  sizes.push_back(static_cast<int>(out.rows()));
  net.mlp = Mlp(sizes);
  net.mlp.initialise(rng);
  set_ranges(net, train_in, train_out);
  if (position && ranges.position[kC].max - ranges.position[kC].min >= 360.0) {
    // A full turn of C: the nominal range, so NeuralIk's wrap lands inside it.
    net.input_min[4] = ranges.position[kC].min;
    net.input_max[4] = ranges.position[kC].max;
  }
  if (axis == kC && o.c_output == COutput::kSinCos) {
    net.output_min.setConstant(-1.0);  // sin and cos have a known range; no data-dependent scale
    net.output_max.setConstant(1.0);
  }
  for (Eigen::Index r = 0; r < net.output_min.size(); ++r)
    if (!(net.output_max[r] > net.output_min[r]))
      throw std::invalid_argument(std::string("neural training: targets of net ") +
                                  kAxisLetters[axis] + " are constant over the training set");

  auto make = [&](const std::vector<Eigen::Index>& idx) {
    Dataset d;
    d.inputs = normalise_inputs(net, columns(in, idx));
    d.targets = normalise_outputs(net, columns(out, idx));
    return d;
  };
  const Dataset training = make(split.training);
  const Dataset validation = make(split.validation);
  const Dataset test = make(split.test);

  ProgressCallback net_progress;
  if (progress) net_progress = [&](const TrainingProgress& p) { progress(axis, p); };
  ar.training_count = static_cast<int>(split.training.size());
  ar.validation_count = static_cast<int>(split.validation.size());
  ar.test_count = static_cast<int>(split.test.size());
  if (o.trainer == Trainer::kLevenbergMarquardt)
    ar.result = train_levenberg_marquardt(net.mlp, training, validation, o.levenberg_marquardt,
                                          net_progress);
  else
    ar.result = train_gradient_descent(net.mlp, training, validation, o.gradient_descent[axis],
                                       net_progress);
  ar.test_mse = mean_squared_error(net.mlp, test);

  // Physical errors on validation and test; C as a wrapped angle.
  const Eigen::ArrayXd val_err = physical_errors(net, axis, o, rot, out, split.validation, validation);
  const Eigen::ArrayXd test_err = physical_errors(net, axis, o, rot, out, split.test, test);
  ar.validation_rms = rms(val_err);
  ar.test_rms = rms(test_err);
  ar.test_max_abs = test_err.size() ? test_err.abs().maxCoeff() : 0.0;
  if (axis == kC) {
    ar.validation_mse_angle = val_err.size() ? (val_err / 180.0).square().mean() : 0.0;
    ar.test_mse_angle = test_err.size() ? (test_err / 180.0).square().mean() : 0.0;
  }
  ar.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_axis).count();
  ar.cpu_seconds = static_cast<double>(std::clock() - cpu_axis) / CLOCKS_PER_SEC;
  return net;
}

/// End to end on fresh random joints (|A| >= min_tilt, where C is defined): rotary nets first,
/// their A and C into the position nets, exactly as NeuralIk::predict runs in the IK stage.
void evaluate_end_to_end(const NeuralIk& model, const MachineKinematics& m, const NeuralTrainingOptions& o,
                         const JointRanges& ranges, std::mt19937_64& rng, NeuralTrainingReport& rep) {
  constexpr int kEndToEnd = 5000;
  std::vector<ToolPose> poses(kEndToEnd);
  std::vector<Axes> truth(kEndToEnd);
  for (int i = 0; i < kEndToEnd; ++i) {
    Axes& j = truth[static_cast<std::size_t>(i)];
    for (int a = 0; a < kNumAxes; ++a)
      j[a] = uniform(rng, ranges.position[a].min, ranges.position[a].max);
    if (std::abs(j[kA]) < o.min_tilt) j[kA] = j[kA] < 0 ? -o.min_tilt : o.min_tilt;
    if (!m.travel[kA].contains(j[kA])) j[kA] = ranges.rotary_a.min;
    poses[static_cast<std::size_t>(i)] = forward_kinematics(m, j, 0.0);
  }
  std::vector<NeuralIkPrediction> predicted(kEndToEnd);
  model.predict(poses, 0.0, truth, predicted);
  Axes sum_sq{};
  rep.end_to_end = {};
  rep.end_to_end.count = kEndToEnd;
  for (int i = 0; i < kEndToEnd; ++i)
    for (int a = 0; a < kNumAxes; ++a) {
      const double e = predicted[static_cast<std::size_t>(i)].joints[a] - truth[static_cast<std::size_t>(i)][a];
      sum_sq[a] += e * e;
      rep.end_to_end.max_abs[a] = std::max(rep.end_to_end.max_abs[a], std::abs(e));
    }
  for (int a = 0; a < kNumAxes; ++a) rep.end_to_end.rms[a] = std::sqrt(sum_sq[a] / kEndToEnd);
  Axes linear_sq{};
  rep.position_only = {};
  rep.position_only.count = kEndToEnd;
  for (int i = 0; i < kEndToEnd; ++i) {
    const Axes& j = truth[static_cast<std::size_t>(i)];
    const NeuralIkPrediction p =
        model.predict_linear(poses[static_cast<std::size_t>(i)], 0.0, j[kA], j[kC]);
    for (int a = kX; a <= kZ; ++a) {
      const double e = p.joints[a] - j[a];
      linear_sq[a] += e * e;
      rep.position_only.max_abs[a] = std::max(rep.position_only.max_abs[a], std::abs(e));
    }
  }
  for (int a = kX; a <= kZ; ++a) rep.position_only.rms[a] = std::sqrt(linear_sq[a] / kEndToEnd);
}

}  // namespace

NeuralIk train_neural_ik(const MachineKinematics& m, const std::string& machine_name,
                         const NeuralTrainingOptions& o, NeuralTrainingReport* report,
                         const NeuralProgressCallback& progress) {
  using Clock = std::chrono::steady_clock;
  const auto t_start = Clock::now();
  const std::clock_t cpu_start = std::clock();
  NeuralTrainingReport local_report;
  NeuralTrainingReport& rep = report ? *report : local_report;
  rep = {};

  for (int a = 0; a < kNumAxes; ++a)
    for (int h : o.hidden[a])
      if (h < 1 || h > 1024)
        throw std::invalid_argument(std::string("neural training: hidden layer of net ") +
                                    kAxisLetters[a] + " has " + std::to_string(h) +
                                    " units; must be in [1, 1024]");
  if (!(o.min_tilt >= 0 && o.min_tilt < 90))
    throw std::invalid_argument("neural training: min_tilt " + std::to_string(o.min_tilt) +
                                " deg outside [0, 90)");

  std::mt19937_64 rng(o.seed);
  const int branch = training_branch_sign(m);
  const JointRanges ranges = joint_ranges(m, o, branch);

  // Data and splits first, then the nets in X Y Z A C order: the stream of draws is fixed.
  const RawData pos = position_data(m, o, ranges, rng);
  const Split pos_split = split_indices(pos.inputs.cols(), o.position_split, rng, "position");
  const RawData rot = rotary_data(m, o, ranges, rng);
  const Split rot_split = split_indices(rot.inputs.cols(), o.rotary_split, rng, "rotary");

  AxisNets nets;
  for (int axis = 0; axis < kNumAxes; ++axis)
    nets[axis] = train_axis(axis, pos, rot, pos_split, rot_split, ranges, o, rng, progress, rep.axes[axis]);

  NeuralIk model({machine_name, o.preset, o.seed}, branch, o.c_output, std::move(nets));
  evaluate_end_to_end(model, m, o, ranges, rng, rep);
  rep.seconds = std::chrono::duration<double>(Clock::now() - t_start).count();
  rep.cpu_seconds = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
  return model;
}

}  // namespace gcpipe::neural
