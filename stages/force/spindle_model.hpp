// A spindle model a process engineer trains on measured runs and the force stage runs along a
// program: seed 003's NNOE (stages/calibrate/nnoe.hpp, one implementation) predicting the
// spindle's power or current from the path feed, the spindle speed and a cutting flag, the
// regressor structure chosen among its Table 1 rows by the verification FPE
// (stages/force/README.md sec. 8b). Trained by `gcpipe train-spindle` on the UMich mill runs
// (umich_force.hpp is the one reader), written as a YAML model file with its units, channels,
// sample period, normalisation and the ranges it was trained over, read back by the force stage
// (`force.spindle_model`).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "nnoe_force.hpp"
#include "spindle_inputs.hpp"
#include "umich_force.hpp"

namespace gcpipe::force {

/// One input of the model: its name (feed, spindle, cutting), unit and the range trained over.
struct SpindleChannel {
  std::string name, unit;
  double min = 0, max = 0;
};

struct SpindleModel {
  std::string quantity;        //!< "power" or "current"
  std::string column;          //!< the measured column it predicts (S1_OutputPower)
  std::string unit;            //!< of the quantity, as the data state it
  std::string data;            //!< what the training runs were (material, load): the model's limits
  double period = 0;           //!< sample period of the training runs and of the model [s]
  std::vector<SpindleChannel> channels;
  double output_min = 0, output_max = 0;  //!< the measured quantity's range in the training runs
  std::vector<std::string> fit_runs, verify_runs;
  std::string regressors;      //!< "P(t-1) f(t-1) S(t-1) cut(t-1)"
  double fit_fpe = 0, verify_fpe = 0;  //!< [% of the fit runs' variance]
  calibrate::NnoeModel nnoe;
};

struct SpindleTrainingOptions {
  std::string quantity = "power";    //!< power | current
  int hidden = 8;                    //!< tanh units of every structure
  calibrate::NnoeOptions nnoe{20000, 40, 1};
};

/// Every structure tried, the one chosen and the model built from it.
struct SpindleTraining {
  std::vector<StructureScore> table;  //!< Table 1's five rows, then the ablation without the feed
  std::size_t chosen = 0;             //!< index into table (one of the five Table 1 rows)
  SpindleModel model;
  UmichRun fit, verify;               //!< the runs concatenated
};

/// Reads the runs (UMich CSVs), trains Table 1's structures on `fit`, scores them on `verify` and
/// keeps the lowest verification FPE among them. Throws std::runtime_error for an unreadable run.
SpindleTraining train_spindle_model(const std::vector<std::filesystem::path>& fit,
                                    const std::vector<std::filesystem::path>& verify,
                                    const SpindleTrainingOptions& options = {});

/// The model's inputs of a UMich run, in the model's channel order and units.
calibrate::Channels umich_channels(const UmichRun& run);
/// The measured quantity of a run the model predicts.
const std::vector<double>& measured(const UmichRun& run, const SpindleModel& m);

/// The model's parallel (output-error) run over the inputs: one prediction per sample [model unit].
std::vector<double> predict_spindle(const SpindleModel& m, const calibrate::Channels& inputs);

/// The model file's text (YAML, every number to the shortest exact digits, so that the model read
/// back predicts what was trained); the caller writes it (pipeline/output_dir.hpp's AtomicFile).
std::string spindle_model_yaml(const SpindleModel& m);
/// Reads a model file; throws ConfigError naming the file, the key and what is wrong.
SpindleModel read_spindle_model(const std::filesystem::path& file);

/// Why the force stage cannot supply the model's inputs (a channel it does not know, or a unit it
/// cannot convert to), naming each; "" when it can. It supplies feed (mm/s or mm/min), spindle
/// (rev/s or rev/min) and cutting (flag).
std::string unsupplied_channels(const SpindleModel& m);

/// The model's quantity along a program, and what the engineer must know to trust it.
struct SpindlePrediction {
  std::vector<double> value;          //!< one per model sample of the program [model unit]
  std::size_t cutting_samples = 0;    //!< samples in cutting moves
  double mean_cutting = 0, max_cutting = 0;  //!< over the cutting samples [model unit]
  double min_program = 0, max_program = 0;  //!< over every sample [model unit]
  /// Inputs outside the range the model was trained over: "spindle: 66.67 rev/s > 53.3 trained
  /// (91 % of the samples)"; the model extrapolates there.
  std::vector<std::string> outside_training;
};

/// Runs the model along the program's inputs (converted to the model's units; unsupplied_channels
/// must be ""). The inputs' period must be the model's.
SpindlePrediction predict_along_program(const SpindleModel& m, const ProgramInputs& in);

}  // namespace gcpipe::force
