// Trace CSV: exact round trip and a diagnostic with line:col for every kind of damage.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <sstream>

#include "trace.hpp"

using namespace gcpipe;

namespace {

std::vector<Diagnostic> errors_of(const std::string& text, std::size_t* rows = nullptr) {
  std::istringstream in(text);
  TraceReader r(in, "t.csv");
  TraceRow row;
  Diagnostic d;
  std::vector<Diagnostic> out;
  std::size_t n = 0;
  for (TraceStatus s; (s = r.next(row, d)) != TraceStatus::kEnd;) {
    if (s == TraceStatus::kError) out.push_back(d);
    else ++n;
  }
  if (rows) *rows = n;
  return out;
}

const std::string kGood = "0.001000,1,2,3,4,5,1.5,2,3,4,5";

}  // namespace

TEST(Trace, WritesTheExactHeaderAndRoundTripsEveryDouble) {
  std::ostringstream out;
  TraceWriter w(out);
  std::vector<TraceRow> rows;
  for (int k = 0; k < 100; ++k) {
    TraceRow r;
    r.t = k * 0.001;
    for (int i = 0; i < 5; ++i) {
      r.command[static_cast<std::size_t>(i)] = std::sin(k + i) * 123.456789 + 1e-9 * k;
      r.actual[static_cast<std::size_t>(i)] = r.command[static_cast<std::size_t>(i)] - 1.0 / 3.0 * 1e-3;
    }
    rows.push_back(r);
    w.row(r);
  }
  const std::string text = out.str();
  EXPECT_EQ(text.substr(0, text.find('\n')), "t,X_cmd,Y_cmd,Z_cmd,A_cmd,C_cmd,X,Y,Z,A,C");
  std::istringstream in(text);
  TraceReader r(in, "t.csv");
  TraceRow row;
  Diagnostic d;
  for (const auto& expected : rows) {
    ASSERT_EQ(r.next(row, d), TraceStatus::kRow) << format(d);
    EXPECT_NEAR(row.t, expected.t, 5e-7);
    EXPECT_EQ(row.command, expected.command);
    EXPECT_EQ(row.actual, expected.actual);
  }
  EXPECT_EQ(r.next(row, d), TraceStatus::kEnd);
}

// The formatter that reuses a repeated column's text writes the bytes of append_trace_row, row
// by row: columns that change, stay, return to an earlier value, equal their command (the text
// copied from it), 0 and -0, denormals, extremes.
TEST(Trace, RowFormatterWritesTheBytesOfAppendTraceRow) {
  std::mt19937_64 rng(3);
  std::uniform_int_distribution<int> pick(0, 7);
  const double specials[] = {0.0, -0.0, 1.6e-322, -1e300, 5e-324, 1.0 / 3.0, 123.456, 2.5};
  TraceRowFormatter format;
  std::string fast, plain;
  TraceRow r;
  for (int k = 0; k < 5000; ++k) {
    r.t = k * 0.001;
    for (std::size_t i = 0; i < 5; ++i) {
      if (pick(rng) < 3) r.command[i] = specials[static_cast<std::size_t>(pick(rng))];  // else it stays
      if (pick(rng) < 2) r.actual[i] = std::sin(k * 0.01 + static_cast<double>(i)) * 50;
      if (pick(rng) == 0) r.actual[i] = r.command[i];  // an axis on its command: the text is shared
    }
    format.append(fast, r);
    fast += '\n';
    append_trace_row(plain, r);
    plain += '\n';
  }
  EXPECT_EQ(fast, plain);
}

TEST(Trace, RejectsDamagedRowsWithLineColumnAndReason) {
  const std::string head = "t,X_cmd,Y_cmd,Z_cmd,A_cmd,C_cmd,X,Y,Z,A,C\n";
  std::size_t rows = 0;
  auto e = errors_of(head + kGood + "\n0.002000,1,2,3\n", &rows);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(rows, 1u);
  EXPECT_EQ(e[0].line, 3u);
  EXPECT_EQ(e[0].column, 15u);
  EXPECT_NE(e[0].message.find("4 of 11"), std::string::npos) << e[0].message;

  e = errors_of(head + "0.002000,1,2,3,4,5,1.5,2x,3,4,5\n");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0].column, 25u);  // the 'x' after "2"
  EXPECT_NE(e[0].message.find("'Y'"), std::string::npos) << e[0].message;

  e = errors_of(head + "0.002000,1,2,,4,5,1.5,2,3,4,5\n");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0].column, 14u);
  EXPECT_NE(e[0].message.find("Z_cmd"), std::string::npos);

  e = errors_of(head + kGood + ",7\n");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_NE(e[0].message.find("more than 11"), std::string::npos);

  e = errors_of(head + kGood + "\n" + kGood + "\n");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_NE(e[0].message.find("does not increase"), std::string::npos);

  e = errors_of(head + "0.002000,nan,2,3,4,5,1.5,2,3,4,5\n");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0].column, 10u);

  e = errors_of("t,X,Y\n" + kGood + "\n", &rows);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0].line, 1u);
  EXPECT_EQ(e[0].column, 4u);  // first character that differs
  EXPECT_EQ(rows, 1u);
  EXPECT_TRUE(errors_of(head + kGood + "\r\n").empty());  // CRLF files from Windows tools
}
