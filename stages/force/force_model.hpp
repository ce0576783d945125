// Mechanistic milling force of a straight-fluted (zero helix) end mill, after Altintas,
// Manufacturing Automation (2nd ed., 2012), ch. 2 "Mechanics of milling": each engaged tooth
// cuts a chip h(phi) = c sin(phi) (c = feed per tooth, phi = immersion angle measured clockwise
// from the feed normal) and feels
//
//   Ft = Ktc a h + Kte a,   Fr = Krc a h + Kre a,   Fa = Kac a h + Kae a
//
// (tangential, radial, axial; cutting coefficients K.c [N/mm^2] on the chip area, edge
// coefficients K.e [N/mm] on the edge length in cut). Resolved in the feed frame (x along the
// feed, y along the feed normal on the side where phi = 0, z along the spindle):
//
//   Fx = -Ft cos(phi) - Fr sin(phi),   Fy = Ft sin(phi) - Fr cos(phi),   Fz = Fa.
//
// Derivations, the closed-form mean forces and the checks: stages/force/README.md.
#pragma once

#include <array>
#include <functional>
#include <string>

namespace gcpipe::force {

/// Cutting and edge coefficients of one tool/material pair, with where they come from.
struct CuttingCoefficients {
  double Ktc = 0, Krc = 0, Kac = 0;  //!< cutting coefficients [N/mm^2]
  double Kte = 0, Kre = 0, Kae = 0;  //!< edge coefficients [N/mm]
  std::string source;                //!< publication the values were taken from
};

/// The shipped coefficient sets by name ("al7075"); throws std::invalid_argument otherwise.
CuttingCoefficients material_coefficients(const std::string& name);

/// Tangential, radial and axial components of an edge's force (or of a coefficient of it).
struct EdgeForce {
  double tangential = 0, radial = 0, axial = 0;
};

/// Radial and axial force as fractions of the tangential force that a user states, with where
/// they come from (a law that gives the tangential force only, such as Kienzle's, needs them).
struct ForceRatios {
  double radial = 0;   //!< Fr / Ft
  double axial = 0;    //!< Fa / Ft
  std::string source;  //!< where the ratios come from (into the report)
};

/// The force on one edge per mm of edge length in cut, at chip thickness h [mm]:
///
///   F(h) = chip * h^p + edge        (each of tangential, radial, axial)
///
/// The mechanistic model is p = 1, chip = (Ktc, Krc, Kac), edge = (Kte, Kre, Kae). Kienzle's law
/// (kienzle.hpp) is p = 1 - mc, chip = kc1 (1, Fr/Ft, Fa/Ft), edge = 0; without stated ratios only
/// the tangential component is known (radial_axial_known false; radial and axial are 0 then and
/// nothing that depends on them may be reported).
struct ForceLaw {
  EdgeForce chip;               //!< [N/mm^(1+p)]: N per mm of edge per mm^p of chip thickness
  EdgeForce edge;               //!< [N/mm]
  double feed_exponent = 1;     //!< p
  bool radial_axial_known = true;

  ForceLaw() = default;
  ForceLaw(const CuttingCoefficients& k);  // NOLINT(google-explicit-constructor): a set is a law
  /// h^p; 0 for h <= 0 when p != 1 (a power law has no negative chip; the affine law keeps h).
  double chip_factor(double h) const;
};

/// Force on the cutter in the feed frame [N].
struct Force3 {
  double x = 0, y = 0, z = 0;
  double norm() const;
};

/// Cutting conditions of one tooth pass: straight flutes, constant axial depth.
struct Cut {
  int flutes = 2;                 //!< N
  double feed_per_tooth = 0.05;   //!< c [mm]
  double axial_depth = 1;         //!< a [mm]
  double phi_start = 0;           //!< entry immersion angle [rad]
  double phi_exit = 0;            //!< exit immersion angle [rad]
};

/// Entry and exit angles of a straight cut of radial depth ae with a tool of diameter D.
/// Up (conventional) milling: [0, acos(1 - 2 ae/D)]; down (climb): [pi - acos(1 - 2 ae/D), pi].
std::array<double, 2> immersion_angles(double radial_depth, double diameter, bool climb);

/// Force on one tooth at immersion phi (zero outside [phi_start, phi_exit]) [N].
Force3 tooth_force(const ForceLaw& law, const Cut& cut, double phi);
/// Sum over the N teeth when tooth 0 is at rotation angle phi [N].
Force3 instantaneous_force(const ForceLaw& law, const Cut& cut, double phi);
/// Mean force over one revolution in closed form (Altintas ch. 2; README sec. 2) [N].
Force3 mean_force_closed_form(const CuttingCoefficients& k, const Cut& cut);
/// Mean tangential force summed over the teeth, so mean torque = D/2 times it [N].
double mean_tangential_force(const CuttingCoefficients& k, const Cut& cut);

/// An engagement that varies around the tool: axial depth of material a(phi) >= 0 [mm] at the
/// immersion phi in [0, 2 pi); a(phi) = 0 where the tooth is in air.
using AxialProfile = std::function<double(double phi)>;

/// Mean force and largest instantaneous resultant over one revolution for a tool whose engaged
/// edge length varies with the immersion (numerical: `steps` points per revolution).
/// The mean is affine in c^p (p = the law's feed_exponent): mean = c^p mean_per_feed + edge part.
struct RevolutionForce {
  Force3 mean;            //!< mean force vector [N]
  Force3 mean_per_feed;   //!< the part proportional to c^p, per unit c^p [N/mm^p] (p = 1: d mean / d c)
  double peak = 0;        //!< largest |F| over the revolution [N]
  double mean_tangential = 0;  //!< mean sum of Ft (torque / radius) [N]
};
RevolutionForce revolution_force(const ForceLaw& law, int flutes, double feed_per_tooth,
                                 const AxialProfile& depth, int steps = 720);

/// Largest feed per tooth whose mean force |c m1 + m0| stays at or under `target` (m1 the part
/// proportional to c, m0 the edge part), solving the quadratic; `c_max` when it never reaches it.
double feed_for_mean_force(const Force3& m1, const Force3& m0, double target, double c_max);

/// Static deflection of the tool tip as a cantilever clamped at the holder: delta = F L^3 / (3 E I),
/// I = pi d^4 / 64 with d the effective diameter of the fluted tool [mm].
double cantilever_deflection(double force_N, double stickout_mm, double modulus_GPa,
                             double effective_diameter_mm);

}  // namespace gcpipe::force
