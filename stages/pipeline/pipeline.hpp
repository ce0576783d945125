// The in-process runner: builds a chain of registered stages and runs a program through it.
// `gcpipe batch` runs every stage; each subcommand runs a prefix of the same chain (its stages
// and their upstreams), so no command wires stages by hand.
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "stage.hpp"

namespace gcpipe::pipeline {

/// The stages `name` needs: itself and every upstream up to the source, in pipeline order.
std::vector<std::string> chain_to(std::string_view name);

class Pipeline {
 public:
  /// Builds the stages `names` (registered; each one's upstream among them), in registry order.
  Pipeline(const std::vector<std::string>& names, const StageContext& context);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  /// The stage called `name` (nullptr when not in this pipeline), e.g. to attach a tap.
  Stage* stage(std::string_view name);
  /// `sink` also receives everything stage `name` emits (output files, command-line taps).
  void attach(std::string_view name, Emitter& sink);
  /// Hands one source line to the source stage. False: the program was stopped.
  bool line(std::string_view text, std::size_t overlong_length = 0);
  /// Ends the program: every stage's finish(), in order.
  void finish(bool complete);
  /// Every stage's report section and figures, in order; r.json is the whole report object.
  void report(nlohmann::ordered_json& json, std::string& text, const std::filesystem::path& dir,
              const std::string& input_base, std::vector<std::string>& files, const Progress& progress);
  /// Names of the stages, in order.
  std::vector<std::string> names() const;
  /// Lines or cycles rejected by any stage.
  std::uint64_t rejected() const;
  /// The first stage's failure (see Stage::failure), prefixed with its name; empty when none.
  std::string failure() const;

 private:
  struct Node;
  std::vector<std::unique_ptr<Node>> nodes_;
  Node* find(std::string_view name);
};

/// Reads the file open at `fd` (`name` for messages, `size` 0 when unknown) line by line into
/// `pipeline`, cutting lines at `max_line_length` as the parser expects. Prints progress to stderr
/// about once a second when `progress`. Returns false when the program was stopped or the read
/// failed (`error` then says why).
bool run_lines(Pipeline& pipeline, int fd, const std::string& name, std::uint64_t size,
               std::size_t max_line_length, bool progress, std::string& error);

}  // namespace gcpipe::pipeline
