// Multiplicative plasticity F = Fe Fp (thesis eq 2.3-2.5, Bargteil et al. 2007).
//
// Design. Each element stores Fp (det 1, starts at I), its inverse FpInv and the hardening
// accumulator delta. The elastic energy sees Fe = F FpInv = Ds (DmInv FpInv), so the element
// kernels need nothing new: pass the effective rest inverse DmInv * FpInv and the ORIGINAL
// rest volume (det Fp = 1 keeps it).
//
// Update convention. Eq 2.4 writes Fp <- Fp V Sigma_hat^beta V^T with Fe = U Sigma V^T. V lives
// in the intermediate (plastic) configuration, the domain of Fe and the range of Fp, so the
// increment has to act on that side: Fp <- (V Sigma_hat^beta V^T) Fp. Then with beta = 1 the new
// elastic part F Fp^-1 = U Sigma V^T V Sigma_hat^-1 V^T = det(Sigma)^(1/3) U V^T is a rotation
// times a volume scaling: all shape change moved into Fp. Multiplying on the right, as the
// equation is printed, agrees only while Fp and V Sigma V^T commute (the first update from
// Fp = I) and otherwise pushes Fp away from the current deformation; the unit tests check both
// facts. FpInv is updated from the same factors (FpInv V Sigma_hat^-beta V^T), not by inversion,
// and both are rescaled to det Fp = 1 each update so round-off cannot drift the volume.
//
// Only yielding elements pay: the spectral norm of the stress is compared with the yield
// threshold first, and the SVD runs only above it.
#pragma once

#include "eigen_sym.h"
#include "math.h"
#include "svd3.h"

namespace gf {

/// Plastic flow parameters of eq 2.5 (see gf::PlasticitySettings).
struct PlasticParams {
  double yieldStress = 0;  ///< sigma_p [Pa]
  double flowRate = 1;     ///< v in [0, 1]
  double hardening = 0;    ///< K [1/s]: the threshold grows by K delta, delta in [Pa s]
};

/// Smallest elastic singular value for which a plastic update runs. Inverted or crushed
/// elements are left to the elastic energy's inversion handling: det(Sigma)^(-1/3) and the
/// power Sigma^beta are undefined for s2 <= 0.
constexpr double kPlasticStretchMin = 1e-6;

/// Fe = F Fp^-1 (eq 2.3).
GF_HD Mat3 elasticDeformation(const Mat3& F, const Mat3& FpInv) { return F * FpInv; }

/// ||sigma||_2 of eq 2.5: the spectral norm (largest |eigenvalue|) of the symmetric part.
GF_HD double stressSpectralNorm(const Mat3& sigma) {
  Mat3 s;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) s(i, j) = 0.5 * (sigma(i, j) + sigma(j, i));
  double w[3];
  Mat3 q;
  symmetricEigen<3>(s, w, q);
  const double a = fabs(w[0]), b = fabs(w[2]);  // values sorted descending
  return a > b ? a : b;
}

/// One plastic step of eq 2.4-2.5 for an element whose elastic part Fe carries the stress
/// sigma (material-frame or Cauchy: only its spectral norm is used). When ||sigma|| exceeds
/// yieldStress + hardening * delta, moves the fraction beta of Fe's isochoric stretch into Fp
/// (left-multiplied, see the file comment), updates FpInv, adds dt ||sigma|| to delta and
/// returns true. Below yield, for flowRate 0 and for inverted or degenerate Fe it returns false
/// and changes nothing.
GF_HD bool plasticUpdate(const PlasticParams& p, const Mat3& sigma, const Mat3& Fe, double dt,
                         Mat3& Fp, Mat3& FpInv, double& delta) {
  const double sn = stressSpectralNorm(sigma);
  const double threshold = p.yieldStress + p.hardening * delta;
  if (!(sn > threshold)) return false;  // below yield (or NaN): the cheap early-out
  // eq 2.5
  double beta = p.flowRate * (sn - threshold) / sn;
  beta = beta < 0 ? 0.0 : (beta > 1 ? 1.0 : beta);
  if (!(beta > 0)) return false;
  const Svd3 svd = svd3(Fe);
  if (!(svd.s.z > kPlasticStretchMin)) return false;
  // eq 2.4: Sigma_hat = det(Sigma)^(-1/3) Sigma has unit determinant, so does its power.
  const double scale = 1.0 / cbrt(svd.s.x * svd.s.y * svd.s.z);
  double up[3], down[3];
  for (int a = 0; a < 3; ++a) {
    up[a] = pow(scale * svd.s[a], beta);
    down[a] = 1.0 / up[a];
  }
  Mat3 inc, incInv;  // V Sigma_hat^(+-beta) V^T
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double a = 0, b = 0;
      for (int k = 0; k < 3; ++k) {
        const double vv = svd.V(i, k) * svd.V(j, k);
        a += vv * up[k];
        b += vv * down[k];
      }
      inc(i, j) = a;
      incInv(i, j) = b;
    }
  Mat3 fp = inc * Fp;
  Mat3 fpInv = FpInv * incInv;
  // Re-impose det Fp = 1 against round-off accumulated over many steps.
  const double d = det(fp);
  if (!(d > 0)) return false;
  const double c = cbrt(d);
  Fp = (1.0 / c) * fp;
  FpInv = c * fpInv;
  delta += dt * sn;
  return true;
}

}  // namespace gf
