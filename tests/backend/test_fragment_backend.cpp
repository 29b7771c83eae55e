// The device backend's fragment labelling (gpu/fragment_labels.cu) against the CPU executor and
// a serial union-find on the edge graphs of tet meshes (a box, a sphere) with random shares of
// their edges broken, from none to most. Labels are integers, so the device must give the
// CPU's labels exactly, and both the union-find's (every node labelled with the lowest node of
// its component). Built twice like test_element_backend.cpp: the host build (label `backend`,
// CI) and the CUDA build (labels `backend` and `gpu`; skipped, and reported as skipped, where
// no device exists).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "common/union_find_labels.h"
#include "gpu/fragment_labels.h"
#include "graphfrac/jobs.h"
#include "graphfrac/mesh.h"
#include "mesh/edge_graph.h"
#include "step/executor.h"
#include "surface/fragment_stages.h"

namespace gf {
namespace {

struct MeshCase {
  const char* name;
  bool sphere;
};

std::string caseName(const testing::TestParamInfo<MeshCase>& info) { return info.param.name; }

class FragmentBackend : public testing::TestWithParam<MeshCase> {};

TEST_P(FragmentBackend, LabelsMatchTheCpuAndAUnionFind) {
  std::string why;
  if (!gpu::deviceAvailable(why)) GTEST_SKIP() << why;
  const TetMesh m = GetParam().sphere ? gen::sphere(1, 8) : gen::box(1, 0.5, 0.5, 16, 8, 8);
  ThreadPoolJobSystem jobs(2);
  int components = 0;
  const detail::EdgeGraph g = detail::EdgeGraph::build(m.tets.data(), m.tetCount(), m.nodeCount());
  gpu::DeviceFragmentLabels device;
  ASSERT_TRUE(device.upload(g)) << device.error();
  std::mt19937 rng(3);
  for (int share : {0, 10, 40, 70, 95}) {
    std::vector<uint8_t> broken(size_t(g.edgeCount));
    for (auto& b : broken) b = int(rng() % 100) < share;
    const std::vector<int32_t> truth = test::unionFindLabels(g, broken);

    const size_t n = size_t(g.nodeCount);
    std::vector<int32_t> cpu(n), next(n), dev(n, -1);
    std::vector<double> changed(n);
    const detail::FragmentGraphView view{g.nodeCount, g.edgeNodes.data(), g.nodeEdgeStart.data(),
                                         g.nodeEdges.data(), broken.data()};
    const int32_t cpuRounds =
        detail::labelComponents(detail::CpuExecutor(jobs), view, nullptr, g.nodeCount, cpu.data(),
                                next.data(), changed.data());
    int32_t devRounds = -1;
    ASSERT_TRUE(device.label(broken.data(), dev.data(), devRounds)) << device.error();
    EXPECT_EQ(cpu, truth) << share << " % broken";
    EXPECT_EQ(dev, cpu) << share << " % broken";
    EXPECT_EQ(devRounds, cpuRounds);
    for (size_t u = 0; u < n; ++u) components += truth[u] == int32_t(u);
    std::printf("[ figures ] %s: %zu nodes, %d %% broken, %d rounds\n", gpu::deviceName().c_str(),
                n, share, cpuRounds);
  }
  // The heavily broken cases made many pieces.
  EXPECT_GT(components, int(m.nodeCount()) / 2);
}

const MeshCase kMeshes[] = {{"Box", false}, {"Sphere", true}};

// The host build (gf_backend_tests) and the CUDA build (gf_gpu_tests) name their cases apart.
#if defined(GF_GPU_CUDA)
INSTANTIATE_TEST_SUITE_P(Device, FragmentBackend, testing::ValuesIn(kMeshes), caseName);
#else
INSTANTIATE_TEST_SUITE_P(HostBuild, FragmentBackend, testing::ValuesIn(kMeshes), caseName);
#endif

}  // namespace
}  // namespace gf
