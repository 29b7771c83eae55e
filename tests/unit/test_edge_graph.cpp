// Edge graph: counts against Euler's formula and consistency of every map.
#include <graphfrac/mesh.h>
#include <gtest/gtest.h>

#include <set>
#include <utility>

#include "mesh/edge_graph.h"

namespace gf::detail {
namespace {

TEST(EdgeGraph, CountsAndMapsAreConsistent) {
  const TetMesh m = gen::box(1, 1, 1, 3, 2, 2);
  const EdgeGraph g = EdgeGraph::build(m.tets.data(), m.tetCount(), m.nodeCount());
  // Independent count: the set of node pairs of all tets.
  std::set<std::pair<int, int>> pairs;
  for (size_t t = 0; t < m.tetCount(); ++t)
    for (const auto& e : kTetEdgeNodes) {
      int a = m.tets[4 * t + e[0]], b = m.tets[4 * t + e[1]];
      pairs.insert({std::min(a, b), std::max(a, b)});
    }
  ASSERT_EQ(size_t(g.edgeCount), pairs.size());
  // Euler characteristic of a ball: V - E + F - T = 1, with F = (4T + boundary faces) / 2.
  const long V = long(m.nodeCount()), T = long(m.tetCount());
  const long F = (4 * T + long(m.boundaryFaces().size() / 3)) / 2;
  EXPECT_EQ(V - g.edgeCount + F - T, 1);
  for (size_t t = 0; t < m.tetCount(); ++t)
    for (int k = 0; k < 6; ++k) {
      const int32_t e = g.tetEdges[6 * t + k];
      const int a = m.tets[4 * t + kTetEdgeNodes[k][0]], b = m.tets[4 * t + kTetEdgeNodes[k][1]];
      EXPECT_EQ(g.find(a, b), e);
      bool listed = false;
      for (int32_t s = g.edgeTetStart[e]; s < g.edgeTetStart[e + 1]; ++s)
        listed |= g.edgeTets[s] == int32_t(6 * t + k);
      EXPECT_TRUE(listed);
    }
  int32_t degreeSum = 0;
  for (int32_t v = 0; v < g.nodeCount; ++v)
    degreeSum += g.nodeEdgeStart[v + 1] - g.nodeEdgeStart[v];
  EXPECT_EQ(degreeSum, 2 * g.edgeCount);
  EXPECT_EQ(g.find(0, 0), -1);
}

}  // namespace
}  // namespace gf::detail
