// Trace readers: every kind of bad input is rejected with file:line:col and the reason; with
// skip_bad_rows the usable rest is kept and what was dropped is counted. And the real UMich
// traces (where the shared data folder is present).
#include <gtest/gtest.h>

#include <filesystem>
#include <sstream>

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

}  // namespace
}  // namespace gcpipe::calibrate

#include "umich.hpp"

namespace gcpipe::calibrate {
namespace {

TEST(CalibrateUmich, FitOnFourExperimentsPredictTheOtherTwo) {
  const std::filesystem::path dir = std::filesystem::path(GCPIPE_SHARED_DATA) / "traces/umich_smart_cnc_mill";
  if (!std::filesystem::exists(dir)) GTEST_SKIP() << "shared data absent: " << dir;
  std::vector<MeasuredTrace> fit, pred;
  for (int i = 1; i <= 6; ++i) {
    ReadOptions o;
    o.skip_bad_rows = true;
    auto r = read_trace_file(dir / ("experiment_0" + std::to_string(i) + ".csv"), o);
    ASSERT_TRUE(r.trace) << i;
    (i <= 4 ? fit : pred).push_back(std::move(*r.trace));
  }
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
