// The force stage in gcpipe batch: without a force section nothing changes (the golden outputs
// test holds the bytes); with pipeline_configs/force_al7075.yaml the seed 000 slot gets planned
// feeds, the report's force object shows the mean force held within 5 % of the target and a
// shorter cycle, the figures exist, and the compensation receives the planned program.
#include <gtest/gtest.h>

#include <cmath>
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
  // Issue 36 item 4: the planned program's cycle as the interpolator runs it, against the
  // simulate stage's (which runs the planned blocks). Since issue 31 force_al7075.yaml, derived
  // from the default, runs the look-ahead control: its cycle is its plan of the planned blocks,
  // never shorter than the interpolator's (the feeds are upper bounds) and longer by its
  // acceleration phases and exact stops (measured 80.95 s against 75.08 s; under seed 002's
  // control it was at most the final settling longer, 50 Ts = 3.2 s).
  const double planned_cycle = after.at("interpolated").at("cycle_time_s").get<double>();
  const double simulated = report.at("simulation").at("cycle_time_before_s").get<double>();
  EXPECT_GE(simulated, planned_cycle - 1e-3);
  EXPECT_LE(simulated, 1.1 * planned_cycle);
  EXPECT_GE(planned_cycle, f.at("force_only_cycle_time_s").get<double>() - 1e-9);
  EXPECT_LT(planned_cycle, 0.9 * before.at("interpolated").at("cycle_time_s").get<double>());
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

// Issue 36 item 5: the seed 000 slot in C45 (VDI 3323 group 2 by Kienzle's law, S2000 F600, see
// the sample's comments) without stated radial/axial ratios: tangential force, torque and power,
// no deflection and no error budget. The steady loops' force against the closed form of a straight
// climb cut of the same engagement (59.84 deg, c = 0.1 mm, a = 5 mm): N a kc1 c^0.78 / (2 pi)
// S_0.78(120.16 deg, 180 deg) = 337.17 N (stages/force/README.md sec. 6b; the swept loop is on a
// curved path, 2 % under it on the Al7075 set too).
TEST(ForceStage, BatchReportsTheSeed000SlotInC45ByKienzlesLaw) {
  const fs::path dir = tmpdir("force_c45");
  const fs::path table = fs::path(kSource) / ".." / "shared" / "data" / "force" / "vdi3323_kienzle.tsv";
  Outcome b = gcpipe({"batch", kSource + "/samples/trochoid_slot_seed000_c45.nc", "--config",
                      kSource + "/pipeline_configs/force_c45.yaml", "-o", dir.string(), "--quiet", "--no-simulate"});
  if (b.status != 0 && b.err.find("table was not found") != std::string::npos)
    GTEST_SKIP() << "the VDI 3323 table was not built in (" << table << " absent at configure time): " << b.err;
  ASSERT_EQ(b.status, 0) << b.err;
  const auto report = read_json(dir / "report.json");
  const auto& f = report.at("force");
  const auto& k = f.at("kienzle");
  EXPECT_EQ(k.at("vdi3323_group").get<int>(), 2);
  EXPECT_EQ(k.at("kc1_N_mm2").get<double>(), 1500);
  EXPECT_EQ(k.at("mc").get<double>(), 0.22);
  EXPECT_EQ(k.at("grade").get<std::string>(), "C45 annealed");
  EXPECT_EQ(k.at("table").at("sha256").get<std::string>().size(), 64u);
  const auto& p = f.at("programmed");
  EXPECT_FALSE(p.contains("max_mean_force_N")) << "a resultant without radial and axial forces";
  EXPECT_FALSE(p.contains("max_deflection_um"));
  EXPECT_NE(p.at("deflection").get<std::string>().find("radial"), std::string::npos);
  EXPECT_FALSE(report.contains("error_budget"));
  const double ft = p.at("max_mean_tangential_force_N").get<double>();
  EXPECT_NEAR(ft, 337.17, 0.05 * 337.17);
  EXPECT_LE(ft, 337.17 * 1.005);  // the curved path's arc never takes more than the straight cut's
  EXPECT_NEAR(p.at("max_torque_Nm").get<double>(), ft * 0.010, 1e-9 * ft);               // D/2 = 10 mm
  EXPECT_NEAR(p.at("max_power_W").get<double>(), ft * 0.010 * 2 * M_PI * 2000 / 60, 1e-6 * ft);  // S2000
  EXPECT_GT(p.at("cutting_time_s").get<double>(), 300.0);  // F600: twice the F1200 slot's 156.7 s
  EXPECT_TRUE(fs::exists(dir / "plots" / "force_path.png"));
  EXPECT_TRUE(fs::exists(dir / "plots" / "force_time.png"));
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
