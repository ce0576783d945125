// Behaviour stays put: what gcpipe batch writes for every shipped sample is compared with what
// was recorded. output.nc by its bytes (FNV-1a hashes in tests/golden/outputs.txt); compensated.nc
// by value against the recorded program (tests/golden/compensated/*.nc.gz: gzip -9n, deterministic,
// a seventh of the text's 5.6 MB in the repository), since its numbers come out of
// a long floating-point computation whose last bits differ between CPUs (glibc's FMA paths: the
// same commit wrote shop_pocket_inch.nc's compensated.nc with other bytes on an AMD EPYC than on
// the machine that recorded it): every line the same words, every number within 1 um (or 1 mdeg,
// or 1 mm/min of feed). And the same sample twice on one machine gives the same bytes. A
// refactoring must leave them unchanged; a change of behaviour updates them on purpose
// (GCPIPE_UPDATE_GOLDEN=1 rewrites both) and says why in its commit.
#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <sstream>

#include "cli_helpers.hpp"

namespace {

std::uint64_t fnv1a(const std::string& bytes) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : bytes) h = (h ^ c) * 1099511628211ull;
  return h;
}

const fs::path kGolden = fs::path(GCPIPE_SOURCE_DIR) / "tests" / "golden" / "outputs.txt";
const fs::path kGoldenPrograms = fs::path(GCPIPE_SOURCE_DIR) / "tests" / "golden" / "compensated";

/// The words of a G-code line: a letter and its number, or any other run of characters (comments
/// stay text).
std::vector<std::string> words(const std::string& line) {
  std::vector<std::string> out;
  std::size_t i = 0;
  while (i < line.size()) {
    if (line[i] == ' ') { ++i; continue; }
    if (line[i] == '(' || line[i] == ';') { out.push_back(line.substr(i)); break; }
    std::size_t j = i + 1;
    while (j < line.size() && line[j] != ' ' && line[j] != '(' && line[j] != ';' && !(std::isalpha(static_cast<unsigned char>(line[j])) && j > i + 1)) ++j;
    out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

/// "" when `got` is `want` by value (see the file comment), else the first difference.
std::string differs_by_value(const std::string& want, const std::string& got, double tolerance) {
  std::istringstream a(want), b(got);
  std::string la, lb;
  for (std::size_t n = 1;; ++n) {
    const bool ea = !std::getline(a, la), eb = !std::getline(b, lb);
    if (ea || eb) return ea && eb ? "" : "line " + std::to_string(n) + ": one program ends before the other";
    const auto wa = words(la), wb = words(lb);
    bool same = wa.size() == wb.size();
    for (std::size_t k = 0; same && k < wa.size(); ++k) {
      if (wa[k] == wb[k]) continue;
      const bool numeric = wa[k].size() > 1 && wb[k].size() > 1 && wa[k][0] == wb[k][0] && std::isalpha(static_cast<unsigned char>(wa[k][0]));
      char* end_a = nullptr;
      char* end_b = nullptr;
      const double va = numeric ? std::strtod(wa[k].c_str() + 1, &end_a) : 0, vb = numeric ? std::strtod(wb[k].c_str() + 1, &end_b) : 0;
      same = numeric && *end_a == '\0' && *end_b == '\0' && std::abs(va - vb) <= tolerance;
    }
    if (!same) return "line " + std::to_string(n) + ": recorded '" + la + "', now '" + lb + "'";
  }
}

/// The text of a gzip file (through gzip -dc: the recorded programs are stored compressed).
std::string gunzip(const fs::path& gz) {
  const std::string cmd = "gzip -dc '" + gz.string() + "'";
  std::string text;
  if (FILE* p = ::popen(cmd.c_str(), "r")) {
    char buf[65536];
    for (std::size_t n; (n = std::fread(buf, 1, sizeof buf, p)) > 0;) text.append(buf, n);
    ::pclose(p);
  }
  return text;
}

/// Writes `text` to `gz` as gzip -9n does (no name or time in the header: the same text gives
/// the same bytes, so an unchanged program leaves no change in git).
void gzip_to(const std::string& text, const fs::path& gz) {
  const std::string cmd = "gzip -9nc > '" + gz.string() + "'";
  if (FILE* p = ::popen(cmd.c_str(), "w")) {
    std::fwrite(text.data(), 1, text.size(), p);
    ::pclose(p);
  }
}

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
    if (c.compensated) {
      const fs::path recorded = kGoldenPrograms / (std::string(c.sample) + ".gz");
      const std::string now_text = slurp(dir / c.sample / "compensated.nc");
      if (update) {
        fs::create_directories(kGoldenPrograms);
        gzip_to(now_text, recorded);
      } else {
        const std::string want = gunzip(recorded);
        ASSERT_FALSE(want.empty()) << recorded << " is missing or not gzip";
        EXPECT_EQ(differs_by_value(want, now_text, 1e-3), "")
            << c.sample << "/compensated.nc changed; if on purpose, rerun with GCPIPE_UPDATE_GOLDEN=1";
      }
    }
    for (const char* file : {"output.nc"}) {
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

TEST(GoldenOutputs, ByValueComparisonSeesAChangeAndIgnoresTheLastDigit) {
  EXPECT_EQ(differs_by_value("G1 X1.0000 Y2.0000 F300.\n", "G1 X1.0001 Y2.0000 F300.\n", 1e-3), "");
  EXPECT_NE(differs_by_value("G1 X1.0000 Y2.0000\n", "G1 X1.0020 Y2.0000\n", 1e-3), "");
  EXPECT_NE(differs_by_value("G1 X1.0000\n", "G0 X1.0000\n", 1e-3), "");
  EXPECT_NE(differs_by_value("G1 X1.0000 (a)\n", "G1 X1.0000 (b)\n", 1e-3), "");
  EXPECT_NE(differs_by_value("G1 X1.0\nM30\n", "G1 X1.0\n", 1e-3), "");
}

TEST(GoldenOutputs, TheSameSampleTwiceGivesTheSameBytes) {
  const fs::path dir = tmpdir("golden_twice");
  std::string first;
  for (int run = 0; run < 2; ++run) {
    const Outcome r = gcpipe({"batch", std::string(GCPIPE_SOURCE_DIR) + "/samples/fanuc_post_pocket.nc", "-o", (dir / std::to_string(run)).string(), "--quiet"});
    ASSERT_EQ(r.status, 0) << r.err;
    const std::string bytes = slurp(dir / std::to_string(run) / "compensated.nc");
    if (run == 0) first = bytes;
    else EXPECT_TRUE(bytes == first) << "compensated.nc differs between two runs of the same sample";
  }
}

}  // namespace
