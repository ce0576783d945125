// gcpipe parse: the parse stage alone, resolved blocks to stdout.
#include <cstdio>
#include <iostream>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "output_dir.hpp"
#include "program_run.hpp"

namespace gcpipe::cli {

namespace {

// Formats every block the parse stage emits: a fixed-width line, or JSON Lines.
class BlockPrinter final : public pipeline::Emitter {
 public:
  BlockPrinter(const std::string& path, bool json) : out_(path), json_(json) {}
  bool block(const ResolvedBlock& b) override {
    if (json_) {
      append_json(buf_, b);
    } else {
      char tmp[256];
      std::snprintf(tmp, sizeof tmp, "%6llu %-8s X%.4f Y%.4f Z%.4f A%.4f C%.4f F%.4g",
                    static_cast<unsigned long long>(b.line), to_string(b.motion), b.target[kX], b.target[kY],
                    b.target[kZ], b.target[kA], b.target[kC], b.feed);
      buf_ += tmp;
    }
    buf_ += '\n';
    out_.write(buf_);
    return true;
  }
  bool diagnostic(const Diagnostic&, DiagnosticKind) override { return true; }
  bool text(std::string&) override { return true; }
  void product(const std::shared_ptr<const pipeline::Product>&) override {}
  void commit() {
    out_.write(buf_, true);
    out_.commit();
  }

 private:
  pipeline::AtomicFile out_;
  bool json_;
  std::string buf_;
};

}  // namespace

int run_parse(const ParseArgs& a) {
  pipeline::install_stop_handlers();
  PrintedLog log;
  ProgramRun run(a, {"parse"}, log);
  BlockPrinter printer(a.output, a.json);
  run.pipeline().attach("parse", printer);
  const bool complete = run.run();
  if (pipeline::stop_requested()) return exit_status(complete, "", 0);
  printer.commit();
  nlohmann::ordered_json counts;
  std::string text;
  std::vector<std::string> files;
  run.pipeline().report(counts, text, {}, {}, files, {});
  std::fprintf(stderr, "%s: %llu lines read, %llu blocks emitted, %llu rejected, %llu skipped by block delete\n",
               run.input_name().c_str(), counts["lines_read"].get<unsigned long long>(),
               counts["blocks_emitted"].get<unsigned long long>(), counts["lines_rejected"].get<unsigned long long>(),
               counts["lines_deleted"].get<unsigned long long>());
  if (!complete) std::cerr << "gcpipe parse: " << run.error() << "\n";
  return exit_status(complete, "", log.errors());
}

}  // namespace gcpipe::cli
