// Behaviour stays put: the bytes gcpipe batch writes for every shipped sample (output.nc, and
// compensated.nc where it is quick to compute) are compared with the FNV-1a hashes recorded in
// tests/golden/outputs.txt. A refactoring must leave them unchanged; a change of behaviour
// updates the file on purpose (GCPIPE_UPDATE_GOLDEN=1 rewrites it) and says why in its commit.
#include <gtest/gtest.h>

#include <cstdlib>
#include <map>

#include "cli_helpers.hpp"

namespace {

std::uint64_t fnv1a(const std::string& bytes) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : bytes) h = (h ^ c) * 1099511628211ull;
  return h;
}

const fs::path kGolden = fs::path(GCPIPE_SOURCE_DIR) / "tests" / "golden" / "outputs.txt";

std::map<std::string, std::string> read_golden() {
  std::map<std::string, std::string> m;
  std::ifstream f(kGolden);
  std::string key, value;
  while (f >> key >> value) m[key] = value;
  return m;
}

struct Case {
  const char* sample;
  const char* config;  // relative to the source tree; "" = default
  bool compensated;    // also compare compensated.nc
};

TEST(GoldenOutputs, EverySampleWritesTheRecordedBytes) {
  const std::vector<Case> cases = {
      {"five_axis_demo.nc", "", true},
      {"tool_vector_demo.nc", "", true},
      {"circle_test_seed002.nc", "pipeline_configs/circle_test.yaml", true},
      {"trochoid_slot_f3000.nc", "", false},
      {"trochoid_slot_seed000.nc", "", false},
      {"shop_pocket_inch.nc", "", true},
      {"fanuc_post_pocket.nc", "", true},
  };
  const bool update = std::getenv("GCPIPE_UPDATE_GOLDEN") != nullptr;
  std::map<std::string, std::string> golden = read_golden(), now;
  const fs::path dir = tmpdir("golden");
  for (const Case& c : cases) {
    std::vector<std::string> args{"batch", std::string(GCPIPE_SOURCE_DIR) + "/samples/" + c.sample, "-o",
                                  (dir / c.sample).string(), "--quiet"};
    if (*c.config) args.insert(args.end(), {"--config", std::string(GCPIPE_SOURCE_DIR) + "/" + c.config});
    if (!c.compensated) args.push_back("--no-simulate");
    const Outcome r = gcpipe(args);
    ASSERT_EQ(r.status, 0) << c.sample << ": " << r.err;
    for (const char* file : {"output.nc", "compensated.nc"}) {
      if (std::string(file) == "compensated.nc" && !c.compensated) continue;
      const std::string key = std::string(c.sample) + "/" + file;
      char hex[17];
      std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(fnv1a(slurp(dir / c.sample / file))));
      now[key] = hex;
      if (!update) EXPECT_EQ(golden[key], hex) << key << " changed; if on purpose, rerun with GCPIPE_UPDATE_GOLDEN=1";
    }
  }
  if (update) {
    std::ofstream f(kGolden);
    for (const auto& [k, v] : now) f << k << ' ' << v << '\n';
  }
}

}  // namespace
