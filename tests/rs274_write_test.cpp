// output.nc judged by LinuxCNC's interpreter (issue 30): a program and gcpipe's output.nc of it
// (parse, then write in the LinuxCNC dialect with the source's frames, as the write stage does)
// both go through `rs274 -n 0 -g -v VARFILE -t TOOLTABLE FILE` on one control state that is not
// gcpipe's machine file:
//  - the parameter file holds probed work offsets (G54 X-312.4 Y-201.7 Z-405.3, G55..G59 others),
//    G28 and G30 positions away from machine zero (#5161-#5166, #5181-#5186), where gcpipe's
//    machine file has G54 and both at zero (standalone rs274 starts in G54 whatever #5220 holds:
//    that output.nc asserts no G54 of its own is tests/write_test.cpp's to check);
//  - the tool table's lengths and radii differ from the machine file's (T1 100 mm, T2 110 mm).
// rs274 rewrites its parameter file at the end of a run, so each run gets a fresh copy.
// Both runs must make the same moves in machine coordinates: rs274 prints STRAIGHT_TRAVERSE,
// STRAIGHT_FEED and ARC_FEED in program coordinates and units, with SET_G5X_OFFSET,
// SET_G92_OFFSET, USE_TOOL_LENGTH_OFFSET and USE_LENGTH_UNITS as calls of their own; machine
// coordinates in mm are (position + G5x + G92 + tool offset) x units. Moves that go nowhere are
// dropped on both sides. Paired move by move: the kind (traverse, feed, arc), the end point, an
// arc's centre, a feed move's rate, within 5e-4 program units (rs274 prints 4 decimals).
// rs274 must reject no line of output.nc.
//
// Programs: every LinuxCNC-dialect program under ../shared/data that gcpipe accepts, the samples/
// whose source rs274 reads (Fanuc samples: parsed as Fanuc, written as LinuxCNC), and seeded
// generated programs with work offsets and G10 L2/L20, G28/G30/G53, G43 H/G49 with tool changes,
// G92/G52, canned cycles, polar coordinates, subroutines with named parameters and cutter
// compensation.
//
// Deliberate differences (also in docs/reference.md, "The write stage"); the generated programs
// avoid them, and a program that hits one would show as a disagreement:
//  - Canned cycles are written expanded into G0/G1 moves from the parser's position: a G98
//    return to an initial level the control decided (a cycle right after G28/G30/G53, a change
//    of work system or of tool length, before any absolute Z) goes to the machine file's level.
//  - An arc in R format, or cutter compensation's entry, from a position only the control knows
//    (as above, before an absolute move of the plane's axes) is written with the centre the
//    parser found from its own start.
//  - G43 without H takes the tool the parser knows is loaded (H0 before any M6), not the
//    control's.
//  - Across dialects (not judged here: rs274 reads LinuxCNC only) G10 L20, G10 L2 P0, a Fanuc
//    G91 G10 and G1 G53 on Fanuc are written as the machine file resolves them, with a note.
#include <gtest/gtest-spi.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <regex>
#include <set>
#include <sstream>

#include "parse_helpers.hpp"
#include "rs274_util.hpp"
#include "write.hpp"

using namespace gcpipe;
using namespace gcpipe::test;
using namespace gcpipe::test::rs274;
namespace fs = std::filesystem;

namespace {

fs::path work_dir() { return fs::path(testing::TempDir()) / ("gcpipe_rs274_write_" + std::to_string(::getpid())); }

// The control state: values in the parameter file are in rs274's internal unit, the inch (it has
// no ini to say mm), so each mm value is divided by 25.4.
std::string control_parameters() {
  const std::vector<std::pair<int, double>> mm = {
      {5161, 12.5}, {5162, -30.0}, {5163, 150.0}, {5164, 5.0}, {5166, 10.0},   // G28 home
      {5181, -40.0}, {5182, 25.0}, {5183, 120.0}, {5184, -5.0}, {5186, 20.0},  // G30 home
      {5221, -312.4}, {5222, -201.7}, {5223, -405.3},                          // G54
      {5241, 101.3}, {5242, -57.9}, {5243, -388.1}, {5244, 3.0},               // G55
      {5261, -12.0}, {5262, 240.5}, {5263, -300.0},                            // G56
      {5281, 55.0}, {5282, 66.0}, {5283, -77.0},                               // G57
      {5301, -1.5}, {5302, 2.5}, {5303, -350.0},                               // G58
      {5321, 400.0}, {5322, -400.0}, {5323, -250.0}, {5326, 15.0},             // G59
  };
  const std::set<int> angles = {5164, 5166, 5184, 5186, 5244, 5326};
  std::map<int, double> in_order;
  for (const auto& [n, v] : mm) in_order[n] = angles.count(n) ? v : v / 25.4;
  std::string t;  // rs274 reads the numbers in increasing order only
  char buf[64];
  for (const auto& [n, v] : in_order) {
    std::snprintf(buf, sizeof buf, "%d %.9f\n", n, v);
    t += buf;
  }
  return t;
}

// Lengths and radii measured on the control, in inches as rs274 standalone reads its table:
// 3.1 in = 78.74 mm and 4.2 in = 106.68 mm, where the machine file has 100 and 110 mm.
const char* kToolTable = "T1 P1 D0.4 Z3.1 ;measured\nT2 P2 D0.8 Z4.2 ;measured\n";

MachineConfig machine_file() {
  MachineConfig m;
  m.name = "rs274_write";
  m.tools[1] = {100.0, 10.0};
  m.tools[2] = {110.0, 20.0};
  return m;  // G54 and the reference positions at machine zero
}

// rs274 on the text with the control state below.
Rs274Run run_rs274(const std::string& name, const std::string& text) {
  return rs274::run(work_dir(), name, text, control_parameters(), kToolTable);
}

struct Written {
  bool accepted = false;  // gcpipe's parser rejected no line
  std::string text;       // output.nc
};

// The write stage's output of a program: parsed in its dialect, written in LinuxCNC's with the
// source's frames.
Written write_output(const std::string& source, ParseOptions po) {
  po.block_delete = false;  // rs274's default
  const Parsed p = parse_text(source, po, machine_file(), "source.ngc");
  WriteOptions wo;
  wo.dialect = Dialect::kLinuxCnc;
  wo.source_frames = true;
  Writer w(wo);
  Written out;
  out.accepted = p.first_error() == nullptr;
  std::size_t i = 0, j = 0;
  for (bool is_block : p.order) {
    if (is_block) w.write(p.blocks[i++], out.text);
    else w.write_diagnostic(p.diags[j++], out.text);
  }
  return out;
}

struct Tally {
  std::size_t programs = 0, moves = 0, disagreements = 0, not_judged = 0, deliberate = 0;
  double max_difference = 0;  // [mm]
};

// The two runs move alike: same number of moves, each of the same kind to the same place.
bool same_moves(const Rs274Run& source, const Rs274Run& output, Tally& t, const std::string& what) {
  bool same = source.moves.size() == output.moves.size();
  EXPECT_EQ(source.moves.size(), output.moves.size()) << what << ": number of moves differs";
  const std::size_t n = std::min(source.moves.size(), output.moves.size());
  for (std::size_t i = 0; i < n && same; ++i) {
    const Move& a = source.moves[i];
    const Move& b = output.moves[i];
    double d = 0;
    for (int k = 0; k < 6; ++k) d = std::max(d, std::fabs(a.end[k] - b.end[k]));
    if (a.kind == 'A' && b.kind == 'A')
      for (int k = 0; k < 2; ++k) d = std::max(d, std::fabs(a.centre[k] - b.centre[k]));
    t.max_difference = std::max(t.max_difference, d);
    const bool feed_ok = a.kind == 'T' || std::fabs(a.feed - b.feed) <= 1e-6 * std::max(1.0, a.feed);
    if (a.kind != b.kind || d > std::max(a.tol, b.tol) || !feed_ok) {
      ADD_FAILURE() << what << ": move " << i << " differs: source " << a.kind << " (" << a.end[0] << ", " << a.end[1]
                    << ", " << a.end[2] << ") F" << a.feed << ", output.nc " << b.kind << " (" << b.end[0] << ", "
                    << b.end[1] << ", " << b.end[2] << ") F" << b.feed;
      same = false;
    }
  }
  t.moves += n;
  return same;
}

// rs274's complaints that are no motion: M428/M429/M430 are user M codes of the xyzac_trt
// configuration that standalone rs274 does not load (TCP on/off; gcpipe writes them as read).
const std::regex kUserMCodes(R"(^M-code greater than 199: M4(28|29|30)|^\S*\s*M4(28|29|30)\b)");

std::vector<std::string> motion_complaints(const Rs274Run& r, const std::regex& allowed) {
  std::vector<std::string> out;
  for (const auto& line : r.rejected)
    if (!std::regex_search(line, allowed) && !std::regex_search(line, kUserMCodes) &&
        line.find(" M428") == std::string::npos && line.find(" M429") == std::string::npos)
      out.push_back(line);
  return out;
}

// One program judged: rs274 on the source and on output.nc. `allowed` are rs274's complaints
// about the source that are the source's dialect, not motion (a Fanuc G4 X dwell). A program
// with a deliberate difference (`deliberate`: why) must differ, so that the list cannot go stale.
void judge(const std::string& name, const std::string& source, const ParseOptions& po, Tally& t,
           const std::regex& allowed = std::regex("$^"), const char* deliberate = nullptr) {
  SCOPED_TRACE(name);
  const Written w = write_output(source, po);
  if (!w.accepted) {
    std::printf("not judged: %s: gcpipe rejects a line of the source\n", name.c_str());
    ++t.not_judged;
    return;
  }
  const Rs274Run theirs = run_rs274(name + "_source", source);
  const auto complaints = motion_complaints(theirs, allowed);
  if (!complaints.empty()) {
    std::printf("not judged: %s: rs274 rejects the source: %s\n", name.c_str(), complaints.front().c_str());
    ++t.not_judged;
    return;
  }
  const Rs274Run ours = run_rs274(name + "_output", w.text);
  const auto ours_complaints = motion_complaints(ours, std::regex("$^"));
  EXPECT_TRUE(ours_complaints.empty()) << "rs274 rejects output.nc: " << ours_complaints.front() << "\n" << w.text;
  ++t.programs;
  if (deliberate) {
    Tally scratch;
    testing::ScopedTrace why(__FILE__, __LINE__, deliberate);
    EXPECT_NONFATAL_FAILURE(same_moves(theirs, ours, scratch, name), "differs");
    std::printf("deliberate difference: %s: %s\n", name.c_str(), deliberate);
    ++t.deliberate;
    return;
  }
  if (!ours_complaints.empty() || !same_moves(theirs, ours, t, name + "\nsource:\n" + source + "\noutput.nc:\n" + w.text))
    ++t.disagreements;
}

void report(const char* what, const Tally& t) {
  std::printf("%s: %zu programs judged, %zu paired moves, max difference %.2g mm, %zu disagreements, %zu deliberate "
              "differences, %zu not judged\n",
              what, t.programs, t.moves, t.max_difference, t.disagreements, t.deliberate, t.not_judged);
}

// Seeded programs on the features that depend on the control's frames. Every move that could
// depend on a position only the control knows is either an absolute move, or a G91 move (which
// output.nc must write as the increment); cycles, arcs and compensation start from an absolute
// position (see the deliberate differences above).
class FrameProgram {
 public:
  explicit FrameProgram(unsigned seed) : rng_(seed), inch_(seed % 8 == 0) {}

  std::string text() {
    std::string t = std::string(inch_ ? "G20" : "G21") + " G90 G17 G40 G80 F" + len(200) + "\n" + subroutine();
    if (pick(2)) t += "G5" + std::to_string(4 + pick(6)) + "\n";
    t += pick(2) ? "G91 G0 X" + len(5) + " Y" + len(-3) + "\nG90\n" : "";  // from where the control stands
    t += "T1 M6\nG43 H1\n" + place();
    const int steps = 8 + pick(8);
    for (int i = 0; i < steps; ++i) t += step();
    return t + "G0 Z" + len(30) + "\nM2\n";
  }

 private:
  int pick(int n) { return static_cast<int>(rng_() % static_cast<unsigned>(n)); }
  double uni(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng_); }
  // A length of the program's units: mm values shown in inches for an inch program.
  std::string len(double mm) {
    char b[32];
    std::snprintf(b, sizeof b, "%.4f", inch_ ? mm / 25.4 : mm);
    return b;
  }
  std::string any(double lo, double hi) { return len(uni(lo, hi)); }
  std::string xy() { return "X" + any(-40, 40) + " Y" + any(-40, 40); }
  // An absolute position of every axis the next moves start from.
  std::string place() { return "G0 " + xy() + "\nG0 Z" + any(5, 20) + "\n"; }

  std::string subroutine() {
    return "o<ring> sub\n#<cx> = #1\n#<cy> = #2\n#<r> = #3\nG0 X[#<cx> + #<r>] Y#<cy>\nG0 Z" + len(2) +
           "\nG1 Z[-#4]\nG3 X[#<cx> + #<r>] Y#<cy> I[-#<r>] J0\nG0 Z" + len(5) + "\no<ring> endsub\n";
  }

  std::string step() {
    switch (pick(13)) {
      case 0: return "G5" + std::to_string(4 + pick(6)) + "\n" + (pick(2) ? place() : "G91 G1 X" + any(-5, 5) + " Z" + any(-2, 2) + "\nG90\n");
      case 1: return g10_l2();
      case 2: return "G10 L20 P" + std::to_string(pick(7)) + " X" + any(-10, 10) + (pick(2) ? " Z" + any(-5, 5) : "") + "\n" + place();
      case 3: return home();
      case 4: return pick(2) ? "G53 G0 Z" + any(-20, -1) + "\n" : "G1 G53 X" + any(-50, 50) + " Y" + any(-50, 50) + " F" + len(300) + "\n";
      case 5: return tool_length();
      case 6: return cycle();
      case 7: return polar();
      case 8: return "o<ring> call [" + any(-20, 20) + "] [" + any(-20, 20) + "] [" + any(2, 6) + "] [" + any(0.5, 2) + "]\n";
      case 9: return compensated();
      case 10: return shift();
      case 11: return place() + "G1 Z" + any(-3, 0) + " F" + len(150) + "\nG2 " + xy() + " R" + len(60) + "\n";
      default: return "G91 G1 X" + any(-8, 8) + " Y" + any(-8, 8) + " F" + len(250) + "\nG90 G0 " + xy() + "\n";
    }
  }
  std::string g10_l2() {
    std::string t = "G10 L2 P" + std::to_string(pick(7)) + " X" + any(-100, 100);
    if (pick(2)) t += " Y" + any(-100, 100);
    if (pick(2)) t += " Z" + any(-300, 0);
    return t + "\n" + (pick(2) ? place() : "G91 G0 Z" + any(-3, 3) + "\nG90\n");
  }
  std::string home() {
    switch (pick(5)) {
      case 0: return "G91 G28 Z0\nG90\n" + place();
      case 1: return "G28 X" + any(-20, 20) + " Z" + any(10, 30) + "\n" + place();
      case 2: return "G28\nG91 G0 X" + any(-5, 5) + "\nG90\n" + place();
      case 3: return "G30 Z" + any(10, 30) + "\nG91 G1 Z" + any(-5, 0) + " F" + len(100) + "\nG90\n" + place();
      default: return "G91 G30 X0 Y0\nG90\n" + place();
    }
  }
  std::string tool_length() {
    const int tool = 1 + pick(2);
    const std::string h = std::to_string(tool);
    switch (pick(4)) {
      case 0: return "T" + h + " M6\nG43 H" + h + "\nG0 Z" + any(5, 20) + "\n";
      case 1: return "G49\nG91 G0 Z" + any(-2, 2) + "\nG90\n";
      case 2: return "G10 L1 P" + h + " Z" + any(50, 150) + "\nG43 H" + h + "\n" + place();
      default: return "T" + h + " M6\nG0 G43 H" + h + " Z" + any(5, 20) + "\n";
    }
  }
  std::string cycle() {
    const char* codes[] = {"G81", "G82", "G83", "G73", "G85"};
    const std::string code = codes[pick(5)];
    std::string extra = code == "G82" ? " P0.2" : code == "G83" || code == "G73" ? " Q" + any(0.5, 1.5) : "";
    if (pick(3) == 0)  // incremental holes in a row, from the absolute start
      return place() + "G91 G98 " + code + " X" + any(2, 6) + " Y" + any(-3, 3) + " Z" + any(-4, -1) + " R" + any(-3, -1) +
             extra + " L" + std::to_string(2 + pick(3)) + "\nG90 G80\n";
    return place() + (pick(2) ? "G98 " : "G99 ") + code + " " + xy() + " Z" + any(-4, -1) + " R" + any(1, 3) + extra +
           "\n" + xy() + "\nG80\n";
  }
  std::string polar() {
    std::string t = place() + "G0 @" + any(5, 30) + " ^" + std::to_string(pick(360)) + "\n";
    if (pick(2)) t += "G91 G1 @" + any(1, 5) + " ^" + std::to_string(10 + pick(80)) + " F" + len(200) + "\nG90\n";
    return t;
  }
  std::string compensated() {
    const std::string r = any(0.5, 2);
    return "G10 L1 P1 R" + r + "\nG0 X" + len(-30) + " Y" + len(-30) + "\nG0 Z" + len(1) + "\n" + (pick(2) ? "G41" : "G42") +
           " D1\nG1 X0 Y0 F" + len(200) + "\nG1 X" + len(20) + "\nG3 X" + len(30) + " Y" + len(10) + " R" + len(10) +
           "\nG1 Y" + len(25) + "\nG40\nG1 X" + len(-30) + " Y" + len(-30) + "\n";
  }
  std::string shift() {
    switch (pick(3)) {
      case 0: return "G92 X0 Y0\nG0 " + xy() + "\nG92.1\n" + place();
      case 1: return "G92 Z" + any(-5, 5) + "\nG92.2\nG0 " + xy() + "\nG92.3\nG0 Z" + any(1, 10) + "\nG92.1\n" + place();
      default: return "G52 X" + any(-20, 20) + " Y" + any(-20, 20) + "\nG0 " + xy() + "\nG52 X0 Y0\n" + place();
    }
  }

  std::mt19937 rng_;
  bool inch_;
};

ParseOptions linuxcnc() {
  ParseOptions o;
  o.dialect = Dialect::kLinuxCnc;
  return o;
}

}  // namespace

// The two programs of issue 30, on the control state above: the retract to Z home goes to the
// control's G28 position and the G10 L2 fixture offset holds, in output.nc as in the source.
TEST(Rs274Write, UserExamplesMoveAsTheSourceOnTheControl) {
  if (rs274_path().empty()) GTEST_SKIP() << "rs274 (Debian package linuxcnc-uspace) is not installed";
  Tally t;
  judge("user_g28", "G21 G90 G17\nT1 M6\nG54 G0 X-5. Y-5.\nG43 Z50. H1\nG1 Z-2. F300.\nG1 X50. F1500.\nG0 Z25.\nM5\n"
                    "G91 G28 Z0\nG90\nM30\n", linuxcnc(), t);
  judge("user_g10", "G10 L2 P1 Z-300\nG54\nG0 X10 Y10 Z50\nM2\n", linuxcnc(), t);
  report("user examples", t);
  EXPECT_EQ(t.programs, 2u);
  EXPECT_EQ(t.disagreements, 0u);
  EXPECT_GE(t.moves, 7u);
}

TEST(Rs274Write, GeneratedFramePrograms) {
  if (rs274_path().empty()) GTEST_SKIP() << "rs274 (Debian package linuxcnc-uspace) is not installed";
  const char* env = std::getenv("GCPIPE_RS274_WRITE_PROGRAMS");
  const unsigned programs = env ? static_cast<unsigned>(std::atoi(env)) : 220;
  Tally t;
  for (unsigned seed = 1; seed <= programs; ++seed) judge("frames_" + std::to_string(seed), FrameProgram(seed).text(), linuxcnc(), t);
  report("generated frame programs", t);
  EXPECT_EQ(t.disagreements, 0u);
  EXPECT_EQ(t.not_judged, 0u) << "every generated program must be accepted by gcpipe and rs274";
  EXPECT_GE(t.programs, 200u);
  EXPECT_GE(t.moves, 20u * t.programs);  // the programs move: a comparison of nothing would pass
}

TEST(Rs274Write, SharedLinuxCncPrograms) {
  if (rs274_path().empty()) GTEST_SKIP() << "rs274 (Debian package linuxcnc-uspace) is not installed";
  const auto programs = shared_programs();
  if (programs.empty()) GTEST_SKIP() << shared_data() << " is absent: real programs not judged";
  Tally t;
  for (const auto& path : programs)
    if (options_for(path).dialect == Dialect::kLinuxCnc) judge(path.filename().string(), read_file(path), options_for(path), t);
  report("shared LinuxCNC programs", t);
  EXPECT_EQ(t.disagreements, 0u);
  EXPECT_GE(t.programs, 12u);  // the 6 bad__bad-arc programs are rejected on purpose
}

// The shipped samples are Fanuc programs: parsed as Fanuc, written as LinuxCNC. Judged where
// rs274 reads the source's motion (it rejects G43.4/G43.5, G275 and Fanuc's cutter
// compensation start-up; a Fanuc dwell `G4 X` is a dwell, not motion, and is let pass).
TEST(Rs274Write, ShippedSamples) {
  if (rs274_path().empty()) GTEST_SKIP() << "rs274 (Debian package linuxcnc-uspace) is not installed";
  Tally t;
  std::vector<fs::path> samples;
  for (const auto& e : fs::directory_iterator(fs::path(GCPIPE_SOURCE_DIR) / "samples"))
    if (e.path().extension() == ".nc") samples.push_back(e.path());
  std::sort(samples.begin(), samples.end());
  const std::regex fanuc_dwell(R"(^Dwell time missing with g4$|G4 X)");
  // Cutter compensation is resolved by the parser (Fanuc's start-up geometry, the machine file's
  // radius): output.nc cuts that tool-centre path, the control its own from its table's radius.
  const std::map<std::string, const char*> deliberate = {
      {"shop_pocket_inch.nc", "cutter compensation resolved with the machine file's radius and Fanuc's geometry"}};
  for (const auto& path : samples) {
    const auto d = deliberate.find(path.filename().string());
    judge(path.filename().string(), read_file(path), ParseOptions{}, t, fanuc_dwell,
          d == deliberate.end() ? nullptr : d->second);
  }
  report("samples", t);
  EXPECT_EQ(t.disagreements, 0u);
  EXPECT_EQ(t.deliberate, deliberate.size());
  EXPECT_GE(t.programs, 3u);  // fanuc_post_pocket.nc, circle_test_seed002.nc, shop_pocket_inch.nc
}
