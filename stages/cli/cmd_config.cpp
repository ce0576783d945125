// gcpipe config --print: the effective pipeline config, every key each stage reads with the
// value it uses, the ones the file leaves out marked as defaults. The stages are built exactly as
// batch builds them, with a ConfigReadLog listening, so the list cannot fall behind the code.
#include <cstdio>
#include <map>
#include <vector>

#include "commands.hpp"
#include "gcpipe/config.hpp"
#include "program_stream.hpp"
#include "stage.hpp"

namespace gcpipe::cli {

namespace {

class SilentLog : public pipeline::DiagnosticLog {
 public:
  void report(const Diagnostic&) override {}
};

/// The reads of one file, first read of each key kept, in the order the stages read them.
std::map<std::string, std::vector<ConfigRead>> reads_by_file(const std::vector<ConfigRead>& reads,
                                                             std::vector<std::string>& file_order) {
  std::map<std::string, std::vector<ConfigRead>> by_file;
  for (const ConfigRead& r : reads) {
    auto& list = by_file[r.file];
    if (list.empty()) file_order.push_back(r.file);
    bool seen = false;
    for (const ConfigRead& k : list) seen = seen || k.key == r.key;
    if (!seen) list.push_back(r);
  }
  return by_file;
}

/// YAML text needs quotes when it is empty or holds what YAML would read as structure.
std::string yaml_scalar(const std::string& v) {
  if (!v.empty() && v.front() == '[') return v;
  const bool plain = !v.empty() && v.find_first_of(":#{}&*!|>'\"%@`,") == std::string::npos && v.front() != ' ' && v.back() != ' ';
  return plain ? v : "\"" + v + "\"";
}

/// Prints `reads` as nested YAML: a dotted key opens its mappings once, in the order first read.
void print_nested(const std::vector<ConfigRead>& reads) {
  std::vector<std::string> open;  // the mappings the previous line sat in
  for (const ConfigRead& r : reads) {
    std::vector<std::string> parts;
    for (std::size_t b = 0, e; b <= r.key.size(); b = e + 1) {
      e = r.key.find('.', b);
      if (e == std::string::npos) e = r.key.size();
      parts.push_back(r.key.substr(b, e - b));
    }
    std::size_t common = 0;
    while (common < open.size() && common + 1 < parts.size() && open[common] == parts[common]) ++common;
    open.resize(common);
    for (std::size_t d = common; d + 1 < parts.size(); ++d) {
      std::printf("%*s%s:\n", static_cast<int>(2 * d), "", parts[d].c_str());
      open.push_back(parts[d]);
    }
    const std::string line = std::string(2 * (parts.size() - 1), ' ') + parts.back() + ": " + yaml_scalar(r.value);
    if (r.defaulted) std::printf("%-60s # default\n", line.c_str());
    else std::printf("%s\n", line.c_str());
  }
}

}  // namespace

int run_config(const ConfigArgs& args) {
  ConfigReadLog log;
  const PipelineConfig config = load_config_option(args.config);
  SilentLog silent;
  std::vector<std::string> failed;
  for (const pipeline::StageInfo& s : pipeline::registry()) {
    pipeline::StageContext context;
    context.config = &config;
    context.file = "-";
    context.log = &silent;
    for (const pipeline::StageInfo& all : pipeline::registry()) context.stages.push_back(all.name);
    try {
      (void)s.make(context);
    } catch (const std::exception& e) {
      failed.push_back(std::string(s.name) + " cannot be built: " + e.what());
    }
  }
  std::vector<std::string> files;
  const auto by_file = reads_by_file(log.reads(), files);
  std::printf("# The effective config: every key the stages read, with the value they use\n"
              "# (\"# default\": the file leaves it out). gcpipe config --print --config %s\n",
              args.config.empty() ? "(default)" : args.config.c_str());
  for (const std::string& file : files) {
    std::printf("\n# ---- %s\n", file.c_str());
    print_nested(by_file.at(file));
  }
  for (const std::string& f : failed) {
    std::printf("\n# stage %s\n", f.c_str());
    std::fprintf(stderr, "gcpipe config: stage %s\n", f.c_str());
  }
  return failed.empty() ? 0 : 1;
}

}  // namespace gcpipe::cli
