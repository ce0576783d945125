// Why `gcpipe parse --json` keeps a hand-written JSON writer (block.cpp append_json) while every
// report uses nlohmann-json: the same resolved blocks as JSON Lines, hand-written against
// nlohmann-json (object built and dumped per block, as parse --json would have to). Both texts are
// checked to hold the same values before anything is timed. Figures in README.md.
//
//   build/tests/json_bench --benchmark_counters_tabular=true
#include <benchmark/benchmark.h>

#include <nlohmann/json.hpp>

#include "parse.hpp"
#include "synthetic_program.hpp"

namespace {

using namespace gcpipe;
using Json = nlohmann::ordered_json;

using Json = nlohmann::ordered_json;

const char* plane_name(Plane p) { return p == Plane::kXY ? "XY" : p == Plane::kZX ? "ZX" : "YZ"; }

const char* stop_name(ProgramStop s) {
  return s == ProgramStop::kStop ? "M0" : s == ProgramStop::kOptionalStop ? "M1" : s == ProgramStop::kEnd ? "M2" : "M30";
}

const char* spindle_name(Spindle s) { return s == Spindle::kCW ? "M3" : s == Spindle::kCCW ? "M4" : "M5"; }

template <std::size_t N>
Json list(const std::array<double, N>& v) {
  return Json(std::vector<double>(v.begin(), v.end()));
}

Json slot_json(const TrochoidSlot& t) {
  return {{"start", list(t.start)},        {"end", list(t.end)},       {"bottom", t.bottom},
          {"clearance", t.clearance},      {"width", t.width},         {"step", t.step},
          {"depth_step", t.depth_step},    {"tool_diameter", t.tool_diameter}, {"climb", t.climb}};
}

// What the block moves: motion, end points and the geometry of its kind.
void add_motion(Json& j, const ResolvedBlock& b) {
  j["motion"] = to_string(b.motion);
  j["start"] = list(b.start);
  j["target"] = list(b.target);
  if (b.motion == Motion::kArcCW || b.motion == Motion::kArcCCW) {
    j["plane"] = plane_name(b.plane);
    j["centre"] = list(b.centre);
    j["radius"] = b.radius;
    j["turns"] = b.turns;
  }
  if (b.motion == Motion::kDwell) j["dwell"] = b.dwell;
  if (b.motion == Motion::kTrochoidSlot) j["slot"] = slot_json(b.slot);
}

// The modal state in force: feed, spindle, tool, offsets, units, stops.
void add_modes(Json& j, const ResolvedBlock& b) {
  j["feed"] = b.feed;
  j["feed_mode"] = b.feed_mode == FeedMode::kInverseTime ? "G93" : "G94";
  j["spindle_speed"] = b.spindle_speed;
  j["spindle"] = spindle_name(b.spindle);
  j["tool"] = b.tool;
  j["tool_in_spindle"] = b.tool_in_spindle;
  j["tool_length_offset"] = b.tool_length_offset;
  j["tool_length"] = b.tool_length;
  j["tool_length_active"] = b.tool_length_active;
  j["tcp"] = b.tcp;
  if (b.tool_vector_mode) {  // only in G43.5 mode, so that other programs' JSON is unchanged
    j["tool_vector_mode"] = true;
    j["tool_vector"] = list(b.tool_vector);
  }
  j["coolant"] = b.coolant;
  j["work_offset"] = b.work_offset;
  j["work_origin"] = list(b.work_origin);
  j["source_units"] = b.source_units == Units::kInch ? "inch" : "mm";
  if (b.tool_change) j["tool_change"] = true;
  if (b.stop != ProgramStop::kNone) j["stop"] = stop_name(b.stop);
  if (b.program_number >= 0) j["program_number"] = b.program_number;
  if (b.percent) j["percent"] = true;
}


Json to_json(const ResolvedBlock& b) {
  Json j;
  j["line"] = b.line;
  j["text"] = b.text;
  if (!b.comment.empty()) j["comment"] = b.comment;
  add_motion(j, b);
  add_modes(j, b);
  return j;
}

const std::vector<ResolvedBlock>& blocks() {
  static const std::vector<ResolvedBlock> b = [] {
    std::string text;
    cli::SyntheticProgram gen(1);
    gen.header(text);
    for (int i = 0; i < 100'000; ++i) gen.next(text);
    gen.footer(text);
    Parser parser(ParseOptions{}, MachineConfig{}, "synthetic");
    std::vector<ResolvedBlock> out;
    feed_text(parser, text, {[&out](const ResolvedBlock& b) {
                               out.push_back(b);
                               return true;
                             },
                             [](const Diagnostic&) { return true; }});
    return out;
  }();
  return b;
}

void BM_JsonLinesHandWritten(benchmark::State& s) {
  const auto& all = blocks();  // built before the timing
  std::string out;
  std::uint64_t bytes = 0;
  for (auto _ : s) {
    out.clear();
    for (const auto& b : all) {
      append_json(out, b);
      out += '\n';
    }
    bytes += out.size();
    benchmark::DoNotOptimize(out.data());
  }
  s.SetBytesProcessed(static_cast<std::int64_t>(bytes));
  s.counters["blocks/s"] = benchmark::Counter(static_cast<double>(all.size()) * static_cast<double>(s.iterations()),
                                             benchmark::Counter::kIsRate);
}

void BM_JsonLinesNlohmann(benchmark::State& s) {
  const auto& all = blocks();
  std::string out;
  std::uint64_t bytes = 0;
  for (auto _ : s) {
    out.clear();
    for (const auto& b : all) {
      out += to_json(b).dump(-1, ' ', false, Json::error_handler_t::replace);
      out += '\n';
    }
    bytes += out.size();
    benchmark::DoNotOptimize(out.data());
  }
  s.SetBytesProcessed(static_cast<std::int64_t>(bytes));
  s.counters["blocks/s"] = benchmark::Counter(static_cast<double>(all.size()) * static_cast<double>(s.iterations()),
                                             benchmark::Counter::kIsRate);
}

BENCHMARK(BM_JsonLinesHandWritten)->Unit(benchmark::kMillisecond)->MinTime(1);
BENCHMARK(BM_JsonLinesNlohmann)->Unit(benchmark::kMillisecond)->MinTime(1);

// The two writers must say the same thing, or the comparison means nothing.
bool same_values() {
  std::string text;
  for (const auto& b : blocks()) {
    text.clear();
    append_json(text, b);
    if (Json::parse(text) != to_json(b)) return false;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (!same_values()) {
    std::fprintf(stderr, "json_bench: the two writers disagree; nothing timed\n");
    return 1;
  }
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  return 0;
}
