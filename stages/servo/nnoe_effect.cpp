// The `nnoe` effect: seed 003's neural output-error model, fitted by `gcpipe calibrate` on what the
// calibrated drive model leaves of a measured trace (stages/calibrate/nnoe.hpp), applied as a
// correction of the position in the simulation, so that `gcpipe batch --config calibrated.yaml`
// simulates the machine with it.
//
// It runs the same series as NnoeModel::simulate, in streaming form:
//   inputs   commanded velocity and acceleration by central differences (0 at the first sample),
//   decimate block means of D samples (the model steps every D samples, about 4 ms),
//   eq. (12) y^(t) = g(y^(t-1..t-na), v(t-1..t-nb), a(t-1..t-nb)), held at +-20 scales,
//   expand   linear between block centres back to every sample.
// Sample n needs the block after the one whose centre precedes it, hence lookahead(): the drive
// gives this effect a longer command window (the interpolated commands are known ahead; the
// output is still the machine's at tick n). tests/calibrate_nnoe_effect_test.cpp checks it
// against NnoeModel::simulate.
#include <algorithm>
#include <cmath>
#include <deque>
#include <string>

#include "gcpipe/config.hpp"
#include "mlp.hpp"
#include "servo.hpp"

namespace gcpipe::servo {

namespace {

class NnoeCorrection final : public AxisEffect {
 public:
  std::unique_ptr<AxisEffect> clone() const override { return std::make_unique<NnoeCorrection>(*this); }
  NnoeCorrection(const EffectSettings& s, const EffectContext& ctx)
      : d_(static_cast<int>(s.get("decimation", 1))),
        na_(static_cast<int>(s.get("na", 1))),
        nb_(static_cast<int>(s.get("nb", 1))),
        period_(ctx.period),
        y_scale_(s.get("y_scale", 1)),
        y_offset_(s.get("y_offset", 0)),
        u_scale_(s.list("u_scale")),
        u_offset_(s.list("u_offset")),
        net_({na_ + 2 * nb_, static_cast<int>(s.get("hidden", 1)), 1}) {
    const double trained = s.get("period", 0);
    if (std::abs(trained - ctx.period) > 1e-9 * ctx.period)
      throw ConfigError("effect nnoe: fitted on samples every " + std::to_string(trained) +
                        " s, but the pipeline interpolates every " + std::to_string(ctx.period) +
                        " s; calibrate on a trace at the pipeline's period (interpolate.period)");
    if (u_scale_.size() != 2 || u_offset_.size() != 2)
      throw ConfigError("effect nnoe: 'u_scale' and 'u_offset' need two numbers each (velocity, acceleration)");
    const auto& w = s.list("weights");
    if (static_cast<Eigen::Index>(w.size()) != net_.parameter_count())
      throw ConfigError("effect nnoe: 'weights' has " + std::to_string(w.size()) + " numbers, the structure na=" +
                        std::to_string(na_) + " nb=" + std::to_string(nb_) + " hidden=" +
                        std::to_string(net_.layer_sizes()[1]) + " needs " + std::to_string(net_.parameter_count()));
    net_.set_parameters(Eigen::Map<const Eigen::VectorXd>(w.data(), static_cast<Eigen::Index>(w.size())));
    x_.resize(static_cast<Eigen::Index>(na_ + 2 * nb_), 1);
  }

  std::string_view name() const override { return "nnoe"; }
  bool output_only() const override { return true; }
  // Sample n interpolates towards the block holding n + (D + 1) / 2, whose inputs need one
  // sample more for the central difference.
  int lookahead() const override { return d_ / 2 + 2; }

  void reset(double) override {
    cmd_.clear();
    received_ = 0;
    sum_v_ = sum_a_ = 0;
    v_dec_.clear();
    a_dec_.clear();
    y_dec_.assign(1, y_offset_);  // y^(0): before a whole regressor, the output's centre
    first_block_ = 0;
    tick_ = 0;
  }

  double correction(std::span<const double> window) override {
    ++tick_;  // window[1] is sample tick_, window[0] sample tick_ - 1
    for (std::size_t i = 0; i < window.size(); ++i)
      if (tick_ - 1 + i == received_) receive(window[i]);
    return at_sample(tick_);
  }

 private:
  // Sample k = received_ arrives; sample k - 1 gets its central difference.
  void receive(double c) {
    cmd_.push_back(c);
    if (cmd_.size() > 3) cmd_.pop_front();
    const std::size_t k = received_++;
    if (k == 0) return;
    double v = 0, a = 0;
    if (k >= 2) {
      v = (cmd_[2] - cmd_[0]) / (2 * period_);
      a = (cmd_[2] - 2 * cmd_[1] + cmd_[0]) / (period_ * period_);
    }
    sum_v_ += v, sum_a_ += a;
    if (k % static_cast<std::size_t>(d_) == 0) close_block();  // samples k - D .. k - 1 are in
  }

  void close_block() {
    v_dec_.push_back(sum_v_ / d_);
    a_dec_.push_back(sum_a_ / d_);
    sum_v_ = sum_a_ = 0;
    step_model();
    // Keep what the regressor and the interpolation can still reach.
    const auto keep = static_cast<std::size_t>(std::max(na_, nb_)) + 4;
    while (y_dec_.size() > keep) y_dec_.pop_front(), ++first_block_;
    while (v_dec_.size() > keep) v_dec_.pop_front(), a_dec_.pop_front();
  }

  // y^ of block t = first_block_ + y_dec_.size() from the blocks before it (eq. 12): the block
  // just closed is t - 1, the newest of v_dec_, a_dec_; y_dec_ ends with y^(t - 1).
  void step_model() {
    const std::size_t t = first_block_ + y_dec_.size();
    if (t < static_cast<std::size_t>(std::max(na_, nb_))) {
      y_dec_.push_back(y_offset_);
      return;
    }
    Eigen::Index j = 0;
    for (int i = 1; i <= na_; ++i) x_(j++, 0) = (y_dec_[y_dec_.size() - static_cast<std::size_t>(i)] - y_offset_) / y_scale_;
    for (int i = 1; i <= nb_; ++i) x_(j++, 0) = (v_dec_[v_dec_.size() - static_cast<std::size_t>(i)] - u_offset_[0]) / u_scale_[0];
    for (int i = 1; i <= nb_; ++i) x_(j++, 0) = (a_dec_[a_dec_.size() - static_cast<std::size_t>(i)] - u_offset_[1]) / u_scale_[1];
    const double g = net_.forward(x_)(0, 0);
    y_dec_.push_back(std::clamp(g, -20.0, 20.0) * y_scale_ + y_offset_);
  }

  // Linear between block centres (block i stands at i D + (D - 1) / 2); before the first centre,
  // the first block's value.
  double at_sample(std::size_t n) const {
    const double D = d_;
    const double q = (static_cast<double>(n) - (D - 1) / 2) / D;
    const double f = std::floor(q);
    const auto i = static_cast<std::ptrdiff_t>(f);
    return block(i) + (q - f) * (block(i + 1) - block(i));
  }

  double block(std::ptrdiff_t i) const {
    if (y_dec_.empty()) return y_offset_;
    const auto lo = static_cast<std::ptrdiff_t>(first_block_);
    const auto hi = lo + static_cast<std::ptrdiff_t>(y_dec_.size()) - 1;
    return y_dec_[static_cast<std::size_t>(std::clamp(i, lo, hi) - lo)];
  }

  int d_, na_, nb_;
  double period_, y_scale_, y_offset_;
  std::vector<double> u_scale_, u_offset_;
  neural::Mlp net_;
  Eigen::MatrixXd x_;
  std::deque<double> cmd_;             //!< the last three commands received
  std::size_t received_ = 0;           //!< commands received (samples 0 .. received_ - 1)
  double sum_v_ = 0, sum_a_ = 0;       //!< the open block's sums
  std::deque<double> v_dec_, a_dec_;   //!< decimated inputs, the newest last
  std::deque<double> y_dec_;           //!< decimated outputs from block first_block_ on
  std::size_t first_block_ = 0;
  std::size_t tick_ = 0;
};

}  // namespace

std::unique_ptr<AxisEffect> make_nnoe(const EffectSettings& s, const EffectContext& ctx) {
  return std::make_unique<NnoeCorrection>(s, ctx);
}

}  // namespace gcpipe::servo
