// The IK stage's figures: neural against analytic joints along the program, and each solver's
// tool-tip error. PNG through OpenCV (gcpipe_plot); each function throws naming the file it
// cannot write.
#pragma once

#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include <cstdint>

#include "gcpipe/kinematics.hpp"

namespace gcpipe {

/// Neural and analytic IK along the program, one entry per IK point.
struct IkSeries {
  std::vector<double> index;                         //!< point number (x axis)
  std::array<std::vector<double>, kNumAxes> diff;    //!< neural - analytic [mm, deg]
  Axes tolerance{};                                  //!< divergence tolerance [mm, deg]
  std::vector<double> flagged;                       //!< point numbers flagged neural_diverged (a sample of them on a long program)
  std::uint64_t flagged_count = 0;                   //!< points flagged neural_diverged, all of them
  std::vector<double> tip_error_analytic;            //!< |FK(analytic) - programmed tip| [mm]
  std::vector<double> tip_error_neural;              //!< |FK(neural) - programmed tip| [mm]
  std::uint64_t neural_points = 0;                   //!< points the neural IK solved, all of them
                                                     //!< (the report's count; index holds a sample)
};

/// Neural minus analytic joints per axis along the path, with the tolerance band and flags.
void plot_ik_divergence(const std::filesystem::path& png, const IkSeries& s, const std::string& title);
/// Tool-tip error of each solver (mm, log axis) along the path.
void plot_ik_tip_error(const std::filesystem::path& png, const IkSeries& s, const std::string& title);

}  // namespace gcpipe
