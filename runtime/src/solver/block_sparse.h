// Block-sparse matrix of the implicit step: square, 3x3 blocks, CSR over block rows.
//
// Design: both triangles are stored (full pattern), so SpMV is a plain parallel loop over block
// rows with disjoint writes, the same layout a CUDA kernel reads. The pattern comes from the
// tets once and never changes for a body's life (no remeshing; fracture changes values only),
// so assembly uses precomputed gather lists: every block sums its element contributions in a
// fixed order, which gives identical bits for any thread count without atomics.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "graphfrac/jobs.h"
#include "solver/sparse_stages.h"

namespace gf::detail {

/// Outcome of a linear solve (PCG or direct).
struct SolveReport {
  int iterations = 0;           ///< PCG iterations (0 for the direct solver).
  double relativeResidual = 0;  ///< |b - A x| / |b| of the returned x (0 when b == 0).
  bool converged = false;       ///< False on the iteration cap, breakdown or factorisation failure.
};

/// Square matrix of 3x3 blocks in block-CSR with the full (symmetric) pattern.
struct BlockSparseMatrix {
  int32_t n = 0;                  ///< Block rows (= block columns = nodes).
  std::vector<int32_t> rowStart;  ///< n + 1 offsets into col.
  std::vector<int32_t> col;       ///< Block column of each block, sorted within a row.
  std::vector<double> values;     ///< 9 per block, row-major 3x3.

  /// Pattern of every node pair sharing a tet plus every diagonal block; values zero. Tets name
  /// nodes in [0, nodeCount) (meshes are validated before this); a node index outside that
  /// range is skipped rather than written out of bounds.
  static BlockSparseMatrix fromTets(const int32_t* tets, size_t tetCount, size_t nodeCount);

  /// Number of stored blocks.
  int32_t blockCount() const { return static_cast<int32_t>(col.size()); }
  /// Index of block (r, c), or -1 if it is not in the pattern. Binary search in row r.
  int32_t find(int32_t r, int32_t c) const;
  /// Index of the diagonal block of row r (always present for a matrix from fromTets).
  int32_t diagonal(int32_t r) const { return find(r, r); }
  /// The 9 row-major values of block k.
  double* block(int32_t k) { return values.data() + 9 * static_cast<size_t>(k); }
  /// The 9 row-major values of block k.
  const double* block(int32_t k) const { return values.data() + 9 * static_cast<size_t>(k); }
  /// The matrix as the stages read it (valid until the pattern or the values are reallocated).
  BlockMatrixView view() const { return {n, rowStart.data(), col.data(), values.data()}; }
  /// Zeroes every value, keeping the pattern (a stage: it runs every Newton iteration).
  void setZero(JobSystem& jobs);
  /// y = A x over 3 n scalars; parallel over block rows. x and y must not alias.
  void multiply(const double* x, double* y, JobSystem& jobs) const;
};

/// Gather lists: for every block of the pattern, the element blocks that add into it.
struct ElementGather {
  std::vector<int32_t> start;  ///< blockCount + 1 offsets into entry.
  /// Element-local node block (a, b) of an element matrix as AssembleStage reads it: 2 * (its
  /// upper block's index in the element matrices, 10 elem + upper block (min, max)) + (a > b,
  /// read transposed); in increasing element order within a block, so the summation order is
  /// fixed. kGatherLookahead entries of padding follow start.back(). Elements below 2^31 / 20.
  std::vector<int32_t> entry;
  /// tetCount * 16: the block index of element pair (a, b), or -1 for a skipped node.
  std::vector<int32_t> elementBlockIndex;

  /// Builds the lists for `tets` against the pattern of A (typically from fromTets).
  static ElementGather build(const int32_t* tets, size_t tetCount, const BlockSparseMatrix& A);
};

/// Passes over the whole matrix that gatherElementBlocks takes over, block by block, with their
/// bits (AssembleStage): the step's first assembly writes A, K(x_n) for Rayleigh damping and
/// their axpy in one pass over the element matrices.
struct GatherFusion {
  bool accumulate = true;            ///< add into A (false: replace, as setZero and then add)
  BlockSparseMatrix* sum = nullptr;  ///< also receives the sum alone (A's pattern), or null
  const BlockSparseMatrix* addAfter = nullptr;  ///< A += addScale * addAfter last (A's pattern)
  double addScale = 0;
};

/// Adds scale * (sum of element contributions) into every block of A. elementMatrices holds a
/// symmetric 12x12 matrix per tet (rows/columns node-major, 3a + i) as its upper node blocks,
/// kElementMatrixSize doubles (kernels/math.h); the blocks below are their transposes.
/// Parallel over blocks with a fixed order inside each block: same bits for any thread count.
void gatherElementBlocks(const ElementGather& gather, const double* elementMatrices, double scale,
                         BlockSparseMatrix& A, JobSystem& jobs, const GatherFusion& fusion = {});

/// Dirichlet nodes: zeroes the block rows and columns of every node with fixedNode[i] != 0 and
/// puts the identity on its diagonal block, which keeps A symmetric positive definite. The
/// caller zeroes the right-hand side at those nodes, so the solution is zero there. Rows are
/// independent: same bits for any thread count.
void applyDirichlet(BlockSparseMatrix& A, const uint8_t* fixedNode, JobSystem& jobs = serialJobs());

}  // namespace gf::detail
