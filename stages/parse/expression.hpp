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

/// Numbered (#1..#5602, LinuxCNC's range) and named (#<name>) parameters. Names are case-insensitive, spaces ignored.
///
/// Named parameters are scoped as in LinuxCNC: a name with a leading underscore (`#<_depth>`) is
/// global; any other is local to the subroutine call that set it (the main program is a level of
/// its own), so a recursive subroutine keeps each call's `#<level>` and a caller never sees its
/// callee's names. enter_call()/leave_call() bracket each o-word call.
///
/// Fanuc Custom Macro B has vacant ("null") variables: #0 always, and every variable that was never
/// set or was set from a vacant one. With enable_vacancy() (dialect fanuc) the store keeps that
/// state and #0 reads as vacant; without it (LinuxCNC) a parameter never set reads 0, as rs274's.
class ParameterStore {
 public:
  static constexpr int kMaxNumbered = 5602;
  /// The control's offsets a program may read (compensated.nc's guard does): the G54..G59 origins
  /// (#5221 + 20 k, axes X Y Z A C), LinuxCNC's system in use #5220, G92 flag #5210, tool in the
  /// spindle #5400 and its length #5403, Fanuc's tool length in force #5081..#5085 and external
  /// work offset #5201..#5205 (0: gcpipe's machine file has none). Set from the parser's
  /// state before each expression; a program cannot set them (G10 L2 / G43 H do).
  static bool is_offset_parameter(int n, bool fanuc);
  bool get_numbered(int n, double& v) const;  //!< false when out of range (#0 is in range with vacancy)
  bool get_named(const std::string& name, double& v) const;  //!< false when never set
  void set_numbered(int n, double v);
  void set_named(const std::string& name, double v);
  void enter_call() { local_named_.emplace_back(); }  //!< a call starts with no local names
  void leave_call() {                                  //!< the call's local names are gone
    if (local_named_.size() > 1) local_named_.pop_back();
  }
  static bool is_global_name(const std::string& name) { return !name.empty() && name[0] == '_'; }
  void enable_vacancy() { vacancy_ = true; }
  bool vacancy() const { return vacancy_; }
  /// With vacancy: #n holds no value (never set, set from a vacant value, or n = 0).
  bool vacant(int n) const { return vacancy_ && (n == 0 || set_[static_cast<std::size_t>(n)] == 0); }
  void set_vacant(int n) { numbered_[static_cast<std::size_t>(n)] = 0, set_[static_cast<std::size_t>(n)] = 0; }

 private:
  std::vector<double> numbered_ = std::vector<double>(kMaxNumbered + 1, 0.0);
  std::vector<std::uint8_t> set_ = std::vector<std::uint8_t>(kMaxNumbered + 1, 0);
  std::unordered_map<std::string, double> global_named_;
  // One map of local names per call level; [0] is the main program's.
  std::vector<std::unordered_map<std::string, double>> local_named_ =
      std::vector<std::unordered_map<std::string, double>>(1);
  std::unordered_map<std::string, double>& named_map(const std::string& name) {
    return is_global_name(name) ? global_named_ : local_named_.back();
  }
  const std::unordered_map<std::string, double>& named_map(const std::string& name) const {
    return is_global_name(name) ? global_named_ : local_named_.back();
  }
  bool vacancy_ = false;
};

/// A pending assignment: LinuxCNC applies all of a line's assignments after the line is read.
struct Assignment {
  bool named = false;
  int number = 0;
  std::string name;
  double value = 0;
  bool vacant = false;  //!< Fanuc: `#2 = #1` with #1 vacant leaves #2 vacant
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
  /// The value just read is a vacant variable as it stands (`#1`, `[#1]`, `-#1` with #1 vacant;
  /// Fanuc only). An operation on it uses 0 and is not vacant: `#1 * 5` is 0 (0i-MF manual
  /// B-64604EN, Custom Macro, "Null variables").
  bool vacant() const { return vacant_; }
  const std::string& error() const { return error_; }
  std::size_t error_pos() const { return error_pos_; }

 private:
  bool expression(std::string_view s, std::size_t& p, double& out, int depth);  // inside [ ]
  bool binary(std::string_view s, std::size_t& p, double& out, int precedence, int depth);
  bool unary(std::string_view s, std::size_t& p, double& out, int depth);
  bool function(std::string_view s, std::size_t& p, double& out, int depth, bool& matched);
  bool number(std::string_view s, std::size_t& p, double& out);
  bool parameter(std::string_view s, std::size_t& p, double& out, int depth);
  bool fail(std::size_t pos, std::string msg);
  const ParameterStore& params_;
  std::string error_;
  std::size_t error_pos_ = 0;
  bool vacant_ = false;  //!< of the value the innermost read just produced
};

/// Lower-cases and removes blanks: LinuxCNC's rule for parameter names.
std::string normalise_parameter_name(std::string_view raw);

}  // namespace gcpipe
