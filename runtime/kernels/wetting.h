// Elasticity of a wet porous solid (thesis sec 7.2.2, after Yoon and Cowin 2009).
//
// Design. Both phases are isotropic, so every elasticity and compliance tensor of eq 7.1-7.4
// is a J K decomposition, E = 3k J + 2mu K (J the volumetric, K the deviatoric projector), and
// the tensor algebra of the thesis reduces to two scalars per tensor: sums, products and
// inverses act on the bulk and the shear part separately. The Eshelby tensor of a spherical
// inclusion in an isotropic matrix is P = alpha J + beta K with
//   alpha = 3 k_s / (3 k_s + 4 mu_s),  beta = 6 (k_s + 2 mu_s) / (5 (3 k_s + 4 mu_s)),
// and Q^I = (E^s - E^w)^-1 E^s has the parts k_s / (k_s - k_w) and mu_s / (mu_s - mu_w), so
// eq 7.4 gives per part
//   1 / k_eff = (1 / k_s) (1 + phi (k_s - k_w) / ((1 - alpha) k_s + alpha k_w))
// (and the same for mu with beta): the division by k_s - k_w is multiplied out, so equal
// phases need no special case and the denominator is positive for any k_w >= 0. Eq 7.4 is the
// dilute (non-interacting) estimate: at large phi it can leave the bracket of eq 7.3 (above
// the Voigt bound for voids once phi > beta, or a non-positive compliance for inclusions much
// stiffer in bulk than the matrix once phi >= alpha), so the result is clamped into it. For
// isotropic tensors the Loewner order of eq 7.3 is the order of both scalars, so clamping each
// keeps the tensor inside the bracket.
#pragma once

#include "gf_hd.h"

namespace gf {

/// Bulk modulus k and shear modulus mu [Pa] of an isotropic phase or mixture.
struct IsoModuli {
  double k = 0;
  double mu = 0;
};

/// k and mu of Young's modulus E and Poisson ratio nu.
GF_HD IsoModuli isoFromYoung(double E, double nu) {
  return {E / (3.0 * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))};
}
/// Young's modulus of (k, mu); 0 when both vanish.
GF_HD double youngOf(IsoModuli m) {
  const double d = 3.0 * m.k + m.mu;
  return d > 0 ? 9.0 * m.k * m.mu / d : 0.0;
}
/// Poisson ratio of (k, mu) (0 when both vanish).
GF_HD double poissonOf(IsoModuli m) {
  const double d = 3.0 * m.k + m.mu;
  return d > 0 ? (3.0 * m.k - 2.0 * m.mu) / (2.0 * d) : 0.0;
}

namespace detail {
// (1 - phi) a + phi b, and its harmonic counterpart a b / ((1 - phi) b + phi a) with the limit
// 0 when a phase of zero stiffness is present (phi > 0).
GF_HD double arithmeticMix(double a, double b, double phi) { return (1.0 - phi) * a + phi * b; }
GF_HD double harmonicMix(double a, double b, double phi) {
  const double d = (1.0 - phi) * b + phi * a;
  return d > 0 ? a * b / d : 0.0;
}
// One part of eq 7.4: the matrix's modulus s, the inclusions' w, the Eshelby factor p.
GF_HD double dilutePart(double s, double w, double p, double phi) {
  const double compliance = 1.0 + phi * (s - w) / ((1.0 - p) * s + p * w);
  return compliance > 0 ? s / compliance : 1e300;  // clamped to Voigt by the caller
}
GF_HD double clampTo(double v, double lo, double hi) { return v < lo ? lo : (v > hi ? hi : v); }
}  // namespace detail

// eq 7.1: the Voigt (upper) bound of a mixture with fluid volume fraction phi.
GF_HD IsoModuli voigtBound(IsoModuli solid, IsoModuli fluid, double phi) {
  return {detail::arithmeticMix(solid.k, fluid.k, phi),
          detail::arithmeticMix(solid.mu, fluid.mu, phi)};
}

// eq 7.2: the Reuss (lower) bound, the inverse of the mixed compliances.
GF_HD IsoModuli reussBound(IsoModuli solid, IsoModuli fluid, double phi) {
  return {detail::harmonicMix(solid.k, fluid.k, phi), detail::harmonicMix(solid.mu, fluid.mu, phi)};
}

/// eq 7.4 (with eq 7.3 as the clamp, see the file comment): the effective moduli of a solid
/// matrix holding spherical fluid inclusions of volume fraction phi in [0, 1]. Equals the
/// solid at phi = 0; continuous and, for a fluid softer than the solid in both parts,
/// non-increasing in phi.
GF_HD IsoModuli eshelbyEffective(IsoModuli solid, IsoModuli fluid, double phi) {
  if (!(phi > 0)) return solid;
  const double ks = solid.k, ms = solid.mu;
  const double alpha = 3.0 * ks / (3.0 * ks + 4.0 * ms);
  const double beta = 6.0 * (ks + 2.0 * ms) / (5.0 * (3.0 * ks + 4.0 * ms));
  const IsoModuli hi = voigtBound(solid, fluid, phi), lo = reussBound(solid, fluid, phi);
  return {detail::clampTo(detail::dilutePart(ks, fluid.k, alpha, phi), lo.k, hi.k),
          detail::clampTo(detail::dilutePart(ms, fluid.mu, beta, phi), lo.mu, hi.mu)};
}

}  // namespace gf
