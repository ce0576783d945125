// gcpipe: G-code stream processing for five-axis machining. main() declares every subcommand's
// options with CLI11 (the help text comes from these declarations) and dispatches to run_<name>.
// This is the only file that includes CLI11: it is a heavy header.
#include <functional>
#include <iostream>
#include <optional>

#include <malloc.h>

#include <CLI/CLI.hpp>

#include "commands.hpp"
#include "did_you_mean.hpp"
#include "output_dir.hpp"
#include "stage.hpp"

using namespace gcpipe::cli;

namespace {

constexpr const char* kExitStatus =
    "Exit status: 0 every line accepted, 3 finished with rejected lines, 1 stopped or failed (the\n"
    "reason is printed), 2 usage error, 130/143 interrupted by SIGINT/SIGTERM.";

const CLI::Validator kNonEmpty(
    [](std::string& s) { return s.empty() ? std::string("must not be empty") : std::string(); }, "NONEMPTY");

// --config, --tool-table, --strict, --progress, --no-progress and the input program.
void add_program_options(CLI::App& sub, ProgramArgs& a) {
  sub.add_option("input", a.input, "the program (ISO 6983 G-code); - reads standard input")->required();
  // No file check here: the config loader names the file and says what is wrong with it.
  sub.add_option("--config", a.config, "pipeline config (default: pipeline_configs/default.yaml)");
  sub.add_option("--tool-table", a.tool_table,
                 "a shop's tool table (LinuxCNC .tbl or YAML) instead of the machine file's tools")
      ->check(CLI::ExistingFile);
  sub.add_flag("--strict", a.strict, "stop at the first rejected line (default: reject it and go on)");
  sub.add_flag("--progress", a.progress, "progress on stderr even when it is not a terminal");
  sub.add_flag("--no-progress", a.no_progress, "no progress on stderr, even on a terminal");
}

void add_config(CLI::App& app, ConfigArgs& a) {
  auto* s = app.add_subcommand("config", "show the effective pipeline config: every key the stages read, defaults included");
  s->add_option("--config", a.config, "pipeline config (default: pipeline_configs/default.yaml)");
  s->add_flag("--print", a.print, "print it as YAML (the default and only action)");
  s->footer("Builds every registered stage from the config as gcpipe batch does and prints each key it reads,\n"
            "grouped by file (the pipeline config, the machine file, the drives file, ...), a key the file leaves\n"
            "out marked '# default'. Exit status: 0, or 1 when a stage cannot be built from this config (the\n"
            "reason is printed at the end).");
}

void add_batch(CLI::App& app, BatchArgs& a) {
  auto* s = app.add_subcommand("batch", "run the whole pipeline on a program: file in, files out");
  add_program_options(*s, a);
  s->add_option("-o,--output-dir", a.outdir, "output folder (created when missing)")->required()->check(kNonEmpty);
  s->add_flag("--no-simulate", a.no_simulate,
              "streaming stages only (parse, trochoid, ik, write): memory independent of the program's length");
  s->add_option("--model", a.model,
                "neural IK model (default: the config's ik.model); given, the neural IK is compared and drawn also on a "
                "program whose A and C do not move")
      ->check(CLI::ExistingFile);
  s->add_flag("--keep-going", a.keep_going,
              "write compensated.nc although lines were rejected (without them); by default such a program is not compensated");
  s->add_flag("--quiet", a.quiet, "print nothing but errors that stop the run");
  s->footer(std::string("Runs every stage in-process, in pipeline order (gcpipe stages): parse -> trochoid -> write\n"
      "(output.nc) and -> ik -> simulate -> compensate (compensated.nc), then the report and the\n"
      "figures. Writes in OUTDIR: compensated.nc, report.json, report.txt, plots/*.png, output.nc,\n"
      "summary.json, diagnostics.txt. Files of an earlier run there are removed first; every file is\n"
      "written as NAME.part and renamed when complete. The simulation's long series and the program's\n"
      "blocks are kept in unlinked scratch files in $GCPIPE_SCRATCH_DIR (default /var/tmp; about 50\n"
      "bytes a planned millisecond while the run lasts), not in memory.") + "\n\n" + kExitStatus +
      "\nbatch also exits 4 when it finished without writing compensated.nc and nothing failed: the config\n"
      "has no servo section (no drives to compensate for) or the program has no cutting moves; the reason\n"
      "is in report.txt and in summary.json as `not_compensated`. A program with rejected lines exits 3 and\n"
      "gets no compensated.nc unless --keep-going is given.");
}

void add_parse(CLI::App& app, ParseArgs& a) {
  auto* s = app.add_subcommand("parse", "parse a program and print its resolved blocks");
  add_program_options(*s, a);
  s->add_flag("--json", a.json, "one JSON object per block (JSON Lines), every resolved field");
  s->add_option("-o,--output", a.output, "write to this file instead of standard output")->check(kNonEmpty);
  s->footer(std::string("The parse stage alone: one line per resolved block (source line, motion, absolute target X Y Z\n"
      "[mm] A C [deg], feed). Errors go to stderr as file:line:col: error: reason.") + "\n\n" + kExitStatus);
}

void add_trochoid(CLI::App& app, TrochoidArgs& a) {
  auto* s = app.add_subcommand("trochoid", "expand G275 trochoidal slot cycles into G1/G2/G3 blocks");
  add_program_options(*s, a);
  s->add_option("-o,--output", a.output, "write to this file instead of standard output")->check(kNonEmpty);
  s->add_option("--png", a.png, "tool path coloured by radial engagement (PNG)")->check(kNonEmpty);
  s->footer(std::string("parse -> trochoid -> write: every G275 cycle replaced by its tool path (seed 000 eq. 6,\n"
      "stages/trochoid/README.md). A cycle that cannot be machined is reported as file:line: error and\n"
      "left out as a comment; rapids at the clearance plane then take the tool to the cycle's end.") + "\n\n" + kExitStatus);
}

void add_ik(CLI::App& app, IkArgs& a) {
  auto* s = app.add_subcommand("ik", "inverse kinematics of a program: analytic and neural joints with flags");
  add_program_options(*s, a);
  s->add_flag("--csv", a.csv, "CSV output (the only format)")->required();
  s->add_option("--model", a.model, "neural IK model written by gcpipe train-ik (default: the config's ik.model)")
      ->check(CLI::ExistingFile);
  s->add_flag("--tool-vector", a.tool_vector, "TCP blocks give only their tool vector; the IK chooses A and C");
  s->add_option("-o,--output", a.output, "write to this file instead of standard output")->check(kNonEmpty);
  s->footer(std::string("parse -> trochoid -> ik: every block's end point solved. Tool-centre-point blocks (G43.4, M428,\n"
      "G43.5) give the tip; other blocks are machine axes. CSV: line,X,Y,Z,A,C,Xn,Yn,Zn,An,Cn,flags\n"
      "(analytic joints, then the neural model's, mm and deg, 6 decimals; flags joined by '|').\n"
      "Without a model the neural columns are empty. A summary goes to stderr.") + "\n\n" "Exit status: 0 all points solved, 4 some points failed (travel/unreachable), 3 some lines rejected,\n"
            "1 stopped, 2 usage.");
}

void add_simulate(CLI::App& app, SimulateArgs& a) {
  auto* s = app.add_subcommand("simulate", "predict the axis motion of a program (interpolator + feed drives)");
  add_program_options(*s, a);
  s->add_option("-o,--output", a.output, "the axis trace CSV (- for standard output)")->required()->check(kNonEmpty);
  s->add_option("--report", a.report, "per tick: t, actual tool tip [mm], contour error [mm]")->check(kNonEmpty);
  s->add_option("--circle", a.circle,
                "R_C,R_W [mm]: add seed 002's circle-test columns to the report (alpha, beta, "
                "alpha_minus_beta [rad], radius_decrease, shape_error [mm])");
  s->footer(std::string("parse -> trochoid -> ik -> simulate: the program interpolated at the config's period, smoothed\n"
      "per axis (acc/dec, Ts from the drives file), each axis through seed 002's feed-drive model, the\n"
      "actual tool tip through the kinematics and its contour error against the nominal path: the same\n"
      "harness and metric as gcpipe batch's report. Trace: t,X_cmd..C_cmd,X..C (s, mm, deg).") + "\n\n" + kExitStatus);
}

void add_synth(CLI::App& app, SynthArgs& a) {
  auto* s = app.add_subcommand("synth", "write a seeded synthetic five-axis program for load tests");
  auto* blocks = s->add_option("--blocks", a.blocks, "this many blocks")->check(CLI::PositiveNumber);
  auto* mb = s->add_option("--megabytes", a.megabytes, "about this many MB")->check(CLI::PositiveNumber);
  auto* cam = s->add_option("--cam-segments", a.cam_segments,
                            "a CAM-like 2.5D finishing pass of this many 0.1-2 mm moves and arcs instead")
                  ->check(CLI::Range(1, 10000000));
  blocks->excludes(mb);
  cam->excludes(blocks)->excludes(mb);
  s->add_option("--seed", a.seed, "random seed");
  s->add_option("-o,--output", a.output, "write to this file instead of standard output")->check(kNonEmpty);
}

void add_train_ik(CLI::App& app, TrainIkArgs& a) {
  auto* s = app.add_subcommand("train-ik", "train the neural IK of a machine (deterministic for a seed)");
  s->add_option("--config", a.config, "pipeline config naming the machine");
  s->add_option("-o,--output", a.output, "the model file to write")->required()->check(kNonEmpty);
  s->add_option("--seed", a.seed, "random seed")->check(CLI::Range(0.0, 9007199254740992.0));
  s->add_option("--preset", a.preset, "paper (seed 000 as printed) or improved")->check(CLI::IsMember({"paper", "improved"}));
  s->add_option("--samples", a.samples, "random samples per position net (12..1e7)")->check(CLI::Range(12, 10000000));
  s->add_option("--max-iterations", a.max_iterations, "training iterations (1..1e6)")->check(CLI::Range(1, 1000000));
  s->add_option("--trainer", a.trainer, "lm (Levenberg-Marquardt) or gd (gradient descent)")->check(CLI::IsMember({"lm", "gd"}));
  s->add_option("--c-output", a.c_output, "angle or sincos")->check(CLI::IsMember({"angle", "sincos"}));
  s->add_flag("--quiet", a.quiet, "no progress");
}

void add_train_spindle(CLI::App& app, TrainSpindleArgs& a) {
  auto* s = app.add_subcommand("train-spindle", "train seed 003's NNOE on the spindle power or current of measured runs");
  s->add_option("runs", a.fit, "measured runs to fit on (UMich mill CSV)")->required()->check(CLI::ExistingFile);
  s->add_option("--verify", a.verify, "measured runs to choose the structure on (not fitted)")->required()->check(CLI::ExistingFile);
  s->add_option("-o,--output", a.output, "the model file to write (force.spindle_model)")->required()->check(kNonEmpty);
  s->add_option("--quantity", a.quantity, "power (S1_OutputPower) or current (S1_CurrentFeedback)")
      ->check(CLI::IsMember({"power", "current"}));
  s->add_option("--png", a.png, "the verification figure (default: MODEL's name with _verification.png)")->check(kNonEmpty);
  s->add_option("--hidden", a.hidden, "tanh units of every structure (1..64)")->check(CLI::Range(1, 64));
  s->add_option("--max-iterations", a.max_iterations, "Levenberg-Marquardt iterations (1..1000)")->check(CLI::Range(1, 1000));
  s->add_flag("--quiet", a.quiet, "no progress");
  s->footer("Reads the runs (spindle power and current, path feed from the commanded X Y Z velocities, commanded\n"
            "spindle speed, a cutting flag from Machining_Process), trains seed 003's Table 1 structures on the\n"
            "fit runs, prints each one's fit and verification FPE and keeps the lowest verification FPE. The model\n"
            "file holds the quantity and its unit, the channels with their units and training ranges, the sample\n"
            "period and the normalisation; gcpipe batch predicts the quantity along a program with\n"
            "force.spindle_model: MODEL (stages/force/README.md sec. 8b).\n\n"
            "Exit status: 0 written, 1 unreadable run or output, 2 usage.");
}

/// The trace-reading options calibrate and evaluate share (stages/calibrate/README.md §1).
void add_trace_format_options(CLI::App* s, std::string& format, std::vector<std::string>& columns, double& period) {
  s->add_option("--format", format, "csv, umich, halsampler or shdr (default: detected from the first line)")
      ->check(CLI::IsMember({"csv", "umich", "halsampler", "shdr"}));
  s->add_option("--columns", columns,
                "halsampler: the pin of every column in order (n, t, X_cmd..C_cmd, X..C, <axis>_torque, "
                "<axis>_current, - to ignore); shdr: QUANTITY=ITEM pairs (default X=Xposition, X_cmd=Xcommanded, ...)")
      ->delimiter(',');
  s->add_option("--period", period, "halsampler without a t column: the sampler thread's period [s]")
      ->check(CLI::PositiveNumber);
}

void add_calibrate(CLI::App& app, CalibrateArgs& a) {
  auto* s = app.add_subcommand("calibrate", "find where the machine differs from its model in measured traces");
  s->add_option("traces", a.traces, "measured traces of one machine (shared trace CSV, UMich CSV, halsampler, SHDR)")->required()->check(CLI::ExistingFile);
  s->add_option("--config", a.config, "pipeline config of the model (default: pipeline_configs/default.yaml)");
  s->add_option("-o,--output-dir", a.outdir, "output folder: calibration.json, calibrated.yaml, report.txt, plots/")
      ->required()->check(kNonEmpty);
  add_trace_format_options(s, a.format, a.columns, a.period);
  s->add_flag("--skip-bad-rows", a.skip_bad_rows, "use the usable rest of a trace with bad rows, and count what was dropped");
  s->add_flag("--no-plots", a.no_plots, "write no figures");
  s->add_flag("--progress", a.progress, "progress on stderr even when it is not a terminal");
  s->add_flag("--no-progress", a.no_progress, "no progress on stderr, even on a terminal");
  s->footer("Replays the traces' commands through the model, refits the declared drive parameters, names\n"
            "catalogued effects (backlash, coulomb_friction, feedback_delay, measurement_delay, lead_error,\n"
            "scale_error, torque_limit) by BIC with a held-out check, and fits seed 003's NNOE to what no\n"
            "effect explains (stages/calibrate/README.md). calibrated.yaml is a pipeline config for gcpipe batch.\n\n"
            "Exit status: 0 done, 3 done with rows skipped, 1 stopped (bad input or config), 2 usage.");
}

void add_evaluate(CLI::App& app, EvaluateArgs& a) {
  auto* s = app.add_subcommand("evaluate", "measured tool-tip contour error of a real run against its program");
  s->add_option("--trace", a.trace, "the measured trace of a run of the program")->required()->check(CLI::ExistingFile);
  s->add_option("--program", a.program, "the G-code that was run")->required()->check(CLI::ExistingFile);
  s->add_option("--ran", a.ran, "the program the machine ran when it is --program's compensated.nc (the trace is checked against it)")
      ->check(CLI::ExistingFile);
  s->add_option("--config", a.config, "pipeline config (machine kinematics; default: pipeline_configs/default.yaml)");
  add_trace_format_options(s, a.format, a.columns, a.period);
  s->add_flag("--skip-bad-rows", a.skip_bad_rows, "use the usable rest of a trace with bad rows");
  s->add_option("--json", a.json, "also write the figures as JSON to this file")->check(kNonEmpty);
  s->footer("Cutting moves and rapids apart. A trace whose commands are not a run of the program (or of --ran) is\n"
            "refused. Exit status: 0 done, 3 rows skipped, 1 stopped (also: not a run of the program), 2 usage.");
}

#ifdef GCPIPE_WITH_DDS
void add_dds_options(CLI::App& s, DdsArgs& a) {
  s.add_option("--domain", a.domain, "DDS domain id (default $GCPIPE_DDS_DOMAIN, else 0)")->check(CLI::Range(0, 232));
  s.add_option("--profiles", a.profiles, "QoS/transport profiles (default pipeline_configs/dds_profiles.xml)")
      ->check(CLI::ExistingFile);
  s.add_option("--network", a.network,
               "how this host reaches the others: a participant profile file such as "
               "pipeline_configs/dds_network_shop.xml (default: shared memory and loopback only)")
      ->check(CLI::ExistingFile);
  s.add_option("--identity", a.identity, "DDS Security identity folder made by stages/dds/make_security.sh")
      ->check(CLI::ExistingDirectory);
  s.add_option("--subscribers", a.subscribers, "readers a publisher waits for before its first sample")
      ->check(CLI::Range(1, 100));
  s.add_option("--timeout", a.timeout, "longest wait for readers, a blocked write, acknowledgements [s]")
      ->check(CLI::PositiveNumber);
  s.add_option("--idle-timeout", a.idle_timeout, "a consumer gives up after this long without a sample; 0 = never [s]")
      ->check(CLI::NonNegativeNumber);
  s.add_option("--monitor-history", a.monitor_history,
               "a late monitor still gets what was published this long ago, within the last 256 batches "
               "of each topic; 0 = those 256 however old [s]")
      ->check(CLI::NonNegativeNumber);
  // A writer beats eight times within the timeout (cmd_dds.cpp), so a few lost or late beats on a
  // loaded machine are no alarm; 1 s at least.
  s.add_option("--heartbeat-timeout", a.heartbeat_timeout,
               "a reader takes the stage before for dead or frozen after this long without its heartbeat [s]")
      ->check(CLI::Range(1.0, 3600.0));
  s.add_option("--stall-timeout", a.stall_timeout,
               "a reader takes the stage before for stalled after this long working without progress [s]")
      ->check(CLI::Range(1.0, 1e6));
  s.add_option("--partition", a.partition,
               "DDS partition of every reader and writer (gcpipe stream gives each run its own; '*' sees them all)");
  s.add_flag("--replay", a.replay, "also take programs published before this process started");
}

void add_feed(CLI::App& app, FeedArgs& a) {
  auto* s = app.add_subcommand("feed", "publish a program on the pipeline's program topic");
  s->add_option("input", a.input, "the program; - reads standard input")->required();
  s->add_option("--config", a.config, "pipeline config (its parse.max_line_length cuts lines as batch does)")
      ->check(CLI::ExistingFile);
  s->add_option("--chunk-bytes", a.chunk_bytes, "publish a chunk once it holds this much text (default 128 KB; 16 KB with --rate)")
      ->check(CLI::Range(1024, 1048576));
  s->add_option("--rate", a.rate, "send at most this many bytes of the program a second, as a drip feed; 0 = as fast as it is taken [bytes/s]")
      ->check(CLI::NonNegativeNumber);
  s->add_option("--program-id", a.program_id, "program id (default: time-based)");
  s->add_option("--out", a.topic, "topic (default gcpipe_program)");
  add_dds_options(*s, a);
}

void add_node(CLI::App& app, NodeArgs& a) {
  auto* s = app.add_subcommand("node", "run one stage of the pipeline as a DDS node (or several in one process)");
  // The stages with a DDS topic, from the registry: the help cannot fall behind a new node.
  std::string nodes;
  for (const auto& info : gcpipe::pipeline::registry())
    if (*info.topic != '\0') nodes += std::string(nodes.empty() ? "" : ", ") + info.name;
  s->add_option("stage", a.stages,
                "the stage: " + nodes + " (see gcpipe stages); several: one process runs them all, each in its own thread")
      ->required();
  s->add_option("--config", a.config, "pipeline config");
  s->add_option("--batch-bytes", a.batch_bytes, "publish a batch once it holds this much")->check(CLI::Range(1024, 1048576));
  s->add_option("--in", a.in, "input topic (default: the stage's edge); one per stage, comma-separated")->delimiter(',');
  s->add_option("--out", a.out, "output topic (default: the stage's edge); one per stage, comma-separated")->delimiter(',');
  s->add_option("--readers", a.readers,
                "readers of each stage's output, comma-separated; 0: nobody reads it, publish at once (default: --subscribers)")
      ->delimiter(',')->check(CLI::Range(0, 100));
  s->add_flag("--forever", a.forever, "serve programs until SIGINT/SIGTERM");
  s->add_flag("--strict", a.strict, "stop each program at its first rejected line (parse, trochoid)");
  s->add_option("--pipeline-stages", a.pipeline_stages,
                "the whole pipeline's stages, comma-separated (gcpipe launch gives them): a stage "
                "leaves to a later node what that one reports")->delimiter(',');
  s->add_option("--report-dir", a.report_dir, "draw each program's figures into this folder (gcpipe stream's OUTDIR)");
  s->add_option("--report-readers", a.report_readers,
                "report sinks to wait for before publishing each program's report part")->check(CLI::Range(0, 100));
  s->add_option("--program-id", a.program_id, "take only this program id (the one gcpipe feed --program-id publishes); another program on the domain is refused and named (gcpipe stream sets it)");
  add_dds_options(*s, a);
}

void add_report_sink(CLI::App& app, ReportSinkArgs& a) {
  auto* s = app.add_subcommand("report-sink",
                               "write report.json, report.txt, summary.json and diagnostics.txt from the report "
                               "parts the nodes publish (gcpipe stream starts one)");
  s->add_option("-o,--output-dir", a.output, "the output folder")->required()->check(kNonEmpty);
  s->add_option("--stages", a.stages, "the nodes whose parts make the report, comma-separated, in chain order")
      ->required()->delimiter(',');
  s->add_option("--config", a.config, "pipeline config (named in report.json)");
  s->add_option("--program-id", a.program_id, "take only this program id (the one gcpipe feed --program-id publishes); another program on the domain is refused and named (gcpipe stream sets it)");
  add_dds_options(*s, a);
}

void add_sink(CLI::App& app, SinkArgs& a) {
  auto* s = app.add_subcommand("sink", "write the program arriving on a G-code topic to a file");
  s->add_option("-o,--output", a.output, "the file (written as .part, renamed when complete)")->required()->check(kNonEmpty);
  s->add_option("--in", a.in, "topic (default gcpipe_gcode)");
  s->add_option("--program-id", a.program_id, "take only this program id (the one gcpipe feed --program-id publishes); another program on the domain is refused and named (gcpipe stream sets it)");
  add_dds_options(*s, a);
}

void add_monitor(CLI::App& app, MonitorArgs& a) {
  auto* s = app.add_subcommand("monitor", "print a live summary of a pipeline topic, or of every stage of a pipeline");
  auto* topic = s->add_option("topic", a.topic,
                              "the topic to watch: an edge (gcpipe_program, gcpipe_blocks, gcpipe_toolpath, ...) or "
                              "the telemetry gcpipe_ik_results (IK points and flags) or gcpipe_samples (simulated "
                              "ticks: contour error, torque saturation)");
  auto* pipeline = s->add_option("--pipeline", a.pipeline,
                                 "every stage of a pipeline: a pipeline file, or the name of one in "
                                 "pipeline_configs/pipelines (e.g. streaming); its domain unless --domain or $GCPIPE_DDS_DOMAIN");
  topic->excludes(pipeline);
  s->add_option("--type", a.type, "program, blocks, gcode, ik or samples (default: from the topic name)")->excludes(pipeline);
  s->add_option("--period", a.period, "seconds between summaries")->check(CLI::Range(0.05, 3600.0));
  s->add_option("--plot", a.plot,
                "redraw this PNG every period: the simulated contour error over machine time (gcpipe_samples, "
                "or a pipeline with a simulate node)")
      ->check(kNonEmpty);
  add_dds_options(*s, a);
}

void add_launch_options(CLI::App& s, LaunchArgs& a) {
  s.add_option("--domain", a.domain, "DDS domain id (default $GCPIPE_DDS_DOMAIN, else the pipeline file's)")->check(CLI::Range(0, 232));
  s.add_flag("-v,--verbose", a.verbose, "print every line of every process, prefixed with its name");
}

void add_launch(CLI::App& app, LaunchArgs& a) {
  auto* s = app.add_subcommand("launch", "start and supervise a whole pipeline of DDS nodes from a pipeline file");
  s->add_option("pipeline", a.pipeline, "the pipeline file (e.g. pipeline_configs/pipelines/streaming.yaml)")->required()->check(CLI::ExistingFile);
  add_launch_options(*s, a);
  s->footer("One process per stage, any start order; one status line per process; Ctrl-C stops them all. A crashed stage "
            "stops the pipeline (exit 1, naming it) or is started again, as the file's on_crash says. Programs are "
            "fed with: gcpipe feed IN.nc --domain D. Format: stages/dds/README.md.");
}

void add_stream(CLI::App& app, StreamArgs& a) {
  auto* s = app.add_subcommand("stream", "run one program through the DDS pipeline: the files gcpipe batch writes for it");
  s->add_option("input", a.input, "the program")->required()->check(CLI::ExistingFile);
  s->add_option("-o,--output-dir", a.output, "output folder: output.nc and, with the compensate node, compensated.nc")
      ->required()->check(kNonEmpty);
  s->add_option("--config", a.config, "pipeline config every node reads (default: the pipeline file's)")->check(CLI::ExistingFile);
  s->add_option("--pipeline", a.pipeline, "the pipeline file (default pipeline_configs/pipelines/streaming.yaml)")->check(CLI::ExistingFile);
  s->add_option("--feed-rate", a.feed_rate, "the feed sends at most this many bytes of the program a second; 0 = unpaced [bytes/s]")
      ->check(CLI::NonNegativeNumber);
  add_launch_options(*s, a);
  s->footer("Launches the file's nodes, a feed and one sink per written program, and stops when the program is "
            "through. output.nc and compensated.nc are byte-identical to gcpipe batch's with the same config. "
            "Exit status: as gcpipe batch (0, 3 lines rejected, 1 failed: the stage is named).");
}
#endif

#ifdef GCPIPE_WITH_DDS
// The streaming commands' options; they run in the plugin (dds_loader.cpp).
struct DdsCommands {
  FeedArgs feed;
  NodeArgs node;
  SinkArgs sink;
  ReportSinkArgs report_sink;
  MonitorArgs monitor;
  LaunchArgs launch;
  StreamArgs stream;
  DdsCleanArgs clean;
  /// The options of the DDS command `name`, or null for any other command.
  const void* args_of(const std::string& name) const {
    if (name == "dds-clean") return &clean;
    if (name == "feed") return &feed;
    if (name == "node") return &node;
    if (name == "sink") return &sink;
    if (name == "report-sink") return &report_sink;
    if (name == "monitor") return &monitor;
    if (name == "launch") return &launch;
    if (name == "stream") return &stream;
    return nullptr;
  }
};

void add_dds_commands(CLI::App& app, DdsCommands& d) {
  add_feed(app, d.feed);
  add_node(app, d.node);
  add_sink(app, d.sink);
  add_report_sink(app, d.report_sink);
  add_monitor(app, d.monitor);
  add_launch(app, d.launch);
  add_stream(app, d.stream);
  auto* dds = app.add_subcommand("dds", "DDS housekeeping on this host");
  dds->require_subcommand(1, 1);
  dds->add_subcommand("clean",
                      "remove the Fast DDS shared memory (/dev/shm/fastrtps_*) that no live process maps: what "
                      "killed processes left (gcpipe launch and stream do this when they start)");
}
#endif

/// Parses the command line; an exit status when the run ends here (help, version, usage error).
std::optional<int> parse_command_line(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // A mistyped command or option is named, with what was probably meant; CLI11's own message
    // ("A subcommand is required", "not expected: x.yaml --confg") does not say which word.
    if (e.get_exit_code() != 0) {
      const std::string unknown = gcpipe::cli::explain_unknown_words(app, std::vector<std::string>(argv + 1, argv + argc));
      if (!unknown.empty()) {
        std::cerr << "gcpipe: " << unknown << "\n";
        return 2;
      }
    }
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  return std::nullopt;
}

/// Runs the command `name` through `dispatch` (its exit status, or nullopt for no such command)
/// and turns what it throws into an exit status.
int run_command(const std::string& name, const std::function<std::optional<int>()>& dispatch) {
  try {
    if (const auto status = dispatch()) return *status;
  } catch (const std::exception& e) {
    // A long step polls for SIGINT/SIGTERM through its progress callback, which throws.
    if (gcpipe::pipeline::stop_requested()) return 128 + gcpipe::pipeline::stop_signal();
    // Configuration and construction errors arrive here; per-line errors never throw.
    std::cerr << "gcpipe " << name << ": " << e.what() << "\n";
    return 1;
  }
  std::cerr << "gcpipe: no command '" << name << "'\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  // glibc serves an allocation above the mmap threshold from a fresh mmap whose pages fault in
  // again (about 10 us per 4 KiB page on the VM measured) and gives it back when it is freed;
  // below it, from the heap, where freed memory is reused but stays resident. 32 MB: series made
  // again many times (the planner's per-chunk speeds and slow-down factors) stay in the heap,
  // larger ones made once and held are mapped, so that what one phase frees does not stay
  // resident beside the next phase's (issue 12: 317 -> 297 MB peak on the one-hour program when
  // this was set, from 256 MB). The longest series (raw samples, reference) have since gone to
  // scratch files (gcpipe/scratch.hpp) and no longer come from malloc.
  mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);
  mallopt(M_TRIM_THRESHOLD, 512 * 1024 * 1024);
  CLI::App app{"gcpipe: G-code stream-processing pipeline for table-table five-axis machines", "gcpipe"};
  app.set_version_flag("--version", std::string("gcpipe ") + GCPIPE_VERSION);
  app.require_subcommand(1, 1);
  BatchArgs batch;
  ParseArgs parse;
  TrochoidArgs trochoid;
  IkArgs ik;
  SimulateArgs simulate;
  SynthArgs synth;
  TrainIkArgs train_ik;
  TrainSpindleArgs train_spindle;
  add_batch(app, batch);
  add_parse(app, parse);
  add_trochoid(app, trochoid);
  add_ik(app, ik);
  add_simulate(app, simulate);
  auto* stages = app.add_subcommand("stages", "list the registered stages, their edges and ports");
  ConfigArgs config;
  add_config(app, config);
  CalibrateArgs calibrate;
  EvaluateArgs evaluate;
  add_calibrate(app, calibrate);
  add_evaluate(app, evaluate);
  add_train_ik(app, train_ik);
  add_train_spindle(app, train_spindle);
  add_synth(app, synth);
#ifdef GCPIPE_WITH_DDS
  DdsCommands dds;
  add_dds_commands(app, dds);
#endif
  if (const auto status = parse_command_line(app, argc, argv)) return *status;
  std::string name = app.get_subcommands().front()->get_name();
  if (name == "dds") name += "-" + app.get_subcommands().front()->get_subcommands().front()->get_name();
  return run_command(name, [&]() -> std::optional<int> {
    if (name == "batch") return run_batch(batch);
    if (name == "parse") return run_parse(parse);
    if (name == "trochoid") return run_trochoid(trochoid);
    if (name == "ik") return run_ik(ik);
    if (name == "simulate") return run_simulate(simulate);
    if (name == "stages") return (void)stages, run_stages();
    if (name == "config") return run_config(config);
    if (name == "calibrate") return run_calibrate(calibrate);
    if (name == "evaluate") return run_evaluate(evaluate);
    if (name == "train-ik") return run_train_ik(train_ik);
    if (name == "train-spindle") return run_train_spindle(train_spindle);
    if (name == "synth") return run_synth(synth);
#ifdef GCPIPE_WITH_DDS
    if (const void* args = dds.args_of(name)) return run_dds_command(name.c_str(), args);
#endif
    return std::nullopt;
  });
}
