// Water in a porous body (thesis sec 7.2.1-7.2.2): per-tet water mass m_w, saturation
// S_w = m_w / C_e (C_e = rho_w * porosity * V_e, the tet's capacity: the thesis's m_w / V_e with
// water measured in capacity units), brushes that add or remove water where they touch, and
// diffusion between face neighbours along the saturation gradient (Patkar and Chaudhuri 2013,
// without dripping).
//
// Design. Diffusion is a finite-volume two-point flux on the rest mesh (water lives in the
// material): through the face f shared by tets a and b flows
//   q_f = G_f (S_a - S_b) h,   G_f = rho_w porosity D A_f / |c_a - c_b|
// (A_f the rest face area, c the rest centroids, D the diffusivity). The flux stage computes
// q_f once per face and the gather stage subtracts it from a and adds it to b, in a fixed CSR
// order, so the total water mass changes only by round-off and the result does not depend on
// the thread count. Explicit Euler is a convex combination of the old saturations, hence
// monotone (S stays in [0, 1], no negative water) when h sum_f G_f / C_e <= 1 for every tet;
// a step of dt takes ceil(dt * rateBound) equal substeps so that holds.
// A body gets this model at its first wet brush: a body that never gets wet pays nothing (no
// buffers, one null check per step, and a null per-tet stiffness in the element pass).
// Cracks. Water lives per tet, while a graph crack runs between the corner cells of nodes
// inside the tets, so a tet cannot hold water on both sides of one. Once a crack separates the
// body into fragments, each tet's water belongs to the fragment of most of its nodes (ties: the
// lowest fragment), and a face passes water only through the corners of its nodes that lie in
// that fragment for both tets: a share of 0, 1/3, 2/3 or 1 of G_f. Water then never crosses
// from one fragment's tets to another's, and it still diffuses freely inside each. A crack that
// has not yet separated the body does not stop it.
#pragma once

#include <cstdint>
#include <vector>

#include "fem/fem_body.h"
#include "graphfrac/defs.h"
#include "graphfrac/jobs.h"
#include "kernels/contact.h"
#include "kernels/materials.h"
#include "kernels/wetting.h"

namespace gf::detail {

/// Rest-mesh data of a body's water transport; fixed for its lifetime.
struct WettingModel {
  WettingSettings settings;
  std::vector<int32_t> faceTets;      ///< 2 per interior face: the tets a < b sharing it
  std::vector<double> conductance;    ///< G_f per face [kg/s per unit saturation]
  std::vector<int32_t> tetFaceStart;  ///< tetCount + 1 (CSR)
  std::vector<int32_t> tetFace;       ///< 2 f + 0 where the tet is a (loses q_f), 2 f + 1 if b
  std::vector<double> capacity;       ///< C_e = rho_w porosity V_e [kg]
  double rateBound = 0;               ///< max_e sum_f G_f / C_e [1/s]
  std::vector<double> flux;           ///< scratch, one per face
  /// Per face, the share of G_f that passes between fragments (see Cracks); empty: all.
  std::vector<double> open;
  /// Scratch of updateCrackBarriers, one per tet: its owning fragment, and 1 where its nodes
  /// lie in more than one fragment.
  std::vector<int32_t> owner;
  std::vector<double> split;
};

/// The model of a body's rest mesh with these settings.
WettingModel buildWettingModel(const FemModel& model, const WettingSettings& settings);

/// Sets w.open from the fragment of every node (see Cracks in the file comment): O(tets) in two
/// stages, run at each step of a wetted body with broken edges.
void updateCrackBarriers(const FemModel& model, WettingModel& w, const int32_t* nodeFragment,
                         JobSystem& jobs);

/// Diffusion substeps a step of dt takes (>= 1): the stability bound of the file comment.
int32_t diffusionSubsteps(const WettingModel& w, double dt);

/// A wet (+) or dry (-) brush stroke queued for the next step.
struct WaterStroke {
  Vec3 centre;
  double radius = 0;
  double rate = 0;  ///< saturation per second, negative for drying
};

/// Distance from p to tet t at positions x (0 inside).
GF_HD double distanceToTet(const int32_t* tets, const double* x, int32_t t, Vec3 p) {
  Vec3 c[4];
  for (int a = 0; a < 4; ++a) {
    const int64_t n = tets[4 * int64_t(t) + a];
    c[a] = {x[3 * n], x[3 * n + 1], x[3 * n + 2]};
  }
  // Inside when p lies on the inner side of all four faces (either orientation of the tet).
  const int faces[4][4] = {{1, 2, 3, 0}, {0, 3, 2, 1}, {0, 1, 3, 2}, {0, 2, 1, 3}};
  bool inside = true;
  double best = 1e300;
  for (const auto& f : faces) {
    const Vec3 a = c[f[0]], b = c[f[1]], d = c[f[2]], opposite = c[f[3]];
    const Vec3 n = cross(b - a, d - a);
    if (dot(n, p - a) * dot(n, opposite - a) < 0) inside = false;
    const Vec3 w = closestOnTriangle(p, a, b, d);
    const Vec3 q = w.x * a + w.y * b + w.z * d;
    const double dist = norm(p - q);
    best = dist < best ? dist : best;
  }
  return inside ? 0.0 : best;
}

/// Adds rate * h of saturation to every tet within `radius` of `centre` (at positions x),
/// clamped to [0, 1].
struct WaterBrushStage {
  const int32_t* tets = nullptr;
  const double* x = nullptr;
  const double* capacity = nullptr;
  Vec3 centre;
  double radius = 0;
  double delta = 0;  ///< saturation change
  double* water = nullptr;

  GF_HD void operator()(int32_t t) const {
    if (distanceToTet(tets, x, t, centre) > radius) return;
    double s = water[t] / capacity[t] + delta;
    s = s < 0 ? 0 : (s > 1 ? 1 : s);
    water[t] = s * capacity[t];
  }
};

/// Tet t's owning fragment (that of most of its nodes, the lowest on a tie) and whether its
/// nodes lie in more than one fragment (see Cracks in the file comment).
struct CrackOwnerStage {
  const int32_t* tets = nullptr;
  const int32_t* nodeFragment = nullptr;
  int32_t* owner = nullptr;
  double* split = nullptr;

  GF_HD void operator()(int32_t t) const {
    int32_t frag[4];
    for (int k = 0; k < 4; ++k) frag[k] = nodeFragment[tets[4 * int64_t(t) + k]];
    for (int i = 1; i < 4; ++i)  // four entries: insertion sort
      for (int j = i; j > 0 && frag[j - 1] > frag[j]; --j) {
        const int32_t tmp = frag[j];
        frag[j] = frag[j - 1];
        frag[j - 1] = tmp;
      }
    int32_t best = frag[0], bestCount = 0;
    for (int i = 0; i < 4;) {
      int j = i;
      while (j < 4 && frag[j] == frag[i]) ++j;
      if (j - i > bestCount) best = frag[i], bestCount = j - i;
      i = j;
    }
    owner[t] = best;
    split[t] = frag[0] != frag[3] ? 1.0 : 0.0;
  }
};

/// Face f's open share: 0 between tets of different owners, else the fraction of its three
/// nodes that lie in their owner's fragment.
struct CrackOpenStage {
  const int32_t* tets = nullptr;
  const int32_t* nodeFragment = nullptr;
  const int32_t* faceTets = nullptr;
  const int32_t* owner = nullptr;
  double* open = nullptr;

  GF_HD void operator()(int32_t f) const {
    const int32_t a = faceTets[2 * int64_t(f)], b = faceTets[2 * int64_t(f) + 1];
    if (owner[a] != owner[b]) {
      open[f] = 0;
      return;
    }
    // The face's nodes: those of a that b shares.
    int shared = 0, inside = 0;
    for (int k = 0; k < 4; ++k) {
      const int32_t n = tets[4 * int64_t(a) + k];
      bool inB = false;
      for (int m = 0; m < 4; ++m) inB |= tets[4 * int64_t(b) + m] == n;
      if (!inB) continue;
      ++shared;
      inside += nodeFragment[n] == owner[a];
    }
    open[f] = shared == 3 ? inside / 3.0 : 0.0;
  }
};

/// q_f = G_f (S_a - S_b) h for every face (mass from a to b), times the face's open share.
struct WaterFluxStage {
  const int32_t* faceTets = nullptr;
  const double* conductance = nullptr;
  const double* capacity = nullptr;
  const double* water = nullptr;
  const double* open = nullptr;  ///< WettingModel::open, null: all open
  double h = 0;
  double* flux = nullptr;

  GF_HD void operator()(int32_t f) const {
    const int32_t a = faceTets[2 * int64_t(f)], b = faceTets[2 * int64_t(f) + 1];
    const double g = open ? conductance[f] * open[f] : conductance[f];
    flux[f] = g * (water[a] / capacity[a] - water[b] / capacity[b]) * h;
  }
};

/// m_e -= outgoing fluxes, += incoming ones, in CSR order (see the file comment).
struct WaterGatherStage {
  const int32_t* tetFaceStart = nullptr;
  const int32_t* tetFace = nullptr;
  const double* flux = nullptr;
  double* water = nullptr;

  GF_HD void operator()(int32_t t) const {
    double dm = 0;
    for (int32_t k = tetFaceStart[t]; k < tetFaceStart[t + 1]; ++k) {
      const int32_t ref = tetFace[k];
      dm += (ref & 1) ? flux[ref >> 1] : -flux[ref >> 1];
    }
    water[t] += dm;
  }
};

/// The kernel coefficients (mu, lambda) of each tet from its saturation (eq 7.1-7.4): the
/// body's material as the dry matrix, water as spherical inclusions of volume fraction
/// porosity * S_w.
struct WetStiffnessStage {
  const double* water = nullptr;
  const double* capacity = nullptr;
  double porosity = 0;
  IsoModuli solid, fluid;
  int model = kStableNeoHookean;
  double* tetLame = nullptr;  ///< 2 per tet

  GF_HD void operator()(int32_t t) const {
    const double s = water[t] / capacity[t];
    const IsoModuli m = eshelbyEffective(solid, fluid, porosity * s);
    const MaterialCoeffs c = makeMaterialCoeffs(model, youngOf(m), poissonOf(m), 0, Vec3{});
    tetLame[2 * int64_t(t)] = c.mu;
    tetLame[2 * int64_t(t) + 1] = c.lambda;
  }
};

/// Applies the strokes, then diffuses over dt (diffusionSubsteps), through `jobs`.
void advanceWater(const FemModel& model, WettingModel& w, std::vector<double>& water,
                  const double* x, const std::vector<WaterStroke>& strokes, double dt,
                  JobSystem& jobs);
/// Per-tet (mu, lambda) of `state` from its water (state.water non-empty).
void refreshWetStiffness(const FemModel& model, const WettingModel& w, FemState& state,
                         JobSystem& jobs);

}  // namespace gf::detail
