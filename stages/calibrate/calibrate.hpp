// Stage `calibrate` (issue #13): measured traces -> residual against the configured model ->
// refitted declared parameters and named effects (BIC, held-out check) -> NNOE for what is left
// -> calibration.json, calibrated.yaml (+ calibrated_drives.yaml), report.txt, plots/*.png.
// And `evaluate`: the measured tool-tip contour error of a real run against a program's nominal
// path. Both are library entry points the CLI calls (stages/cli is not touched here).
// Method and derivations: README.md beside this file.
#pragma once

#include <functional>
#include <array>
#include <span>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "compensate.hpp"
#include "identify.hpp"
#include "measured_trace.hpp"
#include "nnoe.hpp"

namespace gcpipe::calibrate {

/// Exit status of both commands, as the rest of gcpipe: 0 done, 3 done with rejected rows
/// skipped (--skip-bad-rows), 1 stopped (bad input, bad config, cannot write), 2 usage error.
struct CalibrateRequest {
  std::vector<std::string> traces;    //!< one or more traces of the same machine
  std::string config;                 //!< pipeline config (machine, interpolate, servo.drives)
  std::string outdir;                 //!< created if missing; files written as NAME.part, renamed
  std::optional<std::string> format;  //!< "csv" | "umich" | "halsampler" | "shdr"; detected when absent
  bool skip_bad_rows = false;         //!< use the usable rest of a trace and count what was dropped
  bool plots = true;                  //!< write plots/*.png
  std::vector<std::string> columns;   //!< halsampler column map / SHDR item map (ReadOptions::columns)
  double period = 0;                  //!< halsampler without a time column [s]
};

int run_calibrate(const CalibrateRequest& request, std::ostream& out, std::ostream& err);

struct EvaluateRequest {
  std::string trace;                  //!< measured trace of a run of `program`
  std::string program;                //!< the G-code that was run (the nominal path measured against)
  /// The G-code the machine ran when it is not `program` (its compensated.nc): the trace's
  /// commands are checked against this one, the contour error is measured against `program`.
  std::optional<std::string> ran;
  std::string config;                 //!< pipeline config (machine kinematics, parse options)
  std::optional<std::string> format;
  bool skip_bad_rows = false;
  std::optional<std::string> json;    //!< also write the figures as JSON here
  std::vector<std::string> columns;   //!< halsampler column map / SHDR item map
  double period = 0;                  //!< halsampler without a time column [s]
};

int run_evaluate(const EvaluateRequest& request, std::ostream& out, std::ostream& err);

/// Why traces cannot be calibrated together (their sampling periods differ), or nullopt.
std::optional<std::string> mixed_periods(const std::vector<MeasuredTrace>& traces);

/// ReadOptions from a request's format, column map and period; false (and why, on err) when
/// the format name is unknown.
bool read_options(const std::optional<std::string>& format, const std::vector<std::string>& columns, double period,
                  bool skip_bad_rows, ReadOptions& options, std::ostream& err);

// --- pieces, exposed for the tests and the benchmark ---

/// Contour error of a measured run: distance of the measured tool tip (FK of the actual joints)
/// to the program's nominal tool-tip path (FK of the raw interpolated joints), by the simulate
/// stage's one metric (simulate::ContourSearch, searched up to where the nominal has got by the
/// sample's time) and its classification: rapids (G0) apart from feed moves and dwells. The trace's
/// time is aligned with the program's at the first commanded motion. Units mm.
struct ContourFigures {
  double cutting_max = 0, cutting_rms = 0, rapid_max = 0, rapid_rms = 0;
  double t_at_cutting_max = 0;       //!< [s] trace time
  std::uint64_t line_at_cutting_max = 0;
  std::size_t cutting_samples = 0, rapid_samples = 0, idle_samples = 0;
};
/// Throws std::runtime_error when the program cannot be run by the model. Does not check that the
/// trace is a run of the program (run_evaluate does, with check_trace_runs_program, first).
ContourFigures measured_contour_error(const compensate::Model& model, std::span<const ResolvedBlock> program,
                                      const MeasuredTrace& trace);

/// Whether a trace's commanded positions are a run of `program`: the trace's commands against the
/// program's nominal commands (the control model's smoothed interpolator output, compensate's
/// Tick::command, the quantity a control logs as "commanded" and simulate_trace records), aligned
/// at the first commanded motion as measured_contour_error does, then shifted by the best of a
/// few ticks either side. Checked in this order: the axes that move (in one but not the other),
/// the commands sample by sample over the overlap, the duration of the commanded motion. The
/// rule and its numbers are in check_trace_runs_program's definition and the README (evaluate).
struct ProgramMatch {
  enum class Part : std::uint8_t { kNone, kAxes, kCommands, kDuration };
  Part part = Part::kNone;    //!< kNone: the trace follows the program
  bool ok() const { return part == Part::kNone; }
  std::string message;        //!< when not ok: where they part, by how much, and what to do
  // kAxes and kCommands: where they part
  int axis = -1;
  std::size_t sample = 0;     //!< trace sample index
  double t = 0;               //!< [s] trace time of that sample
  double trace_value = 0, nominal_value = 0;  //!< commanded in the trace, nominal there [mm, deg]
  double deviation = 0, tolerance = 0;        //!< [mm, deg]: outside the nominal's time window, allowed
  std::uint64_t line = 0;     //!< program line of the nominal block at that time
  // kDuration
  double trace_duration = 0, nominal_duration = 0;  //!< [s] first to last commanded motion
  // always
  long shift_ticks = 0;       //!< time shift chosen around the first-motion alignment
  double worst = 0;           //!< largest deviation / tolerance over the compared samples
  std::array<double, kNumAxes> resolution{};  //!< detected quantisation of the trace's commands (0: none)
};
/// The resolution of a logged command: the coarsest decimal grid (1, 0.5, 0.1, ... 0.0001 mm or
/// deg) that 99 % of its values lie on; 0 when none is, or when it changes fewer than 5 times.
/// UMich's commands: X 1 mm, Y and Z 0.1 mm.
double command_resolution(const std::vector<double>& values);
/// Throws std::runtime_error when the program cannot be run by the model or the trace's commands
/// never move (as measured_contour_error).
/// `planned`: under the look-ahead control (interpolate.control: lookahead) the machine ran the
/// control's plan of `program` (an original program); false for timed points the control runs
/// as given (a compensated.nc, --ran).
ProgramMatch check_trace_runs_program(const compensate::Model& model, std::span<const ResolvedBlock> program,
                                      const MeasuredTrace& trace, const std::string& program_name = "the program",
                                      bool planned = true);

/// Radius at which rotary errors are stated in micrometres: 100 mm (a part's size on the
/// MX-330 table); rms_deg is given beside it.
inline constexpr double kRotaryRadiusMm = 100.0;

/// Prediction error figures of one model over a trace.
struct PredictionError {
  Axes rms_um{}, max_um{};   //!< linear axes in um; A, C in um at kRotaryRadiusMm
  Axes rms_deg{};            //!< A, C only (0 for X Y Z)
  double tip_rms_um = 0, tip_max_um = 0;  //!< tool tip through the kinematics, workpiece frame
};

/// Everything the calibration found, before it is written out.
struct Calibration {
  std::vector<std::string> traces;
  std::size_t rows = 0;
  std::uint64_t rows_skipped = 0, rows_unused = 0;
  double period = 0;
  Axes noise{};  //!< [mm, deg]
  std::array<AxisIdentification, kNumAxes> axes;
  std::array<std::optional<NnoeModel>, kNumAxes> nnoe;
  PredictionError declared, refit, calibrated, with_nnoe;
  std::vector<double> t;                           //!< joined time axis [s]
  std::array<std::vector<double>, kNumAxes> command, actual;
  std::array<std::vector<double>, kNumAxes> effort;  //!< torque [N*m] or current [A], when every trace has it
  std::array<std::string, kNumAxes> effort_kind;     //!< "torque", "current" or ""
  std::size_t split = 0;                           //!< first held-out sample
  std::size_t begin = 1;                           //!< first scored sample (start transient out)
  servo::DriveSet drives;                          //!< the calibrated drives
};

/// Runs the identification on traces already read (the tests use this with simulated traces).
/// `progress(done, total)` after each step (an axis identified, an axis's fallback fitted).
Calibration calibrate_traces(const std::vector<MeasuredTrace>& traces, const compensate::Model& model,
                             const IdentifyOptions& options = {},
                             const std::function<void(std::uint64_t done, std::uint64_t total)>& progress = {});

/// Prediction error of the per-axis predictions `pred` against the measured actual positions.
PredictionError prediction_error(const Calibration& c, const compensate::Model& model,
                                 const std::array<const std::vector<double>*, kNumAxes>& pred);

/// Writes calibration.json, calibrated.yaml, calibrated_drives.yaml, report.txt (and plots/ when
/// `plots`) into outdir, each as NAME.part renamed when complete. Throws std::runtime_error
/// naming the file that could not be written.
void write_outputs(const Calibration& c, const compensate::Model& model, const std::string& config_path,
                   const std::string& outdir, bool plots);

/// calibration.json text (the schema of issue #13 plus the scores of every candidate).
std::string calibration_json(const Calibration& c);
/// report.txt text.
std::string report_text(const Calibration& c);

/// The figures of plots/ (residual vs time, velocity, position, hysteresis, criterion bars).
std::vector<std::string> write_plots(const Calibration& c, const std::string& outdir);

/// The calibrated drives file text (YAML, every axis, effects under `effects:`).
std::string drives_yaml(const Calibration& c, const servo::DriveSet& configured);
/// Warnings calibrated_drives.yaml carries (DriveSet::prediction_warnings): every driven axis
/// whose calibrated prediction stays above 5x the noise or has a structural mismatch.
std::vector<std::string> prediction_warnings(const Calibration& c);
/// A drives file (pipeline_configs/drives/*.yaml layout) for `d`, after a comment `header`.
std::string drives_text(const servo::DriveSet& d, const std::string& header);
/// The NNOE `m`, fitted on samples every `period` s, as the servo's `nnoe` effect (the settings
/// calibrated.yaml carries under the axis's `effects:`).
servo::EffectSettings nnoe_effect(const NnoeModel& m, double period);
/// The pipeline config at `config_path` with servo.drives = `drives_file` (relative to where the
/// result is written) and its other relative paths made absolute.
std::string pipeline_yaml(const std::string& config_path, const std::string& drives_file);

}  // namespace gcpipe::calibrate
