// The merge of free pieces that share a tet (fem/piece_merge.h, gpu/piece_merge.cu) on the
// device executor against the CPU executor and a serial union-find, on random pieces and tets:
// merged ids are integers, so the device must give the CPU's ids, count and rounds exactly. Built
// twice like test_fragment_backend.cpp: label `backend` (host build, CI) and `gpu` (skipped, and
// reported as skipped, where no device exists).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "common/piece_merge_truth.h"
#include "fem/piece_merge.h"
#include "gpu/piece_merge.h"
#include "graphfrac/jobs.h"
#include "step/executor.h"

namespace gf {

TEST(PieceMergeBackend, DeviceMergesLikeTheCpuAndAUnionFind) {
  std::string why;
  if (!gpu::deviceAvailable(why)) GTEST_SKIP() << why;
  ThreadPoolJobSystem jobs(2);
  int seed = 40;
  for (int32_t count : {5, 300, 4000})
    for (int cross : {0, 3, 30}) {
      const test::PieceMergeCase c =
          test::randomPieceMergeCase(6000, count, 5000, cross, unsigned(seed++));
      const std::string what =
          std::to_string(count) + " pieces, " + std::to_string(cross) + " % joining tets";
      std::vector<int32_t> truth = c.pieceOf;
      const int32_t merged = test::mergePiecesByUnionFind(c.tets, truth, c.count);

      // CPU executor, host memory.
      const size_t n = size_t(c.count), chunks = size_t(detail::pieceMergeChunks(c.count));
      std::vector<int32_t> cpu = c.pieceOf, label(n), next(n), rootId(n + 1), chunkSum(chunks),
                           chunkOffset(chunks + 1);
      std::vector<double> changed(n);
      int32_t cpuRounds = -1;
      const int32_t cpuCount =
          detail::mergePiecesSharingTets(detail::CpuExecutor(jobs), c.tets.data(),
                                         int32_t(c.tets.size() / 4), cpu.data(), c.nodes, c.count,
                                         {label.data(), next.data(), changed.data(), rootId.data(),
                                          chunkSum.data(), chunkOffset.data()},
                                         &cpuRounds);

      // Device executor, device memory (gpu/piece_merge.cu).
      gpu::DevicePieceMerge device;
      ASSERT_TRUE(device.upload(c.tets.data(), int32_t(c.tets.size() / 4), c.nodes))
          << device.error();
      std::vector<int32_t> dev = c.pieceOf;
      int32_t devCount = -1, devRounds = -1;
      ASSERT_TRUE(device.merge(dev.data(), c.count, devCount, devRounds)) << device.error();

      EXPECT_EQ(cpuCount, merged) << what;
      EXPECT_EQ(cpu, truth) << what;
      EXPECT_EQ(devCount, cpuCount) << what;
      EXPECT_EQ(dev, cpu) << what;
      EXPECT_EQ(devRounds, cpuRounds) << what;
    }
}

}  // namespace gf
