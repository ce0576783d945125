#include "force_model.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>

namespace gcpipe::force {

namespace {
constexpr double kPi = std::numbers::pi;
constexpr double kTwoPi = 2 * std::numbers::pi;

/// Angle folded into [0, 2 pi).
double wrap(double phi) {
  double w = std::fmod(phi, kTwoPi);
  return w < 0 ? w + kTwoPi : w;
}
}  // namespace

CuttingCoefficients material_coefficients(const std::string& name) {
  if (name == "al7075") {
    // Al7075-T6, carbide end mill, dry: the set identified by Altintas' group and printed in
    // the review by Cheng et al., "Milling Force Model for Aviation Aluminum Alloy: Academic
    // Insight and Perspective Analysis", Chin. J. Mech. Eng. 34 (2021) 93, Table 5, row [190].
    // README sec. 1 says why this table and not the book page itself.
    return {767.01, 168.8, 222.0, 27.7, 26.6, 0.7,
            "Al7075-T6, Cheng et al. CJME 34 (2021) 93, Table 5 row [190] (Altintas' mechanistic "
            "set): Ktc 767.01 Krc 168.8 Kac 222 N/mm^2, Kte 27.7 Kre 26.6 Kae 0.7 N/mm"};
  }
  throw std::invalid_argument("unknown material '" + name + "' (shipped: al7075; or give the six "
                              "coefficients with material: custom)");
}

ForceLaw::ForceLaw(const CuttingCoefficients& k)
    : chip{k.Ktc, k.Krc, k.Kac}, edge{k.Kte, k.Kre, k.Kae}, feed_exponent(1), radial_axial_known(true) {}

double ForceLaw::chip_factor(double h) const {
  if (feed_exponent == 1) return h;
  return h > 0 ? std::pow(h, feed_exponent) : 0.0;
}

double Force3::norm() const { return std::sqrt(x * x + y * y + z * z); }

std::array<double, 2> immersion_angles(double radial_depth, double diameter, bool climb) {
  const double ratio = std::clamp(radial_depth / diameter, 0.0, 1.0);
  const double sweep = std::acos(1 - 2 * ratio);  // pi for a full slot
  if (climb) return {kPi - sweep, kPi};
  return {0.0, sweep};
}

Force3 tooth_force(const ForceLaw& law, const Cut& cut, double phi) {
  const double p = wrap(phi);
  if (p < cut.phi_start || p > cut.phi_exit) return {};
  const double s = std::sin(p), c = std::cos(p);
  const double hp = law.chip_factor(cut.feed_per_tooth * s);
  const double a = cut.axial_depth;
  const double ft = law.chip.tangential * a * hp + law.edge.tangential * a;
  const double fr = law.chip.radial * a * hp + law.edge.radial * a;
  const double fa = law.chip.axial * a * hp + law.edge.axial * a;
  return {-ft * c - fr * s, ft * s - fr * c, fa};
}

Force3 instantaneous_force(const ForceLaw& law, const Cut& cut, double phi) {
  Force3 sum;
  const double pitch = kTwoPi / cut.flutes;
  for (int j = 0; j < cut.flutes; ++j) {
    const Force3 f = tooth_force(law, cut, phi + j * pitch);
    sum.x += f.x;
    sum.y += f.y;
    sum.z += f.z;
  }
  return sum;
}

Force3 mean_force_closed_form(const CuttingCoefficients& k, const Cut& cut) {
  // Integrals of one tooth's force over [phi_st, phi_ex], times N / 2 pi (README sec. 2).
  const double N = cut.flutes, a = cut.axial_depth, c = cut.feed_per_tooth;
  const auto x_at = [&](double p) {
    return N * a * c / (8 * kPi) * (k.Ktc * std::cos(2 * p) - k.Krc * (2 * p - std::sin(2 * p))) +
           N * a / (2 * kPi) * (-k.Kte * std::sin(p) + k.Kre * std::cos(p));
  };
  const auto y_at = [&](double p) {
    return N * a * c / (8 * kPi) * (k.Ktc * (2 * p - std::sin(2 * p)) + k.Krc * std::cos(2 * p)) -
           N * a / (2 * kPi) * (k.Kte * std::cos(p) + k.Kre * std::sin(p));
  };
  const auto z_at = [&](double p) {
    return N * a / (2 * kPi) * (-k.Kac * c * std::cos(p) + k.Kae * p);
  };
  const double s = cut.phi_start, e = cut.phi_exit;
  return {x_at(e) - x_at(s), y_at(e) - y_at(s), z_at(e) - z_at(s)};
}

double mean_tangential_force(const CuttingCoefficients& k, const Cut& cut) {
  const double N = cut.flutes, a = cut.axial_depth, c = cut.feed_per_tooth;
  return N * a / (2 * kPi) *
         (k.Ktc * c * (std::cos(cut.phi_start) - std::cos(cut.phi_exit)) +
          k.Kte * (cut.phi_exit - cut.phi_start));
}

RevolutionForce revolution_force(const ForceLaw& law, int flutes, double feed_per_tooth,
                                 const AxialProfile& depth, int steps) {
  // Sample the edge length in cut once per immersion angle; the tooth force is affine in c^p
  // (h^p = c^p sin^p), so the chip part (per unit c^p) and the edge part are accumulated apart
  // for the feed planner.
  RevolutionForce out;
  const double dphi = kTwoPi / steps;
  const EdgeForce& k = law.chip;
  const EdgeForce& e = law.edge;
  const double cp = law.chip_factor(feed_per_tooth);
  std::vector<Force3> cut_part(steps), edge_part(steps);
  for (int i = 0; i < steps; ++i) {
    const double phi = (i + 0.5) * dphi;
    const double a = depth(phi);
    const double s = std::sin(phi), co = std::cos(phi);
    const double sp = law.chip_factor(s);  // sin^p: the chip per unit c^p
    cut_part[i] = {a * sp * (-k.tangential * co - k.radial * s), a * sp * (k.tangential * s - k.radial * co),
                   a * sp * k.axial};
    edge_part[i] = {a * (-e.tangential * co - e.radial * s), a * (e.tangential * s - e.radial * co), a * e.axial};
    out.mean_tangential += a * (k.tangential * cp * sp + e.tangential);
  }
  const int pitch_steps = steps / flutes;  // teeth are `steps / flutes` samples apart
  Force3 m0;
  for (int i = 0; i < steps; ++i) {
    Force3 f;
    for (int j = 0; j < flutes; ++j) {
      const int at = (i + j * pitch_steps) % steps;
      f.x += cp * cut_part[at].x + edge_part[at].x;
      f.y += cp * cut_part[at].y + edge_part[at].y;
      f.z += cp * cut_part[at].z + edge_part[at].z;
    }
    out.peak = std::max(out.peak, f.norm());
    out.mean_per_feed.x += cut_part[i].x; out.mean_per_feed.y += cut_part[i].y; out.mean_per_feed.z += cut_part[i].z;
    m0.x += edge_part[i].x; m0.y += edge_part[i].y; m0.z += edge_part[i].z;
  }
  // Mean over a revolution of the N-tooth sum = N / (2 pi) * integral of one tooth = N/steps * sum.
  const double w = static_cast<double>(flutes) / steps;
  out.mean_per_feed = {w * out.mean_per_feed.x, w * out.mean_per_feed.y, w * out.mean_per_feed.z};
  out.mean = {cp * out.mean_per_feed.x + w * m0.x, cp * out.mean_per_feed.y + w * m0.y,
              cp * out.mean_per_feed.z + w * m0.z};
  out.mean_tangential *= w;
  return out;
}

double feed_for_mean_force(const Force3& m1, const Force3& m0, double target, double c_max) {
  // |c m1 + m0|^2 = target^2:  A c^2 + 2 B c + C = 0 with A = m1.m1, B = m1.m0, C = m0.m0 - T^2.
  const double A = m1.x * m1.x + m1.y * m1.y + m1.z * m1.z;
  const double B = m1.x * m0.x + m1.y * m0.y + m1.z * m0.z;
  const double C = m0.x * m0.x + m0.y * m0.y + m0.z * m0.z - target * target;
  if (A <= 0) return c_max;  // nothing cuts: the feed is free
  if (C >= 0) return 0.0;    // the edge forces alone reach the target
  const double c = (-B + std::sqrt(B * B - A * C)) / A;  // the positive root (C < 0)
  return std::min(c, c_max);
}

double cantilever_deflection(double force_N, double stickout_mm, double modulus_GPa,
                             double effective_diameter_mm) {
  const double E = modulus_GPa * 1e3;  // N/mm^2
  const double I = kPi * std::pow(effective_diameter_mm, 4) / 64;  // mm^4
  return force_N * std::pow(stickout_mm, 3) / (3 * E * I);
}

}  // namespace gcpipe::force
