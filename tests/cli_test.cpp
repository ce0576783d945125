// The gcpipe executable as a user runs it: help, batch outputs, exit codes, bad configs, and
// memory that does not grow with the length of the program.
#include <gtest/gtest.h>

#include <regex>
#include <sys/resource.h>
#include <sys/wait.h>
#include <spawn.h>
#include <fcntl.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "cli_helpers.hpp"

namespace {

const std::string kSample = std::string(GCPIPE_SOURCE_DIR) + "/samples/five_axis_demo.nc";

}  // namespace

TEST(Cli, HelpListsCommandsAndEachCommandHasUsage) {
  Outcome r = gcpipe({"--help"});
  EXPECT_EQ(r.status, 0);
  for (const char* c : {"batch", "parse", "synth"}) EXPECT_NE(r.out.find(c), std::string::npos) << c;
  Outcome b = gcpipe({"batch", "--help"});
  EXPECT_EQ(b.status, 0);
  EXPECT_NE(b.out.find("Usage: gcpipe batch"), std::string::npos);
  Outcome u = gcpipe({"frobnicate"});
  EXPECT_EQ(u.status, 2);
  EXPECT_NE(u.err.find("--help"), std::string::npos) << u.err;
  Outcome o = gcpipe({"batch", kSample, "-o", tmpdir("bogus").string(), "--bogus"});
  EXPECT_EQ(o.status, 2);
  EXPECT_NE(o.err.find("--bogus"), std::string::npos) << o.err;
  // Usage comes from the option declarations (CLI11), so every accepted option is documented.
  for (const char* c : {"batch", "parse", "trochoid", "ik", "simulate", "stages", "calibrate", "evaluate", "train-ik", "synth"}) {
    Outcome h = gcpipe({c, "--help"});
    EXPECT_EQ(h.status, 0) << c;
    EXPECT_NE(h.out.find(std::string("Usage: gcpipe ") + c), std::string::npos) << c << ": " << h.out;
  }
  Outcome nb = gcpipe({"batch", "--help"});
  EXPECT_NE(nb.out.find("--no-progress"), std::string::npos) << nb.out;
  Outcome empty = gcpipe({"batch", kSample, "-o", ""});
  EXPECT_EQ(empty.status, 2) << "-o \"\" is a usage error";
}

// A mistyped command or option is named with what was probably meant (CLI11 alone said "A
// subcommand is required" for `gcpipe bacth` and "not expected: x.yaml --confg" for --confg).
TEST(Cli, MistypedCommandsAndOptionsAreNamedWithWhatWasMeant) {
  const std::string out = tmpdir("did_you_mean").string();
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"bacth", kSample}, "unknown command 'bacth': did you mean 'batch'?"},
      {{"batch", kSample, "--confg", "x.yaml", "-o", out}, "unknown option '--confg' for gcpipe batch: did you mean '--config'?"},
      {{"calibrate", "h1.csv", "--output", out}, "unknown option '--output' for gcpipe calibrate: did you mean '--output-dir'?"},
      {{"simulate", kSample, "--quiett"}, "unknown option '--quiett' for gcpipe simulate"},
      {{"frobnicate"}, "unknown command 'frobnicate' (gcpipe --help lists them)"},
  };
  for (const auto& [args, expected] : cases) {
    const Outcome r = gcpipe(args);
    EXPECT_EQ(r.status, 2) << args[0];
    EXPECT_NE(r.err.find(expected), std::string::npos) << r.err;
  }
  // Known words with a wrong value keep CLI11's message, which names the value.
  const Outcome v = gcpipe({"batch", "/nonexistent/x.nc", "-o", out});
  EXPECT_EQ(v.err.find("unknown"), std::string::npos) << v.err;
}

// --progress into a pipe (a log, CI): plain lines with percent and elapsed time at every tenth,
// no carriage returns, and every step closed (a step that stops reporting early says "done").
TEST(Cli, ProgressIntoALogIsPlainLinesWithPercentAndTime) {
  const Outcome r = gcpipe({"batch", (fs::path(GCPIPE_SOURCE_DIR) / "samples" / "trochoid_slot_f3000.nc").string(), "-o",
                            tmpdir("progress").string(), "--progress"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(r.err.find('\r'), std::string::npos);
  EXPECT_NE(r.err.find("compensating (learning, window by window):   0 % (0/"), std::string::npos) << r.err;
  EXPECT_TRUE(std::regex_search(r.err, std::regex("compensating \\(learning, window by window\\): +[1-9][0-9] % \\([0-9]+/[0-9]+\\), [0-9.]+ s")))
      << r.err;
  EXPECT_NE(r.err.find("compensating (learning, window by window): done, "), std::string::npos) << r.err;
}

TEST(Cli, BatchWritesProgramSummaryAndDiagnostics) {
  const fs::path out = tmpdir("batch");
  Outcome r = gcpipe({"batch", kSample, "-o", out.string()});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(fs::exists(out / "output.nc"));
  EXPECT_TRUE(fs::exists(out / "summary.json"));
  const auto summary = read_json(out / "summary.json");
  EXPECT_EQ(summary.at("lines_rejected"), 0) << summary.dump();
  EXPECT_EQ(summary.at("lines_read"), 31);
  EXPECT_NE(r.out.find("31 read = 31 emitted + 0 rejected"), std::string::npos) << r.out;
}

TEST(Cli, RejectedLinesGiveExitThreeAndStrictStops) {
  const fs::path dir = tmpdir("bad");
  {
    std::ofstream p(dir / "bad.nc");
    p << "G0 X1\nG0 B2\nG1 X5 F100\nG1 X[1/0]\nM30\n";
  }
  Outcome r = gcpipe({"batch", (dir / "bad.nc").string(), "-o", (dir / "out").string()});
  EXPECT_EQ(r.status, 3);
  EXPECT_NE(r.err.find("bad.nc:2:4: error: unknown word 'B2'"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("bad.nc:4:7: error: division by zero"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("5 read = 3 emitted + 2 rejected"), std::string::npos) << r.out;
  Outcome s = gcpipe({"batch", (dir / "bad.nc").string(), "-o", (dir / "out2").string(), "--strict"});
  EXPECT_EQ(s.status, 1);
  EXPECT_NE(s.err.find("parse.strict"), std::string::npos) << s.err;
  EXPECT_NE(s.out.find("2 read = 1 emitted + 1 rejected"), std::string::npos) << s.out;
}

TEST(Cli, WrongConfigIsRejectedWithKeyValueAndReason) {
  const fs::path dir = tmpdir("cfg");
  {
    std::ofstream c(dir / "bad.yaml");
    c << "machine: " << GCPIPE_SOURCE_DIR << "/pipeline_configs/machines/mx330.yaml\nparse:\n  max_line_length: 5\n";
  }
  Outcome r = gcpipe({"parse", kSample, "--config", (dir / "bad.yaml").string()});
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("bad.yaml:3:20: key 'parse.max_line_length': value '5' is outside the valid range [16, 65536]"),
            std::string::npos)
      << r.err;
  {
    std::ofstream c(dir / "typo.yaml");
    c << "machine: " << GCPIPE_SOURCE_DIR << "/pipeline_configs/machines/mx330.yaml\nparse:\n  dialekt: fanuc\n";
  }
  Outcome t = gcpipe({"parse", kSample, "--config", (dir / "typo.yaml").string()});
  EXPECT_EQ(t.status, 1);
  EXPECT_NE(t.err.find("key 'parse.dialekt': unknown key"), std::string::npos) << t.err;
  Outcome m = gcpipe({"parse", kSample, "--config", (dir / "missing.yaml").string()});
  EXPECT_EQ(m.status, 1);
  EXPECT_NE(m.err.find("cannot open config file"), std::string::npos) << m.err;
}

// Streaming: peak memory is set by the longest line, not by the length of the program.
TEST(Cli, PeakMemoryDoesNotGrowWithProgramLength) {
  const fs::path dir = tmpdir("rss");
  ASSERT_EQ(gcpipe({"synth", "--megabytes", "20", "-o", (dir / "small.nc").string()}).status, 0);
  ASSERT_EQ(gcpipe({"synth", "--megabytes", "200", "-o", (dir / "large.nc").string()}).status, 0);
  // The streaming stages (the simulation keeps the program in memory and is skipped here).
  Outcome small = gcpipe({"batch", (dir / "small.nc").string(), "-o", (dir / "o1").string(), "--quiet", "--no-simulate"});
  Outcome large = gcpipe({"batch", (dir / "large.nc").string(), "-o", (dir / "o2").string(), "--quiet", "--no-simulate"});
  ASSERT_EQ(small.status, 0) << small.err;
  ASSERT_EQ(large.status, 0) << large.err;
  EXPECT_GT(fs::file_size(dir / "o2" / "output.nc"), 9 * fs::file_size(dir / "o1" / "output.nc"));
  RecordProperty("peak_rss_20MB", std::to_string(small.max_rss_mb));
  RecordProperty("peak_rss_200MB", std::to_string(large.max_rss_mb));
  std::printf("peak RSS: 20 MB program %.1f MB, 200 MB program %.1f MB\n", small.max_rss_mb, large.max_rss_mb);
  EXPECT_LT(large.max_rss_mb, small.max_rss_mb + 2.0);  // ten times the input, the same memory
  fs::remove_all(dir);
}

// parse -> trochoid -> write: the paper's slot expands, its figure is drawn, and an impossible
// cycle is rejected with its line while the rest of the program still runs from the right place.
TEST(Cli, BatchExpandsTrochoidCyclesAndDrawsTheirFigure) {
  const fs::path out = tmpdir("troch");
  Outcome r = gcpipe({"batch", std::string(GCPIPE_SOURCE_DIR) + "/samples/trochoid_slot_seed000.nc", "-o", out.string()});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("parse -> trochoid -> write -> force -> ik -> simulate -> compensate"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("1 G275 cycles expanded, 0 rejected"), std::string::npos) << r.out;
  ASSERT_TRUE(fs::exists(out / "plots" / "trochoid_engagement.png"));
  EXPECT_GT(fs::file_size(out / "plots" / "trochoid_engagement.png"), 20000u);  // a drawn figure, not an empty canvas
  EXPECT_GT(fs::file_size(out / "output.nc"), 300000u);  // ~20,000 expanded blocks

  const fs::path dir = tmpdir("troch_bad");
  {
    std::ofstream p(dir / "slots.nc");
    p << "T2 M6\nG0 X0 Y0 Z5\nG1 F1000 Z5\n"
         "G275 X0 Y60 Z-5 R5 W18 K1.5\n"   // narrower than the D20 tool: impossible
         "G275 X40 Y60 Z-5 R5 W28 K1\n"    // fine, starts where the first one would have ended
         "M30\n";
  }
  Outcome b = gcpipe({"batch", (dir / "slots.nc").string(), "-o", (dir / "o").string()});
  EXPECT_EQ(b.status, 3);
  EXPECT_NE(b.err.find("slots.nc:4: error: G275 rejected:"), std::string::npos) << b.err;
  EXPECT_NE(b.out.find("1 G275 cycles expanded, 1 rejected"), std::string::npos) << b.out;
}

// The main job end to end on seed 002's circle test: a compensated program that reads back with
// this project's parser in both dialects, a report with the before/after figures, and the plots.
TEST(Cli, BatchCompensatesTheCircleTestAndWritesReportAndPlots) {
  const fs::path out = tmpdir("circle");
  Outcome r = gcpipe({"batch", std::string(GCPIPE_SOURCE_DIR) + "/samples/circle_test_seed002.nc", "-o", out.string(),
                      "--config", std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/circle_test.yaml"});
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("-> simulate -> compensate"), std::string::npos) << r.out;
  for (const char* f : {"compensated.nc", "report.json", "report.txt", "output.nc", "summary.json"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
  for (const char* f : {"toolpath.png", "ballbar.png", "contour_error.png", "following_error.png"}) {
    ASSERT_TRUE(fs::exists(out / "plots" / f)) << f;
    EXPECT_GT(fs::file_size(out / "plots" / f), 20000u) << f << " looks blank";
  }
  const auto report = read_json(out / "report.json");
  const auto& sim = report.at("simulation");
  EXPECT_EQ(sim.at("compensated"), true) << sim.dump().substr(0, 400);
  // The 2 pi condition (lines 41-44) comes down at least tenfold, measured on the written file.
  bool found = false;
  for (const auto& seg : sim.at("segments")) {
    if (seg.at("first_line") != 41) continue;
    found = true;
    EXPECT_GE(seg.at("max_contour_error_reduction").get<double>(), 10.0) << seg.dump();
  }
  EXPECT_TRUE(found) << sim.dump().substr(0, 2000);
  // What a sceptic asks for: cutting and rapid moves apart, both cycle times, and the original
  // slowed to the compensated program's cycle time.
  for (const char* k : {"contour_error_before", "contour_error_after"})
    for (const char* part : {"cutting", "rapid"}) {
      EXPECT_GE(sim.at(k).at(part).at("max_mm").get<double>(), 0.0) << k << "." << part;
      EXPECT_GE(sim.at(k).at(part).at("rms_mm").get<double>(), 0.0) << k << "." << part;
    }
  EXPECT_EQ(sim.at("contour_error_before").at("cutting").at("max_mm"), sim.at("contour_error_before").at("max_mm"));
  const double before_s = sim.at("cycle_time_before_s").get<double>(), after_s = sim.at("cycle_time_after_s").get<double>();
  EXPECT_NEAR(before_s, 34.6, 0.5);
  const auto& slowed = sim.at("slowed_original");
  EXPECT_LT(slowed.at("feed_factor").get<double>(), 1.0);
  EXPECT_NEAR(slowed.at("cycle_time_s").get<double>(), after_s, 0.02 * after_s) << slowed.dump();
  // The compensated program keeps the structure and reads back in its dialect (Fanuc here). Its
  // guard is written in that dialect (IF [...] THEN #3000), so a LinuxCNC reading of it fails at
  // the guard since issue 30; the LinuxCNC form is run by rs274 in tests/rs274_compensated_test.cpp.
  std::ifstream c(out / "compensated.nc");
  std::stringstream cs;
  cs << c.rdbuf();
  const std::string program = cs.str();
  EXPECT_EQ(program.rfind("%", 0), 0u);
  EXPECT_NE(program.find("O2 (SEED 002 SYNCHRONOUS CIRCLE TEST)"), std::string::npos);
  EXPECT_NE(program.find("(source: G3 X13. Y0 I-8. J0 C360. F15)"), std::string::npos);
  EXPECT_NE(program.find("M30"), std::string::npos);
  EXPECT_NE(program.find("IF [ABS[#5221 - 0.0000] GT 0.0010] THEN #3000 = 1"), std::string::npos);
  Outcome p = gcpipe({"parse", (out / "compensated.nc").string(), "--strict"});
  EXPECT_EQ(p.status, 0) << p.err;
}

// The default config ships a neural IK model: batch draws the neural-against-analytic figures and
// puts the divergence statistics into summary.json and report.json.
TEST(Cli, BatchDrawsTheIkFiguresAndReportsDivergence) {
  const fs::path out = tmpdir("ikplots");
  Outcome r = gcpipe({"batch", std::string(GCPIPE_SOURCE_DIR) + "/samples/five_axis_demo.nc", "-o", out.string()});
  ASSERT_EQ(r.status, 0) << r.err;
  for (const char* f : {"ik_divergence.png", "ik_tip_error.png", "toolpath.png", "contour_error.png", "following_error.png"}) {
    ASSERT_TRUE(fs::exists(out / "plots" / f)) << f;
    EXPECT_GT(fs::file_size(out / "plots" / f), 20000u) << f << " looks blank";
  }
  for (const char* f : {"summary.json", "report.json"}) {
    const auto j = read_json(out / f);
    EXPECT_EQ(j.at("ik").at("points"), 14) << f;
    EXPECT_EQ(j.at("ik").at("neural").at("max_abs_diff").size(), 5u) << f;
  }
}

// Issue 6's second goal: the paper's slot at F3000 (the README's first command) comes down at
// least tenfold in maximum contour error, measured on the written compensated.nc.
TEST(Cli, BatchCompensatesTheSlotAtF3000TenfoldOrBetter) {
  const fs::path out = tmpdir("slot3000");
  Outcome r = gcpipe({"batch", std::string(GCPIPE_SOURCE_DIR) + "/samples/trochoid_slot_f3000.nc", "-o", out.string()});
  ASSERT_EQ(r.status, 0) << r.err;
  std::ifstream j(out / "report.json");
  std::stringstream js;
  js << j.rdbuf();
  const std::string report = js.str();
  const auto at = report.find("\"max_contour_error_reduction\":");
  ASSERT_NE(at, std::string::npos) << report.substr(0, 2000);
  const double reduction = std::stod(report.substr(at + 30));
  std::printf("slot at F3000: max contour error down %.2fx\n", reduction);
  EXPECT_GE(reduction, 10.0);
  EXPECT_TRUE(fs::exists(out / "compensated.nc"));
  EXPECT_TRUE(fs::exists(out / "plots" / "trochoid_engagement.png"));
}
