// The merge of free pieces that share a tet (fem/piece_merge.h, run by Integrator::groupPieces
// under the projection damage model) against a plain serial union-find on random inputs and
// on a body's mesh: the same merged ids and count, and the same ids and rounds for any thread
// count.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "common/piece_merge_truth.h"
#include "fem/piece_merge.h"
#include "graphfrac/jobs.h"
#include "graphfrac/mesh.h"
#include "step/executor.h"

namespace gf::detail {
namespace {

struct MergeResult {
  std::vector<int32_t> pieceOf;
  int32_t count = 0, rounds = 0;
};

MergeResult mergeOnCpu(JobSystem& jobs, const test::PieceMergeCase& c) {
  MergeResult r;
  r.pieceOf = c.pieceOf;
  const size_t n = size_t(c.count), chunks = size_t(pieceMergeChunks(c.count));
  std::vector<int32_t> label(n), next(n), rootId(n + 1), chunkSum(chunks), chunkOffset(chunks + 1);
  std::vector<double> changed(n);
  const PieceMergeScratch s{label.data(),  next.data(),     changed.data(),
                            rootId.data(), chunkSum.data(), chunkOffset.data()};
  r.count = mergePiecesSharingTets(CpuExecutor(jobs), c.tets.data(), int32_t(c.tets.size() / 4),
                                   r.pieceOf.data(), c.nodes, c.count, s, &r.rounds);
  return r;
}

void expectLikeUnionFind(const test::PieceMergeCase& c, const std::string& what) {
  std::vector<int32_t> truth = c.pieceOf;
  const int32_t merged = test::mergePiecesByUnionFind(c.tets, truth, c.count);
  ThreadPoolJobSystem one(1), two(2), four(4);
  const MergeResult r1 = mergeOnCpu(one, c);
  EXPECT_EQ(r1.count, merged) << what;
  EXPECT_EQ(r1.pieceOf, truth) << what;
  for (JobSystem* jobs : {static_cast<JobSystem*>(&two), static_cast<JobSystem*>(&four)}) {
    const MergeResult r = mergeOnCpu(*jobs, c);
    EXPECT_EQ(r.pieceOf, r1.pieceOf) << what << ", " << jobs->threadCount() << " threads";
    EXPECT_EQ(r.rounds, r1.rounds) << what << ", " << jobs->threadCount() << " threads";
  }
}

TEST(PieceMerge, RandomPiecesMergeLikeASerialUnionFind) {
  int seed = 1;
  // From no joining tet to most pieces joined, with few and many pieces.
  for (int32_t count : {2, 7, 60, 900})
    for (int cross : {0, 1, 5, 30, 100}) {
      const test::PieceMergeCase c =
          test::randomPieceMergeCase(3000, count, 2000, cross, unsigned(seed++));
      expectLikeUnionFind(
          c, std::to_string(count) + " pieces, " + std::to_string(cross) + " % joining tets");
    }
}

TEST(PieceMerge, ALongChainMergesIntoOnePiece) {
  const test::PieceMergeCase c = test::chainPieceMergeCase(5000, 9);
  expectLikeUnionFind(c, "chain of 5000 pieces");
  ThreadPoolJobSystem two(2);
  const MergeResult r = mergeOnCpu(two, c);
  EXPECT_EQ(r.count, 1);
  // Hooking and shortcutting: far fewer rounds than the chain is long.
  EXPECT_LT(r.rounds, 200);
  std::printf("[ figures ] chain of 5000 pieces merged in %d rounds\n", r.rounds);
}

TEST(PieceMerge, FragmentsOfABoxJoinedByDamagedTets) {
  // A box's nodes cut into slabs along x (pieces numbered against x), a share of the tets
  // across slab borders kept as damaged tets that join their slabs.
  const TetMesh m = gen::box(2, 0.5, 0.5, 24, 6, 6);
  const int32_t nodes = int32_t(m.nodeCount()), slabs = 12;
  for (int keepPercent : {0, 20, 100}) {
    test::PieceMergeCase c;
    c.nodes = nodes;
    c.count = slabs;
    c.pieceOf.resize(size_t(nodes));
    for (int32_t n = 0; n < nodes; ++n) {
      const int32_t slab =
          std::min(slabs - 1, int32_t(m.positions[3 * size_t(n)] / 2.0 * double(slabs)));
      c.pieceOf[size_t(n)] = slabs - 1 - slab;
    }
    std::mt19937 rng(unsigned(keepPercent) + 1);
    for (size_t t = 0; t < m.tetCount(); ++t) {
      const int32_t* v = &m.tets[4 * t];
      const bool cross = c.pieceOf[size_t(v[0])] != c.pieceOf[size_t(v[1])] ||
                         c.pieceOf[size_t(v[0])] != c.pieceOf[size_t(v[2])] ||
                         c.pieceOf[size_t(v[0])] != c.pieceOf[size_t(v[3])];
      if (cross && int(rng() % 100) >= keepPercent) continue;
      c.tets.insert(c.tets.end(), v, v + 4);
    }
    expectLikeUnionFind(c, "box slabs, " + std::to_string(keepPercent) + " % of border tets");
  }
}

}  // namespace
}  // namespace gf::detail
