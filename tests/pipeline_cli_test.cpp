// One pipeline (issue 10): every subcommand is a prefix of batch's chain and agrees with batch;
// outputs are complete or absent under their final names; an output folder is never left with
// files of an earlier run; a missing compensated.nc is a failure with its reason.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <set>
#include <thread>

#include "cli_helpers.hpp"

namespace {

const std::string kSamples = std::string(GCPIPE_SOURCE_DIR) + "/samples/";

// The number gcpipe simulate prints after "max contour error", in um.
double printed_max_contour_um(const std::string& err) {
  const auto at = err.find("max contour error ");
  if (at == std::string::npos) return -1;
  return std::stod(err.substr(at + 18));
}

std::size_t lines_of(const std::string& text) {
  std::size_t n = 0;
  for (char c : text) n += c == '\n';
  return n;
}

class SubcommandAgrees : public ::testing::TestWithParam<const char*> {};

TEST_P(SubcommandAgrees, WithBatchOnPointsContourErrorAndBytes) {
  const std::string program = kSamples + GetParam();
  const fs::path dir = tmpdir(std::string("agree_") + GetParam());
  Outcome b = gcpipe({"batch", program, "-o", (dir / "batch").string(), "--quiet"});
  ASSERT_EQ(b.status, 0) << b.err;
  const auto report = read_json(dir / "batch" / "report.json");
  // trochoid = parse -> trochoid -> write: the same bytes as batch's output.nc.
  Outcome t = gcpipe({"trochoid", program, "-o", (dir / "trochoid.nc").string()});
  ASSERT_EQ(t.status, 0) << t.err;
  EXPECT_EQ(slurp(dir / "trochoid.nc"), slurp(dir / "batch" / "output.nc"));
  // ik = parse -> trochoid -> ik: one CSV row per point batch counted.
  Outcome k = gcpipe({"ik", program, "--csv", "-o", (dir / "ik.csv").string()});
  ASSERT_EQ(k.status, 0) << k.err;
  EXPECT_EQ(lines_of(slurp(dir / "ik.csv")) - 1, report.at("ik").at("points").get<std::size_t>());
  // simulate = parse -> trochoid -> ik -> simulate: the report's contour error, to the printed digit.
  Outcome s = gcpipe({"simulate", program, "-o", (dir / "trace.csv").string()});
  ASSERT_EQ(s.status, 0) << s.err;
  const double batch_um = report.at("simulation").at("contour_error_before").at("max_mm").get<double>() * 1e3;
  EXPECT_NEAR(printed_max_contour_um(s.err), batch_um, 0.00005 + 1e-9 * batch_um) << s.err;
  const auto ticks_at = s.err.find(": ") + 2;
  EXPECT_EQ(lines_of(slurp(dir / "trace.csv")) - 1, std::stoull(s.err.substr(ticks_at))) << "one trace row per tick";
  // parse alone: one line per block the parser emitted.
  Outcome p = gcpipe({"parse", program, "-o", (dir / "parse.txt").string()});
  ASSERT_EQ(p.status, 0) << p.err;
  EXPECT_EQ(lines_of(slurp(dir / "parse.txt")), report.at("blocks_emitted").get<std::size_t>());
}

INSTANTIATE_TEST_SUITE_P(Samples, SubcommandAgrees, ::testing::Values("trochoid_slot_seed000.nc", "five_axis_demo.nc"));

const std::vector<std::string> kFinalNames = {"output.nc", "compensated.nc", "report.json", "report.txt",
                                              "summary.json", "diagnostics.txt"};

class Interrupted : public ::testing::TestWithParam<int> {};

// A batch stopped half way leaves nothing under a final name: neither its own cut-short files
// nor the complete files of an earlier run in the same folder.
TEST_P(Interrupted, BatchLeavesNoCompleteLookingOutput) {
  const int sig = GetParam();
  const fs::path dir = tmpdir("interrupt_" + std::to_string(sig));
  const fs::path out = dir / "out";
  ASSERT_EQ(gcpipe({"batch", kSamples + "five_axis_demo.nc", "-o", out.string(), "--quiet"}).status, 0);
  ASSERT_TRUE(fs::exists(out / "compensated.nc"));
  // A program that takes several seconds to compensate (about 8 s on the 2-core VM; 4000 segments
  // came down to under 2.5 s when the learning's contour search got faster, so that the stop came
  // after the last file was committed).
  const fs::path program = dir / "cam16000.nc";
  ASSERT_EQ(gcpipe({"synth", "--cam-segments", "16000", "--seed", "1", "-o", program.string()}).status, 0);
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = spawn_gcpipe({"batch", program.string(), "-o", out.string()}, dir / "stdout", dir / "stderr");
  ASSERT_GT(pid, 0);
  // Half way: the program is read and the simulation or the learning is running.
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));
  ::kill(pid, sig);
  int st = 0;
  ::waitpid(pid, &st, 0);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_TRUE(WIFEXITED(st)) << "killed by the signal instead of stopping cleanly";
  EXPECT_EQ(WEXITSTATUS(st), 128 + sig) << slurp(dir / "stderr");
  for (const auto& f : kFinalNames) EXPECT_FALSE(fs::exists(out / f)) << f << " exists after the stop";
  for (const auto& e : fs::recursive_directory_iterator(out))
    EXPECT_NE(e.path().extension(), ".part") << e.path() << " left behind";
  EXPECT_LT(seconds, 60.0);
}

INSTANTIATE_TEST_SUITE_P(Signals, Interrupted, ::testing::Values(SIGINT, SIGTERM));

TEST(OutputFolder, ReusedFolderKeepsNothingOfTheEarlierRun) {
  const fs::path out = tmpdir("reuse") / "out";
  ASSERT_EQ(gcpipe({"batch", kSamples + "five_axis_demo.nc", "-o", out.string(), "--quiet"}).status, 0);
  ASSERT_TRUE(fs::exists(out / "compensated.nc"));
  ASSERT_TRUE(fs::exists(out / "plots" / "toolpath.png"));
  Outcome r = gcpipe({"batch", kSamples + "trochoid_slot_seed000.nc", "-o", out.string(), "--no-simulate", "--quiet"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_FALSE(fs::exists(out / "compensated.nc"));
  EXPECT_FALSE(fs::exists(out / "plots" / "toolpath.png"));
  EXPECT_TRUE(fs::exists(out / "plots" / "trochoid_engagement.png"));
  const auto summary = read_json(out / "summary.json");
  EXPECT_NE(summary.at("input").get<std::string>().find("trochoid_slot_seed000.nc"), std::string::npos);
  const auto report = read_json(out / "report.json");
  for (const auto& f : report.at("outputs")) EXPECT_TRUE(fs::exists(out / f.get<std::string>())) << f;
}

// No compensated.nc (here: the program runs longer than compensate.max_machine_time) is a
// failure: non-zero exit status and the reason in summary.json, not exit 0.
// A config of the MX-330 with its drives whose compensate.max_machine_time is `seconds`.
fs::path config_with_max_machine_time(const fs::path& dir, const std::string& seconds) {
  const fs::path path = dir / "bound.yaml";
  std::ofstream c(path);
  c << "machine: " << GCPIPE_SOURCE_DIR << "/pipeline_configs/machines/mx330.yaml\n"
    << "servo:\n  drives: " << GCPIPE_SOURCE_DIR << "/pipeline_configs/drives/seed002.yaml\n"
    << "compensate:\n  max_machine_time: " << seconds << "\n";
  return path;
}

TEST(OutputFolder, MissingCompensatedProgramIsAFailureWithItsReason) {
  const fs::path dir = tmpdir("nocomp");
  Outcome r = gcpipe({"batch", kSamples + "five_axis_demo.nc", "-o", (dir / "out").string(), "--config",
                      config_with_max_machine_time(dir, "2").string(), "--quiet"});
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out" / "compensated.nc"));
  const auto summary = read_json(dir / "out" / "summary.json");
  ASSERT_TRUE(summary.contains("failure")) << summary.dump();
  EXPECT_NE(summary.at("failure").get<std::string>().find("max_machine_time"), std::string::npos) << summary.dump();
  EXPECT_TRUE(fs::exists(dir / "out" / "output.nc")) << "the streaming stages' output stays";
}

// A program the control runs within compensate.max_machine_time but whose planned reference would
// not (five_axis_demo: 15.99 s on the control, 17.16 s planned; bound 16.5 s) is refused with the
// bound, the control's cycle and what to change.
TEST(OutputFolder, APlanLongerThanTheBoundSaysWhatToRaise) {
  const fs::path dir = tmpdir("planlong");
  Outcome r = gcpipe({"batch", kSamples + "five_axis_demo.nc", "-o", (dir / "out").string(), "--config",
                      config_with_max_machine_time(dir, "16.5").string(), "--quiet"});
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out" / "compensated.nc"));
  for (const char* part : {"planned reference would run longer than compensate.max_machine_time (16.5 s",
                           "the control runs the program in 16.0 s", "raise compensate.max_machine_time"})
    EXPECT_NE(r.err.find(part), std::string::npos) << part << "\n" << r.err;
}

// Limits are errors, not flags: a move past an axis's travel is rejected at its line with the
// axis, the position and the limit; nothing is compensated and the exit status says so.
TEST(Limits, TravelViolationIsAnErrorAtItsLine) {
  const fs::path dir = tmpdir("travel");
  {
    std::ofstream p(dir / "far.nc");
    p << "G21 G90 G94\nG0 X0 Y0 Z0\nG1 X100 F2000\nG1 X500 F2000\nG0 X0\nM30\n";
  }
  Outcome r = gcpipe({"batch", (dir / "far.nc").string(), "-o", (dir / "out").string(), "--quiet"});
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_NE(r.err.find("far.nc:4:1: error: axis X goes to"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("outside its travel [-217.5, 217.5] mm"), std::string::npos) << r.err;
  EXPECT_NE(slurp(dir / "out" / "diagnostics.txt").find("far.nc:4:1: error: axis X"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir / "out" / "compensated.nc"));
  EXPECT_NE(read_json(dir / "out" / "summary.json").at("failure").get<std::string>().find("axis X"), std::string::npos);
  Outcome s = gcpipe({"simulate", (dir / "far.nc").string(), "-o", (dir / "trace.csv").string()});
  EXPECT_EQ(s.status, 1) << s.err;
  EXPECT_NE(s.err.find("far.nc:4:1: error: axis X goes to"), std::string::npos) << s.err;
  EXPECT_FALSE(fs::exists(dir / "trace.csv")) << "no trace for a program the machine cannot run";
}

// compensate.max_machine_time holds inside one block: an arc of 4800 turns (5 h at F1000) is
// refused before it is interpolated, at its line, with no trace left behind.
TEST(Limits, OneBlockPastTheMachineTimeBoundIsRefusedAtItsLine) {
  const fs::path dir = tmpdir("longblock");
  {
    std::ofstream p(dir / "turns.nc");
    p << "G21 G90 G94 G17\nG0 X10 Y0 Z5\nG1 Z0 F100\nG2 X10 Y0 I-10 J0 P4800 F1000\nM30\n";
  }
  Outcome s = gcpipe({"simulate", (dir / "turns.nc").string(), "-o", (dir / "trace.csv").string()});
  EXPECT_EQ(s.status, 1) << s.err;
  EXPECT_NE(s.err.find("line 4 (G2 X10 Y0 I-10 J0 P4800 F1000): this block takes 18095.6 s"), std::string::npos) << s.err;
  EXPECT_NE(s.err.find("compensate.max_machine_time"), std::string::npos) << s.err;
  EXPECT_FALSE(fs::exists(dir / "trace.csv"));
}

// A shop's tool table on the command line: T/H numbers the machine file does not know resolve
// from it; without it the block that uses an unknown tool's geometry (G43 H7) is an error at its
// line that names where tools come from.
TEST(ToolTable, CommandLineTableResolvesTheShopsTools) {
  const fs::path dir = tmpdir("tooltable");
  {
    std::ofstream t(dir / "shop.tbl");
    t << "T7 P7 Z123.5 D10 ;shop end mill\n";
    std::ofstream p(dir / "t7.nc");
    p << "G21 G90 G94\nT7 M6\nG43 H7\nG0 X0 Y0 Z50\nM30\n";
  }
  Outcome without = gcpipe({"parse", (dir / "t7.nc").string()});
  EXPECT_EQ(without.status, 3) << without.err;
  // T7 alone is a warning (a tool the machine file lacks may be in the control's table); G43 H7
  // uses its length, and that line is the error.
  EXPECT_NE(without.err.find("t7.nc:3:5: error: H7: tool 7 is not in the machine config's tool table"), std::string::npos)
      << without.err;
  Outcome with = gcpipe({"parse", (dir / "t7.nc").string(), "--tool-table", (dir / "shop.tbl").string(), "--json"});
  EXPECT_EQ(with.status, 0) << with.err;
  EXPECT_NE(with.out.find("\"tool_length\":123.5"), std::string::npos) << with.out;
}

// gcpipe evaluate on the simulate stage's own trace of a program measures the same rapid error as
// batch's report: a cross-check of the measured-data contour error against the simulation's
// (cutting moves are classified differently: evaluate by the nearest point of the path, since a
// measured run has no tick to match, the simulation by the block being run).
TEST(Evaluate, SimulatedTraceGivesBatchsRapidError) {
  const fs::path dir = tmpdir("evaluate");
  const std::string program = kSamples + "five_axis_demo.nc";
  ASSERT_EQ(gcpipe({"batch", program, "-o", (dir / "batch").string(), "--quiet"}).status, 0);
  ASSERT_EQ(gcpipe({"simulate", program, "-o", (dir / "trace.csv").string()}).status, 0);
  Outcome e = gcpipe({"evaluate", "--trace", (dir / "trace.csv").string(), "--program", program, "--json",
                      (dir / "evaluate.json").string()});
  ASSERT_EQ(e.status, 0) << e.err;
  const auto measured = read_json(dir / "evaluate.json");
  const auto report = read_json(dir / "batch" / "report.json");
  const double batch_rapid_um = report.at("simulation").at("contour_error_before").at("rapid").at("max_mm").get<double>() * 1e3;
  EXPECT_NEAR(measured.at("rapid").at("max_um").get<double>(), batch_rapid_um, 1e-3 * batch_rapid_um);
  EXPECT_GT(measured.at("cutting").at("samples").get<int>(), 10000);
}

}  // namespace

// G61 through the whole batch: the control model stops at every corner, so the original runs
// longer than in G64; the plan stops there too; output.nc keeps the program's G61; compensated.nc
// carries the stops in its timed points and runs in the control's plain mode (no G61, which would
// stop at every point), within the 1.02x of the planned cycle that issue 12 asks.
TEST(PathMode, ExactStopRunsThroughBatchAndTheCompensatedProgramRunsAsPlanned) {
  const fs::path dir = tmpdir("path_mode");
  auto run = [&](const std::string& mode) {
    const fs::path program = dir / (mode + ".nc");
    {
      std::ofstream p(program);
      p << "G21 G90 G94 G17 " << mode << "\nG0 X0 Y0 Z5\nG1 Z0 F500\nG1 X20 F3000\nY20\nX0\nY0\nG0 Z5\nM30\n";
    }
    const fs::path out = dir / ("out_" + mode);
    const Outcome r = gcpipe({"batch", program.string(), "-o", out.string(), "--quiet"});
    EXPECT_EQ(r.status, 0) << r.err;
    return out;
  };
  const fs::path blend = run("G64"), stop = run("G61");
  const auto sb = read_json(blend / "report.json").at("simulation");
  const auto ss = read_json(stop / "report.json").at("simulation");
  EXPECT_GT(ss.at("cycle_time_before_s").get<double>(), sb.at("cycle_time_before_s").get<double>() + 0.3);
  EXPECT_NE(slurp(stop / "output.nc").find("G61"), std::string::npos);
  EXPECT_EQ(slurp(stop / "compensated.nc").find("G61"), std::string::npos);
  EXPECT_TRUE(ss.at("compensated").get<bool>()) << ss.at("note");
  EXPECT_LE(ss.at("cycle_time_after_s").get<double>(), 1.02 * ss.at("cycle_time_planned_s").get<double>());
  // The plan stops where the control does (measured: 9.39 -> 1.06 um). Before the plan knew the
  // G61 stops it blended those corners, ran 4.70 s against the original's 5.59 s and made the
  // error worse (34.8 um): this fails then.
  EXPECT_LT(ss.at("contour_error_after").at("cutting").at("max_mm").get<double>(),
            0.5 * ss.at("contour_error_before").at("cutting").at("max_mm").get<double>());
  EXPECT_GE(ss.at("cycle_time_planned_s").get<double>(), ss.at("cycle_time_before_s").get<double>());
}

// gcpipe config --print builds the stages and lists what they read: the file's values as
// written, the keys it leaves out as "# default", each file (pipeline config, machine, drives)
// in its own group. A key a stage reads cannot be missing from it, so a new option shows up
// without a hand-kept list.
TEST(ConfigPrint, ShowsTheFilesValuesAndMarksTheDefaults) {
  const Outcome r = gcpipe({"config", "--print", "--config", std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/circle_test.yaml"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("# ---- " + std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/circle_test.yaml"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("interpolate:\n  period: 0.001\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("nmv5000.yaml"), std::string::npos) << "the machine file has its own group";
  EXPECT_NE(r.out.find("seed002.yaml"), std::string::npos) << "the drives file has its own group";
  const std::size_t key = r.out.find("  max_machine_time: 3600");
  ASSERT_NE(key, std::string::npos) << r.out;
  const std::size_t eol = r.out.find('\n', key);
  EXPECT_NE(r.out.substr(key, eol - key).find("# default"), std::string::npos) << "compensate.max_machine_time is not in the file";
  EXPECT_EQ(r.out.find("  period: 0.001  "), std::string::npos) << "a value the file gives is not marked as a default";
}

TEST(ConfigPrint, AStageThatCannotBeBuiltIsNamedAndTheStatusIsOne) {
  const fs::path dir = tmpdir("config_print");
  {
    std::ofstream f(dir / "bad.yaml");
    f << "machine: " << GCPIPE_SOURCE_DIR << "/pipeline_configs/machines/mx330.yaml\nservo:\n  drives: " << GCPIPE_SOURCE_DIR
      << "/pipeline_configs/drives/seed002.yaml\ninterpolate:\n  smoothing: cubic\n";
  }
  const Outcome r = gcpipe({"config", "--print", "--config", (dir / "bad.yaml").string()});
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("stage simulate cannot be built"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("'interpolate.smoothing'"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("# stage simulate cannot be built"), std::string::npos) << "the printed config says it too";
}

// Real posts (issue 31 item 5): what a shop's program meets in batch.
namespace {

// A spiral of 120 G2 arcs at F999 in/min (423 mm/s): above X's speed bound on the MX-330 (250
// mm/s, the acceleration over the drive's Ts), as arcspiral.ngc with its feed raised is.
fs::path spiral_at_f999(const fs::path& dir) {
  const fs::path path = dir / "spiral999.nc";
  std::ofstream p(path);
  p << "G20 G64\nG0 Z1\nG0 X1.8 Y0\nG1 Z-0.1 F999\n";
  double r = 1.8, a = 0;
  char line[120];
  for (int k = 0; k < 120; ++k) {
    a += 0.35, r -= 0.01;
    std::snprintf(line, sizeof line, "G2 X%.6f Y%.6f R%.6f\n", r * std::cos(-a), r * std::sin(-a), r);
    p << line;
  }
  p << "G0 Z1\nM30\n";
  return path;
}

// Every file report.json and report.txt list exists, and every file in the folder is listed.
void expect_listed_files_are_the_written_ones(const fs::path& out) {
  const auto report = read_json(out / "report.json");
  std::set<std::string> listed;
  for (const auto& f : report.at("outputs")) listed.insert(f.get<std::string>());
  const std::string text = slurp(out / "report.txt");
  for (const auto& f : listed) {
    EXPECT_TRUE(fs::exists(out / f)) << f << " is listed but was not written";
    EXPECT_NE(text.find(f), std::string::npos) << f << " is not in report.txt";
  }
  for (const auto& e : fs::recursive_directory_iterator(out)) {
    if (!e.is_regular_file()) continue;
    const std::string rel = fs::relative(e.path(), out).string();
    EXPECT_EQ(listed.count(rel), 1u) << rel << " was written but is not listed";
  }
}

}  // namespace

// Before the fix every point of such a program was refused ("no iterate stayed within the axis
// limits: points slowed by the interpolator's speed bound", exit 1): a control clamps the feed.
TEST(RealPosts, AFeedAboveAnAxisBoundIsClampedWithANoteAndCompensated) {
  const fs::path dir = tmpdir("f999");
  const fs::path out = dir / "out";
  // Under seed 002's control, whose acc/dec after interpolation bounds X at 250 mm/s (the
  // acceleration over the drive's Ts). The look-ahead control of default.yaml has no such filter:
  // X's bound there is the machine file's 500 mm/s, above the programmed 423 mm/s.
  const Outcome r = gcpipe({"batch", spiral_at_f999(dir).string(), "-o", out.string(), "--quiet", "--config",
                            std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/seed002_control.yaml"});
  ASSERT_EQ(r.status, 0) << r.err;
  const auto sim = read_json(out / "report.json").at("simulation");
  EXPECT_TRUE(sim.at("compensated").get<bool>()) << sim.at("note");
  const auto& clamp = sim.at("feed_clamped");
  EXPECT_GE(clamp.at("blocks").get<int>(), 100) << clamp.dump();
  EXPECT_EQ(clamp.at("first_line").get<int>(), 4) << clamp.dump();  // the plunge at F999 too
  EXPECT_NEAR(clamp.at("most_clamped").at("programmed_feed_mm_min").get<double>(), 999 * 25.4, 0.1) << "F999 in/min";
  const double percent = clamp.at("most_clamped").at("feed_percent").get<double>();
  EXPECT_GT(percent, 0.0);
  EXPECT_LT(percent, 100.0 * 250.0 / 423.0 + 5.0) << "X's bound over the programmed 423 mm/s";
  EXPECT_NE(slurp(out / "report.txt").find("feed clamped: "), std::string::npos);
  EXPECT_LT(sim.at("contour_error_after").at("max_mm").get<double>(), sim.at("contour_error_before").at("max_mm").get<double>());
  expect_listed_files_are_the_written_ones(out);
}

// A program with a rejected line would run without it: no compensated.nc unless --keep-going.
TEST(RealPosts, RejectedLinesGetNoCompensatedProgramUnlessKeepGoing) {
  const fs::path dir = tmpdir("rejected_post");
  const fs::path program = dir / "bad.nc";
  {
    std::ofstream p(program);
    p << "G21 G90\nG0 X0 Y0 Z5\nG1 Z0 F500\nG1 X20 B2\nG1 X20 Y10 F3000\nG1 X0\nM30\n";
  }
  const Outcome r = gcpipe({"batch", program.string(), "-o", (dir / "out").string(), "--quiet"});
  EXPECT_EQ(r.status, 3) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out" / "compensated.nc"));
  EXPECT_TRUE(fs::exists(dir / "out" / "output.nc"));
  const auto summary = read_json(dir / "out" / "summary.json");
  ASSERT_TRUE(summary.contains("not_compensated")) << summary.dump();
  for (const char* part : {"1 line was rejected", "line 4", "--keep-going"})
    EXPECT_NE(summary.at("not_compensated").get<std::string>().find(part), std::string::npos) << part;
  EXPECT_NE(slurp(dir / "out" / "report.txt").find("not compensated: 1 line was rejected"), std::string::npos);
  expect_listed_files_are_the_written_ones(dir / "out");

  const Outcome k = gcpipe({"batch", program.string(), "-o", (dir / "kept").string(), "--quiet", "--keep-going"});
  EXPECT_EQ(k.status, 3) << k.err;  // lines were still rejected
  EXPECT_TRUE(fs::exists(dir / "kept" / "compensated.nc"));
  EXPECT_TRUE(read_json(dir / "kept" / "report.json").at("simulation").at("compensated").get<bool>());
  expect_listed_files_are_the_written_ones(dir / "kept");
}

// A program of rapids only has nothing to compensate: it is said, exit 4, and no "0.00 um".
TEST(RealPosts, AProgramWithoutCuttingMovesIsNotCompensated) {
  const fs::path dir = tmpdir("rapids_only");
  const fs::path program = dir / "rapids.nc";
  {
    std::ofstream p(program);
    p << "G21 G90\nG0 X0 Y0 Z5\nG0 X20 Y10\nG0 X40 Y0 Z10\nM30\n";
  }
  const Outcome r = gcpipe({"batch", program.string(), "-o", (dir / "out").string()});
  EXPECT_EQ(r.status, 4) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out" / "compensated.nc"));
  EXPECT_NE(r.err.find("not compensated: the program has no cutting moves"), std::string::npos) << r.err;
  const auto summary = read_json(dir / "out" / "summary.json");
  EXPECT_NE(summary.value("not_compensated", "").find("no cutting moves"), std::string::npos) << summary.dump();
  EXPECT_FALSE(summary.contains("failure")) << summary.dump();
  const std::string text = slurp(dir / "out" / "report.txt");
  EXPECT_EQ(text.find("contour error after"), std::string::npos) << text;
  EXPECT_EQ(text.find("0.00 um"), std::string::npos) << text;
  expect_listed_files_are_the_written_ones(dir / "out");
}

// A config without drives (LinuxCNC's xyzac-trt machine: no servo section) compensates nothing:
// batch says why and exits 4, not 0; --no-simulate asks for that and exits 0.
TEST(RealPosts, AConfigWithoutDrivesSaysSoInItsExitStatus) {
  const fs::path dir = tmpdir("no_drives");
  const fs::path program = dir / "square.nc";
  {
    std::ofstream p(program);
    p << "G21 G90 G94\nG0 X0 Y0 Z5\nG1 Z0 F500\nG1 X20 F1000\nY20\nX0\nY0\nG0 Z5\nM30\n";
  }
  const std::string config = std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/linuxcnc_xyzac_trt.yaml";
  const Outcome r = gcpipe({"batch", program.string(), "-o", (dir / "out").string(), "--config", config});
  EXPECT_EQ(r.status, 4) << r.err;
  EXPECT_NE(r.err.find("not compensated: the config has no servo section"), std::string::npos) << r.err;
  EXPECT_NE(read_json(dir / "out" / "summary.json").value("not_compensated", "").find("no servo section"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir / "out" / "compensated.nc"));
  expect_listed_files_are_the_written_ones(dir / "out");
  const Outcome n = gcpipe({"batch", program.string(), "-o", (dir / "asked").string(), "--config", config, "--no-simulate"});
  EXPECT_EQ(n.status, 0) << n.err;
}

// compensate.enabled: false asks for the simulation and its report only: exit 0, the reason in
// summary.json, no failure (it was "no compensated program", exit 1).
TEST(RealPosts, ACompensationTurnedOffInTheConfigIsNoFailure) {
  const fs::path dir = tmpdir("compensate_off");
  const fs::path config = dir / "off.yaml";
  std::ofstream(config) << "machine: " << GCPIPE_SOURCE_DIR << "/pipeline_configs/machines/mx330.yaml\n"
                        << "servo:\n  drives: " << GCPIPE_SOURCE_DIR << "/pipeline_configs/drives/seed002.yaml\n"
                        << "compensate:\n  enabled: false\n";
  const Outcome r = gcpipe({"batch", kSamples + "five_axis_demo.nc", "-o", (dir / "out").string(), "--config", config.string(), "--quiet"});
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out" / "compensated.nc"));
  const auto summary = read_json(dir / "out" / "summary.json");
  EXPECT_FALSE(summary.contains("failure")) << summary.dump();
  EXPECT_NE(summary.value("not_compensated", "").find("compensate.enabled is false"), std::string::npos) << summary.dump();
  EXPECT_TRUE(fs::exists(dir / "out" / "plots" / "contour_error.png")) << "the original is still simulated and drawn";
  expect_listed_files_are_the_written_ones(dir / "out");
}

// The tool-path figure is drawn in the plane that holds the error (issue 31 item 6): a G18
// profile's in XZ, where an XY projection showed a line; a G17 square's in XY. The plane and the
// magnification the figure states are in report.json, in batch and in a DDS node alike.
TEST(Figures, TheToolPathIsDrawnInThePlaneOfItsError) {
  const fs::path dir = tmpdir("planes");
  auto plane_of = [&](const std::string& name, const std::string& text) {
    const fs::path program = dir / (name + ".nc");
    std::ofstream(program) << text;
    const Outcome r = gcpipe({"batch", program.string(), "-o", (dir / name).string(), "--quiet"});
    EXPECT_EQ(r.status, 0) << r.err;
    const auto figure = read_json(dir / name / "report.json").at("simulation").at("toolpath_figure");
    EXPECT_GE(figure.at("magnification").get<double>(), 1.0);
    return figure.at("plane").get<std::string>();
  };
  EXPECT_EQ(plane_of("g18", "G21 G18 G90 G94\nG0 X0 Y0 Z5\nG1 Z0 F500\nG1 X20 F3000\nG2 X40 Z0 I10 K0\nG1 X60\n"
                            "G3 X80 Z0 I10 K0\nG1 Z5\nM30\n"),
            "XZ");
  EXPECT_EQ(plane_of("g17", "G21 G17 G90 G94\nG0 X0 Y0 Z5\nG1 Z0 F500\nG1 X20 F3000\nY20\nX0\nY0\nG0 Z5\nM30\n"), "XY");
  EXPECT_TRUE(fs::exists(dir / "g18" / "plots" / "toolpath.png"));
}

// Reports that fit the program (issue 33 item 5): a three-axis program gets no neural-IK section
// or figures unless --model asks for them; ideal drives are named as such, not "Z 0/0".
TEST(Reports, AThreeAxisProgramGetsNoNeuralIkUnlessAskedAndIdealAxesAreNamed) {
  const fs::path dir = tmpdir("three_axis");
  const Outcome r = gcpipe({"batch", kSamples + "shop_pocket_inch.nc", "-o", (dir / "out").string(), "--quiet"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out" / "plots" / "ik_divergence.png"));
  EXPECT_FALSE(fs::exists(dir / "out" / "plots" / "ik_tip_error.png"));
  const auto report = read_json(dir / "out" / "report.json");
  EXPECT_TRUE(report.at("ik").at("neural").is_null()) << report.at("ik").dump();
  EXPECT_NE(report.at("ik").value("neural_skipped", "").find("three-axis"), std::string::npos);
  const std::string text = slurp(dir / "out" / "report.txt");
  EXPECT_EQ(text.find("neural_outside_envelope"), std::string::npos) << text;
  // The default drives model Z and A as ideal (pipeline_configs/drives/seed002.yaml).
  EXPECT_EQ(report.at("simulation").at("ideal_axes"), nlohmann::json::array({"Z", "A"}));
  EXPECT_NE(text.find("Z A ideal (model: ideal, actual = command)"), std::string::npos) << text;
  EXPECT_EQ(text.find(" Z 0/0"), std::string::npos) << text;

  const std::string model = std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/models/mx330_improved_seed1.model";
  const Outcome asked = gcpipe({"batch", kSamples + "shop_pocket_inch.nc", "-o", (dir / "asked").string(), "--quiet",
                                "--model", model});
  ASSERT_EQ(asked.status, 0) << asked.err;
  EXPECT_TRUE(fs::exists(dir / "asked" / "plots" / "ik_divergence.png"));
  EXPECT_FALSE(read_json(dir / "asked" / "report.json").at("ik").at("neural").is_null());
}

// gcpipe calibrate reports its progress as every long command does (issue 33 item 4): one line a
// step into a log, percent of the axes done, and the last at 100 %.
TEST(CalibrateProgress, TheIdentificationReportsItsStepsAsPlainLines) {
  const fs::path dir = tmpdir("calibrate_progress");
  const std::string config = std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/circle_test.yaml";
  const Outcome sim = gcpipe({"simulate", std::string(GCPIPE_SOURCE_DIR) + "/samples/circle_test_seed002.nc", "--config", config,
                              "-o", (dir / "trace.csv").string(), "--no-progress"});
  ASSERT_EQ(sim.status, 0) << sim.err;
  const Outcome r = gcpipe({"calibrate", (dir / "trace.csv").string(), "--config", config, "-o", (dir / "cal").string(),
                            "--progress", "--no-plots"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("identifying each axis's drive and effects:   0 % (0/10)"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("identifying each axis's drive and effects: 100 % (10/10)"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find('\r'), std::string::npos) << "no carriage returns into a log";
  const Outcome quiet = gcpipe({"calibrate", (dir / "trace.csv").string(), "--config", config, "-o", (dir / "cal2").string(),
                                "--no-progress", "--no-plots"});
  ASSERT_EQ(quiet.status, 0) << quiet.err;
  EXPECT_EQ(quiet.err.find("identifying"), std::string::npos) << quiet.err;
}
