// Issue 32 item 3: no input hangs. Every hostile input of the issue runs here under a deadline
// (the child is killed past it, so the test itself cannot hang) and must end with a non-zero exit,
// an error naming the key or the line, and no output that looks complete. Signals: SIGINT and
// SIGTERM must end every such run within 1 s (measured, docs/benchmarks.md); asserted within 3 s
// here so that a busy 2-core CI machine does not fail the test.
#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <thread>
#include <tuple>

#include "cli_helpers.hpp"

namespace {

using Clock = std::chrono::steady_clock;

const std::string kSource = GCPIPE_SOURCE_DIR;
constexpr double kSignalBound = 3.0;  // [s] test margin over the measured < 1 s

struct Bounded {
  Outcome o;
  bool killed = false;            // still running at the deadline
  double seconds_after_signal = 0;
};

// Runs gcpipe; after `signal_after` s (when >= 0) sends `sig`; kills it at `deadline` s.
Bounded run_bounded(const std::vector<std::string>& args, double deadline, int sig = 0, double signal_after = -1) {
  static int counter = 0;
  const fs::path dir = tmpdir("bounded_" + std::to_string(counter++));
  Bounded b;
  const pid_t pid = spawn_gcpipe(args, dir / "out", dir / "err");
  if (pid < 0) return b;
  const auto t0 = Clock::now();
  auto sent = t0;
  bool signalled = false;
  int st = 0;
  for (;;) {
    if (::waitpid(pid, &st, WNOHANG) == pid) break;
    const double t = std::chrono::duration<double>(Clock::now() - t0).count();
    if (sig != 0 && !signalled && t >= signal_after) {
      ::kill(pid, sig);
      sent = Clock::now();
      signalled = true;
    }
    if (t > deadline) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &st, 0);
      b.killed = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  if (signalled) b.seconds_after_signal = std::chrono::duration<double>(Clock::now() - sent).count();
  b.o.status = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
  b.o.out = slurp(dir / "out");
  b.o.err = slurp(dir / "err");
  return b;
}

fs::path write_file(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary) << text;
  return p;
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

const std::string kPeck = "G21 G90 G94\nG0 X0 Y0 Z10\nG98 G83 X0 Y0 Z-100 R2 Q0.000001 F100\nM30\n";

std::string nested_repeats(int inner) {
  return "G21 G90 G94 G0 X0 Y0 Z10\no1 repeat [1000]\no2 repeat [1000]\no3 repeat [" + std::to_string(inner) +
         "]\nG91 G1 X0.001 F100\no3 endrepeat\no2 endrepeat\no1 endrepeat\nM2\n";
}

fs::path linuxcnc_config(const fs::path& dir) {
  return write_file(dir / "lcnc.yaml", "machine: " + kSource + "/pipeline_configs/machines/mx330.yaml\nparse:\n  dialect: linuxcnc\n");
}

// n copies of seed 000's slot cut over one another, at F`feed` (one takes at least 150 s at F1200).
fs::path overlapping_slots(const fs::path& dir, int n, int feed = 1200) {
  std::string p = "G17 G21 G40 G49 G54 G80 G90 G94\nT2 M6\nS4000 M3\nG1 F" + std::to_string(feed) + "\n";
  for (int i = 0; i < n; ++i) p += "G0 Z5\nG0 X0 Y14\nG0 Z0\nG275 X0 Y106 Z-10 R5 W28 K1.5 Q5 P1\n";
  return write_file(dir / ("slots" + std::to_string(n) + ".nc"), p + "G0 Z50\nM5\nM30\n");
}

// An alias bomb: nine lines naming 10^9 values.
fs::path alias_bomb(const fs::path& dir) {
  std::string y = "a0: &a0 [x, x, x, x, x, x, x, x, x, x]\n";
  for (int i = 1; i < 9; ++i) {
    y += "a" + std::to_string(i) + ": &a" + std::to_string(i) + " [";
    for (int k = 0; k < 10; ++k) y += (k ? ", *a" : "*a") + std::to_string(i - 1);
    y += "]\n";
  }
  return write_file(dir / "bomb.yaml", y + "machine: " + kSource + "/pipeline_configs/machines/mx330.yaml\n");
}

TEST(CliHostileInput, PeckExpansionIsRefusedAtItsLineNamingTheKey) {
  const fs::path dir = tmpdir("peck");
  const Bounded r = run_bounded({"parse", write_file(dir / "peck.nc", kPeck).string(), "-o", (dir / "o.txt").string()}, 60);
  ASSERT_FALSE(r.killed) << "2 GB in 75 s before the fix";
  EXPECT_EQ(r.o.status, 3) << r.o.err;
  EXPECT_TRUE(contains(r.o.err, "peck.nc:3:")) << r.o.err;
  EXPECT_TRUE(contains(r.o.err, "parse.max_cycle_moves")) << r.o.err;
  EXPECT_TRUE(contains(r.o.err, "raise Q")) << r.o.err;
}

TEST(CliHostileInput, NestedRepeatsPastTheBoundAreRefusedBeforeTheyRun) {
  const fs::path dir = tmpdir("repeats");
  const Bounded r = run_bounded({"parse", write_file(dir / "rep.ngc", nested_repeats(1000)).string(), "--config",
                                 linuxcnc_config(dir).string(), "-o", (dir / "o.txt").string()},
                                120);
  ASSERT_FALSE(r.killed);
  EXPECT_EQ(r.o.status, 3) << r.o.err;
  EXPECT_TRUE(contains(r.o.err, "rep.ngc:4:")) << r.o.err;
  EXPECT_TRUE(contains(r.o.err, "parse.max_loop_passes")) << r.o.err;
  EXPECT_LT(fs::file_size(dir / "o.txt"), 10000u) << "1 GB of blocks were written before the fix";
}

TEST(CliHostileInput, AliasBombConfigIsRefusedAtOnceWithSummary) {
  const fs::path dir = tmpdir("bomb");
  const fs::path program = write_file(dir / "ok.nc", "G21 G90 G94\nG0 X0 Y0 Z10\nM30\n");
  const auto t0 = Clock::now();
  const Bounded r = run_bounded({"batch", program.string(), "-o", (dir / "out").string(), "--config",
                                 alias_bomb(dir).string(), "--quiet"},
                                60);
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  ASSERT_FALSE(r.killed);
  EXPECT_LT(seconds, 10.0) << "58 s before the fix; 0.04 s measured after";
  EXPECT_EQ(r.o.status, 1);
  EXPECT_TRUE(contains(r.o.err, "bomb.yaml: more than 1000000 values")) << r.o.err;
  const auto summary = read_json(dir / "out" / "summary.json");
  EXPECT_TRUE(contains(summary.at("failure").get<std::string>(), "bomb.yaml")) << summary.dump();
}

// At F3000 the 25 slots take at least 25 x 63 s, within compensate.max_machine_time (3600 s):
// expanded, and the engagement report is what the bound on its blocks keeps short.
TEST(CliHostileInput, OverlappingTrochoidCyclesSkipTheReportNamingTheKey) {
  const fs::path dir = tmpdir("slots");
  const Bounded r = run_bounded({"batch", overlapping_slots(dir, 25, 3000).string(), "-o", (dir / "out").string(),
                                 "--no-simulate"},
                                120);
  ASSERT_FALSE(r.killed) << "minutes in the engagement report before the fix";
  EXPECT_EQ(r.o.status, 0) << r.o.err;
  EXPECT_TRUE(contains(r.o.out, "more than trochoid.max_report_blocks (50000)")) << r.o.out;
  const auto summary = read_json(dir / "out" / "summary.json");
  EXPECT_TRUE(summary.at("trochoid").contains("engagement_not_analysed")) << summary.dump();
}

// At F1200 each of the 25 slots takes at least 156.6 s, 23 of them 3603 s: past
// compensate.max_machine_time (3600 s), refused at
// the cycle that crosses it, before it is expanded, and no later cycle is expanded either.
TEST(CliHostileInput, TrochoidCyclesPastTheMachineTimeAreRefusedBeforeTheyAreExpanded) {
  const fs::path dir = tmpdir("slots_time");
  const Bounded r = run_bounded({"batch", overlapping_slots(dir, 25).string(), "-o", (dir / "out").string(),
                                 "--no-simulate", "--quiet"},
                                120);
  ASSERT_FALSE(r.killed);
  EXPECT_EQ(r.o.status, 1) << r.o.err;
  EXPECT_TRUE(contains(r.o.err, "slots25.nc:96: G275 not expanded: the G275 cycles up to this line take at least"))
      << "the 23rd cycle (line 96) crosses 3600 s\n" << r.o.err;
  EXPECT_TRUE(contains(r.o.err, "more than compensate.max_machine_time (3600 s)")) << r.o.err;
  const auto summary = read_json(dir / "out" / "summary.json");
  EXPECT_TRUE(contains(summary.at("failure").get<std::string>(), "compensate.max_machine_time")) << summary.dump();
  EXPECT_EQ(summary.at("trochoid").at("cycles_expanded").get<int>(), 22) << summary.dump();
  EXPECT_EQ(summary.at("trochoid").at("cycles_rejected").get<int>(), 3) << summary.dump();
  EXPECT_TRUE(contains(slurp(dir / "out" / "diagnostics.txt"), "slots25.nc:104: error: G275 not expanded"))
      << "every later cycle is refused too";
}

TEST(CliHostileInput, ARunThatCannotStartLeavesSummaryWithItsFailure) {
  const fs::path dir = tmpdir("nostart");
  const fs::path out = dir / "out";
  ASSERT_EQ(gcpipe({"batch", kSource + "/samples/five_axis_demo.nc", "-o", out.string(), "--quiet"}).status, 0);
  Outcome missing = gcpipe({"batch", (dir / "missing.nc").string(), "-o", out.string(), "--quiet"});
  EXPECT_EQ(missing.status, 1);
  EXPECT_FALSE(fs::exists(out / "compensated.nc"));
  EXPECT_TRUE(contains(read_json(out / "summary.json").at("failure").get<std::string>(), "missing.nc: cannot open"));
  const fs::path bad = write_file(dir / "bad.yaml", "machine: " + kSource + "/pipeline_configs/machines/mx330.yaml\nparse:\n  max_line_length: 5\n");
  Outcome config = gcpipe({"batch", kSource + "/samples/five_axis_demo.nc", "-o", out.string(), "--config",
                           bad.string(), "--quiet"});
  EXPECT_EQ(config.status, 1);
  EXPECT_TRUE(contains(read_json(out / "summary.json").at("failure").get<std::string>(), "parse.max_line_length"));
}

// A line within parse.max_line_length whose comment the writer carries into compensated.nc, past
// that limit there (issue 32: "compensated.nc does not read back: line is 261 bytes long").
TEST(CliHostileInput, LongLineOfTheWritersOwnOutputReadsBack) {
  const fs::path dir = tmpdir("longline");
  const std::string comment(240, 'X');
  const fs::path p = write_file(dir / "long.nc", "G21 G90 G94 G17\nG0 X0 Y0 Z10\nG1 X10 F500 (" + comment + ")\nG1 Y10\nM30\n");
  Outcome r = gcpipe({"batch", p.string(), "-o", (dir / "out").string(), "--quiet"});
  EXPECT_EQ(r.status, 0) << r.err;
  const std::string compensated = slurp(dir / "out" / "compensated.nc");
  std::size_t longest = 0;
  for (std::size_t pos = 0, end; pos < compensated.size(); pos = end + 1) {
    end = std::min(compensated.find('\n', pos), compensated.size());
    longest = std::max(longest, end - pos);
  }
  EXPECT_GT(longest, 256u) << "the case needs a written line past the input limit";
}

TEST(CliHostileInput, OutputToAFolderIsRefusedAndLeavesNoPart) {
  const fs::path dir = tmpdir("outdir");
  fs::create_directories(dir / "folder");
  Outcome r = gcpipe({"parse", kSource + "/samples/five_axis_demo.nc", "-o", (dir / "folder").string()});
  EXPECT_EQ(r.status, 1);
  EXPECT_TRUE(contains(r.err, "is a folder: give a file name")) << r.err;
  EXPECT_FALSE(fs::exists(dir / "folder.part"));
}

// Messages that name the cause and what to do.
struct MessageCase {
  const char* name;
  std::string program;
  std::string expected;
};

TEST(CliHostileInput, MessagesNameTheCause) {
  const fs::path dir = tmpdir("messages");
  const std::vector<MessageCase> cases = {
      {"cr", "G21 G90 G94\rG0 X0 Y0 Z10\rG1 X10 F100\rM30\r", "the file's lines end in CR only"},
      {"utf16", std::string("\xFF\xFEG\0001\0\n\0", 8), "the file looks like UTF-16"},
      {"f0", "G21 G90 G94\nG0 X0 Y0 Z10\nG1 X10 F0\nM30\n", "f0.nc:3:8: error: F0 is no feed"},
  };
  for (const auto& c : cases) {
    Outcome r = gcpipe({"parse", write_file(dir / (std::string(c.name) + ".nc"), c.program).string(), "-o", "/dev/null"});
    EXPECT_EQ(r.status, 3) << c.name << "\n" << r.err;
    EXPECT_TRUE(contains(r.err, c.expected)) << c.name << "\n" << r.err;
  }
  Outcome cr_long = gcpipe({"parse", write_file(dir / "crlong.nc", std::string(40, 'G') + "\r" + std::string(300, ' ') + "\r").string(),
                            "-o", "/dev/null"});
  EXPECT_TRUE(contains(cr_long.err, "parse.max_line_length in the pipeline config); the lines end in CR only")) << cr_long.err;
}

TEST(CliHostileInput, TooShortInterpolationPeriodNamesTheKeys) {
  const fs::path dir = tmpdir("period");
  const fs::path config = write_file(dir / "period.yaml", "machine: " + kSource + "/pipeline_configs/machines/mx330.yaml\nservo:\n  drives: " +
                                                              kSource + "/pipeline_configs/drives/seed002.yaml\ninterpolate:\n  period: 0.00001\n");
  Outcome r = gcpipe({"simulate", kSource + "/samples/five_axis_demo.nc", "-o", (dir / "t.csv").string(), "--config", config.string()});
  EXPECT_EQ(r.status, 1);
  EXPECT_TRUE(contains(r.err, "interpolate.period = 1e-05 s does not fit the drives in")) << r.err;
  EXPECT_TRUE(contains(r.err, "raise interpolate.period")) << r.err;
  EXPECT_FALSE(fs::exists(dir / "t.csv"));
}

TEST(CliHostileInput, WorkOffsetPastTravelIsATravelErrorNotATimeOne) {
  const fs::path dir = tmpdir("g10");
  const fs::path p = write_file(dir / "g10.nc", "G21 G90 G94\nG0 X0 Y0 Z10\nG10 L2 P1 X99999\nG1 X10 F100\nM30\n");
  Outcome r = gcpipe({"simulate", p.string(), "-o", (dir / "t.csv").string()});
  EXPECT_EQ(r.status, 1);
  EXPECT_TRUE(contains(r.err, "line 4 (G1 X10 F100): axis X goes to 100009.000 mm, outside its travel")) << r.err;
  EXPECT_TRUE(contains(r.err, "check the work offset (G10 L2/L20")) << r.err;
  EXPECT_FALSE(fs::exists(dir / "t.csv"));
}

// SIGINT and SIGTERM end every input-sized loop: the run exits 128 + signal within the bound and
// leaves no file under its final name.
struct StopCase {
  const char* name;
  std::function<std::vector<std::string>(const fs::path& dir)> args;
  std::vector<std::string> final_names;  // relative to dir: must not exist after the stop
  double signal_after;                   // [s]
};

class InterruptHostile : public ::testing::TestWithParam<std::tuple<int, int>> {};

const std::vector<StopCase>& stop_cases() {
  static const std::vector<StopCase> cases = {
      {"dev_zero", [](const fs::path& dir) { return std::vector<std::string>{"parse", "/dev/zero", "-o", (dir / "z.txt").string()}; },
       {"z.txt"}, 1.0},
      {"nested_repeats",  // 10^8 passes: within the bound, so it runs until stopped
       [](const fs::path& dir) {
         return std::vector<std::string>{"parse", write_file(dir / "rep.ngc", nested_repeats(100)).string(), "--config",
                                         linuxcnc_config(dir).string(), "-o", (dir / "rep.txt").string()};
       },
       {"rep.txt"}, 2.0},
      {"trochoid_report",  // two overlapping slots: about 17 s of engagement analysis
       [](const fs::path& dir) {
         return std::vector<std::string>{"batch", overlapping_slots(dir, 2).string(), "-o", (dir / "out").string(),
                                         "--no-simulate", "--quiet"};
       },
       {"out/summary.json", "out/report.json", "out/plots/trochoid_engagement.png"}, 4.0},
  };
  return cases;
}

TEST_P(InterruptHostile, StopsWithinTheBoundAndLeavesNothingComplete) {
  const auto [sig, index] = GetParam();
  const StopCase& c = stop_cases()[static_cast<std::size_t>(index)];
  const fs::path dir = tmpdir(std::string("stop_") + c.name + "_" + std::to_string(sig));
  const Bounded r = run_bounded(c.args(dir), c.signal_after + 30, sig, c.signal_after);
  ASSERT_FALSE(r.killed) << c.name << ": still running " << 30 << " s after the signal";
  EXPECT_EQ(r.o.status, 128 + sig) << c.name << "\n" << r.o.err;
  EXPECT_LE(r.seconds_after_signal, kSignalBound) << c.name;
  for (const auto& f : c.final_names) EXPECT_FALSE(fs::exists(dir / f)) << c.name << ": " << f;
}

INSTANTIATE_TEST_SUITE_P(Signals, InterruptHostile,
                         ::testing::Combine(::testing::Values(SIGINT, SIGTERM), ::testing::Values(0, 1, 2)));

}  // namespace
