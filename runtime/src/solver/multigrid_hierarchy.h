// Galerkin multigrid hierarchy (thesis sec 6.2, Xian et al. 2019): furthest-point handles,
// nearest-handle binding, smoothed-aggregation prolongations P and the coarse operators
// A_{l+1} = P^T A_l P.
//
// Design: every coarse level binds each fine node to exactly one handle, and the levels are
// nested (a level's handles are a subset of the next finer level's, and a finer handle belongs
// to the coarser handle its own node is bound to). The tentative prolongation U of level l
// moves a finer row with the affine map of its handle: on level 1, fine node i gets
// x_i = T_h [(X_i - X_h) / s_l; 1] (eq 6.6-6.7); deeper, a finer handle's affine map is the
// coarser one seen from its own origin (eq 6.8, a 12x12 change of reference point). Rest
// coordinates are taken relative to the handle and divided by a level length s_l (the RMS
// distance of the fine nodes to their handle) so the linear and the translation columns have
// the same magnitude and the 12x12 coarse blocks stay well conditioned; this is a change of
// basis of the same coarse space. U alone is piecewise constant per aggregate, so its basis
// functions jump at aggregate borders and carry a large energy; one V-cycle then reduces the
// residual only about 1.5x at 100 nodes per handle. Smoothed aggregation (Vanek, Mandel and
// Brezina 1996) applies one damped block-Jacobi step to each level's U, P = (I - omega D^-1
// A_F) U with omega = 4 / (3 rho(D^-1 A_F)): the borders are smoothed over one ring of
// neighbours while the near-null space that U carries exactly (the affine fields, which hold
// the rigid modes) stays nearly untouched. A_F is the finer matrix without the blocks across
// broken edges, so no basis function reaches across a crack. P is smoothed with the matrix of
// the first assemble after build or rebind and then kept: the Galerkin product with the
// current matrix keeps every coarse operator exact for the system being solved (any fixed P
// gives an SPD V-cycle), and re-smoothing every solve would add a power iteration and the
// smoothing products (about a third more refresh time) for a basis that changes little while
// the body deforms. Every level's operator is the product P^T (A P) over precomputed block
// pairs in a fixed order (deterministic for any thread count); the transfers are the block
// products with P and P^T. Dirichlet nodes are bound to no handle (zero rows of P), so the
// coarse correction never moves them.
#pragma once

#include <cstdint>
#include <vector>

#include "graphfrac/jobs.h"
#include "graphfrac/status.h"
#include "solver/block_sparse.h"
#include "solver/galerkin_stages.h"
#include "solver/multigrid_stages.h"

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
  void setBroken(const int32_t* edgeNodes, const uint8_t* broken, int32_t edgeCount,
                 JobSystem& jobs = serialJobs());
  /// Connected components over unbroken edges, numbered by their lowest node; returns the
  /// count, component per node. The same on any thread count.
  int32_t components(std::vector<int32_t>& component, JobSystem& jobs = serialJobs()) const;
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

/// nearestSources kept from one re-binding to the next: after edges only broke (and the
/// sources are the same), only the nodes whose shortest path crossed a newly broken edge are
/// searched again; the result equals a full search.
struct NearestSearch {
  std::vector<int32_t> owner, pred;  ///< per node: index into the sources, predecessor node
  std::vector<double> dist;
  void update(const NodeGraph& g, const std::vector<int32_t>& sources);

 private:
  std::vector<int32_t> sourcesThen, childStart, child, cleared;
  std::vector<uint8_t> aliveThen;
};

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

/// One coarse level (level 1 is the finest coarse level). Its prolongation P_l maps this level's
/// handles to the next finer level (the mesh's nodes for l = 1, 3x12 blocks; level l-1's
/// handles deeper, 12x12 blocks).
struct CoarseLevel {
  std::vector<int32_t> handleNode;  ///< fine node of each handle
  NearestSearch search;             ///< the binding's Dijkstra from handleNode
  /// Per fine node: its handle at this level (composed through the finer levels), or -1 for a
  /// Dirichlet node or a node of a fragment too small to get a handle.
  std::vector<int32_t> nodeHandle;
  std::vector<double> coord;         ///< 3 per fine node: (X_i - X_h) / scale, 0 when unbound
  double scale = 1;                  ///< s_l [m]
  std::vector<int32_t> finerParent;  ///< deeper levels: this level's handle of each finer handle
  std::vector<double> childOffset;   ///< deeper levels, 3 per finer handle: (X_H - X_h) / scale
  double childRatio = 1;             ///< deeper levels: s_{l-1} / s_l

  /// P_l, block-CSR over the finer level's rows (columns = handles, increasing); each block is
  /// B x 12 row-major with B = 3 on level 1 and 12 deeper. Without smoothing it is the tentative
  /// prolongator T (eq 6.6-6.8: one block per bound row); smoothed, P = (I - omega D^-1 A_F) T.
  std::vector<int32_t> pStart, pCol, pRow;
  std::vector<double> pValues;
  std::vector<int32_t> ptStart, ptBlock;  ///< per handle, its P blocks by increasing finer row
  /// The transpose in that order, for the restriction P^T r to stream: the finer row of each
  /// entry and, smoothed, a copy of its block (the same B x 12 values as pValues).
  std::vector<int32_t> ptRow;
  std::vector<double> ptValues;
  /// The filtered finer-level matrix A_F of the smoothing, block-CSR over the finer rows, the
  /// diagonal block first: on level 1 the blocks of unbroken edges, deeper the alive blocks of
  /// level l-1; fBlock indexes the finer matrix's blocks.
  std::vector<int32_t> fStart, fBlock, fCol;
  /// Smoothing terms of each P block: pairs (finer-level matrix block A_rj, row j), j over the
  /// row's unbroken neighbours and itself whose parent is the block's handle.
  std::vector<int32_t> sStart, sBlock, sRow;
  double omega = 0;      ///< the damping of the last smoothing (0: tentative)
  double lambdaMax = 0;  ///< its estimate of rho(D^-1 A_F) on the finer level
  bool prolongationFresh = false;
  /// Q = A_{l-1} P, block-CSR like P; each block the sum of the listed (A block, P block) pairs.
  std::vector<int32_t> qStart, qCol, qcStart, qcA, qcP;
  std::vector<double> qValues;
  CoarseMatrix A;  ///< A_l = P^T A_{l-1} P (eq 6.4)
  /// Per block of A: 1 where P^T A_F P has the block too (a chain of unbroken edges joins the
  /// two handles' basis functions), 0 where only blocks across broken edges couple them. The
  /// next level's smoothing keeps the alive blocks only: no crack to filter means none dropped,
  /// so its smoothing keeps the affine fields as the fine one does.
  std::vector<uint8_t> alive;
  std::vector<int32_t> mirror;  ///< per block below the diagonal, its transpose's index; else -1
  /// Per coarse block on or above the diagonal, the (P block, Q block) pairs of one finer row
  /// each, rows increasing (the blocks below mirror them).
  std::vector<int32_t> gatherStart, gatherP, gatherQ;
  /// Level 1 only, 16 per handle: N N^T with N the near-null directions of the aggregate's
  /// [X; 1] Gram matrix (an aggregate of 1-3 nodes or of coplanar nodes). The tentative U, and
  /// so P, maps them to zero, so the coarse operator is singular there; adding them to the
  /// diagonal block changes no correction. Deeper levels inherit the regularised operator
  /// through P^T A P and keep zeros here.
  std::vector<double> nullProjector;
};

/// What a refresh leaves on one coarse level beyond its patterns: the operator and, smoothed,
/// the prolongator with the damping it was smoothed with.
struct CoarseLevelValues {
  std::vector<double> A;  ///< A_l's blocks; empty: not kept
  std::vector<double> P;  ///< smoothed P_l's blocks; empty: tentative, or to be re-smoothed
  double omega = 0, lambdaMax = 0;
};

/// The coarse levels of one body and the operations between them.
class MultigridHierarchy {
 public:
  /// Handle counts per coarse level, finest coarse level first, chosen from the body's free
  /// node count (MultigridSettings::levels empty): a fixed number of nodes per handle on
  /// level 1 (fewer with `smooth`), then 8 times fewer handles per level down to a coarsest
  /// level small enough to factorise on every refresh.
  static std::vector<int32_t> defaultCounts(int32_t freeNodes, bool smooth);

  /// Builds the levels for `counts` handles per coarse level, finest coarse level first
  /// (strictly decreasing). Counts above the number of free nodes are clamped. smooth: smoothed
  /// aggregation (one damped-Jacobi step on each tentative prolongator), else tentative only;
  /// filter: MultigridSettings::prolongationFilter.
  Result<void> build(const std::vector<int32_t>& counts, const double* restPositions,
                     const uint8_t* fixedNode, const BlockSparseMatrix& A, bool smooth = false,
                     double filter = 0);
  /// Crack re-binding (SPEC §5): re-binds every level by Dijkstra over unbroken edges from the
  /// existing handles, gives a handle to each fragment that has none (so counts can grow),
  /// rebuilds the patterns, and marks the prolongators for re-smoothing at the next assemble.
  /// The searches and the patterns run on `jobs`, with the same result for any thread count.
  void rebind(const int32_t* edgeNodes, const uint8_t* broken, int32_t edgeCount,
              JobSystem& jobs = serialJobs());
  /// Recomputes every level's operator from the fine matrix (same pattern as at build); the
  /// prolongators are smoothed first when they are not fresh (after build and rebind, or
  /// after invalidateProlongation).
  void assemble(const BlockSparseMatrix& A, JobSystem& jobs);
  /// Re-smooth the prolongators with the matrix of the next assemble.
  void invalidateProlongation();
  /// Every level's values (level 1 first), the operators only when `operators`.
  std::vector<CoarseLevelValues> values(bool operators) const;
  /// Puts back values() of a hierarchy with the same binding; false (nothing changed) when
  /// their sizes do not match the patterns.
  bool setValues(const std::vector<CoarseLevelValues>& values);

  /// The prolongator between MG level `level` and level + 1 as the transfer stages read it
  /// (valid until the next build, rebind or assemble).
  ProlongationView prolongation(int level) const;
  /// What coarse level l's operator is computed from (galerkin_stages.h), valid until the
  /// next build or rebind; assemble() runs galerkinProduct on it.
  GalerkinLevelView galerkinView(int l);
  /// coarse = P^T fine between MG level `level` and level + 1 (level 0 is the fine mesh).
  void restrictTo(int level, const double* fine, double* coarse, JobSystem& jobs) const;
  /// fine += P coarse between MG level `level` and level + 1 (eq 6.3, 6.8).
  void prolongAdd(int level, const double* coarse, double* fine, JobSystem& jobs) const;

  int coarseLevelCount() const { return static_cast<int>(m_levels.size()); }
  /// Coarse level `l`, 1-based (1 = finest coarse level).
  const CoarseLevel& level(int l) const { return m_levels[static_cast<size_t>(l - 1)]; }
  const NodeGraph& graph() const { return m_graph; }
  int32_t handleCount(int l) const { return static_cast<int32_t>(level(l).handleNode.size()); }
  bool smoothed() const { return m_smooth; }
  /// Whether level l's prolongation is smoothed (else tentative).
  bool smoothesLevel(int l) const { return m_smooth && l >= 1; }
  /// The tentative block (B x 12, row-major) of finer row `row` of level l's prolongator, zero
  /// when the row is unbound. Level 1: [x_i; 1]^T (x) I3 (eq 6.6-6.7); deeper: eq 6.8.
  void tentativeBlock(int l, int32_t row, double* out) const;
  /// The same block for the affine map of level-l handle `handle` (not necessarily the row's
  /// own): [(X_row - X_handle) / s_l; 1]^T (x) I3 on level 1, eq 6.8 from that handle deeper.
  void tentativeBlockFor(int l, int32_t row, int32_t handle, double* out) const;

 private:
  void bindAll(JobSystem& jobs);
  void buildPatterns(JobSystem& jobs);
  template <int B>
  void smoothProlongation(int l, const BlockSparseMatrix& A, JobSystem& jobs);

  NodeGraph m_graph;
  bool m_smooth = true;
  double m_filter = 0;
  std::vector<double> m_rest;
  std::vector<uint8_t> m_fixed;
  std::vector<int32_t> m_fineRow;  ///< block row of each fine block
  std::vector<int32_t> m_fineRowStart, m_fineCol;
  std::vector<CoarseLevel> m_levels;
  // Prolongator smoothing scratch: inverse diagonal blocks and power-iteration vectors of the
  // finer level, sized at build and rebind.
  std::vector<double> m_invDiag, m_v, m_w, m_t, m_partials;
  std::vector<int32_t> m_graphBlock;  ///< fine block of each m_graph adjacency entry
};

}  // namespace gf::detail
