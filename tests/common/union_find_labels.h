// The independent truth the fragment tests compare with: a serial union-find over a graph's
// unbroken edges, each node labelled with the smallest node of its set.
#pragma once

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <vector>

#include "mesh/edge_graph.h"

namespace gf::test {

inline std::vector<int32_t> unionFindLabels(const detail::EdgeGraph& g,
                                            const std::vector<uint8_t>& broken) {
  std::vector<int32_t> parent(size_t(g.nodeCount));
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int32_t a) {
    while (parent[size_t(a)] != a) a = parent[size_t(a)] = parent[size_t(parent[size_t(a)])];
    return a;
  };
  for (int32_t e = 0; e < g.edgeCount; ++e) {
    if (broken[size_t(e)]) continue;
    const int32_t a = find(g.edgeNodes[2 * size_t(e)]), b = find(g.edgeNodes[2 * size_t(e) + 1]);
    if (a != b) parent[size_t(std::max(a, b))] = std::min(a, b);
  }
  std::vector<int32_t> label(parent.size());
  for (int32_t u = 0; u < g.nodeCount; ++u) label[size_t(u)] = find(u);
  return label;
}

}  // namespace gf::test
