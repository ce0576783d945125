// gcpipe train-spindle: seed 003's NNOE on the spindle of measured runs (stages/force/
// spindle_model.hpp): Table 1's structures trained on some runs and scored on others, the one with
// the lowest verification FPE written as a model file that `force.spindle_model` runs along a
// program, and a figure of its prediction of the verification runs against the measurement.
#include <cstdio>
#include <filesystem>
#include <string>

#include "commands.hpp"
#include "force_report.hpp"
#include "output_dir.hpp"
#include "spindle_model.hpp"

namespace gcpipe::cli {
namespace {

std::vector<std::filesystem::path> paths_of(const std::vector<std::string>& files) {
  return {files.begin(), files.end()};
}

/// The table on stdout, Markdown as in stages/force/README.md sec. 8, the chosen row marked.
void print_table(const force::SpindleTraining& t) {
  const force::SpindleModel& m = t.model;
  std::printf("spindle %s (%s): fit %s (%zu samples), verify %s (%zu samples), every %g s\n\n", m.quantity.c_str(),
              m.column.c_str(), t.fit.file.c_str(), t.fit.power.size(), t.verify.file.c_str(), t.verify.power.size(),
              m.period);
  std::printf("| regressors | fit FPE %% | verify FPE %% | |\n|---|---|---|---|\n");
  for (std::size_t i = 0; i < t.table.size(); ++i) {
    const bool ablation = i + 1 == t.table.size() && t.table.size() > 5;
    std::printf("| %s | %.2f | %.2f | %s |\n", t.table[i].regressors.c_str(), t.table[i].training_fpe,
                t.table[i].verification_fpe, i == t.chosen ? "**chosen**" : ablation ? "ablation: no feed, not a candidate" : "");
  }
  std::printf("\nchosen: %s, the lowest verification FPE of Table 1's structures (%.2f %%): the verification runs\n"
              "were not trained on, so their error is the one a new program will see; the fit FPE barely tells the\n"
              "structures apart, and a structure that fits well but drifts on unseen runs would predict nonsense.\n",
              m.regressors.c_str(), m.verify_fpe);
  const force::StructureScore& ablation = t.table.back();
  std::printf("without the feed (ablation) the verification FPE is %.2f %%: the feed explains %.2f points of it.\n",
              ablation.verification_fpe, ablation.verification_fpe - t.table[0].verification_fpe);
}

std::filesystem::path figure_path(const TrainSpindleArgs& a) {
  if (!a.png.empty()) return a.png;
  std::filesystem::path p(a.output);
  return p.replace_filename(p.stem().string() + "_verification.png");
}

void write_verification_figure(const force::SpindleTraining& t, const std::filesystem::path& png) {
  const force::SpindleModel& m = t.model;
  const auto predicted = force::predict_spindle(m, force::umich_channels(t.verify));
  char note[256];
  std::snprintf(note, sizeof note, "%s: verification FPE %.1f %% (fit %.1f %%); runs in wax at low load (README sec. 8)",
                m.regressors.c_str(), m.verify_fpe, m.fit_fpe);
  force::write_prediction_png(png, force::measured(t.verify, m), predicted, m.period,
                              "spindle " + m.quantity + " of the verification runs " + t.verify.file, note,
                              m.column + " [" + (m.quantity == "current" ? "A" : "as recorded") + "]");
}

}  // namespace

int run_train_spindle(const TrainSpindleArgs& a) {
  force::SpindleTrainingOptions o;
  o.quantity = a.quantity;
  o.hidden = a.hidden;
  o.nnoe.max_iterations = a.max_iterations;
  if (!a.quiet)
    std::fprintf(stderr, "training seed 003's Table 1 structures on %zu run(s), %d tanh units, %d LM iterations\n",
                 a.fit.size(), o.hidden, o.nnoe.max_iterations);
  const force::SpindleTraining t = force::train_spindle_model(paths_of(a.fit), paths_of(a.verify), o);
  pipeline::write_file_atomically(a.output, force::spindle_model_yaml(t.model));
  const auto png = figure_path(a);
  write_verification_figure(t, png);
  print_table(t);
  std::printf("model written to %s (units, channels, sample period and normalisation in it); figure %s\n",
              a.output.c_str(), png.string().c_str());
  return 0;
}

}  // namespace gcpipe::cli
