// Union-find over int32 ids for the cut body's pieces and its surface's vertices: the smaller
// root wins, so a set's root is its first member and results do not depend on the join order.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

namespace gf::detail {

/// The root of i, halving the path on the way.
inline int32_t findRoot(std::vector<int32_t>& parent, int32_t i) {
  while (parent[size_t(i)] != i) {
    parent[size_t(i)] = parent[size_t(parent[size_t(i)])];
    i = parent[size_t(i)];
  }
  return i;
}

/// Joins the sets of a and b under the smaller root.
inline void unite(std::vector<int32_t>& parent, int32_t a, int32_t b) {
  a = findRoot(parent, a);
  b = findRoot(parent, b);
  if (a != b) parent[size_t(std::max(a, b))] = std::min(a, b);
}

}  // namespace gf::detail
