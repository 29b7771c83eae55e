// The per-tet and per-cell stages of fracture detection (thesis eq 4.10-4.12, SPEC §2),
// written once for both executors like fem/element_stage.h: criterion stresses, the stress
// bounds that let the non-local average be skipped, the average itself, the candidate edges
// of each tet, each candidate edge's reporting tet, the compaction of the candidate edges in
// edge-id order and their events, and the damage masks.
#pragma once

#include <cstdint>

#include "fem/element_stage.h"
#include "fracture/edge_break.h"
#include "kernels/damage.h"
#include "kernels/edge_stress.h"
#include "kernels/element.h"
#include "kernels/split_point.h"
#include "step/reduce.h"
#include "step/scan.h"

namespace gf::detail {

/// Normal stress N^T S N of a symmetric tensor in Voigt order [xx yy zz xy xz yz] (tensor
/// shear) along unit direction n: one row of T (eq 4.9, SPEC §2) applied to S (eq 4.8).
GF_HD double edgeNormalStress(const double* s, const double* n) {
  return s[0] * n[0] * n[0] + s[1] * n[1] * n[1] + s[2] * n[2] * n[2] +
         2.0 * (s[3] * n[0] * n[1] + s[4] * n[0] * n[2] + s[5] * n[1] * n[2]);
}

/// Upper bound of the largest eigenvalue of a symmetric Voigt tensor (Gershgorin): no normal
/// stress n^T S n exceeds it, nor any weighted mean of such tensors' normal stresses.
GF_HD double maxPrincipalBound(const double* s) {
  const double a = s[0] + fabs(s[3]) + fabs(s[4]);
  const double b = s[1] + fabs(s[3]) + fabs(s[5]);
  const double c = s[2] + fabs(s[4]) + fabs(s[5]);
  return a > b ? (a > c ? a : c) : (b > c ? b : c);
}

/// Material-frame stress of every tet the element pass did not give one (6 per tet, Voigt):
/// damaged tets at their damage model's level (eq 4.32: chi times the stress; zero across a
/// tet already split), and undamaged ones too when `undamagedToo`. A rigid tet (a piece in
/// rigid physics) has zero stress, as the element pass gives it, damaged or not.
struct CriterionStressStage {
  const int32_t* tets = nullptr;
  const double* x = nullptr;
  const Mat3* restInverse = nullptr;  ///< Dm^-1, or Dm^-1 Fp^-1 when plastic (eq 2.3)
  MaterialCoeffs coeffs;
  const Vec3* fibreDir = nullptr;   ///< per tet, or null
  const double* tetLame = nullptr;  ///< 2 per tet, or null (see ElementStage)
  const uint8_t* tetMask = nullptr;
  const double* chi = nullptr;
  /// Per tet, or null: 1 for a tet of a piece handed to rigid physics. Its nodes are set to
  /// R X + t by each World::setFragmentTransform and move by the rigid velocity field in
  /// between (straight lines), so any strain their positions show is round-off or that field's
  /// linearised turn, not load. Judging it also cost a full SVD per tet and substep once a body
  /// had shattered into pieces in Bullet (docs/validation.md, issue 14 item 2).
  const uint8_t* rigidTet = nullptr;
  bool degradation = false;  ///< damage model of eq 4.32-4.33 (else projection)
  bool undamagedToo = false;
  double* stress = nullptr;
  /// kSvdCacheStride per tet, or null: the element pass's SVD cache (svd3.h). A tet whose F is
  /// the one the last element pass saw (the step ended where the criterion now looks) takes
  /// its SVD from there; same bits either way.
  double* svdCache = nullptr;

  GF_HD Mat3 intactStress(int32_t t) const {
    Vec3 xe[4];
    tetCorners(tets, x, t, xe);
    const MaterialCoeffs c = tetCoeffs(coeffs, fibreDir, t, tetLame);
    const Mat3 F = deformationGradient(xe, restInverse[t]);
    return materialStress(
        c, F, cachedSvd3(F, svdCache ? svdCache + kSvdCacheStride * int64_t(t) : nullptr));
  }

  GF_HD void operator()(int32_t t) const {
    double* s = stress + 6 * int64_t(t);
    if (rigidTet && rigidTet[t]) {
      for (int k = 0; k < 6; ++k) s[k] = 0;
      return;
    }
    const uint8_t mask = tetMask[t];
    if (mask == 0) {
      if (undamagedToo) toVoigt(intactStress(t), s);
      return;
    }
    uint8_t brokenLocal[6];
    for (int k = 0; k < 6; ++k) brokenLocal[k] = (mask >> k) & 1;
    // A tet already split into pieces carries no stress between them.
    if (cornersDisconnected(brokenLocal)) {
      for (int k = 0; k < 6; ++k) s[k] = 0;
      return;
    }
    toVoigt(intactStress(t), s);
    const double scale = degradation ? chi[t] : 1.0;
    for (int k = 0; k < 6; ++k) s[k] *= scale;
  }
};

/// The edge data of the criterion: the graph's edges of each tet, their rest directions as
/// seen from the tet, strengths and broken flags.
struct CriterionEdges {
  const int32_t* tetEdges = nullptr;       ///< 6 per tet
  const double* edgeDirections = nullptr;  ///< 18 per tet: unit rest direction of each local edge
  const double* strength = nullptr;        ///< per edge
  const uint8_t* broken = nullptr;         ///< per edge

  /// Bits of the local edges of tet t whose normal stress under S reaches their strength
  /// (eq 4.11: tensile only, because strengths are positive).
  GF_HD uint8_t edgesAtStrength(const double* S, int32_t t) const {
    uint8_t mask = 0;
    for (int k = 0; k < 6; ++k) {
      const int32_t edge = tetEdges[6 * int64_t(t) + k];
      if (broken[edge]) continue;
      if (edgeNormalStress(S, edgeDirections + 18 * int64_t(t) + 3 * k) >= strength[edge])
        mask |= uint8_t(1u << k);
    }
    return mask;
  }
  /// The weakest unbroken edge of tet t (infinity when all are broken).
  GF_HD double weakestEdge(int32_t t) const {
    double w = HUGE_VAL;
    for (int k = 0; k < 6; ++k) {
      const int32_t edge = tetEdges[6 * int64_t(t) + k];
      if (!broken[edge] && strength[edge] < w) w = strength[edge];
    }
    return w;
  }
};

/// Bit of CriterionWorkspace::candidates: the tet's averaged stress was computed.
constexpr uint8_t kAveragedBit = 0x80;
constexpr uint8_t kEdgeBits = 0x3f;

/// Local criterion: each tet judged by its own stress; the Gershgorin bound spares the edge
/// gathers of tets far below the body's weakest strength.
struct LocalCandidateStage {
  CriterionEdges edges;
  const double* tetStress = nullptr;
  double weakest = 0;
  uint8_t* candidates = nullptr;

  GF_HD void operator()(int32_t t) const {
    const double* S = tetStress + 6 * int64_t(t);
    candidates[t] = maxPrincipalBound(S) >= weakest ? edges.edgesAtStrength(S, t) : 0;
  }
};

/// Per tet, the Gershgorin bound of its stress.
struct StressBoundStage {
  const double* tetStress = nullptr;
  double* bound = nullptr;

  GF_HD void operator()(int32_t t) const {
    bound[t] = maxPrincipalBound(tetStress + 6 * int64_t(t));
  }
};

/// The centroid grid of the non-local average as flat arrays (FractureModel::grid).
struct GridView {
  int32_t dims[3] = {0, 0, 0};
  const int32_t* start = nullptr;  ///< CSR: tets per cell
  const int32_t* items = nullptr;
  const int32_t* tetCell = nullptr;  ///< cell of each tet
};

/// Per cell, the largest bound of its tets.
struct CellMaxStage {
  GridView grid;
  const double* bound = nullptr;
  double* cellMax = nullptr;

  GF_HD void operator()(int32_t c) const {
    double m = -HUGE_VAL;
    for (int32_t s = grid.start[c]; s < grid.start[c + 1]; ++s)
      m = bound[grid.items[s]] > m ? bound[grid.items[s]] : m;
    cellMax[c] = m;
  }
};

/// eq 4.10, normalised: the neighbour list holds the tet itself with a positive weight, so the
/// weights' sum is > 0.
struct NonlocalAverage {
  const int32_t* neighbourStart = nullptr;
  const int32_t* neighbourIndex = nullptr;
  const float* neighbourWeight = nullptr;

  GF_HD void average(const double* tetStress, int32_t t, double* out) const {
    double acc[6] = {0, 0, 0, 0, 0, 0};
    double wsum = 0;
    for (int32_t s = neighbourStart[t]; s < neighbourStart[t + 1]; ++s) {
      const double w = neighbourWeight[s];
      const double* sj = tetStress + 6 * int64_t(neighbourIndex[s]);
      for (int c = 0; c < 6; ++c) acc[c] += w * sj[c];
      wsum += w;
    }
    for (int c = 0; c < 6; ++c) out[c] = acc[c] / wsum;
  }
};

/// The non-local average of every tet (6 per tet into out).
struct AverageStage {
  NonlocalAverage avg;
  const double* tetStress = nullptr;
  double* out = nullptr;

  GF_HD void operator()(int32_t t) const { avg.average(tetStress, t, out + 6 * int64_t(t)); }
};

/// Non-local criterion: a tet whose 27 surrounding cells' largest bound stays below its
/// weakest unbroken edge cannot reach it (a weighted mean of normal stresses never exceeds
/// the largest principal stress among the neighbours) and is skipped exactly; the others
/// average their stress and judge their edges by it.
struct NonlocalCandidateStage {
  CriterionEdges edges;
  GridView grid;
  NonlocalAverage avg;
  const double* tetStress = nullptr;
  const double* cellMax = nullptr;
  double* averaged = nullptr;  ///< 6 per tet, written for the tets not skipped
  uint8_t* candidates = nullptr;

  GF_HD void operator()(int32_t t) const {
    const double weakestHere = edges.weakestEdge(t);
    const int32_t id = grid.tetCell[t];
    const int32_t nx = grid.dims[0], ny = grid.dims[1], nz = grid.dims[2];
    const int32_t ix = id % nx, iy = (id / nx) % ny, iz = id / (nx * ny);
    double reach = -HUGE_VAL;
    for (int32_t z = iz > 0 ? iz - 1 : 0; z <= iz + 1 && z < nz; ++z)
      for (int32_t y = iy > 0 ? iy - 1 : 0; y <= iy + 1 && y < ny; ++y)
        for (int32_t x = ix > 0 ? ix - 1 : 0; x <= ix + 1 && x < nx; ++x) {
          const double m = cellMax[(z * ny + y) * nx + x];
          reach = m > reach ? m : reach;
        }
    if (!(reach >= weakestHere)) {
      candidates[t] = 0;
      return;
    }
    double* a = averaged + 6 * int64_t(t);
    avg.average(tetStress, t, a);
    candidates[t] = uint8_t(kAveragedBit | edges.edgesAtStrength(a, t));
  }
};

/// 1 when tet t's candidate mask holds an edge at strength, else 0: a max-reduction term, so
/// a step with nothing near its strength skips the edge pass.
struct AnyCandidateTerm {
  const uint8_t* candidates = nullptr;
  GF_HD double operator()(int32_t t) const { return (candidates[t] & kEdgeBits) ? 1.0 : 0.0; }
};

/// Per edge e: flag[e] 1 when an incident tet's candidate mask holds it, and then the tet that
/// reports it (eq 4.12): the largest normal stress over the incident tets in slot order (the
/// first on ties) from the averaged stress where non-local, skipping the tets the bound left
/// without one (they cannot reach this edge's strength).
struct EdgeCandidateStage {
  const int32_t* edgeTetStart = nullptr;
  const int32_t* edgeTets = nullptr;  ///< slots 6 tet + local edge
  const uint8_t* candidates = nullptr;
  const double* tetStress = nullptr;
  const double* averaged = nullptr;  ///< null: local
  const double* edgeDirections = nullptr;
  uint8_t* flag = nullptr;
  double* stress = nullptr;
  int32_t* tet = nullptr;

  GF_HD void operator()(int32_t e) const {
    flag[e] = 0;
    for (int32_t s = edgeTetStart[e]; s < edgeTetStart[e + 1]; ++s)
      if (candidates[edgeTets[s] / 6] & (1u << (edgeTets[s] % 6))) flag[e] = 1;
    if (!flag[e]) return;
    double best = -HUGE_VAL;
    int32_t bestTet = -1;
    for (int32_t s = edgeTetStart[e]; s < edgeTetStart[e + 1]; ++s) {
      const int64_t t = edgeTets[s] / 6;
      const double* S = tetStress + 6 * t;
      if (averaged) {
        if (!(candidates[t] & kAveragedBit)) continue;
        S = averaged + 6 * t;
      }
      const double sig = edgeNormalStress(S, edgeDirections + 18 * t + 3 * (edgeTets[s] % 6));
      if (sig > best) {
        best = sig;
        bestTet = int32_t(t);
      }
    }
    stress[e] = best;
    tet[e] = bestTet;
  }
};

/// Candidate edge i breaks: its flag is set (damage never heals) and its event written, with
/// the edge's midpoint in `positions` when given.
struct BreakEventStage {
  const int32_t* edges = nullptr;  ///< the candidate edges, sorted
  const double* stress = nullptr;  ///< EdgeCandidateStage's, per edge
  const int32_t* tet = nullptr;
  const int32_t* edgeNodes = nullptr;
  const double* positions = nullptr;
  uint8_t* broken = nullptr;
  EdgeBreak* events = nullptr;

  GF_HD void operator()(int32_t i) const {
    const int32_t e = edges[i];
    broken[e] = 1;
    EdgeBreak ev;
    ev.edge = e;
    ev.tet = tet[e];
    ev.stress = stress[e];
    ev.split = 0.5;
    if (positions) {
      const double* xa = positions + 3 * int64_t(edgeNodes[2 * int64_t(e)]);
      const double* xb = positions + 3 * int64_t(edgeNodes[2 * int64_t(e) + 1]);
      ev.position = {0.5 * (xa[0] + xb[0]), 0.5 * (xa[1] + xb[1]), 0.5 * (xa[2] + xb[2])};
    }
    events[i] = ev;
  }
};

/// Break i of a batch about to be applied: its split ratio from the elastic forces on the
/// edge's two nodes (fig 4.10, kernels/split_point.h), each the sum of -dE_t/dx_n over the
/// node's tets in element order, at x and with the damage from before the batch, i.e. the
/// forces in the body at the moment the edge breaks.
struct ForceRatioSplitStage {
  ElementStage element;  ///< the body's element pass at x (its outputs are not written)
  const int32_t* nodeRefStart = nullptr;  ///< CSR node -> 4 tet + corner, in element order
  const int32_t* nodeRef = nullptr;
  const int32_t* edgeNodes = nullptr;
  EdgeBreak* breaks = nullptr;  ///< the batch; `split` is written

  GF_HD Vec3 nodeForce(int32_t n) const {
    Vec3 f{};
    for (int32_t k = nodeRefStart[n]; k < nodeRefStart[n + 1]; ++k) {
      const int32_t ref = nodeRef[k];
      double g[12];
      element.evaluate(ref / 4, g, nullptr);
      const int c = ref % 4;
      f -= Vec3{g[3 * c], g[3 * c + 1], g[3 * c + 2]};
    }
    return f;
  }

  GF_HD void operator()(int32_t i) const {
    const int64_t e = breaks[i].edge;
    breaks[i].split = forceRatioSplit(nodeForce(edgeNodes[2 * e]), nodeForce(edgeNodes[2 * e + 1]));
  }
};

/// Bit k of masks[t] set when local edge k of tet t is broken.
struct EdgeMaskStage {
  const int32_t* tetEdges = nullptr;
  const uint8_t* broken = nullptr;
  uint8_t* masks = nullptr;

  GF_HD void operator()(int32_t t) const {
    uint8_t mask = 0;
    for (int k = 0; k < 6; ++k)
      if (broken[tetEdges[6 * int64_t(t) + k]]) mask |= uint8_t(1u << k);
    masks[t] = mask;
  }
};

/// The per-edge stress and reporting tet of candidate i, compacted (what a device sends back of
/// EdgeCandidateStage's arrays).
struct CandidateGatherStage {
  const int32_t* edges = nullptr;  ///< the candidate edges
  const double* edgeStress = nullptr;
  const int32_t* edgeTet = nullptr;
  double* stress = nullptr;
  int32_t* tet = nullptr;

  GF_HD void operator()(int32_t i) const {
    stress[i] = edgeStress[edges[i]];
    tet[i] = edgeTet[edges[i]];
  }
};

/// The criterion's arrays as its stages read them: the host's (criterion.h's criterionView) or
/// a device's copies (gpu/criterion.h). Scratch as CriterionWorkspace's; candidateEdges has room
/// for every edge.
struct CriterionView {
  CriterionEdges edges;
  bool nonLocal = false;
  GridView grid;  ///< non-local only, as `average` and `cells`
  int32_t cells = 0;
  NonlocalAverage average;
  int32_t tetCount = 0, edgeCount = 0;
  const int32_t* edgeTetStart = nullptr;
  const int32_t* edgeTets = nullptr;
  double* averaged = nullptr;
  uint8_t* candidates = nullptr;
  double* bound = nullptr;
  double* cellMax = nullptr;
  uint8_t* edgeFlag = nullptr;
  double* edgeStress = nullptr;
  int32_t* edgeTet = nullptr;
  int32_t* chunkCount = nullptr;
  int32_t* chunkOffset = nullptr;
  int32_t* candidateEdges = nullptr;
};

/// The unbroken edges whose normal stress under tetStress reaches their strength (eq 4.11-4.12),
/// none weaker than `weakest`: their count, their ids in increasing order in candidateEdges,
/// and per candidate edge its stress and reporting tet (edgeStress, edgeTet). readInt(p) reads
/// an int32_t the stages wrote (a device's: a copy back). fracture/criterion.h's design note.
template <class Exec, class ReadInt>
int32_t findCandidateEdges(const Exec& exec, const CriterionView& v, const double* tetStress,
                           double weakest, const ReadInt& readInt) {
  if (!v.nonLocal) {
    exec.run(v.tetCount, 512, LocalCandidateStage{v.edges, tetStress, weakest, v.candidates});
  } else {
    // Bound first: per tet, per cell, and against the weakest edge of the body.
    exec.run(v.tetCount, 1024, StressBoundStage{tetStress, v.bound});
    exec.run(v.cells, 1024, CellMaxStage{v.grid, v.bound, v.cellMax});
    if (!(exec.template reduce<MaxOp>(v.cells, ArrayTerm{v.cellMax}) >= weakest)) return 0;
    exec.run(v.tetCount, 256,
             NonlocalCandidateStage{v.edges, v.grid, v.average, tetStress, v.cellMax, v.averaged,
                                    v.candidates});
  }
  if (!(exec.template reduce<MaxOp>(v.tetCount, AnyCandidateTerm{v.candidates}) > 0)) return 0;
  const int32_t E = v.edgeCount;
  exec.run(E, 1024,
           EdgeCandidateStage{v.edgeTetStart, v.edgeTets, v.candidates, tetStress,
                              v.nonLocal ? v.averaged : nullptr, v.edges.edgeDirections, v.edgeFlag,
                              v.edgeStress, v.edgeTet});
  // The candidates in edge-id order: counts per chunk, their offsets, then each chunk's edges.
  const int32_t chunks = (E + kCompactChunk - 1) / kCompactChunk;
  exec.run(chunks, 4, CompactCountStage{v.edgeFlag, E, v.chunkCount});
  exec.run(1, 1, CompactOffsetStage{v.chunkCount, chunks, v.chunkOffset});
  exec.run(chunks, 4, CompactScatterStage{v.edgeFlag, E, v.chunkOffset, v.candidateEdges});
  return readInt(v.chunkOffset + chunks);
}

}  // namespace gf::detail
