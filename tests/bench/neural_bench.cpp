// Neural IK throughput on one core (issue 3 item 8: at least 1 M poses/s batched, paper
// architecture). The models are trained once at start-up with a short LM run (speed does not
// depend on how well the weights fit) for the mx330 config: Table 5's layer sizes exactly, and
// the default preset's (C net 2-12-12-2).
//
// Run: build/tests/neural_bench --benchmark_min_time=2
#include <benchmark/benchmark.h>

#include <optional>
#include <vector>

#include "gcpipe/config.hpp"
#include "gcpipe/kinematics.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "mlp.hpp"
#include "neural_ik.hpp"
#include "neural_train.hpp"

namespace {

using gcpipe::Axes;
using gcpipe::ToolPose;
using namespace gcpipe::neural;

struct Fixture {
  gcpipe::MachineKinematics kinematics;
  std::optional<NeuralIk> model;
  std::vector<ToolPose> poses;
  std::vector<Axes> joints;
};

Fixture make_fixture(bool paper_architecture) {
  Fixture out;
  const auto pc = gcpipe::load_pipeline_config(std::string(GCPIPE_SOURCE_DIR) +
                                               "/pipeline_configs/default.yaml");
  out.kinematics = gcpipe::load_kinematics(pc.machine_section);
  NeuralTrainingOptions o = preset_options("improved");
  if (paper_architecture) {  // Table 5 exactly: C net 2-6-12-1 with an angle output
    o.hidden = preset_options("paper").hidden;
    o.c_output = COutput::kAngle;
  }
  {
    o.position_samples = 600;
    o.position_split = {400, 100};
    o.rotary_samples = 300;
    o.rotary_split = {200, 50};
    o.levenberg_marquardt.max_iterations = 3;
    out.model.emplace(train_neural_ik(out.kinematics, pc.machine.name, o));
    std::mt19937_64 rng(7);
    for (int i = 0; i < 65536; ++i) {
      Axes j;
      for (int a = 0; a < gcpipe::kNumAxes; ++a)
        j[a] = uniform(rng, out.kinematics.travel[a].min, out.kinematics.travel[a].max);
      j[gcpipe::kC] = uniform(rng, -180, 180);
      out.joints.push_back(j);
      out.poses.push_back(gcpipe::forward_kinematics(out.kinematics, j, 0.0));
    }
  }
  return out;
}

const Fixture& fixture() {
  static const Fixture f = make_fixture(true);
  return f;
}

const Fixture& improved_fixture() {
  static const Fixture f = make_fixture(false);
  return f;
}

// All five nets per pose, batched: what the IK stage calls per batch of resolved points.
void run_batched(benchmark::State& state, const Fixture& f) {
  const auto batch = static_cast<std::size_t>(state.range(0));
  std::vector<NeuralIkPrediction> out(batch);
  std::size_t offset = 0;
  for (auto _ : state) {
    if (offset + batch > f.poses.size()) offset = 0;
    f.model->predict(std::span(f.poses).subspan(offset, batch), 100.0,
                     std::span(f.joints).subspan(offset, batch), out);
    benchmark::DoNotOptimize(out.data());
    offset += batch;
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * batch));
  state.counters["poses/s"] =
      benchmark::Counter(static_cast<double>(state.iterations() * batch), benchmark::Counter::kIsRate);
}
void BM_NeuralIkBatched(benchmark::State& state) { run_batched(state, fixture()); }
BENCHMARK(BM_NeuralIkBatched)->Arg(1)->Arg(64)->Arg(1024)->Arg(16384);

// The default (improved) preset's model: C net 2-12-12-2.
void BM_NeuralIkBatchedImproved(benchmark::State& state) {
  run_batched(state, improved_fixture());
}
BENCHMARK(BM_NeuralIkBatchedImproved)->Arg(1)->Arg(1024);

// One X net (5-25-11-1) alone on normalised inputs: the cost of the paper's largest net, in the
// float inference copy predict() uses and in the double training path.
void BM_MlpInference_5_25_11_1(benchmark::State& state) {
  const Fixture& f = fixture();
  const MlpInference net(f.model->nets()[gcpipe::kX].mlp);
  const auto batch = static_cast<std::size_t>(state.range(0));
  std::mt19937_64 rng(3);
  std::vector<float> x(5 * batch), y;
  for (float& v : x) v = static_cast<float>(uniform(rng, -1, 1));
  MlpInference::Workspace workspace;
  for (auto _ : state) {
    net.forward(x.data(), batch, y, workspace);
    benchmark::DoNotOptimize(y.data());
  }
  state.counters["samples/s"] = benchmark::Counter(
      static_cast<double>(state.iterations() * batch), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_MlpInference_5_25_11_1)->Arg(256)->Arg(4096);

void BM_MlpForwardDouble_5_25_11_1(benchmark::State& state) {
  const Fixture& f = fixture();
  const Mlp& net = f.model->nets()[gcpipe::kX].mlp;
  const Eigen::Index batch = state.range(0);
  std::mt19937_64 rng(3);
  Eigen::MatrixXd x(5, batch);
  for (Eigen::Index i = 0; i < x.size(); ++i) x.data()[i] = uniform(rng, -1, 1);
  Eigen::MatrixXd y;
  MlpWorkspace workspace;
  for (auto _ : state) {
    net.forward(x, y, workspace);
    benchmark::DoNotOptimize(y.data());
  }
  state.counters["samples/s"] = benchmark::Counter(
      static_cast<double>(state.iterations() * batch), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_MlpForwardDouble_5_25_11_1)->Arg(256);

// The analytic reference on the same poses, for scale.
void BM_AnalyticIk(benchmark::State& state) {
  const Fixture& f = fixture();
  std::size_t i = 0;
  for (auto _ : state) {
    const auto r = gcpipe::inverse_kinematics(f.kinematics, f.poses[i], f.joints[i], 0.0);
    benchmark::DoNotOptimize(r);
    i = (i + 1) % f.poses.size();
  }
  state.counters["poses/s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_AnalyticIk);

}  // namespace

BENCHMARK_MAIN();
