// The fracture criterion of graph-based FEM (thesis eq 4.10-4.12, SPEC §2): average the
// material-frame element stress over a radius R_d, project it on every edge's rest direction,
// and break each unbroken edge whose tensile normal stress from ANY incident tet reaches its
// strength. Damage never heals.
//
// Design: one parallel pass over tets writes, per tet, a 6-bit mask of the (tet, local edge)
// pairs at or above strength; when any is set, a pass over edges flags the candidates and
// picks each one's reporting tet (largest normal stress, lowest tet id on ties), a compaction
// lists them in edge-id order, and a pass over that list sets the flags and writes the events
// in that order. Nothing depends on the thread count.
// Cost: the non-local average is the expensive part (at R_d = 5 mean edge lengths a tet of a
// solid mesh has ~4k neighbours), so it is computed only where it could matter: a weighted
// mean of normal stresses never exceeds the largest principal stress among the neighbours,
// and all neighbours lie in the 27 grid cells around the tet, so a tet whose cells' largest
// Gershgorin bound stays below its edges' strengths is skipped exactly. When no tet comes
// near its strength the whole call is a bound per tet, a max per cell and a byte scan.
#pragma once

#include <cstdint>
#include <vector>

#include "fracture/fracture_model.h"
#include "fracture/fracture_stages.h"
#include "graphfrac/jobs.h"
#include "mesh/edge_graph.h"

namespace gf::detail {

/// Scratch of the criterion, sized on first use and reused, so a step allocates nothing
/// after warm-up.
struct CriterionWorkspace {
  /// 6 per tet: S averaged over R_d (non-local only), computed only for the tets whose bound
  /// could reach a strength (bit 7 of `candidates`); call averageStress for all of them.
  std::vector<double> averaged;
  /// Per tet: bit k set when local edge k reached strength; bit 7 when `averaged` holds it.
  std::vector<uint8_t> candidates;
  std::vector<double> bound;    ///< Per tet: Gershgorin bound of max principal stress.
  std::vector<double> cellMax;  ///< Per grid cell: largest bound of its tets.
  /// Room for every edge; the last call's candidates first, sorted (its count of them).
  std::vector<int32_t> candidateEdges;
  // Per edge: candidate flag, and the reporting tet's stress and id (EdgeCandidateStage).
  std::vector<uint8_t> edgeFlag;
  std::vector<double> edgeStress;
  std::vector<int32_t> edgeTet;
  std::vector<int32_t> chunkCount, chunkOffset;  ///< of the compaction
};

/// Non-local average of eq 4.10 with the model's linear weights, normalised by their sum:
/// out[6 t..] = sum_j w_tj S_j / sum_j w_tj. `out` holds 6 per tet. Parallel over tets.
/// The brittle seed choice wants it for every tet; the criterion computes it only where needed.
void averageStress(const FractureModel& model, const double* tetStress, double* out,
                   JobSystem& jobs);

/// The host's view of the model's arrays, `strength`, `broken` and `ws` (sized here).
CriterionView criterionView(const FractureModel& model, const EdgeGraph& graph,
                            const double* strength, const uint8_t* broken, CriterionWorkspace& ws);

/// Breaks the `count` candidates findCandidateEdges left in `ws` (eq 4.12, in edge-id order):
/// sets their flags in `broken` and appends their events (split points at `positions`, when
/// given). Returns count.
int32_t breakCandidates(const EdgeGraph& graph, const CriterionWorkspace& ws, int32_t count,
                        std::vector<uint8_t>& broken, std::vector<EdgeBreak>& events,
                        JobSystem& jobs, const double* positions);

/// Runs the criterion (eq 4.11-4.12) on per-tet material-frame stresses (6 per tet, Voigt)
/// against the per-edge strengths `strength` (the body's current ones, FractureData).
/// Sets broken[e] = 1 for every newly broken edge and appends one EdgeBreak per such edge to
/// `events`, sorted by edge id. `positions` (current, 3 per node) is optional and only used
/// for the events' split points (left at 0 when null). Returns the number of edges broken.
int32_t evaluateCriterion(const FractureModel& model, const EdgeGraph& graph,
                          const double* strength, const double* tetStress,
                          std::vector<uint8_t>& broken, std::vector<EdgeBreak>& events,
                          CriterionWorkspace& ws, JobSystem& jobs,
                          const double* positions = nullptr);

/// Per-tet 6-bit mask of broken local edges (bit k = kTetEdgeNodes[k]); `masks` holds one
/// byte per tet. A tet with a non-zero mask is damaged (fig 4.5).
void brokenEdgeMasks(const EdgeGraph& graph, const uint8_t* broken, uint8_t* masks,
                     JobSystem& jobs);

/// Incremental form of brokenEdgeMasks: sets the bits of the tets around each event's edge.
/// O(events), for the steps in which something broke.
void applyBreaksToMasks(const EdgeGraph& graph, const EdgeBreak* events, size_t count,
                        uint8_t* masks);

/// Tets with at least one broken edge, sorted by id (every element sharing a broken edge is
/// damaged, fig 4.5).
std::vector<int32_t> damagedTets(const EdgeGraph& graph, const uint8_t* broken);

}  // namespace gf::detail
