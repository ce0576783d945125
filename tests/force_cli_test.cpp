// The force stage in gcpipe batch: without a force section nothing changes (the golden outputs
// test holds the bytes); with pipeline_configs/force_al7075.yaml the seed 000 slot gets planned
// feeds, the report's force object shows the mean force held within 5 % of the target and a
// shorter cycle, the figures exist, and the compensation receives the planned program.
#include <gtest/gtest.h>

#include <regex>

#include "cli_helpers.hpp"

namespace {

const std::string kSource = GCPIPE_SOURCE_DIR;

/// The F words of a written program, in order.
std::vector<double> feeds_of(const std::string& text) {
  std::vector<double> f;
  const std::regex word("F([0-9.]+)");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), word); it != std::sregex_iterator(); ++it)
    f.push_back(std::stod((*it)[1]));
  return f;
}

TEST(ForceStage, BatchPlansTheSeed000SlotAndReportsIt) {
  const fs::path dir = tmpdir("force_batch");
  Outcome b = gcpipe({"batch", kSource + "/samples/trochoid_slot_seed000.nc", "--config",
                      kSource + "/pipeline_configs/force_al7075.yaml", "-o", dir.string(), "--quiet"});
  ASSERT_EQ(b.status, 0) << b.err;
  const auto report = read_json(dir / "report.json");
  ASSERT_TRUE(report.contains("force")) << report.dump(2);
  const auto& f = report.at("force");
  const double target = f.at("target_force_N").get<double>();
  EXPECT_EQ(target, 185.0);
  const auto& before = f.at("programmed");
  const auto& after = f.at("planned");
  EXPECT_NEAR(after.at("max_mean_force_N").get<double>(), target, 0.05 * target);
  EXPECT_LE(after.at("max_peak_force_N").get<double>(), 1.05 * 740);
  EXPECT_LT(after.at("cutting_time_s").get<double>(), 0.9 * before.at("cutting_time_s").get<double>());
  EXPECT_GT(after.at("max_deflection_um").get<double>(), 0.0);
  EXPECT_TRUE(fs::exists(dir / "plots" / "force_path.png"));
  EXPECT_TRUE(fs::exists(dir / "plots" / "force_time.png"));
  // The deflection beside the servo contour error: every simulated bucket placed on a force
  // sample (frames agree), both maxima reported, the figure drawn.
  const auto& budget = report.at("error_budget");
  EXPECT_GT(budget.at("matched_fraction").get<double>(), 0.9);
  EXPECT_NEAR(budget.at("max_contour_error_um").get<double>(),
              1e3 * report.at("simulation").at("contour_error_before").at("max_mm").get<double>(), 1e-6);
  EXPECT_GT(budget.at("max_deflection_um").get<double>(), 0.0);
  EXPECT_TRUE(fs::exists(dir / "plots" / "error_budget.png"));
  // output.nc is the expansion as programmed (write hangs off trochoid); compensated.nc is
  // written from the planned program, whose feeds now vary beyond the programmed 600/1200/2400.
  const auto planned = feeds_of(slurp(dir / "compensated.nc"));
  const auto programmed = feeds_of(slurp(dir / "output.nc"));
  ASSERT_FALSE(planned.empty());
  EXPECT_GT(*std::max_element(planned.begin(), planned.end()), *std::max_element(programmed.begin(), programmed.end()));
}

TEST(ForceStage, BadForceKeyNamesFileAndKey) {
  const fs::path dir = tmpdir("force_badkey");
  const fs::path cfg = dir / "bad.yaml";
  std::ofstream(cfg) << "machine: " << kSource << "/pipeline_configs/machines/mx330.yaml\nforce:\n  flutes: 3\n  stick_out: 60\n";
  Outcome b = gcpipe({"batch", kSource + "/samples/trochoid_slot_seed000.nc", "--config", cfg.string(), "-o",
                      (dir / "out").string(), "--quiet", "--no-simulate"});
  EXPECT_NE(b.status, 0);
  EXPECT_NE(b.err.find("bad.yaml"), std::string::npos) << b.err;
  EXPECT_NE(b.err.find("stick_out"), std::string::npos) << b.err;
}

}  // namespace
