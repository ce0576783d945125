// LinuxCNC's interpreter as a judge: rs274 run on a program with a given control state (parameter
// file, tool table), its canonical calls read into moves in machine coordinates. Shared by
// tests/rs274_write_test.cpp (output.nc) and tests/rs274_compensated_test.cpp (compensated.nc).
#pragma once

#include <gtest/gtest.h>

#include <array>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace gcpipe::test::rs274 {

namespace fs = std::filesystem;

constexpr double kTol = 5e-4;  // [program units] two printed values of 4 decimals, summed

inline std::string rs274_path() {
  for (const char* p : {"/usr/bin/rs274", "/usr/local/bin/rs274"})
    if (fs::exists(p)) return p;
  return {};
}

struct Move {
  char kind = 'T';  // T traverse, F feed, A arc
  std::array<double, 6> end{};  // X Y Z [mm] A B C [deg], machine coordinates
  std::array<double, 2> centre{};  // arc: in its plane [mm], machine coordinates
  double feed = 0;  // feed moves [mm/min]
  int turn = 0;     // arc: rs274's rotation (> 0 counter-clockwise, |turn| - 1 extra full turns)
  int u = 0, w = 1;  // arc: its plane's first and second axis (centre[0], centre[1]); the normal is 3 - u - w
  double tol = kTol;  // [mm]
};

struct Rs274Run {
  std::vector<Move> moves;
  std::vector<std::string> rejected;  // messages and lines rs274 rejected
};

inline std::vector<double> numbers(const std::string& args) {
  std::vector<double> v;
  std::string s = args;
  for (char& c : s)
    if (c == ',') c = ' ';
  std::stringstream ss(s);
  for (double x; ss >> x;) v.push_back(x);
  return v;
}

// The canonical calls of one run, turned into moves in machine coordinates [mm].
class CanonReader {
 public:
  void call(const std::string& name, const std::string& args) {
    if (name == "USE_LENGTH_UNITS") scale_ = args.find("INCHES") != std::string::npos ? 25.4 : 1.0;
    else if (name == "SELECT_PLANE") plane_ = args;
    else if (name == "SET_FEED_RATE") feed_ = numbers(args).at(0);  // program units: scaled when it moves
    else if (name == "SET_G5X_OFFSET") store(g5x_, numbers(args), 1);
    else if (name == "SET_G92_OFFSET") store(g92_, numbers(args), 0);
    else if (name == "USE_TOOL_LENGTH_OFFSET") store(tool_, numbers(args), 0);
    else if (name == "STRAIGHT_TRAVERSE" || name == "STRAIGHT_FEED") straight(name == "STRAIGHT_FEED", numbers(args));
    else if (name == "ARC_FEED") arc(numbers(args));
  }
  std::vector<Move> moves;

 private:
  // Offsets in mm (linear) at the time they are set: a later G20/G21 does not change them.
  void store(std::array<double, 6>& to, const std::vector<double>& v, std::size_t first) {
    for (std::size_t i = 0; i < 6; ++i) to[i] = v.at(first + i) * (i < 3 ? scale_ : 1.0);
  }
  double machine(int axis, double program) const {
    return program * (axis < 3 ? scale_ : 1.0) + g5x_[axis] + g92_[axis] + tool_[axis];
  }
  void add(Move m) {
    m.tol = kTol * scale_;
    bool same = true;
    for (int a = 0; a < 6; ++a) same = same && std::fabs(m.end[a] - last_[a]) <= 1e-9;
    last_ = m.end;
    if (!same) moves.push_back(m);
  }
  void straight(bool feed, const std::vector<double>& v) {
    Move m;
    m.kind = feed ? 'F' : 'T';
    for (int a = 0; a < 6; ++a) m.end[a] = machine(a, v.at(a));
    m.feed = feed ? feed_ * scale_ : 0;
    add(m);
  }
  // ARC_FEED(first end, second end, first centre, second centre, turn, normal end, a, b, c, ...):
  // the plane's axes (XY: X Y, normal Z; XZ: Z X, normal Y; YZ: Y Z, normal X).
  void arc(const std::vector<double>& v) {
    const int u = plane_ == "CANON_PLANE_XY" ? 0 : plane_ == "CANON_PLANE_XZ" ? 2 : 1;
    const int w = plane_ == "CANON_PLANE_XY" ? 1 : plane_ == "CANON_PLANE_XZ" ? 0 : 2;
    const int n = 3 - u - w;
    Move m;
    m.kind = 'A';
    m.end[u] = machine(u, v.at(0));
    m.end[w] = machine(w, v.at(1));
    m.end[n] = machine(n, v.at(5));
    for (int a = 3; a < 6; ++a) m.end[a] = machine(a, v.at(a + 3));
    m.centre = {machine(u, v.at(2)), machine(w, v.at(3))};
    m.turn = static_cast<int>(v.at(4));
    m.u = u;
    m.w = w;
    m.feed = feed_ * scale_;
    add(m);
  }
  double scale_ = 1;
  std::string plane_ = "CANON_PLANE_XY";
  double feed_ = 0;
  std::array<double, 6> g5x_{}, g92_{}, tool_{}, last_{};
};

// rs274 on a copy of the text with M2 appended (see tests/rs274_diff_test.cpp: without an end,
// -n 0 repeats its complaint without end), in `dir`, with the parameter file `var` and the tool
// table `tbl` (both rewritten for each run: rs274 rewrites its parameter file at the end).
inline Rs274Run run(const fs::path& dir, const std::string& name, const std::string& text, const std::string& var_text,
                    const std::string& tbl_text) {
  fs::create_directories(dir);
  const fs::path program = dir / (name + ".ngc"), var = dir / "control.var", tbl = dir / "control.tbl";
  std::ofstream(program) << text << (text.empty() || text.back() == '\n' ? "" : "\n") << "M2\n";
  std::ofstream(var) << var_text;
  std::ofstream(tbl) << tbl_text;
  const fs::path out = dir / "rs274.out", err = dir / "rs274.err";
  const std::string cmd = "timeout 120 " + rs274_path() + " -n 0 -g -v '" + var.string() + "' -t '" + tbl.string() +
                          "' '" + program.string() + "' >'" + out.string() + "' 2>'" + err.string() + "'";
  Rs274Run r;
  if (std::system(cmd.c_str()) != 0) ADD_FAILURE() << "rs274 failed: " << cmd;
  static const std::regex canon(R"(^\s*\d+ N\S*\s+(\w+)\((.*)\)\s*$)");
  CanonReader reader;
  std::ifstream o(out);
  for (std::string line; std::getline(o, line);) {
    std::smatch m;
    if (std::regex_match(line, m, canon)) reader.call(m[1], m[2]);
  }
  r.moves = std::move(reader.moves);
  std::ifstream e(err);
  for (std::string line; std::getline(e, line);)
    if (line != "executing" && !line.empty()) r.rejected.push_back(line);
  return r;
}

}  // namespace gcpipe::test::rs274
