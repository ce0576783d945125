// gcpipe launch and gcpipe stream (stages/dds/launcher.hpp): the supervised pipeline writes batch
// mode's bytes, stops loudly and within a bound when a stage dies, starts a stage again when the
// pipeline file says so, stops everything on SIGINT, and leaves no shared memory behind. Each test
// runs on a DDS domain of its own (224-229: above the 20-99 that dds_pipeline_test's tests claim, and
// with ports above Linux's ephemeral range),
// so that tests running side by side never mix.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <chrono>
#include <regex>
#include <thread>

#include "cli_helpers.hpp"
#include "cpu_hog.hpp"

namespace {

const fs::path kSource = GCPIPE_SOURCE_DIR;

// A pipeline file for `domain` with the shipped default config; `extra` adds pipeline: keys.
fs::path pipeline_file(const fs::path& dir, int domain, const std::string& extra = "",
                       const std::string& nodes = "[parse, trochoid, write, force, compensate]") {
  const fs::path f = dir / "pipeline.yaml";
  std::ofstream(f) << "pipeline:\n  name: test\n  domain: " << domain << "\n  config: "
                   << (kSource / "pipeline_configs" / "default.yaml").string() << "\n" << extra << "nodes: " << nodes << "\n";
  return f;
}

bool wait_for(const fs::path& log, const std::string& text, double limit_s) {
  const auto t0 = std::chrono::steady_clock::now();
  while (slurp(log).find(text) == std::string::npos) {
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > limit_s) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return true;
}

// Exit status of `pid`, or -1 when it has not ended within `limit_s` (then it is killed).
int wait_exit(pid_t pid, double limit_s, double* took = nullptr) {
  const auto t0 = std::chrono::steady_clock::now();
  int st = 0;
  for (;;) {
    if (waitpid(pid, &st, WNOHANG) == pid) break;
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > limit_s) {
      kill(pid, SIGKILL);
      waitpid(pid, &st, 0);
      return -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  if (took) *took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

std::size_t occurrences(const std::string& text, const std::string& part) {
  std::size_t n = 0;
  for (std::size_t at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) ++n;
  return n;
}

// A stream of the seed 000 slot with its feed paced at `rate` bytes/s (so the program is still in
// flight when the test acts), once every process it started is ready; its log is dir/stream.log.
pid_t paced_slot_stream(const fs::path& dir, int domain, int rate) {
  const fs::path log = dir / "stream.log";
  const pid_t stream = spawn_gcpipe({"stream", (kSource / "samples" / "trochoid_slot_seed000.nc").string(), "-o",
                                     (dir / "out").string(), "--domain", std::to_string(domain), "--feed-rate",
                                     std::to_string(rate)},
                                    dir / "stream.out", log);
  EXPECT_TRUE(wait_for(log, "processes ready", 60)) << slurp(log);
  return stream;
}

// Those of `pids` still running: an orphan that exited is a zombie until whoever adopted it
// reaps it, and counts as gone.
int still_running(const std::vector<pid_t>& pids) {
  int n = 0;
  for (pid_t p : pids) {
    const std::string status = slurp(fs::path("/proc") / std::to_string(p) / "status");
    n += !status.empty() && status.find("State:\tZ") == std::string::npos;
  }
  return n;
}

// The pid of the node process `stage` that the launcher started for `domain`.
pid_t node_pid(const fs::path& log, const std::string& stage) {
  const std::regex re("  " + stage + ": started \\(pid ([0-9]+)\\)");
  std::smatch m;
  const std::string text = slurp(log);
  pid_t pid = -1;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator(); ++it)
    pid = std::stoi((*it)[1]);  // the newest start
  return pid;
}

// Shared-memory files of the ports of `domain` (Fast DDS: 7400 + 250 domain + 10 + participant).
std::vector<std::string> shm_of_domain(int domain) {
  std::vector<std::string> left;
  const int base = 7400 + 250 * domain + 10;
  for (const auto& e : fs::directory_iterator("/dev/shm")) {
    const std::string n = e.path().filename().string();
    for (int k = 0; k < 20; ++k)
      if (n.find("fastrtps_port" + std::to_string(base + k)) != std::string::npos) left.push_back(n);
  }
  return left;
}

}  // namespace

TEST(Stream, WritesBatchModesBytesOnTheSamples) {
  for (const char* sample : {"five_axis_demo.nc", "trochoid_slot_seed000.nc"}) {
    SCOPED_TRACE(sample);
    const fs::path dir = tmpdir(std::string("stream_") + sample);
    const fs::path in = kSource / "samples" / sample;
    const Outcome batch = gcpipe({"batch", in.string(), "-o", (dir / "batch").string(), "--quiet"});
    ASSERT_EQ(batch.status, 0) << batch.err;
    // A stale file in the output folder must not survive the run.
    fs::create_directories(dir / "stream");
    std::ofstream(dir / "stream" / "compensated.nc") << "stale\n";
    // A monitor of the whole pipeline, up before the stream starts, sees every stage end the
    // program (on the short demo: the slot's 21 MB of ticks in 0.4 s can outrun a monitor on a
    // busy machine, and the keep-last copies then drop what it cannot take, as they must).
    const bool watch = std::string(sample) == "five_axis_demo.nc";
    const fs::path watched = dir / "monitor.txt";
    pid_t monitor = -1;
    if (watch) {
      monitor = spawn_gcpipe({"monitor", "--pipeline", "streaming", "--domain", "225", "--period", "5",
                              "--idle-timeout", "120"}, watched, dir / "monitor.err");
      ASSERT_TRUE(wait_for(watched, "gcpipe monitor: pipeline streaming", 30)) << slurp(dir / "monitor.err");
    }
    const Outcome s = gcpipe({"stream", in.string(), "-o", (dir / "stream").string(), "--domain", "225"});
    ASSERT_EQ(s.status, 0) << s.err;
    if (watch) {
      EXPECT_EQ(wait_exit(monitor, 60), 0) << slurp(watched) << slurp(dir / "monitor.err");
      const std::string seen = slurp(watched);
      EXPECT_EQ(occurrences(seen, "end of program"), 9u) << seen;  // seven edges and the two telemetry topics
      EXPECT_EQ(seen.find("MISSING"), std::string::npos) << seen;
      EXPECT_EQ(seen.find("joined late"), std::string::npos) << seen;
    }
    // Seven nodes, two G-code sinks, the report sink and the feed.
    EXPECT_NE(s.err.find("all 11 processes ready"), std::string::npos) << s.err;
    EXPECT_TRUE(slurp(dir / "stream" / "output.nc") == slurp(dir / "batch" / "output.nc"));
    EXPECT_TRUE(slurp(dir / "stream" / "compensated.nc") == slurp(dir / "batch" / "compensated.nc"));
    // The report from the nodes' parts equals batch's but for the wall time; so do the figures.
    for (const char* name : {"report.json", "summary.json"}) {
      auto streamed = nlohmann::json::parse(slurp(dir / "stream" / name));
      auto expected = nlohmann::json::parse(slurp(dir / "batch" / name));
      streamed.erase("seconds");
      expected.erase("seconds");
      EXPECT_EQ(streamed, expected) << name;
    }
    EXPECT_TRUE(slurp(dir / "stream" / "diagnostics.txt") == slurp(dir / "batch" / "diagnostics.txt"));
    const auto outputs = nlohmann::json::parse(slurp(dir / "batch" / "report.json"))["outputs"];
    EXPECT_GE(outputs.size(), 8u);
    for (const auto& file : outputs) {
      const std::string f = file.get<std::string>();
      if (f.rfind("plots/", 0) == 0) EXPECT_TRUE(slurp(dir / "stream" / f) == slurp(dir / "batch" / f)) << f;
    }
  }
  EXPECT_TRUE(shm_of_domain(225).empty());
}

// The shipped monitoring pipeline: output.nc as batch writes it, and nothing compensated; its ik
// and simulate nodes are there for monitors only, so the simulate node's edge has no reader and
// it must not wait for one. A monitor of the pipeline, up first, sees all seven topics end the
// program, and the contour error batch reports.
TEST(Stream, TheMonitoringPipelineWritesTheProgramAndShowsItsTelemetry) {
  const fs::path dir = tmpdir("stream_monitoring");
  const fs::path in = kSource / "samples" / "five_axis_demo.nc";
  const Outcome batch = gcpipe({"batch", in.string(), "-o", (dir / "batch").string(), "--quiet"});
  ASSERT_EQ(batch.status, 0) << batch.err;
  const fs::path watched = dir / "monitor.txt";
  const pid_t monitor = spawn_gcpipe({"monitor", "--pipeline", "monitoring", "--domain", "227", "--period", "5",
                                      "--idle-timeout", "120"}, watched, dir / "monitor.err");
  ASSERT_TRUE(wait_for(watched, "gcpipe monitor: pipeline monitoring", 30)) << slurp(dir / "monitor.err");
  const Outcome s = gcpipe({"stream", in.string(), "-o", (dir / "stream").string(), "--pipeline",
                            (kSource / "pipeline_configs" / "pipelines" / "monitoring.yaml").string(), "--domain", "227"});
  ASSERT_EQ(s.status, 0) << s.err;
  EXPECT_TRUE(slurp(dir / "stream" / "output.nc") == slurp(dir / "batch" / "output.nc"));
  EXPECT_FALSE(fs::exists(dir / "stream" / "compensated.nc"));
  EXPECT_EQ(wait_exit(monitor, 60), 0) << slurp(watched) << slurp(dir / "monitor.err");
  const std::string seen = slurp(watched);
  EXPECT_EQ(occurrences(seen, "end of program"), 7u) << seen;  // five edges and the two telemetry topics
  EXPECT_EQ(seen.find("MISSING"), std::string::npos) << seen;
  // The last status line of the simulated ticks holds the program's whole maximum.
  const std::regex status("contour um: now [0-9.]+ max ([0-9.]+)");
  std::string last_max;
  for (auto it = std::sregex_iterator(seen.begin(), seen.end(), status); it != std::sregex_iterator(); ++it)
    last_max = (*it)[1];
  ASSERT_FALSE(last_max.empty()) << seen;
  const double max_mm = nlohmann::json::parse(slurp(dir / "batch" / "report.json"))["simulation"]["contour_error_before"]["cutting"]["max_mm"];
  EXPECT_NEAR(std::stod(last_max) * 1e-3, max_mm, 1e-6) << seen;
  EXPECT_TRUE(shm_of_domain(227).empty());
}

// Two pipelines at once, each on the domain its file names: neither sees the other's programs
// and both write batch's bytes.
TEST(Stream, TwoPipelinesOnOneHostStayApart) {
  const fs::path dir = tmpdir("stream_two");
  const std::vector<std::pair<std::string, int>> runs = {{"five_axis_demo.nc", 224}, {"tool_vector_demo.nc", 226}};
  std::vector<pid_t> pids;
  for (const auto& [sample, domain] : runs) {
    const fs::path in = kSource / "samples" / sample;
    const Outcome batch = gcpipe({"batch", in.string(), "-o", (dir / ("batch_" + sample)).string(), "--quiet"});
    ASSERT_EQ(batch.status, 0) << batch.err;
  }
  for (const auto& [sample, domain] : runs)
    pids.push_back(spawn_gcpipe({"stream", (kSource / "samples" / sample).string(), "-o", (dir / ("stream_" + sample)).string(),
                                 "--domain", std::to_string(domain)},
                                dir / (sample + ".out"), dir / (sample + ".err")));
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const std::string& sample = runs[i].first;
    SCOPED_TRACE(sample);
    EXPECT_EQ(wait_exit(pids[i], 120), 0) << slurp(dir / (sample + ".err"));
    for (const char* f : {"output.nc", "compensated.nc"})
      EXPECT_TRUE(slurp(dir / ("stream_" + sample) / f) == slurp(dir / ("batch_" + sample) / f)) << f;
    EXPECT_EQ(slurp(dir / (sample + ".err")).find("second writer"), std::string::npos);
  }
}

// Two pipelines on ONE domain (a user who forgot to give each its own): each stream run has its
// own DDS partition, so neither matches the other's readers and writers, and every process takes
// only its feed's program id besides. Each writes batch's bytes of its own program, never the
// other's.
TEST(Stream, TwoStreamsOnOneDomainNeverWriteEachOthersProgram) {
  const fs::path dir = tmpdir("stream_shared_domain");
  const std::vector<std::string> samples = {"five_axis_demo.nc", "tool_vector_demo.nc"};
  for (const auto& sample : samples) {
    const Outcome batch = gcpipe({"batch", (kSource / "samples" / sample).string(), "-o", (dir / ("batch_" + sample)).string(), "--quiet"});
    ASSERT_EQ(batch.status, 0) << batch.err;
  }
  std::vector<pid_t> pids;
  for (const auto& sample : samples)
    pids.push_back(spawn_gcpipe({"stream", (kSource / "samples" / sample).string(), "-o", (dir / ("stream_" + sample)).string(),
                                 "--domain", "221"},
                                dir / (sample + ".out"), dir / (sample + ".err")));
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const std::string& sample = samples[i];
    const std::string& other = samples[1 - i];
    SCOPED_TRACE(sample);
    int status = wait_exit(pids[i], 240);
    // Known defect, not this test's subject: now and then (1 run in 7 on an idle 2-core VM) a
    // feed and its parse node never match in Fast DDS's discovery and the feed gives up after 30 s
    // (loudly, exit 1). The stream is then run once more, on the same shared domain, and says so.
    if (status != 0 && slurp(dir / (sample + ".err")).find("no reader of gcpipe_program within") != std::string::npos) {
      std::printf("%s: feed and parse never matched (known Fast DDS discovery defect); running the stream again\n", sample.c_str());
      const pid_t again = spawn_gcpipe({"stream", (kSource / "samples" / sample).string(), "-o", (dir / ("stream_" + sample)).string(),
                                        "--domain", "221"},
                                       dir / (sample + ".out"), dir / (sample + ".err"));
      status = wait_exit(again, 240);
    }
    EXPECT_EQ(status, 0) << slurp(dir / (sample + ".err"));
    for (const char* f : {"output.nc", "compensated.nc"}) {
      const fs::path written = dir / ("stream_" + sample) / f;
      EXPECT_FALSE(slurp(written) == slurp(dir / ("batch_" + other) / f)) << f << " holds " << other;
      EXPECT_TRUE(slurp(written) == slurp(dir / ("batch_" + sample) / f)) << f;
    }
    EXPECT_TRUE(slurp(dir / ("stream_" + sample) / "report.txt").find(other) == std::string::npos);
  }
}

// One precedence for the domain of every DDS command: --domain, else $GCPIPE_DDS_DOMAIN, else the
// pipeline file's (stream and launch used to run on the file's domain 0 whatever the variable).
TEST(Stream, RunsOnTheDomainOfGcpipeDdsDomain) {
  const fs::path dir = tmpdir("stream_env_domain");
  const fs::path in = kSource / "samples" / "five_axis_demo.nc";
  ASSERT_EQ(setenv("GCPIPE_DDS_DOMAIN", "223", 1), 0);  // domains of their own: ctest runs tests side by side
  const Outcome s = gcpipe({"stream", in.string(), "-o", (dir / "stream").string()});
  const Outcome flag = gcpipe({"stream", in.string(), "-o", (dir / "flag").string(), "--domain", "219"});
  unsetenv("GCPIPE_DDS_DOMAIN");
  EXPECT_EQ(s.status, 0) << s.err;
  EXPECT_NE(s.err.find("(DDS domain 223)"), std::string::npos) << s.err;
  EXPECT_EQ(flag.status, 0) << flag.err;
  EXPECT_NE(flag.err.find("(DDS domain 219)"), std::string::npos) << flag.err;
}

// A supervisor killed with SIGKILL cannot stop its children: they follow it (PR_SET_PDEATHSIG)
// and leave within seconds instead of serving on the domain, shared memory and all, for ever.
TEST(Stream, ItsProcessesLeaveWhenTheStreamIsKilled) {
  const fs::path dir = tmpdir("stream_killed");
  const fs::path log = dir / "stream.log";
  const pid_t stream = paced_slot_stream(dir, 218, 200);
  std::vector<pid_t> children;
  for (const char* name : {"feed", "parse", "write", "compensate", "sink output.nc", "report-sink"}) {
    children.push_back(node_pid(log, name));
    ASSERT_GT(children.back(), 0) << name << "\n" << slurp(log);
  }
  kill(stream, SIGKILL);
  wait_exit(stream, 10);
  const auto t0 = std::chrono::steady_clock::now();
  while (still_running(children) > 0 && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(15))
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("children of the killed stream gone after %.2f s\n", took);
  EXPECT_EQ(still_running(children), 0) << "children still running 15 s after their supervisor was killed";
  // They leave all at once, and Fast DDS then leaves port files of the domain in /dev/shm (their
  // segments too): the next stream removes what no live process maps, as `gcpipe dds clean` does.
  std::printf("shared-memory files of domain 218 left by the killed run: %zu\n", shm_of_domain(218).size());
  const Outcome next = gcpipe({"stream", (kSource / "samples" / "five_axis_demo.nc").string(), "-o", (dir / "next").string(),
                               "--domain", "218"});
  EXPECT_EQ(next.status, 0) << next.err;
  EXPECT_TRUE(shm_of_domain(218).empty()) << "shared memory left after the next stream on the domain";
}

// Stop means stop: SIGTERM to a stream mid-program ends every process it started within a
// bound that holds under load (3 s asserted; the time is printed), none of them killed by the
// supervisor's SIGKILL fallback, and no file that looks complete: outputs only as .part.
TEST(Stream, SigtermMidProgramStopsEveryProcessAndLeavesOnlyPartFiles) {
  const fs::path dir = tmpdir("stream_sigterm");
  const fs::path log = dir / "stream.log";
  const pid_t stream = paced_slot_stream(dir, 217, 300);
  std::this_thread::sleep_for(std::chrono::seconds(1));  // the program is in flight (paced feed)
  std::vector<pid_t> children;
  for (const char* name : {"feed", "parse", "trochoid", "write", "force", "ik", "simulate", "compensate", "sink output.nc",
                           "sink compensated.nc", "report-sink"})
    children.push_back(node_pid(log, name));
  kill(stream, SIGTERM);
  double took = 0;
  const int status = wait_exit(stream, 30, &took);
  std::printf("stream stopped %.2f s after SIGTERM, exit %d\n", took, status);
  EXPECT_EQ(status, 143);  // 128 + SIGTERM, as every gcpipe command
  EXPECT_LT(took, 3.0) << slurp(log);
  EXPECT_EQ(slurp(log).find("killed by signal 9"), std::string::npos) << "a process needed SIGKILL:\n" << slurp(log);
  EXPECT_EQ(still_running(children), 0) << "processes of the stream still running after it exited";
  for (const char* f : {"output.nc", "compensated.nc", "report.json"}) EXPECT_FALSE(fs::exists(dir / "out" / f)) << f;
}

TEST(Stream, APipelineWithoutTheForceNodeReadsTheToolpathDirectly) {
  const fs::path dir = tmpdir("stream_noforce");
  const fs::path in = kSource / "samples" / "five_axis_demo.nc";
  const fs::path file = pipeline_file(dir, 226, "", "[parse, trochoid, write, compensate]");
  const Outcome batch = gcpipe({"batch", in.string(), "-o", (dir / "batch").string(), "--quiet"});
  ASSERT_EQ(batch.status, 0);
  const Outcome s = gcpipe({"stream", in.string(), "-o", (dir / "stream").string(), "--pipeline", file.string()});
  ASSERT_EQ(s.status, 0) << s.err;
  // Without a force section the force stage passes blocks through, so the bytes are batch's.
  EXPECT_TRUE(slurp(dir / "stream" / "compensated.nc") == slurp(dir / "batch" / "compensated.nc"));
}

// Stages grouped into processes (`groups:`): two processes run the seven stages, each stage in a
// thread of its own, and write batch's bytes; a group that dies is named and stops the pipeline.
TEST(Stream, GroupedStagesWriteBatchModesBytes) {
  const fs::path dir = tmpdir("stream_groups");
  const fs::path in = kSource / "samples" / "trochoid_slot_f3000.nc";
  const fs::path file = pipeline_file(dir, 226, "groups: [parse+trochoid+write, ik+force+simulate+compensate]\n",
                                      "[parse, trochoid, write, force, ik, simulate, compensate]");
  const Outcome batch = gcpipe({"batch", in.string(), "-o", (dir / "batch").string(), "--quiet"});
  ASSERT_EQ(batch.status, 0) << batch.err;
  const Outcome s = gcpipe({"stream", in.string(), "-o", (dir / "stream").string(), "--pipeline", file.string()});
  ASSERT_EQ(s.status, 0) << s.err;
  // Two groups, two G-code sinks, the report sink and the feed.
  EXPECT_NE(s.err.find("all 6 processes ready"), std::string::npos) << s.err;
  EXPECT_NE(s.err.find("force+ik+simulate+compensate: started"), std::string::npos) << s.err;  // chain order
  EXPECT_TRUE(slurp(dir / "stream" / "output.nc") == slurp(dir / "batch" / "output.nc"));
  EXPECT_TRUE(slurp(dir / "stream" / "compensated.nc") == slurp(dir / "batch" / "compensated.nc"));
  auto streamed = nlohmann::json::parse(slurp(dir / "stream" / "report.json"));
  auto expected = nlohmann::json::parse(slurp(dir / "batch" / "report.json"));
  streamed.erase("seconds");
  expected.erase("seconds");
  EXPECT_EQ(streamed, expected);
  // A dead group stops the pipeline, named as the process it is.
  const fs::path log = dir / "launch.log";
  const pid_t launch = spawn_gcpipe({"launch", file.string()}, dir / "out", log);
  ASSERT_TRUE(wait_for(log, "all 2 processes ready", 60)) << slurp(log);
  const pid_t victim = node_pid(log, "parse\\+trochoid\\+write");
  ASSERT_GT(victim, 0) << slurp(log);
  ASSERT_EQ(kill(victim, SIGKILL), 0);
  EXPECT_EQ(wait_exit(launch, 30), 1) << slurp(log);
  EXPECT_NE(slurp(log).find("stage parse+trochoid+write stopped (killed by signal 9)"), std::string::npos) << slurp(log);
  EXPECT_TRUE(shm_of_domain(226).empty());
}

TEST(Launch, ADeadStageStopsThePipelineNamingItAndLeavesNoSharedMemory) {
  const fs::path dir = tmpdir("launch_kill");
  // Every stage between the ends in turn, and the last one.
  for (const char* stage : {"trochoid", "force", "ik", "simulate", "compensate"}) {
    SCOPED_TRACE(stage);
    const fs::path log = dir / (std::string(stage) + ".log");
    const fs::path file = pipeline_file(dir, 227, "", "[parse, trochoid, write, force, ik, simulate, compensate]");
    const pid_t launch = spawn_gcpipe({"launch", file.string()}, dir / "out", log);
    ASSERT_TRUE(wait_for(log, "all 7 processes ready", 60)) << slurp(log);
    const pid_t victim = node_pid(log, stage);
    ASSERT_GT(victim, 0);
    ASSERT_EQ(kill(victim, SIGKILL), 0);
    double took = 0;
    EXPECT_EQ(wait_exit(launch, 30, &took), 1) << slurp(log);
    EXPECT_LT(took, 10) << "the pipeline took too long to stop";
    EXPECT_NE(slurp(log).find(std::string("stage ") + stage + " stopped (killed by signal 9)"), std::string::npos) << slurp(log);
    EXPECT_TRUE(shm_of_domain(227).empty()) << "shared memory left after the pipeline stopped";
  }
}

TEST(Launch, RestartsACrashedStageWhenTheFileSaysSoAndStopsOnSigint) {
  const fs::path dir = tmpdir("launch_restart");
  const fs::path log = dir / "launch.log";
  const pid_t launch = spawn_gcpipe({"launch", pipeline_file(dir, 228, "  on_crash: restart\n").string()}, dir / "out", log);
  ASSERT_TRUE(wait_for(log, "all 5 processes ready", 60)) << slurp(log);
  const pid_t first = node_pid(log, "write");
  ASSERT_GT(first, 0);
  kill(first, SIGKILL);
  ASSERT_TRUE(wait_for(log, "write: restarting (1 of 3)", 20)) << slurp(log);
  // The restarted process's own "started (pid)" line (the first "ready after" is in the log already).
  for (int i = 0; i < 400 && node_pid(log, "write") == first; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_NE(node_pid(log, "write"), first) << slurp(log);
  auto readies = [&] {
    const std::string text = slurp(log);
    int n = 0;
    for (std::size_t at = text.find("write: ready after"); at != std::string::npos; at = text.find("write: ready after", at + 1)) ++n;
    return n;
  };
  for (int i = 0; i < 400 && readies() < 2; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(readies(), 2) << slurp(log);
  kill(launch, SIGINT);
  EXPECT_EQ(wait_exit(launch, 30), 130) << slurp(log);
  EXPECT_TRUE(shm_of_domain(228).empty());
}

// A stage that dies with a program in flight is started again, but does not resume that program
// (its input's history died with the process, and the feed had already gone): the pipeline says
// so loudly instead. The program's sink ends INCOMPLETE naming the dead stage, within the
// heartbeat timeout; the restarted stage then serves the next program, with batch's bytes.
TEST(Launch, ARestartedStageLosesTheProgramInFlightLoudlyAndServesTheNext) {
  const fs::path dir = tmpdir("launch_restart_mid_program");
  const fs::path log = dir / "launch.log";
  const fs::path big = dir / "big.nc", small = kSource / "samples" / "five_axis_demo.nc";
  ASSERT_EQ(gcpipe({"synth", "--blocks", "400000", "--seed", "3", "-o", big.string()}).status, 0);
  const Outcome batch = gcpipe({"batch", small.string(), "-o", (dir / "batch").string(), "--quiet", "--no-simulate"});
  ASSERT_EQ(batch.status, 0) << batch.err;
  const std::vector<std::string> dds = {"--domain", "228", "--idle-timeout", "60"};
  auto with_dds = [&](std::vector<std::string> args) {
    args.insert(args.end(), dds.begin(), dds.end());
    return args;
  };
  const pid_t launch = spawn_gcpipe(
      {"launch", "-v", pipeline_file(dir, 228, "  on_crash: restart\n", "[parse, trochoid, write]").string()}, dir / "out", log);
  // A failed assertion must not leave the pipeline running into the next test on this domain.
  struct StopOnExit {
    pid_t pid;
    ~StopOnExit() {
      if (kill(pid, SIGINT) == 0) wait_exit(pid, 30);
    }
  } stop_launch{launch};
  ASSERT_TRUE(wait_for(log, "all 3 processes ready", 60)) << slurp(log);
  const pid_t first_parse = node_pid(log, "parse");
  const pid_t sink1 = spawn_gcpipe(with_dds({"sink", "-o", (dir / "first.nc").string()}), dir / "sink1.out", dir / "sink1.err");
  ASSERT_TRUE(wait_for(dir / "sink1.err", "gcpipe sink: ready", 30)) << slurp(dir / "sink1.err");
  // Parse is killed once its first batches are out: mid-program (its 400,000 lines take it
  // about a second), as a monitor of its edge sees.
  const pid_t watch = spawn_gcpipe(with_dds({"monitor", "gcpipe_blocks", "--period", "0.05"}), dir / "watch.out", dir / "watch.err");
  ASSERT_TRUE(wait_for(dir / "watch.out", "matched", 30)) << slurp(dir / "watch.out") << slurp(dir / "watch.err");
  const pid_t feed1 = spawn_gcpipe(with_dds({"feed", big.string()}), dir / "feed1.out", dir / "feed1.err");
  const std::regex started("batches [1-9]");
  for (int i = 0; i < 3000 && !std::regex_search(slurp(dir / "watch.out"), started); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_TRUE(std::regex_search(slurp(dir / "watch.out"), started)) << slurp(dir / "watch.out");
  ASSERT_EQ(kill(first_parse, SIGKILL), 0);
  double took = 0;
  EXPECT_EQ(wait_exit(sink1, 30, &took), 1) << slurp(dir / "sink1.err");
  std::printf("the sink gave up %.2f s after the kill\n", took);
  // The heartbeat (4 s) names the dead stage before its discovery lease (8 s) runs out; in about
  // 1 run of 9 the heartbeat pair never matches (stages/dds/README.md "Watchdog") and the lease
  // tells instead, naming the edge: either is a loud end, never a silent one.
  const std::string err1 = slurp(dir / "sink1.err");
  const bool by_heartbeat = err1.find("the parse stage") != std::string::npos && err1.find("sent no heartbeat") != std::string::npos;
  const bool by_lease = err1.find("the writer of gcpipe_blocks went away") != std::string::npos;
  EXPECT_TRUE(by_heartbeat || by_lease) << err1;
  std::printf("told by %s\n", by_heartbeat ? "the heartbeat" : "the discovery lease");
  EXPECT_FALSE(fs::exists(dir / "first.nc"));
  EXPECT_NE(wait_exit(feed1, 30), 0) << slurp(dir / "feed1.err");  // its reader went away
  ASSERT_TRUE(wait_for(log, "parse: restarting (1 of 3)", 20)) << slurp(log);
  for (int i = 0; i < 400 && node_pid(log, "parse") == first_parse; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ASSERT_NE(node_pid(log, "parse"), first_parse) << slurp(log);
  // The next program goes through the restarted stage whole.
  const pid_t sink2 = spawn_gcpipe(with_dds({"sink", "-o", (dir / "second.nc").string()}), dir / "sink2.out", dir / "sink2.err");
  ASSERT_TRUE(wait_for(dir / "sink2.err", "gcpipe sink: ready", 30)) << slurp(dir / "sink2.err");
  const pid_t feed2 = spawn_gcpipe(with_dds({"feed", small.string()}), dir / "feed2.out", dir / "feed2.err");
  EXPECT_EQ(wait_exit(feed2, 60), 0) << slurp(dir / "feed2.err");
  EXPECT_EQ(wait_exit(sink2, 60), 0) << slurp(dir / "sink2.err") << slurp(log);
  EXPECT_TRUE(slurp(dir / "second.nc") == slurp(dir / "batch" / "output.nc"));
  kill(watch, SIGTERM);
  wait_exit(watch, 10);
  kill(launch, SIGINT);
  EXPECT_EQ(wait_exit(launch, 30), 130) << slurp(log);
  EXPECT_TRUE(shm_of_domain(228).empty());
}

// Issue 34: a compensate node killed while it collected a program was never noticed (its sink
// stayed "ready" past 120 s): it sends nothing before the program's end, so no sample of the
// program was in flight on its edge to be lost. Its heartbeat says it holds the program; once the
// heartbeat stops for heartbeat_timeout (4 s), its sink ends the program naming the stage, on a
// machine loaded by two busy loops. The launcher restarts stages only after 60 s here: the sink
// notices by itself, as without a supervisor.
TEST(Launch, AKilledCompensateNodeIsNamedByItsSinkWithinTheHeartbeatTimeout) {
  gcpipe_test::CpuHog hog(2);
  const fs::path dir = tmpdir("launch_kill_compensate");
  const fs::path log = dir / "launch.log";
  const std::vector<std::string> dds = {"--domain", "217", "--idle-timeout", "120"};
  auto with_dds = [&](std::vector<std::string> args) {
    args.insert(args.end(), dds.begin(), dds.end());
    return args;
  };
  const pid_t launch = spawn_gcpipe(
      {"launch", pipeline_file(dir, 217, "  on_crash: restart\n  restart_delay: 60\n").string()}, dir / "out", log);
  struct StopOnExit {
    pid_t pid;
    ~StopOnExit() {
      if (kill(pid, SIGINT) == 0) wait_exit(pid, 30);
    }
  } stop_launch{launch};
  ASSERT_TRUE(wait_for(log, "all 5 processes ready", 60)) << slurp(log);
  const pid_t compensate = node_pid(log, "compensate");
  ASSERT_GT(compensate, 0);
  const pid_t sink = spawn_gcpipe(with_dds({"sink", "--in", "gcpipe_compensated", "-o", (dir / "comp.nc").string()}),
                                  dir / "sink.out", dir / "sink.err");
  ASSERT_TRUE(wait_for(dir / "sink.err", "gcpipe sink: ready", 30)) << slurp(dir / "sink.err");
  const pid_t gcode_sink = spawn_gcpipe(with_dds({"sink", "-o", (dir / "out.nc").string()}), dir / "gsink.out", dir / "gsink.err");
  ASSERT_TRUE(wait_for(dir / "gsink.err", "gcpipe sink: ready", 30)) << slurp(dir / "gsink.err");
  // Killed once the force node has sent the whole program on the compensate node's input: the
  // compensate node took its batches as they came (it only collects them) and now compensates,
  // for seconds. (Killed at the first batch instead, it had now and then not taken it yet under
  // the hog: then its heartbeat had not said it held the program, and the batches died with it
  // unseen; nothing downstream can know of a program no stage after the force node ever took.)
  const pid_t watch = spawn_gcpipe(with_dds({"monitor", "gcpipe_planned", "--period", "0.05"}), dir / "watch.out", dir / "watch.err");
  ASSERT_TRUE(wait_for(dir / "watch.out", "matched", 30)) << slurp(dir / "watch.out") << slurp(dir / "watch.err");
  const pid_t feed = spawn_gcpipe(with_dds({"feed", (kSource / "samples" / "trochoid_slot_seed000.nc").string()}),
                                  dir / "feed.out", dir / "feed.err");
  ASSERT_TRUE(wait_for(dir / "watch.out", "end of program", 120)) << slurp(dir / "watch.out") << slurp(dir / "watch.err");
  ASSERT_FALSE(fs::exists(dir / "comp.nc")) << "compensated before the kill: the test proves nothing";
  ASSERT_EQ(kill(compensate, SIGKILL), 0);
  double took = 0;
  EXPECT_EQ(wait_exit(sink, 60, &took), 1) << slurp(dir / "sink.err");
  std::printf("the compensated program's sink gave up %.2f s after the kill (heartbeat timeout 4 s)\n", took);
  EXPECT_LT(took, 10) << "the sink took too long to notice";
  const std::string err = slurp(dir / "sink.err");
  EXPECT_NE(err.find("the compensate stage (pid " + std::to_string(compensate) + ", writer of gcpipe_compensated) sent no heartbeat"),
            std::string::npos) << err;
  EXPECT_NE(err.find("the program is lost"), std::string::npos) << err;
  EXPECT_NE(err.find("INCOMPLETE"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(dir / "comp.nc"));
  // The other branch of the tree is unaffected: output.nc arrives whole.
  EXPECT_EQ(wait_exit(gcode_sink, 60), 0) << slurp(dir / "gsink.err");
  wait_exit(feed, 60);
  kill(watch, SIGTERM);
  wait_exit(watch, 10);
}

TEST(Launch, PipelineFileErrorsNameTheKey) {
  const fs::path dir = tmpdir("launch_errors");
  auto run_with = [&](const std::string& nodes, const std::string& extra = "") {
    return gcpipe({"launch", pipeline_file(dir, 229, extra, nodes).string()});
  };
  Outcome unknown = run_with("[parse, calibrate]");
  EXPECT_EQ(unknown.status, 1);
  EXPECT_NE(unknown.err.find("'calibrate' is not one of"), std::string::npos) << unknown.err;
  Outcome twice = run_with("[parse, parse]");
  EXPECT_NE(twice.err.find("listed twice"), std::string::npos) << twice.err;
  Outcome crash = run_with("[parse]", "  on_crash: retry\n");
  EXPECT_NE(crash.err.find("on_crash"), std::string::npos) << crash.err;
  Outcome identity = run_with("[parse]", "  identity: no_such_folder\n");
  EXPECT_NE(identity.err.find("identity"), std::string::npos) << identity.err;
  EXPECT_NE(identity.err.find("no such folder"), std::string::npos) << identity.err;
  Outcome history = run_with("[parse]", "  monitor_history: -1\n");
  EXPECT_EQ(history.status, 1);
  EXPECT_NE(history.err.find("monitor_history"), std::string::npos) << history.err;
  Outcome beat = run_with("[parse]", "  heartbeat_timeout: 0.5\n");  // under 1 s: eight beats would be 60 ms apart
  EXPECT_EQ(beat.status, 1);
  EXPECT_NE(beat.err.find("heartbeat_timeout"), std::string::npos) << beat.err;
  Outcome stall = run_with("[parse]", "  stall_timeout: 0\n");
  EXPECT_EQ(stall.status, 1);
  EXPECT_NE(stall.err.find("stall_timeout"), std::string::npos) << stall.err;
  Outcome network = run_with("[parse]", "  network: no_such_file.xml\n");
  EXPECT_NE(network.err.find("network"), std::string::npos) << network.err;
  Outcome stranger = run_with("[parse, trochoid]", "groups: [parse+write]\n");
  EXPECT_NE(stranger.err.find("stage 'write' of group 'parse+write' is not in nodes"), std::string::npos) << stranger.err;
  Outcome alone = run_with("[parse, trochoid]", "groups: [parse]\n");
  EXPECT_NE(alone.err.find("a group joins two or more"), std::string::npos) << alone.err;
  Outcome twice_grouped = run_with("[parse, trochoid, write]", "groups: [parse+trochoid, trochoid+write]\n");
  EXPECT_NE(twice_grouped.err.find("stage 'trochoid' is in two groups"), std::string::npos) << twice_grouped.err;
  EXPECT_EQ(gcpipe({"launch", (dir / "missing.yaml").string()}).status, 2);  // CLI: no such file
}

// Every shipped pipeline file loads and runs a sample through (domain 224, a test of its own).
TEST(Launch, EveryShippedPipelineFileRunsASample) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(kSource / "pipeline_configs" / "pipelines")) {
    if (e.path().extension() != ".yaml") continue;
    SCOPED_TRACE(e.path().string());
    const fs::path dir = tmpdir("launch_shipped");
    const Outcome s = gcpipe({"stream", (kSource / "samples" / "five_axis_demo.nc").string(), "-o", dir.string(),
                              "--pipeline", e.path().string(), "--domain", "224"});
    EXPECT_EQ(s.status, 0) << s.err;
    ++n;
  }
  EXPECT_GE(n, 1);
}
