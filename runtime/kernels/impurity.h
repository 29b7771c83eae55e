// Random-graph impurities (thesis sec 5.2, SPEC §4): the per-node draws and the per-edge
// strength factor, plain functions so the CPU and a CUDA backend compute the same bits.
//
// Design. The draws are a counter-based hash of (seed, stream, index), never a stateful RNG,
// so a node's impurity does not depend on the order nodes are visited, the thread count or the
// backend. The break probability p_ij of eq 5.1 enters the stress criterion as an effective
// strength sigma_th (1 - p_ij) / (1 - p_ref) (docs/design.md "Impurities"), with the degrees
// normalised by the rest degree: eq 5.3's h saturates near x = 5, and the raw degrees of a tet
// mesh (10-20) would give x > 200 and p < 1e-80 on every intact edge.
#pragma once

#include <cstdint>

#include "kernels/gf_hd.h"

namespace gf {

/// SplitMix64's finaliser (Steele, Lea and Flood 2014): a bijective avalanche of 64 bits.
GF_HD uint64_t mix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

/// Uniform in (0, 1), never 0 or 1: the 53 high bits of the hash of (seed, stream, index).
GF_HD double hashUniform(uint64_t seed, uint64_t stream, uint64_t index) {
  const uint64_t h =
      mix64(mix64(seed ^ 0x9e3779b97f4a7c15ull) + mix64(stream * 0x632be59bd9b4e019ull + index));
  return (double(h >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

/// Gaussian N(0, sigma^2) of node k (eq 5.2) by Box-Muller on two hashed uniforms; a zero
/// (probability 0, but the hash could give it) becomes the smallest normal double so that
/// alpha_k != 0 holds as eq 5.2 asks.
GF_HD double impurityGaussian(uint64_t seed, int64_t k, double sigma) {
  const double u1 = hashUniform(seed, 1, uint64_t(k)), u2 = hashUniform(seed, 2, uint64_t(k));
  const double a = sigma * sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2);
  return a != 0 ? a : 2.2250738585072014e-308;
}

/// Uniform on (-sqrt(3) sigma, sqrt(3) sigma): variance sigma^2, like the Gaussian.
GF_HD double impurityUniform(uint64_t seed, int64_t k, double sigma) {
  const double a = sigma * 1.7320508075688772 * (2.0 * hashUniform(seed, 1, uint64_t(k)) - 1.0);
  return a != 0 ? a : 2.2250738585072014e-308;
}

/// 1 - h(x) with h(x) = (e^x - 1) / (e^x + 1) (eq 5.3), i.e. 2 / (e^x + 1), exact to the last
/// bit for large x where 1 - h would cancel; x = inf gives 0.
GF_HD double oneMinusH(double x) { return 2.0 / (exp(x) + 1.0); }

/// Break probability p_ij of eq 5.1. di, dj: the nodes' current degree over their rest degree
/// (in [0, 1]); ai, aj: their impurities (0 = pure: 1/|alpha| = inf when degrading, so an edge
/// with a pure node keeps p = 0). upgrade: the material-upgradation branch.
GF_HD double impurityBreakProbability(double di, double dj, double ai, double aj, bool upgrade) {
  const double bi = fabs(ai), bj = fabs(aj);
  if (upgrade) return oneMinusH(2.0 * (di + bi) * (dj + bj));  // eq 5.1, upgradation
  if (bi == 0 || bj == 0) return 0;
  return oneMinusH(2.0 * (di + 1.0 / bi) * (dj + 1.0 / bj));  // eq 5.1, degradation
}

/// The strength factor (1 - p_ij) / (1 - p_ref): 1 for a pure intact edge in both modes
/// (p_ref = 0 degrading, 1 - h(2) = 1 - tanh(1) upgrading, eq 5.1 at alpha = 0, d = 1).
GF_HD double impurityStrengthFactor(double di, double dj, double ai, double aj, bool upgrade) {
  const double p = impurityBreakProbability(di, dj, ai, aj, upgrade);
  return upgrade ? (1.0 - p) / 0.7615941559557649 : 1.0 - p;
}

}  // namespace gf
