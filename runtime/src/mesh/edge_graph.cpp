#include "mesh/edge_graph.h"

#include <algorithm>
#include <utility>

namespace gf::detail {

EdgeGraph EdgeGraph::build(const int32_t* tets, size_t tetCount, size_t nodeCount) {
  EdgeGraph g;
  g.nodeCount = int32_t(nodeCount);
  // Every (tet, local edge) as (min node, max node, tet*6 + local), sorted: equal keys are one
  // edge, and the sort makes edge ids independent of the tet order's accidents.
  struct Ref {
    int32_t a, b, slot;
  };
  std::vector<Ref> refs;
  refs.reserve(6 * tetCount);
  for (size_t t = 0; t < tetCount; ++t)
    for (int k = 0; k < 6; ++k) {
      int32_t a = tets[4 * t + kTetEdgeNodes[k][0]], b = tets[4 * t + kTetEdgeNodes[k][1]];
      if (a > b) std::swap(a, b);
      refs.push_back({a, b, int32_t(6 * t + k)});
    }
  std::sort(refs.begin(), refs.end(), [](const Ref& x, const Ref& y) {
    return x.a != y.a ? x.a < y.a : (x.b != y.b ? x.b < y.b : x.slot < y.slot);
  });
  g.tetEdges.assign(6 * tetCount, -1);
  g.edgeTetStart.push_back(0);
  for (size_t i = 0; i < refs.size(); ++i) {
    if (i == 0 || refs[i].a != refs[i - 1].a || refs[i].b != refs[i - 1].b) {
      if (i > 0) g.edgeTetStart.push_back(int32_t(i));
      g.edgeNodes.push_back(refs[i].a);
      g.edgeNodes.push_back(refs[i].b);
    }
    const int32_t e = int32_t(g.edgeNodes.size() / 2 - 1);
    g.tetEdges[refs[i].slot] = e;
    g.edgeTets.push_back(refs[i].slot);
  }
  g.edgeTetStart.push_back(int32_t(refs.size()));
  if (refs.empty()) g.edgeTetStart = {0};
  g.edgeCount = int32_t(g.edgeNodes.size() / 2);

  g.nodeEdgeStart.assign(nodeCount + 1, 0);
  for (int32_t v : g.edgeNodes) ++g.nodeEdgeStart[v + 1];
  for (size_t i = 0; i < nodeCount; ++i) g.nodeEdgeStart[i + 1] += g.nodeEdgeStart[i];
  g.nodeEdges.resize(g.edgeNodes.size());
  std::vector<int32_t> fill(g.nodeEdgeStart.begin(), g.nodeEdgeStart.end() - 1);
  for (int32_t e = 0; e < g.edgeCount; ++e) {
    g.nodeEdges[fill[g.edgeNodes[2 * e]]++] = e;
    g.nodeEdges[fill[g.edgeNodes[2 * e + 1]]++] = e;
  }
  return g;
}

int32_t EdgeGraph::find(int32_t a, int32_t b) const {
  if (a > b) std::swap(a, b);
  if (a < 0 || a >= nodeCount) return -1;
  for (int32_t k = nodeEdgeStart[a]; k < nodeEdgeStart[a + 1]; ++k) {
    const int32_t e = nodeEdges[k];
    if (edgeNodes[2 * e] == a && edgeNodes[2 * e + 1] == b) return e;
  }
  return -1;
}

}  // namespace gf::detail
