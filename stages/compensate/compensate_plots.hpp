// Error figures of the batch job (PNG through OpenCV, via gcpipe_plot): tool path with the error
// magnified, ballbar-style polar plots of circles, contour error over time, per-axis following
// error,. Each function writes one file and throws
// std::runtime_error naming it when it cannot.
#pragma once

#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "compensate.hpp"

namespace gcpipe::compensate {

/// Workpiece-frame tool path: nominal, actual before and after, the error magnified so that the
/// largest "before" error is visible (the factor is in the title).
void plot_toolpath(const std::filesystem::path& png, const Evaluation& before, const Evaluation* after,
                   const std::string& title);

/// Ballbar-style polar plots, one panel per circle segment (up to 6): radial deviation of the
/// actual tool tip from the fitted nominal circle against the angle, magnified around the circle.
/// Returns false (writes nothing) when the program has no circle.
bool plot_ballbar(const std::filesystem::path& png, const Nominal& nominal, const Evaluation& before,
                  const Evaluation* after, const std::string& title);

/// Contour error over time, before and after [um].
void plot_contour_error(const std::filesystem::path& png, const Evaluation& before, const Evaluation* after,
                        const std::string& title, const Evaluation* feedforward = nullptr);

/// Per-axis following error (command - actual) over time, before above and after below
/// [um for X Y Z, mdeg for A C].
void plot_following_error(const std::filesystem::path& png, const Evaluation& before, const Evaluation* after,
                          const std::string& title);

}  // namespace gcpipe::compensate
