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
