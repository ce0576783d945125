// Error figures of the batch job (PNG through OpenCV, via gcpipe_plot): tool path with the error
// magnified, ballbar-style polar plots of circles, contour error along the programmed path,
// per-axis following error. Each function writes one file and throws std::runtime_error naming it
// when it cannot.
//
// Every figure takes the runs it compares as a list, each with its role (plot::Role: before,
// feed-forward, after), drawn in the role's colour in that order: a third run slots in as one
// more entry.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "compensate.hpp"
#include "plot.hpp"

namespace gcpipe::compensate {

/// One simulated run of a figure. `before` runs on the control's clock (tick n is raw sample n of
/// the nominal run); the compensated program and a feed-forward run run on the reference's
/// (tick n has reached raw sample Nominal::progress[n]).
struct FigureRun {
  plot::Role role = plot::Role::kBefore;
  const Evaluation* evaluation = nullptr;
  bool on_reference_clock = false;
  std::string what;  //!< a few words for the legend ("control runs the original")
};
using FigureRuns = std::vector<FigureRun>;

/// The programmed tool-tip path length [mm] the original has run at the place of the part each
/// point of `run`'s series stands for: the axis on which the runs of different clocks line up.
/// Empty when the nominal run no longer holds what it takes (its progress was released).
std::vector<double> programmed_path_length(const Model& model, const Nominal& nominal, const FigureRun& run);

/// How toolpath.png shows the whole path: the plane ("XY", "XZ" or "YZ") and the deviation's
/// magnification (report.json simulation.toolpath_figure, in batch and in a DDS node alike).
struct ToolpathView {
  std::string plane;
  double magnification = 1;
};
ToolpathView toolpath_view(const Nominal& nominal, const FigureRuns& runs);

/// Workpiece-frame tool path in the plane holding most of the first run's deviation on cutting
/// moves (XY, XZ or YZ; rapids are not the part's error):
/// nominal and every run, the deviation from the nominal magnified by a factor chosen so that the
/// largest error is visible, stated in the figure; beside it a 20 mm window around that error.
void plot_toolpath(const std::filesystem::path& png, const Nominal& nominal, const FigureRuns& runs,
                   const std::string& title);

/// Ballbar-style polar plots, one panel per circle segment (up to 6): radial deviation of the
/// actual tool tip from the fitted nominal circle against the angle, magnified around the circle.
/// Returns false (writes nothing) when the program has no circle.
bool plot_ballbar(const std::filesystem::path& png, const Nominal& nominal, const FigureRuns& runs,
                  const std::string& title);

/// Contour error [um] on a log axis against the programmed path length, every run on that one
/// axis (time when the nominal's progress is gone).
void plot_contour_error(const std::filesystem::path& png, const Model& model, const Nominal& nominal,
                        const FigureRuns& runs, const std::string& title);

/// Per-axis following error (command - actual) over time, one panel per run [um for X Y Z, mdeg
/// for A C]; axes that do not move (or are modelled as ideal) are named as such, not drawn.
void plot_following_error(const std::filesystem::path& png, const Model& model, const FigureRuns& runs,
                          const std::string& title);

}  // namespace gcpipe::compensate
