// The merge of free pieces that share a tet (fem/piece_merge.h, gpu/piece_merge.cu) on the
// device executor against the CPU executor and a serial union-find, on random pieces and tets:
// merged ids are integers, so the device must give the CPU's ids, count and rounds exactly. Built
// twice like test_fragment_backend.cpp: the host build (label `backend`, CI) and the CUDA build
// (labels `backend` and `gpu`; skipped, and reported as skipped, where no device exists).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "common/piece_merge_truth.h"
#include "fem/piece_merge.h"
#include "gpu/piece_merge.h"
#include "graphfrac/jobs.h"
#include "step/executor.h"

namespace gf {
namespace {

struct PieceCase {
  const char* name;
  int32_t count;  // free pieces before the merge
  unsigned seed;  // of the first of the three joining shares
};

std::string caseName(const testing::TestParamInfo<PieceCase>& info) { return info.param.name; }

class PieceMergeBackend : public testing::TestWithParam<PieceCase> {};

TEST_P(PieceMergeBackend, DeviceMergesLikeTheCpuAndAUnionFind) {
  std::string why;
  if (!gpu::deviceAvailable(why)) GTEST_SKIP() << why;
  ThreadPoolJobSystem jobs(2);
  const int32_t count = GetParam().count;
  unsigned seed = GetParam().seed;
  for (int cross : {0, 3, 30}) {
    const test::PieceMergeCase c = test::randomPieceMergeCase(6000, count, 5000, cross, seed++);
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

// The seeds are those the three piece counts had when this was one case (40, 43, 46).
const PieceCase kCases[] = {
    {"FivePieces", 5, 40}, {"ThreeHundredPieces", 300, 43}, {"FourThousandPieces", 4000, 46}};

// The host build (gf_backend_tests) and the CUDA build (gf_gpu_tests) name their cases apart.
#if defined(GF_GPU_CUDA)
INSTANTIATE_TEST_SUITE_P(Device, PieceMergeBackend, testing::ValuesIn(kCases), caseName);
#else
INSTANTIATE_TEST_SUITE_P(HostBuild, PieceMergeBackend, testing::ValuesIn(kCases), caseName);
#endif

}  // namespace
}  // namespace gf
