// The `force:` section of a pipeline config: tool, material, spindle, stock and the force-aware
// feed. Every key, unit and range: stages/force/README.md sec. 5.
#pragma once

#include <array>
#include <filesystem>
#include <optional>
#include <string>

#include "force_model.hpp"
#include "kienzle.hpp"

namespace gcpipe {
class Config;
}

namespace gcpipe::force {

struct ToolSpec {
  double diameter = 20;               //!< D [mm]; the config's 0 = the tool table's (stage)
  int flutes = 3;                     //!< N
  double flute_length = 30;           //!< longest edge length in cut [mm]
  double stickout = 60;               //!< holder face to tip, the cantilever length L [mm]
  double modulus = 600;               //!< Young's modulus E of the tool [GPa] (carbide ~ 600)
  double effective_diameter_factor = 0.8;  //!< d_eff = factor * D for the fluted section's I
  double effective_diameter() const { return effective_diameter_factor * diameter; }
};

/// The work material: the force law and what the report says about where it comes from.
struct Material {
  ForceLaw law = material_coefficients("al7075");
  std::string source = material_coefficients("al7075").source;  //!< the mechanistic set's source
  std::optional<KienzleGroup> group;   //!< the VDI 3323 row, when the law is Kienzle's
  std::string grade;                   //!< "C45 annealed" as the config names it; "" when not named
  std::optional<ForceRatios> ratios;   //!< the stated Fr/Ft, Fa/Ft (Kienzle only)
  /// Radial and axial forces known: the resultant, its peak and the deflection can be reported.
  bool resultant_known() const { return law.radial_axial_known; }
};

struct ForceOptions {
  ToolSpec tool;
  Material material;
  double spindle_speed = 0;      //!< [rev/min]; 0 = the program's S word
  std::array<double, 5> stock{};  //!< xmin ymin xmax ymax top [mm]; all 0 = around the path
  double cell = 0.05;            //!< node spacing of the height field [mm]
  double sample_spacing = 0;     //!< path length between force samples [mm]; 0 = one spindle
                                 //!< revolution of travel (the planner wants finer: README)
  double target_force = 0;       //!< mean force the feed planner holds [N]; 0 = planner off
  double peak_force = 0;         //!< instantaneous force never exceeded [N]; 0 = 2 * target
  double max_feed_factor = 3;    //!< planned feed <= factor * programmed feed [-]
  double min_feed = 10;          //!< planned feed never below [mm/min]
  std::filesystem::path spindle_model;  //!< a model of gcpipe train-spindle (resolved); empty: none
};

/// Reads the section; throws ConfigError naming file, key, value and limit; unknown keys rejected.
ForceOptions load_force_options(const Config& section);

}  // namespace gcpipe::force
