// The streaming pipeline end to end: feed -> node parse -> node trochoid -> node write -> sink,
// each a separate process of the built gcpipe executable (so shared memory and UDP are really
// used; two participants in one process would take Fast DDS's in-process shortcut), must write
// exactly the bytes `gcpipe batch` writes, and exit with batch mode's status.
#include <gtest/gtest.h>

#include "cpu_hog.hpp"
#include "dds_test_util.hpp"

#include <nlohmann/json.hpp>

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <regex>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace {

namespace fs = std::filesystem;
using gcpipe_test::clean_dead_shared_memory;
using gcpipe_test::Process;
using gcpipe_test::slurp;
using gcpipe_test::wait_for_log;

const std::string kConfig = std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/default.yaml";
// Every process gets this: no step can wait longer than this by itself [s].
constexpr const char* kIdle = "60";

// Extra arguments per process of run_pipeline; a node given a `keep` pointer is left running
// (--forever) and handed to the caller, who ends it.
struct PipelineArgs {
  std::vector<std::string> parse, trochoid, write, feed;
  std::unique_ptr<Process>* keep_parse = nullptr;
  std::unique_ptr<Process>* keep_trochoid = nullptr;
};

class DdsPipeline : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("gcpipe_dds_" + std::string(info->name()) + "_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    domain_ = std::to_string(claim_domain());
  }

  // Tests run in parallel (ctest -j) must not hear each other: each holds an exclusive lock on
  // one domain id for its lifetime. The lock dies with the process, so a crash frees it.
  // Domains 20..99 only, a precaution: from domain 102 on, the ports (7400 + 250 domain + ...)
  // fall into Linux's ephemeral range (32768-60999), where another process's outgoing socket can
  // hold one.
  int claim_domain() {
    const int first = 20 + getpid() % 80;
    for (int k = 0; k < 80; ++k) {
      const int domain = 20 + (first - 20 + k) % 80;
      const fs::path lock = fs::temp_directory_path() / ("gcpipe_dds_domain_" + std::to_string(domain) + ".lock");
      const int fd = ::open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
      if (fd < 0) continue;
      if (flock(fd, LOCK_EX | LOCK_NB) == 0) {
        domain_lock_ = fd;
        return domain;
      }
      ::close(fd);
    }
    ADD_FAILURE() << "no free DDS domain id in [20, 100)";
    return 0;
  }

  void TearDown() override {
    if (any_killed_) {
      // A SIGKILLed participant leaves its shared-memory segments behind.
      clean_dead_shared_memory();
    }
    if (!HasFailure()) fs::remove_all(dir_);
    else std::cerr << "logs kept in " << dir_ << "\n";
    if (domain_lock_ >= 0) ::close(domain_lock_);
  }

  std::vector<std::string> dds_args(std::vector<std::string> args) const {
    for (const char* a : {"--domain", domain_.c_str(), "--idle-timeout", kIdle, "--timeout", kIdle})
      args.emplace_back(a);
    return args;
  }

  struct BatchResult {
    int status = 0;
    std::string output;
  };

  BatchResult run_batch(const fs::path& input, const std::vector<std::string>& extra = {}) {
    // The DDS chain is parse -> trochoid -> write: batch's output.nc is the comparison, its
    // simulation and compensation (not part of this chain) are skipped.
    std::vector<std::string> args = {"batch", input.string(), "-o", (dir_ / "batch").string(),
                                     "--config", kConfig, "--quiet", "--no-simulate"};
    args.insert(args.end(), extra.begin(), extra.end());
    Process p("batch", args, dir_);
    BatchResult r;
    r.status = p.wait();
    r.output = slurp(dir_ / "batch" / "output.nc");
    return r;
  }

  struct PipelineResult {
    int feed = -2, parse = -2, trochoid = -2, write = -2, sink = -2;
    std::string output;
    std::string sink_log;
  };

  // Starts the consumers first, as an operator would, then the feeder; the feeder waits for its
  // reader anyway, so the order only saves time.
  // A program published before the sink exists is a replay to it (skipped without --replay):
  // start the rest only once the sink says it is ready, since under load a sink can take longer
  // to start than a feed.
  // The whole chain as nodes (ik and simulate included) against batch: the same compensated.nc
  // and output.nc, and monitors of the telemetry topics see what report.json says: the number of
  // IK points, and the cutting moves' largest contour error of the uncompensated program.
  void compensate_chain_equals_batch(const fs::path& dir, const fs::path& input, const std::string& config) {
    Process batch("batch", {"batch", input.string(), "-o", (dir / "batch").string(), "--config", config, "--quiet"}, dir);
    ASSERT_EQ(batch.wait(), 0);
    const std::string expected = slurp(dir / "batch" / "compensated.nc");
    ASSERT_FALSE(expected.empty());
    const auto report = nlohmann::json::parse(slurp(dir / "batch" / "report.json"));
    const fs::path comp = dir / "compensated.nc", out = dir / "sink.nc";
    Process ik_monitor("monitor_ik", dds_args({"monitor", "gcpipe_ik_results", "--period", "5"}), dir);
    const fs::path live = dir / "contour_live.png";
    Process sample_monitor("monitor_samples",
                           dds_args({"monitor", "gcpipe_samples", "--period", "5", "--plot", live.string()}), dir);
    Process sink_comp("sink_comp", dds_args({"sink", "--in", "gcpipe_compensated", "-o", comp.string()}), dir);
    Process sink("sink", dds_args({"sink", "-o", out.string()}), dir);
    wait_until_ready(sink_comp);
    wait_until_ready(sink);
    Process compensate("compensate", dds_args({"node", "compensate", "--config", config}), dir);
    Process simulate("simulate", dds_args({"node", "simulate", "--config", config}), dir);
    Process ik("ik", dds_args({"node", "ik", "--config", config}), dir);
    Process force("force", dds_args({"node", "force", "--config", config}), dir);
    Process write("write", dds_args({"node", "write", "--config", config}), dir);
    Process trochoid("trochoid", dds_args({"node", "trochoid", "--config", config, "--subscribers", "2"}), dir);
    Process parse("parse", dds_args({"node", "parse", "--config", config}), dir);
    // Telemetry never waits for a monitor: the program starts once both see their writer.
    ASSERT_TRUE(wait_for_log(ik_monitor, "matched")) << slurp(ik_monitor.log);
    ASSERT_TRUE(wait_for_log(sample_monitor, "matched")) << slurp(sample_monitor.log);
    Process feed("feed", dds_args({"feed", input.string(), "--config", config}), dir);
    EXPECT_EQ(feed.wait(), 0);
    EXPECT_EQ(sink_comp.wait(), 0) << slurp(sink_comp.log);
    EXPECT_EQ(sink.wait(), 0) << slurp(sink.log);
    EXPECT_EQ(compensate.wait(), 0) << slurp(compensate.log);
    EXPECT_EQ(simulate.wait(), 0) << slurp(simulate.log);
    EXPECT_EQ(ik.wait(), 0) << slurp(ik.log);
    EXPECT_EQ(force.wait(), 0) << slurp(force.log);
    EXPECT_EQ(write.wait(), 0);
    EXPECT_EQ(trochoid.wait(), 0);
    EXPECT_EQ(parse.wait(), 0);
    EXPECT_EQ(ik_monitor.wait(), 0) << slurp(ik_monitor.log);
    EXPECT_EQ(sample_monitor.wait(), 0) << slurp(sample_monitor.log);
    any_killed_ |= feed.killed || sink.killed || sink_comp.killed || compensate.killed || force.killed ||
                   simulate.killed || ik.killed;
    EXPECT_TRUE(slurp(comp) == expected) << "compensated program differs from batch";
    EXPECT_TRUE(slurp(out) == slurp(dir / "batch" / "output.nc"));
    const std::string ik_seen = slurp(ik_monitor.log), samples_seen = slurp(sample_monitor.log);
    EXPECT_NE(ik_seen.find("end of program: " + std::to_string(report["ik"]["points"].get<long>()) + " IK points"),
              std::string::npos) << ik_seen;
    const std::size_t at = samples_seen.rfind(" max ");
    ASSERT_NE(at, std::string::npos) << samples_seen;
    const double max_um = std::stod(samples_seen.substr(at + 5));
    EXPECT_NEAR(max_um, report["simulation"]["contour_error_before"]["cutting"]["max_mm"].get<double>() * 1e3, 6e-4)
        << samples_seen;
    EXPECT_EQ(samples_seen.find("MISSING"), std::string::npos) << samples_seen;
    // monitor --plot drew the live figure at least at the end, under its final name only.
    EXPECT_EQ(slurp(live).substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8)) << live;
    EXPECT_GT(fs::file_size(live), 10000u);
    EXPECT_FALSE(fs::exists(live.string() + ".part"));
  }

  static void wait_until_ready(const Process& sink) {
    for (int i = 0; i < 600 && slurp(sink.log).find("gcpipe sink: ready") == std::string::npos; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }

  // Each process starts once the one before says it is up (its participant, reader and writer
  // exist), as `gcpipe launch` starts them: started in one instant on a loaded machine, a pair of
  // them now and then never matched (ShippedSamplesMatchBatchByteForByte once: "no reader of
  // gcpipe_gcode within 60 s", its sink ready all along). A wait on what a process says, not on
  // the machine's speed.
  static void wait_until_up(const Process& node) {
    EXPECT_TRUE(wait_for_log(node, ": up on domain")) << slurp(node.log);
  }

  PipelineResult run_pipeline(const fs::path& input, const PipelineArgs& extra = {}) {
    const fs::path out = dir_ / "sink.nc";
    // An earlier program's output must not pass for this one's when this sink writes nothing.
    fs::remove(out);
    fs::remove(out.string() + ".part");
    auto with = [](std::vector<std::string> a, const std::vector<std::string>& more) {
      a.insert(a.end(), more.begin(), more.end());
      return a;
    };
    Process sink("sink", dds_args({"sink", "-o", out.string()}), dir_);
    wait_until_ready(sink);
    Process write("write", dds_args(with({"node", "write", "--config", kConfig}, extra.write)), dir_);
    wait_until_up(write);
    auto trochoid = std::make_unique<Process>(
        "trochoid", dds_args(with({"node", "trochoid", "--config", kConfig}, extra.trochoid)), dir_);
    wait_until_up(*trochoid);
    auto parse = std::make_unique<Process>(
        "parse", dds_args(with({"node", "parse", "--config", kConfig}, extra.parse)), dir_);
    wait_until_up(*parse);
    Process feed("feed", dds_args(with({"feed", input.string(), "--config", kConfig}, extra.feed)),
                 dir_);
    PipelineResult r;
    r.feed = feed.wait();
    r.sink = sink.wait();
    r.write = write.wait();
    // Nodes kept for the caller are still serving (--forever); the others must have left.
    auto finish = [this](std::unique_ptr<Process>& p, std::unique_ptr<Process>* keep, int& status) {
      if (keep != nullptr) {
        *keep = std::move(p);
        return;
      }
      status = p->wait();
      any_killed_ |= p->killed;
    };
    finish(trochoid, extra.keep_trochoid, r.trochoid);
    finish(parse, extra.keep_parse, r.parse);
    any_killed_ |= feed.killed || sink.killed || write.killed;
    r.output = slurp(out);
    r.sink_log = slurp(sink.log);
    return r;
  }

  // `node_extra` goes to every node, `feed_extra` to the feeder.
  void expect_same_as_batch(const fs::path& input, const std::vector<std::string>& node_extra = {},
                            const std::vector<std::string>& feed_extra = {}) {
    const BatchResult batch = run_batch(input);
    ASSERT_FALSE(batch.output.empty()) << "batch wrote nothing for " << input;
    PipelineArgs extra;
    extra.parse = extra.trochoid = extra.write = node_extra;
    extra.feed = feed_extra;
    const PipelineResult pipe = run_pipeline(input, extra);
    EXPECT_EQ(pipe.feed, 0) << slurp(dir_ / "feed.log");
    EXPECT_EQ(pipe.parse, 0) << slurp(dir_ / "parse.log");
    EXPECT_EQ(pipe.trochoid, 0) << slurp(dir_ / "trochoid.log");
    EXPECT_EQ(pipe.write, 0) << slurp(dir_ / "write.log");
    EXPECT_EQ(pipe.sink, batch.status) << pipe.sink_log;
    EXPECT_EQ(pipe.output.size(), batch.output.size());
    EXPECT_TRUE(pipe.output == batch.output) << "sink output differs from batch for " << input;
  }

  void middle_node_fault(int signal);

  fs::path dir_;
  std::string domain_;
  bool any_killed_ = false;
  int domain_lock_ = -1;
};

// ~20,000 lines of five-axis moves, arcs, comments, with lines the parser must reject (a word
// twice, an arc that cannot exist, an overlong line), block-delete lines, CRLF endings and no
// final newline.
fs::path generate_program(const fs::path& dir, int lines) {
  std::mt19937 rng(4242);
  std::uniform_real_distribution<double> xy(-60, 60), z(-5, 0), a(-30, 30), c(0, 360);
  std::ofstream f(dir / "generated.nc", std::ios::binary);
  f << "%\nO2001 (GENERATED)\nG21 G17 G90 G94\nT1 M6\nG54\nG43 H1\nS9000 M3\nM8\n";
  f << "G0 X0. Y0. Z10. A0. C0.\nG1 Z-1. F600.\n";
  char buf[256];
  for (int k = 0; k < lines; ++k) {
    switch (k % 20) {
      case 3:
        std::snprintf(buf, sizeof buf, "G2 X%.3f Y%.3f I5. J0 (arc %d)", 0.0, 0.0, k);
        break;  // first and last point differ in general: a genuine arc or a rejected one
      case 7: std::snprintf(buf, sizeof buf, "/G1 X%.3f", xy(rng)); break;
      case 11: std::snprintf(buf, sizeof buf, "G1 X1. X2. Y%d.", k % 50); break;
      case 13: std::snprintf(buf, sizeof buf, "(note %d)\r", k); break;
      case 17: std::snprintf(buf, sizeof buf, "G0 x%.2f y%.2f", xy(rng), xy(rng)); break;
      default:
        std::snprintf(buf, sizeof buf, "G1 X%.3f Y%.3f Z%.3f A%.3f C%.3f F%d", xy(rng), xy(rng),
                      z(rng), a(rng), c(rng), 500 + k % 1000);
    }
    f << buf << "\n";
    if (k % 5000 == 4999) f << "(" << std::string(400, 'L') << ")\n";  // over 256 bytes
  }
  f << "M30\n%";
  return dir / "generated.nc";
}

// `cycles` G275 trochoidal slots (D10 tool, thousands of blocks each) among ordinary moves. Cycle
// `impossible` is narrower than the tool (W8 < D10): the trochoid stage rejects it, and a
// diagnostic followed by skip moves with the cycle's line number flows through. Lines the parser
// rejects and block-delete lines follow every cycle from `bad_from` on (so strict mode can be
// made to stop at the impossible cycle rather than at a parser error).
fs::path generate_cycle_program(const fs::path& dir, int cycles, int impossible, int bad_from) {
  std::ofstream f(dir / "cycles.nc", std::ios::binary);
  f << "%\nO2002 (GENERATED G275 CYCLES)\nG17 G21 G40 G49 G54 G80 G90 G94\nT2 M6\nS6000 M3\n";
  char buf[160];
  for (int k = 0; k < cycles; ++k) {
    const double x = 40.0 * k, length = 12.0 + 3.0 * (k % 4);
    std::snprintf(buf, sizeof buf, "G0 X%.1f Y10. Z5.\nG0 Z0\nG1 F%d\n", x, 700 + 50 * k);
    f << buf;
    if (k == impossible)
      std::snprintf(buf, sizeof buf, "G275 X%.1f Y%.1f Z-3 R5 W8 K0.5 Q0 D10 (W < D)\n", x,
                    10 + length);
    else if (k % 2 == 0)
      std::snprintf(buf, sizeof buf, "G275 X%.1f Y%.1f Z-3 R5 W14 K0.7 Q0 D10\n", x, 10 + length);
    else
      std::snprintf(buf, sizeof buf, "G275 X%.1f Y%.1f Z-4 R5 W16 K1.0 Q2 D10 P1\n", x,
                    10 + length);
    f << buf << "G0 Z5.\n";
    if (k >= bad_from) f << "G1 X1. X2. Y3.\n/G1 X5.\n";
    for (int j = 0; j < 20; ++j) {
      std::snprintf(buf, sizeof buf, "G1 X%.3f Y%.3f F900 (move %d)\n", x + 0.5 * j, 5.0 + j % 3, j);
      f << buf;
    }
  }
  f << "G0 Z50.\nM5\nM30\n%\n";
  return dir / "cycles.nc";
}

TEST_F(DdsPipeline, ShippedSamplesMatchBatchByteForByte) {
  const fs::path samples = fs::path(GCPIPE_SOURCE_DIR) / "samples";
  int n = 0;
  for (const auto& e : fs::directory_iterator(samples)) {
    if (e.path().extension() != ".nc") continue;
    ++n;
    SCOPED_TRACE(e.path().string());
    expect_same_as_batch(e.path());
  }
  EXPECT_GT(n, 0) << "no samples/*.nc";
}

TEST_F(DdsPipeline, GeneratedProgramWithBadLinesMatchesBatchByteForByte) {
  const fs::path input = generate_program(dir_, 20000);
  expect_same_as_batch(input);
  const auto summary = nlohmann::json::parse(slurp(dir_ / "batch" / "summary.json"));
  // The program must really exercise rejection and block delete, or the test proves less.
  EXPECT_GT(summary.at("lines_rejected").get<int>(), 0) << summary.dump();
  EXPECT_GT(summary.at("lines_deleted").get<int>(), 0) << summary.dump();
}

// A paced feed (a DNC drip feed's --rate) sends no faster than its rate and changes no byte.
// Without --chunk-bytes a paced feed cuts 16 KB chunks (the unpaced default is 128 KB).
TEST_F(DdsPipeline, PacedFeedKeepsItsRateAndChangesNoByte) {
  const fs::path input = generate_program(dir_, 20000);
  const double bytes = static_cast<double>(fs::file_size(input));
  const double rate = bytes / 1.5;  // the whole program due after 1.5 s
  expect_same_as_batch(input, {}, {"--rate", std::to_string(rate)});
  const std::string log = slurp(dir_ / "feed.log");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(log, m, std::regex(" bytes in ([0-9]+) chunks, ([0-9.]+) s;"))) << log;
  // Chunks of 16 KB of CDR text (each line counted with 20 bytes of overhead): more than the
  // file's bytes / 16 KB, and far more than with 128 KB.
  EXPECT_GT(std::stoi(m[1]), bytes / 16384) << log;
  EXPECT_LT(std::stoi(m[1]), 3 * bytes / 16384) << log;
  // The last chunk was not sent before it was due: the feed paces by the lines' bytes with one
  // newline each, a little less than the file's (CRLF lines, the missing final newline).
  EXPECT_GE(std::stod(m[2]), 1.4) << log;
}

TEST_F(DdsPipeline, RejectedCycleDiagnosticAndSkipMovesMatchBatchByteForByte) {
  const fs::path input = generate_cycle_program(dir_, 6, 3, 0);
  expect_same_as_batch(input);
  const auto summary = nlohmann::json::parse(slurp(dir_ / "batch" / "summary.json"));
  // The program must really expand cycles and reject one, or the test proves less.
  EXPECT_EQ(summary.at("trochoid").at("cycles_expanded"), 5) << summary.dump();
  EXPECT_EQ(summary.at("trochoid").at("cycles_rejected"), 1) << summary.dump();
  const std::string output = slurp(dir_ / "sink.nc");
  const auto diag = output.find("G275 rejected: slot width W8");
  ASSERT_NE(diag, std::string::npos);
  // The skip moves of the rejected cycle come right after its diagnostic (batch mode's order).
  EXPECT_NE(output.find("G275 left out", diag), std::string::npos);
  EXPECT_NE(slurp(dir_ / "trochoid.log").find("5 G275 cycles expanded, 1 rejected"),
            std::string::npos)
      << slurp(dir_ / "trochoid.log");
  // 1 KB batches: a cycle's diagnostic and its skip moves, and every expansion, are cut across
  // many samples; the order must survive that.
  expect_same_as_batch(input, {"--batch-bytes", "1024"}, {"--chunk-bytes", "1024"});
}

TEST_F(DdsPipeline, StrictModeStopsAtTheFirstRejectedCycleWhereBatchStops) {
  // The first error is the impossible cycle (parser errors only after it): batch stops there,
  // after writing the cycle's diagnostic and skip moves. Only the parse node gets --strict; the
  // trochoid node follows the mode its input batches carry.
  const fs::path input = generate_cycle_program(dir_, 4, 1, 2);
  const BatchResult batch = run_batch(input, {"--strict"});
  EXPECT_EQ(batch.status, 1);
  ASSERT_NE(batch.output.find("G275 rejected"), std::string::npos) << batch.output;
  PipelineArgs strict;
  strict.parse = {"--strict"};
  const PipelineResult pipe = run_pipeline(input, strict);
  EXPECT_EQ(pipe.parse, 0);
  EXPECT_EQ(pipe.trochoid, 0) << slurp(dir_ / "trochoid.log");
  EXPECT_EQ(pipe.write, 0) << slurp(dir_ / "write.log");
  EXPECT_EQ(pipe.sink, 1) << pipe.sink_log;
  EXPECT_NE(pipe.sink_log.find("strict mode stopped"), std::string::npos) << pipe.sink_log;
  EXPECT_NE(slurp(dir_ / "trochoid.log").find("(strict stop)"), std::string::npos);
  EXPECT_TRUE(pipe.output == batch.output);
}

TEST_F(DdsPipeline, WriteNodeReadsTheParserDirectlyAndTopicsCanBeRenamed) {
  // Without the trochoid node (a program without G275 writes the same), on renamed topics; a
  // monitor of a non-default name needs --type.
  const fs::path input = fs::path(GCPIPE_SOURCE_DIR) / "samples" / "five_axis_demo.nc";
  const BatchResult batch = run_batch(input);
  const fs::path out = dir_ / "sink.nc";
  Process sink("sink", dds_args({"sink", "-o", out.string(), "--in", "t_gcode"}), dir_);
  Process write("write", dds_args({"node", "write", "--config", kConfig, "--in", "t_blocks",
                                   "--out", "t_gcode"}), dir_);
  Process parse("parse", dds_args({"node", "parse", "--config", kConfig, "--in", "t_program",
                                   "--out", "t_blocks", "--forever", "--monitor-history", "60"}), dir_);
  Process feed("feed", dds_args({"feed", input.string(), "--config", kConfig, "--out",
                                 "t_program"}), dir_);
  EXPECT_EQ(feed.wait(), 0);
  EXPECT_EQ(sink.wait(), batch.status) << slurp(sink.log);
  EXPECT_EQ(write.wait(), 0) << slurp(write.log);
  EXPECT_TRUE(slurp(out) == batch.output);
  Process untyped("untyped", dds_args({"monitor", "t_blocks"}), dir_);
  EXPECT_EQ(untyped.wait(30), 2) << slurp(untyped.log);
  Process monitor("monitor", dds_args({"monitor", "t_blocks", "--type", "blocks", "--period",
                                       "0.2"}), dir_);
  EXPECT_EQ(monitor.wait(60), 0);
  const auto summary = nlohmann::json::parse(slurp(dir_ / "batch" / "summary.json"));
  const std::string lines = std::to_string(summary.at("lines_read").get<std::uint64_t>());
  EXPECT_NE(slurp(monitor.log).find("end of program: " + lines + " lines read"), std::string::npos)
      << lines << "\n" << slurp(monitor.log);
  kill(parse.pid, SIGTERM);
  EXPECT_EQ(parse.wait(30), 0) << slurp(parse.log);
  any_killed_ |= feed.killed || sink.killed || write.killed || parse.killed || monitor.killed ||
                 untyped.killed;
}

TEST_F(DdsPipeline, StalledReaderBlocksTheWriterAndNothingIsLost) {
  // 1 KB batches make thousands of samples, far beyond the 256-sample history. The write node is
  // frozen (SIGSTOP) while the program flows until the trochoid node's history is full and, the
  // trochoid node then being stuck retrying, the parse node's too: write() returns false and must
  // be retried, never dropped (../shared/DESIGN.md section 7), on both edges.
  const fs::path input = generate_program(dir_, 20000);
  const BatchResult batch = run_batch(input);
  const fs::path out = dir_ / "sink.nc";
  Process sink("sink", dds_args({"sink", "-o", out.string()}), dir_);
  Process write("write", dds_args({"node", "write", "--config", kConfig, "--batch-bytes", "1024"}),
                dir_);
  Process trochoid("trochoid", dds_args({"node", "trochoid", "--config", kConfig, "--batch-bytes",
                                         "1024"}), dir_);
  Process parse("parse", dds_args({"node", "parse", "--config", kConfig, "--batch-bytes", "1024"}),
                dir_);
  // Freeze the write node only once both upstream nodes have matched their readers ("ready"), or
  // they would merely wait for a reader instead of filling their histories.
  ASSERT_TRUE(wait_for_log(trochoid, "ready")) << slurp(trochoid.log);
  ASSERT_TRUE(wait_for_log(parse, "ready")) << slurp(parse.log);
  ASSERT_EQ(kill(write.pid, SIGSTOP), 0);
  Process feed("feed", dds_args({"feed", input.string(), "--config", kConfig, "--chunk-bytes",
                                 "1024"}), dir_);
  // Each node says so when its first write() finds the history full.
  const bool trochoid_filled = wait_for_log(trochoid, "history full");
  const bool parse_filled = wait_for_log(parse, "history full");
  ASSERT_EQ(kill(write.pid, SIGCONT), 0);
  EXPECT_TRUE(trochoid_filled) << slurp(trochoid.log);
  EXPECT_TRUE(parse_filled) << slurp(parse.log);
  EXPECT_EQ(feed.wait(), 0);
  EXPECT_EQ(parse.wait(), 0);
  EXPECT_EQ(trochoid.wait(), 0) << slurp(trochoid.log);
  EXPECT_EQ(write.wait(), 0);
  EXPECT_EQ(sink.wait(), batch.status) << slurp(sink.log);
  any_killed_ |= feed.killed || parse.killed || trochoid.killed || write.killed || sink.killed;
  EXPECT_TRUE(slurp(out) == batch.output);
  for (const Process* p : {&parse, &trochoid}) {
    const std::string log = slurp(p->log);
    const auto at = log.find("writes retried on a full history: ");
    ASSERT_NE(at, std::string::npos) << log;
    const std::string retried = log.substr(at + std::strlen("writes retried on a full history: "));
    EXPECT_GT(std::stoull(retried), 0u) << "the history never filled:\n" << log;
  }
}

TEST_F(DdsPipeline, StrictModeStopsWhereBatchStops) {
  const fs::path input = generate_program(dir_, 2000);
  const BatchResult batch = run_batch(input, {"--strict"});
  EXPECT_EQ(batch.status, 1);
  PipelineArgs strict;
  strict.parse = {"--strict"};
  const PipelineResult pipe = run_pipeline(input, strict);
  EXPECT_EQ(pipe.parse, 0);
  EXPECT_EQ(pipe.trochoid, 0);
  EXPECT_EQ(pipe.write, 0);
  EXPECT_EQ(pipe.sink, 1) << pipe.sink_log;
  EXPECT_NE(pipe.sink_log.find("strict mode stopped"), std::string::npos) << pipe.sink_log;
  EXPECT_TRUE(pipe.output == batch.output);
}

TEST_F(DdsPipeline, ForeverNodesServeSuccessiveProgramsAndSinksSkipReplays) {
  // Nodes serving with --forever keep finished programs in their transient-local history; a
  // sink started for the next program must not take the replayed old one.
  const fs::path first = fs::path(GCPIPE_SOURCE_DIR) / "samples" / "trochoid_slot_seed000.nc";
  const fs::path second = generate_program(dir_, 3000);
  const BatchResult batch_first = run_batch(first);
  const BatchResult batch_second = run_batch(second);
  Process parse("parse", dds_args({"node", "parse", "--config", kConfig, "--forever"}), dir_);
  Process trochoid("trochoid", dds_args({"node", "trochoid", "--config", kConfig, "--forever"}),
                   dir_);
  Process write("write", dds_args({"node", "write", "--config", kConfig, "--forever"}), dir_);
  for (const auto& [input, batch] : {std::pair{first, batch_first}, std::pair{second, batch_second}}) {
    SCOPED_TRACE(input.string());
    const fs::path out = dir_ / "sink.nc";
    fs::remove(out);
    Process sink("sink", dds_args({"sink", "-o", out.string()}), dir_);
    wait_until_ready(sink);
    Process feed("feed", dds_args({"feed", input.string(), "--config", kConfig}), dir_);
    EXPECT_EQ(feed.wait(), 0);
    EXPECT_EQ(sink.wait(), batch.status) << slurp(sink.log);
    any_killed_ |= feed.killed || sink.killed;
    EXPECT_TRUE(slurp(out) == batch.output);
    if (input == second)  // the first program was still in the write node's history
      EXPECT_NE(slurp(sink.log).find("skipping program"), std::string::npos) << slurp(sink.log);
  }
  kill(parse.pid, SIGTERM);
  kill(trochoid.pid, SIGTERM);
  kill(write.pid, SIGTERM);
  EXPECT_EQ(parse.wait(30), 0) << slurp(parse.log);
  EXPECT_EQ(trochoid.wait(30), 0) << slurp(trochoid.log);
  EXPECT_EQ(write.wait(30), 0) << slurp(write.log);
  any_killed_ |= parse.killed || trochoid.killed || write.killed;
}

// A sink started for one program id (as gcpipe stream starts its sinks) writes that program only:
// another one arriving first on its topic (another pipeline's, on a shared domain) is refused and
// named, never written.
TEST_F(DdsPipeline, ASinkForOneProgramIdRefusesAnotherProgramAndNamesIt) {
  const fs::path other = fs::path(GCPIPE_SOURCE_DIR) / "samples" / "trochoid_slot_seed000.nc";
  const fs::path ours = generate_program(dir_, 2000);
  const BatchResult batch_ours = run_batch(ours);
  Process parse("parse", dds_args({"node", "parse", "--config", kConfig, "--forever"}), dir_);
  Process trochoid("trochoid", dds_args({"node", "trochoid", "--config", kConfig, "--forever"}), dir_);
  Process write("write", dds_args({"node", "write", "--config", kConfig, "--forever"}), dir_);
  const fs::path out = dir_ / "ours.nc";
  Process sink("sink", dds_args({"sink", "-o", out.string(), "--program-id", "424242"}), dir_);
  wait_until_ready(sink);
  Process feed_other("feed other", dds_args({"feed", other.string(), "--config", kConfig, "--program-id", "111"}), dir_);
  EXPECT_EQ(feed_other.wait(), 0) << slurp(feed_other.log);
  Process feed_ours("feed ours", dds_args({"feed", ours.string(), "--config", kConfig, "--program-id", "424242"}), dir_);
  EXPECT_EQ(feed_ours.wait(), 0) << slurp(feed_ours.log);
  EXPECT_EQ(sink.wait(), batch_ours.status) << slurp(sink.log);
  EXPECT_TRUE(slurp(out) == batch_ours.output);
  EXPECT_NE(slurp(sink.log).find("refusing program 111 ('" + other.string() + "'): started for program 424242 only"),
            std::string::npos)
      << slurp(sink.log);
  for (Process* p : {&parse, &trochoid, &write}) kill(p->pid, SIGTERM);
  for (Process* p : {&parse, &trochoid, &write}) EXPECT_EQ(p->wait(30), 0) << slurp(p->log);
  any_killed_ |= feed_other.killed || feed_ours.killed || sink.killed || parse.killed || trochoid.killed || write.killed;
}

TEST_F(DdsPipeline, LateMonitorStillSeesTheEndMarker) {
  const fs::path input = generate_cycle_program(dir_, 4, 2, 0);
  const BatchResult batch = run_batch(input);
  std::unique_ptr<Process> parse, trochoid;
  PipelineArgs extra;
  // The copies for monitors keep a minute here (default 5 s): the monitors below start after the
  // program is through, and a loaded CI machine must not make that "too late".
  extra.parse = extra.trochoid = {"--forever", "--monitor-history", "60"};
  extra.keep_parse = &parse;
  extra.keep_trochoid = &trochoid;
  const PipelineResult pipe = run_pipeline(input, extra);
  ASSERT_NE(parse, nullptr);
  ASSERT_NE(trochoid, nullptr);
  EXPECT_EQ(pipe.sink, batch.status) << pipe.sink_log;
  EXPECT_TRUE(pipe.output == batch.output);
  // The program is over; both nodes still hold their histories for late joiners.
  Process blocks("monitor_blocks", dds_args({"monitor", "gcpipe_blocks", "--period", "0.2"}), dir_);
  Process toolpath("monitor_toolpath", dds_args({"monitor", "gcpipe_toolpath", "--period", "0.2"}),
                   dir_);
  EXPECT_EQ(blocks.wait(60), 0);
  EXPECT_EQ(toolpath.wait(60), 0);
  const auto summary = nlohmann::json::parse(slurp(dir_ / "batch" / "summary.json"));
  auto count = [&summary](const std::string& key) { return std::to_string(summary.at(key).get<std::uint64_t>()); };
  const std::string parsed = "end of program: " + count("lines_read") + " lines read, " +
                             count("blocks_emitted") + " blocks, " + count("lines_rejected") +
                             " rejected, " + count("lines_deleted") + " deleted";
  const std::string diagnostics =
      std::to_string(std::stoull(count("lines_rejected")) + std::stoull(count("lines_deleted")));
  // gcpipe_blocks: the parse node sent the parsed blocks and one diagnostic per bad line.
  EXPECT_NE(slurp(blocks.log).find(parsed + "; sent " + count("blocks_emitted") + " blocks, " +
                                   diagnostics + " diagnostics, 0 blocks rejected"),
            std::string::npos)
      << parsed << "\n" << slurp(blocks.log);
  // gcpipe_toolpath: the same parser counts forwarded, plus what the trochoid node sent: batch
  // mode's written blocks, and the rejected cycle's diagnostic on top of the parser's.
  const std::string rejected = std::to_string(summary.at("trochoid").at("cycles_rejected").get<std::uint64_t>());
  EXPECT_EQ(rejected, "1");
  EXPECT_NE(slurp(toolpath.log).find(
                parsed + "; sent " + count("blocks_written") + " blocks, " +
                std::to_string(std::stoull(diagnostics) + 1) + " diagnostics, 1 blocks rejected"),
            std::string::npos)
      << slurp(toolpath.log);
  kill(parse->pid, SIGTERM);
  kill(trochoid->pid, SIGTERM);
  EXPECT_EQ(parse->wait(30), 0) << slurp(parse->log);
  EXPECT_EQ(trochoid->wait(30), 0) << slurp(trochoid->log);
  any_killed_ |= parse->killed || trochoid->killed || blocks.killed || toolpath.killed;
}

}  // namespace

// The compensate node beside the write node: the write node reads the trochoid node's output, the
// force node too (a pass-through without a `force:` section, the feed planner with one), the
// compensate node the force node's; the compensated program arriving on gcpipe_compensated is
// batch mode's compensated.nc, byte for byte (the same stage code on the same blocks).
TEST_F(DdsPipeline, CompensateNodeWritesBatchModesCompensatedProgram) {
  compensate_chain_equals_batch(dir_, fs::path(GCPIPE_SOURCE_DIR) / "samples" / "five_axis_demo.nc", kConfig);
}

// With the force stage's feed planner on (force_al7075.yaml): the force node rewrites the feeds of
// the whole program at its end, and the compensation works on the planned program in both modes.
TEST_F(DdsPipeline, ForceNodePlansTheFeedsAsBatchModeDoes) {
  const fs::path dir = dir_ / "force";
  fs::create_directories(dir);
  std::ofstream(dir / "slot.nc") << "%\nO0001 (a short slot)\nG17 G21 G90 G94 G54\nT1 M6\nS4000 M3\nG0 X0 Y0 Z5\n"
                                    "G1 Z-5 F300\nG1 X40 F800\nG1 Y8\nG1 X0\nG0 Z5\nM30\n%\n";
  compensate_chain_equals_batch(dir, dir / "slot.nc", std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/force_al7075.yaml");
  const std::string planned = slurp(dir / "batch" / "compensated.nc");
  EXPECT_NE(planned.find("F"), std::string::npos);
}

// The middle node killed (-9) or frozen (SIGSTOP) while a program flows, with no supervisor, on a
// machine loaded by two busy loops: the node after it hears no heartbeat from it for
// heartbeat_timeout (4 s) and ends the program with an end marker naming the stage; the sink then
// stops with that reason, non-zero, and leaves no file under the final name. Upstream, the parse
// node stops with the reason too (its reader's discovery lease, 8 s). The feed is paced and the
// fault comes once output reached the sink, so the program is in flight at the fault however fast
// or slow the machine is (killed 0.7 s after the feed's start, as before, a loaded machine had
// not begun it: the write node then waited out its 60 s idle timeout, 58 s in one run).
void DdsPipeline::middle_node_fault(int signal) {
  gcpipe_test::CpuHog hog(2);
  // 16 MB at 0.5 MB/s: a pace the chain keeps under the hog, so that the write node has no
  // backlog of its input to work through before it can notice (it does, from its history, first).
  const fs::path input = generate_program(dir_, 400000);
  const fs::path out = dir_ / "sink.nc";
  Process sink("sink", dds_args({"sink", "-o", out.string()}), dir_);
  wait_until_ready(sink);
  Process write("write", dds_args({"node", "write", "--config", kConfig}), dir_);
  wait_until_up(write);
  Process trochoid("trochoid", dds_args({"node", "trochoid", "--config", kConfig}), dir_);
  wait_until_up(trochoid);
  Process parse("parse", dds_args({"node", "parse", "--config", kConfig}), dir_);
  ASSERT_TRUE(wait_for_log(parse, "ready")) << slurp(parse.log);
  Process feed("feed", dds_args({"feed", input.string(), "--config", kConfig, "--rate", "500000"}), dir_);
  const fs::path part = out.string() + ".part";
  for (int i = 0; i < 3000 && (!fs::exists(part) || fs::file_size(part) == 0); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ASSERT_GT(fs::file_size(part), 0u) << "nothing reached the sink in 60 s\n" << slurp(write.log) << slurp(feed.log);
  ASSERT_EQ(kill(trochoid.pid, signal), 0);
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(write.wait(45), 1) << slurp(write.log);
  EXPECT_EQ(sink.wait(45), 1) << slurp(sink.log);
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // The heartbeat timeout (4 s) sets the bound; issue 34 asks 10 s. In 3 runs of 27 the write
  // node never received the trochoid node's heartbeats at all, though their
  // edge worked (Fast DDS 2.9 now and then never matches a pair of endpoints: stages/dds/README.md,
  // Watchdog), and the discovery lease (8 s) named the dead writer instead: within the bound too.
  const std::string named = "the trochoid stage (pid " + std::to_string(trochoid.pid) + ", writer of gcpipe_toolpath)";
  const bool by_heartbeat = slurp(write.log).find(named + " sent no heartbeat") != std::string::npos;
  const bool by_lease = slurp(write.log).find("the writer of gcpipe_toolpath went away mid-program") != std::string::npos;
  std::printf("write and sink gave up %.2f s after the %s, told by the %s\n", took, strsignal(signal),
              by_heartbeat ? "heartbeat (timeout 4 s)" : by_lease ? "discovery lease (8 s)" : "?");
  EXPECT_LT(took, 10) << "downstream took too long to give up";
  EXPECT_GT(took, 3.5) << "given up before the heartbeat timeout: not by the watchdog";
  EXPECT_TRUE(by_heartbeat || by_lease) << slurp(write.log);
  if (by_heartbeat) EXPECT_NE(slurp(write.log).find("it died or is frozen"), std::string::npos) << slurp(write.log);
  EXPECT_NE(slurp(sink.log).find("INCOMPLETE"), std::string::npos) << slurp(sink.log);
  EXPECT_NE(slurp(sink.log).find(by_heartbeat ? named : "went away mid-program"), std::string::npos) << slurp(sink.log);
  EXPECT_FALSE(fs::exists(out));
  if (signal == SIGSTOP) {
    kill(trochoid.pid, SIGCONT);
    kill(trochoid.pid, SIGKILL);
  }
  trochoid.wait(5);
  // Upstream, the parse node finds its reader gone (blocked on its history, or at its next
  // write) and stops with the reason instead of waiting out its write timeout.
  EXPECT_EQ(parse.wait(45), 1) << slurp(parse.log);
  EXPECT_NE(slurp(parse.log).find("a reader went away"), std::string::npos) << slurp(parse.log);
  feed.wait(60);
  // What the killed node left (its segment, port queues, semaphores): `gcpipe dds clean` removes
  // the Fast DDS files no live process maps. (Removing every file that appeared since the test
  // began took the port queues of live processes of other pipelines on the host with them, when
  // other engineers' tests or the soak ran beside it: their nodes then matched no new
  // participant. `fastdds shm clean` may take a starting participant's port.)
  clean_dead_shared_memory();
}

TEST_F(DdsPipeline, KilledMiddleNodeEndsTheProgramDownstreamWithTheReason) { middle_node_fault(SIGKILL); }

TEST_F(DdsPipeline, FrozenMiddleNodeIsNamedWithinTheHeartbeatTimeout) { middle_node_fault(SIGSTOP); }

// One edge, two writers: a second trochoid node on the same domain (as when two pipelines share a
// domain id) sends the same program on gcpipe_toolpath. The write node and the sink name that
// cause, not a missing batch, and nothing is written under the final name.
TEST_F(DdsPipeline, ASecondWriterOnAnEdgeIsNamedAsTheCause) {
  const fs::path input = generate_program(dir_, 20000);
  const fs::path out = dir_ / "sink.nc";
  Process sink("sink", dds_args({"sink", "-o", out.string()}), dir_);
  wait_until_ready(sink);
  Process write("write", dds_args({"node", "write", "--config", kConfig}), dir_);
  // 8 KB batches: hundreds of them, so that the two writers' batches of the program interleave at
  // the write node (with the default 128 KB the program is a dozen batches, and the first writer
  // can be through before the second one's first batch arrives).
  Process first("trochoid_1", dds_args({"node", "trochoid", "--config", kConfig, "--batch-bytes", "8192"}), dir_);
  Process second("trochoid_2", dds_args({"node", "trochoid", "--config", kConfig, "--batch-bytes", "8192"}), dir_);
  Process parse("parse", dds_args({"node", "parse", "--config", kConfig, "--subscribers", "2", "--batch-bytes", "8192"}), dir_);
  Process feed("feed", dds_args({"feed", input.string(), "--config", kConfig}), dir_);
  EXPECT_EQ(write.wait(60), 1) << slurp(write.log);
  EXPECT_EQ(sink.wait(60), 1) << slurp(sink.log);
  EXPECT_NE(slurp(write.log).find("a second writer on gcpipe_toolpath sends this program too"), std::string::npos)
      << slurp(write.log);
  EXPECT_NE(slurp(sink.log).find("a second writer on gcpipe_toolpath"), std::string::npos) << slurp(sink.log);
  EXPECT_EQ(slurp(sink.log).find("is missing"), std::string::npos) << slurp(sink.log);
  EXPECT_FALSE(fs::exists(out));
  for (Process* p : {&first, &second, &parse, &feed}) p->wait(60);
}

// gcpipe monitor reads each edge's keep-last copy (TOPIC_monitor), never the edge itself: a monitor
// started before the write node is not counted as the trochoid node's reader (which would make it
// publish before write exists), and a monitor frozen with SIGSTOP holds nobody back.
TEST_F(DdsPipeline, MonitorsStartedFirstOrFrozenLeaveTheOutputAlone) {
  const fs::path input = fs::path(GCPIPE_SOURCE_DIR) / "samples" / "trochoid_slot_seed000.nc";
  const BatchResult batch = run_batch(input);
  Process early("monitor_early", dds_args({"monitor", "gcpipe_toolpath", "--period", "0.5"}), dir_);
  Process frozen("monitor_frozen", dds_args({"monitor", "gcpipe_blocks", "--period", "0.5"}), dir_);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ASSERT_EQ(kill(frozen.pid, SIGSTOP), 0);
  const fs::path out = dir_ / "sink.nc";
  Process trochoid("trochoid", dds_args({"node", "trochoid", "--config", kConfig}), dir_);
  Process parse("parse", dds_args({"node", "parse", "--config", kConfig}), dir_);
  Process feed("feed", dds_args({"feed", input.string(), "--config", kConfig}), dir_);
  // Only the monitor reads gcpipe_toolpath so far: the trochoid node must still be waiting.
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  EXPECT_EQ(slurp(trochoid.log).find("ready"), std::string::npos) << slurp(trochoid.log);
  Process sink("sink", dds_args({"sink", "-o", out.string()}), dir_);
  wait_until_ready(sink);
  Process write("write", dds_args({"node", "write", "--config", kConfig}), dir_);
  EXPECT_EQ(sink.wait(60), batch.status) << slurp(sink.log);
  EXPECT_EQ(write.wait(60), 0);
  EXPECT_EQ(trochoid.wait(60), 0) << slurp(trochoid.log);
  EXPECT_EQ(parse.wait(60), 0) << slurp(parse.log);
  EXPECT_EQ(feed.wait(60), 0);
  EXPECT_TRUE(slurp(out) == batch.output);
  kill(frozen.pid, SIGCONT);
  kill(frozen.pid, SIGTERM);
  kill(early.pid, SIGTERM);
  frozen.wait(10);
  early.wait(10);
  EXPECT_NE(slurp(early.log).find("end of program"), std::string::npos) << slurp(early.log);
}
