#include "did_you_mean.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <numeric>

namespace gcpipe::cli {

std::size_t edit_distance(std::string_view a, std::string_view b) {
  // Optimal string alignment: Levenshtein plus the transposition of two adjacent letters, the
  // commonest typing slip.
  const std::size_t n = a.size(), m = b.size();
  std::vector<std::vector<std::size_t>> d(n + 1, std::vector<std::size_t>(m + 1));
  for (std::size_t i = 0; i <= n; ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= m; ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= n; ++i)
    for (std::size_t j = 1; j <= m; ++j) {
      const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[n][m];
}

std::string closest(std::string_view typed, const std::vector<std::string>& candidates) {
  std::string best;
  std::size_t best_d = typed.size() <= 4 ? 2 : 3;  // accepted: below this
  for (const auto& c : candidates) {
    const std::size_t d = edit_distance(typed, c);
    if (d < best_d) {
      best_d = d;
      best = c;
    }
  }
  if (!best.empty() || typed.size() < 3) return best;
  for (const auto& c : candidates)  // an abbreviation: "--out" for "--output-dir"
    if (c.size() > typed.size() && c.compare(0, typed.size(), typed) == 0) return c;
  return "";
}

namespace {

std::vector<std::string> command_names(const CLI::App& app) {
  std::vector<std::string> out;
  for (const CLI::App* s : app.get_subcommands([](const CLI::App*) { return true; })) out.push_back(s->get_name());
  return out;
}

std::vector<std::string> option_names(const CLI::App& app) {
  std::vector<std::string> out;
  for (const CLI::Option* o : app.get_options([](const CLI::Option*) { return true; })) {
    for (const auto& l : o->get_lnames()) out.push_back("--" + l);
    for (const auto& s : o->get_snames()) out.push_back("-" + s);
  }
  return out;
}

std::string command_path(const CLI::App& app) {
  std::string path;
  for (const CLI::App* a = &app; a != nullptr; a = a->get_parent())
    path = a->get_name() + (path.empty() ? "" : " " + path);
  return path;
}

std::string guess(const std::string& typed, const std::vector<std::string>& candidates) {
  const std::string c = closest(typed, candidates);
  return c.empty() ? "" : ": did you mean '" + c + "'?";
}

}  // namespace

std::string explain_unknown_words(const CLI::App& app, const std::vector<std::string>& args) {
  const CLI::App* at = &app;
  bool options_ended = false;
  for (const auto& arg : args) {
    if (arg == "--") options_ended = true;
    if (options_ended || arg.empty()) continue;
    if (arg[0] == '-' && arg.size() > 1) {
      // An option: known to this command (or to a command above it, which CLI11 passes up)?
      const std::string name = arg.substr(0, arg.find('='));
      if (name.size() == 2 || name.rfind("--", 0) == 0) {
        bool known = false;
        for (const CLI::App* a = at; a != nullptr && !known; a = a->get_parent()) {
          const auto names = option_names(*a);
          known = std::find(names.begin(), names.end(), name) != names.end();
        }
        if (!known)
          return "unknown option '" + name + "' for " + command_path(*at) + guess(name, option_names(*at)) +
                 " (" + command_path(*at) + " --help lists them)";
      }
      continue;
    }
    // A word: the next command while the current one has subcommands and none was given yet.
    const auto commands = command_names(*at);
    if (commands.empty()) continue;
    const auto it = std::find(commands.begin(), commands.end(), arg);
    if (it == commands.end())
      return "unknown command '" + arg + "'" + guess(arg, commands) + " (" + command_path(*at) + " --help lists them)";
    at = at->get_subcommand(arg);
  }
  return "";
}

}  // namespace gcpipe::cli
