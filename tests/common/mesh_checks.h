// Independent reference computations shared by tests: connected components by a plain search
// over unbroken edges, the enclosed volume of a mesh's boundary (divergence theorem), and lumped
// node masses.
#pragma once

#include <graphfrac/mesh.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <vector>

#include "mesh/edge_graph.h"

namespace gf::test {

/// Lumped node masses as the runtime builds them: a quarter of each tet's mass per corner.
inline std::vector<double> lumpedMasses(const TetMesh& m, double rho) {
  std::vector<double> mass(m.nodeCount(), 0.0);
  for (size_t t = 0; t < m.tetCount(); ++t) {
    glm::dvec3 p[4];
    for (int k = 0; k < 4; ++k) {
      const size_t n = size_t(m.tets[4 * t + size_t(k)]);
      p[k] = {m.positions[3 * n], m.positions[3 * n + 1], m.positions[3 * n + 2]};
    }
    const double v = std::abs(glm::dot(p[1] - p[0], glm::cross(p[2] - p[0], p[3] - p[0]))) / 6;
    for (int k = 0; k < 4; ++k) mass[size_t(m.tets[4 * t + size_t(k)])] += 0.25 * rho * v;
  }
  return mass;
}

/// Connected components of the node graph over unbroken edges; returns the count and labels.
inline int components(const detail::EdgeGraph& g, const std::vector<uint8_t>& broken,
                      std::vector<int>& label) {
  label.assign(size_t(g.nodeCount), -1);
  int count = 0;
  std::vector<int32_t> stack;
  for (int32_t s = 0; s < g.nodeCount; ++s) {
    if (label[s] >= 0) continue;
    label[s] = count;
    stack.assign(1, s);
    while (!stack.empty()) {
      const int32_t v = stack.back();
      stack.pop_back();
      for (int32_t i = g.nodeEdgeStart[v]; i < g.nodeEdgeStart[v + 1]; ++i) {
        const int32_t e = g.nodeEdges[i];
        if (broken[e]) continue;
        const int32_t w = g.edgeNodes[2 * e] == v ? g.edgeNodes[2 * e + 1] : g.edgeNodes[2 * e];
        if (label[w] < 0) {
          label[w] = count;
          stack.push_back(w);
        }
      }
    }
    ++count;
  }
  return count;
}

/// Volume enclosed by the mesh's boundary faces (positive when they face outward).
inline double enclosedVolume(const TetMesh& m) {
  const std::vector<int32_t> f = m.boundaryFaces();
  double s = 0;
  for (size_t i = 0; i < f.size(); i += 3) {
    const double* a = &m.positions[3 * static_cast<size_t>(f[i])];
    const double* b = &m.positions[3 * static_cast<size_t>(f[i + 1])];
    const double* c = &m.positions[3 * static_cast<size_t>(f[i + 2])];
    s += a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
         a[2] * (b[0] * c[1] - b[1] * c[0]);
  }
  return s / 6.0;
}

}  // namespace gf::test
