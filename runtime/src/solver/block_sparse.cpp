// Block-sparse pattern, deterministic gather assembly, Dirichlet rows and SpMV.
#include "solver/block_sparse.h"

#include <algorithm>
#include <cstdint>
#include <stdexcept>

#include "solver/vector_stages.h"
#include "step/executor.h"

namespace gf::detail {

namespace {
// Rows per SpMV/assembly range: a few hundred blocks of work, enough to hide scheduling cost.
constexpr uint32_t kRowGrain = 128;
}  // namespace

BlockSparseMatrix BlockSparseMatrix::fromTets(const int32_t* tets, size_t tetCount,
                                              size_t nodeCount) {
  BlockSparseMatrix A;
  A.n = static_cast<int32_t>(nodeCount);
  auto valid = [&](int32_t v) { return v >= 0 && static_cast<size_t>(v) < nodeCount; };

  // Count candidate entries per row (4 per tet incidence, plus the diagonal), fill, then sort
  // and deduplicate each row in place.
  std::vector<int64_t> offset(nodeCount + 1, 0);
  for (size_t i = 0; i < nodeCount; ++i) offset[i + 1] = 1;
  for (size_t t = 0; t < tetCount; ++t)
    for (int a = 0; a < 4; ++a)
      if (valid(tets[4 * t + a])) offset[tets[4 * t + a] + 1] += 4;
  for (size_t i = 0; i < nodeCount; ++i) offset[i + 1] += offset[i];
  std::vector<int32_t> cand(static_cast<size_t>(offset[nodeCount]));
  std::vector<int64_t> fill(offset.begin(), offset.end() - 1);
  for (size_t i = 0; i < nodeCount; ++i) cand[fill[i]++] = static_cast<int32_t>(i);
  for (size_t t = 0; t < tetCount; ++t) {
    const int32_t* v = tets + 4 * t;
    for (int a = 0; a < 4; ++a) {
      if (!valid(v[a])) continue;
      for (int b = 0; b < 4; ++b) {
        // A skipped (invalid) partner still takes a slot; it becomes a duplicate diagonal.
        cand[fill[v[a]]++] = valid(v[b]) ? v[b] : v[a];
      }
    }
  }

  A.rowStart.assign(nodeCount + 1, 0);
  A.col.reserve(cand.size() / 2);
  for (size_t i = 0; i < nodeCount; ++i) {
    auto first = cand.begin() + offset[i];
    auto last = cand.begin() + offset[i + 1];
    std::sort(first, last);
    last = std::unique(first, last);
    A.col.insert(A.col.end(), first, last);
    A.rowStart[i + 1] = static_cast<int32_t>(A.col.size());
  }
  A.col.shrink_to_fit();
  A.values.assign(9 * A.col.size(), 0.0);
  return A;
}

int32_t BlockSparseMatrix::find(int32_t r, int32_t c) const {
  if (r < 0 || r >= n) return -1;
  const int32_t* first = col.data() + rowStart[r];
  const int32_t* last = col.data() + rowStart[r + 1];
  const int32_t* it = std::lower_bound(first, last, c);
  return (it != last && *it == c) ? static_cast<int32_t>(it - col.data()) : -1;
}

void BlockSparseMatrix::setZero(JobSystem& jobs) {
  CpuExecutor(jobs).run(int32_t(values.size()), 4096, FillStage{0.0, values.data()});
}

void BlockSparseMatrix::multiply(const double* x, double* y, JobSystem& jobs) const {
  CpuExecutor(jobs).run(n, kRowGrain, SpmvStage{view(), x, y});
}

ElementGather ElementGather::build(const int32_t* tets, size_t tetCount,
                                   const BlockSparseMatrix& A) {
  // An entry holds 2 * (10 elem + upper block) + 1 in an int32_t.
  if (tetCount > size_t(INT32_MAX) / (2 * kElementMatrixSize / 9))
    throw std::length_error("ElementGather: more than 107 million tets");
  ElementGather g;
  g.elementBlockIndex.resize(16 * tetCount);
  g.start.assign(static_cast<size_t>(A.blockCount()) + 1, 0);
  for (size_t t = 0; t < tetCount; ++t) {
    for (int a = 0; a < 4; ++a) {
      for (int b = 0; b < 4; ++b) {
        int32_t k = A.find(tets[4 * t + a], tets[4 * t + b]);
        g.elementBlockIndex[16 * t + 4 * a + b] = k;
        if (k >= 0) ++g.start[k + 1];
      }
    }
  }
  for (size_t k = 0; k < static_cast<size_t>(A.blockCount()); ++k) g.start[k + 1] += g.start[k];
  // The lookahead's padding names block 0 of element 0: only ever prefetched.
  g.entry.assign(static_cast<size_t>(g.start.back()) + kGatherLookahead, 0);
  std::vector<int32_t> fill(g.start.begin(), g.start.end() - 1);
  // Element-major traversal makes each block's list increasing: a fixed summation order.
  for (size_t e = 0; e < 16 * tetCount; ++e) {
    int32_t k = g.elementBlockIndex[e];
    if (k < 0) continue;
    const int a = int(e / 4 % 4), b = int(e % 4);
    const int upper = upperBlockOffset(std::min(a, b), std::max(a, b)) / 9;
    g.entry[fill[k]++] =
        2 * (kElementMatrixSize / 9 * static_cast<int32_t>(e / 16) + upper) + (a > b);
  }
  return g;
}

void gatherElementBlocks(const ElementGather& gather, const double* elementMatrices, double scale,
                         BlockSparseMatrix& A, JobSystem& jobs, const GatherFusion& fusion) {
  AssembleStage stage{gather.start.data(), gather.entry.data(), elementMatrices, scale,
                      A.values.data()};
  stage.accumulate = fusion.accumulate;
  if (fusion.sum) stage.sum = fusion.sum->values.data();
  if (fusion.addAfter) {
    stage.addAfter = fusion.addAfter->values.data();
    stage.addScale = fusion.addScale;
  }
  CpuExecutor(jobs).run(A.blockCount(), 4 * kRowGrain, stage);
}

void applyDirichlet(BlockSparseMatrix& A, const uint8_t* fixedNode, JobSystem& jobs) {
  CpuExecutor(jobs).run(
      A.n, kRowGrain, DirichletStage{A.rowStart.data(), A.col.data(), fixedNode, A.values.data()});
}

}  // namespace gf::detail
