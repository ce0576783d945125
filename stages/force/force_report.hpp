// Figures of the force along a program: the tool path coloured by the mean force, and the force
// and the engagement against time.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "path_force.hpp"

namespace gcpipe::force {

/// Tool-tip path in XY, each revolution's segment coloured by its mean force [N] (`resultant`
/// false: the radial and axial forces are not known, coloured by the mean tangential force).
void write_force_path_png(const std::filesystem::path& png, const PathForce& p, const std::string& title,
                          bool resultant = true);
/// Two panels against time: mean and peak force [N] (`resultant` false: the mean tangential
/// force [N]); radial depth ae and axial depth ap [mm].
void write_force_time_png(const std::filesystem::path& png, const PathForce& p, const std::string& title,
                          bool resultant = true);

/// A model's prediction against its reference series, sampled every `period` seconds.
void write_prediction_png(const std::filesystem::path& png, const std::vector<double>& reference,
                          const std::vector<double>& predicted, double period, const std::string& title,
                          const std::string& note, const std::string& ylabel);

/// Two panels against the program's time on the interpolator's clock (one value every `period`
/// seconds): a spindle model's prediction, with its mean over the cutting samples; the path feed
/// [mm/s] and the cutting flag the model was given.
void write_spindle_prediction_png(const std::filesystem::path& png, const std::vector<double>& predicted,
                                  const std::vector<double>& cutting, const std::vector<double>& feed, double period,
                                  const std::string& title, const std::string& note, const std::string& ylabel);

}  // namespace gcpipe::force
