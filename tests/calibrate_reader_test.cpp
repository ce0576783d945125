// Trace readers: every kind of bad input is rejected with file:line:col and the reason; with
// skip_bad_rows the usable rest is kept and what was dropped is counted. And the real UMich
// traces (where the shared data folder is present).
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <sstream>

#include "calibrate_test_util.hpp"
#include "measured_trace.hpp"

namespace gcpipe::calibrate {
namespace {

const char* kHeader = "t,X_cmd,Y_cmd,Z_cmd,A_cmd,C_cmd,X,Y,Z,A,C\n";

std::string rows(int n, double t0 = 0) {
  std::ostringstream s;
  for (int i = 0; i < n; ++i) s << t0 + 0.001 * i << ",1,2,3,0,0,1,2,3,0,0\n";
  return s.str();
}

ReadResult read(const std::string& text, bool skip = false, std::size_t min_rows = 5) {
  std::istringstream in(text);
  ReadOptions o;
  o.skip_bad_rows = skip;
  o.min_rows = min_rows;
  return read_trace(in, "t.csv", o);
}

std::string first(const ReadResult& r) { return r.diagnostics.empty() ? "" : format(r.diagnostics.front()); }

TEST(CalibrateReader, ReadsTheSharedCsvWithOptionalTorqueAndUnits) {
  auto r = read(std::string(kHeader) + rows(10));
  ASSERT_TRUE(r.trace) << first(r);
  EXPECT_EQ(r.trace->size(), 10u);
  EXPECT_NEAR(r.trace->period, 0.001, 1e-12);
  EXPECT_EQ(r.trace->actual[kZ][3], 3);
  r = read("t[s],X_cmd[mm],Y_cmd[mm],Z_cmd[mm],A_cmd[deg],C_cmd[deg],X[mm],Y[mm],Z[mm],A[deg],C[deg],Y_torque[N*m]\n"
           "0,1,2,3,0,0,1,2,3,0,0,5.5\n0.001,1,2,3,0,0,1,2,3,0,0,6\n0.002,1,2,3,0,0,1,2,3,0,0,6\n0.003,1,2,3,0,0,1,2,3,0,0,6\n0.004,1,2,3,0,0,1,2,3,0,0,6\n");
  ASSERT_TRUE(r.trace) << first(r);
  EXPECT_EQ(r.trace->effort_kind[kY], "torque");
  EXPECT_EQ(r.trace->effort[kY][0], 5.5);
}

TEST(CalibrateReader, EveryBadInputSaysWhereAndWhy) {
  EXPECT_EQ(first(read("time,X_cmd\n" + rows(10))),
            "t.csv:1:1: error: unknown header: column 1 is 'time', expected 't' (shared trace CSV t,X_cmd,...,C_cmd,X,...,C; or pass --format)");
  EXPECT_EQ(first(read("t[s],X_cmd,Y_cmd,Z_cmd,A_cmd,C_cmd,X,Y,Z,A,C\n" + rows(10))),
            "t.csv:1:6: error: units missing for column 'X_cmd': the header gives units for some columns; give [mm] here too");
  EXPECT_EQ(first(read("t[s],X_cmd[in],Y_cmd[mm],Z_cmd[mm],A_cmd[deg],C_cmd[deg],X[mm],Y[mm],Z[mm],A[deg],C[deg]\n" + rows(10))),
            "t.csv:1:6: error: column 'X_cmd' is in 'in'; convert it to mm");
  EXPECT_EQ(first(read(std::string(kHeader) + rows(3) + "0.003,1,2,x3,0,0,1,2,3,0,0\n" + rows(5, 0.004))),
            "t.csv:5:11: error: column 'Z_cmd' 'x3' is not a number");
  EXPECT_EQ(first(read(std::string(kHeader) + rows(3) + "0.003,1,2,3,0,0,1,nan,3,0,0\n" + rows(5, 0.004))),
            "t.csv:5:19: error: column 'Y' 'nan' is not finite");
  EXPECT_EQ(first(read(std::string(kHeader) + rows(3) + "0.003,1,2,3\n" + rows(5, 0.004))),
            "t.csv:5:12: error: row has 4 of 11 columns (truncated?)");
  EXPECT_EQ(first(read(std::string(kHeader) + rows(3) + "0.001,1,2,3,0,0,1,2,3,0,0\n" + rows(5, 0.004))),
            "t.csv:5:1: error: time 0.001000 s does not increase (previous 0.002000 s)");
  EXPECT_EQ(first(read(std::string(kHeader) + rows(5) + rows(5, 0.05))),
            "t.csv:7:1: error: gap of 0.046000 s before this row (period 0.001000 s): samples are missing");
  EXPECT_EQ(first(read(std::string(kHeader) + rows(3), false, 200)),
            "t.csv:4:1: error: only 3 usable rows; the fit needs at least 200 (record a longer trace)");
  EXPECT_FALSE(read(std::string(kHeader) + rows(3) + "0.003,1,2,3\n" + rows(5, 0.004)).trace);
}

TEST(CalibrateReader, SkipBadRowsKeepsTheUsableRestAndCountsIt) {
  // One bad row in the middle: dropped and counted; the time gap it leaves splits the trace and
  // the longest gap-free stretch is used.
  const auto r = read(std::string(kHeader) + rows(6) + "0.006,1,2,3,0,0,1,2,oops,0,0\n" + rows(10, 0.007) + rows(3, 0.1), true);
  ASSERT_TRUE(r.trace) << first(r);
  EXPECT_EQ(r.trace->rows_skipped, 1u);
  EXPECT_EQ(r.trace->size(), 10u);
  EXPECT_EQ(r.trace->rows_unused, 9u);
  EXPECT_EQ(r.trace->lines_read, 20u);
}

TEST(CalibrateReader, UmichTracesReadWithVelocitiesAndCurrents) {
  const std::filesystem::path p = std::filesystem::path(GCPIPE_SHARED_DATA) / "traces/umich_smart_cnc_mill/experiment_01.csv";
  if (!std::filesystem::exists(p)) GTEST_SKIP() << "shared data absent: " << p;
  const auto r = read_trace_file(p, ReadOptions{});
  ASSERT_TRUE(r.trace) << first(r);
  EXPECT_EQ(r.trace->format, TraceFormat::kUmichCsv);
  EXPECT_NEAR(r.trace->period, 0.1, 1e-12);
  EXPECT_EQ(r.trace->size(), 1055u);
  EXPECT_EQ(r.trace->effort_kind[kX], "current");
  EXPECT_EQ(r.trace->actual_velocity[kY].size(), 1055u);
  EXPECT_EQ(r.trace->actual[kX][0], 198.0);
}

// --- LinuxCNC halsampler: no header, the column map from the user ---------------------------

/// halsampler -t output: sample number, then X_cmd X Y_cmd Y as the cfg string "ffff" ordered them.
std::string hal_rows(int n, int n0 = 0) {
  std::ostringstream s;
  for (int i = 0; i < n; ++i) s << n0 + i << " " << 0.01 * (n0 + i) << " " << 0.01 * (n0 + i) - 0.001 << " 2 2.0005\n";
  return s.str();
}

ReadResult read_hal(const std::string& text, std::vector<std::string> columns, double period, bool skip = false) {
  std::istringstream in(text);
  ReadOptions o;
  o.skip_bad_rows = skip;
  o.min_rows = 5;
  o.columns = std::move(columns);
  o.period = period;
  return read_trace(in, "h.txt", o);
}

const std::vector<std::string> kHalColumns = {"n", "X_cmd", "X", "Y_cmd", "Y"};

TEST(CalibrateReader, HalsamplerWithSampleNumbersAndAPeriod) {
  const auto r = read_hal(hal_rows(10), kHalColumns, 0.001);
  ASSERT_TRUE(r.trace) << first(r);
  EXPECT_EQ(r.trace->format, TraceFormat::kHalsampler);  // detected: a line of numbers
  EXPECT_EQ(r.trace->size(), 10u);
  EXPECT_NEAR(r.trace->period, 0.001, 1e-12);
  EXPECT_NEAR(r.trace->t[3], 0.003, 1e-12);
  EXPECT_NEAR(r.trace->command[kX][4], 0.04, 1e-12);
  EXPECT_NEAR(r.trace->actual[kY][4], 2.0005, 1e-12);
  EXPECT_EQ(r.trace->command[kZ].size(), 10u);  // axes the map lacks are held at zero
  EXPECT_EQ(r.trace->actual[kC][9], 0.0);
}

TEST(CalibrateReader, HalsamplerWithATimeColumnAndIgnoredPins) {
  std::ostringstream s;
  for (int i = 0; i < 8; ++i) s << 0.002 * i << "\t1 " << 0.1 * i << " " << 0.1 * i << " -3\n";
  const auto r = read_hal(s.str(), {"t", "-", "Z_cmd", "Z", "Z_current"}, 0);
  ASSERT_TRUE(r.trace) << first(r);
  EXPECT_NEAR(r.trace->period, 0.002, 1e-12);
  EXPECT_NEAR(r.trace->actual[kZ][5], 0.5, 1e-12);
  EXPECT_EQ(r.trace->effort_kind[kZ], "current");
  EXPECT_EQ(r.trace->effort[kZ][7], -3.0);
}

TEST(CalibrateReader, HalsamplerBadInputSaysWhereAndWhy) {
  EXPECT_EQ(first(read_hal(hal_rows(10), {}, 0.001)),
            "h.txt:1:1: error: halsampler columns: halsampler output has no header; give the pin of every column with "
            "--columns, e.g. --columns n,X_cmd,X,Y_cmd,Y --period 0.001");
  EXPECT_EQ(first(read_hal(hal_rows(10), {"n", "X_cmd", "X", "Y_cmd", "Y_pos"}, 0.001)),
            "h.txt:1:1: error: halsampler columns: 'Y_pos' is not one of n, t, X_cmd..C_cmd, X..C, <axis>_torque, <axis>_current or -");
  EXPECT_EQ(first(read_hal(hal_rows(10), {"n", "X_cmd", "X", "Y_cmd", "-"}, 0.001)),
            "h.txt:1:1: error: halsampler columns: column Y_cmd has no actual column Y");
  EXPECT_EQ(first(read_hal(hal_rows(10), kHalColumns, 0)),
            "h.txt:1:1: error: halsampler columns: without a t column the time is n x period: give --period (the sampler thread's period, s)");
  EXPECT_EQ(first(read_hal(hal_rows(3) + "3 0.03 0.029 2 2.0x05\n" + hal_rows(5, 4), kHalColumns, 0.001)),
            "h.txt:4:19: error: column 'Y' '2.0x05' is not a number");
  EXPECT_EQ(first(read_hal(hal_rows(3) + "3 0.03 inf 2 2.0005\n" + hal_rows(5, 4), kHalColumns, 0.001)),
            "h.txt:4:8: error: column 'X' 'inf' is not finite");
  EXPECT_EQ(first(read_hal(hal_rows(3) + "3 0.03 0.029\n" + hal_rows(5, 4), kHalColumns, 0.001)),
            "h.txt:4:13: error: row has 3 of 5 columns (truncated?)");
  EXPECT_EQ(first(read_hal(hal_rows(3) + "3 0.03 0.029 2 2.0005 7\n" + hal_rows(5, 4), kHalColumns, 0.001)),
            "h.txt:4:23: error: row has more than 5 columns");
  EXPECT_EQ(first(read_hal(hal_rows(4) + hal_rows(5, 2), kHalColumns, 0.001)),
            "h.txt:5:1: error: time 0.002000 s does not increase (previous 0.003000 s)");
  // An overrun of the sampler's FIFO: sample numbers jump, which is a gap.
  EXPECT_EQ(first(read_hal(hal_rows(5) + hal_rows(5, 40), kHalColumns, 0.001)),
            "h.txt:6:1: error: gap of 0.036000 s before this row (period 0.001000 s): samples are missing");
  EXPECT_EQ(first(read_hal(hal_rows(3), kHalColumns, 0.001)),
            "h.txt:3:1: error: only 3 usable rows; the fit needs at least 5 (record a longer trace)");
}

TEST(CalibrateReader, HalsamplerSkipBadRowsCountsThem) {
  const auto r = read_hal(hal_rows(6) + "6 0.06 oops 2 2\n" + hal_rows(10, 7), kHalColumns, 0.001, true);
  ASSERT_TRUE(r.trace) << first(r);
  EXPECT_EQ(r.trace->rows_skipped, 1u);
  EXPECT_EQ(r.trace->size(), 10u);  // the dropped row leaves a gap: the longer stretch is used
  EXPECT_EQ(r.trace->rows_unused, 6u);
}

// --- MTConnect SHDR: records on change, one row per adapter cycle ----------------------------

/// An SHDR stream of X (actual, commanded) at 10 ms cycles; Y only in the first cycle (on change,
/// so it keeps its value).
std::string shdr_stream(int cycles, int first_cycle = 0) {
  std::ostringstream s;
  for (int i = first_cycle; i < first_cycle + cycles; ++i) {
    char ts[64];
    std::snprintf(ts, sizeof ts, "2016-05-13T17:24:%02d.%06dZ", 10 + i / 100, (i % 100) * 10000);
    s << ts << "|Xcommanded|" << 0.1 * i << "\n" << ts << "|Xposition|" << 0.1 * i - 0.01 << "\n";
    if (i == first_cycle) s << ts << "|Ycommanded|5\n" << ts << "|Yposition|5.002\n" << ts << "|execution|ACTIVE\n";
  }
  return s.str();
}

ReadResult read_shdr_text(const std::string& text, std::vector<std::string> columns = {}, bool skip = false) {
  std::istringstream in(text);
  ReadOptions o;
  o.skip_bad_rows = skip;
  o.min_rows = 5;
  o.columns = std::move(columns);
  return read_trace(in, "s.shdr", o);
}

TEST(CalibrateReader, ShdrRowsPerCycleWithHeldValues) {
  const auto r = read_shdr_text(shdr_stream(10));
  ASSERT_TRUE(r.trace) << first(r);
  EXPECT_EQ(r.trace->format, TraceFormat::kShdr);  // detected from the first record
  EXPECT_EQ(r.trace->size(), 10u);
  // Epoch seconds in a double resolve 0.24 us in 2016: far below any control's period.
  EXPECT_NEAR(r.trace->period, 0.01, 1e-6);
  EXPECT_NEAR(r.trace->t[9], 0.09, 1e-6);  // from the first row, not the epoch
  EXPECT_NEAR(r.trace->command[kX][7], 0.7, 1e-12);
  EXPECT_NEAR(r.trace->actual[kX][7], 0.69, 1e-12);
  EXPECT_NEAR(r.trace->actual[kY][9], 5.002, 1e-12);  // sent once, held
}

TEST(CalibrateReader, ShdrItemMapRenamesItems) {
  std::string text = shdr_stream(10);
  for (auto [from, to] : {std::pair{"|Xcommanded|", "|Xcom|"}, std::pair{"|Xposition|", "|Xact|"}})
    for (auto p = text.find(from); p != std::string::npos; p = text.find(from)) text.replace(p, std::strlen(from), to);
  EXPECT_FALSE(read_shdr_text(text).trace);
  const auto r = read_shdr_text(text, {"X_cmd=Xcom", "X=Xact"});
  ASSERT_TRUE(r.trace) << first(r);
  EXPECT_NEAR(r.trace->actual[kX][3], 0.29, 1e-12);
}

TEST(CalibrateReader, ShdrBadInputSaysWhereAndWhy) {
  // Actual positions only (as in the NIST GF Agie stream): nothing to calibrate against.
  std::string actual_only;
  std::istringstream all(shdr_stream(10));
  for (std::string l; std::getline(all, l);)
    if (l.find("commanded") == std::string::npos) actual_only += l + "\n";
  EXPECT_EQ(first(read_shdr_text(actual_only)),
            "s.shdr:1:1: error: no commanded positions in the SHDR stream (none of Xcommanded, Ycommanded, Zcommanded, "
            "Acommanded, Ccommanded occurs): without commands there is no residual to calibrate; if the adapter names "
            "them otherwise, map them with --columns X_cmd=ITEM,...");
  EXPECT_EQ(first(read_shdr_text(shdr_stream(10), {"X_cmd"})),
            "s.shdr:1:1: error: SHDR columns: 'X_cmd' is not QUANTITY=ITEM with QUANTITY one of X_cmd..C_cmd, X..C, <axis>_torque, <axis>_current");
  const std::string base = shdr_stream(3);
  EXPECT_EQ(first(read_shdr_text(base + "2016-05-13T17:24:10.030000Z|Xposition|0.2x9\n" + shdr_stream(5, 4))),
            "s.shdr:10:42: error: item 'Xposition' '0.2x9' is not a number");
  EXPECT_EQ(first(read_shdr_text(base + "2016-05-13T17:24:10.030000Z|Xposition|-inf\n" + shdr_stream(5, 4))),
            "s.shdr:10:39: error: item 'Xposition' '-inf' is not finite");
  EXPECT_EQ(first(read_shdr_text(base + "2016-05-13T17:24:10.03|Xposition\n" + shdr_stream(5, 4))),
            "s.shdr:10:1: error: not an SHDR record: expected YYYY-MM-DDThh:mm:ss[.f]Z|item|value");
  EXPECT_EQ(first(read_shdr_text(shdr_stream(5) + shdr_stream(5, 2))),
            "s.shdr:14:1: error: time 0.020000 s does not increase (previous 0.040000 s)");
  EXPECT_EQ(first(read_shdr_text(shdr_stream(5) + shdr_stream(5, 40))),
            "s.shdr:14:1: error: gap of 0.360000 s before this row (period 0.010000 s): samples are missing");
  EXPECT_EQ(first(read_shdr_text(shdr_stream(3))),
            "s.shdr:9:1: error: only 3 usable rows; the fit needs at least 5 (record a longer trace)");
}

TEST(CalibrateReader, ShdrSkipBadRowsCountsThem) {
  const auto r = read_shdr_text(shdr_stream(6) + "garbage\n" + shdr_stream(10, 6), {}, true);
  ASSERT_TRUE(r.trace) << first(r);
  EXPECT_EQ(r.trace->rows_skipped, 1u);
  EXPECT_EQ(r.trace->size(), 16u);  // a line that is no record drops no cycle
}

TEST(CalibrateReader, FormatNamesRoundTrip) {
  for (auto f : {TraceFormat::kSharedCsv, TraceFormat::kUmichCsv, TraceFormat::kHalsampler, TraceFormat::kShdr})
    EXPECT_EQ(parse_format(format_name(f)), f);
  EXPECT_FALSE(parse_format("xml"));
}

// The NIST GF Agie stream: actual X Y Z A C only, on change at ~6 Hz. The reader says why it
// cannot be calibrated, and with the actual channel mapped as a stand-in command (to see what
// rows it gives) the sampling shows the gaps.
TEST(CalibrateReader, NistShdrHasNoCommandsToCalibrateAgainst) {
  const std::filesystem::path p = std::filesystem::path(GCPIPE_SHARED_DATA) / "traces/nist_gfagie01_xyzac/GFAgie01-20160513-20160514.txt";
  if (!std::filesystem::exists(p)) GTEST_SKIP() << "shared data absent: " << p;
  auto r = read_trace_file(p, ReadOptions{});
  EXPECT_FALSE(r.trace);
  ASSERT_FALSE(r.diagnostics.empty());
  EXPECT_NE(format(r.diagnostics.back()).find("no commanded positions in the SHDR stream"), std::string::npos)
      << format(r.diagnostics.back());
  ReadOptions o;
  o.columns = {"X_cmd=Xposition", "Y_cmd=Yposition", "Z_cmd=Zposition", "A_cmd=Aposition", "C_cmd=Cposition"};
  o.skip_bad_rows = true;
  r = read_trace_file(p, o);
  ASSERT_TRUE(r.trace) << (r.diagnostics.empty() ? "" : format(r.diagnostics.front()));
  std::printf("NIST SHDR, actual positions as stand-in commands: %zu rows in the longest gap-free stretch, period %.3f s, "
              "%llu rows outside it, %llu lines\n", r.trace->size(), r.trace->period,
              static_cast<unsigned long long>(r.trace->rows_unused), static_cast<unsigned long long>(r.trace->lines_read));
  EXPECT_GT(r.trace->period, 0.1);  // on change at ~6-7 Hz: no servo dynamics resolved
  EXPECT_GT(r.trace->rows_unused, r.trace->size());  // idle spells send nothing: mostly gaps
}

}  // namespace
}  // namespace gcpipe::calibrate

#include "umich.hpp"

namespace gcpipe::calibrate {
namespace {

TEST(CalibrateUmich, FitOnFourExperimentsPredictTheOtherTwo) {
  std::vector<MeasuredTrace> all = test::umich_experiments();
  if (all.empty()) GTEST_SKIP() << "shared data absent: " << GCPIPE_SHARED_DATA << "/traces/umich_smart_cnc_mill";
  ASSERT_EQ(all.size(), 6u);
  std::vector<MeasuredTrace> fit(all.begin(), all.begin() + 4), pred(all.begin() + 4, all.end());
  const auto res = umich_analysis(fit, pred);
  for (int a = 0; a < 3; ++a) {
    const auto& x = res[static_cast<std::size_t>(a)];
    std::printf("UMich %c: velocity gain %.4f delay %.1f s, rms %.3f -> %.3f mm/s; current Fc %.3f +- %.3f A, Fv %.5f +- %.5f A s/mm, "
                "Ka %.6f A s^2/mm, I0 %.3f A, rms %.3f -> %.3f A (%zu fit, %zu predicted samples)\n",
                "XYZ"[a], x.gain, x.delay_s, x.v_rms_before, x.v_rms_after, x.current[0], x.current_sigma[0], x.current[1],
                x.current_sigma[1], x.current[2], x.current[3], x.i_rms_before, x.i_rms_after, x.fit_samples, x.predict_samples);
    // At 100 ms the actual velocity follows the command with no visible lag and unit gain: the
    // servo dynamics are far faster than the sampling, so the velocity model adds nothing.
    EXPECT_NEAR(x.gain, 1, 0.02) << "XYZ"[a];
    EXPECT_EQ(x.delay_s, 0) << "XYZ"[a];
    EXPECT_NEAR(x.v_rms_after, x.v_rms_before, 0.01 * x.v_rms_before) << "XYZ"[a];
    // The currents carry the friction: Coulomb + viscous + inertia predicts the unseen
    // experiments' X and Y currents to less than half the rms of a constant. Z's current
    // column is all zero in this data set.
    if (a < 2) {
      EXPECT_LT(x.i_rms_after, 0.5 * x.i_rms_before) << "XYZ"[a];
      EXPECT_GT(x.current[0], 10 * x.current_sigma[0]) << "XYZ"[a];
    } else {
      EXPECT_EQ(x.i_rms_before, 0);
    }
  }
}

}  // namespace
}  // namespace gcpipe::calibrate
