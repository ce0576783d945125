// Test helpers: parse a program held in a string, or a file, into blocks and diagnostics.
#pragma once

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "gcpipe/config.hpp"
#include "gcpipe/pipeline_config.hpp"
#include "parse.hpp"

namespace gcpipe::test {

struct Parsed {
  std::vector<ResolvedBlock> blocks;
  std::vector<Diagnostic> diags;
  ParseSummary summary;
  /// The order things came out: true = the next block, false = the next diagnostic.
  std::vector<bool> order;
  const Diagnostic* first_error() const {
    for (const auto& d : diags)
      if (d.severity == Severity::kError) return &d;
    return nullptr;
  }
};

inline MachineConfig test_machine() {
  MachineConfig m;
  m.name = "test";
  m.tools[1] = {100.0, 10.0};
  m.tools[2] = {110.0, 20.0};
  m.work_offsets[1] = {100, 50, -20, 0, 0};  // G55
  return m;
}

inline Parsed parse_text(const std::string& text, ParseOptions opt = {},
                         MachineConfig machine = test_machine(), std::string file = "t.nc") {
  Parsed out;
  Parser p(opt, std::move(machine), file);
  std::istringstream in(text);
  std::string line;
  const ParseSink sink{[&](const ResolvedBlock& b) {
                         out.blocks.push_back(b);
                         out.order.push_back(true);
                         return true;
                       },
                       [&](const Diagnostic& d) {
                         out.diags.push_back(d);
                         out.order.push_back(false);
                         return true;
                       }};
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();  // as LineReader does
    const std::size_t cut = line.size() > opt.max_line_length ? line.size() : 0;
    p.feed(cut ? std::string_view(line).substr(0, opt.max_line_length) : std::string_view(line), sink, cut);
  }
  p.finish(sink);
  out.summary = p.summary();
  return out;
}

inline std::string read_file(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

inline std::filesystem::path shared_data() { return std::filesystem::path(GCPIPE_SHARED_DATA); }

/// Every G-code program under ../shared/data (empty when the folder is absent).
inline std::vector<std::filesystem::path> shared_programs() {
  std::vector<std::filesystem::path> out;
  if (!std::filesystem::exists(shared_data())) return out;
  for (const auto& e : std::filesystem::recursive_directory_iterator(shared_data())) {
    const auto ext = e.path().extension().string();
    if (ext == ".ngc" || ext == ".NC" || ext == ".nc") out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

/// The parse options a shipped program needs: LinuxCNC's for its files, the NIST Heidenhain export
/// is inch with absolute arc centres (see README, "Real programs").
inline ParseOptions options_for(const std::filesystem::path& p) {
  ParseOptions o;
  const std::string s = p.string();
  if (s.find("linuxcnc") != std::string::npos) o.dialect = Dialect::kLinuxCnc;
  if (s.find("nist_gfagie01") != std::string::npos) {
    o.initial_units = Units::kInch;
    o.absolute_arc_centres = true;
  }
  return o;
}

}  // namespace gcpipe::test
