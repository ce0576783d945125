#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "gcpipe/config.hpp"
#include "gcpipe/number_format.hpp"
#include "gcpipe/pipeline_config.hpp"

using namespace gcpipe;

TEST(NumberFormat, ShortestRoundTripsAndKeepsThePoint) {
  for (double v : {0.0, -0.0, 1.0, 12.3, -0.001, 1e-9, 123456.789, 0.1 + 0.2, 25.4 * 0.1, 1e20}) {
    std::string s;
    append_shortest(s, v);
    EXPECT_NE(s.find('.'), std::string::npos) << s;
    EXPECT_EQ(s.find('e'), std::string::npos) << s;
    EXPECT_EQ(std::stod(s), v) << s;
  }
  std::string s;
  append_shortest(s, -0.0);
  EXPECT_EQ(s, "0.");
  // The fixed form of tiny and huge values is long; found by the trochoid stage (1.1e-16).
  for (double v : {1.1102230246251565e-16, 4.9406564584124654e-324, 1.7976931348623157e308}) {
    s.clear();
    append_shortest(s, v);
    EXPECT_EQ(std::strtod(s.c_str(), nullptr), v) << s;  // stod throws ERANGE on denormals
  }
}

TEST(NumberFormat, FixedDropsTrailingZeros) {
  std::string s;
  append_fixed(s, 1.5, 4);
  EXPECT_EQ(s, "1.5");
  s.clear();
  append_fixed(s, -0.00001, 4);
  EXPECT_EQ(s, "0.");
  s.clear();
  append_fixed(s, 3.0, 3);
  EXPECT_EQ(s, "3.");
  s.clear();
  append_fixed(s, -1.7976931348623157e308, 9);  // 309 integer digits: found by parse_fuzz
  EXPECT_EQ(s.size(), 1 + 309 + 1u);
  EXPECT_EQ(s.back(), '.');
}

TEST(Config, ReportsKeyValueRangeAndPosition) {
  auto c = Config::from_string("a:\n  speed: 5000\n  name: x\n", "test.yaml");
  auto a = c.section("a");
  EXPECT_DOUBLE_EQ(a.number("speed", "mm/min", 0, 6000), 5000);
  try {
    a.number("speed", "mm/min", 0, 100);
    FAIL();
  } catch (const ConfigError& e) {
    std::string m = e.what();
    EXPECT_NE(m.find("test.yaml:2:10"), std::string::npos) << m;
    EXPECT_NE(m.find("a.speed"), std::string::npos) << m;
    EXPECT_NE(m.find("'5000'"), std::string::npos) << m;
    EXPECT_NE(m.find("[0, 100] mm/min"), std::string::npos) << m;
  }
  EXPECT_THROW(a.reject_unknown({"speed"}), ConfigError);
  EXPECT_THROW(a.number("name", "mm", 0, 1), ConfigError);
  EXPECT_THROW(Config::from_string("a: [1, 2", "bad.yaml"), ConfigError);
}

TEST(Config, EveryShippedPipelineConfigLoads) {
  namespace fs = std::filesystem;
  int n = 0;
  for (const auto& e : fs::directory_iterator(fs::path(GCPIPE_SOURCE_DIR) / "pipeline_configs")) {
    if (e.path().extension() != ".yaml") continue;
    EXPECT_NO_THROW(load_pipeline_config(e.path())) << e.path();
    ++n;
  }
  EXPECT_GE(n, 1);
}

#include <unistd.h>

#include "gcpipe/line_reader.hpp"

// Lines of every length and terminator, across the 1 MiB read boundary: the reported full length
// never depends on where a line falls against a read.
TEST(LineReader, OverlongLinesAndCrLfAnywhereInTheBuffer) {
  std::string text;
  std::vector<std::size_t> lengths;
  for (std::size_t i = 0; i < 20000; ++i) {
    const std::size_t len = (i * 7919) % 2000;
    text.append(len, static_cast<char>('A' + i % 26));
    text += (i % 3 == 0) ? "\r\n" : "\n";
    lengths.push_back(len);
  }
  text.append(700, 'Z');  // a last line without a terminator
  lengths.push_back(700);
  char path[] = "/tmp/gcpipe_line_reader_XXXXXX";
  const int fd = mkstemp(path);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(write(fd, text.data(), text.size()), static_cast<ssize_t>(text.size()));
  lseek(fd, 0, SEEK_SET);
  gcpipe::LineReader r(fd, 256);
  std::string_view line;
  bool overlong = false;
  std::size_t full = 0, n = 0;
  while (r.next(line, overlong, full)) {
    ASSERT_LT(n, lengths.size());
    EXPECT_EQ(full, lengths[n]) << "line " << n + 1;
    EXPECT_EQ(overlong, lengths[n] > 256) << "line " << n + 1;
    EXPECT_EQ(line.size(), std::min<std::size_t>(lengths[n], 256)) << "line " << n + 1;
    ++n;
  }
  EXPECT_EQ(n, lengths.size());
  close(fd);
  unlink(path);
}
