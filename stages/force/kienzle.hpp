// Kienzle's law for the tangential (main) cutting force of one edge, with the specific cutting
// force kc1 and exponent mc of the material groups of DIN/ISO 513 and VDI 3323:
//
//   kc = kc1 h^(-mc),   Ft = kc b h = kc1 b h^(1 - mc)
//
// (h the uncut chip thickness [mm], b the width of cut [mm]; kc1 is kc at h = 1 mm, b = 1 mm).
// The table is third-party data read from ../shared/data/force/vdi3323_kienzle.tsv at configure
// time into the build (CMakeLists.txt); its PROVENANCE.md says where it comes from and what it
// does not give: grade names, radial and axial forces, edge coefficients. Radial and axial forces
// come only from ratios Fr/Ft, Fa/Ft a user states with their source (ForceRatios).
//
// On a straight-fluted end mill an edge at immersion phi cuts h = c sin(phi) over b = a, so the
// mean over a revolution of the N-edge sum has the closed form (README sec. 2b)
//
//   mean Ft = N a kc1 c^p / (2 pi) * S_p(phi_st, phi_ex),   p = 1 - mc,   S_p = int sin^p.
#pragma once

#include <istream>
#include <string>
#include <vector>

#include "force_model.hpp"

namespace gcpipe::force {

/// One row of the table (columns as in vdi3323_kienzle.tsv).
struct KienzleGroup {
  int group = 0;               //!< VDI 3323 group number
  std::string iso;             //!< ISO 513 main group: P, M, N
  std::string material;        //!< the table's description of the group
  std::string condition;       //!< annealed, quenched and tempered, ...
  double tensile_N_mm2 = 0;    //!< typical tensile strength; 0 where the table leaves it blank
  double hardness_HB = 0;      //!< typical Brinell hardness
  double kc1 = 0;              //!< specific cutting force at h = 1 mm, b = 1 mm [N/mm^2]
  double mc = 0;               //!< chip-thickness exponent [-]
  std::string describe() const;  //!< "group 2 (P, non-alloy steel ..., annealed, 190 HB)"
};

/// The table's text, PROVENANCE.md and SHA-256 as generated into the build at configure time
/// (empty strings when the data folder was absent then).
struct EmbeddedKienzleTable {
  const char* tsv;
  const char* provenance;
  const char* sha256;
  const char* from;  //!< the file it was generated from
};
const EmbeddedKienzleTable& embedded_kienzle_table();

/// Parses the tab-separated table (header line first); throws std::runtime_error naming `name`,
/// the line and what is wrong.
std::vector<KienzleGroup> parse_kienzle_table(std::istream& in, const std::string& name);
/// The embedded table, parsed once; empty when the data were absent at configure time.
const std::vector<KienzleGroup>& kienzle_table();
/// The row of `group`; throws std::invalid_argument naming the groups the table has (or saying
/// that the table was not built in, and where it was looked for).
const KienzleGroup& kienzle_group(int group);
/// The "Source:" paragraph of the embedded PROVENANCE.md, on one line ("" without it).
std::string kienzle_source();

/// kc = kc1 h^-mc [N/mm^2] at chip thickness h > 0 [mm].
double specific_cutting_force(const KienzleGroup& g, double h);

/// Kienzle's law as a ForceLaw (force_model.hpp): p = 1 - mc, tangential chip coefficient kc1, no
/// edge term; radial and axial as the stated ratios of the tangential force, or unknown (nullptr).
ForceLaw kienzle_law(double kc1, double mc, const ForceRatios* ratios);

/// The VDI 3323 groups a grade falls in, as PROVENANCE.md states them (README sec. 1b): C45 / 1045
/// annealed 2, quenched_and_tempered 3; 42CrMo4 / 4140 quenched_and_tempered 7, 8 or 9 by
/// strength; 1018: 1; 316L: 14; H13 annealed: 10. `condition` "" when the grade has one only.
/// Throws std::invalid_argument naming the grades, or the conditions the grade has.
std::vector<int> grade_groups(const std::string& grade, const std::string& condition);

/// S_p(a, b) = integral of sin(phi)^p over [a, b], 0 <= a <= b <= pi, p > -1: a series in sin or
/// cos of the nearer end, whichever converges faster, and the complete integral
/// S_p(0, pi) = sqrt(pi) Gamma((p + 1) / 2) / Gamma(p / 2 + 1) (README sec. 2b).
double sine_power_integral(double p, double a, double b);

/// Mean over a revolution of the N-edge sum of Ft under Kienzle's law, closed form [N].
double kienzle_mean_tangential_force(double kc1, double mc, const Cut& cut);
/// The mean force vector in the feed frame with Fr = radial Ft, Fa = axial Ft, closed form [N].
Force3 kienzle_mean_force_closed_form(double kc1, double mc, const ForceRatios& ratios, const Cut& cut);

}  // namespace gcpipe::force
