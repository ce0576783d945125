// The stage interface: what every stage of the pipeline implements, so that one chain definition
// serves `gcpipe batch`, every subcommand and every DDS node (stages/README.md).
//
// A stage consumes one kind of input (program text lines, or resolved blocks with the line
// diagnostics between them), emits any number of items downstream through an Emitter, and at the
// end of a program may emit more (a compensated program), contribute to the report and draw its
// figures. Stages know nothing of DDS or files; the runner (pipeline.hpp) and the generic DDS node
// (stages/dds/stage_node.hpp) connect them.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "gcpipe/block.hpp"
#include "gcpipe/diagnostic.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "gcpipe/telemetry.hpp"

namespace gcpipe::pipeline {

/// What travels on an edge. kProgram: source text, line by line (a G-code program; for the
/// calibrate stage the rows of a measured trace); kBlocks: resolved blocks and the diagnostics of
/// lines that produced none, in source order; kGcode: written program text; kNone: nothing — the
/// stage's result is its product and its report (calibrate), so no stage can hang off it.
enum class Port : std::uint8_t { kProgram, kBlocks, kGcode, kNone };
const char* to_string(Port port);

/// What a stage emits for monitors beside its output: Emitter::ik_point or Emitter::sample.
enum class Telemetry : std::uint8_t { kNone, kIkPoints, kSamples };

/// A result too large or too rich for an edge's items that a stage hands to the next one in the
/// same process (the simulation of a whole program, handed from `simulate` to `compensate`).
/// A consumer that gets none computes what it needs itself, so a stage also works alone.
struct Product {
  virtual ~Product() = default;
};

/// Where a stage's output goes: the next stage, a file, or a DDS writer.
class Emitter {
 public:
  virtual ~Emitter() = default;
  /// False: downstream asks to stop this program (strict mode, a full disk).
  virtual bool block(const ResolvedBlock& block) = 0;
  virtual bool diagnostic(const Diagnostic& diag, DiagnosticKind kind) = 0;
  /// Written G-code; the consumer takes the text and leaves `gcode` empty.
  virtual bool text(std::string& gcode) = 0;
  virtual void product(const std::shared_ptr<const Product>& product) = 0;
  /// Telemetry for monitors (gcpipe/telemetry.hpp): not part of the program, never waited for.
  /// A stage produces it only when the emitter listens, so a run without monitors pays nothing.
  virtual bool wants_telemetry() const { return false; }
  virtual void ik_point(const IkTelemetry&) {}
  virtual void sample(const SampleTelemetry&) {}
};

/// Every diagnostic a stage raises (not the ones it forwards) is also reported here, once: the
/// runner's log writes diagnostics.txt and stderr, a DDS node's log stderr.
class DiagnosticLog {
 public:
  virtual ~DiagnosticLog() = default;
  virtual void report(const Diagnostic& diag) = 0;
};

/// Progress of a long step: (what, done, total).
using Progress = std::function<void(const char* what, std::uint64_t done, std::uint64_t total)>;

/// What a stage is built from: the pipeline config, the input's name and the command line's
/// overrides of config keys.
struct StageContext {
  const PipelineConfig* config = nullptr;
  std::string file;               //!< input name, for diagnostics
  DiagnosticLog* log = nullptr;   //!< never null while stages run
  Progress progress;              //!< may be empty
  bool strict = false;            //!< --strict (or parse.strict): stop a program at its first error
  bool keep_going = false;        //!< --keep-going: compensate a program although lines of it were rejected
  std::string ik_model;           //!< --model: neural IK model instead of the config's ik.model
  bool ik_tool_vector = false;    //!< --tool-vector: TCP blocks give only their tool vector
  std::vector<std::string> stages;  //!< names of the stages in this process (set by Pipeline)
  /// The stages of the whole pipeline when this process runs a part of it (a DDS node), else
  /// empty (= `stages`). A stage whose work a later stage reports again (simulate, when
  /// compensate follows anywhere) leaves the report to that one.
  std::vector<std::string> pipeline_stages;
  /// The pipeline's stages, wherever they run.
  const std::vector<std::string>& whole_pipeline() const { return pipeline_stages.empty() ? stages : pipeline_stages; }
};

/// What a stage contributes at the end of a program: its keys of report.json (by convention one
/// object named after the stage; the parse stage's line counts stand at the top), lines of
/// report.txt, and figures drawn into `dir` when there is one.
struct ReportContext {
  nlohmann::ordered_json* json = nullptr;  //!< the whole report object
  std::string* text = nullptr;     //!< report.txt, each line starting with two blanks
  std::filesystem::path dir;       //!< output folder; empty: no files (a DDS node)
  std::string input_base;          //!< input file name without folders, for titles
  std::vector<std::string>* files = nullptr;  //!< files written, relative to dir
  Progress progress;
};

class Stage {
 public:
  virtual ~Stage() = default;
  /// One source line (stages whose input is Port::kProgram). `overlong_length` > 0: the reader cut
  /// the line at the maximum length and it had that many bytes.
  virtual bool line(std::string_view text, std::size_t overlong_length, Emitter& out);
  /// One block (stages whose input is Port::kBlocks). False stops the program.
  virtual bool block(const ResolvedBlock& block, Emitter& out) = 0;
  /// A diagnostic from upstream; the default hands it on.
  virtual bool diagnostic(const Diagnostic& diag, DiagnosticKind kind, Emitter& out) {
    return out.diagnostic(diag, kind);
  }
  /// A product from upstream; the default hands it on.
  virtual void product(const std::shared_ptr<const Product>& p, Emitter& out) { out.product(p); }
  /// End of program. `complete`: every line arrived and none stopped the program.
  virtual bool finish(bool complete, Emitter& out) {
    (void)complete;
    (void)out;
    return true;
  }
  /// Report section and figures (after finish).
  virtual void report(ReportContext& r) const { (void)r; }
  /// Non-empty when this stage could not do its job for the program (the reason): the run's exit
  /// status is then non-zero even though every line was read.
  virtual std::string failure() const { return {}; }
  /// Lines or cycles this stage rejected (exit status 3 when any).
  virtual std::uint64_t rejected() const { return 0; }
};

/// A registered stage: its place in the chain and how to build it.
struct StageInfo {
  const char* name;
  const char* upstream;  //!< the stage whose output this one consumes ("" for the source)
  const char* summary;   //!< one line, for --help and `gcpipe stages`
  Port input;
  Port output;
  std::unique_ptr<Stage> (*make)(const StageContext& context);
  /// The DDS topic its output goes on when it runs as a node ("" = not on DDS yet); a node reads
  /// the topic of its nearest upstream that has one (the program topic for the source).
  const char* topic = "";
  /// What telemetry it emits, and the topic that goes on as a node (IkBatch for IK points,
  /// SampleBatch for samples, idl/gcpipe.idl; published on the keep-last monitor copy only).
  Telemetry telemetry = Telemetry::kNone;
  const char* telemetry_topic = "";
};

/// Every stage, in pipeline order (generated from stages/CMakeLists.txt's GCPIPE_STAGES list).
const std::vector<StageInfo>& registry();
/// The registered stage called `name`; throws std::runtime_error listing the known names.
const StageInfo& find_stage(std::string_view name);
/// The topic `gcpipe feed` publishes programs on, which the source stage reads.
inline constexpr const char* kProgramTopic = "gcpipe_program";
/// The topic stage `name` reads by default as a node: its nearest upstream's with a topic.
std::string input_topic(std::string_view name);

}  // namespace gcpipe::pipeline
