// gcpipe train-ik: trains the neural IK model (stages/ik/neural_train.hpp) for the configured
// machine and writes the versioned model file. Deterministic for a seed.
#include <cinttypes>
#include <cstdio>
#include <iostream>
#include <string>

#include "command.hpp"
#include "commands.hpp"
#include "gcpipe/config.hpp"
#include "gcpipe/kinematics.hpp"
#include "neural_train.hpp"
#include "program_stream.hpp"

namespace gcpipe::cli {
namespace {

int run_train_ik(const std::vector<std::string>& argv) {
  Args args(argv,
            {"--config", "-o", "--seed", "--preset", "--samples", "--max-iterations", "--trainer",
             "--c-output"},
            {"--quiet"});
  if (!args.ok()) return usage_error(kTrainIkCommand, args.error());
  if (!args.positional().empty())
    return usage_error(kTrainIkCommand, "unexpected argument '" + args.positional()[0] + "'");
  const auto output = args.value("-o");
  if (!output) return usage_error(kTrainIkCommand, "give the model file to write with -o MODEL");

  neural::NeuralTrainingOptions options;
  try {
    options = neural::preset_options(args.value_or("--preset", "improved"));
  } catch (const std::invalid_argument& e) {
    return usage_error(kTrainIkCommand, e.what());
  }
  const double seed = args.number_or("--seed", 1);
  const double samples = args.number_or("--samples", 0);
  const double iterations = args.number_or("--max-iterations", 0);
  if (!args.ok()) return usage_error(kTrainIkCommand, args.error());
  if (!(seed >= 0 && seed <= 9007199254740992.0 && seed == static_cast<double>(static_cast<std::uint64_t>(seed))))
    return usage_error(kTrainIkCommand, "--seed must be a whole number in [0, 2^53]");
  options.seed = static_cast<std::uint64_t>(seed);
  if (samples != 0) {
    if (!(samples >= 12 && samples <= 1e7 && samples == static_cast<int>(samples)))
      return usage_error(kTrainIkCommand, "--samples must be a whole number in [12, 1e7]");
    // Random sampling; 2/3 training, 1/6 validation, 1/6 test for both data sets.
    const int n = static_cast<int>(samples);
    options.sampling = neural::Sampling::kRandom;
    options.position_samples = n;
    options.position_split = {2 * n / 3, n / 6};
    options.rotary_samples = n / 2;
    options.rotary_split = {n / 3, n / 12};
    options.preset = "custom";
  }
  if (iterations != 0) {
    if (!(iterations >= 1 && iterations <= 1e6 && iterations == static_cast<int>(iterations)))
      return usage_error(kTrainIkCommand, "--max-iterations must be a whole number in [1, 1e6]");
    options.levenberg_marquardt.max_iterations = static_cast<int>(iterations);
    for (auto& gd : options.gradient_descent) gd.max_epochs = static_cast<int>(iterations);
    options.preset = "custom";
  }

  if (const auto trainer = args.value("--trainer")) {
    if (*trainer != "lm" && *trainer != "gd")
      return usage_error(kTrainIkCommand, "--trainer must be lm or gd, not '" + *trainer + "'");
    options.trainer = *trainer == "lm" ? neural::Trainer::kLevenbergMarquardt
                                       : neural::Trainer::kGradientDescent;
    options.preset = "custom";
  }
  if (const auto c_output = args.value("--c-output")) {
    if (*c_output != "angle" && *c_output != "sincos")
      return usage_error(kTrainIkCommand,
                         "--c-output must be angle or sincos, not '" + *c_output + "'");
    options.c_output = *c_output == "angle" ? neural::COutput::kAngle : neural::COutput::kSinCos;
    options.preset = "custom";
  }

  const PipelineConfig pc = load_config_option(args.value_or("--config", ""));
  const MachineKinematics kinematics = load_kinematics(pc.machine_section);
  const bool quiet = args.flag("--quiet");
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

  // Summary on stdout (a Markdown table, pasted into stages/ik/README.md).
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
              report.cpu_seconds, report.seconds, output->c_str());
  return 0;
}

}  // namespace

constinit const Command kTrainIkCommand{
    "train-ik", "train the neural IK model for the configured machine",
    "Usage: gcpipe train-ik -o MODEL [--config CFG] [--preset paper|improved] [--seed N]\n"
    "                       [--samples N] [--max-iterations N] [--trainer lm|gd]\n"
    "                       [--c-output angle|sincos] [--quiet]\n"
    "\n"
    "Generates training data from the machine's analytic kinematics (joints within travel ->\n"
    "forward kinematics), trains the per-axis networks of seed 000 Table 5 and writes the model\n"
    "file (text, 'gcpipe-neural-ik v1'). The same seed and options give the same file, byte for\n"
    "byte. Progress goes to stderr, a summary table (MSE on normalised targets, errors in mm and\n"
    "deg) to stdout. See stages/ik/README.md, \"Neural IK\".\n"
    "\n"
    "  -o MODEL             model file to write\n"
    "  --config CFG         pipeline config naming the machine (default pipeline_configs/default.yaml)\n"
    "  --preset P           paper: 5^5 grid, Table 5 split and rates, gradient descent, C angle;\n"
    "                       improved (default): random data, Levenberg-Marquardt, C as sin/cos\n"
    "  --seed N             random seed for data, split and initial weights (default 1)\n"
    "  --samples N          random data: N position points, N/2 rotary points, split 2/3, 1/6,\n"
    "                       1/6 (overrides the preset's data; the model's preset becomes 'custom')\n"
    "  --max-iterations N   LM iterations or gradient-descent epochs per net (preset 'custom')\n"
    "  --trainer T          lm (Levenberg-Marquardt) or gd (gradient descent with the preset's\n"
    "                       rates; the improved preset has Table 5's) (preset 'custom')\n"
    "  --c-output O         C net output: angle or sincos (preset 'custom')\n"
    "  --quiet              no progress lines\n"
    "Exit status: 0 written, 1 error (config, training, file), 2 usage.\n",
    run_train_ik};

}  // namespace gcpipe::cli
