// Every shipped pipeline config loads in every stage that reads it, and a pipeline config with a
// section no stage reads (a typo such as "parze:") is rejected.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "gcpipe/config.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "force_options.hpp"
#include "ik.hpp"
#include "interpolate.hpp"
#include "parse.hpp"
#include "servo.hpp"
#include "trochoid.hpp"
#include "write.hpp"

namespace fs = std::filesystem;
using namespace gcpipe;

TEST(ShippedConfigs, EverySectionLoadsInItsStage) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(fs::path(GCPIPE_SOURCE_DIR) / "pipeline_configs")) {
    if (e.path().extension() != ".yaml") continue;
    SCOPED_TRACE(e.path().string());
    PipelineConfig pc;
    ASSERT_NO_THROW(pc = load_pipeline_config(e.path()));
    EXPECT_NO_THROW(load_parse_options(pc.root.section("parse")));
    EXPECT_NO_THROW(load_write_options(pc.root.section("write")));
    EXPECT_NO_THROW(load_trochoid_options(pc.root.section("trochoid")));
    EXPECT_NO_THROW(load_ik_options(pc.root.section("ik")));
    EXPECT_NO_THROW(interpolate::load_interpolate_options(pc.root.section("interpolate")));
    // A VDI 3323 material needs the table built in from ../shared/data (absent: it says so).
    const bool needs_table = pc.root.has("force") && pc.root.section("force").is_mapping("material");
    if (needs_table && force::kienzle_table().empty())
      std::printf("%s: force section not loaded: the VDI 3323 table was not built in\n", e.path().c_str());
    else if (pc.root.has("force"))
      EXPECT_NO_THROW(force::load_force_options(pc.root.section("force")));
    if (pc.root.has("servo")) {
      const Config servo = pc.root.section("servo");
      EXPECT_NO_THROW(servo::load_drives(Config::load_file(servo.resolve(servo.string("drives", "")))));
    }
    ++n;
  }
  EXPECT_GE(n, 3);
}

TEST(ShippedConfigs, UnknownTopLevelSectionIsRejected) {
  const fs::path p = fs::temp_directory_path() / "gcpipe_configs_test_typo.yaml";
  {
    std::ofstream f(p);
    f << "machine: " << GCPIPE_SOURCE_DIR << "/pipeline_configs/machines/mx330.yaml\nparze:\n  strict: true\n";
  }
  try {
    load_pipeline_config(p);
    FAIL() << "a misspelt section was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("key 'parze': unknown key"), std::string::npos) << e.what();
  }
  fs::remove(p);
}
