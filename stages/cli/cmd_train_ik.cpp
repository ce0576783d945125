// gcpipe train-ik: trains the neural IK model (stages/ik/neural_train.hpp) for the configured
// machine and writes the versioned model file. Deterministic for a seed.
#include <cinttypes>
#include <cstdio>
#include <iostream>
#include <string>

#include "commands.hpp"
#include "gcpipe/config.hpp"
#include "gcpipe/kinematics.hpp"
#include "neural_train.hpp"
#include "program_stream.hpp"

namespace gcpipe::cli {
namespace {

// The preset named, with the command line's changes (which make it a "custom" one).
neural::NeuralTrainingOptions training_options(const TrainIkArgs& args) {
  neural::NeuralTrainingOptions options = neural::preset_options(args.preset);
  options.seed = args.seed;
  if (args.samples != 0) {
    // Random sampling; 2/3 training, 1/6 validation, 1/6 test for both data sets.
    const int n = args.samples;
    options.sampling = neural::Sampling::kRandom;
    options.position_samples = n;
    options.position_split = {2 * n / 3, n / 6};
    options.rotary_samples = n / 2;
    options.rotary_split = {n / 3, n / 12};
    options.preset = "custom";
  }
  if (args.max_iterations != 0) {
    options.levenberg_marquardt.max_iterations = args.max_iterations;
    for (auto& gd : options.gradient_descent) gd.max_epochs = args.max_iterations;
    options.preset = "custom";
  }
  if (!args.trainer.empty()) {
    options.trainer = args.trainer == "lm" ? neural::Trainer::kLevenbergMarquardt : neural::Trainer::kGradientDescent;
    options.preset = "custom";
  }
  if (!args.c_output.empty()) {
    options.c_output = args.c_output == "angle" ? neural::COutput::kAngle : neural::COutput::kSinCos;
    options.preset = "custom";
  }
  return options;
}

// The summary on stdout: a Markdown table, pasted into stages/ik/README.md.
void print_training_table(const neural::NeuralIk& model, const neural::NeuralTrainingReport& report,
                          const std::string& output) {
  std::printf("| net | layers | train/val/test | iterations | stop | MSE val | MSE test | "
              "RMS val | RMS test | max test | CPU [s] |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (int a = 0; a < kNumAxes; ++a) {
    const auto& r = report.axes[a];
    std::string layers;
    for (int s : model.nets()[a].mlp.layer_sizes())
      layers += (layers.empty() ? "" : "-") + std::to_string(s);
    const char* unit = a <= kZ ? "mm" : "deg";
    std::printf("| %c | %s | %d/%d/%d | %d | %s | %.3e | %.3e | %.4g %s | %.4g %s | %.4g %s | %.1f |\n",
                kAxisLetters[a], layers.c_str(), r.training_count, r.validation_count, r.test_count,
                r.result.iterations, r.result.stop_reason.c_str(), r.result.validation_mse,
                r.test_mse, r.validation_rms, unit, r.test_rms, unit, r.test_max_abs, unit,
                r.cpu_seconds);
  }
  const auto& c = report.axes[kC];
  std::printf("\nC as a wrapped angle, normalised by 180 deg: MSE val %.3e, MSE test %.3e\n",
              c.validation_mse_angle, c.test_mse_angle);
  std::printf("end to end (%d random poses, rotary nets feed the position nets): RMS", 
              report.end_to_end.count);
  for (int a = 0; a < kNumAxes; ++a)
    std::printf(" %c %.4g", kAxisLetters[a], report.end_to_end.rms[a]);
  std::printf("; max");
  for (int a = 0; a < kNumAxes; ++a)
    std::printf(" %c %.4g", kAxisLetters[a], report.end_to_end.max_abs[a]);
  std::printf(" [mm, deg]\nposition nets alone, exact A and C, same poses: RMS");
  for (int a = kX; a <= kZ; ++a)
    std::printf(" %c %.4g", kAxisLetters[a], report.position_only.rms[a]);
  std::printf("; max");
  for (int a = kX; a <= kZ; ++a)
    std::printf(" %c %.4g", kAxisLetters[a], report.position_only.max_abs[a]);
  std::printf(" [mm]\ntraining time %.1f s CPU (%.1f s wall); model written to %s\n",
              report.cpu_seconds, report.seconds, output.c_str());
}

}  // namespace

int run_train_ik(const TrainIkArgs& args) {
  const neural::NeuralTrainingOptions options = training_options(args);
  const auto output = std::optional<std::string>(args.output);
  const PipelineConfig pc = load_config_option(args.config);
  const MachineKinematics kinematics = load_kinematics(pc.machine_section);
  const bool quiet = args.quiet;
  neural::NeuralProgressCallback progress;
  if (!quiet)
    progress = [](int axis, const neural::TrainingProgress& p) {
      if (p.iteration % 10 == 0 || p.iteration == 1)
        std::fprintf(stderr, "  net %c  iteration %5d  training MSE %.4e  validation MSE %.4e%s\n",
                     kAxisLetters[axis], p.iteration, p.training_mse, p.validation_mse,
                     p.damping > 0 ? "" : " (gradient descent)");
    };
  if (!quiet)
    std::fprintf(stderr, "training neural IK for machine '%s', preset %s, seed %" PRIu64 "\n",
                 pc.machine.name.c_str(), options.preset.c_str(), options.seed);
  neural::NeuralTrainingReport report;
  const neural::NeuralIk model =
      neural::train_neural_ik(kinematics, pc.machine.name, options, &report, progress);
  model.save(*output);

  print_training_table(model, report, *output);
  return 0;
}

}  // namespace gcpipe::cli
