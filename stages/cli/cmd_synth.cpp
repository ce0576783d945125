// gcpipe synth: a seeded synthetic five-axis program of any size, for load tests and benchmarks.
#include <cstdio>
#include <string>

#include "command.hpp"
#include "commands.hpp"
#include "program_stream.hpp"
#include "synthetic_program.hpp"

namespace gcpipe::cli {
namespace {

int run_synth(const std::vector<std::string>& argv) {
  Args args(argv, {"--blocks", "--megabytes", "--seed", "-o"}, {});
  const double blocks = args.number_or("--blocks", 0);
  const double mb = args.number_or("--megabytes", 0);
  const double seed = args.number_or("--seed", 1);
  if (!args.ok()) return usage_error(kSynthCommand, args.error());
  if ((blocks <= 0) == (mb <= 0)) return usage_error(kSynthCommand, "give either --blocks N or --megabytes M (positive)");
  OutputFile out(args.value_or("-o", "-"));
  SyntheticProgram gen(static_cast<std::uint64_t>(seed));
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
  out.close();
  return 0;
}

}  // namespace

constinit const Command kSynthCommand{
    "synth", "write a seeded synthetic five-axis program (load tests)",
    "Usage: gcpipe synth (--blocks N | --megabytes M) [--seed S] [-o OUT]\n"
    "\n"
    "Writes a valid synthetic program: 70 % simultaneous XYZAC moves, 22 % G2/G3 arcs, feed\n"
    "changes and comments, seeded so the same arguments give the same bytes. For benchmarks and\n"
    "memory tests, e.g. gcpipe synth --megabytes 1000 | gcpipe parse - -o /dev/null\n",
    run_synth};

}  // namespace gcpipe::cli
