// Identification on traces from gcpipe's own simulator: the right effect on the right axis with
// its parameters within 10 %, the calibrated prediction within 2x the noise, no effect named on
// clean traces, two effects found together. The configured drive parameters are off by +-20 %.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <sstream>

#include "axis_model.hpp"
#include "calibrate_test_util.hpp"
#include "identify.hpp"

namespace gcpipe::calibrate {
namespace {

using test::Scenario;

TEST(CalibrateIdentify, BacklashOnYCircle) {
  Scenario sc = test::circle_scenario();
  sc.machine.drives.axes[kY].effects.push_back(test::effect("backlash", {{"width", 0.010}}));
  const auto r = test::identify(sc, kY, 1);
  test::print(r);
  ASSERT_EQ(r.named.size(), 1u);
  EXPECT_EQ(r.named[0].effect, "backlash");
  EXPECT_NEAR(r.named[0].params[0].value, 0.010, 0.001);
}

}  // namespace
}  // namespace gcpipe::calibrate
