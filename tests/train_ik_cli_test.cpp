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
