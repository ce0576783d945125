// gcpipe synth: a seeded synthetic five-axis program of any size, for load tests and benchmarks.
#include <cstdio>
#include <string>

#include "output_dir.hpp"
#include "commands.hpp"
#include "program_stream.hpp"
#include "synthetic_program.hpp"

namespace gcpipe::cli {
namespace {

}  // namespace

int run_synth(const SynthArgs& args) {
  if (args.cam_segments > 0) {
    pipeline::AtomicFile out(args.output);
    std::string text = cam_like_program(args.seed, args.cam_segments);
    out.write(text, true);
    out.commit();
    return 0;
  }
  if ((args.blocks <= 0) == (args.megabytes <= 0)) {
    std::fprintf(stderr, "gcpipe synth: give either --blocks N, --megabytes M or --cam-segments N (positive)\n");
    return 2;
  }
  const double blocks = args.blocks, mb = args.megabytes;
  pipeline::AtomicFile out(args.output);
  SyntheticProgram gen(args.seed);
  std::string buf;
  gen.header(buf);
  const auto limit_bytes = static_cast<std::uint64_t>(mb * 1e6);
  std::uint64_t written = 0, count = 0;
  while (blocks > 0 ? static_cast<double>(count) < blocks : written + buf.size() < limit_bytes) {
    const std::size_t before = buf.size();
    gen.next(buf);
    ++count;
    if (blocks <= 0 && written + buf.size() >= limit_bytes) {
      buf.resize(before);  // stay within the size asked for
      break;
    }
    if (buf.size() >= (1u << 20)) {
      written += buf.size();
      out.write(buf, true);
    }
  }
  gen.footer(buf);
  out.write(buf, true);
  out.commit();
  return 0;
}

}  // namespace gcpipe::cli
