// LinuxCNC-style expressions and parameters: `[1 + 2 * #3]`, `sqrt[2]`, `#<name>`, `#5 = 1`.
//
// Needed for real programs (LinuxCNC's own arc-tolerance tests are written with them) and kept
// separate from the word scanner so that the plain-number hot path never touches it.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace gcpipe {

/// Numbered (#1..#5399) and named (#<name>) parameters. Names are case-insensitive, spaces ignored.
class ParameterStore {
 public:
  static constexpr int kMaxNumbered = 5399;
  bool get_numbered(int n, double& v) const;  //!< false when out of range
  bool get_named(const std::string& name, double& v) const;  //!< false when never set
  void set_numbered(int n, double v);
  void set_named(const std::string& name, double v);

 private:
  std::vector<double> numbered_ = std::vector<double>(kMaxNumbered + 1, 0.0);
  std::unordered_map<std::string, double> named_;
};

/// A pending assignment: LinuxCNC applies all of a line's assignments after the line is read.
struct Assignment {
  bool named = false;
  int number = 0;
  std::string name;
  double value = 0;
};

/// Reads one value at `pos` in `line`: a bracketed expression, a parameter reference, or a
/// function call such as `sqrt[2]`. On error returns false with `error` and `error_pos` set.
/// Whitespace inside is ignored.
class ExpressionReader {
 public:
  explicit ExpressionReader(const ParameterStore& params) : params_(params) {}
  bool read_value(std::string_view line, std::size_t& pos, double& out);
  /// Reads an expression without outer brackets, as Fanuc Macro B writes them (`#1 = #2 + 3`).
  bool read_expression(std::string_view line, std::size_t& pos, double& out);
  /// Reads `#n` or `#<name>` as an assignment target (after '#').
  bool read_target(std::string_view line, std::size_t& pos, Assignment& target);
  const std::string& error() const { return error_; }
  std::size_t error_pos() const { return error_pos_; }

 private:
  bool expression(std::string_view s, std::size_t& p, double& out, int depth);  // inside [ ]
  bool binary(std::string_view s, std::size_t& p, double& out, int precedence, int depth);
  bool unary(std::string_view s, std::size_t& p, double& out, int depth);
  bool number(std::string_view s, std::size_t& p, double& out);
  bool parameter(std::string_view s, std::size_t& p, double& out, int depth);
  bool fail(std::size_t pos, std::string msg);
  const ParameterStore& params_;
  std::string error_;
  std::size_t error_pos_ = 0;
};

/// Lower-cases and removes blanks: LinuxCNC's rule for parameter names.
std::string normalise_parameter_name(std::string_view raw);

}  // namespace gcpipe
