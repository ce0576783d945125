// The parse stage: syntax, modal resolution, every class of error with its column, LinuxCNC's
// golden arc files and every real program under ../shared/data.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <regex>
#include <fstream>

#include "parse_helpers.hpp"

using namespace gcpipe;
using namespace gcpipe::test;

namespace {

const ResolvedBlock& last(const Parsed& p) { return p.blocks.back(); }

// Parses `text`, expects exactly one rejected line whose message contains `what` at `col`.
void expect_error(const std::string& text, const std::string& what, std::uint32_t col,
                  ParseOptions opt = {}) {
  SCOPED_TRACE(text);
  Parsed p = parse_text(text, opt);
  const Diagnostic* d = p.first_error();
  ASSERT_NE(d, nullptr) << "no error for: " << text;
  EXPECT_NE(d->message.find(what), std::string::npos) << d->message;
  EXPECT_EQ(d->column, col) << format(*d);
  EXPECT_EQ(d->file, "t.nc");
}

}  // namespace

TEST(ParseSyntax, WordsCaseSpacesSignsAndShortNumbers) {
  Parsed p = parse_text("g 1 x 1 0 . 5 y+.5 z-.25 f 1 0 0\n");
  ASSERT_EQ(p.blocks.size(), 1u) << (p.diags.empty() ? "" : format(p.diags[0]));
  const auto& b = last(p);
  EXPECT_EQ(b.motion, Motion::kLinear);
  EXPECT_DOUBLE_EQ(b.target[kX], 10.5);
  EXPECT_DOUBLE_EQ(b.target[kY], 0.5);
  EXPECT_DOUBLE_EQ(b.target[kZ], -0.25);
  EXPECT_DOUBLE_EQ(b.feed, 100);
  EXPECT_EQ(b.axis_words, (1u << kX) | (1u << kY) | (1u << kZ));
}

TEST(ParseSyntax, CommentsAreCollectedAndKept) {
  Parsed p = parse_text("(first) G0 X1 ( second ) ; third (with parens)\n");
  ASSERT_EQ(p.blocks.size(), 1u);
  EXPECT_EQ(last(p).comment, "first | second | third (with parens)");
  EXPECT_DOUBLE_EQ(last(p).target[kX], 1);
}

TEST(ParseSyntax, ProgramStructure) {
  Parsed p = parse_text("%\nO1234 (NAME)\n:77\nN10 G0 X1\n\n%\n");
  ASSERT_EQ(p.blocks.size(), 6u);
  EXPECT_TRUE(p.blocks[0].percent);
  EXPECT_EQ(p.blocks[1].program_number, 1234);
  EXPECT_EQ(p.blocks[1].comment, "NAME");
  EXPECT_EQ(p.blocks[2].program_number, 77);
  EXPECT_EQ(p.blocks[3].motion, Motion::kRapid);
  EXPECT_EQ(p.blocks[4].motion, Motion::kNone);
  EXPECT_TRUE(p.blocks[5].percent);
}

TEST(ParseSyntax, FanucDecimalPointRule) {
  ParseOptions o;
  o.decimal_point_increments = true;
  Parsed p = parse_text("G1 Z50 F100\nG1 Z50.\nG1 A90\nG20\nG1 X1\n", o);
  ASSERT_EQ(p.blocks.size(), 5u);
  EXPECT_DOUBLE_EQ(p.blocks[0].target[kZ], 0.050);      // increments of 0.001 mm
  EXPECT_DOUBLE_EQ(p.blocks[0].feed, 100);              // F is never scaled by the rule
  EXPECT_DOUBLE_EQ(p.blocks[1].target[kZ], 50);
  EXPECT_DOUBLE_EQ(p.blocks[2].target[kA], 0.090);      // 0.001 deg
  EXPECT_NEAR(p.blocks[4].target[kX], 0.0001 * 25.4, 1e-15);  // 0.0001 inch
  Parsed plain = parse_text("G1 Z50 F100\n");
  EXPECT_DOUBLE_EQ(plain.blocks[0].target[kZ], 50);
}

TEST(ParseSyntax, BlockDeleteSwitch) {
  Parsed on = parse_text("G0 X1\n/G0 X2\n");
  EXPECT_EQ(on.summary.lines_deleted, 1u);
  EXPECT_DOUBLE_EQ(last(on).target[kX], 1);
  ASSERT_EQ(on.diags.size(), 1u);
  EXPECT_EQ(on.diags[0].severity, Severity::kNote);
  ParseOptions o;
  o.block_delete = false;
  Parsed off = parse_text("G0 X1\n/G0 X2\n", o);
  EXPECT_EQ(off.summary.lines_deleted, 0u);
  EXPECT_DOUBLE_EQ(last(off).target[kX], 2);
}

TEST(ParseModal, IncrementalUnitsAndOffsets) {
  Parsed p = parse_text("G91 G1 X1 F100\nX1\nG90 G20 X1\nG55 G21 X1 Y1 Z1\n");
  ASSERT_EQ(p.blocks.size(), 4u);
  EXPECT_DOUBLE_EQ(p.blocks[0].target[kX], 1);
  EXPECT_DOUBLE_EQ(p.blocks[1].target[kX], 2);
  EXPECT_DOUBLE_EQ(p.blocks[2].target[kX], 25.4);
  EXPECT_DOUBLE_EQ(p.blocks[2].feed, 100);  // F was given in mm/min; G20 does not rescale it
  EXPECT_EQ(p.blocks[2].source_units, Units::kInch);
  // G55 origin (100, 50, -20) from the machine config.
  EXPECT_DOUBLE_EQ(p.blocks[3].target[kX], 101);
  EXPECT_DOUBLE_EQ(p.blocks[3].target[kY], 51);
  EXPECT_DOUBLE_EQ(p.blocks[3].target[kZ], -19);
  EXPECT_EQ(p.blocks[3].work_offset, 55);
  EXPECT_DOUBLE_EQ(p.blocks[3].start[kX], 25.4);
}

TEST(ParseModal, InchFeedIsConverted) {
  Parsed p = parse_text("G20 G1 X1 F10\n");
  EXPECT_DOUBLE_EQ(last(p).feed, 254);
}

// A feed per minute below parse.min_feed is a post's slip (F0.001 for F1000) that would run for
// hours: an error at the F word. Inverse-time feeds are not feed rates and pass; 0 turns it off.
TEST(ParseModal, FeedBelowTheMinimumIsAnErrorAtItsWord) {
  expect_error("G21 G94\nG1 X1 F0.5\n", "feed F0.5 is below the minimum feed of 1 mm/min (parse.min_feed", 7);
  expect_error("G20 G94\nG1 X1 F0.01\n", "feed F0.01 is below the minimum feed", 7);  // 0.254 mm/min
  EXPECT_EQ(parse_text("G21 G93 G1 X1 F0.001\n").first_error(), nullptr) << "G93 F is 1/min, not a feed rate";
  EXPECT_EQ(parse_text("G20 G1 X1 F0.04\n").first_error(), nullptr) << "0.04 in/min = 1.016 mm/min";
  ParseOptions off;
  off.min_feed = 0;
  EXPECT_EQ(parse_text("G21 G1 X1 F0.001\n", off).first_error(), nullptr);
}

// G95: a move in feed per revolution runs at F x S, and is resolved to that feed in mm/min (what
// G94 would say; rs274_diff_test checks it against LinuxCNC). With no turning spindle, no spindle
// speed or no F it would not move: an error at the motion word, as would a product below
// parse.min_feed. G97 (rev/min, a mill's only mode) is accepted; G96 is not.
TEST(ParseModal, FeedPerRevolutionIsFTimesTheSpindleSpeed) {
  Parsed p = parse_text("G21 S2000 M3\nG95 G1 X1 F0.1\nS500 X2\nG97 S1000 X3\nG94 X4 F300\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  ASSERT_EQ(p.blocks.size(), 5u);
  EXPECT_DOUBLE_EQ(p.blocks[1].feed, 200);
  EXPECT_DOUBLE_EQ(p.blocks[2].feed, 50);
  EXPECT_DOUBLE_EQ(p.blocks[3].feed, 100);
  EXPECT_EQ(p.blocks[3].feed_mode, FeedMode::kUnitsPerMinute);
  EXPECT_DOUBLE_EQ(p.blocks[4].feed, 300);
  EXPECT_DOUBLE_EQ(last(parse_text("G20 S1000 M3 G95 G1 X1 F0.004\n")).feed, 101.6);  // 0.004 in/rev
  expect_error("G21 S2000\nG95 G1 X1 F0.1\n", "with the spindle stopped", 5);
  expect_error("G21 M3\nG95 G1 X1 F0.1\n", "without a spindle speed: program S", 5);
  expect_error("G21 S2000 M3\nG95 G1 X1\n", "without a feed: program F (mm per revolution)", 5);
  expect_error("G21 S10 M3\nG95 G1 X1 F0.01\n", "F x S = 0.1 mm/min is below the minimum feed", 5);
  expect_error("G21 S10 M3\nG94 G1 X1 F100\nG95 X2\n", "without a feed: program F", 5);  // switching drops the feed
  expect_error("G96 S200 M3\n", "G96 (constant surface speed) is not supported on this milling machine", 1);
  // Found by parse_fuzz: 1500 in/rev at 8000 rev/min is 3e8 mm/min, which output.nc could not say.
  expect_error("G20 G95 S8000 M3\nG1 X1 F1500\n", "G95 feed F x S = 304800000 mm/min is out of range", 7);
  expect_error("G21 G95 F1000 M3\nS200000\n", "G95 feed F x S = 2e+08 mm/min is out of range", 1);
}

// G64 P is the path tolerance in force (the planner blends corners within it); inches are
// converted; G64 without P, G61 and G61.1 leave none (compensate.path_tolerance then). G61 / G61.1
// are the path mode in force (the interpolator stops at every block end in them).
TEST(ParseModal, G64PIsThePathToleranceInForce) {
  Parsed p = parse_text("G21 G64 P0.005\nG1 X1 F100\nG20 G64 P0.001 X1\nG61 X2\nG64 P0.01 X3\nG64 X4\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  ASSERT_EQ(p.blocks.size(), 6u);
  EXPECT_DOUBLE_EQ(p.blocks[0].path_tolerance, 0.005);
  EXPECT_DOUBLE_EQ(p.blocks[1].path_tolerance, 0.005);  // modal
  EXPECT_DOUBLE_EQ(p.blocks[2].path_tolerance, 0.0254);
  EXPECT_DOUBLE_EQ(p.blocks[3].path_tolerance, 0);
  EXPECT_DOUBLE_EQ(p.blocks[4].path_tolerance, 0.254);
  EXPECT_DOUBLE_EQ(p.blocks[5].path_tolerance, 0);
  const PathMode modes[] = {PathMode::kBlend, PathMode::kBlend, PathMode::kBlend, PathMode::kExactStop,
                            PathMode::kBlend, PathMode::kBlend};
  for (std::size_t i = 0; i < 6; ++i) EXPECT_EQ(p.blocks[i].path_mode, modes[i]) << i;
  EXPECT_EQ(parse_text("G61.1 G1 X1 F100\nG1 X2\n").blocks.back().path_mode, PathMode::kExactPath);
  expect_error("G21 G64 P-0.01\n", "G64 P-0.01 is not a path tolerance of 0 to 25.4 mm", 9);
  expect_error("G21 G64 P26\n", "G64 P26 is not a path tolerance", 9);
}

TEST(ParseModal, ToolLengthTcpSpindleCoolant) {
  Parsed p = parse_text("T1 M6\nG43 H1 S1200 M3 M8\nG43.4 H1\nG49\nM7 M8\nM9 M8\nM5 M9\n");
  ASSERT_EQ(p.blocks.size(), 7u) << format(p.diags.at(0));
  EXPECT_TRUE(p.blocks[0].tool_change);
  EXPECT_EQ(p.blocks[0].tool_in_spindle, 1);
  EXPECT_TRUE(p.blocks[1].tool_length_active);
  EXPECT_DOUBLE_EQ(p.blocks[1].tool_length, 100);
  EXPECT_EQ(p.blocks[1].spindle, Spindle::kCW);
  EXPECT_DOUBLE_EQ(p.blocks[1].spindle_speed, 1200);
  EXPECT_EQ(p.blocks[1].coolant, kCoolantFlood);
  EXPECT_TRUE(p.blocks[2].tcp);
  EXPECT_FALSE(p.blocks[3].tcp);
  EXPECT_FALSE(p.blocks[3].tool_length_active);
  EXPECT_EQ(p.blocks[4].coolant, kCoolantFlood | kCoolantMist);
  EXPECT_EQ(p.blocks[5].coolant, kCoolantFlood);
  EXPECT_EQ(p.blocks[6].coolant, 0);
  EXPECT_EQ(p.blocks[6].spindle, Spindle::kOff);
}

// G09 (Fanuc, group 00): the block it is on stops exactly at its end, as in G61; the mode in
// force (G64 and its P) goes on in the next block. LinuxCNC has no G9 (rs274: "Unknown g code
// used"): there it is rejected with what to write instead.
TEST(ParseModal, G09StopsItsOwnBlockExactly) {
  Parsed p = parse_text("G21 G64 P0.02\nG1 X10 F600\nG09 G1 X20\nG1 Y10\nG9 X0 Y0\nG61 X5\nG9 X6\nG64 X7\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  ASSERT_EQ(p.blocks.size(), 8u);
  const PathMode modes[] = {PathMode::kBlend,     PathMode::kBlend,     PathMode::kExactStop, PathMode::kBlend,
                            PathMode::kExactStop, PathMode::kExactStop, PathMode::kExactStop, PathMode::kBlend};
  for (std::size_t i = 0; i < 8; ++i) EXPECT_EQ(p.blocks[i].path_mode, modes[i]) << "line " << i + 1;
  EXPECT_DOUBLE_EQ(p.blocks[2].path_tolerance, 0);     // as a G61 block: it stops
  EXPECT_DOUBLE_EQ(p.blocks[3].path_tolerance, 0.02);  // G64 P0.02 goes on after the G09 block
  ParseOptions lc;
  lc.dialect = Dialect::kLinuxCnc;
  expect_error("G1 X1 F100\nG9 X2\n", "G9 (exact stop for one block) is Fanuc G-code, not LinuxCNC's: parse with dialect fanuc", 1, lc);
}

TEST(ParseModal, TcpSpellingsPerDialect) {
  ParseOptions lc;
  lc.dialect = Dialect::kLinuxCnc;
  Parsed p = parse_text("M428\nG43 H1\nM429\n", lc);
  EXPECT_TRUE(p.blocks[0].tcp);
  EXPECT_TRUE(p.blocks[1].tcp);  // LinuxCNC: G43 is only the length
  EXPECT_FALSE(p.blocks[2].tcp);
  Parsed f = parse_text("G43.4 H1\nG43 H1\n");
  EXPECT_TRUE(f.blocks[0].tcp);
  EXPECT_FALSE(f.blocks[1].tcp);  // Fanuc: G43 replaces G43.4 (one modal group)
}

TEST(ParseModal, DwellPerDialect) {
  Parsed f = parse_text("G4 P500\nG4 X1.5\n");
  EXPECT_EQ(f.blocks[0].motion, Motion::kDwell);
  EXPECT_DOUBLE_EQ(f.blocks[0].dwell, 0.5);
  EXPECT_DOUBLE_EQ(f.blocks[1].dwell, 1.5);
  EXPECT_DOUBLE_EQ(f.blocks[1].target[kX], 0);  // X is time here, not a move
  ParseOptions lc;
  lc.dialect = Dialect::kLinuxCnc;
  Parsed l = parse_text("G4 P1.5\n", lc);
  EXPECT_DOUBLE_EQ(l.blocks[0].dwell, 1.5);
}

// LinuxCNC: G80 is in the motion group; rs274 rejects axis words after it (the Fanuc rule is
// ParseAccept.FanucAxisWordsAfterG80MoveInTheMotionModeBeforeTheCycle).
TEST(ParseModal, G80CancelsMotionModeInLinuxCnc) {
  ParseOptions lc;
  lc.dialect = Dialect::kLinuxCnc;
  Parsed p = parse_text("G1 X1 F100\nG80\nX2\n", lc);
  const Diagnostic* d = p.first_error();
  ASSERT_NE(d, nullptr);
  EXPECT_NE(d->message.find("without a motion mode"), std::string::npos);
}

TEST(ParseArcs, CentreFormatInEachPlane) {
  Parsed p = parse_text("G1 X0 Y0 Z0 F100\nG2 X10 Y0 I5 J0\nG18 G3 Z0 X20 K0 I5\nG19 G2 Y10 Z0 J5 K0\n");
  ASSERT_EQ(p.blocks.size(), 4u) << format(p.diags.at(0));
  const auto& a = p.blocks[1];
  EXPECT_EQ(a.motion, Motion::kArcCW);
  EXPECT_EQ(a.plane, Plane::kXY);
  EXPECT_DOUBLE_EQ(a.centre[0], 5);
  EXPECT_DOUBLE_EQ(a.centre[1], 0);
  EXPECT_DOUBLE_EQ(a.radius, 5);
  const auto& b = p.blocks[2];
  EXPECT_EQ(b.plane, Plane::kZX);
  EXPECT_DOUBLE_EQ(b.centre[0], 15);
  EXPECT_DOUBLE_EQ(b.centre[2], 0);
  const auto& c = p.blocks[3];
  EXPECT_EQ(c.plane, Plane::kYZ);
  EXPECT_DOUBLE_EQ(c.centre[1], 5);
  EXPECT_DOUBLE_EQ(c.centre[0], 20);  // normal-axis coordinate of the start
}

TEST(ParseArcs, RadiusFormatPicksTheRightCentre) {
  // CW from (0,0) to (2,0): R>0 takes the short arc, centre below the chord; R<0 the long arc.
  const double r = std::sqrt(2.0);
  for (auto [code, sign, cy] : {std::tuple{"G2", 1, -1.0}, {"G2", -1, 1.0}, {"G3", 1, 1.0}, {"G3", -1, -1.0}}) {
    std::string prog = "G1 X0 Y0 F100\n" + std::string(code) + " X2 Y0 R" + std::to_string(sign * r) + "\n";
    Parsed p = parse_text(prog);
    ASSERT_EQ(p.blocks.size(), 2u) << prog;
    EXPECT_NEAR(p.blocks[1].centre[0], 1, 1e-6) << prog;
    EXPECT_NEAR(p.blocks[1].centre[1], cy, 1e-6) << prog;
  }
}

TEST(ParseArcs, FullCircleHelixAndTurns) {
  ParseOptions lc;
  lc.dialect = Dialect::kLinuxCnc;
  Parsed p = parse_text("G1 X0 Y0 Z0 F100\nG2 I5\nG3 Z-3 I5 P3\n", lc);
  ASSERT_EQ(p.blocks.size(), 3u) << format(p.diags.at(0));
  EXPECT_EQ(p.blocks[1].target, p.blocks[1].start);  // end = start: a full circle
  EXPECT_DOUBLE_EQ(p.blocks[1].radius, 5);
  EXPECT_DOUBLE_EQ(p.blocks[2].target[kZ], -3);
  EXPECT_EQ(p.blocks[2].turns, 3);
}

TEST(ParseArcs, AbsoluteCentresByConfigAndG901) {
  ParseOptions o;
  o.absolute_arc_centres = true;
  Parsed p = parse_text("G1 X10 Y0 F100\nG3 X0 Y10 I0 J0\n", o);
  ASSERT_EQ(p.blocks.size(), 2u);
  EXPECT_DOUBLE_EQ(p.blocks[1].centre[0], 0);
  Parsed q = parse_text("G1 X10 Y0 F100\nG90.1 G3 X0 Y10 I0 J0\n");
  ASSERT_EQ(q.blocks.size(), 2u);
  EXPECT_DOUBLE_EQ(q.blocks[1].radius, 10);
}

TEST(ParseErrors, EachClassNamesWordValueAndColumn) {
  expect_error("G0 X1 B2\n", "unknown word 'B2'", 7);
  expect_error("G0 X1 E2\n", "'E' is not a word", 7);
  expect_error("G0 X1 X2\n", "word X appears twice", 7);
  expect_error("G0 G1 X1 F1\n", "G0 and G1 in one block", 4);
  expect_error("G20 G21\n", "same modal group", 5);
  expect_error("M3 M4\n", "M3 and M4", 4);
  expect_error("G1 X1\n", "G1 without a feed", 1);
  expect_error("G1 X[sqrt[-1]] F1\n", "not a finite number", 6);
  expect_error("G1 X[10**400] F1\n", "overflow", 8);
  expect_error("G1 X99999999 F1\n", "out of range", 4);
  expect_error("G91 G1 X60000 F1\nX60000\n", "takes X to 120000 mm, out of range", 1);  // found by parse_fuzz
  expect_error("G1 X0 Y0 F1\nG2 X1 I1e5\n", "'E' is not a word", 9);
  expect_error("G1 X0 Y0 F1\nG2 X1 I[10**60]\n", "I1e+60 is out of range", 7);
  expect_error("G1 X1e5 F1\n", "'E' is not a word", 6);
  expect_error("G41 X1\n", "G41 without a tool", 1);
  expect_error("M98 P100\n", "subprogram O100 is not defined", 1);
  expect_error("M123\n", "not a supported M code", 1);
  expect_error("G12.5\n", "not a supported G code", 1);
  expect_error("G1.55 X1\n", "not a valid G code", 1);
  expect_error("H1\n", "without G43", 1);
  expect_error("G43 H9\n", "tool 9 is not in the machine config", 5);
  expect_error("G1 X1 I2 F1\n", "word I2 has no meaning here", 7);
  expect_error("G0 X\n", "has no value", 5);
  expect_error("G0 X1.2.3\n", "two decimal points", 8);
  expect_error("G0 (open\n", "not closed", 4);
  expect_error("G0 (a (b) )\n", "comment inside a comment", 7);
  expect_error("G4 P1 X1\n", "G4 with both X", 4);
  expect_error("G93 G1 X1\n", "inverse-time", 5);
  expect_error("X1\n", "without a motion mode", 1);
  expect_error("o100 sub\n", "o100 sub has no o100 endsub", 1);
  expect_error("o<x> call\n", "no subroutine o<x> is defined in this file", 1);
  expect_error("G1 X0 Y0 F1\nG2 X10 Y0 R4\n", "cannot exist", 11);
  expect_error("G1 X0 Y0 F1\nG2 X10 Y0 I4 J0\n", "radius to end of arc differs", 11);
  expect_error("G1 X0 Y0 F1\nG2 X10 Y0 K4\n", "K4 in a G2 block in the XY (G17) plane: the centre is given by I and J", 11);
  expect_error("G0 X#<nope>\n", "used before it is set", 5);
  expect_error("G0 X1 G1 @\n", "unexpected '@'", 10);
  expect_error("G0 X1 /\n", "only allowed at the start", 7);
  expect_error("S-5\n", "out of range", 1);
  expect_error("T1.5\n", "not a whole number", 1);
  expect_error("F-1\n", "negative", 1);
  ParseOptions shortline;
  shortline.max_line_length = 16;
  expect_error("G0 X1 Y2 Z3 A4 C5 (long)\n", "the limit is 16", 17, shortline);
}

TEST(ParseErrors, ControlBytesAndNulOutsideComments) {
  Parsed p = parse_text(std::string("G0 X1\x01\n", 8));
  ASSERT_NE(p.first_error(), nullptr);
  EXPECT_NE(p.first_error()->message.find("0x01"), std::string::npos);
  Parsed q = parse_text(std::string("G0 X1 (\xb0 is fine here)\n"));
  EXPECT_EQ(q.first_error(), nullptr);
}

TEST(ParseErrors, RejectedLineLeavesNoTraceAndTheRestGoesOn) {
  Parsed p = parse_text("G91 G1 X1 F100\nG90 X5 B1\nX1\n#1=7 G0 B2\nG0 X#1\n");
  ASSERT_EQ(p.summary.lines_rejected, 2u);
  ASSERT_EQ(p.blocks.size(), 3u);
  EXPECT_DOUBLE_EQ(p.blocks[1].target[kX], 2);  // still incremental: line 2 never happened
  EXPECT_DOUBLE_EQ(p.blocks[2].target[kX], 2 + 0);  // #1 was not set by the rejected line 4
  EXPECT_EQ(p.summary.lines_read, p.summary.blocks_emitted + p.summary.lines_rejected + p.summary.lines_deleted);
}

TEST(ParseErrors, StrictModeIsTheCallersStop) {
  // The parser reports; the parse stage stops in strict mode (tested through the CLI in cli_test).
  ParseOptions o;
  o.strict = true;
  Parsed p = parse_text("G0 X1\nG0 B1\nG0 X2\n", o);
  EXPECT_EQ(p.summary.lines_rejected, 1u);
}

TEST(ParseExpressions, ParametersFunctionsAndPrecedence) {
  Parsed p = parse_text(
      "#1 = 5\n#<Abc> = [#1 * 2]\nG0 X#1 Y#<aBC>\nG0 X[2 + 3 * 4] Y[atan[1]/[1]] Z[sqrt[16] + abs[-1]]\n"
      "G0 X[7 mod 4] Y[-7 mod 4] Z[2 ** 3]\n#2 = 1 #3 = #2\nG0 X#3\nG0 X-#1 Y[fix[2.7]] Z[fup[2.2]]\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  const auto& b = p.blocks;
  EXPECT_DOUBLE_EQ(b[2].target[kX], 5);
  EXPECT_DOUBLE_EQ(b[2].target[kY], 10);
  EXPECT_DOUBLE_EQ(b[3].target[kX], 14);
  EXPECT_NEAR(b[3].target[kY], 45, 1e-12);
  EXPECT_DOUBLE_EQ(b[3].target[kZ], 5);
  EXPECT_DOUBLE_EQ(b[4].target[kX], 3);
  EXPECT_DOUBLE_EQ(b[4].target[kY], 1);  // LinuxCNC: non-negative remainder
  EXPECT_DOUBLE_EQ(b[4].target[kZ], 8);
  // #3 = #2 read the old #2: assignments apply after the line. That #2 was never set, so in the
  // Fanuc dialect #3 is vacant and X#3 leaves X where it was (X3); LinuxCNC reads 0.
  EXPECT_DOUBLE_EQ(b[6].target[kX], 3);
  EXPECT_DOUBLE_EQ(b[7].target[kX], -5);
  EXPECT_DOUBLE_EQ(b[7].target[kY], 2);
  EXPECT_DOUBLE_EQ(b[7].target[kZ], 3);
}

TEST(ParseCycle, TrochoidSlotResolves) {
  Parsed p = parse_text("T2 M6\nG0 X0 Y0 Z5\nG1 F800 Z5\nG275 X120 Y0 Z-10 R5 W28 K1.5 Q5 P-1\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  const auto& b = last(p);
  EXPECT_EQ(b.motion, Motion::kTrochoidSlot);
  EXPECT_DOUBLE_EQ(b.slot.tool_diameter, 20);  // from T2 in the tool table
  EXPECT_DOUBLE_EQ(b.slot.width, 28);
  EXPECT_DOUBLE_EQ(b.slot.step, 1.5);
  EXPECT_DOUBLE_EQ(b.slot.depth_step, 5);
  EXPECT_DOUBLE_EQ(b.slot.bottom, -10);
  EXPECT_DOUBLE_EQ(b.slot.clearance, 5);
  EXPECT_FALSE(b.slot.climb);
  EXPECT_DOUBLE_EQ(b.target[kX], 120);
  EXPECT_DOUBLE_EQ(b.target[kZ], 5);
  expect_error("G1 F800 X0\nG275 X10 Z-1 R5 W0 K1 D10\n", "slot width must be positive", 17);
  expect_error("G1 F800 X0\nG275 X10 Z-1 R5 W12 K1\n", "needs the tool diameter", 1);
  expect_error("G1 F800 X0\nG275 X10 Z-1 W12 K1 D10\n", "needs R", 1);
}

// LinuxCNC's canonical output for its own arc tests: the end point and centre of each good arc.
TEST(ParseGolden, LinuxCncArcToleranceFiles) {
  const auto dir = shared_data() / "gcode/linuxcnc/interp_arc_tolerance";
  if (!std::filesystem::exists(dir)) GTEST_SKIP() << dir << " is absent: LinuxCNC golden files not checked";
  int good = 0, bad = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (e.path().extension() != ".ngc") continue;
    SCOPED_TRACE(name);
    ParseOptions o;
    o.dialect = Dialect::kLinuxCnc;
    Parsed p = parse_text(read_file(e.path()), o);
    if (name.rfind("good__", 0) == 0) {
      ++good;
      ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
      const std::string expected = read_file(e.path().string() + ".expected");
      std::smatch m;
      const std::regex arc(R"(ARC_FEED\(([-0-9.]+), ([-0-9.]+), ([-0-9.]+), ([-0-9.]+), (-?\d+),)");
      ASSERT_TRUE(std::regex_search(expected, m, arc));
      const double k = name.find("imperial") != std::string::npos ? 1 / 25.4 : 1.0;  // canon units
      const ResolvedBlock* a = nullptr;
      for (const auto& b : p.blocks)
        if (b.motion == Motion::kArcCW || b.motion == Motion::kArcCCW) a = &b;
      ASSERT_NE(a, nullptr);
      EXPECT_NEAR(a->target[kX] * k, std::stod(m[1]), 5e-5);
      EXPECT_NEAR(a->target[kY] * k, std::stod(m[2]), 5e-5);
      EXPECT_NEAR(a->centre[0] * k, std::stod(m[3]), 5e-5);
      EXPECT_NEAR(a->centre[1] * k, std::stod(m[4]), 5e-5);
      EXPECT_EQ(a->motion == Motion::kArcCW ? -a->turns : a->turns, std::stoi(m[5]));
    } else {
      ++bad;
      ASSERT_NE(p.first_error(), nullptr) << "a bad__ arc was accepted";
      EXPECT_NE(p.first_error()->message.find("radius to end of arc differs from radius to start"), std::string::npos);
      // The file's first comment holds LinuxCNC's message; our r1 and r2 agree with it.
      const std::string src = read_file(e.path());
      std::smatch m;
      ASSERT_TRUE(std::regex_search(src, m, std::regex(R"(r1=([0-9.]+) r2=([0-9.]+))")));
      EXPECT_NE(p.first_error()->message.find("r1=" + m[1].str()), std::string::npos) << p.first_error()->message;
      EXPECT_NE(p.first_error()->message.find("r2=" + m[2].str()), std::string::npos) << p.first_error()->message;
    }
  }
  EXPECT_EQ(good, 6);
  EXPECT_EQ(bad, 6);
}

// Every real program is accepted, except features listed in the README as unsupported.
TEST(ParseReal, EveryProgramUnderSharedDataIsAcceptedOrPreciselyRejected) {
  auto programs = shared_programs();
  if (programs.empty()) GTEST_SKIP() << shared_data() << " is absent: real programs not checked";
  int checked = 0;
  for (const auto& path : programs) {
    const std::string name = path.filename().string();
    if (name.rfind("bad__", 0) == 0) continue;  // LinuxCNC's own must-fail files: ParseGolden
    SCOPED_TRACE(name);
    Parsed p = parse_text(read_file(path), options_for(path), test_machine(), path.string());
    EXPECT_EQ(p.summary.lines_read, p.summary.blocks_emitted + p.summary.lines_rejected + p.summary.lines_deleted);
    if (name == "helix_ac.ngc") {
      // A LinuxCNC subroutine library file: o<helix_ac> sub ... endsub, all of it, never called:
      // the definition is collected and not run where it stands (21 notes), as rs274 does.
      EXPECT_EQ(p.summary.blocks_emitted, 1u);  // the comment line before the sub
      EXPECT_EQ(p.summary.lines_not_run, 21u);
    }
    EXPECT_EQ(p.summary.lines_rejected, 0u) << format(*p.first_error());
    ++checked;
  }
  EXPECT_GE(checked, 12);
}

TEST(ParseReal, ImpellerReachesMinus400DegreesOfC) {
  const auto path = shared_data() / "gcode/linuxcnc/xyzac_trt/impeller-7bl-xyzac.ngc";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " is absent";
  Parsed p = parse_text(read_file(path), options_for(path));
  double cmin = 0, amin = 0;
  for (const auto& b : p.blocks) {
    cmin = std::min(cmin, b.target[kC]);
    amin = std::min(amin, b.target[kA]);
    if (b.motion == Motion::kLinear) {
      EXPECT_EQ(b.feed_mode, FeedMode::kInverseTime);
      EXPECT_TRUE(b.tcp);
    }
  }
  EXPECT_NEAR(cmin, -399.81, 0.01);  // the program's own summary comment: Cmin -399.81
  EXPECT_NEAR(amin, -74.49, 0.01);   // Amin -74.49
}

// G43.5 (Fanuc TCP type 2): the tool axis programmed as a vector I J K in the workpiece frame.
TEST(ParseToolVector, G435ProgramsTheToolAxisModally) {
  Parsed p = parse_text(
      "G43.5 H1\n"                           // 1
      "G0 X10 Y0 Z5 I0 J0 K2\n"              // 2: any length, normalised
      "G1 X20 F100\n"                        // 3: no I J K: the vector in force stays
      "G1 I3 J4\n"                           // 4: K omitted = 0; a move without axis words
      "G91 G1 X1 I1 J1 K1\n"                 // 5: a direction is absolute in G91 too
      "G90 G2 X23 Y2 I1 J1\n"                // 6: arc: I J are the centre, the vector stays
      "G43.5 H2\n"                           // 7: a new H keeps the vector
      "G43.4 H1\n"                           // 8: G43.4 ends G43.5 (one modal group)
      "G43.5 H1\nG0 X0 I0 J0 K1\nG49\n");    // 9..11
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  ASSERT_EQ(p.blocks.size(), 11u);
  const auto& b = p.blocks;
  EXPECT_TRUE(b[0].tool_vector_mode);
  EXPECT_TRUE(b[0].tcp);
  EXPECT_DOUBLE_EQ(b[0].tool_length, 100);
  EXPECT_EQ(b[1].motion, Motion::kRapid);
  EXPECT_EQ(b[1].tool_vector, (Vec3{0, 0, 1}));
  EXPECT_EQ(b[2].tool_vector, (Vec3{0, 0, 1}));
  EXPECT_EQ(b[3].motion, Motion::kLinear);  // I J K alone make a move (the rotaries turn)
  EXPECT_EQ(b[3].axis_words, 0);
  EXPECT_NEAR(b[3].tool_vector[0], 0.6, 1e-15);
  EXPECT_NEAR(b[3].tool_vector[1], 0.8, 1e-15);
  EXPECT_EQ(b[3].tool_vector[2], 0);
  const double r3 = 1 / std::sqrt(3.0);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(b[4].tool_vector[static_cast<std::size_t>(k)], r3, 1e-15);
  EXPECT_DOUBLE_EQ(b[4].target[kX], 21);
  EXPECT_EQ(b[5].motion, Motion::kArcCW);
  EXPECT_DOUBLE_EQ(b[5].centre[0], 22);
  EXPECT_DOUBLE_EQ(b[5].centre[1], 1);
  EXPECT_EQ(b[5].tool_vector, b[4].tool_vector);
  EXPECT_TRUE(b[6].tool_vector_mode);
  EXPECT_DOUBLE_EQ(b[6].tool_length, 110);
  EXPECT_EQ(b[6].tool_vector, b[4].tool_vector);
  EXPECT_FALSE(b[7].tool_vector_mode);
  EXPECT_TRUE(b[7].tcp);
  EXPECT_EQ(b[7].tool_vector, (Vec3{0, 0, 1}));
  EXPECT_TRUE(b[9].tool_vector_mode);
  EXPECT_FALSE(b[10].tool_vector_mode);
  EXPECT_FALSE(b[10].tcp);
  // G43 alone (length only) also ends it.
  Parsed g43 = parse_text("G43.5 H1\nG0 X1 I0 J0 K1\nG43 H1\n");
  ASSERT_EQ(g43.blocks.size(), 3u);
  EXPECT_FALSE(g43.blocks[2].tool_vector_mode);
  EXPECT_FALSE(g43.blocks[2].tcp);
}

TEST(ParseToolVector, ErrorsNameWordValueAndColumn) {
  expect_error("G43.5 H1\nG0 X1 I0 J0 K0\n", "zero length", 7);
  expect_error("G43.5 H1\nG0 X1 I[1/10**12] J0 K0\n", "zero length", 7);
  expect_error("G43.5 H1\nG0 X1 I[10**7]\n", "tool vector component I1e+07 is out of range", 7);
  expect_error("G43.5 H1\nG0 X1 I0 J0 K1\nG1 X2 A10 F100\n", "rotary word A10 in G43.5 mode", 7);
  expect_error("G43.5 H1\nG0 C90 I0 J0 K1\n", "rotary word C90 in G43.5 mode", 4);
  expect_error("G43.5 H1\nG0 X1 Y2 Z3\n", "first move in G43.5 mode without a tool vector", 1);
  expect_error("G43.5 H1\nG80 I0 J0 K1\n", "without a motion mode", 5);
  expect_error("G43.5 H9\n", "tool 9 is not in the machine config", 7);
  expect_error("G0 X1 I0 J0 K1\n", "word K1 has no meaning here", 13);  // not in G43.5
  ParseOptions lc;
  lc.dialect = Dialect::kLinuxCnc;
  expect_error("G43.5 H1\nG0 X1 I0 J0 K1\n", "LinuxCNC has no tool-vector TCP", 1, lc);
  // The message carries file:line:col.
  Parsed p = parse_text("G43.5 H1\nG0 X1 I0 J0 K0\n");
  ASSERT_NE(p.first_error(), nullptr);
  EXPECT_EQ(format(*p.first_error()).rfind("t.nc:2:7: error: tool vector I0 J0 K0 has zero length", 0), 0u)
      << format(*p.first_error());
}

// ---- Issue 14: the G-code real programs carry ------------------------------------------------

namespace {

ParseOptions linuxcnc() {
  ParseOptions o;
  o.dialect = Dialect::kLinuxCnc;
  return o;
}

// End points of the moving blocks, in program coordinates.
std::vector<Axes> ends(const Parsed& p) {
  std::vector<Axes> out;
  for (const auto& b : p.blocks) {
    if (b.motion != Motion::kRapid && b.motion != Motion::kLinear && b.motion != Motion::kArcCW &&
        b.motion != Motion::kArcCCW)
      continue;
    Axes a{};
    for (int k = 0; k < kNumAxes; ++k) a[k] = b.target[k] - b.work_origin[k];
    out.push_back(a);
  }
  return out;
}

void expect_xyz(const Axes& a, double x, double y, double z) {
  EXPECT_NEAR(a[kX], x, 1e-9);
  EXPECT_NEAR(a[kY], y, 1e-9);
  EXPECT_NEAR(a[kZ], z, 1e-9);
}

}  // namespace

TEST(ParseIssue14, G80SharesABlockWithG0InBothDialects) {
  for (ParseOptions o : {ParseOptions{}, linuxcnc()}) {
    Parsed p = parse_text("G0 G17 G40 G49 G80 G90 X1 Y2\nG80 G1 X3 F100\nG80\n", o);
    ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
    EXPECT_EQ(p.blocks[0].motion, Motion::kRapid);  // G80 yields to G0 in the same block
    EXPECT_EQ(p.blocks[1].motion, Motion::kLinear);
  }
  expect_error("G80 G81 X1 Z-1 R1 F1\n", "G80 and G81 in one block belong to the same modal group", 5);
  expect_error("G0 G81 X1 Z-1 R1 F1\n", "G0 and G81 in one block", 4);
}

// FANUC Series 0i-MF operator's manual, "Drilling cycle, spot drilling (G81)", the example of six
// holes (G99 between holes, G98 on the last); worked by hand with the tool starting at Z0 (the
// initial level) and R-100 Z-150 F120.
TEST(ParseIssue14, FanucG81ManualExampleByHand) {
  Parsed p = parse_text("M3 S2000\nG90 G99 G81 X300. Y-250. Z-150. R-100. F120.\nY-550.\nY-750.\nX1000.\n"
                        "Y-550.\nG98 Y-750.\nG80\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  const auto e = ends(p);
  ASSERT_EQ(e.size(), 4u + 3 * 5);
  expect_xyz(e[0], 300, -250, 0);     // rapid to the hole at the initial level
  expect_xyz(e[1], 300, -250, -100);  // rapid to R
  expect_xyz(e[2], 300, -250, -150);  // feed to the bottom
  expect_xyz(e[3], 300, -250, -100);  // G99: back to R
  expect_xyz(e[4], 300, -550, -100);  // next hole at R (no stroke down to R: it is there)
  expect_xyz(e[5], 300, -550, -150);
  expect_xyz(e[6], 300, -550, -100);
  expect_xyz(e[15], 1000, -550, -100);
  expect_xyz(e[16], 1000, -750, -100);
  expect_xyz(e[17], 1000, -750, -150);
  expect_xyz(e[18], 1000, -750, 0);  // G98 on the last hole: back to the initial level
  EXPECT_EQ(p.blocks[1].motion, Motion::kRapid);
  EXPECT_EQ(p.blocks[3].motion, Motion::kLinear);
  for (const auto& b : p.blocks) EXPECT_TRUE(b.line >= 1 && b.line <= 8);
  EXPECT_EQ(p.summary.blocks_emitted, 8u);  // lines, not moves
  EXPECT_EQ(p.summary.blocks_out, 1u + 19 + 1);  // M3, the moves, G80
}

// Fanuc conventions: P of G82 in ms, K repeats, G91 R from the initial level and Z from R,
// G73's chip-break retract d = 0.254 mm (LinuxCNC's 0.010 in).
TEST(ParseIssue14, FanucDwellRepeatsIncrementalAndPeck) {
  Parsed p = parse_text("G0 X0 Y0 Z10\nG82 X5 Z-2 R3 P1500 F100\nG80\nG91 G81 X10 Z-3 R-5 K3\nG90 G80\n"
                        "G73 X0 Y0 Z-2 R1 Q1\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  bool dwell = false;
  for (const auto& b : p.blocks)
    if (b.motion == Motion::kDwell) dwell = std::fabs(b.dwell - 1.5) < 1e-12;
  EXPECT_TRUE(dwell);
  const auto e = ends(p);
  // G91 K3: holes at X15, X25, X35 (from X5), R at 10 - 5 = 5, bottom 5 - 3 = 2.
  int holes = 0;
  for (const auto& a : e)
    if (std::fabs(a[kZ] - 2) < 1e-9) {
      EXPECT_NEAR(a[kX], 15 + 10 * holes, 1e-9);
      ++holes;
    }
  EXPECT_EQ(holes, 3);
  // G73: feed to 0, rapid up 0.254, feed to -1, up, feed to -2, back to the initial level.
  const std::vector<double> zs = {0, 0.254, -1, -1 + 0.254, -2, 10};
  ASSERT_GE(e.size(), zs.size());
  for (std::size_t i = 0; i < zs.size(); ++i) EXPECT_NEAR(e[e.size() - zs.size() + i][kZ], zs[i], 1e-9) << i;
}

TEST(ParseIssue14, MachineCoordinatesReferenceReturnAndShifts) {
  MachineConfig m = test_machine();
  m.reference_positions[0] = {0, 0, 200, 0, 0};   // G28
  m.reference_positions[1] = {-50, 0, 150, 0, 0}; // G30
  Parsed p = parse_text("G55 G0 X1 Y1 Z1\nG53 X7 Z9\nG91 G28 Z0\nG90 G30 X2\nG92 X0 Y0\nG0 X1\nG92.1\nG52 X5\nG0 X1\n",
                        {}, m);
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  // G55 origin (100, 50, -20); G53 X7 Z9 is machine X7 Z9.
  EXPECT_DOUBLE_EQ(p.blocks[1].target[kX], 7);
  EXPECT_DOUBLE_EQ(p.blocks[1].target[kZ], 9);
  EXPECT_DOUBLE_EQ(p.blocks[1].target[kY], 51);
  // G91 G28 Z0: the intermediate point is where Z stands (no move), then Z goes to the G28
  // position; X and Y stay.
  EXPECT_DOUBLE_EQ(p.blocks[2].target[kZ], 200);
  EXPECT_DOUBLE_EQ(p.blocks[2].target[kX], 7);
  EXPECT_EQ(p.blocks[2].line, 3u);
  // G30 X2: through X2 in G55 (machine 102) to the G30 X, machine -50.
  EXPECT_DOUBLE_EQ(p.blocks[3].target[kX], 102);
  EXPECT_DOUBLE_EQ(p.blocks[4].target[kX], -50);
  EXPECT_EQ(p.blocks[4].line, 4u);
  // G92 X0 at machine X-50: X1 is machine X-49; the blocks keep the G55 origin.
  EXPECT_DOUBLE_EQ(p.blocks[6].target[kX], -49);
  EXPECT_DOUBLE_EQ(p.blocks[6].work_origin[kX], 100);
  // G92.1 clears it, G52 X5 shifts by 5: X1 is machine 100 + 5 + 1.
  EXPECT_DOUBLE_EQ(p.blocks.back().target[kX], 106);
  expect_error("G91 G53 X1\n", "G53 with G91", 5);
  expect_error("G2 X2 I1 F1\nG53 X1\n", "G53 needs G0 or G1", 1, linuxcnc());
}

TEST(ParseIssue14, ByteOrderMarkDwellWithMotionHugeFeedAndLookAhead) {
  Parsed p = parse_text("\xEF\xBB\xBFG0 X1\nG0 G4 P500\nX2\nG93 G1 X3 F2000000\nG94\nG05.1 Q1\nG08 P1\nG05 P10000\nG05.1 Q0\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  EXPECT_DOUBLE_EQ(p.blocks[0].target[kX], 1);
  EXPECT_EQ(p.blocks[1].motion, Motion::kDwell);
  EXPECT_DOUBLE_EQ(p.blocks[1].dwell, 0.5);
  EXPECT_EQ(p.blocks[2].motion, Motion::kRapid);  // G0 set in the dwell block stays in force
  EXPECT_DOUBLE_EQ(p.blocks[3].feed, 2e6);
  expect_error("G0 G4 P1 Y5\n", "a dwell block cannot move", 10);
  expect_error("G5.1 X1 I1 J1\n", "LinuxCNC spline", 1, linuxcnc());
  expect_error("G8\n", "lathe radius mode", 1, linuxcnc());
  expect_error("G1 X1 F200000000\n", "out of range", 7);
}

// Bug: a numbered subroutine's body ran as main-program code; if/else ran every branch.
TEST(ParseIssue14, SubroutineBodiesAreNotRunWhereTheyStandAndBranchesTakeOne) {
  Parsed p = parse_text("o100 sub\nG0 X99\no100 endsub\n#1 = 2\no1 if [#1 eq 1]\nG0 X1\no1 elseif [#1 eq 2]\nG0 X2\n"
                        "o1 else\nG0 X3\no1 endif\no100 call\n",
                        linuxcnc());
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  const auto e = ends(p);
  ASSERT_EQ(e.size(), 2u);
  EXPECT_DOUBLE_EQ(e[0][kX], 2);   // the elseif branch only
  EXPECT_DOUBLE_EQ(e[1][kX], 99);  // the body, run by the call
  EXPECT_EQ(p.blocks.back().line, 2u);  // the move carries the line it was written on
  EXPECT_EQ(p.summary.lines_read, p.summary.blocks_emitted + p.summary.lines_rejected + p.summary.lines_deleted);
  EXPECT_EQ(p.summary.lines_not_run, 5u);  // the 3 definition lines, 2 lines of branches not taken
}

TEST(ParseIssue14, LoopsRunAsOftenAsTheirConditionSays) {
  Parsed p = parse_text("#1 = 0\no1 while [#1 lt 5]\nG0 X#1\n#1 = [#1 + 1]\no1 endwhile\n"
                        "o2 repeat [3]\nG91 G0 Y1\no2 endrepeat\nG90\no3 do\nG0 Z#1\n#1 = [#1 - 1]\no3 while [#1 gt 3]\n",
                        linuxcnc());
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  const auto e = ends(p);
  ASSERT_EQ(e.size(), 5u + 3 + 2);
  for (int i = 0; i < 5; ++i) EXPECT_DOUBLE_EQ(e[static_cast<std::size_t>(i)][kX], i);
  EXPECT_DOUBLE_EQ(e[7][kY], 3);
  EXPECT_DOUBLE_EQ(e[9][kZ], 4);
  EXPECT_EQ(p.summary.lines_read, 13u);
  EXPECT_EQ(p.summary.lines_read, p.summary.blocks_emitted + p.summary.lines_rejected + p.summary.lines_deleted);
  EXPECT_EQ(p.summary.blocks_out, p.blocks.size());
}

TEST(ParseIssue14, RunawayLoopsRecursionAndWaitingEndInAClearError) {
  ParseOptions o = linuxcnc();
  o.max_loop_passes = 1000;
  Parsed loop = parse_text("o1 while [1]\no1 endwhile\nG0 X1\n", o);
  ASSERT_NE(loop.first_error(), nullptr);
  EXPECT_NE(loop.first_error()->message.find("ran 1000 passes and was stopped"), std::string::npos);
  EXPECT_DOUBLE_EQ(ends(loop).back()[kX], 1);  // the program goes on after the loop
  Parsed rec = parse_text("o<r> sub\no<r> call\no<r> endsub\no<r> call\nG0 X2\n", o);
  ASSERT_NE(rec.first_error(), nullptr);
  EXPECT_NE(rec.first_error()->message.find("nested deeper than 64"), std::string::npos);
  EXPECT_EQ(rec.summary.lines_rejected, 1u);
  o.max_buffered_lines = 100;
  std::string waits = "o<later> call\n";
  for (int i = 0; i < 150; ++i) waits += "G0 X" + std::to_string(i) + "\n";
  Parsed w = parse_text(waits, o);
  ASSERT_NE(w.first_error(), nullptr);
  EXPECT_NE(w.first_error()->message.find("parse.max_buffered_lines"), std::string::npos);
  EXPECT_EQ(w.first_error()->line, 1u);
  EXPECT_EQ(w.blocks.size(), 150u);  // the lines after the call still run
}

TEST(ParseIssue14, ErrorsInsideACallNameTheFailingLineAndRejectTheCall) {
  Parsed p = parse_text("o<s> sub\nG0 X1\nG1 X2\no<s> endsub\no<s> call\nG0 X3\n", linuxcnc());
  ASSERT_NE(p.first_error(), nullptr);
  EXPECT_EQ(p.first_error()->line, 3u);
  EXPECT_NE(p.first_error()->message.find("G1 without a feed"), std::string::npos);
  EXPECT_NE(p.first_error()->message.find("called at line 5"), std::string::npos);
  EXPECT_EQ(p.summary.lines_rejected, 1u);
  EXPECT_EQ(p.summary.lines_read, p.summary.blocks_emitted + p.summary.lines_rejected + p.summary.lines_deleted);
}

TEST(ParseIssue14, ToolTableFilesAndTheirErrors) {
  const auto dir = std::filesystem::path(testing::TempDir());
  const auto tbl = dir / "shop.tbl";
  std::ofstream(tbl) << "; shop tools\nT5 P5 D6.0 Z+42.5 ;drill\nT7 P7 Z30 D12\n";
  const auto tools = load_tool_table(tbl);
  ASSERT_EQ(tools.size(), 2u);
  EXPECT_DOUBLE_EQ(tools.at(5).length, 42.5);
  EXPECT_DOUBLE_EQ(tools.at(7).diameter, 12);
  const auto yaml = dir / "shop.yaml";
  std::ofstream(yaml) << "tools:\n  9: {length: 75, diameter: 8, name: spot}\n";
  EXPECT_DOUBLE_EQ(load_tool_table(yaml).at(9).length, 75);
  const auto bad = dir / "bad.tbl";
  std::ofstream(bad) << "T1 Z10\nT2 Zx\n";
  try {
    load_tool_table(bad);
    ADD_FAILURE() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.tbl:2: tool table: 'Zx'"), std::string::npos) << e.what();
  }
  MachineConfig m = test_machine();
  merge_tool_table(m, tbl);
  Parsed p = parse_text("G43 H5\nT7 M6\nG43 H3\nT3\n", {}, m);
  EXPECT_DOUBLE_EQ(p.blocks[0].tool_length, 42.5);
  ASSERT_EQ(p.diags.size(), 2u);
  EXPECT_NE(p.diags[0].message.find("tool 3 is not in tool table " + tbl.string()), std::string::npos);
  EXPECT_EQ(p.diags[0].column, 5u);
  EXPECT_NE(p.diags[1].message.find("T3: tool 3 is not in tool table"), std::string::npos);
}

// FANUC Series 0i-MF operator's manual, "Changing workpiece coordinate system" (G10 L2 Pp IP_):
// p = 1..6 for G54..G59; in G90 the values are the new offset, in G91 they are added to it.
TEST(ParseIssue14, FanucG10L2ByHand) {
  Parsed p = parse_text("G10 L2 P2 X100. Y50. Z-20.\nG55 G0 X0 Y0 Z0\nG91 G10 L2 P2 X-10.\nG90 G0 X1\nG10 L2 P1 Z5\nG54 G0 Z0\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  EXPECT_DOUBLE_EQ(p.blocks[1].target[kX], 100);
  EXPECT_DOUBLE_EQ(p.blocks[1].target[kZ], -20);
  EXPECT_DOUBLE_EQ(p.blocks[3].target[kX], 91);  // offset 100 - 10, plus X1
  EXPECT_DOUBLE_EQ(p.blocks[5].target[kZ], 5);
  // The blocks publish the machine file's origin (G55: 100 50 -20 in the test machine), so every
  // later stage and the writer see one frame.
  EXPECT_DOUBLE_EQ(p.blocks[3].work_origin[kX], 100);
  expect_error("G10 L20 P1 X0\n", "extended work offsets", 5);
  expect_error("G10 L1 P1 Z10\n", "G10 L1 is not supported", 5);
  expect_error("G10 L2 P7 X0\n", "must be 1..6", 8);
}

TEST(ParseIssue14, LinuxCncPolarCoordinates) {
  Parsed p = parse_text("G0 @2 ^90\nG0 @1\nG91 G0 @1 ^90\n", linuxcnc());
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  EXPECT_NEAR(p.blocks[0].target[kY], 2, 1e-12);
  EXPECT_NEAR(p.blocks[1].target[kY], 1, 1e-12);  // the angle stays
  EXPECT_NEAR(p.blocks[2].target[kX], -2, 1e-12); // G91: distance 1 + 1, angle 90 + 90
  expect_error("G0 X1 @1 ^2\n", "polar coordinates (@ ^) and X", 4, linuxcnc());
  expect_error("G18\nG0 @1 ^0\n", "need the G17 plane", 4, linuxcnc());
  expect_error("G0 @1\n", "unexpected '@'", 4);  // not a Fanuc word
}

// FANUC Series 0i-MF operator's manual, "Subprogram" (M98 P L, M99): the main program calls
// O1010 twice (M98 P1010 L2, and the older form P21010); the subprogram follows M30 and ends
// with M99. Worked by hand: each run moves X by 10 incrementally.
TEST(ParseIssue14, FanucSubprogramsByHand) {
  Parsed p = parse_text("O0001\nG90 G0 X0 Y0\nM98 P1010 L2\nM98 P21010\nG90 G0 Y5\nM98 P1020\nM30\n"
                        "O1010 (STEP)\nG91 G1 X10. F100\nG90\nM99\nO1020\nM98 P1010\nG0 Z1\nM99\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  const auto e = ends(p);
  ASSERT_EQ(e.size(), 1u + 4 + 1 + 1 + 1);
  for (int i = 0; i < 4; ++i) EXPECT_DOUBLE_EQ(e[static_cast<std::size_t>(1 + i)][kX], 10.0 * (i + 1));
  EXPECT_DOUBLE_EQ(e[5][kY], 5);
  EXPECT_DOUBLE_EQ(e[6][kX], 50);  // O1020 calls O1010 once more
  EXPECT_DOUBLE_EQ(e[7][kZ], 1);
  EXPECT_EQ(p.blocks[2].line, 3u);  // the M98 line itself (it moves nothing)
  EXPECT_EQ(p.blocks[3].line, 9u);  // the moves carry the subprogram's line
  EXPECT_EQ(p.summary.lines_not_run, 8u);  // the two subprograms where they stand
  EXPECT_EQ(p.summary.lines_read, p.summary.blocks_emitted + p.summary.lines_rejected + p.summary.lines_deleted);
  Parsed missing = parse_text("M98 P2000\nG0 X1\nM30\n");
  ASSERT_NE(missing.first_error(), nullptr);
  EXPECT_NE(missing.first_error()->message.find("subprogram O2000 is not defined"), std::string::npos);
  EXPECT_EQ(missing.first_error()->line, 1u);
  expect_error("G0 X1\nM99\n", "M99 in the main program", 1);
  expect_error("M98 P1\n", "M98 (Fanuc subprogram call/return) is not LinuxCNC", 1, linuxcnc());
}

// FANUC Series 0i-MF operator's manual, Custom Macro B, "sum of the numbers from 1 to 10", once
// with WHILE [..] DO 1 ... END 1 and once with IF [..] GOTO and GOTO back; by hand: 55.
TEST(ParseIssue14, FanucMacroBByHand) {
  Parsed w = parse_text("O0001;\n#1=0;\n#2=1;\nWHILE[#2 LE 10]DO 1;\n#1=#1+#2;\n#2=#2+1;\nEND 1;\nG0 X#1;\n"
                        "IF [#1 EQ 55] THEN #3=7;\nIF [#1 NE 55] THEN #3=8;\nG0 Y#3\nM30;\n");
  ASSERT_EQ(w.first_error(), nullptr) << format(*w.first_error());
  ASSERT_EQ(ends(w).size(), 2u);
  EXPECT_DOUBLE_EQ(ends(w)[0][kX], 55);
  EXPECT_DOUBLE_EQ(ends(w)[1][kY], 7);
  EXPECT_EQ(w.summary.lines_read, w.summary.blocks_emitted + w.summary.lines_rejected + w.summary.lines_deleted);
  Parsed g = parse_text("O9500;\n#1=0;\n#2=1;\nN1 IF[#2 GT 10] GOTO 2;\n#1=#1+#2;\n#2=#2+1;\nGOTO 1;\nG0 Z99;\n"
                        "N2 G0 X#1;\nM30;\n");
  ASSERT_EQ(g.first_error(), nullptr) << format(*g.first_error());
  ASSERT_EQ(ends(g).size(), 1u);  // G0 Z99 is jumped over
  EXPECT_DOUBLE_EQ(ends(g)[0][kX], 55);
  EXPECT_EQ(g.summary.lines_not_run, 1u);
  ParseOptions o;
  o.max_loop_passes = 500;
  Parsed runaway = parse_text("#1=0\nN1 #1=#1+1\nGOTO 1\nG0 X#1\n", o);
  ASSERT_NE(runaway.first_error(), nullptr);
  EXPECT_NE(runaway.first_error()->message.find("jumped back 500 times and was stopped"), std::string::npos);
  EXPECT_DOUBLE_EQ(ends(runaway).back()[kX], 501);  // the program goes on after the GOTO
  expect_error("GOTO 7\nG0 X1\n", "GOTO 7: no block N7 follows it", 1);
}

// The machine file's `tool_table` key: a path relative to the machine file, merged over `tools`.
TEST(ParseIssue14, MachineFileToolTableKey) {
  const auto dir = std::filesystem::path(testing::TempDir()) / "gcpipe_machine_tbl";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "shop.tbl") << "T1 P1 D12 Z80.5\nT5 P5 D6 Z42\n";
  const std::string base = read_file(std::filesystem::path(GCPIPE_SOURCE_DIR) / "pipeline_configs/machines/mx330.yaml");
  std::ofstream(dir / "machine.yaml") << base << "\ntool_table: shop.tbl\nreference_positions:\n  G28: [0, 0, 250, 0, 0]\n";
  const MachineConfig m = load_machine(Config::load_file(dir / "machine.yaml"));
  EXPECT_DOUBLE_EQ(m.tools.at(1).length, 80.5);  // the table replaces the machine file's T1
  EXPECT_DOUBLE_EQ(m.tools.at(2).length, 110);   // and keeps the others
  EXPECT_DOUBLE_EQ(m.tools.at(5).diameter, 6);
  EXPECT_EQ(m.tool_table_source, (dir / "shop.tbl").string());
  EXPECT_DOUBLE_EQ(m.reference_positions[0][kZ], 250);
  std::ofstream(dir / "bad.yaml") << base << "\ntool_table: missing.tbl\n";
  EXPECT_THROW(load_machine(Config::load_file(dir / "bad.yaml")), ConfigError);
}

// Bug: an unclosed loop, branch or definition counted its opening line twice (emitted or
// skipped when it ran, and again as rejected at the end of input).
TEST(ParseIssue14, UnclosedStructuresCountTheirOpeningLineOnce) {
  for (const char* text : {"G0 X1\no1 while [1]\nG0 X2\n", "G0 X1\no1 if [1]\nG0 X2\n", "G0 X1\no1 if [0]\nG0 X2\n",
                           "G0 X1\no<s> sub\nG0 X2\n", "G0 X1\no1 do\nG0 X2\n", "G0 X1\no1 repeat [2]\nG0 X2\n",
                           // a loop that runs zero times and never ends was passed over silently
                           "G0 X1\no1 while [0]\nG0 X2\n", "G0 X1\no1 repeat [0]\nG0 X2\n"}) {
    SCOPED_TRACE(text);
    Parsed p = parse_text(text, linuxcnc());
    ASSERT_NE(p.first_error(), nullptr);
    EXPECT_EQ(p.first_error()->line, 2u);
    EXPECT_EQ(p.summary.lines_read, 3u);
    EXPECT_EQ(p.summary.lines_rejected, 1u);
    EXPECT_EQ(p.summary.lines_read, p.summary.blocks_emitted + p.summary.lines_rejected + p.summary.lines_deleted);
  }
  Parsed f = parse_text("#1 = 0\nWHILE [#1 LT 0] DO 1\nG0 X1\n");  // Fanuc, zero passes, no END 1
  ASSERT_NE(f.first_error(), nullptr);
  EXPECT_EQ(f.first_error()->line, 2u);
  EXPECT_EQ(f.summary.lines_rejected, 1u);
  EXPECT_EQ(f.summary.lines_read, f.summary.blocks_emitted + f.summary.lines_rejected + f.summary.lines_deleted);
}

// G10 tool entries, worked by hand from the manuals. LinuxCNC (G-code reference, "G10 L1" and
// "G10 L10"): L1 P Z R sets tool P's length and radius; L10 sets the length such that the
// current Z reads as the word after G43 reloads it (length = Z now + length in force - Z word).
// Fanuc (0i-MF operator's manual B-64604EN, "Tool compensation values input by program (G10)",
// tool compensation memory C): L10 P R = length geometry, L12 P R = radius geometry, and in
// G91 R is added to the value stored.
TEST(ParseIssue14, G10ToolEntriesFromTheProgram) {
  Parsed l = parse_text("T1 M6\nG10 L1 P1 Z42 R3\nG43 H1\nG0 Z5\nG10 L10 P1 Z2\nG43 H1\n"
                        "G1 F800 X0\nG275 X10 Z-1 R5 W12 K1\n",
                        linuxcnc());
  ASSERT_EQ(l.first_error(), nullptr) << format(*l.first_error());
  EXPECT_DOUBLE_EQ(l.blocks[2].tool_length, 42);  // L1 is in force for the next G43
  EXPECT_DOUBLE_EQ(l.blocks[5].tool_length, 45);  // 5 + 42 - 2
  EXPECT_DOUBLE_EQ(l.blocks.back().slot.tool_diameter, 6);  // R is the radius
  expect_error("G10 L1 P7 Z5\n", "tool 7 is not in", 8, linuxcnc());
  expect_error("G10 L1 P1\n", "without Z or R has no effect", 1, linuxcnc());
  expect_error("G10 L1 P1 X5\n", "not X", 11, linuxcnc());
  expect_error("G10 L2 P1 R5\n", "rotated coordinate system", 11, linuxcnc());
  Parsed f = parse_text("T1 M6\nG10 L10 P1 R120.\nG43 H1\nG91 G10 L10 P1 R-5.\nG90 G43 H1\nG10 L12 P7 R4.\n"
                        "T7 M6\nG1 F800 X0\nG275 X10 Z-1 R5 W12 K1\n");
  ASSERT_EQ(f.first_error(), nullptr) << format(*f.first_error());
  EXPECT_DOUBLE_EQ(f.blocks[2].tool_length, 120);
  EXPECT_DOUBLE_EQ(f.blocks[4].tool_length, 115);  // G91: R added
  EXPECT_DOUBLE_EQ(f.blocks.back().slot.tool_diameter, 8);  // a new offset number P7, radius 4
  expect_error("G10 L11 P1 R0.1\n", "wear offsets (L11, L13) are not modelled", 5);
}

// Fanuc Custom Macro B system variables (0i-MF operator's manual B-64604EN, "System variables"):
// #5001..#5005 read the end position of the last block in work coordinates (X Y Z A C here),
// #3000 = n stops the program with alarm 3000 + n and the comment as its message.
TEST(ParseIssue14, FanucPositionVariablesAndAlarm) {
  Parsed p = parse_text("G55 G0 X10 Y20 Z5\n#1 = #5001 + #5002\nG0 X#1 Z[#5003 - 1]\nG91 G0 X1\nG0 Y#5001\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  const auto e = ends(p);
  ASSERT_EQ(e.size(), 4u);
  // ends() gives work coordinates: #5001 + #5002 = 10 + 20 (G55's origin X100 Y50 is not in it)
  EXPECT_DOUBLE_EQ(e[1][kX], 30);
  EXPECT_DOUBLE_EQ(e[1][kZ], 4);
  EXPECT_DOUBLE_EQ(e[3][kY], 20 + 31);  // G91: Y moves by the X read, 31
  expect_error("#5002 = 3\n", "read only", 1);
  Parsed a = parse_text("G0 X1\n#1 = 0\nWHILE [#1 LT 3] DO 1\n#1 = #1 + 1\nIF [#1 EQ 2] THEN #3000 = 12 (TOOL BROKEN)\n"
                        "G0 X#1\nEND 1\nG0 X9\nM30\n");
  ASSERT_NE(a.first_error(), nullptr);
  EXPECT_EQ(a.first_error()->line, 5u);
  EXPECT_NE(a.first_error()->message.find("macro alarm 3012: TOOL BROKEN"), std::string::npos) << a.first_error()->message;
  EXPECT_DOUBLE_EQ(ends(a).back()[kX], 1);  // the loop's first pass moved to X1; nothing after
  EXPECT_EQ(a.summary.lines_read, a.summary.blocks_emitted + a.summary.lines_rejected + a.summary.lines_deleted);
  EXPECT_EQ(a.summary.lines_not_run, 2u);  // G0 X9 and M30
  Parsed m = parse_text("G0 X1\n#3000 = 1 (STOP)\nG0 X2\n");
  ASSERT_NE(m.first_error(), nullptr);
  EXPECT_EQ(m.first_error()->column, 1u);
  EXPECT_EQ(m.blocks.size(), 1u);
  EXPECT_EQ(m.summary.lines_not_run, 1u);
}

// The control's offsets a program reads (compensated.nc's guard, issue 30), as rs274 and the 0i
// number them. LinuxCNC: #5221 + 20 k + {X 0, Y 1, Z 2, A 3, C 5} the G54..G59 origins in the
// machine's unit, #5220 the system in use, #5210 a G92 shift applied, #5400 the tool in the
// spindle and #5403 its length in the tool table; `(abort, msg)` stops the program. Fanuc:
// #5221 + 20 k + {0..4} in axis order, #5083 the tool length in force, #5201.. the external
// offset (none). A program cannot assign them. rs274 reads the same LinuxCNC values (checked by
// hand with `(debug, ...)` on rs274 of linuxcnc-uspace: #5403 is the loaded tool's table length, G43
// or not; the parameters are in its internal unit, the inch for standalone rs274).
TEST(ParseIssue30, TheControlsOffsetsReadAsTheControlNumbersThem) {
  ParseOptions lc;
  lc.dialect = Dialect::kLinuxCnc;
  // G55's origin is X100 Y50 Z-20 in the test machine; G10 moves G54's.
  Parsed p = parse_text("G10 L2 P1 X7 C30\nG55\nT2 M6\nG0 X[#5241] Y[#5242] Z[#5243]\nG0 X[#5221] C[#5226]\n"
                        "G0 X[#5220] Y[#5400] Z[#5403]\n",
                        lc);
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  const auto e = ends(p);
  ASSERT_EQ(e.size(), 3u);
  EXPECT_DOUBLE_EQ(e[0][kX], 100);
  EXPECT_DOUBLE_EQ(e[0][kY], 50);
  EXPECT_DOUBLE_EQ(e[0][kZ], -20);
  EXPECT_DOUBLE_EQ(e[1][kX], 7);
  EXPECT_DOUBLE_EQ(e[1][kC], 30);
  EXPECT_DOUBLE_EQ(e[2][kX], 2);    // G55
  EXPECT_DOUBLE_EQ(e[2][kY], 2);    // T2 in the spindle
  EXPECT_DOUBLE_EQ(e[2][kZ], 110);  // its length
  EXPECT_DOUBLE_EQ(ends(parse_text("G0 X1\nG92 X5\nG0 Y[#5210]\n", lc)).back()[kY], 1);  // a G92 shift applied
  EXPECT_DOUBLE_EQ(ends(parse_text("G0 X1\nG0 Y[#5210]\n", lc)).back()[kY], 0);
  Parsed stop = parse_text("G0 X1\no1 if [#5221 NE 5]\n(abort, G54 X is not 5)\no1 endif\nG0 X2\n", lc);
  ASSERT_NE(stop.first_error(), nullptr);
  EXPECT_EQ(stop.first_error()->line, 3u);
  EXPECT_NE(stop.first_error()->message.find("abort: G54 X is not 5"), std::string::npos) << stop.first_error()->message;
  EXPECT_EQ(ends(stop).back()[kX], 1);  // nothing after the abort runs
  Parsed go = parse_text("G0 X1\no1 if [#5221 NE 0]\n(abort, G54 X is not 0)\no1 endif\nG0 X2\n", lc);
  EXPECT_EQ(go.first_error(), nullptr);
  EXPECT_EQ(ends(go).back()[kX], 2);
  // Fanuc: G55 X is #5241, C (the fifth axis) #5245; #5083 the length in force.
  Parsed f = parse_text("G0 X[#5241] Y[#5245] Z[#5083]\nG43 H1\nG0 X[#5083] Y[#5201]\n");
  ASSERT_EQ(f.first_error(), nullptr) << format(*f.first_error());
  EXPECT_DOUBLE_EQ(ends(f)[0][kX], 100);
  EXPECT_DOUBLE_EQ(ends(f)[0][kY], 0);
  EXPECT_DOUBLE_EQ(ends(f)[0][kZ], 0);
  EXPECT_DOUBLE_EQ(ends(f)[1][kX], 100);
  EXPECT_DOUBLE_EQ(ends(f)[1][kY], 0);
  Parsed set = parse_text("#5221 = 3\n");
  ASSERT_NE(set.first_error(), nullptr);
  EXPECT_NE(set.first_error()->message.find("G10 L2"), std::string::npos) << set.first_error()->message;
}

// Fanuc Custom Macro B vacant ("null") variables, as the 0i-MF operator's manual B-64604EN,
// Custom Macro, "Null variables" states them: #0 is always vacant, and so is a variable never set.
//  - quotation: with #1 vacant, `G90 X100 Y#1` is `G90 X100` (the address is left out);
//  - replacement: `#2 = #1` leaves #2 vacant; `#2 = #1 * 5` and `#2 = #1 + #1` give 0;
//  - conditions: vacant differs from 0 only in EQ and NE: `#1 EQ #0` true, `#1 EQ 0` false,
//    `#1 NE 0` true, `#1 GE #0` true, `#1 GT 0` false.
// LinuxCNC has no vacancy: a parameter never set reads 0 (rs274 does the same).
TEST(ParseIssue14, FanucVacantVariablesByTheManual) {
  constexpr std::uint8_t kYWord = 1u << kY, kZWord = 1u << kZ;
  Parsed q = parse_text("G90 G0 X5 Y7\nG90 G0 X100 Y#1\n");
  ASSERT_EQ(q.first_error(), nullptr) << format(*q.first_error());
  ASSERT_EQ(ends(q).size(), 2u);
  EXPECT_DOUBLE_EQ(ends(q)[1][kX], 100);
  EXPECT_DOUBLE_EQ(ends(q)[1][kY], 7);  // Y left out: the machine stays at Y7, not Y0
  EXPECT_EQ(q.blocks[1].axis_words & kYWord, 0);

  Parsed r = parse_text("#2 = #1\n#3 = #1 * 5\n#4 = #1 + #1\nG0 X1 Y#2\nG0 X#3 Y#4 Z#0\n");
  ASSERT_EQ(r.first_error(), nullptr) << format(*r.first_error());
  ASSERT_EQ(ends(r).size(), 2u);
  const ResolvedBlock& first = *std::find_if(r.blocks.begin(), r.blocks.end(), [](const auto& b) { return b.line == 4; });
  const ResolvedBlock& second = *std::find_if(r.blocks.begin(), r.blocks.end(), [](const auto& b) { return b.line == 5; });
  EXPECT_EQ(first.axis_words & kYWord, 0);   // #2 stayed vacant
  EXPECT_DOUBLE_EQ(ends(r)[1][kX], 0);       // #1 * 5 = 0, a value
  EXPECT_NE(second.axis_words & kYWord, 0);  // #1 + #1 = 0, a value
  EXPECT_EQ(second.axis_words & kZWord, 0);  // #0

  // Each condition sets #11.. to 1 when it holds; G0 X.. Y.. Z.. reads them back in threes.
  Parsed c = parse_text(
      "#11 = 0\n#12 = 0\n#13 = 0\n#14 = 0\n#15 = 0\n#16 = 0\n"
      "IF [#1 EQ #0] THEN #11 = 1\nIF [#1 EQ 0] THEN #12 = 1\nIF [#1 NE 0] THEN #13 = 1\n"
      "IF [#1 GE #0] THEN #14 = 1\nIF [#1 GT 0] THEN #15 = 1\n#5 = 0\nIF [#5 EQ #0] THEN #16 = 1\n"
      "G0 X#11 Y#12 Z#13\nG0 X#14 Y#15 Z#16\n");
  ASSERT_EQ(c.first_error(), nullptr) << format(*c.first_error());
  const auto e = ends(c);
  ASSERT_EQ(e.size(), 2u);
  EXPECT_DOUBLE_EQ(e[0][kX], 1);  // #1 EQ #0
  EXPECT_DOUBLE_EQ(e[0][kY], 0);  // #1 EQ 0 is false
  EXPECT_DOUBLE_EQ(e[0][kZ], 1);  // #1 NE 0
  EXPECT_DOUBLE_EQ(e[1][kX], 1);  // #1 GE #0
  EXPECT_DOUBLE_EQ(e[1][kY], 0);  // #1 GT 0 is false
  EXPECT_DOUBLE_EQ(e[1][kZ], 0);  // 0 is a value, not vacant

  // A variable cleared with #0 is vacant again; #0 itself cannot be set, and the rest still runs.
  Parsed cleared = parse_text("#7 = 3\nG0 X#7\n#7 = #0\nG0 X1 Y#7\n");
  ASSERT_EQ(cleared.first_error(), nullptr) << format(*cleared.first_error());
  EXPECT_EQ(cleared.blocks.back().axis_words & kYWord, 0);
  expect_error("#0 = 5\n", "#0 is the vacant variable", 2);
  Parsed rest = parse_text("G0 X1\n#0 = 5\nG0 X2\n");
  ASSERT_NE(rest.first_error(), nullptr);
  EXPECT_EQ(rest.first_error()->line, 2u);
  EXPECT_DOUBLE_EQ(ends(rest).back()[kX], 2);

  // A system variable gcpipe does not keep is an error where it is read, not a silent vacancy.
  expect_error("#1 = #4003\n", "system variable #4003 is not modelled", 6);

  // LinuxCNC: no vacancy, #0 is out of range, an unset parameter reads 0.
  Parsed l = parse_text("G0 X5 Y7\nG0 X100 Y#1\n", linuxcnc());
  ASSERT_EQ(l.first_error(), nullptr) << format(*l.first_error());
  EXPECT_DOUBLE_EQ(ends(l)[1][kY], 0);
  expect_error("G0 X#0\n", "parameter number", 5, linuxcnc());
}

namespace {
struct Expected {
  Motion motion;
  double x, y, z;
  Spindle spindle;
  double dwell = 0;
  bool stop = false;
};
void expect_moves(const Parsed& p, std::uint64_t line, const std::vector<Expected>& want) {
  std::vector<const ResolvedBlock*> got;
  for (const auto& b : p.blocks)
    if (b.line == line) got.push_back(&b);
  ASSERT_EQ(got.size(), want.size()) << "line " << line;
  for (std::size_t i = 0; i < want.size(); ++i) {
    SCOPED_TRACE("line " + std::to_string(line) + " move " + std::to_string(i));
    EXPECT_EQ(got[i]->motion, want[i].motion);
    EXPECT_DOUBLE_EQ(got[i]->target[kX], want[i].x);
    EXPECT_DOUBLE_EQ(got[i]->target[kY], want[i].y);
    EXPECT_DOUBLE_EQ(got[i]->target[kZ], want[i].z);
    EXPECT_EQ(got[i]->spindle, want[i].spindle);
    EXPECT_DOUBLE_EQ(got[i]->dwell, want[i].dwell);
    EXPECT_EQ(got[i]->stop == ProgramStop::kStop, want[i].stop);
  }
}
}  // namespace

// Fanuc boring cycles, worked by hand from the 0i-MF operator's manual (B-64604EN), canned
// cycles section (G76 fine boring, G87 back boring, G88 boring): the shift direction is the
// machine's (parameter 5101 RD2 RD1; parse.boring_shift), Q the shift, P the dwell in ms.
TEST(ParseIssue14, FanucBoringCyclesByHand) {
  const auto R = Motion::kRapid, F = Motion::kLinear, D = Motion::kDwell;
  const auto on = Spindle::kCW, off = Spindle::kOff;
  Parsed p = parse_text("G17 G90 G0 X0 Y0 Z50 S500 M3 F100\nG98 G76 X10 Y5 Z-20 R2 Q1.5 P500\nG80\n"
                        "G99 G88 X30 Y0 Z-10 R2 P1000\nG80\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  expect_moves(p, 2, {{R, 10, 5, 50, on}, {R, 10, 5, 2, on}, {F, 10, 5, -20, on}, {D, 10, 5, -20, on, 0.5},
                      {R, 11.5, 5, -20, off}, {R, 11.5, 5, 50, off}, {R, 10, 5, 50, off}});
  expect_moves(p, 4, {{R, 30, 0, 50, on}, {R, 30, 0, 2, on}, {F, 30, 0, -10, on}, {D, 30, 0, -10, on, 1},
                      {D, 30, 0, -10, off, 0, true}, {R, 30, 0, 2, off}});
  EXPECT_EQ(p.blocks.back().spindle, on);  // the spindle turns again after the cycle
  ParseOptions minus_y;
  minus_y.boring_shift = 3;  // RD2 RD1 = 1 1: -Y in G17
  Parsed b = parse_text("G17 G90 G0 X0 Y0 Z50 S500 M3 F100\nG98 G87 X20 Y5 Z-5 R-25 Q2\nG80\n", minus_y);
  ASSERT_EQ(b.first_error(), nullptr) << format(*b.first_error());
  expect_moves(b, 2, {{R, 20, 5, 50, on}, {R, 20, 3, 50, off}, {R, 20, 3, -25, off}, {R, 20, 5, -25, off},
                      {F, 20, 5, -5, on}, {R, 20, 3, -5, off}, {R, 20, 3, 50, off}, {R, 20, 5, 50, off}});
  expect_error("G0 Z50\nG99 G87 X1 Z-5 R-25 Q2 F100\n", "use G98", 5);
  expect_error("G0 Z50\nG76 X1 Z-5 R2 F100\n", "positive shift Q", 1);
  expect_error("G87 X1 Z-5 R-25 Q2 F100\n", "not LinuxCNC G-code", 1, linuxcnc());
}

// Cutter radius compensation (LinuxCNC dialect; the geometry is compared with rs274 in
// rs274_diff_test.cpp). Here: what the stream looks like and the errors.
namespace {

// Every block starts where the one before it left the tool, lines come out in order, and every
// line is accounted for.
void expect_continuous(const Parsed& p) {
  for (std::size_t i = 1; i < p.blocks.size(); ++i) {
    SCOPED_TRACE("block " + std::to_string(i) + ", line " + std::to_string(p.blocks[i].line));
    EXPECT_LE(p.blocks[i - 1].line, p.blocks[i].line);
    for (int a = 0; a < kNumAxes; ++a) EXPECT_NEAR(p.blocks[i].start[a], p.blocks[i - 1].target[a], 1e-9) << a;
    if (p.blocks[i].motion == Motion::kArcCW || p.blocks[i].motion == Motion::kArcCCW) {
      const auto& b = p.blocks[i];
      const double rs = std::hypot(b.start[kX] - b.centre[0], b.start[kY] - b.centre[1]);
      EXPECT_NEAR(rs, b.radius, 1e-9);
    }
  }
  const ParseSummary& s = p.summary;
  EXPECT_EQ(s.lines_read, s.blocks_emitted + s.lines_rejected + s.lines_deleted);
}

}  // namespace

TEST(ParseIssue14, CutterCompHoldsOneMoveInOrder) {
  // Tool 2 of the machine's table: diameter 20, radius 10.
  Parsed p = parse_text("G21 G90 G17 F100\nG0 X-50 Y-50 Z0\nG41 D2\nG1 X0 Y0 (entry)\nG1 X100\nM8\nG1 Z-5\n"
                        "o1 if [1]\n  G1 Y100\no1 endif\nG1 X0\nG40\nG0 Z10\nG0 X-50 Y-50\n",
                        linuxcnc());
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  expect_continuous(p);
  const auto e = ends(p);
  // the rapid, the entry, the corner arc, X100 cut at the concave corner, the Z move there,
  // Y100, X0 (held until G40 ends it at its offset end), the exit move with Z, the last rapid.
  ASSERT_EQ(e.size(), 9u);
  EXPECT_NEAR(e[1][kX], -10 / std::sqrt(2.0), 1e-9);  // perpendicular to the entry, left
  EXPECT_NEAR(e[2][kY], 10, 1e-9);                     // round the convex corner at X0 Y0
  EXPECT_NEAR(e[3][kX], 90, 1e-9);                     // concave: the intersection
  EXPECT_NEAR(e[4][kZ], -5, 1e-9);
  EXPECT_NEAR(e[4][kX], 90, 1e-9);                     // the Z move stands at the held move's end
  EXPECT_NEAR(e[5][kY], 90, 1e-9);
  EXPECT_NEAR(e[6][kX], 0, 1e-9);
  EXPECT_NEAR(e[6][kY], 90, 1e-9);                     // G40: the offset end
  EXPECT_NEAR(e[7][kZ], 10, 1e-9);
  EXPECT_NEAR(e[7][kY], 100, 1e-9);                    // the exit move reaches the programmed point
  EXPECT_EQ(p.summary.lines_rejected, 0u);
  // A program that stops in compensation: finish() hands out the held move.
  Parsed q = parse_text("G0 X-50 Y0\nG42 D1\nG1 X0 F100\nG1 X100\n", linuxcnc());
  ASSERT_EQ(q.first_error(), nullptr);
  ASSERT_EQ(ends(q).size(), 3u);
  EXPECT_NEAR(ends(q).back()[kY], -5, 1e-9);  // G42: right of +X
  expect_continuous(q);
}

// An I J arc whose radii differ by just under LinuxCNC's 0.1 % (30 and 30.0299 mm) is accepted;
// under compensation with the tool inside it (G41 on a G3) its offset path keeps the centre and the
// difference on a radius 5 mm smaller: 0.12 %, which output.nc's read-back (and a control) would
// reject, so the programmed arc is rejected at its line. Outside (G42) the path's 0.085 % is fine.
// Found by parse_fuzz (tests/fuzz/regressions/compensated-arc-past-the-relative-radius-tolerance).
TEST(ParseIssue14, AnArcWhoseOffsetPathLeavesTheRadiusToleranceIsRejectedAtItsLine) {
  const std::string arc = "G3 X130.0299 Y30 I0 J30\n";
  const std::string plain = "G21 G90 G17 F100\nG0 X-50 Y0 Z0\nG1 X0 Y0\nG1 X100 Y0\n";
  EXPECT_EQ(parse_text(plain + arc, linuxcnc()).first_error(), nullptr);
  expect_error("G21 G90 G17 F100\nG0 X-50 Y0 Z0\nG41 D1\nG1 X0 Y0\nG1 X100 Y0\n" + arc,
               "G3: with G41 the tool path's radii differ by 0.0299 mm, 0.1195 % of its radius 25.03 mm", 4, linuxcnc());
  const Parsed outside = parse_text("G21 G90 G17 F100\nG0 X-50 Y0 Z0\nG42 D1\nG1 X0 Y0\nG1 X100 Y0\n" + arc +
                                        "G40 G1 X150 Y60\n", linuxcnc());
  EXPECT_EQ(outside.first_error(), nullptr) << format(*outside.first_error());
}

TEST(ParseIssue14, CutterCompErrorsRejectTheirLineOnly) {
  const std::string head = "G21 G90 G17 F100\nG0 X-50 Y0 Z0\nG41 D1\nG1 X0 Y0\nG1 X100 Y0\n";
  expect_error(head + "G3 X100 Y6 R3\n", "tool radius 5 mm not less than arc radius 3 mm with G41", 4, linuxcnc());
  expect_error("G0 X0 Y0\nG41 D1\nG1 X3 F100\n", "entry move is 3 mm long, not longer than the tool radius 5 mm", 4,
               linuxcnc());
  // An arc as the entry move: LinuxCNC runs it (geometry compared with rs274: comp_arc_entry).
  EXPECT_EQ(parse_text("G0 X0 Y0\nG41 D1\nG2 X20 Y0 R10 F100\n", linuxcnc()).first_error(), nullptr);
  expect_error(head + "G40\nG2 X120 Y20 R20\n", "the move that leaves cutter compensation must be a straight line", 4,
               linuxcnc());
  expect_error(head + "G42 D1\n", "already on: program G40 first", 1, linuxcnc());
  expect_error(head + "G18\n", "cannot use a plane change with cutter radius compensation on", 1, linuxcnc());
  expect_error(head + "G81 X1 Y1 Z-1 R1\n", "cannot use a canned cycle with cutter radius compensation on", 1, linuxcnc());
  expect_error(head + "T2 M6\n", "cannot use a tool change", 4, linuxcnc());
  expect_error("G19 G41 D1\n", "LinuxCNC allows cutter radius compensation only in the XY and XZ planes", 5, linuxcnc());
  expect_error("G41 D7\n", "tool 7 is not in", 5, linuxcnc());
  expect_error("G41\n", "without a tool", 1, linuxcnc());
  expect_error("G41.1\n", "G41.1 needs D: the tool diameter", 1, linuxcnc());
  expect_error("G40 D1\n", "word D1 has no meaning here", 5, linuxcnc());
  expect_error("G0 X0 Y0\nG41 D1\nG2 X20 Y0 R10 F100\n", "Fanuc alarm PS0034", 4);
  expect_error("G42.1 D3\n", "not Fanuc G-code", 1);
  // A step shorter than the radius into a concave corner: the short move is rejected (rs274
  // reports it one line later, at the move that ends it) and the contour goes on without it.
  Parsed p = parse_text(head + "G1 X100 Y2\nG1 X200 Y2\nG40 G1 X250 Y0\n", linuxcnc());
  ASSERT_NE(p.first_error(), nullptr);
  EXPECT_EQ(p.first_error()->line, 6u);
  EXPECT_NE(p.first_error()->message.find("cannot reach it without gouging"), std::string::npos) << p.first_error()->message;
  EXPECT_EQ(p.summary.lines_rejected, 1u);
  expect_continuous(p);
  const auto e = ends(p);
  // A spike of 2.5 deg into the tool's side: concave, and the tool (radius 5) would have to go
  // 115 mm back into it: an error. (rs274 goes round its tip with an arc and cuts into the part.)
  const double a = (180 - 2.5) * std::acos(-1.0) / 180;
  char spike[64];
  std::snprintf(spike, sizeof spike, "G1 X%.6f Y%.6f\n", 100 + 20 * std::cos(a), -20 * std::sin(a));
  expect_error("G0 X-50 Y0\nG42 D1\nG1 X0 F100\nG1 X100\n" + std::string(spike), "cannot reach it without gouging", 4,
               linuxcnc());
  // The rapid, the entry, X100, X200 joined to it without a corner (0.02 rad), the exit.
  ASSERT_EQ(e.size(), 5u);
  EXPECT_NEAR(e[3][kX], 200 - 5 * std::sin(std::atan(0.02)), 1e-9);
  EXPECT_NEAR(e[3][kY], 2 + 5 * std::cos(std::atan(0.02)), 1e-9);
  EXPECT_NEAR(e.back()[kX], 250, 1e-9);
}

// Fanuc cutter compensation C (FANUC 0i-MF / 30i operator's manual, "Cutter compensation C",
// Type A start-up and cancel, SUP = 0), worked by hand. alpha is the angle between the two moves
// on the workpiece side; D is the tool number whose table diameter / 2 is the radius (tool 1:
// r = 5, tool 2: r = 10). Default dialect: Fanuc.
namespace {

struct XY {
  Motion motion;
  double x, y;
};

// The moving blocks of `p` (from the `from`-th on), in program coordinates.
void expect_path(const Parsed& p, std::size_t from, const std::vector<XY>& want) {
  std::vector<const ResolvedBlock*> got;
  for (const auto& b : p.blocks)
    if (b.motion == Motion::kRapid || b.motion == Motion::kLinear || b.motion == Motion::kArcCW ||
        b.motion == Motion::kArcCCW)
      got.push_back(&b);
  ASSERT_EQ(got.size(), from + want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    const ResolvedBlock& b = *got[from + i];
    SCOPED_TRACE("move " + std::to_string(from + i) + ", line " + std::to_string(b.line));
    EXPECT_EQ(b.motion, want[i].motion);
    EXPECT_NEAR(b.target[kX] - b.work_origin[kX], want[i].x, 1e-6);
    EXPECT_NEAR(b.target[kY] - b.work_origin[kY], want[i].y, 1e-6);
  }
}

}  // namespace

// (1) A 40 x 40 square, G41 r = 5, clockwise round its outside (climb). Every corner is an outer
// corner with alpha = 90 deg: obtuse rule (90 <= alpha < 180), no corner arc, the tool goes to the
// intersection of the two offset lines: the corners of the 50 x 50 square (-5,-5) .. (45,45).
// Start-up Type A: the entry ends at (0,0) offset perpendicular to the next move's start
// direction (+Y, left: -X): (-5,0). Cancel Type A: the held Y10 ends perpendicular to its end
// direction, (-5,10), and the G40 move goes straight to its programmed end.
TEST(ParseIssue14, FanucCutterCompSquareOuterCornersMeetAtIntersections) {
  const auto L = Motion::kLinear;
  Parsed p = parse_text("G21 G90 G17\nG0 X-20 Y-20 Z5\nG1 Z-2 F300\nG41 D1 G1 X0 Y0\nY40\nX40\nY0\nX0\nY10\n"
                        "G40 G1 X-20 Y-20\nG0 Z5\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  expect_continuous(p);
  expect_path(p, 2, {{L, -5, 0}, {L, -5, 45}, {L, 45, 45}, {L, 45, -5}, {L, -5, -5}, {L, -5, 10}, {L, -20, -20},
                     {Motion::kRapid, -20, -20}});
  EXPECT_EQ(p.summary.lines_rejected, 0u);
  EXPECT_EQ(p.summary.blocks_out, p.summary.blocks_emitted);  // no corner moves added
}

// (2) An outer corner of alpha = 60 deg (acute rule, alpha < 90): +X to (50,0), then 20 mm
// towards -120 deg to (40,-17.3205081). G41 r = 5, corner c = (50,0), t1 = (1,0), n1 = (0,1),
// t2 = (-1/2, -sqrt3/2), n2 = (sqrt3/2, -1/2):
//   P1 = c + r n1 + r t1 = (55, 5): the first move runs on along its offset line to it;
//   P2 = c + r n2 - r t2 = (50 + 2.5 sqrt3 + 2.5, -2.5 + 2.5 sqrt3) = (56.8301270, 1.8301270):
//   one extra G1 (a block of the second move's line) from P1 to P2;
//   the second move then runs from P2 along its offset line to its end, held until G40 ends it
//   perpendicular to its end direction: (40 + 2.5 sqrt3, -17.3205081 - 2.5) = (44.3301270, -19.8205081).
TEST(ParseIssue14, FanucCutterCompAcuteOuterCornerGoesRoundByTwoPoints) {
  const auto L = Motion::kLinear;
  Parsed p = parse_text("G21 G90 G17\nG0 X-20 Y10 Z0\nG41 D1 G1 X0 Y0 F300\nX50\nX40 Y-17.3205081\nG40 X60 Y-30\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  expect_continuous(p);
  const double s3 = std::sqrt(3.0);
  expect_path(p, 1, {{L, 0, 5}, {L, 55, 5}, {L, 52.5 + 2.5 * s3, -2.5 + 2.5 * s3}, {L, 40 + 2.5 * s3, -17.3205081 - 2.5},
                     {L, 60, -30}});
  std::size_t on_line5 = 0;
  for (const auto& b : p.blocks) on_line5 += b.line == 5;
  EXPECT_EQ(on_line5, 2u);  // the P1 -> P2 move and the second move itself
}

// (3) An inner corner of alpha = 270 deg (+X then +Y with G41, the tool inside): the intersection
// of the offset paths (y = 5 and x = 45): (45,5), as LinuxCNC's concave corner.
TEST(ParseIssue14, FanucCutterCompInnerCornerEndsAtTheIntersection) {
  const auto L = Motion::kLinear;
  Parsed p = parse_text("G0 X-20 Y-20 Z0\nG41 D1 G1 X0 Y0 F300\nX50\nY40\nG40 X70 Y60\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  expect_continuous(p);
  expect_path(p, 1, {{L, 0, 5}, {L, 45, 5}, {L, 45, 40}, {L, 70, 60}});
  // Too short a move into an inner corner would gouge: an error on that line only.
  Parsed g = parse_text("G0 X-20 Y-20 Z0\nG41 D1 G1 X0 Y0 F300\nX50\nY4\nX0\nG40 X-20 Y-20\n");
  ASSERT_NE(g.first_error(), nullptr);
  EXPECT_EQ(g.first_error()->line, 4u);  // Y4: its offset end (45,4) lies before the corner (45,5)
  EXPECT_NE(g.first_error()->message.find("without gouging"), std::string::npos) << g.first_error()->message;
  expect_continuous(g);
  EXPECT_EQ(g.summary.lines_read, g.summary.blocks_emitted + g.summary.lines_rejected + g.summary.lines_deleted);
}

// (4) Start-up Type A with G42 D2 (r = 10) on a line of its own: the first move after it (a
// diagonal entry from (-30,-10) to (0,0)) ends at (0,0) offset perpendicular to the START
// direction of the next move (+Y, right: +X): (10,0), not perpendicular to the entry itself as in
// LinuxCNC. Cancel Type A: Y50 ends at (10,50), offset perpendicular to its end direction; the
// G40 move goes from there straight to (-30,60). Fanuc has no minimum start-up length.
TEST(ParseIssue14, FanucCutterCompStartUpAndCancelTypeA) {
  const auto L = Motion::kLinear;
  Parsed p = parse_text("G0 X-30 Y-10 Z0\nG42 D2\nG1 X0 Y0 F200\nG1 Y50\nG40 G1 X-30 Y60\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  expect_continuous(p);
  expect_path(p, 1, {{L, 10, 0}, {L, 10, 50}, {L, -30, 60}});
  Parsed l = parse_text("G0 X-30 Y-10 Z0\nG42 D2\nG1 X0 Y0 F200\nG1 Y50\nG40 G1 X-30 Y60\n", linuxcnc());
  ASSERT_EQ(l.first_error(), nullptr) << format(*l.first_error());
  EXPECT_GT(std::fabs(ends(l)[1][kX] - 10), 1);  // LinuxCNC's entry ends elsewhere
  // A start-up move shorter than the radius (LinuxCNC rejects it).
  Parsed s = parse_text("G0 X0 Y-3 Z0\nG41 D1 G1 X0 Y0 F100\nX50\nG40 X60\n");
  ASSERT_EQ(s.first_error(), nullptr) << format(*s.first_error());
  expect_path(s, 1, {{L, 0, 5}, {L, 50, 5}, {L, 60, 0}});
}

// (5) A line into a tangent arc: G41 r = 5, +X to (50,0), G3 to (70,20) about (50,20) (start
// tangent +X: turn 0, no corner; the tool inside the arc, offset radius 15): the line ends where
// the arc's offset starts, (50,5), the arc ends at (65,20). Then the arc (end tangent +Y) into a
// line to (90,40) (direction 45 deg): a right turn of 45 deg, an outer corner of alpha = 135 deg
// (obtuse rule): the tangent line of the arc's offset at its end, x = 65, meets the line's offset
// line (through (70,20) + 5 (-1,1)/sqrt2) at (65, 20 + 5 tan 22.5 deg) = (65, 22.0710678): the arc
// ends at (65,20), a G1 goes on along the tangent to that point, the line starts there and ends
// at (90,40) + 5 (-1,1)/sqrt2 = (86.4644661, 43.5355339) (G40 next).
TEST(ParseIssue14, FanucCutterCompArcsTangentAndObtuse) {
  const auto L = Motion::kLinear;
  Parsed p = parse_text("G0 X-20 Y-10 Z0\nG41 D1 G1 X0 Y0 F300\nX50\nG3 X70 Y20 I0 J20\nG1 X90 Y40\nG40 X100 Y20\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  expect_continuous(p);
  const double h = 5 / std::sqrt(2.0);
  expect_path(p, 1, {{L, 0, 5}, {L, 50, 5}, {Motion::kArcCCW, 65, 20}, {L, 65, 20 + 5 * std::tan(std::acos(-1.0) / 8)},
                     {L, 90 - h, 40 + h}, {L, 100, 20}});
  const ResolvedBlock* arc = nullptr;
  for (const auto& b : p.blocks)
    if (b.motion == Motion::kArcCCW) arc = &b;
  ASSERT_NE(arc, nullptr);
  EXPECT_NEAR(arc->radius, 15, 1e-9);
  EXPECT_NEAR(arc->centre[0] - arc->work_origin[kX], 50, 1e-9);
  EXPECT_NEAR(arc->centre[1] - arc->work_origin[kY], 20, 1e-9);
  // A line into an arc at an outer corner of alpha = 90 deg (obtuse rule): +X to (50,0), then G2
  // about (40,0) to (30,0) (start tangent -Y, the tool outside: offset radius 15). The line's
  // offset y = 5 runs on to the arc's offset tangent line x = 55: (55,5); a G1 goes down the
  // tangent to the arc's offset start (55,0); the arc ends at (25,0) (G40 next).
  Parsed q = parse_text("G0 X-20 Y-10 Z0\nG41 D1 G1 X0 Y0 F300\nX50\nG2 X30 Y0 I-10 J0\nG40 G1 X0 Y20\n");
  ASSERT_EQ(q.first_error(), nullptr) << format(*q.first_error());
  expect_continuous(q);
  expect_path(q, 1, {{L, 0, 5}, {L, 55, 5}, {L, 55, 0}, {Motion::kArcCW, 25, 0}, {L, 0, 20}});
}

// What stays an error in the Fanuc dialect, each on its own line (line:col).
TEST(ParseIssue14, FanucCutterCompErrors) {
  expect_error("G0 X0 Y0\nG41 D1\nG3 X20 Y0 R10 F100\n", "Fanuc alarm PS0034: no arc in the start-up block", 4);
  expect_error("G0 X-10 Y0\nG41 D1 G1 X0 F100\nX50\nG40\nG2 X70 Y20 R20\n", "no arc in the cancel block", 4);
  expect_error("G0 X-10 Y0\nG41 D1 G1 X0 F100\nX50\nG18\n", "cannot use a plane change", 1);
  expect_error("G0 X-10 Y0\nG41 D1 G1 X0 F100\nX50\nG42 D1\n", "already on", 1);
  expect_error("G18 G41 D1\n", "outside the XY plane", 5);
  expect_error("G41.1 D3\n", "not Fanuc G-code", 1);
  // Not implemented: I J K direction words in the start-up block, G39 corner arcs.
  expect_error("G0 X-10 Y0\nG41 D1 G1 X0 I1 J0 F100\n", "word I1 has no meaning here", 14);
  expect_error("G0 X-10 Y0\nG41 D1 G1 X0 F100\nG39 X1\n", "G39 is not a supported G code", 1);
  // An error rejects its own line; the contour goes on without it.
  Parsed p = parse_text("G0 X-10 Y0 Z0\nG41 D1 G1 X0 F100\nX50\nG3 X53 Y6 R3\nY40\nG40 X60 Y50\n");
  ASSERT_NE(p.first_error(), nullptr);
  EXPECT_EQ(p.first_error()->line, 4u);
  EXPECT_EQ(p.first_error()->file, "t.nc");
  EXPECT_EQ(p.summary.lines_rejected, 1u);
  expect_continuous(p);
  expect_path(p, 1, {{Motion::kLinear, 0, 5}, {Motion::kLinear, 45, 5}, {Motion::kLinear, 45, 40},
                     {Motion::kLinear, 60, 50}});
}

// Seeded random Fanuc contours (lines, I J arcs either way, G0 and G1, Z moves between, both
// sides): every block starts where the one before ended and every line is accounted for. On the
// all-line contours (which may cross themselves) each end point of the tool centre after the
// start-up keeps at least the radius from its own line's programmed segment and the one before.
TEST(ParseIssue14, FanucCutterCompRandomContoursStayContinuous) {
  std::size_t checked = 0;
  for (unsigned seed = 1; seed <= 300; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::mt19937 rng(seed);
    auto uni = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
    const bool lines_only = seed % 2 == 0;
    std::string t = rng() % 2 ? "G21 G90 G17 F200\nG0 X-30 Y-30 Z1\nG41 D1\n" : "G21 G90 G17 F200\nG0 X-30 Y-30 Z1\nG42 D1\n";
    std::uint64_t line = 4;
    std::map<std::uint64_t, std::array<double, 4>> segs;  // programmed lines after the start-up, by line
    std::map<std::uint64_t, std::uint64_t> before;         // the XY line before each
    double x = uni(-5, 5), y = uni(-5, 5);
    char buf[200];
    std::snprintf(buf, sizeof buf, "G1 X%.8f Y%.8f\n", x, y);
    t += buf;
    std::uint64_t prev = line++;
    const int n = 6 + static_cast<int>(rng() % 8);
    for (int i = 0; i < n; ++i) {
      const double len = uni(12, 30), dir = uni(0, 2 * std::acos(-1.0));
      const double nx = x + len * std::cos(dir), ny = y + len * std::sin(dir);
      const int kind = lines_only ? static_cast<int>(rng() % 3) : static_cast<int>(rng() % 5);
      if (kind == 2) t += "G1 Z" + std::to_string(uni(-3, 0)) + "\n", ++line;
      if (kind <= 2) {
        std::snprintf(buf, sizeof buf, "G%d X%.8f Y%.8f\n", kind == 0 ? 0 : 1, nx, ny);
        segs[line] = {x, y, nx, ny};
      } else {
        const double h = uni(-1, 1) * len;
        const double cx = (x + nx) / 2 - h * std::sin(dir), cy = (y + ny) / 2 + h * std::cos(dir);
        std::snprintf(buf, sizeof buf, "G%d X%.8f Y%.8f I%.8f J%.8f\n", kind == 3 ? 2 : 3, nx, ny, cx - x, cy - y);
      }
      t += buf;
      before[line] = prev;
      prev = line++;
      x = nx;
      y = ny;
    }
    t += "G40 G1 X-30 Y30\nG0 Z5\nM30\n";
    SCOPED_TRACE(t);
    Parsed p = parse_text(t);
    expect_continuous(p);
    if (!lines_only || p.summary.lines_rejected != 0) continue;
    for (const auto& b : p.blocks) {
      if (segs.count(b.line) == 0 || (b.motion != Motion::kLinear && b.motion != Motion::kRapid)) continue;
      const double ex = b.target[kX] - b.work_origin[kX], ey = b.target[kY] - b.work_origin[kY];
      double d = 1e9;
      for (std::uint64_t l : {b.line, before[b.line]}) {
        if (segs.count(l) == 0) continue;
        const auto& s = segs[l];
        const double vx = s[2] - s[0], vy = s[3] - s[1];
        const double u = std::clamp(((ex - s[0]) * vx + (ey - s[1]) * vy) / (vx * vx + vy * vy), 0.0, 1.0);
        d = std::min(d, std::hypot(ex - s[0] - u * vx, ey - s[1] - u * vy));
      }
      ++checked;
      EXPECT_GE(d, 5 - 1e-6) << "line " << b.line << " ends at " << ex << " " << ey;
    }
  }
  EXPECT_GT(checked, 300u);
}

namespace {

// The plunges of canned-cycle holes (the feed moves down to the bottom), in program coordinates.
std::vector<Axes> plunges(const Parsed& p, double bottom) {
  std::vector<Axes> out;
  for (const Axes& e : ends(p))
    if (std::fabs(e[kZ] - bottom) < 1e-9) out.push_back(e);
  return out;
}

// Notes of lines the program does not run, by line number.
std::map<std::uint64_t, std::string> notes(const Parsed& p) {
  std::map<std::uint64_t, std::string> out;
  for (const auto& d : p.diags)
    if (d.severity == Severity::kNote) out[d.line] = d.message;
  return out;
}

void expect_counts_add_up(const Parsed& p) {
  EXPECT_EQ(p.summary.lines_read, p.summary.blocks_emitted + p.summary.lines_rejected + p.summary.lines_deleted);
}

}  // namespace

// Bug: @ ^ in a canned-cycle block were read as X0 Y0 (holes up to 101.6 mm out of place).
// Expected holes worked by hand (r cos a, r sin a) and checked against rs274's output.
TEST(ParseRound2, PolarWordsPlaceCannedCycleHoles) {
  Parsed p = parse_text("G21 G90 G17 F100\nG0 X0 Y0 Z5\nG81 @10 ^60 Z-2 R1\n@20 ^90\n^0\nG80\n", linuxcnc());
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  const auto holes = plunges(p, -2);
  ASSERT_EQ(holes.size(), 3u);
  const double want[3][2] = {{5, 10 * std::sqrt(3.0) / 2}, {0, 20}, {20, 0}};  // ^0 keeps @20
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR(holes[i][kX], want[i][0], 1e-9) << "hole " << i;
    EXPECT_NEAR(holes[i][kY], want[i][1], 1e-9) << "hole " << i;
  }
  // G91 L6: each repeat adds the distance and the angle again (rs274: a bolt circle from ^60 L6).
  Parsed circle = parse_text("G21 G90 G17 F100\nG55 G0 X10 Y0 Z5\nG91 G81 ^60 Z-2 R-4 L6\nG90 G80\n", linuxcnc());
  ASSERT_EQ(circle.first_error(), nullptr) << format(*circle.first_error());
  const auto bolt = plunges(circle, -1);
  ASSERT_EQ(bolt.size(), 6u);
  for (std::size_t i = 0; i < 6; ++i) {
    const double a = 60.0 * static_cast<double>(i + 1) * std::numbers::pi / 180;
    EXPECT_NEAR(bolt[i][kX], 10 * std::cos(a), 1e-9) << "hole " << i;
    EXPECT_NEAR(bolt[i][kY], 10 * std::sin(a), 1e-9) << "hole " << i;
  }
  // G91 @1 ^60 L3 from X10: the spiral rs274 drills, distance 11, 12, 13 at 60, 120, 180 deg.
  Parsed spiral = parse_text("G21 G90 G17 F100\nG0 X10 Y0 Z5\nG91 G81 @1 ^60 Z-2 R-4 L3\n", linuxcnc());
  const auto s = plunges(spiral, -1);
  ASSERT_EQ(s.size(), 3u);
  EXPECT_NEAR(s[0][kX], 5.5, 1e-9);
  EXPECT_NEAR(s[1][kY], 12 * std::sin(std::numbers::pi * 2 / 3), 1e-9);
  EXPECT_NEAR(s[2][kX], -13, 1e-9);
  expect_error("G81 @1 X1 Z-1 R1 F100\n", "polar coordinates (@ ^) and X", 8, linuxcnc());
  expect_error("G18 G81 X1 Y-1 Z1 R1 F100\nG17 G80\nG18 G81 @1 ^0\n", "in the G17 plane only", 9, linuxcnc());
  expect_error("G0 X0 Y0\nG91 G0 @1 ^30\n", "with the tool at the origin", 8, linuxcnc());
}

// Bug: #<name> was global, so a recursive subroutine's `#<level>` was the innermost call's in
// every caller (X0 X0 X0 where rs274 moves X0 X1 X2). LinuxCNC: a name without a leading '_' is
// local to the call that sets it (the main program has its own); #<_name> is global.
TEST(ParseRound2, NamedParametersAreLocalToEachCall) {
  Parsed rec = parse_text("o100 sub\n#<level> = #1\no1 if [#1 gt 0]\no100 call [#1 - 1]\no1 endif\nG0 X#<level>\n"
                          "o100 endsub\no100 call [2]\n",
                          linuxcnc());
  ASSERT_EQ(rec.first_error(), nullptr) << format(*rec.first_error());
  ASSERT_EQ(ends(rec).size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_DOUBLE_EQ(ends(rec)[i][kX], static_cast<double>(i));
  // Ten levels deep with a local counter and a global one: X10..X1 on the way down, Y0..Y10 on
  // the way up, and #<_calls> counts all eleven calls.
  Parsed deep = parse_text("#<_calls> = 0\no<r> sub\n#<n> = #1\n#<_calls> = [#<_calls> + 1]\no1 if [#<n> gt 0]\n"
                           "G0 X#<n>\no<r> call [#<n> - 1]\no1 endif\nG0 Y#<n>\no<r> endsub\no<r> call [10]\nG0 Z#<_calls>\n",
                           linuxcnc());
  ASSERT_EQ(deep.first_error(), nullptr) << format(*deep.first_error());
  const auto d = ends(deep);
  ASSERT_EQ(d.size(), 10u + 11 + 1);
  for (std::size_t i = 0; i < 10; ++i) EXPECT_DOUBLE_EQ(d[i][kX], 10.0 - static_cast<double>(i));
  for (std::size_t i = 0; i < 11; ++i) EXPECT_DOUBLE_EQ(d[10 + i][kY], static_cast<double>(i));
  EXPECT_DOUBLE_EQ(d.back()[kZ], 11);
  // The main program's names are its own; a callee's vanish when it returns; _names are shared.
  Parsed scope = parse_text("#<a> = 5\n#<_h> = 4\n#31 = 9\no100 sub\n#<b> = 7\n#31 = 8\n#<a> = 6\nG0 X#<a> Y#<_h>\n"
                            "#<_h> = 1\no100 endsub\no100 call\nG0 X#<a> Y#<_h> Z#31\nG0 Y#<b>\n",
                            linuxcnc());
  const auto e = ends(scope);
  ASSERT_EQ(e.size(), 2u);
  EXPECT_DOUBLE_EQ(e[0][kX], 6);
  EXPECT_DOUBLE_EQ(e[0][kY], 4);
  EXPECT_DOUBLE_EQ(e[1][kX], 5);  // the caller's #<a> again
  EXPECT_DOUBLE_EQ(e[1][kY], 1);  // #<_h> set in the call
  EXPECT_DOUBLE_EQ(e[1][kZ], 8);  // #31 is global
  ASSERT_NE(scope.first_error(), nullptr);
  EXPECT_EQ(scope.first_error()->line, 13u);
  EXPECT_NE(scope.first_error()->message.find("#<b> is used before it is set"), std::string::npos);
  EXPECT_NE(scope.first_error()->message.find("local to the subroutine call"), std::string::npos);
  // A subroutine does not see its caller's local names either (rs274: "not defined").
  expect_error("#<a> = 1\no<s> sub\nG0 X#<a>\no<s> endsub\no<s> call\n", "#<a> is used before it is set", 5,
               linuxcnc());
}

// Bug: lines after M2, M30 or a closing '%' ran (`G1 X150` after `M30 %` added 9.4 s of machine
// time). rs274 reads nothing after the end; gcpipe reads each line and notes it as not run.
TEST(ParseRound2, NothingRunsAfterTheProgramEnd) {
  Parsed p = parse_text("G0 X1\nM30\n%\nG1 X150 F100\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  ASSERT_EQ(ends(p).size(), 1u);
  EXPECT_TRUE(p.blocks.back().percent);  // the tape's closing '%' is still written
  EXPECT_EQ(notes(p)[4], "not run: after the program end (M30 at line 2)");
  EXPECT_EQ(p.summary.lines_not_run, 1u);
  expect_counts_add_up(p);
  EXPECT_EQ(p.summary.lines_read, 4u);
  // The '%' that closes a tape opened by '%' ends the program without M2.
  Parsed tape = parse_text("%\nG0 X1\n%\nG0 X2\n", linuxcnc());
  ASSERT_EQ(ends(tape).size(), 1u);
  EXPECT_EQ(notes(tape)[4], "not run: after the program end (% at line 3)");
  expect_counts_add_up(tape);
  // M2 in a subroutine ends the program: the call and the caller do not go on.
  Parsed sub = parse_text("o<s> sub\nG0 X1\nM2\nG0 X5\no<s> endsub\no<s> call\nG0 X9\n", linuxcnc());
  ASSERT_EQ(sub.first_error(), nullptr) << format(*sub.first_error());
  ASSERT_EQ(ends(sub).size(), 1u);
  EXPECT_EQ(notes(sub)[7], "not run: after the program end (M2 at line 3)");
  expect_counts_add_up(sub);
  // M2 in a loop: the loop stops; its end and the lines after are not run, and no error says
  // the loop was left open.
  Parsed loop = parse_text("o1 repeat [3]\nG0 X1\nM2\no1 endrepeat\nG0 X2\n", linuxcnc());
  ASSERT_EQ(loop.first_error(), nullptr) << format(*loop.first_error());
  ASSERT_EQ(ends(loop).size(), 1u);
  EXPECT_EQ(notes(loop).size(), 2u);
  expect_counts_add_up(loop);
  // LinuxCNC: a call before M2 reaches a definition after it (rs274 searches the file forward).
  Parsed later = parse_text("o100 call\nG0 Y1\nM2\no100 sub\nG0 X1\no100 endsub\nG0 Z9\n", linuxcnc());
  ASSERT_EQ(later.first_error(), nullptr) << format(*later.first_error());
  const auto l = ends(later);
  ASSERT_EQ(l.size(), 2u);
  EXPECT_DOUBLE_EQ(l[0][kX], 1);
  EXPECT_DOUBLE_EQ(l[1][kY], 1);
  EXPECT_NE(notes(later)[5].find("part of the definition of subroutine o100"), std::string::npos);
  EXPECT_EQ(notes(later)[7], "not run: after the program end (M2 at line 3)");
  expect_counts_add_up(later);
  // ...but not past the tape's closing '%' (rs274: "Failed to find sub 'Olate' before EOF").
  Parsed closed = parse_text("%\no<late> call\n%\no<late> sub\nG0 X1\no<late> endsub\n", linuxcnc());
  ASSERT_NE(closed.first_error(), nullptr);
  EXPECT_NE(closed.first_error()->message.find("no subroutine o<late> is defined"), std::string::npos);
  EXPECT_TRUE(ends(closed).empty());
  EXPECT_EQ(notes(closed)[4], "not run: after the program end (% at line 3)");
  expect_counts_add_up(closed);
}

// Fanuc subprograms written after M30 are still found and called (M98); the other lines after
// M30 are not run.
TEST(ParseRound2, FanucSubprogramsAfterM30AreCalledAndOtherLinesNotRun) {
  Parsed p = parse_text("%\nO0001\nG90 G0 X0 Y0\nM98 P2000\nG0 X1\nM30\nG1 X150 F100\nO2000\nG0 Y5\nM99\nG0 Z7\n%\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  const auto e = ends(p);
  ASSERT_EQ(e.size(), 3u);
  EXPECT_DOUBLE_EQ(e[1][kY], 5);  // the subprogram
  EXPECT_DOUBLE_EQ(e[2][kX], 1);
  const auto n = notes(p);
  EXPECT_EQ(n.at(7), "not run: after the program end (M30 at line 6)");
  EXPECT_NE(n.at(8).find("part of the definition of subroutine O2000"), std::string::npos);
  EXPECT_EQ(n.at(11), "not run: after the program end (M30 at line 6)");
  EXPECT_TRUE(p.blocks.back().percent);
  EXPECT_EQ(p.summary.lines_not_run, 5u);
  expect_counts_add_up(p);
}

// Found by the round-2 differential programs: in a series of cycles (no G80 between) rs274
// measures a G91 R from the level the series began at, and G98 returns there, also after a
// G99 block left the tool at R. By hand from Z5: R1 (G99, the tool stays at Z1); then G91 R-6
// is 5 - 6 = -1 (not 1 - 6) and the bottom -1 - 1 = -2; then G98 returns to 5, not to the -1
// the block started at. rs274 moves exactly these 12 end points.
TEST(ParseRound2, LinuxCncCycleSeriesMeasuresFromTheLevelItBeganAt) {
  Parsed p = parse_text("G21 G90 G17 F100\nG0 X0 Y0 Z5\nG99 G81 X0 Y0 Z-2 R1\nG91 G81 X1 Z-1 R-6\n"
                        "G90 G98 G81 X3 Z-3 R-2\nG80\n",
                        linuxcnc());
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  std::vector<double> z;
  for (const Axes& e : ends(p)) z.push_back(e[kZ]);
  const std::vector<double> want = {5, 1, -2, 1, 1, -1, -2, -1, -1, -2, -3, 5};
  ASSERT_EQ(z.size(), want.size());
  for (std::size_t i = 0; i < z.size(); ++i) EXPECT_NEAR(z[i], want[i], 1e-12) << "move " << i;
}

// Issue 32 item 2: programs a control runs must not be rejected.
// `G04 P.001 G0 X1.0 Y1.0` (a real program): rs274 prints DWELL(0.0010) and then
// STRAIGHT_TRAVERSE(1, 1, ...): its order of execution dwells before it moves. The dwell goes
// out first as a block of its own on the same line, with the comment and tool change; on Fanuc,
// where X is the dwell time, axis words with G04 stay an error.
TEST(ParseAccept, LinuxCncDwellAndMoveInOneBlockDwellFirst) {
  Parsed p = parse_text("G21 G90 F100\nT1 M6 G04 P.001 G0 X1.0 Y1.0 (dwell, then move)\nX2\n", linuxcnc());
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  ASSERT_EQ(p.blocks.size(), 4u);
  const ResolvedBlock& d = p.blocks[1];
  const ResolvedBlock& m = p.blocks[2];
  EXPECT_EQ(d.line, 2u);
  EXPECT_EQ(d.motion, Motion::kDwell);
  EXPECT_DOUBLE_EQ(d.dwell, 0.001);
  EXPECT_DOUBLE_EQ(d.target[kX], 0);  // it dwells where the tool stands
  EXPECT_TRUE(d.tool_change);
  EXPECT_EQ(d.comment, "dwell, then move");
  EXPECT_EQ(m.line, 2u);
  EXPECT_EQ(m.motion, Motion::kRapid);
  EXPECT_DOUBLE_EQ(m.target[kX], 1);
  EXPECT_DOUBLE_EQ(m.target[kY], 1);
  EXPECT_FALSE(m.tool_change);
  EXPECT_TRUE(m.comment.empty());
  EXPECT_EQ(p.blocks[3].motion, Motion::kRapid);  // the G0 of the dwell block stays in force
  EXPECT_EQ(p.summary.blocks_emitted, 3u);
  expect_error("G0 G4 P1 Y5\n", "a dwell block cannot move", 10);  // Fanuc: unchanged
  expect_error("G21 F100 T1 M6\nG41 D1\nG1 X20 Y20\nG4 P1 X30\n", "under cutter radius compensation", 1, linuxcnc());
  expect_error("G0 Z5\nG81 X1 Y1 Z-1 R1 F100\nG4 P1 X2\n", "canned cycle is in force", 1, linuxcnc());
  expect_error("G2 X2 Y0 I1 J0 F100\nG4 P1 X0\n", "both use P", 1, linuxcnc());
  // The move that leaves compensation is plain: its dwell comes where the held move ended (the
  // tool radius 5 above Y0), as rs274 has it (Rs274Diff: comp_dwell_with_the_exit_move).
  Parsed exit = parse_text("G21 F100 T1 M6\nG0 X-20 Y-20\nG41 D1\nG1 X0 Y0\nG1 X20 Y0\nG40\nG4 P1 G1 X30 Y-10\n", linuxcnc());
  ASSERT_EQ(exit.first_error(), nullptr) << format(*exit.first_error());
  const ResolvedBlock& dw = exit.blocks[exit.blocks.size() - 2];
  EXPECT_EQ(dw.motion, Motion::kDwell);
  EXPECT_NEAR(dw.target[kX], 20, 1e-9);
  EXPECT_NEAR(dw.target[kY], 5, 1e-9);
  EXPECT_EQ(exit.blocks.back().motion, Motion::kLinear);
  EXPECT_NEAR(exit.blocks.back().start[kY], 5, 1e-9);
}

// A real Fanuc program: `G80` then `N992 Z.2`. Fanuc 0i-MF: canned cycles and G80 are group 09,
// G00..G03 group 01; G80 cancels the cycle and group 01 stays as it was before the cycle, so Z.2
// is a move in that mode. It was rejected ("axis word Z without a motion mode").
TEST(ParseAccept, FanucAxisWordsAfterG80MoveInTheMotionModeBeforeTheCycle) {
  Parsed p = parse_text("G21 G90 G17\nG00 X0 Y0 Z5\nG81 X1 Y1 Z-1 R1 F100\nX2\nG80\nN992 Z.2\n"
                        "G01 Z3\nG83 X3 Z-2 R1 Q0.5\nG80\nX4\nG80\nY5\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  auto line = [&](std::uint64_t n) {
    const ResolvedBlock* found = nullptr;
    for (const ResolvedBlock& b : p.blocks)
      if (b.line == n) found = &b;
    return found;
  };
  ASSERT_NE(line(6), nullptr);
  EXPECT_EQ(line(6)->motion, Motion::kRapid);  // G00 was in force before G81
  EXPECT_DOUBLE_EQ(line(6)->target[kZ], 0.2);
  EXPECT_DOUBLE_EQ(line(6)->target[kX], 2);
  ASSERT_NE(line(10), nullptr);
  EXPECT_EQ(line(10)->motion, Motion::kLinear);  // G01 before G83
  EXPECT_DOUBLE_EQ(line(10)->target[kX], 4);
  ASSERT_NE(line(12), nullptr);
  EXPECT_EQ(line(12)->motion, Motion::kLinear);  // G80 without a cycle leaves group 01 alone
  EXPECT_DOUBLE_EQ(line(12)->target[kY], 5);
  // The cycle data are still cleared by G80: a new cycle needs its R and Z again.
  expect_error("G00 Z5\nG81 X1 Y1 Z-1 R1 F100\nG80\nG81 X2\n", "R", 1);
}

// A subprogram that calls one defined after itself (real programs, both forms). It was rejected
// ("O2000 is not defined in this file", "no subroutine o200 is defined"): only the main program
// waited for a later definition. Fanuc finds the O number anywhere in memory and rs274 searches
// the file forward from any level, so the call waits for the definition from inside a subprogram
// too. rs274 moves Y3, Z7, X5 on the LinuxCNC program (Rs274Diff: nested_call_defined_later).
TEST(ParseAccept, SubprogramCallsOneDefinedAfterItself) {
  Parsed f = parse_text("O1000\nG21 G90\nM98 P1500\nG0 X5\nM30\nO1500\nM98 P2000\nM99\nO2000\nG0 Y3\nM99\n");
  ASSERT_EQ(f.first_error(), nullptr) << format(*f.first_error());
  const auto fe = ends(f);
  ASSERT_EQ(fe.size(), 2u);
  EXPECT_DOUBLE_EQ(fe[0][kY], 3);  // O2000, called from O1500
  EXPECT_DOUBLE_EQ(fe[1][kX], 5);
  expect_counts_add_up(f);
  ParseOptions lc;
  lc.dialect = Dialect::kLinuxCnc;
  Parsed l = parse_text("G21 G90\no100 call\nG0 X5\nM2\no100 sub\nG0 Y3\no<later> call [7]\no100 endsub\n"
                        "o<later> sub\nG0 Z#1\no<later> endsub\n", lc);
  ASSERT_EQ(l.first_error(), nullptr) << format(*l.first_error());
  const auto le = ends(l);
  ASSERT_EQ(le.size(), 3u);
  EXPECT_DOUBLE_EQ(le[0][kY], 3);
  EXPECT_DOUBLE_EQ(le[1][kZ], 7);
  EXPECT_DOUBLE_EQ(le[2][kX], 5);
  expect_counts_add_up(l);
  // Still an error where no definition comes, named at the call inside the subprogram.
  Parsed missing = parse_text("O1000\nM98 P1500\nM30\nO1500\nM98 P2000\nM99\n");
  ASSERT_NE(missing.first_error(), nullptr);
  EXPECT_NE(missing.first_error()->message.find("O2000 is not defined in this file"), std::string::npos);
  // A LinuxCNC definition after the tape's closing '%' stays out of reach, from any level.
  Parsed closed = parse_text("%\no100 call\nM2\no100 sub\no200 call\no100 endsub\n%\no200 sub\nG0 Z7\no200 endsub\n", lc);
  ASSERT_NE(closed.first_error(), nullptr);
  EXPECT_EQ(closed.first_error()->line, 5u);
  EXPECT_TRUE(ends(closed).empty());
}

// A real program loads a tool the machine file's table lacks: `T4 M6 F300`. The T word was an
// error, which rejected the whole line (its F too) and then every G1 after it ("without a
// feed"). A control loads any tool number; only the tool's geometry needs the table. So T4 is a
// warning (once per tool), and the error comes where the length or diameter is used, naming the
// tool and the way out (the table, or --tool-table).
TEST(ParseAccept, ToolNotInTheTableIsAWarningUntilItsGeometryIsUsed) {
  Parsed p = parse_text("G21 G90\nT4 M6 F300\nG1 X10\nG1 Y5\nT4 M6\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  ASSERT_EQ(p.diags.size(), 1u);  // the second T4 says nothing new
  const Diagnostic& w = p.diags[0];
  EXPECT_EQ(w.severity, Severity::kWarning);
  EXPECT_EQ(w.line, 2u);
  EXPECT_EQ(w.column, 1u);
  EXPECT_NE(w.message.find("tool 4 is not in the machine config's tool table"), std::string::npos) << w.message;
  EXPECT_NE(w.message.find("--tool-table"), std::string::npos) << w.message;
  ASSERT_EQ(p.blocks.size(), 5u);
  EXPECT_EQ(p.blocks[1].tool, 4);
  EXPECT_TRUE(p.blocks[1].tool_change);
  EXPECT_DOUBLE_EQ(p.blocks[2].feed, 300);  // the F beside T4 M6 is in force
  EXPECT_DOUBLE_EQ(p.blocks[3].target[kY], 5);
  EXPECT_EQ(p.summary.lines_rejected, 0u);
  EXPECT_EQ(p.summary.blocks_emitted, 5u);
  // Where its geometry is used: an error naming the tool and what to do.
  expect_error("T4 M6\nG43 H4\n", "H4: tool 4 is not in the machine config's tool table (machine 'tools'), so its length is unknown", 5);
  expect_error("T4 M6\nG43\n", "--tool-table", 1);
  expect_error("T4 M6 F100\nG41 D4\n", "G41: tool 4 is not in the machine config's tool table (machine 'tools'), so its diameter", 5);
  expect_error("T4 M6\nG41\n", "--tool-table", 1);
  expect_error("T4 M6\nG1 F800 X0\nG275 X10 Z-1 R5 W12 K1\n", "tool 4 is not in the machine config's tool table", 1);
  // A warned line that is rejected for another reason says only its error.
  Parsed bad = parse_text("T5 M6 G2 X1\n");
  ASSERT_EQ(bad.diags.size(), 1u);
  EXPECT_EQ(bad.diags[0].severity, Severity::kError);
}

// Issue 32 item 2: LinuxCNC's predefined parameters (the modal ones are compared with rs274 in
// tests/rs274_diff_test.cpp). #<_task> is 1 as in the running control, where rs274 alone reads 0:
// a program that tests it to skip work in a preview does that work here, as the machine would.
TEST(ParseAccept, LinuxCncTaskParameterReadsAsTheRunningControl) {
  ParseOptions o;
  o.dialect = Dialect::kLinuxCnc;
  Parsed p = parse_text("G21 G90\nG0 X#<_task> Y#5599\nG0 Z[#5420 + 2]\n", o);
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  ASSERT_EQ(p.blocks.size(), 3u);
  EXPECT_DOUBLE_EQ(p.blocks[1].target[kX], 1.0);
  EXPECT_DOUBLE_EQ(p.blocks[1].target[kY], 1.0) << "#5599 is 1 until a program sets it";
  EXPECT_DOUBLE_EQ(p.blocks[2].target[kZ], 3.0) << "#5420 is the X position";
  // The loaded tool's data is not modelled: an error, never a silent 0.
  expect_error("G0 X#5410\n", "parameter #5410 (LinuxCNC's data of the loaded tool) is not modelled", 5, o);
  // Fanuc keeps its own system variables: #5599 is none of them.
  expect_error("G0 X#5599\n", "system variable #5599 is not modelled", 5);
}

// Issue 32 item 2: K on a G17 arc, as Grbl ignores it and FreeCAD posts write it: an error by
// default (LinuxCNC's rule), ignored with a warning on every line that has it when the leniency is on.
TEST(ParseAccept, ArcNormalWordIsIgnoredOnlyWhenAskedAndEveryUseIsReported) {
  const std::string text = "G21 G90 G17\nG1 X0 Y0 F100\nG2 X10 Y0 I5 J0 K0\nG3 X0 Y0 I-5 J0 K0.5\n";
  expect_error(text, "K0 in a G2 block in the XY (G17) plane", 17);
  ParseOptions lenient;
  lenient.ignore_arc_normal_word = true;
  Parsed p = parse_text(text, lenient);
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  ASSERT_EQ(p.diags.size(), 2u) << "one warning per line that has the word";
  for (const Diagnostic& d : p.diags) {
    EXPECT_EQ(d.severity, Severity::kWarning);
    EXPECT_NE(d.message.find("ignored, as Grbl does (parse.ignore_arc_normal_word)"), std::string::npos) << d.message;
  }
  EXPECT_EQ(p.diags[0].line, 3u);
  EXPECT_EQ(p.diags[1].message.substr(0, 4), "K0.5");
  const Parsed plain = parse_text("G21 G90 G17\nG1 X0 Y0 F100\nG2 X10 Y0 I5 J0\nG3 X0 Y0 I-5 J0\n");
  ASSERT_EQ(p.blocks.size(), plain.blocks.size());
  for (std::size_t i = 0; i < p.blocks.size(); ++i)
    for (int a = 0; a < kNumAxes; ++a) EXPECT_NEAR(p.blocks[i].target[a], plain.blocks[i].target[a], 1e-12);
  EXPECT_NEAR(p.blocks[2].centre[kX], 5.0, 1e-12);
}

// Issue 32 item 2: LinuxCNC's M61 Q sets the tool in the spindle without a change (compared with
// rs274 in tests/rs274_diff_test.cpp); a tool the table lacks is a warning, as T is; Fanuc has
// no M61. G10 L2 R0 rotates by nothing and is accepted; any other R stays an error; G10 L11
// names what it lacks.
TEST(ParseAccept, M61AndG10WithoutRotation) {
  ParseOptions o;
  o.dialect = Dialect::kLinuxCnc;
  Parsed p = parse_text("G21 G90\nT1 M6\nM61 Q2\nG43\nG0 Z1\nM61 Q7\n", o);
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  ASSERT_EQ(p.blocks.size(), 6u);
  EXPECT_EQ(p.blocks[2].tool_in_spindle, 2);
  EXPECT_FALSE(p.blocks[2].tool_change) << "M61 changes no tool";
  EXPECT_DOUBLE_EQ(p.blocks[3].tool_length, test_machine().tools.at(2).length);
  ASSERT_EQ(p.diags.size(), 1u);
  EXPECT_EQ(p.diags[0].severity, Severity::kWarning);
  EXPECT_EQ(p.diags[0].line, 6u);
  expect_error("M61\n", "M61 needs Q", 1, o);
  expect_error("M61 Q1.5\n", "Q is a tool number", 5, o);
  expect_error("M61 Q2\n", "M61 is not a supported M code", 1);
  Parsed r0 = parse_text("G21 G90\nG10 L2 P1 X5 R0\nG0 X1\n", o);
  ASSERT_EQ(r0.first_error(), nullptr) << format(*r0.first_error());
  EXPECT_DOUBLE_EQ(r0.blocks[2].target[kX], 6.0);
  expect_error("G10 L2 P1 R5\n", "G10 with R5: a rotated coordinate system (LinuxCNC) is not supported (R0, no rotation, is)", 11, o);
  expect_error("G10 L20 P1 R0 X1\n", "R is not allowed in G10 L20", 12, o);
  expect_error("G10 L11 P1 Z0\n", "G10 L11 sets a tool entry measured in G59.3's coordinates", 5, o);
}

// Issue 32 item 2, Fanuc 0i-MF rigid tapping: M29 S before G84 (or G74) puts the tap under the
// control's spindle, so no M3/M4 need come before it; the path is G84's (in at F, the spindle
// reversed at the bottom, out at F). G80 (or a group 01 code) ends rigid mode. LinuxCNC has no M29.
TEST(ParseAccept, FanucRigidTappingNeedsNoSpindleDirectionBeforeIt) {
  const std::string text = "G21 G90 G17 G94\nG0 X0 Y0 Z10\nM29 S500\nG99 G84 X10 Y10 Z-10 R2 F625\nX20\nG80\n";
  Parsed p = parse_text(text);
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  std::vector<double> z;
  for (const ResolvedBlock& b : p.blocks)
    if (b.line == 4 && b.motion == Motion::kLinear) z.push_back(b.target[kZ]);
  EXPECT_EQ(z, (std::vector<double>{-10.0, 2.0})) << "in to the bottom and out to R at the feed";
  expect_error("G21 G90 G17 G94\nG0 X0 Y0 Z10\nS500\nG99 G84 X10 Y10 Z-10 R2 F625\n",
               "G84 (right-hand tapping) needs the spindle turning clockwise (M3)", 5);
  expect_error("G21 G90 G17 G94\nM29 S500\nG80\nG84 X10 Y10 Z-10 R2 F625\n", "needs the spindle turning clockwise", 1);
  ParseOptions o;
  o.dialect = Dialect::kLinuxCnc;
  expect_error("M29 S500\n", "M29 is not a supported M code", 1, o);
}

// Issue 32 item 2, LinuxCNC G33.1 (compared with rs274 in tests/rs274_diff_test.cpp): in at
// F = K x S, the spindle reversed, out to where it began; what gcpipe does not run says why.
TEST(ParseAccept, LinuxCncRigidTappingAndWhatItRefuses) {
  ParseOptions o;
  o.dialect = Dialect::kLinuxCnc;
  Parsed p = parse_text("G21 G90\nM3 S400\nG0 X5 Y5 Z2\nG33.1 Z-10 K1.5\n", o);
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  ASSERT_EQ(p.blocks.size(), 5u);
  EXPECT_DOUBLE_EQ(p.blocks[3].target[kZ], -10.0);
  EXPECT_DOUBLE_EQ(p.blocks[3].feed, 600.0) << "1.5 mm per revolution at 400 rev/min";
  EXPECT_EQ(p.blocks[3].spindle, Spindle::kCW);
  EXPECT_DOUBLE_EQ(p.blocks[4].target[kZ], 2.0);
  EXPECT_EQ(p.blocks[4].spindle, Spindle::kCCW) << "the tap comes out with the spindle reversed";
  expect_error("M3 S400\nG33.1 Z-10\n", "G33.1 needs K", 1, o);
  expect_error("M3 S400\nG33.1 X1 Z-10 K1\n", "gcpipe taps along Z only", 1, o);
  expect_error("G33.1 Z-10 K1\n", "G33.1 needs the spindle turning", 1, o);
  expect_error("M3 S400\nG33.1 Z-10 K1\nZ-12\n", "", 1, o);  // no motion mode after it: not a silent move
  expect_error("M3 S400\nG33.1 Z-10 K1\n", "G33.1 (threading) is not supported", 1);
}
