// Stage `trochoid`: expands the G275 trochoidal slot cycle into G0/G1 (or G2/G3) blocks.
//
// The loops follow seed 000 eq. (6), x = V t + R cos(w t), y = R sin(w t), written in the slot's
// own frame: u runs from the slot start S to its end E, n is u turned +90 deg in XY. With the
// loop radius R = (W - D) / 2 and the step per revolution K (V = K / 2pi per radian of phase):
//
//   P(phi) = S + a(phi) u + R (cos(phi) u + sigma sin(phi) n)       sigma = +1 CCW, -1 CW
//
// a(phi) is the advance of the loop centre: constant speed V between one revolution of smooth
// acceleration and one of smooth deceleration (a' and a'' continuous, so the curvature of the path
// is continuous along all loops, seed 000 Sec. 3.2). The slot is the stadium of half-width W/2
// around the segment S-E; one full circle at S and one at E clear its round ends. Maths, the
// Table 4 mapping and every figure: stages/trochoid/README.md.
//
// Per-block problems (impossible geometry) return a status and never throw; a bad config throws
// ConfigError.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gcpipe/block.hpp"
#include "gcpipe/diagnostic.hpp"

namespace gcpipe {

class Config;

enum class TrochoidEntry : std::uint8_t {
  kHelix,   //!< helix of the loop radius around S, descending at entry_angle
  kRamp,    //!< zig-zag ramp along the slot axis at entry_angle, then a lead-in half circle
  kPlunge,  //!< straight down at S (centre-cutting tool), then a lead-in half circle
};

/// The `trochoid:` section of a pipeline config (every key in stages/trochoid/README.md).
struct TrochoidOptions {
  double chord_tolerance = 0.001;  //!< max distance output path <-> true curve [mm]
  bool arcs = false;               //!< emit G2/G3 (fitted within chord_tolerance) instead of G1
  TrochoidEntry entry = TrochoidEntry::kHelix;
  double entry_angle_deg = 3.0;    //!< descent angle of helix and ramp [deg]
  double entry_feed_factor = 0.5;  //!< entry feed = factor * F [-]
  double air_feed_factor = 2.0;    //!< feed on the part of each loop that cuts nothing = factor*F
  double air_feed = 0.0;           //!< absolute air feed [mm/min]; 0 = use air_feed_factor
  double air_margin_deg = 10.0;    //!< the air stretch starts/ends this far inside the computed
                                   //!< zero-engagement arc [deg]
  double approach_clearance = 1.0; //!< rapid down to this height above the previous pass [mm]
  double max_engagement_fraction = 0.25;  //!< reject steps whose radial engagement ae > this*D
  double max_axial_depth_factor = 2.0;    //!< reject passes deeper than this * D
  /// The engagement report and figure analyse the expanded cycles of a program together, in time
  /// that grows with the square of cycles cut over one another (2 seed 000 slots: 17 s, 25: hours);
  /// past this many blocks they are left out, with the key named, and no more blocks are kept.
  std::size_t max_report_blocks = 50000;
};

/// Reads the `trochoid` section; throws ConfigError naming key, value and limit.
TrochoidOptions load_trochoid_options(const Config& section);

/// Which part of the cycle an output block belongs to (for analysis and plots).
enum class TrochoidPart : std::uint8_t {
  kApproach,     //!< rapids and retracts between passes
  kEntry,        //!< helix, ramp or plunge and the lead-in
  kStartCircle,  //!< full circle at S clearing the start cap
  kLoops,        //!< the trochoid: acceleration, constant step, deceleration (cutting part)
  kAir,          //!< the part of a loop that cuts nothing, at the air feed
  kEndCircle,    //!< full circle at E clearing the end cap
  kExit,         //!< lead-out half circle and retract
};
const char* to_string(TrochoidPart p);

/// Everything the path generator needs, derived from one G275 block and the options.
struct SlotGeometry {
  double sx = 0, sy = 0;      //!< slot start S (centre of the start cap) [mm]
  double ex = 0, ey = 0;      //!< slot end E [mm]
  double ux = 1, uy = 0;      //!< unit vector S -> E
  double length = 0;          //!< |E - S| [mm]
  double loop_radius = 0;     //!< R = (W - D) / 2 [mm]
  double tool_radius = 0;     //!< r = D / 2 [mm]
  double step = 0;            //!< K: nominal advance per revolution [mm]
  double speed = 0;           //!< V = K_eff / 2pi: advance per radian of phase [mm/rad]
  double sigma = 1;           //!< +1 counter-clockwise loops, -1 clockwise
  double phase0 = 0;          //!< phase of the first loop point (pi/2: at a wall) [rad]
  double cruise_phase = 0;    //!< phase span of the constant-speed stretch [rad]
  // Phase at which each stretch begins: start circle, acceleration, cruise, deceleration, end
  // circle, end of the end circle.
  double phi_start_circle = 0, phi_accel = 0, phi_cruise = 0, phi_decel = 0, phi_end_circle = 0,
         phi_end = 0;

  /// Advance of the loop centre along u at phase phi [mm].
  double advance(double phi) const;
  /// Tool-centre point at phase phi in XY [mm].
  void point(double phi, double& x, double& y) const;
};

/// Builds the geometry of a validated cycle (see TrochoidExpander::validate).
SlotGeometry make_slot_geometry(const TrochoidSlot& slot, bool spindle_ccw);

/// Radial engagement of the steady-state loops, computed exactly (circle intersections, see
/// engagement.hpp) for an infinitely long slot.
struct SteadyEngagement {
  double max_angle = 0;      //!< largest tool engagement angle [rad]
  double max_ae = 0;         //!< r (1 - cos(max_angle)) [mm]
  double phase_of_max = 0;   //!< loop phase where it occurs (0 = front of the loop) [rad]
  double air_begin = 0;      //!< zero-engagement arc of each loop, phase from .. [rad]
  double air_end = 0;        //!< .. to, in (0, 2pi); air_end <= air_begin when there is none
};
SteadyEngagement steady_engagement(double loop_radius, double step, double tool_radius);

/// Closed form at the front of the loop (phase 0), the previous loop's outline taken as a circle
/// of radius R + r around the centre one step back: cos(theta) = (2R(r-K) - K^2) / (2(R+K) r).
/// It underestimates: the largest engagement occurs before the front (README). [rad]
double engagement_angle_front(double loop_radius, double step, double tool_radius);
/// The same circle model maximised over the phase (engaged angle = alpha(phi) + delta(phi),
/// README "Engagement"). [rad]
double engagement_angle_estimate(double loop_radius, double step, double tool_radius);
/// Largest step with ae = r (1 - cos theta_front) <= f * D, closed form:
/// K = -(R + (1 - 2f) r) + sqrt((R + (1 - 2f) r)^2 + 4 f R r)   [mm]
double step_bound_front(double loop_radius, double tool_radius, double fraction);
/// Largest step with the phase-maximised circle model's ae <= f * D (bisection) [mm].
double step_bound_estimate(double loop_radius, double tool_radius, double fraction);
/// Largest step with the exact steady engagement ae <= f * D, by bisection [mm].
double step_bound_exact(double loop_radius, double tool_radius, double fraction);
/// Height of the cusp left on a wall between two loops touching it one step apart, the swept
/// outline there being a circle of radius rho = (R -+ V)^2 / R + r:  h = rho - sqrt(rho^2 - K^2/4)
double wall_scallop_height(double loop_radius, double step, double tool_radius, bool backward_wall);

/// Expands G275 blocks; every other block is copied through unchanged. One instance per program
/// (it keeps no state between blocks, but owns its options).
class TrochoidExpander {
 public:
  struct Status {
    enum class Code : std::uint8_t { kCopied, kExpanded, kRejected };
    Code code = Code::kCopied;
    std::string message;  //!< why a cycle was rejected: names the word, its value and the limit
    bool ok() const { return code != Code::kRejected; }
  };

  explicit TrochoidExpander(TrochoidOptions options = {});

  /// Appends the expansion of `in` to `out` (or `in` itself when it is no cycle). On kRejected
  /// nothing is appended. Every output block carries in.line, in.text and in's modal state.
  /// `parts`, when given, receives one TrochoidPart per appended block.
  Status expand(const ResolvedBlock& in, std::vector<ResolvedBlock>& out,
                std::vector<TrochoidPart>* parts = nullptr) const;

  /// For a rejected cycle: appends rapids that take the tool where the parser's modal state puts
  /// it after the cycle (up to max(start Z, R), over to the target, down to its Z), so that the
  /// rest of the program starts where it expects. Nothing is cut.
  void skip(const ResolvedBlock& in, std::vector<ResolvedBlock>& out) const;

  /// A lower bound of the machine time [s] of the cycle's expansion, from its geometry alone (no
  /// block is made): the loops of every pass at the feeds expand() gives them, measured along
  /// chords (never longer than the path); entry, lead-out, rapids and acceleration left out. 0
  /// for a block that is no cycle or that validate() rejects. stages/trochoid/README.md §2.3.
  double feed_time_lower_bound(const ResolvedBlock& in) const;

  /// Checks a cycle's geometry; empty string when it can be machined, else the reason.
  std::string validate(const ResolvedBlock& in) const;

  /// One block through the stage, exactly as every runner (gcpipe batch, gcpipe trochoid, the DDS
  /// node) handles it: the expansion; or, for a rejected cycle, the skip moves, with `diag` set
  /// to the error to report before them (file:line, "G275 rejected: reason"). Returns the status.
  Status step(const ResolvedBlock& in, const std::string& file, std::vector<ResolvedBlock>& out,
              Diagnostic& diag, std::vector<TrochoidPart>* parts = nullptr) const;

  const TrochoidOptions& options() const { return opt_; }

 private:
  TrochoidOptions opt_;
};

}  // namespace gcpipe
