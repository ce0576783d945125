// Programs as the force stage receives them (parse -> trochoid), for the force tests.
#pragma once

#include <filesystem>
#include <fstream>
#include <istream>
#include <sstream>
#include <string>
#include <vector>

#include "gcpipe/pipeline_config.hpp"
#include "parse.hpp"
#include "trochoid.hpp"

namespace gcpipe::test {

/// The blocks of a program after parse and trochoid, with the default config's machine (mx330).
inline std::vector<ResolvedBlock> trochoid_blocks(std::istream& in) {
  const auto root = std::filesystem::path(GCPIPE_SOURCE_DIR);
  const PipelineConfig pc = load_pipeline_config(root / "pipeline_configs/default.yaml");
  Parser parser(load_parse_options(pc.root.section("parse")), pc.machine, "test");
  TrochoidExpander x(load_trochoid_options(pc.root.section("trochoid")));
  std::vector<ResolvedBlock> out;
  std::string line;
  LineOutput got;
  while (std::getline(in, line)) {
    parser.feed(line, got);
    for (const ResolvedBlock& b : got.blocks) (void)x.expand(b, out);
  }
  return out;
}

inline std::vector<ResolvedBlock> trochoid_blocks(const std::string& text) {
  std::istringstream in(text);
  return trochoid_blocks(in);
}

/// The sample program of seed 000's slot, its blocks.
inline std::vector<ResolvedBlock> seed000_slot_blocks() {
  std::ifstream f(std::filesystem::path(GCPIPE_SOURCE_DIR) / "samples/trochoid_slot_seed000.nc");
  return trochoid_blocks(f);
}

}  // namespace gcpipe::test
