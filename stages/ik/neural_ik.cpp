#include "neural_ik.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace gcpipe::neural {

namespace {

constexpr double kDeg = 180.0 / 3.14159265358979323846;
constexpr const char* kNetNames[kNumAxes] = {"X", "Y", "Z", "A", "C"};
constexpr int kPositionInputs = 5;  // gauge point Px Py Pz, A, C
constexpr int kRotaryInputs = 2;
constexpr int kCInput = 4;          // index of C among the position-net inputs

/// Largest batch evaluated at once: keeps every activation matrix in L1/L2 cache.
constexpr std::size_t kChunk = 256;

int expected_inputs(int axis) { return axis <= kZ ? kPositionInputs : kRotaryInputs; }

int expected_outputs(int axis, COutput c_output) {
  return (axis == kC && c_output == COutput::kSinCos) ? 2 : 1;
}

/// Position nets see C modulo one turn when they were trained on a full turn: X, Y, Z depend on
/// C only through sin C and cos C, so wrapping is exact and an unwrapped C (-399.8 deg in the
/// impeller demo) stays inside the envelope.
bool c_input_is_periodic(const AxisNet& net) {
  return net.input_max[kCInput] - net.input_min[kCInput] >= 360.0 - 1e-9;
}

double wrap_into(double c, double lo) { return c - 360.0 * std::floor((c - lo) / 360.0); }

/// Bit set when a column of x lies outside [min, max] of the net (relative slack 1e-9 of the
/// range so that the training extremes themselves count as inside).
bool outside(const AxisNet& net, const Eigen::Ref<const Eigen::VectorXd>& x) {
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    const double slack = 1e-9 * (net.input_max[i] - net.input_min[i]);
    if (!(x[i] >= net.input_min[i] - slack && x[i] <= net.input_max[i] + slack)) return true;
  }
  return false;
}

void append_number(std::string& out, double v) {
  char buffer[32];
  const auto r = std::to_chars(buffer, buffer + sizeof buffer, v);  // shortest round trip
  out.append(buffer, r.ptr);
}

void append_vector(std::string& out, const char* key, const Eigen::VectorXd& v) {
  out += key;
  for (Eigen::Index i = 0; i < v.size(); ++i) {
    out += ' ';
    append_number(out, v[i]);
  }
  out += '\n';
}

/// Tokenising reader over the model text that remembers line numbers for messages.
class ModelReader {
 public:
  ModelReader(std::string_view text, std::string source) : source_(std::move(source)) {
    std::size_t start = 0;
    while (start <= text.size()) {
      std::size_t end = text.find('\n', start);
      if (end == std::string_view::npos) end = text.size();
      std::string_view line = text.substr(start, end - start);
      if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
      lines_.push_back(line);
      start = end + 1;
    }
  }

  [[noreturn]] void fail(const std::string& reason) const {
    throw std::runtime_error(source_ + ":" + std::to_string(line_ + 1) + ": " + reason);
  }

  /// Tokens of the next non-empty line.
  std::vector<std::string_view> next_line() {
    while (true) {
      if (next_ >= lines_.size()) {
        line_ = lines_.size() - 1;
        fail("unexpected end of model file");
      }
      line_ = next_++;
      std::vector<std::string_view> tokens;
      std::string_view l = lines_[line_];
      std::size_t i = 0;
      while (i < l.size()) {
        while (i < l.size() && (l[i] == ' ' || l[i] == '\t')) ++i;
        std::size_t j = i;
        while (j < l.size() && l[j] != ' ' && l[j] != '\t') ++j;
        if (j > i) tokens.push_back(l.substr(i, j - i));
        i = j;
      }
      if (!tokens.empty()) return tokens;
    }
  }

  /// Next line must be `key value...`; returns the values.
  std::vector<std::string_view> keyed(std::string_view key) {
    auto tokens = next_line();
    if (tokens.front() != key)
      fail("expected '" + std::string(key) + "', found '" + std::string(tokens.front()) + "'");
    tokens.erase(tokens.begin());
    return tokens;
  }

  std::string single(std::string_view key) {
    const auto values = keyed(key);
    if (values.size() != 1)
      fail("'" + std::string(key) + "' takes one value, found " + std::to_string(values.size()));
    return std::string(values.front());
  }

  double number(std::string_view token, const std::string& what) const {
    double v = 0;
    const auto r = std::from_chars(token.data(), token.data() + token.size(), v);
    if (r.ec != std::errc() || r.ptr != token.data() + token.size())
      fail(what + ": '" + std::string(token) + "' is not a number");
    if (!std::isfinite(v)) fail(what + " is " + std::string(token) + "; must be finite");
    return v;
  }

  std::int64_t integer(std::string_view token, const std::string& what) const {
    std::int64_t v = 0;
    const auto r = std::from_chars(token.data(), token.data() + token.size(), v);
    if (r.ec != std::errc() || r.ptr != token.data() + token.size())
      fail(what + ": '" + std::string(token) + "' is not an integer");
    return v;
  }

  Eigen::VectorXd vector(std::string_view key, Eigen::Index expected, const std::string& net) {
    const auto values = keyed(key);
    if (static_cast<Eigen::Index>(values.size()) != expected)
      fail("net " + net + ": '" + std::string(key) + "' has " + std::to_string(values.size()) +
           " values, the layer sizes need " + std::to_string(expected));
    Eigen::VectorXd v(expected);
    for (Eigen::Index i = 0; i < expected; ++i)
      v[i] = number(values[i], "net " + net + " " + std::string(key) + "[" + std::to_string(i) + "]");
    return v;
  }

  /// `count` numbers spread over as many lines as they take.
  Eigen::VectorXd numbers(Eigen::Index count, const std::string& what) {
    Eigen::VectorXd v(count);
    Eigen::Index filled = 0;
    while (filled < count) {
      const auto tokens = next_line();
      for (const auto& t : tokens) {
        if (filled == count)
          fail(what + ": more than the " + std::to_string(count) + " values announced");
        v[filled] = number(t, what + "[" + std::to_string(filled) + "]");
        ++filled;
      }
    }
    return v;
  }

  bool at_end() {
    for (std::size_t i = next_; i < lines_.size(); ++i)
      if (lines_[i].find_first_not_of(" \t") != std::string_view::npos) {
        line_ = i;
        return false;
      }
    return true;
  }

 private:
  std::string source_;
  std::vector<std::string_view> lines_;
  std::size_t next_ = 0;
  std::size_t line_ = 0;
};

}  // namespace

double unwrap_near(double angle, double reference) {
  return angle + 360.0 * std::round((reference - angle) / 360.0);
}

double angle_difference(double a, double b) {
  const double d = std::fmod(a - b + 180.0, 360.0);
  return (d < 0 ? d + 360.0 : d) - 180.0;
}

Eigen::MatrixXd normalise_inputs(const AxisNet& net, const Eigen::Ref<const Eigen::MatrixXd>& x) {
  const Eigen::ArrayXd scale = 2.0 / (net.input_max - net.input_min).array();
  return ((x.colwise() - net.input_min).array().colwise() * scale - 1.0).matrix();
}

Eigen::MatrixXd normalise_outputs(const AxisNet& net, const Eigen::Ref<const Eigen::MatrixXd>& y) {
  const Eigen::ArrayXd scale = 2.0 / (net.output_max - net.output_min).array();
  return ((y.colwise() - net.output_min).array().colwise() * scale - 1.0).matrix();
}

Eigen::MatrixXd denormalise_outputs(const AxisNet& net,
                                    const Eigen::Ref<const Eigen::MatrixXd>& y_normalised) {
  const Eigen::ArrayXd half_range = 0.5 * (net.output_max - net.output_min).array();
  return (((y_normalised.array() + 1.0).colwise() * half_range).matrix().colwise() +
          net.output_min);
}

NeuralIk::NeuralIk(ModelProvenance provenance, int branch_sign, COutput c_output, AxisNets nets)
    : provenance_(std::move(provenance)),
      branch_sign_(branch_sign),
      c_output_(c_output),
      nets_(std::move(nets)) {
  for (const std::string* word : {&provenance_.machine, &provenance_.preset})
    if (word->empty() || word->find_first_of(" \t\r\n") != std::string::npos)
      throw std::invalid_argument("neural IK model: machine and preset names must be single "
                                  "words, got '" + *word + "'");
  if (branch_sign_ != 1 && branch_sign_ != -1)
    throw std::invalid_argument("neural IK model: branch_sign is " + std::to_string(branch_sign_) +
                                "; must be +1 or -1");
  for (int axis = 0; axis < kNumAxes; ++axis) {
    const AxisNet& net = nets_[axis];
    const std::string name = std::string("neural IK model: net ") + kNetNames[axis];
    const int inputs = expected_inputs(axis);
    const int outputs = expected_outputs(axis, c_output_);
    if (net.mlp.layer_sizes().empty())
      throw std::invalid_argument(name + " has no layers");
    if (net.mlp.input_size() != inputs || net.mlp.output_size() != outputs)
      throw std::invalid_argument(name + " maps " + std::to_string(net.mlp.input_size()) + " -> " +
                                  std::to_string(net.mlp.output_size()) + " values; expected " +
                                  std::to_string(inputs) + " -> " + std::to_string(outputs));
    if (!net.mlp.parameters().allFinite())
      throw std::invalid_argument(name + " has NaN or infinite weights");
    auto check_range = [&](const Eigen::VectorXd& lo, const Eigen::VectorXd& hi, int n,
                           const char* what) {
      if (lo.size() != n || hi.size() != n)
        throw std::invalid_argument(name + ": " + what + " range has " + std::to_string(lo.size()) +
                                    "/" + std::to_string(hi.size()) + " entries; expected " +
                                    std::to_string(n));
      for (int i = 0; i < n; ++i)
        if (!(std::isfinite(lo[i]) && std::isfinite(hi[i]) && lo[i] < hi[i]))
          throw std::invalid_argument(name + ": " + what + " " + std::to_string(i) + " range [" +
                                      std::to_string(lo[i]) + ", " + std::to_string(hi[i]) +
                                      "] is empty or not finite");
    };
    check_range(net.input_min, net.input_max, inputs, "input");
    check_range(net.output_min, net.output_max, outputs, "output");
    inference_[axis] = MlpInference(net.mlp);
  }
}

std::string NeuralIk::serialise() const {
  std::string out;
  out += kModelFormat;
  out += '\n';
  out += "machine " + provenance_.machine + '\n';
  out += "preset " + provenance_.preset + '\n';
  out += "seed " + std::to_string(provenance_.seed) + '\n';
  out += "branch_sign " + std::to_string(branch_sign_) + '\n';
  out += std::string("c_output ") + (c_output_ == COutput::kSinCos ? "sincos" : "angle") + '\n';
  for (int axis = 0; axis < kNumAxes; ++axis) {
    const AxisNet& net = nets_[axis];
    out += std::string("net ") + kNetNames[axis] + '\n';
    out += "layers";
    for (int s : net.mlp.layer_sizes()) out += ' ' + std::to_string(s);
    out += '\n';
    append_vector(out, "input_min", net.input_min);
    append_vector(out, "input_max", net.input_max);
    append_vector(out, "output_min", net.output_min);
    append_vector(out, "output_max", net.output_max);
    const Eigen::VectorXd& theta = net.mlp.parameters();
    out += "parameters " + std::to_string(theta.size()) + '\n';
    for (Eigen::Index i = 0; i < theta.size(); ++i) {
      append_number(out, theta[i]);
      out += (i % 8 == 7 || i + 1 == theta.size()) ? '\n' : ' ';
    }
    out += "end\n";
  }
  return out;
}

void NeuralIk::save(const std::filesystem::path& path) const {
  const std::string text = serialise();
  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  if (!file) throw std::runtime_error("cannot open model file '" + path.string() + "' for writing");
  file.write(text.data(), static_cast<std::streamsize>(text.size()));
  file.close();
  if (!file) throw std::runtime_error("cannot write model file '" + path.string() + "'");
}

NeuralIk NeuralIk::load(const std::filesystem::path& path) {
  std::ifstream file(path, std::ios::binary);
  if (!file) throw std::runtime_error("cannot open neural IK model '" + path.string() + "'");
  std::ostringstream text;
  text << file.rdbuf();
  return parse(text.str(), path.string());
}

NeuralIk NeuralIk::parse(std::string_view text, const std::string& source) {
  ModelReader reader(text, source);
  const auto header = reader.next_line();
  const std::string_view magic = kModelFormat.substr(0, kModelFormat.find(' '));
  if (header.size() != 2 || header[0] != magic)
    reader.fail("not a gcpipe neural IK model (first line must be '" + std::string(kModelFormat) +
                "')");
  if (header[1] != kModelFormat.substr(kModelFormat.find(' ') + 1))
    reader.fail("unsupported model version '" + std::string(header[1]) + "'; this build reads '" +
                std::string(kModelFormat) + "'");

  ModelProvenance provenance;
  provenance.machine = reader.single("machine");
  provenance.preset = reader.single("preset");
  const std::int64_t seed = reader.integer(reader.single("seed"), "seed");
  if (seed < 0) reader.fail("seed is " + std::to_string(seed) + "; must be >= 0");
  provenance.seed = static_cast<std::uint64_t>(seed);
  const std::int64_t branch = reader.integer(reader.single("branch_sign"), "branch_sign");
  if (branch != 1 && branch != -1)
    reader.fail("branch_sign is " + std::to_string(branch) + "; must be 1 or -1");
  const std::string c_text = reader.single("c_output");
  if (c_text != "angle" && c_text != "sincos")
    reader.fail("c_output is '" + c_text + "'; must be 'angle' or 'sincos'");
  const COutput c_output = c_text == "sincos" ? COutput::kSinCos : COutput::kAngle;

  AxisNets nets;
  for (int axis = 0; axis < kNumAxes; ++axis) {
    const std::string name = kNetNames[axis];
    const std::string found = reader.single("net");
    if (found != name) reader.fail("expected net " + name + ", found net '" + found + "'");
    const auto size_tokens = reader.keyed("layers");
    std::vector<int> sizes;
    for (const auto& t : size_tokens) {
      const std::int64_t s = reader.integer(t, "net " + name + " layer size");
      if (s < 1 || s > 4096)
        reader.fail("net " + name + ": layer size " + std::to_string(s) + " outside [1, 4096]");
      sizes.push_back(static_cast<int>(s));
    }
    if (sizes.size() < 2) reader.fail("net " + name + ": needs at least two layer sizes");
    const int inputs = expected_inputs(axis);
    const int outputs = expected_outputs(axis, c_output);
    if (sizes.front() != inputs || sizes.back() != outputs)
      reader.fail("net " + name + " maps " + std::to_string(sizes.front()) + " -> " +
                  std::to_string(sizes.back()) + " values; a " + name + " net must map " +
                  std::to_string(inputs) + " -> " + std::to_string(outputs) + " (c_output " +
                  c_text + ")");
    AxisNet& net = nets[axis];
    net.mlp = Mlp(sizes);
    net.input_min = reader.vector("input_min", inputs, name);
    net.input_max = reader.vector("input_max", inputs, name);
    net.output_min = reader.vector("output_min", outputs, name);
    net.output_max = reader.vector("output_max", outputs, name);
    for (int i = 0; i < inputs; ++i)
      if (!(net.input_min[i] < net.input_max[i]))
        reader.fail("net " + name + ": input " + std::to_string(i) + " range is empty");
    for (int i = 0; i < outputs; ++i)
      if (!(net.output_min[i] < net.output_max[i]))
        reader.fail("net " + name + ": output " + std::to_string(i) + " range is empty");
    const std::int64_t count = reader.integer(reader.single("parameters"), "parameter count");
    if (count != net.mlp.parameter_count())
      reader.fail("net " + name + ": " + std::to_string(count) + " parameters announced, layers " +
                  "need " + std::to_string(net.mlp.parameter_count()));
    net.mlp.set_parameters(reader.numbers(count, "net " + name + " parameter"));
    const auto end = reader.next_line();
    if (end.size() != 1 || end[0] != "end")
      reader.fail("net " + name + ": expected 'end' after " + std::to_string(count) +
                  " parameters, found '" + std::string(end[0]) + "'");
  }
  if (!reader.at_end()) reader.fail("unexpected text after the last net");
  return NeuralIk(std::move(provenance), static_cast<int>(branch), c_output, std::move(nets));
}

NeuralIkPrediction NeuralIk::predict(const ToolPose& pose, double tool_length,
                                     const Axes& reference) const {
  NeuralIkPrediction out;
  predict_block({&pose, 1}, tool_length, {&reference, 1}, {&out, 1});
  return out;
}

void NeuralIk::predict(std::span<const ToolPose> poses, double tool_length,
                       std::span<const Axes> references, std::span<NeuralIkPrediction> out) const {
  if (out.size() != poses.size() || (references.size() != poses.size() && references.size() != 1))
    throw std::invalid_argument("NeuralIk::predict: " + std::to_string(poses.size()) + " poses, " +
                                std::to_string(references.size()) + " references, " +
                                std::to_string(out.size()) +
                                " outputs; references must be 1 or one per pose");
  for (std::size_t start = 0; start < poses.size(); start += kChunk) {
    const std::size_t n = std::min(kChunk, poses.size() - start);
    predict_block(poses.subspan(start, n), tool_length,
                  references.size() == 1 ? references : references.subspan(start, n),
                  out.subspan(start, n));
  }
}

namespace {

/// Physical inputs (double, one sample per column) -> normalised float inputs of one net in the
/// feature-major layout of MlpInference.
void normalise_into(const AxisNet& net, const Eigen::Ref<const Eigen::MatrixXd>& x,
                    std::vector<float>& out) {
  const std::size_t n = static_cast<std::size_t>(x.cols());
  out.resize(static_cast<std::size_t>(x.rows()) * n);
  for (Eigen::Index j = 0; j < x.rows(); ++j) {
    const double lo = net.input_min[j];
    const double scale = 2.0 / (net.input_max[j] - lo);
    float* row = out.data() + static_cast<std::size_t>(j) * n;
    for (std::size_t s = 0; s < n; ++s)
      row[s] = static_cast<float>((x(j, static_cast<Eigen::Index>(s)) - lo) * scale - 1.0);
  }
}

/// Normalised float output `row` of sample `i` (batch of n) -> physical value.
double denormalise(const AxisNet& net, const std::vector<float>& y, Eigen::Index row,
                   Eigen::Index i, Eigen::Index n) {
  return net.output_min[row] + 0.5 * (static_cast<double>(y[static_cast<std::size_t>(row * n + i)]) + 1.0) *
                                   (net.output_max[row] - net.output_min[row]);
}

// The rotary nets' inputs of every pose (A: the axis' tilt as (|xy|, z); C: its (x, y)) and the
// unit tool axis; a pose that is not finite is marked so, with +Z in its place to keep the batch
// finite (its result is discarded).
void fill_rotary_inputs(std::span<const ToolPose> poses, double tool_length, Eigen::MatrixXd& a_in,
                        Eigen::MatrixXd& c_in, Eigen::Matrix3Xd& unit_axis, std::span<NeuralIkPrediction> out) {
  for (Eigen::Index i = 0; i < static_cast<Eigen::Index>(poses.size()); ++i) {
    const ToolPose& pose = poses[i];
    Eigen::Vector3d axis(pose.axis[0], pose.axis[1], pose.axis[2]);
    const double norm = axis.norm();
    const bool ok = std::isfinite(norm) && norm > 1e-12 && std::isfinite(pose.tip[0]) &&
                    std::isfinite(pose.tip[1]) && std::isfinite(pose.tip[2]) &&
                    std::isfinite(tool_length);
    out[i] = NeuralIkPrediction{};
    out[i].finite = ok;
    if (!ok) axis = Eigen::Vector3d::UnitZ();
    else axis /= norm;
    unit_axis.col(i) = axis;
    a_in(0, i) = std::hypot(axis.x(), axis.y());
    a_in(1, i) = axis.z();
    c_in(0, i) = axis.x();
    c_in(1, i) = axis.y();
  }
}

// Which nets were asked outside the box they were trained on, per prediction.
void flag_envelope(const AxisNets& nets, const Eigen::MatrixXd& a_in, const Eigen::MatrixXd& c_in,
                   const Eigen::MatrixXd& p_in, std::span<NeuralIkPrediction> out) {
  for (Eigen::Index i = 0; i < a_in.cols(); ++i) {  // the batch's poses
    NeuralIkPrediction& r = out[i];
    EnvelopeBits bits = 0;
    for (int axis = kX; axis <= kZ; ++axis)
      if (outside(nets[axis], p_in.col(i))) bits |= 1u << axis;
    if (outside(nets[kA], a_in.col(i))) bits |= 1u << kA;
    // Below the smallest trained tilt C is (nearly) undefined, whatever the (Oi, Oj) box says.
    if (outside(nets[kC], c_in.col(i)) || a_in(0, i) < nets[kA].input_min[0]) bits |= 1u << kC;
    r.outside_envelope = bits;
    for (double v : r.joints) r.finite = r.finite && std::isfinite(v);
  }
}

}  // namespace

void NeuralIk::predict_block(std::span<const ToolPose> poses, double tool_length,
                             std::span<const Axes> references,
                             std::span<NeuralIkPrediction> out) const {
  const Eigen::Index n = static_cast<Eigen::Index>(poses.size());
  // Per-thread buffers: the IK stage predicts one point at a time, and a dozen allocations per
  // call would cost more than the five nets.
  struct Buffers {
    Eigen::MatrixXd a_in, c_in, p_in;
    Eigen::Matrix3Xd unit_axis;
    MlpInference::Workspace workspace;
    std::vector<float> xf, a_y, c_y, y;
  };
  thread_local Buffers buffers;
  Eigen::MatrixXd& a_in = buffers.a_in;
  Eigen::MatrixXd& c_in = buffers.c_in;
  Eigen::MatrixXd& p_in = buffers.p_in;
  Eigen::Matrix3Xd& unit_axis = buffers.unit_axis;
  a_in.resize(kRotaryInputs, n);
  c_in.resize(kRotaryInputs, n);
  p_in.resize(kPositionInputs, n);
  unit_axis.resize(3, n);
  MlpInference::Workspace& workspace = buffers.workspace;
  std::vector<float>& xf = buffers.xf;
  std::vector<float>& a_y = buffers.a_y;
  std::vector<float>& c_y = buffers.c_y;
  std::vector<float>& y = buffers.y;

  fill_rotary_inputs(poses, tool_length, a_in, c_in, unit_axis, out);

  const AxisNet& a_net = nets_[kA];
  const AxisNet& c_net = nets_[kC];
  normalise_into(a_net, a_in, xf);
  inference_[kA].forward(xf.data(), poses.size(), a_y, workspace);
  normalise_into(c_net, c_in, xf);
  inference_[kC].forward(xf.data(), poses.size(), c_y, workspace);

  const AxisNet& x_net = nets_[kX];
  const bool periodic = c_input_is_periodic(x_net);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Axes& reference = references.size() == 1 ? references[0] : references[i];
    double a = denormalise(a_net, a_y, 0, i, n);
    double c = c_output_ == COutput::kSinCos
                   ? std::atan2(denormalise(c_net, c_y, 0, i, n), denormalise(c_net, c_y, 1, i, n)) *
                         kDeg
                   : denormalise(c_net, c_y, 0, i, n);
    if (branch_sign_ * reference[kA] < 0) {  // the caller is on the other branch
      a = -a;
      c += 180.0;
    }
    c = unwrap_near(c, reference[kC]);
    out[i].joints[kA] = a;
    out[i].joints[kC] = c;
    for (int k = 0; k < 3; ++k)
      p_in(k, i) = poses[i].tip[k] + tool_length * unit_axis(k, i);
    p_in(3, i) = a;
    p_in(kCInput, i) = periodic ? wrap_into(c, x_net.input_min[kCInput]) : c;
  }

  for (int axis = kX; axis <= kZ; ++axis) {
    const AxisNet& net = nets_[axis];
    normalise_into(net, p_in, xf);
    inference_[axis].forward(xf.data(), poses.size(), y, workspace);
    for (Eigen::Index i = 0; i < n; ++i) out[i].joints[axis] = denormalise(net, y, 0, i, n);
  }

  flag_envelope(nets_, a_in, c_in, p_in, out);
}

NeuralIkPrediction NeuralIk::predict_linear(const ToolPose& pose, double tool_length, double a_deg,
                                            double c_deg) const {
  NeuralIkPrediction out;
  const Eigen::Vector3d axis(pose.axis[0], pose.axis[1], pose.axis[2]);
  const double norm = axis.norm();
  out.finite = std::isfinite(norm) && norm > 1e-12 && std::isfinite(tool_length) &&
               std::isfinite(a_deg) && std::isfinite(c_deg) && std::isfinite(pose.tip[0]) &&
               std::isfinite(pose.tip[1]) && std::isfinite(pose.tip[2]);
  if (!out.finite) return out;
  const AxisNet& x_net = nets_[kX];
  Eigen::Matrix<double, kPositionInputs, 1> p;
  for (int k = 0; k < 3; ++k) p[k] = pose.tip[k] + tool_length * axis[k] / norm;
  p[3] = a_deg;
  p[kCInput] = c_input_is_periodic(x_net) ? wrap_into(c_deg, x_net.input_min[kCInput]) : c_deg;
  thread_local MlpInference::Workspace workspace;
  thread_local std::vector<float> xf, y;
  for (int a = kX; a <= kZ; ++a) {
    const AxisNet& net = nets_[a];
    normalise_into(net, p, xf);
    inference_[a].forward(xf.data(), 1, y, workspace);
    out.joints[a] = denormalise(net, y, 0, 0, 1);
    if (outside(net, p)) out.outside_envelope |= 1u << a;
    out.finite = out.finite && std::isfinite(out.joints[a]);
  }
  out.joints[kA] = a_deg;
  out.joints[kC] = c_deg;
  return out;
}

}  // namespace gcpipe::neural
