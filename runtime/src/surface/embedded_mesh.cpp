// Render meshes embedded in the tets: binding at creation, copies per fragment at fracture,
// positions every frame (see the design note in embedded_mesh.h).
#include "surface/embedded_mesh.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "kernels/contact.h"
#include "mesh/mesh_internal.h"
#include "step/executor.h"
#include "surface/surface_stages.h"

namespace gf::detail {

namespace {

inline Vec3 load(const double* p, size_t i) { return {p[3 * i], p[3 * i + 1], p[3 * i + 2]}; }

// A point counts as inside a tet when its weakest barycentric coordinate is above this (round-off
// of points on shared faces).
constexpr double kInsideTolerance = -1e-12;
// The grid has at most this many cells along an axis.
constexpr int kMaxGridCells = 256;

// Barycentric coordinates of P in tet t: (w1, w2, w3) = Dm^-1 (P - X0), w0 = 1 - w1 - w2 - w3.
void barycentric(const Mat3& dmInv, Vec3 X0, Vec3 P, double* w) {
  const Vec3 l = dmInv * (P - X0);
  w[1] = l.x;
  w[2] = l.y;
  w[3] = l.z;
  w[0] = 1 - l.x - l.y - l.z;
}

// The connected component of local node k among a tet's nodes over the joined local edges
// (bit j of `joined` for kTetEdgeNodes[j]), as a mask.
unsigned component(int k, unsigned joined) {
  unsigned group = 1u << k;
  for (int pass = 0; pass < 3; ++pass)
    for (int j = 0; j < 6; ++j) {
      const unsigned pair = (1u << kTetEdgeNodes[j][0]) | (1u << kTetEdgeNodes[j][1]);
      if ((joined >> j & 1u) && (group & pair)) group |= pair;
    }
  return group;
}

// The local node of the largest weight among `mask` (ties: the lowest).
int strongest(const double* w, unsigned mask) {
  int best = -1;
  for (int k = 0; k < 4; ++k)
    if ((mask >> k & 1u) && (best < 0 || w[k] > w[best])) best = k;
  return best;
}

}  // namespace

Result<EmbeddedBinding> EmbeddedBinding::bind(const TetMesh& rest, const RenderMesh& mesh,
                                              const std::string& field) {
  const size_t nt = rest.tetCount(), nv = mesh.vertexCount();
  const double* X = rest.positions.data();
  EmbeddedBinding b;
  b.rest = mesh.positions;
  b.uv = mesh.uvs;
  b.indices = mesh.indices;

  // Rest normals: the artist's, or area-weighted from the triangles where none are given.
  b.restNormal.assign(3 * nv, 0.0);
  if (!mesh.normals.empty()) {
    for (size_t i = 0; i < 3 * nv; ++i) b.restNormal[i] = double(mesh.normals[i]);
  } else {
    for (size_t t = 0; t < mesh.triangleCount(); ++t) {
      const uint32_t* id = &mesh.indices[3 * t];
      const Vec3 p0 = load(b.rest.data(), id[0]);
      const Vec3 n = cross(load(b.rest.data(), id[1]) - p0, load(b.rest.data(), id[2]) - p0);
      for (int c = 0; c < 3; ++c)
        for (int k = 0; k < 3; ++k) b.restNormal[3 * size_t(id[c]) + size_t(k)] += n[k];
    }
  }
  for (size_t v = 0; v < nv; ++v) {
    const Vec3 n = load(b.restNormal.data(), v);
    const double len = norm(n);
    const Vec3 u = len > 0 ? (1 / len) * n : Vec3{0, 0, 1};
    for (int k = 0; k < 3; ++k) b.restNormal[3 * v + size_t(k)] = u[k];
  }

  // Per tet: Dm^-1 and bounding box; the longest edge bounds how far outside a vertex may be.
  std::vector<Mat3> dmInv(nt);
  std::vector<Vec3> lo(nt), hi(nt);
  Vec3 gmin{HUGE_VAL, HUGE_VAL, HUGE_VAL}, gmax{-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
  double longest = 0, extentSum = 0;
  for (size_t t = 0; t < nt; ++t) {
    Vec3 P[4];
    for (int k = 0; k < 4; ++k) P[k] = load(X, size_t(rest.tets[4 * t + size_t(k)]));
    dmInv[t] = inverse(fromColumns(P[1] - P[0], P[2] - P[0], P[3] - P[0]));
    lo[t] = hi[t] = P[0];
    for (int k = 1; k < 4; ++k)
      for (int c = 0; c < 3; ++c) {
        lo[t][c] = std::min(lo[t][c], P[k][c]);
        hi[t][c] = std::max(hi[t][c], P[k][c]);
      }
    for (int j = 0; j < 6; ++j)
      longest = std::max(longest, norm(P[kTetEdgeNodes[j][0]] - P[kTetEdgeNodes[j][1]]));
    double extent = 0;
    for (int c = 0; c < 3; ++c) {
      gmin[c] = std::min(gmin[c], lo[t][c]);
      gmax[c] = std::max(gmax[c], hi[t][c]);
      extent = std::max(extent, hi[t][c] - lo[t][c]);
    }
    extentSum += extent;
  }

  // A uniform grid of about one tet box per cell; each tet is listed in every cell its box
  // touches (CSR).
  double h = extentSum / double(nt);
  for (int c = 0; c < 3; ++c) h = std::max(h, (gmax[c] - gmin[c]) / kMaxGridCells);
  int dim[3];
  for (int c = 0; c < 3; ++c)
    dim[c] = std::clamp(int(std::ceil((gmax[c] - gmin[c]) / h)), 1, kMaxGridCells);
  auto cellOf = [&](double v, int c) {
    return std::clamp(int(std::floor((v - gmin[c]) / h)), 0, dim[c] - 1);
  };
  const size_t cells = size_t(dim[0]) * size_t(dim[1]) * size_t(dim[2]);
  auto cellIndex = [&](int i, int j, int k) {
    return (size_t(k) * size_t(dim[1]) + size_t(j)) * size_t(dim[0]) + size_t(i);
  };
  std::vector<int32_t> start(cells + 1, 0), list;
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<int32_t> fill;
    if (pass == 1) {
      for (size_t c = 0; c < cells; ++c) start[c + 1] += start[c];
      list.resize(size_t(start[cells]));
      fill.assign(start.begin(), start.end() - 1);
    }
    for (size_t t = 0; t < nt; ++t)
      for (int k = cellOf(lo[t].z, 2); k <= cellOf(hi[t].z, 2); ++k)
        for (int j = cellOf(lo[t].y, 1); j <= cellOf(hi[t].y, 1); ++j)
          for (int i = cellOf(lo[t].x, 0); i <= cellOf(hi[t].x, 0); ++i) {
            const size_t c = cellIndex(i, j, k);
            if (pass == 0)
              ++start[c + 1];
            else
              list[size_t(fill[c]++)] = int32_t(t);
          }
  }

  b.tet.assign(nv, -1);
  b.weight.assign(4 * nv, 0.0);
  std::vector<uint32_t> seen(nt, 0);
  uint32_t stamp = 0;
  for (size_t v = 0; v < nv; ++v) {
    const Vec3 P = load(b.rest.data(), v);
    const int ci = cellOf(P.x, 0), cj = cellOf(P.y, 1), ck = cellOf(P.z, 2);
    // Containing tet: the one where P is deepest (largest weakest coordinate), so a point on a
    // shared face goes to one tet whatever the order.
    int32_t best = -1;
    double bestMin = kInsideTolerance, w[4];
    for (int32_t s = start[cellIndex(ci, cj, ck)]; s < start[cellIndex(ci, cj, ck) + 1]; ++s) {
      const int32_t t = list[size_t(s)];
      barycentric(dmInv[size_t(t)], load(X, size_t(rest.tets[4 * size_t(t)])), P, w);
      const double m = std::min({w[0], w[1], w[2], w[3]});
      if (m > bestMin) {
        bestMin = m;
        best = t;
      }
    }
    double bestDist = 0;
    if (best < 0) {
      // Outside every tet: the nearest one, searched ring by ring of cells; cells of ring r + 1
      // are at least r h away, so the search stops once the best is that close.
      bestDist = HUGE_VAL;
      if (++stamp == 0) {
        std::fill(seen.begin(), seen.end(), 0u);
        stamp = 1;
      }
      const int maxRing = std::max({dim[0], dim[1], dim[2]});
      for (int r = 0; r <= maxRing && !(bestDist <= (r - 1) * h); ++r)
        for (int k = std::max(ck - r, 0); k <= std::min(ck + r, dim[2] - 1); ++k)
          for (int j = std::max(cj - r, 0); j <= std::min(cj + r, dim[1] - 1); ++j)
            for (int i = std::max(ci - r, 0); i <= std::min(ci + r, dim[0] - 1); ++i) {
              if (std::max({std::abs(i - ci), std::abs(j - cj), std::abs(k - ck)}) != r) continue;
              const size_t c = cellIndex(i, j, k);
              for (int32_t s = start[c]; s < start[c + 1]; ++s) {
                const int32_t t = list[size_t(s)];
                if (seen[size_t(t)] == stamp) continue;
                seen[size_t(t)] = stamp;
                const int32_t* n = &rest.tets[4 * size_t(t)];
                double d = HUGE_VAL;
                for (const auto& f : kTetFaces) {
                  const Vec3 a = load(X, size_t(n[f[0]])), b = load(X, size_t(n[f[1]])),
                             c = load(X, size_t(n[f[2]]));
                  const Vec3 w = closestOnTriangle(P, a, b, c);
                  d = std::min(d, norm(P - (w.x * a + w.y * b + w.z * c)));
                }
                if (d < bestDist) {
                  bestDist = d;
                  best = t;
                }
              }
            }
      if (!(bestDist <= 2 * longest)) {
        char text[160];
        std::snprintf(text, sizeof text,
                      ".positions[%zu]: (%.6g, %.6g, %.6g) lies %.6g m from the nearest tet, ", v,
                      P.x, P.y, P.z, bestDist);
        char limit[48];
        std::snprintf(limit, sizeof limit, "%.6g m", longest);
        return fail(field, text, "more than twice the longest tet edge (", limit,
                    "): the render mesh does not fit the body's mesh (units or placement?)");
      }
      ++b.outsideCount;
      b.maxOutside = std::max(b.maxOutside, bestDist);
    }
    b.tet[v] = best;
    barycentric(dmInv[size_t(best)], load(X, size_t(rest.tets[4 * size_t(best)])), P,
                &b.weight[4 * v]);
  }
  return b;
}

void EmbeddedSurface::init(const EmbeddedBinding& binding, const TetMesh& rest,
                           const EdgeGraph& graph, const Mat3* restInverse) {
  m_binding = &binding;
  m_rest = &rest;
  m_graph = &graph;
  m_restInverse = restInverse;
  m_frameMark.assign(rest.nodeCount(), 0);
  m_composed = false;
}

uint32_t EmbeddedSurface::addCopy(int32_t source, int32_t tet, const double* w, unsigned group,
                                  int32_t fragment) {
  const uint32_t id = uint32_t(m_vTet.size());
  const int32_t* n = &m_rest->tets[4 * size_t(tet)];
  m_vTet.push_back(tet);
  m_vSource.push_back(source);
  m_vWeight.insert(m_vWeight.end(), w, w + 4);
  m_vGroup.push_back(uint8_t(group));
  m_vNode.push_back(n[strongest(w, group)]);
  m_vFragment.push_back(fragment);
  // A copy that follows only part of its tet needs the local maps of the nodes it follows.
  if (group != 15u)
    for (int k = 0; k < 4; ++k)
      if ((group >> k & 1u) && !m_frameMark[size_t(n[k])]) {
        m_frameMark[size_t(n[k])] = 1;
        m_frameNodes.push_back(n[k]);
      }
  return id;
}

void EmbeddedSurface::rebuild(const uint8_t* broken, const int32_t* nodeFragment) {
  const EmbeddedBinding& b = *m_binding;
  const size_t nv = b.tet.size();
  auto joinedMask = [&](int32_t t) {
    const int32_t* te = &m_graph->tetEdges[6 * size_t(t)];
    unsigned m = 0;
    for (int j = 0; j < 6; ++j) m |= broken[te[j]] ? 0u : 1u << j;
    return m;
  };

  // Each vertex's own fragment and group: those of its tet's node of the largest weight, whose
  // corner cell holds it.
  m_home.resize(nv);
  m_homeGroup.resize(nv);
  for (size_t v = 0; v < nv; ++v) {
    const int32_t t = b.tet[v];
    const int k = strongest(&b.weight[4 * v], 15u);
    m_home[v] = nodeFragment[m_rest->tets[4 * size_t(t) + size_t(k)]];
    m_homeGroup[v] = uint8_t(component(k, joinedMask(t)));
  }

  m_homeCopy.assign(nv, -1);
  m_otherCopy.clear();
  for (int32_t a : m_frameNodes) m_frameMark[size_t(a)] = 0;
  m_frameNodes.clear();
  m_vTet.clear();
  m_vSource.clear();
  m_vWeight.clear();
  m_vGroup.clear();
  m_vNode.clear();
  m_vFragment.clear();
  m_renderIndices.clear();

  const size_t ntri = b.indices.size() / 3;
  for (size_t tri = 0; tri < ntri; ++tri) {
    const uint32_t* id = &b.indices[3 * tri];
    int32_t f = m_home[id[0]];
    if (m_home[id[1]] == m_home[id[2]]) f = m_home[id[1]];
    for (int c = 0; c < 3; ++c) {
      const uint32_t v = id[c];
      const double* w = &b.weight[4 * size_t(v)];
      if (m_home[v] == f) {
        if (m_homeCopy[v] < 0)
          m_homeCopy[v] = int32_t(addCopy(int32_t(v), b.tet[v], w, m_homeGroup[v], f));
        m_renderIndices.push_back(uint32_t(m_homeCopy[v]));
        continue;
      }
      const uint64_t key = uint64_t(v) << 32 | uint32_t(f);
      auto found = m_otherCopy.find(key);
      if (found != m_otherCopy.end()) {
        m_renderIndices.push_back(found->second);
        continue;
      }
      // The copy follows the triangle's fragment: its tet's nodes there, if it has any...
      const int32_t t = b.tet[v];
      const int32_t* n = &m_rest->tets[4 * size_t(t)];
      unsigned inF = 0;
      for (int k = 0; k < 4; ++k) inF |= nodeFragment[n[k]] == f ? 1u << k : 0u;
      uint32_t copy;
      if (inF) {
        copy = addCopy(int32_t(v), t, w, component(strongest(w, inF), joinedMask(t)), f);
      } else {
        // ...else the tet of a vertex of the triangle in that fragment, extrapolated.
        int cu = 0;
        while (m_home[id[cu]] != f) ++cu;
        const uint32_t u = id[cu];
        const int32_t tu = b.tet[u];
        double wu[4];
        barycentric(m_restInverse[tu],
                    load(m_rest->positions.data(), size_t(m_rest->tets[4 * size_t(tu)])),
                    load(b.rest.data(), v), wu);
        copy = addCopy(int32_t(v), tu, wu, m_homeGroup[u], f);
      }
      m_otherCopy.emplace(key, copy);
      m_renderIndices.push_back(copy);
    }
  }
  m_composed = false;
}

void EmbeddedSurface::compose(const CrackSurface& crack) {
  const uint32_t ne = uint32_t(m_vTet.size());
  const std::span<const uint32_t> ci = crack.indices();
  const std::span<const uint8_t> flags = crack.crackFlags();
  m_crackMap.assign(crack.vertexCount(), -1);
  m_crackFrom.clear();
  m_indices.assign(m_renderIndices.begin(), m_renderIndices.end());
  m_triCrack.assign(m_renderIndices.size() / 3, 0);
  for (size_t t = 0; t < flags.size(); ++t) {
    if (!flags[t]) continue;
    for (int c = 0; c < 3; ++c) {
      const uint32_t cv = ci[3 * t + size_t(c)];
      if (m_crackMap[cv] < 0) {
        m_crackMap[cv] = int32_t(ne + m_crackFrom.size());
        m_crackFrom.push_back(int32_t(cv));
      }
      m_indices.push_back(uint32_t(m_crackMap[cv]));
    }
    m_triCrack.push_back(1);
  }
  const size_t nv = ne + m_crackFrom.size();
  m_vertexNode.assign(m_vNode.begin(), m_vNode.end());
  m_vertexFragment.assign(m_vFragment.begin(), m_vFragment.end());
  for (int32_t cv : m_crackFrom) {
    m_vertexNode.push_back(crack.vertexNode()[size_t(cv)]);
    m_vertexFragment.push_back(crack.vertexFragment()[size_t(cv)]);
  }
  m_uv.clear();
  if (!m_binding->uv.empty()) {
    m_uv.assign(2 * nv, 0.0f);
    for (uint32_t v = 0; v < ne; ++v)
      for (int c = 0; c < 2; ++c)
        m_uv[2 * size_t(v) + size_t(c)] = m_binding->uv[2 * size_t(m_vSource[v]) + size_t(c)];
  }
  m_positions.resize(3 * nv);
  m_normals.resize(3 * nv);
  m_positionsF.resize(3 * nv);
  m_normalsF.resize(3 * nv);
  m_crackVersion = crack.topologyVersion();
  m_composed = true;
  ++m_topologyVersion;
}

void EmbeddedSurface::update(const double* x, const CrackSurface& crack, JobSystem* jobs) {
  if (!m_composed || crack.topologyVersion() != m_crackVersion) compose(crack);
  const CpuExecutor exec(jobs ? *jobs : serialJobs());
  const EmbeddedBinding& b = *m_binding;
  const int32_t ne = int32_t(m_vTet.size()), nc = int32_t(m_crackFrom.size());
  exec.run(ne, 256,
           EmbeddedVertexStage{x, m_rest->positions.data(), m_rest->tets.data(), m_restInverse,
                               m_vTet.data(), m_vWeight.data(), m_vGroup.data(), m_vSource.data(),
                               b.rest.data(), b.restNormal.data(), crack.nodeFrame().data(),
                               crack.frameMaps().data(), m_positions.data(), m_normals.data()});
  exec.run(nc, 512,
           GatherVec3Stage{crack.positionsDouble().data(), m_crackFrom.data(),
                           m_positions.data() + 3 * size_t(ne)});
  exec.run(nc, 512,
           GatherVec3Stage{crack.normalsDouble().data(), m_crackFrom.data(),
                           m_normals.data() + 3 * size_t(ne)});
  const int32_t n3 = int32_t(m_positions.size());
  exec.run(n3, 2048, ToFloatStage{m_positions.data(), m_positionsF.data()});
  exec.run(n3, 2048, ToFloatStage{m_normals.data(), m_normalsF.data()});
}

}  // namespace gf::detail
