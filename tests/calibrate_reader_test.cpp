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
