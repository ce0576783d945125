// What a mistyped command line was probably meant to be: the closest command or option name, so
// that `gcpipe bacth` says "did you mean 'batch'" instead of "A subcommand is required".
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace CLI {
class App;
}

namespace gcpipe::cli {

/// Edit distance (insertions, deletions, substitutions, and a swap of two neighbours counted once:
/// "bacth" is one step from "batch").
std::size_t edit_distance(std::string_view a, std::string_view b);

/// The candidate closest to `typed` within 2 edits (or 1 for words of up to 4 letters), or one it
/// begins; empty when none is close enough to be a guess worth printing.
std::string closest(std::string_view typed, const std::vector<std::string>& candidates);

/// After a failed parse of `args` (argv without the program name): the line that names the first
/// unknown command or option and, when one is close, what was probably meant. Empty when every
/// command and option in `args` exists (the error is about something else: a value, a file).
std::string explain_unknown_words(const CLI::App& app, const std::vector<std::string>& args);

}  // namespace gcpipe::cli
