// gcpipe launch PIPELINE.yaml and gcpipe stream IN.nc -o OUTDIR: the supervisor of
// stages/dds/launcher.hpp around the nodes that the pipeline file names.
#include <algorithm>
#include <filesystem>
#include <map>
#include <iostream>

#include "commands.hpp"
#include "dds_runtime.hpp"
#include "dds_tools.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "stage.hpp"
#include "launcher.hpp"
#include "output_dir.hpp"
#include "run_report.hpp"

namespace gcpipe::cli {

namespace fs = std::filesystem;

namespace {

fs::path self_exe() { return fs::read_symlink("/proc/self/exe"); }

dds::LaunchPlan plan_of(const LaunchArgs& a) {
  const fs::path file = a.pipeline.empty() ? default_streaming_file() : fs::path(a.pipeline);
  dds::LaunchPlan plan = dds::load_launch_plan(file);
  // One precedence for every DDS command: --domain, else $GCPIPE_DDS_DOMAIN, else the file's (a
  // user who set the variable to keep a test apart ran on the file's domain 0).
  plan.domain = a.domain ? *a.domain : dds::default_domain(plan.domain);
  return plan;
}

bool runs(const dds::LaunchPlan& plan, const std::string& stage) {
  return std::find(plan.nodes.begin(), plan.nodes.end(), stage) != plan.nodes.end();
}

// A sink writing `file` from `topic`; exit 3 (lines rejected) is a result, as batch's.
dds::LaunchProcess sink_process(const dds::LaunchPlan& plan, const std::string& name, const std::string& topic,
                                const fs::path& file) {
  dds::LaunchProcess p;
  p.name = name;
  p.args = {"sink", "--in", topic, "-o", file.string()};
  const auto dds = dds::plan_dds_args(plan);
  p.args.insert(p.args.end(), dds.begin(), dds.end());
  p.ready_text = "gcpipe sink: ready";
  p.one_shot = true;
  p.ok_statuses = {0, 3};
  return p;
}

// The report sink: report.json, report.txt, summary.json and diagnostics.txt from the nodes' parts.
dds::LaunchProcess report_sink_process(const dds::LaunchPlan& plan, const fs::path& dir) {
  dds::LaunchProcess p;
  p.name = "report-sink";
  p.args = {"report-sink", "-o", dir.string(), "--stages", dds::joined(plan.nodes, ','), "--config", plan.config.string()};
  const auto dds = dds::plan_dds_args(plan);
  p.args.insert(p.args.end(), dds.begin(), dds.end());
  p.ready_text = "gcpipe report-sink: ready";
  p.one_shot = true;
  return p;
}

// Shared memory that processes killed earlier left on this host (a SIGKILLed supervisor's
// children leave theirs): removed before this pipeline's processes map their own.
void clean_dead_shared_memory(const char* command) {
  if (const std::size_t n = dds::clean_dead_shared_memory(); n > 0)
    std::cerr << "gcpipe " << command << ": removed " << n << " shared-memory files of dead DDS processes\n";
}

}  // namespace

int run_dds_clean(const DdsCleanArgs&) {
  const std::size_t n = dds::clean_dead_shared_memory();
  std::cout << "gcpipe dds clean: removed " << n << " shared-memory files no live process maps\n";
  return 0;
}

int run_launch(const LaunchArgs& a) {
  const dds::LaunchPlan plan = plan_of(a);
  dds::install_stop_handlers();
  clean_dead_shared_memory("launch");
  dds::Supervisor sup(self_exe(), plan, std::cerr, a.verbose);
  for (auto& p : dds::node_processes(plan, /*forever=*/true)) sup.add(std::move(p));
  if (!sup.start()) {
    std::cerr << "gcpipe launch: " << sup.message() << "\n";
    return 1;
  }
  const int status = sup.run();
  if (status == 1) std::cerr << "gcpipe launch: " << sup.message() << "\n";
  return status;
}

int run_stream(const StreamArgs& a) {
  dds::LaunchPlan plan = plan_of(a);
  // As for batch: the config the user names is the one every node reads.
  if (!a.config.empty()) plan.config = fs::absolute(a.config);
  if (!runs(plan, "write") && !runs(plan, "compensate"))
    throw std::invalid_argument("the pipeline file runs neither the write nor the compensate node: nothing to write");
  const fs::path out = a.output;
  // Files of an earlier run must not look like this run's: they are replaced or removed.
  pipeline::prepare_output_dir(out, pipeline::run_outputs());

  // One id for this run's program, given to every process of its pipeline: a node or sink takes
  // that program only, so a second pipeline on the same domain can never end up in these files.
  const std::string id = std::to_string(dds::random_program_id());
  // And its own DDS partition: a second pipeline on the same domain does not even match this
  // one's readers and writers (so it cannot take this one's readers for its own, or the other
  // way round); the program id is the second guard.
  // (Not with DDS Security: the permissions make_security.sh writes grant the default partition
  // only; there the program id alone keeps a second pipeline's program out of the files.)
  std::vector<std::string> partition;
  if (plan.identity.empty()) partition = {"--partition", "gcpipe-stream-" + id};
  std::map<std::string, int> sinks;
  std::vector<dds::LaunchProcess> extra;
  if (runs(plan, "write")) {
    extra.push_back(sink_process(plan, "sink output.nc", dds::kGcodeTopicName, out / "output.nc"));
    ++sinks[dds::kGcodeTopicName];
  }
  if (runs(plan, "compensate")) {
    const std::string topic = pipeline::find_stage("compensate").topic;
    extra.push_back(sink_process(plan, "sink compensated.nc", topic, out / "compensated.nc"));
    ++sinks[topic];
  }
  dds::LaunchProcess feed;
  feed.name = "feed";
  feed.args = {"feed", a.input, "--config", plan.config.string(), "--program-id", id};
  if (a.feed_rate > 0) feed.args.insert(feed.args.end(), {"--rate", std::to_string(a.feed_rate)});
  const auto dds_args = dds::plan_dds_args(plan);
  feed.args.insert(feed.args.end(), dds_args.begin(), dds_args.end());
  feed.args.insert(feed.args.end(), partition.begin(), partition.end());
  feed.one_shot = true;

  dds::install_stop_handlers();
  clean_dead_shared_memory("stream");
  dds::Supervisor sup(self_exe(), plan, std::cerr, a.verbose);
  for (auto& p : extra) {
    p.args.insert(p.args.end(), {"--program-id", id});
    p.args.insert(p.args.end(), partition.begin(), partition.end());
    sup.add(std::move(p));
  }
  dds::LaunchProcess report = report_sink_process(plan, out);
  report.args.insert(report.args.end(), {"--program-id", id});
  report.args.insert(report.args.end(), partition.begin(), partition.end());
  sup.add(std::move(report));
  for (auto& p : dds::node_processes(plan, /*forever=*/false, sinks)) {
    // Each node's figures go into OUTDIR, its report part to the report sink.
    p.args.insert(p.args.end(), {"--pipeline-stages", dds::joined(plan.nodes, ','), "--report-dir", out.string(),
                                 "--report-readers", "1", "--program-id", id});
    p.args.insert(p.args.end(), partition.begin(), partition.end());
    sup.add(std::move(p));
  }
  sup.add(std::move(feed));
  if (!sup.start()) {
    std::cerr << "gcpipe stream: " << sup.message() << "\n";
    return 1;
  }
  const int status = sup.run();
  if (status != 0) {
    if (status == 1) std::cerr << "gcpipe stream: " << sup.message() << "\n";
    return status;
  }
  // The sinks' status is batch mode's: 3 when lines or cycles were rejected.
  int result = 0;
  for (const auto& name : {"sink output.nc", "sink compensated.nc"})
    if (sup.exit_status(name) == 3) result = 3;
  std::cerr << "gcpipe stream: wrote " << (runs(plan, "write") ? (out / "output.nc").string() : std::string())
            << (runs(plan, "compensate") ? " " + (out / "compensated.nc").string() : std::string()) << " and "
            << (out / "report.json").string() << " (report.txt, summary.json, diagnostics.txt, plots/)\n";
  return result;
}

}  // namespace gcpipe::cli
