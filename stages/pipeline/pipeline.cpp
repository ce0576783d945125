#include "pipeline.hpp"

#include <chrono>
#include <cstdio>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "gcpipe/line_reader.hpp"
#include "output_dir.hpp"

namespace gcpipe::pipeline {

const char* to_string(Port port) {
  switch (port) {
    case Port::kProgram: return "program";
    case Port::kBlocks: return "blocks";
    case Port::kGcode: return "gcode";
    case Port::kNone: return "-";
  }
  return "?";
}

bool Stage::line(std::string_view, std::size_t, Emitter&) {
  throw std::logic_error("this stage takes blocks, not program lines");
}

const StageInfo& find_stage(std::string_view name) {
  std::string known;
  for (const StageInfo& s : registry()) {
    if (name == s.name) return s;
    known += known.empty() ? "" : ", ";
    known += s.name;
  }
  throw std::runtime_error("unknown stage '" + std::string(name) + "' (known: " + known + ")");
}

std::string input_topic(std::string_view name) {
  for (const StageInfo* s = &find_stage(name); *s->upstream != '\0';) {
    s = &find_stage(s->upstream);
    if (*s->topic != '\0') return s->topic;
  }
  return kProgramTopic;
}

std::vector<std::string> chain_to(std::string_view name) {
  std::vector<std::string> chain;
  for (const StageInfo* s = &find_stage(name);; s = &find_stage(s->upstream)) {
    chain.insert(chain.begin(), s->name);
    if (*s->upstream == '\0') break;
  }
  return chain;
}

// One stage in the graph, and the emitter that fans its output out to its consumers: the stages
// registered downstream of it and any attached sinks.
struct Pipeline::Node final : Emitter {
  const StageInfo* info = nullptr;
  std::unique_ptr<Stage> stage;
  std::vector<Node*> consumers;
  std::vector<Emitter*> sinks;

  bool block(const ResolvedBlock& b) override {
    bool go = true;
    for (Node* c : consumers) go = c->stage->block(b, *c) && go;
    for (Emitter* s : sinks) go = s->block(b) && go;
    return go;
  }
  bool diagnostic(const Diagnostic& d, DiagnosticKind kind) override {
    bool go = true;
    for (Node* c : consumers) go = c->stage->diagnostic(d, kind, *c) && go;
    for (Emitter* s : sinks) go = s->diagnostic(d, kind) && go;
    return go;
  }
  bool text(std::string& gcode) override {
    bool go = true;
    // Each sink takes its own copy (a sink empties what it is given), the last one the text
    // itself: compensated.nc of a one-hour program is tens of MB, and a copy would add to the peak.
    for (std::size_t i = 0; i < sinks.size(); ++i) {
      if (i + 1 == sinks.size()) {
        go = sinks[i]->text(gcode) && go;
        break;
      }
      std::string copy = gcode;
      go = sinks[i]->text(copy) && go;
    }
    gcode.clear();
    return go;
  }
  void product(const std::shared_ptr<const Product>& p) override {
    for (Node* c : consumers) c->stage->product(p, *c);
    for (Emitter* s : sinks) s->product(p);
  }
};

Pipeline::Pipeline(const std::vector<std::string>& names, const StageContext& given) {
  for (const auto& n : names) find_stage(n);  // an unknown name is an error, not ignored
  StageContext context = given;
  context.stages = names;
  for (const StageInfo& info : registry()) {
    bool wanted = false;
    for (const auto& n : names) wanted = wanted || n == info.name;
    if (!wanted) continue;
    auto node = std::make_unique<Node>();
    node->info = &info;
    if (*info.upstream != '\0') {
      Node* up = find(info.upstream);
      if (up == nullptr)
        throw std::logic_error(std::string("stage '") + info.name + "' needs its upstream '" + info.upstream +
                               "' in the pipeline");
      up->consumers.push_back(node.get());
    } else if (!nodes_.empty()) {
      throw std::logic_error("a pipeline has one source stage");
    }
    node->stage = info.make(context);
    nodes_.push_back(std::move(node));
  }
  if (nodes_.empty() || nodes_.front()->info->input != Port::kProgram)
    throw std::logic_error("a pipeline starts with a stage that reads program text");
}

Pipeline::~Pipeline() = default;

Pipeline::Node* Pipeline::find(std::string_view name) {
  for (auto& n : nodes_)
    if (name == n->info->name) return n.get();
  return nullptr;
}

Stage* Pipeline::stage(std::string_view name) {
  Node* n = find(name);
  return n ? n->stage.get() : nullptr;
}

void Pipeline::attach(std::string_view name, Emitter& sink) {
  Node* n = find(name);
  if (n == nullptr) throw std::logic_error("attach: no stage '" + std::string(name) + "' in this pipeline");
  n->sinks.push_back(&sink);
}

bool Pipeline::line(std::string_view text, std::size_t overlong_length) {
  Node& source = *nodes_.front();
  return source.stage->line(text, overlong_length, source);
}

void Pipeline::finish(bool complete) {
  for (auto& n : nodes_) n->stage->finish(complete, *n);
}

void Pipeline::report(nlohmann::ordered_json& json, std::string& text, const std::filesystem::path& dir,
                      const std::string& input_base, std::vector<std::string>& files, const Progress& progress) {
  for (auto& n : nodes_) {
    ReportContext r;
    r.json = &json;
    r.text = &text;
    r.dir = dir;
    r.input_base = input_base;
    r.files = &files;
    r.progress = progress;
    n->stage->report(r);
  }
}

std::vector<std::string> Pipeline::names() const {
  std::vector<std::string> v;
  for (const auto& n : nodes_) v.emplace_back(n->info->name);
  return v;
}

std::uint64_t Pipeline::rejected() const {
  std::uint64_t sum = 0;
  for (const auto& n : nodes_) sum += n->stage->rejected();
  return sum;
}

std::string Pipeline::failure() const {
  for (const auto& n : nodes_) {
    const std::string f = n->stage->failure();
    if (!f.empty()) return std::string(n->info->name) + ": " + f;
  }
  return {};
}

namespace {

// Percent (when the size is known), MB, MB/s and lines, overwritten in place about once a second.
class ProgressLine {
 public:
  ProgressLine(const std::string& name, std::uint64_t size) : name_(name), size_(size) {}
  ~ProgressLine() {
    if (shown_) std::fprintf(stderr, "\n");
  }
  void update(std::uint64_t bytes, std::uint64_t lines) {
    const auto now = clock::now();
    if (now < next_) return;
    next_ = now + std::chrono::seconds(1);
    const double s = std::chrono::duration<double>(now - t0_).count();
    const double mb = static_cast<double>(bytes) / 1e6;
    if (size_ > 0)
      std::fprintf(stderr, "\r%s: %5.1f %%  %.0f MB  %.0f MB/s  %llu lines   ", name_.c_str(),
                   100.0 * static_cast<double>(bytes) / static_cast<double>(size_), mb, mb / s,
                   static_cast<unsigned long long>(lines));
    else
      std::fprintf(stderr, "\r%s: %.0f MB  %.0f MB/s  %llu lines   ", name_.c_str(), mb, mb / s,
                   static_cast<unsigned long long>(lines));
    shown_ = true;
  }

 private:
  using clock = std::chrono::steady_clock;
  std::string name_;
  std::uint64_t size_;
  clock::time_point t0_ = clock::now();
  clock::time_point next_ = t0_ + std::chrono::seconds(1);
  bool shown_ = false;
};

}  // namespace

bool run_lines(Pipeline& pipeline, int fd, const std::string& name, std::uint64_t size,
               std::size_t max_line_length, bool progress, std::string& error) {
  LineReader reader(fd, max_line_length);
  std::string_view line;
  bool overlong = false;
  std::size_t full = 0;
  std::uint64_t lines = 0;
  std::unique_ptr<ProgressLine> shown;
  if (progress) shown = std::make_unique<ProgressLine>(name, size);
  while (reader.next(line, overlong, full)) {
    ++lines;
    if ((lines & 0xff) == 0 && stop_requested()) {
      error = "interrupted by signal " + std::to_string(stop_signal());
      return false;
    }
    if (!pipeline.line(line, overlong ? full : 0)) {
      error = "stopped at the first error (--strict or parse.strict is on)";
      return false;
    }
    if (shown && (lines & 0xfff) == 0) shown->update(reader.bytes_read(), lines);
  }
  if (stop_requested()) {  // the reader ends the input at a stop, in the middle of a line too
    error = "interrupted by signal " + std::to_string(stop_signal());
    return false;
  }
  if (!reader.error().empty()) {
    error = name + ": read error: " + reader.error();
    return false;
  }
  return true;
}

}  // namespace gcpipe::pipeline
