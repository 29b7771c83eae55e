// The mesh's edge graph (thesis ch. 4): fracture is damage on these edges, never a remesh.
// Built once per body; flat CSR arrays a CUDA backend can copy as they are.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace gf::detail {

/// Local edge order of a tet (SPEC §1): 01, 02, 03, 12, 13, 23.
inline constexpr int kTetEdgeNodes[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};

/// Unique edges of a tet mesh with the maps fracture and surfaces need.
struct EdgeGraph {
  int32_t nodeCount = 0;
  int32_t edgeCount = 0;
  std::vector<int32_t> edgeNodes;  ///< 2 per edge, smaller node first; edges sorted by (a, b)
  std::vector<int32_t> tetEdges;   ///< 6 per tet, in kTetEdgeNodes order
  std::vector<int32_t> edgeTetStart, edgeTets;    ///< edge -> tet*6 + local edge (CSR)
  std::vector<int32_t> nodeEdgeStart, nodeEdges;  ///< node -> incident edges (CSR)

  /// Builds the graph from 4 node indices per tet (a validated mesh).
  static EdgeGraph build(const int32_t* tets, size_t tetCount, size_t nodeCount);
  /// Edge index of (a, b) in either order, or -1.
  int32_t find(int32_t a, int32_t b) const;
};

}  // namespace gf::detail
