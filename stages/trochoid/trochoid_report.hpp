// Analysis of an expanded tool path: radial engagement per block, path length, segment count, and
// the tool-path figure coloured by engagement. Works on any program (ours or another generator's).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "gcpipe/block.hpp"
#include "engagement.hpp"
#include "trochoid.hpp"

namespace gcpipe {

struct PathAnalysisOptions {
  double tool_radius = 10.0;    //!< r [mm]
  double sample_spacing = 0.1;  //!< lines split to this for the engagement queries [mm]
  /// Only feed moves ending at or below this Z are cut in the analysis plane; NaN = the deepest
  /// Z any feed move reaches (the floor of the last pass).
  double z_cut = std::numeric_limits<double>::quiet_NaN();
  double min_chip = kMinChip;   //!< chips thinner than this are not engagement [mm]
};

struct PathAnalysis {
  bool has_parts = false;         //!< TrochoidPart tags were given (our own expansion)
  std::size_t feed_moves = 0;     //!< G1/G2/G3 blocks in the whole program
  std::size_t rapid_moves = 0;    //!< G0 blocks
  double feed_length = 0;         //!< length of all feed moves, XYZ [mm]
  double rapid_length = 0;        //!< length of all rapids [mm]
  double z_cut = 0;               //!< analysis plane [mm]
  std::vector<double> block_angle;  //!< per input block: largest engagement angle, 0 if not cut [rad]
  double max_angle = 0;           //!< over blocks that are neither entry nor start circle [rad]
  double max_angle_all = 0;       //!< over all blocks [rad]
  std::size_t max_block = 0;      //!< index of the block with max_angle
  double max_air_angle = 0;       //!< over kAir blocks [rad]
  /// XY polyline of the analysed feed moves with the engagement of each segment (for plots).
  std::vector<double> x, y, angle;
  std::vector<std::size_t> block;   //!< input block each sample belongs to
  std::vector<std::size_t> breaks;  //!< indices in x/y where a new contiguous piece starts
};

/// `parts` may be null (another generator's program): then max_angle == max_angle_all.
PathAnalysis analyse_path(const std::vector<ResolvedBlock>& blocks,
                          const std::vector<TrochoidPart>* parts, const PathAnalysisOptions& opt);

/// Outline of a G275 slot in XY: the stadium of half-width W/2 around its axis (for figures).
std::vector<Point2> slot_outline(const TrochoidSlot& slot);

/// Tool path in XY coloured by the equivalent radial engagement ae [mm], as a PNG, with the
/// given outlines (slot walls) in grey. The figure takes the data's aspect ratio.
void write_engagement_png(const std::filesystem::path& png, const PathAnalysis& a,
                          double tool_radius, const std::string& title,
                          const std::vector<std::vector<Point2>>& outlines = {});

}  // namespace gcpipe
