// The write stage: parse(write(parse(p))) == parse(p) block for block.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <random>

#include "parse_helpers.hpp"
#include "write.hpp"

using namespace gcpipe;
using namespace gcpipe::test;

namespace {

// "Equal" for a round trip: discrete fields identical, numbers within 1e-9 relative to max(1, |v|),
// i.e. 1 nm on a part of 1 m. Exact equality is not possible for arc centres: IJK are offsets from
// the start, and start + (centre - start) need not give back the same double.
constexpr double kTol = 1e-9;

// A straight move that ends where it starts: `G91 G28 Z0` at the reference position already
// (a post's first line) is written as a bare `G0`, which moves nothing either.
bool standing_still(const ResolvedBlock& b) {
  return (b.motion == Motion::kRapid || b.motion == Motion::kLinear) && b.start == b.target;
}

// The blocks that make the machine do something; state is compared inside each of them.
std::vector<ResolvedBlock> active(const Parsed& p) {
  std::vector<ResolvedBlock> out;
  for (const auto& b : p.blocks)
    if ((b.motion != Motion::kNone && !standing_still(b)) || b.stop != ProgramStop::kNone || b.tool_change) out.push_back(b);
  return out;
}

std::string write_all(const Parsed& p, WriteOptions wo) {
  Writer w(wo);
  std::string out;
  // Blocks and diagnostics in the order the parser handed them out, as the batch loop sees them.
  std::size_t i = 0, j = 0;
  for (bool is_block : p.order) {
    if (is_block) w.write(p.blocks[i++], out);
    else w.write_diagnostic(p.diags[j++], out);
  }
  return out;
}

void expect_round_trip_of(const Parsed& first, ParseOptions reparse, WriteOptions wo, double tol,
                          const std::string& what) {
  const std::string text = write_all(first, wo);
  Parsed second = parse_text(text, reparse, test_machine(), "written.nc");
  ASSERT_EQ(second.first_error(), nullptr) << what << ": the written program does not parse: "
                                           << format(*second.first_error());
  auto a = active(first), b = active(second);
  ASSERT_EQ(a.size(), b.size()) << what;
  for (std::size_t k = 0; k < a.size(); ++k) {
    std::string why;
    ASSERT_TRUE(same_meaning(a[k], b[k], tol, &why))
        << what << ": source line " << a[k].line << " '" << a[k].text << "' written as line "
        << b[k].line << " '" << b[k].text << "': " << why;
    if (!wo.source_frames) continue;
    // In the source's frames the program's own origin and its G28/G30/G53 read back too.
    for (int ax = 0; ax < kNumAxes; ++ax)
      ASSERT_NEAR(a[k].frame.origin[ax], b[k].frame.origin[ax], tol * std::max(1.0, std::fabs(a[k].frame.origin[ax])))
          << what << ": origin of source line " << a[k].line << " '" << a[k].text << "' written as '" << b[k].text << "'";
    const bool placed = a[k].frame.code == FrameCode::kHome || a[k].frame.code == FrameCode::kHome2 ||
                        a[k].frame.code == FrameCode::kMachine;
    if (placed && !(a[k].frame.code == FrameCode::kMachine && a[k].motion == Motion::kLinear && wo.dialect == Dialect::kFanuc))
      ASSERT_EQ(a[k].frame.code, b[k].frame.code) << what << ": source line " << a[k].line << " '" << a[k].text
                                                  << "' written as '" << b[k].text << "'";
  }
}

// Both ways of writing: in the source's frames (output.nc) and in the machine file's
// (compensated.nc's way): each reads back to the same blocks.
void expect_round_trip(const Parsed& first, ParseOptions reparse, WriteOptions wo, double tol, const std::string& what) {
  for (bool source_frames : {true, false}) {
    wo.source_frames = source_frames;
    expect_round_trip_of(first, reparse, wo, tol, what + (source_frames ? ", source frames" : ", machine file frame"));
  }
}

// Written for each dialect and read back with that dialect.
void expect_round_trip_in_both_dialects(const Parsed& first) {
  for (Dialect d : {Dialect::kLinuxCnc, Dialect::kFanuc}) {
    WriteOptions wo;
    wo.dialect = d;
    ParseOptions back;
    back.dialect = d;
    expect_round_trip(first, back, wo, kTol, d == Dialect::kFanuc ? "fanuc" : "linuxcnc");
  }
}

}  // namespace

TEST(WriteRoundTrip, EveryProgramUnderSharedData) {
  auto programs = shared_programs();
  if (programs.empty()) GTEST_SKIP() << shared_data() << " is absent: real programs not round-tripped";
  for (const auto& path : programs) {
    SCOPED_TRACE(path.string());
    const ParseOptions po = options_for(path);
    Parsed first = parse_text(read_file(path), po, test_machine(), path.string());
    WriteOptions same;
    same.dialect = po.dialect;
    ParseOptions back;  // the written program is plain mm, incremental centres
    back.dialect = po.dialect;
    expect_round_trip(first, back, same, kTol, "same dialect");
    // Across dialects: LinuxCNC in, Fanuc out (and back) keeps the meaning too.
    WriteOptions other;
    other.dialect = po.dialect == Dialect::kFanuc ? Dialect::kLinuxCnc : Dialect::kFanuc;
    ParseOptions back_other;
    back_other.dialect = other.dialect;
    expect_round_trip(first, back_other, other, kTol, "other dialect");
  }
}

// Issue 14: what the parser expands (cycles, G28, calls, loops) is written as plain moves, which
// read back to the same blocks in either dialect.
TEST(WriteRoundTrip, ExpandedCyclesCallsAndLoopsBecomePlainMoves) {
  const std::string program =
      "o<hole> sub\n  G81 X#1 Y#2 Z-3 R1\n  G80\no<hole> endsub\n"
      "G21 G90 G17 F250 S1200 M3\nG0 X0 Y0 Z10\n#1 = 0\no1 while [#1 lt 3]\n  o<hole> call [#1 * 10] [5]\n"
      "  #1 = [#1 + 1]\no1 endwhile\nG98 G83 X40 Y5 Z-8 R2 Q2.5\nG82 X50 Z-2 R2 P0.5\nG86 X60 Z-2 R2 P0.25\n"
      "G80\nG91 G28 Z0\nG90 G53 G0 X10\nG92 X0\nG0 X5\nG92.1\nG10 L2 P1 X3 Y-2\nG0 X1 Y1\nM2\n";
  ParseOptions lc;
  lc.dialect = Dialect::kLinuxCnc;
  Parsed first = parse_text(program, lc);
  ASSERT_EQ(first.first_error(), nullptr) << format(*first.first_error());
  ASSERT_GT(first.summary.blocks_out, first.summary.blocks_emitted + 20);
  expect_round_trip_in_both_dialects(first);
}

TEST(WriteRoundTrip, ShippedSamples) {
  int n = 0;
  for (const auto& e : std::filesystem::directory_iterator(std::filesystem::path(GCPIPE_SOURCE_DIR) / "samples")) {
    if (e.path().extension() != ".nc") continue;
    SCOPED_TRACE(e.path().string());
    Parsed first = parse_text(read_file(e.path()), {}, test_machine(), e.path().string());
    EXPECT_EQ(first.first_error(), nullptr) << format(*first.first_error());
    expect_round_trip(first, {}, {}, kTol, "sample");
    ++n;
  }
  EXPECT_GE(n, 1);
}

TEST(WriteRoundTrip, FixedDecimalsStayWithinHalfAnIncrement) {
  Parsed first = parse_text("G1 X1.23456789 Y-0.00004 F100\nG2 X3 Y0 I0.88271605 J-1.23456789\n");
  ASSERT_EQ(first.first_error(), nullptr) << format(*first.first_error());
  WriteOptions wo;
  wo.decimals = 4;
  const std::string text = write_all(first, wo);
  EXPECT_NE(text.find("X1.2346"), std::string::npos) << text;
  Parsed second = parse_text(text);
  // The arc written with 4 decimals must still pass the radius check and land within 5e-5 mm.
  ASSERT_EQ(second.first_error(), nullptr) << text;
  auto a = active(first), b = active(second);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k)
    for (int ax = 0; ax < kNumAxes; ++ax) EXPECT_NEAR(a[k].target[ax], b[k].target[ax], 5e-5);
}

TEST(WriteFormat, HeaderLineNumbersCommentsAndRejectedLines) {
  Parsed p = parse_text("%\nO12 (DEMO)\n(setup)\nG20 G0 X1 ; inch\nG0 B5\n/G0 X9\nM30\n%\n");
  const std::string out = write_all(p, {});
  EXPECT_EQ(out,
            "%\n"
            "O12 (DEMO)\n"
            "G17 G21 G40 G49 G54 G80 G90 G94\n"
            "(setup)\n"
            "N4 G20 G0 X1. (inch)\n"
            "(gcpipe: line 5 rejected: unknown word 'B5': this machine has axes X Y Z A C only [no B axis])\n"
            "(gcpipe: line 6: skipped by block delete ['/' with parse.block_delete on])\n"
            "N7 M30\n"
            "%\n");
}

// The path mode and tolerance go out where they change, so the control that runs output.nc blends
// or stops as the source asked (and blends within the G64 P the compensation planned to).
TEST(WriteRoundTrip, PathModeAndTolerance) {
  Parsed p = parse_text("G21 G64 P0.005 G1 X1 F100\nG1 X2\nG61 X3\nG61.1 X4\nG64 X5\nG20 G64 P0.001 X1\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  const std::string out = write_all(p, {});
  EXPECT_NE(out.find("G64 P0.005 G1"), std::string::npos) << out;
  EXPECT_NE(out.find("N2 X2."), std::string::npos) << out;  // modal: not repeated
  EXPECT_NE(out.find("G61 X3."), std::string::npos) << out;
  EXPECT_NE(out.find("G61.1 X4."), std::string::npos) << out;
  EXPECT_NE(out.find("G64 X5."), std::string::npos) << out;
  EXPECT_NE(out.find("G64 P0.001"), std::string::npos) << out;  // in the block's inches
  expect_round_trip_in_both_dialects(p);
}

// A G09 block (Fanuc) is written as G61 on its line and the mode in force again on the next: the
// same stop in both dialects, since LinuxCNC has no G9.
TEST(WriteRoundTrip, G09IsWrittenAsG61ForItsBlock) {
  Parsed p = parse_text("G21 G64 P0.02 G1 X1 F100\nG09 X2\nX3\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  const std::string out = write_all(p, {});
  EXPECT_NE(out.find("G61 X2."), std::string::npos) << out;
  EXPECT_NE(out.find("G64 P0.02 X3."), std::string::npos) << out;
  expect_round_trip_in_both_dialects(p);
}

// Seeded random programs: every combination of modes the generator can draw must round-trip.
// GCPIPE_ROUNDTRIP_PROGRAMS sets how many (default 200).
TEST(WriteRoundTrip, SeededRandomPrograms) {
  const char* env = std::getenv("GCPIPE_ROUNDTRIP_PROGRAMS");
  const int programs = env ? std::atoi(env) : 200;
  for (int seed = 1; seed <= programs; ++seed) {
    std::mt19937_64 rng(static_cast<std::uint64_t>(seed));
    std::uniform_real_distribution<double> pos(-200, 200), ang(-120, 10), unit(0, 1);
    std::uniform_int_distribution<int> pick(0, 15);
    std::string prog = "%\nO" + std::to_string(seed) + "\n";
    bool inch = false, incremental = false;
    double x = 0, y = 0;  // current XY in program units (for consistent arcs)
    for (int i = 0; i < 60; ++i) {
      char buf[200];
      switch (pick(rng)) {
        case 0: prog += inch ? "G21\n" : "G20\n"; inch = !inch; x = y = 0; prog += "G90 G0 X0 Y0\n"; incremental = false; break;
        case 1: prog += incremental ? "G90\n" : "G91\n"; incremental = !incremental; break;
        case 2: prog += "T" + std::to_string(1 + pick(rng) % 2) + " M6 S" + std::to_string(1000 + 100 * pick(rng)) + (unit(rng) < 0.5 ? " M3" : " M4") + "\n"; break;
        case 3: prog += unit(rng) < 0.5 ? "G43 H1\n" : (unit(rng) < 0.5 ? "G43.4 H2\n" : "G49\n"); break;
        case 4: prog += unit(rng) < 0.3 ? "M7\n" : unit(rng) < 0.5 ? "M8\n" : "M9\n"; break;
        case 5: prog += unit(rng) < 0.5 ? "G55\n" : "G54\n"; break;
        case 6: std::snprintf(buf, sizeof buf, "G4 P%d\n", pick(rng) * 100); prog += buf; break;
        case 7: prog += unit(rng) < 0.5 ? "G93\n" : "G94\n"; break;
        default: {
          const double nx = pos(rng), ny = pos(rng);
          const double dx = incremental ? nx - x : nx, dy = incremental ? ny - y : ny;
          const int kind = pick(rng) % 4;
          if (kind < 2) {
            std::snprintf(buf, sizeof buf, "G%d X%.4f Y%.4f Z%.3f A%.3f C%.3f F%.1f (move %d)\n", kind, dx, dy,
                          incremental ? unit(rng) : pos(rng) / 4, incremental ? 0.0 : ang(rng),
                          incremental ? 1.0 : 720 * unit(rng) - 360, 10 + 1000 * unit(rng), i);
            if (incremental) {
              x = nx;
              y = ny;
            } else {
              x = dx;
              y = dy;
            }
          } else {
            // An arc through a centre on the perpendicular bisector, so both radii agree exactly enough.
            const double mx = (x + nx) / 2, my = (y + ny) / 2, h = pos(rng) / 4;
            const double len = std::hypot(nx - x, ny - y) + 1e-9;
            const double cx = mx - h * (ny - y) / len, cy = my + h * (nx - x) / len;
            std::snprintf(buf, sizeof buf, "G17 G%d X%.6f Y%.6f I%.6f J%.6f F%.1f\n", kind, dx, dy, cx - x, cy - y,
                          10 + 1000 * unit(rng));
            x = nx;
            y = ny;
          }
          prog += buf;
        }
      }
    }
    prog += "M30\n%\n";
    Parsed first = parse_text(prog);
    ASSERT_TRUE(first.summary.lines_read > 0);
    expect_round_trip(first, {}, {}, kTol, "random program seed " + std::to_string(seed));
  }
}

// G43.5 programs (tool vector I J K): parse(write(parse(p))) keeps every vector and mode.
TEST(WriteRoundTrip, ToolVectorPrograms) {
  const std::string prog =
      "G43.5 H1\n"
      "G0 X10 Y0 Z5 I0 J0 K2\n"
      "G1 X20 F100\n"
      "G1 I3 J4\n"                      // a move made only of the vector
      "G1 I3 J4\n"                      // the same vector again: still a move
      "G91 G1 X1 I1 J1 K1\n"
      "G90 G2 X23 Y2 I1 J1\n"           // arc centre, vector unchanged
      "G43.5 H2\n"
      "G1 X30 Y5 I-0.1 J0.2 K0.97\n"
      "G43.4 H1\nG0 X0 A10 C20\n"
      "G43.5 H1\nG0 X1 I0.5 J-0.5 K0.7071\n"
      "G49\nG0 Z50\nM30\n";
  Parsed first = parse_text(prog);
  ASSERT_EQ(first.first_error(), nullptr) << format(*first.first_error());
  expect_round_trip(first, {}, {}, kTol, "tool-vector program, shortest numbers");
  // With 4 decimals for coordinates the vector still goes out exactly enough (12 places).
  WriteOptions four;
  four.decimals = 4;
  expect_round_trip(first, {}, four, kTol, "tool-vector program, 4 decimals");
  const std::string text = write_all(first, {});
  EXPECT_NE(text.find("G43.5 H1"), std::string::npos) << text;
  EXPECT_NE(text.find("I0.6 J0.8 K0"), std::string::npos) << text;
}

TEST(WriteRoundTrip, ToolVectorSampleAndSeededRandomPrograms) {
  Parsed sample = parse_text(read_file(std::filesystem::path(GCPIPE_SOURCE_DIR) / "samples" / "tool_vector_demo.nc"));
  ASSERT_EQ(sample.first_error(), nullptr) << format(*sample.first_error());
  expect_round_trip(sample, {}, {}, kTol, "tool_vector_demo.nc");
  for (int seed = 1; seed <= 100; ++seed) {
    std::mt19937_64 rng(static_cast<std::uint64_t>(seed));
    std::uniform_real_distribution<double> pos(-200, 200), comp(-1, 1), unit(0, 1);
    std::string prog = "G43.5 H1\nG0 X0 Y0 Z10 I0 J0 K1\n";
    bool in_mode = true;
    for (int i = 0; i < 40; ++i) {
      char buf[200];
      const double r = unit(rng);
      if (r < 0.08) {
        prog += in_mode ? (unit(rng) < 0.5 ? "G49\n" : "G43.4 H2\n") : "G43.5 H2\nG1 I0 J0 K1 F500\n";
        in_mode = !in_mode;
      } else if (r < 0.12) {
        prog += unit(rng) < 0.5 ? "G91\n" : "G90\n";
      } else if (in_mode) {
        const int words = static_cast<int>(unit(rng) * 4);  // 0: axes only, 1: vector only, else both
        std::string line = unit(rng) < 0.3 ? "G0" : "G1";
        if (words != 1) {
          std::snprintf(buf, sizeof buf, " X%.5f Y%.5f Z%.5f", pos(rng) / 10, pos(rng) / 10, pos(rng) / 40);
          line += buf;
        }
        if (words != 0) {
          std::snprintf(buf, sizeof buf, " I%.7f J%.7f K%.7f", comp(rng), comp(rng), 0.2 + unit(rng));
          line += buf;
        }
        std::snprintf(buf, sizeof buf, " F%.1f\n", 10 + 1000 * unit(rng));
        prog += line + buf;
      } else {
        std::snprintf(buf, sizeof buf, "G1 X%.4f A%.3f C%.3f F500\n", pos(rng) / 10, -30 * unit(rng), 360 * unit(rng));
        prog += buf;
      }
    }
    prog += "M30\n";
    Parsed first = parse_text(prog);
    ASSERT_EQ(first.first_error(), nullptr) << "seed " << seed << ": " << format(*first.first_error()) << "\n" << prog;
    expect_round_trip(first, {}, {}, kTol, "random tool-vector program seed " + std::to_string(seed));
  }
}

// LinuxCNC cannot say G43.5: the writer refuses those blocks with a line naming them, returns
// false and counts them; the blocks outside G43.5 are written and read back as before.
TEST(WriteFormat, LinuxcncDialectRefusesToolVectorBlocks) {
  Parsed p = parse_text("G43.4 H1\nG0 X1 A5 C10\nG43.5 H1\nG0 X2 I0 J0.1 K1\nG1 X3 F100\nG49\nG0 X4\n");
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  WriteOptions lc;
  lc.dialect = Dialect::kLinuxCnc;
  Writer w(lc);
  std::string out;
  std::vector<bool> written;
  for (const auto& b : p.blocks) written.push_back(w.write(b, out));
  EXPECT_EQ(written, (std::vector<bool>{true, true, false, false, false, true, true}));
  EXPECT_EQ(w.refused_blocks(), 3u);
  EXPECT_NE(out.find("(gcpipe: line 4 not written: G43.5 tool-vector TCP has no LinuxCNC equivalent"),
            std::string::npos) << out;
  EXPECT_EQ(out.find("G43.5"), out.find("G43.5 tool-vector"));  // only inside the comments
  ParseOptions lcp;
  lcp.dialect = Dialect::kLinuxCnc;
  Parsed back = parse_text(out, lcp);
  ASSERT_EQ(back.first_error(), nullptr) << format(*back.first_error()) << "\n" << out;
  const auto moves = active(back);
  ASSERT_EQ(moves.size(), 2u) << out;  // G0 X1 A5 C10 and G0 X4
  EXPECT_DOUBLE_EQ(moves[1].target[kX], 4);
  EXPECT_FALSE(moves[1].tcp);
}

// Cutter compensation (LinuxCNC dialect) is resolved in the parser: the tool-centre path is
// written as plain moves without G41/G42, and reads back to the same blocks in either dialect.
TEST(WriteRoundTrip, CutterCompensatedPathBecomesPlainMoves) {
  const std::string program =
      "G21 G90 G17 F300\nG0 X-30 Y-30 Z5\nG41 D1\nG1 X0 Y0\nG1 Z-2\nG1 X40 (concave next)\nG1 Y30\n"
      "G3 X20 Y50 R20\nG2 X0 Y30 R20\nG1 Y0.5\nM8\nG40\nG0 Z5\nG42.1 D6\nG0 X-10 Y-10\nG1 X10 Y10 Z-1\n"
      "G1 X30 Y10.5\nG40 G0 X40 Y0\nM2\n";
  ParseOptions lc;
  lc.dialect = Dialect::kLinuxCnc;
  Parsed first = parse_text(program, lc);
  ASSERT_EQ(first.first_error(), nullptr) << format(*first.first_error());
  ASSERT_GT(first.summary.blocks_out, first.summary.blocks_emitted);  // corner arcs
  expect_round_trip_in_both_dialects(first);
}

// The same for Fanuc cutter compensation C: start-up Type A, outer obtuse and acute corners (the
// extra corner moves), an inner corner, a tangent arc and an arc into an obtuse corner, a G0 under
// compensation, cancel Type A: written as plain moves, read back the same in either dialect.
TEST(WriteRoundTrip, FanucCutterCompensatedPathBecomesPlainMoves) {
  const std::string program =
      "G21 G90 G17 F300\nG0 X-30 Y-30 Z5\nG41 D1 G1 X0 Y0\nG1 Z-2\nG1 X40\nM8\nG1 Y30\nG3 X20 Y50 R20\n"
      "G1 X10 Y70\nG1 X5 Y40\nG0 X0 Y20\nG1 Y0.5\nG1 X-20 Y10 (acute)\nG40 G1 X-30 Y-30\nG0 Z5\nM30\n";
  Parsed first = parse_text(program);
  ASSERT_EQ(first.first_error(), nullptr) << format(*first.first_error());
  ASSERT_EQ(first.summary.blocks_out, first.summary.blocks_emitted + 2);  // arc->line obtuse, acute P1->P2
  expect_round_trip_in_both_dialects(first);
}

// ---- output.nc keeps the source's frames (issue 30) ----

namespace {

std::string write_output_nc(const std::string& program, Dialect dialect = Dialect::kFanuc) {
  ParseOptions po;
  po.dialect = dialect;
  const Parsed p = parse_text(program, po);
  EXPECT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  WriteOptions wo;
  wo.dialect = dialect;
  wo.source_frames = true;
  return write_all(p, wo);
}

}  // namespace

// A user's pocket ends with a retract to Z home. output.nc wrote `N46 Z0.`: the G28 resolved into
// a work coordinate, from the machine file's reference position (machine zero). The control must
// get the G28 itself, to go to its own reference position.
TEST(WriteSourceFrames, G28ReturnIsWrittenAsG28NotAsAWorkCoordinate) {
  const std::string out = write_output_nc(
      "G21 G90 G17\nT1 M6\nG54 G0 X-5. Y-5.\nG43 Z50. H1\nG1 Z-2. F300.\nG1 X50. F1500.\nG0 Z25.\nM5\n"
      "G91 G28 Z0\nG90\nM30\n");
  EXPECT_NE(out.find("N9 G91 G28 Z0.\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N10 G90\n"), std::string::npos) << out;
  EXPECT_EQ(out.find("N9 Z"), std::string::npos) << out;
  EXPECT_EQ(out.find("N9 G0 Z"), std::string::npos) << out;
}

// G10 L2 P1 Z-300 then G54: output.nc dropped the G10 and wrote machine coordinates (Z-250) under
// the header's G54; on a control whose G54 holds the fixture's offset that goes 300 mm lower.
TEST(WriteSourceFrames, G10WorkOffsetIsWrittenInPlaceAndMovesStayInWorkCoordinates) {
  const std::string out = write_output_nc("G10 L2 P1 Z-300\nG54\nG0 X10 Y10 Z50\n");
  EXPECT_NE(out.find("N1 G10 L2 P1 Z-300.\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N2 G54\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N3 G0 X10. Y10. Z50.\n"), std::string::npos) << out;
  EXPECT_EQ(out.find("Z-250"), std::string::npos) << out;
}

// The header states only what the output's own words rely on: no G54 and no G49 the source did
// not program (they would replace the system and the length the control has in force).
TEST(WriteSourceFrames, HeaderAssertsNoWorkSystemOrToolLength) {
  const std::string out = write_output_nc("G0 X1 Y2\nG55 G0 X3\nG43 H1 Z5\nG49\nG49 G0 Z6\n");
  EXPECT_EQ(out.rfind("G17 G21 G40 G80 G90 G94\n", 0), 0u) << out;
  EXPECT_NE(out.find("N1 G0 X1. Y2.\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N2 G55 X3.\n"), std::string::npos) << out;  // Y stays where the control has it
  EXPECT_NE(out.find("N3 G43 H1 Z5.\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N4 G49\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N5 G49 Z6.\n"), std::string::npos) << out;  // as programmed, if repeated
}

// G53 with its machine coordinates; G30 through its intermediate point; G92 and G52 with their
// words; G10 L20 and tool entries in place (LinuxCNC dialect).
TEST(WriteSourceFrames, MachineCoordinatesShiftsAndEntriesAreWrittenAsSuch) {
  const std::string out = write_output_nc(
      "G21 G90\nG55 G0 X1 Y1 Z1\nG53 G0 Z-10\nG1 G53 X-20 F100\nG30 X5 Y6\nG92 X0 Y0\nG0 X2\nG92.1\n"
      "G52 X3\nG52 X0\nG10 L20 P0 Z4\nG10 L1 P1 Z50 R3\nG43 H1\nG0 Z1\nG28\nM2\n",
      Dialect::kLinuxCnc);
  EXPECT_NE(out.find("N3 G53 Z-10.\n"), std::string::npos) << out;  // G0 modal already
  EXPECT_NE(out.find("N4 G53 G1 X-20. F100.\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N5 G30 X5. Y6.\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N6 G92 X0. Y0.\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N7 G0 X2.\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N8 G92.1\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N9 G52 X3.\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N11 G10 L20 P0 Z4.\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N12 G10 L1 P1 Z50. R3.\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N13 G43 H1\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N15 G28\n"), std::string::npos) << out;
}

// A G91 move from a position only the control knows (after G28, at the start) stays an
// increment; once an absolute position is written the output is absolute again.
TEST(WriteSourceFrames, IncrementsFromTheControlsPositionStayIncrements) {
  const std::string out = write_output_nc("G91 G0 X5\nG90 G0 X1 Y1 Z1\nG28 G91 Z0\nG1 Z-3 X2 F100\nG90 G1 Z0\n");
  EXPECT_NE(out.find("N1 G0 G91 X5.\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N2 G90 X1. Y1. Z1.\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N3 G91 G28 Z0.\n"), std::string::npos) << out;
  EXPECT_NE(out.find("N4 G1 X2. Z-3. F100.\n"), std::string::npos) << out;  // still G91: Z from home
  EXPECT_NE(out.find("N5 G90 Z0.\n"), std::string::npos) << out;
}

// Across dialects what one cannot say is written as the machine file resolves it, with a note.
TEST(WriteSourceFrames, WhatTheOtherDialectCannotSayIsResolvedWithANote) {
  ParseOptions lc;
  lc.dialect = Dialect::kLinuxCnc;
  const Parsed p = parse_text("G0 X1 Y1 Z1\nG10 L20 P1 X0\nG1 G53 Z-5 F100\nG10 L1 P1 Z50 R3\nM2\n", lc);
  ASSERT_EQ(p.first_error(), nullptr) << format(*p.first_error());
  WriteOptions fanuc;
  fanuc.source_frames = true;
  const std::string out = write_all(p, fanuc);
  EXPECT_NE(out.find("(gcpipe: line 2: G10 L20 cannot be said in this dialect"), std::string::npos) << out;
  EXPECT_NE(out.find("N2 G10 L2 P1 X1.\n"), std::string::npos) << out;
  EXPECT_NE(out.find("(gcpipe: line 3: G1 G53 has no Fanuc equivalent"), std::string::npos) << out;
  EXPECT_NE(out.find("G10 L12 P1 R3.\nN4 G10 L10 P1 R50.\n"), std::string::npos) << out;
  expect_round_trip_in_both_dialects(p);
}
