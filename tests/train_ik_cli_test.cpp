// `gcpipe train-ik` end to end: the same seed gives the same model file byte for byte, another
// seed a different one, the file loads, and bad options are usage errors.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "neural_ik.hpp"

namespace {

const std::string kGcpipe = std::string(GCPIPE_BINARY_DIR) + "/stages/cli/gcpipe";
const std::string kConfig = std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/default.yaml";

std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

int run(const std::string& args) {
  const std::string command = kGcpipe + " train-ik --config " + kConfig + " " + args +
                              " > /dev/null 2> /dev/null";
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

TEST(TrainIkCli, SameSeedGivesTheSameFileByteForByte) {
  ASSERT_TRUE(std::filesystem::exists(kGcpipe)) << kGcpipe << " not built";
  const std::filesystem::path dir = std::filesystem::path(GCPIPE_BINARY_DIR) / "train_ik_cli_test";
  std::filesystem::create_directories(dir);
  const std::string tiny = " --samples 240 --max-iterations 6 --quiet";
  ASSERT_EQ(run("-o " + (dir / "a.model").string() + " --seed 7" + tiny), 0);
  ASSERT_EQ(run("-o " + (dir / "b.model").string() + " --seed 7" + tiny), 0);
  ASSERT_EQ(run("-o " + (dir / "c.model").string() + " --seed 8" + tiny), 0);
  const std::string a = slurp(dir / "a.model");
  ASSERT_FALSE(a.empty());
  EXPECT_EQ(a, slurp(dir / "b.model"));
  EXPECT_NE(a, slurp(dir / "c.model"));
  const gcpipe::neural::NeuralIk model = gcpipe::neural::NeuralIk::load(dir / "a.model");
  EXPECT_EQ(model.provenance().machine, "mx330");
  EXPECT_EQ(model.provenance().seed, 7u);
  EXPECT_EQ(model.provenance().preset, "custom");
  std::filesystem::remove_all(dir);
}

TEST(TrainIkCli, BadOptionsAreUsageErrors) {
  ASSERT_TRUE(std::filesystem::exists(kGcpipe)) << kGcpipe << " not built";
  EXPECT_EQ(run("--preset fast -o /dev/null"), 2);
  EXPECT_EQ(run("--seed -1 -o /dev/null"), 2);
  EXPECT_EQ(run("--samples 5 -o /dev/null"), 2);
  EXPECT_EQ(run(""), 2);  // no -o
  EXPECT_EQ(run("-o /nonexistent/dir/x.model --samples 240 --max-iterations 1 --quiet"), 1);
}

// A model learns one machine's geometry: gcpipe ik refuses a model trained for another machine.
TEST(TrainIkCli, IkRefusesAModelOfAnotherMachine) {
  ASSERT_TRUE(std::filesystem::exists(kGcpipe)) << kGcpipe << " not built";
  const std::filesystem::path dir = std::filesystem::path(GCPIPE_BINARY_DIR) / "train_ik_cli_other";
  std::filesystem::create_directories(dir);
  const std::string model = (dir / "lc.model").string();
  const std::string lc = std::string(GCPIPE_SOURCE_DIR) + "/pipeline_configs/linuxcnc_xyzac_trt.yaml";
  const std::string train = kGcpipe + " train-ik --config " + lc + " -o " + model +
                            " --samples 240 --max-iterations 2 --quiet > /dev/null 2>&1";
  ASSERT_EQ(WEXITSTATUS(std::system(train.c_str())), 0);
  const std::string sample = std::string(GCPIPE_SOURCE_DIR) + "/samples/five_axis_demo.nc";
  const std::string err = (dir / "err.txt").string();
  const std::string same = kGcpipe + " ik " + sample + " --csv --config " + lc + " --model " + model + " > /dev/null 2>&1";
  EXPECT_NE(WEXITSTATUS(std::system(same.c_str())), 1);  // its own machine: accepted
  const std::string other = kGcpipe + " ik " + sample + " --csv --config " + kConfig + " --model " + model +
                            " > /dev/null 2> " + err;
  EXPECT_EQ(WEXITSTATUS(std::system(other.c_str())), 1);
  EXPECT_NE(slurp(err).find("trained for machine 'linuxcnc_xyzac_trt'"), std::string::npos) << slurp(err);
  std::filesystem::remove_all(dir);
}
