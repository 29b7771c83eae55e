// Galerkin multigrid hierarchy (thesis sec 6.2, Xian et al. 2019): furthest-point handles,
// nearest-handle binding, the piecewise-constant affine prolongation U and the coarse operators
// A_{l+1} = U^T A_l U.
//
// Design: every coarse level binds each fine node to exactly one handle (w in {0, 1}), and the
// levels are nested (a level's handles are a subset of the next finer level's, and a finer
// handle belongs to the coarser handle its own node is bound to), so the composed prolongation
// from the fine mesh to level l is again piecewise constant: fine node i moves with the affine
// map of its level-l handle h, x_i = T_h [(X_i - X_h) / s_l; 1] (eq 6.6-6.7). Rest coordinates
// are taken relative to the handle and divided by a level length s_l (the RMS distance of the
// fine nodes to their handle) so the linear and the translation columns of U have the same
// magnitude and the 12x12 coarse blocks stay well conditioned; this is a change of basis of the
// same coarse space. Each level's operator is therefore gathered straight from the fine matrix
// through a precomputed contribution list (the same numbers as the chain U_1^T ... U_0^T A U_0
// ... U_1), while the V-cycle moves vectors level by level with eq 6.8, a 4x4 (x) I3 change of
// reference point per handle. Dirichlet nodes are bound to no handle (zero rows of U), so the
// coarse correction never moves them.
#pragma once

#include <cstdint>
#include <vector>

#include "graphfrac/jobs.h"
#include "graphfrac/status.h"
#include "solver/block_sparse.h"

namespace gf::detail {

/// The tet edge graph as node adjacency (the off-diagonal pattern of the system matrix) with
/// rest edge lengths and a broken flag per directed entry.
struct NodeGraph {
  int32_t n = 0;
  std::vector<int32_t> start, adj;  ///< CSR, neighbours sorted within a node
  std::vector<double> length;       ///< rest length of each adjacency entry
  std::vector<uint8_t> alive;       ///< 0 once the edge is broken

  static NodeGraph fromPattern(const BlockSparseMatrix& A, const double* restPositions);
  /// Sets the broken state of every listed edge (2 nodes per edge) and revives all others.
  void setBroken(const int32_t* edgeNodes, const uint8_t* broken, int32_t edgeCount);
  /// Connected components over unbroken edges; returns the count, component per node.
  int32_t components(std::vector<int32_t>& component) const;
};

/// Furthest-point sampling with geodesic (Dijkstra) distances over unbroken edges: starts at
/// the lowest-index free node, then repeatedly takes the free node furthest from all chosen ones
/// (ties to the lowest index; unreachable nodes are infinitely far). Returns min(count, free
/// nodes) nodes; any prefix of the result is itself a furthest-point sample.
std::vector<int32_t> furthestPointSample(const NodeGraph& g, const uint8_t* fixedNode,
                                         int32_t count);

/// Multi-source Dijkstra over unbroken edges: owner[i] = index into sources of the nearest
/// source (ties to the lower source index), -1 when unreachable; dist[i] its distance.
void nearestSources(const NodeGraph& g, const int32_t* sources, int32_t sourceCount,
                    std::vector<int32_t>& owner, std::vector<double>& dist);

/// Square matrix of 12x12 blocks (a coarse level), block-CSR with the full symmetric pattern.
/// Inside a block, index 3a + k is affine column a (0-2 linear, 3 translation) and axis k.
struct CoarseMatrix {
  int32_t n = 0;
  std::vector<int32_t> rowStart, col;
  std::vector<double> values;  ///< 144 per block, row-major

  int32_t find(int32_t r, int32_t c) const;
  double* block(int32_t k) { return values.data() + 144 * static_cast<size_t>(k); }
  const double* block(int32_t k) const { return values.data() + 144 * static_cast<size_t>(k); }
};

/// One coarse level (level 1 is the finest coarse level).
struct CoarseLevel {
  std::vector<int32_t> handleNode;  ///< fine node of each handle
  /// Per fine node: its handle at this level (composed through the finer levels), or -1 for a
  /// Dirichlet node or a node of a fragment too small to get a handle.
  std::vector<int32_t> nodeHandle;
  std::vector<double> coord;  ///< 3 per fine node: (X_i - X_h) / scale, 0 when unbound
  double scale = 1;           ///< s_l [m]
  /// Restriction from the next finer level: level 1 lists bound fine nodes, deeper levels the
  /// finer level's handles, each in increasing order (a fixed summation order).
  std::vector<int32_t> childStart, child;
  std::vector<int32_t> finerParent;  ///< deeper levels: this level's handle of each finer handle
  std::vector<double> childOffset;   ///< deeper levels, 3 per finer handle: (X_H - X_h) / scale
  double childRatio = 1;             ///< deeper levels: s_{l-1} / s_l
  CoarseMatrix A;                    ///< A_l = U^T A_{l-1} U (eq 6.4)
  /// Per coarse block, the fine blocks that add into it (increasing): the eq-6.4 gather.
  std::vector<int32_t> gatherStart, gatherBlock;
  /// 16 per handle: N N^T with N the near-null directions of the aggregate's [X; 1] Gram matrix
  /// (an aggregate of 1-3 nodes or of coplanar nodes). U maps them to zero, so the coarse
  /// operator is singular there; adding them to the diagonal block changes no correction.
  std::vector<double> nullProjector;
};

/// The coarse levels of one body and the operations between them.
class MultigridHierarchy {
 public:
  /// Builds the levels for `counts` handles per coarse level, finest coarse level first
  /// (strictly decreasing). Counts above the number of free nodes are clamped.
  Result<void> build(const std::vector<int32_t>& counts, const double* restPositions,
                     const uint8_t* fixedNode, const BlockSparseMatrix& A);
  /// Crack re-binding (SPEC §5): re-binds every level by Dijkstra over unbroken edges from the
  /// existing handles, gives a handle to each fragment that has none (so counts can grow) and
  /// rebuilds the coarse patterns.
  void rebind(const int32_t* edgeNodes, const uint8_t* broken, int32_t edgeCount);
  /// Recomputes every level's operator from the fine matrix (same pattern as at build).
  void assemble(const BlockSparseMatrix& A, JobSystem& jobs);

  /// coarse = U^T fine between MG level `level` and level + 1 (level 0 is the fine mesh).
  void restrictTo(int level, const double* fine, double* coarse, JobSystem& jobs) const;
  /// fine += U coarse between MG level `level` and level + 1 (eq 6.3, 6.8).
  void prolongAdd(int level, const double* coarse, double* fine, JobSystem& jobs) const;

  int coarseLevelCount() const { return static_cast<int>(m_levels.size()); }
  /// Coarse level `l`, 1-based (1 = finest coarse level).
  const CoarseLevel& level(int l) const { return m_levels[static_cast<size_t>(l - 1)]; }
  const NodeGraph& graph() const { return m_graph; }
  int32_t handleCount(int l) const { return static_cast<int32_t>(level(l).handleNode.size()); }

 private:
  void bindAll();
  void buildPatterns();

  NodeGraph m_graph;
  std::vector<double> m_rest;
  std::vector<uint8_t> m_fixed;
  std::vector<int32_t> m_fineRow;  ///< block row of each fine block
  std::vector<int32_t> m_fineRowStart, m_fineCol;
  std::vector<CoarseLevel> m_levels;
};

}  // namespace gf::detail
