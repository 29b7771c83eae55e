// Corner-cell render surface: topology from broken edges, positions every frame (see the
// design note in crack_surface.h).
#include "surface/crack_surface.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>

#include "kernels/math.h"
#include "kernels/svd3.h"
#include "mesh/mesh_internal.h"
#include "step/executor.h"
#include "surface/surface_stages.h"

namespace gf::detail {

namespace {

// Local edge index of local nodes (a, b), either order; -1 on the diagonal.
struct LocalEdgeTable {
  int8_t e[4][4];
};
constexpr LocalEdgeTable makeLocalEdgeTable() {
  LocalEdgeTable t{};
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b) t.e[a][b] = -1;
  for (int k = 0; k < 6; ++k) {
    t.e[kTetEdgeNodes[k][0]][kTetEdgeNodes[k][1]] = static_cast<int8_t>(k);
    t.e[kTetEdgeNodes[k][1]][kTetEdgeNodes[k][0]] = static_cast<int8_t>(k);
  }
  return t;
}
constexpr LocalEdgeTable kLocalEdge = makeLocalEdgeTable();

// Inner quad of local edge k = (i, j): the other two local nodes (p, q) ordered so that
// (i, p, q, j) is an even permutation of (0, 1, 2, 3). Then the quad (e_ij, f_ijp, c, f_ijq)
// faces node j in a positively oriented tet (design note).
struct CrackQuadTable {
  int8_t i[6], j[6], p[6], q[6];
};
constexpr CrackQuadTable makeCrackQuadTable() {
  CrackQuadTable t{};
  for (int k = 0; k < 6; ++k) {
    const int i = kTetEdgeNodes[k][0], j = kTetEdgeNodes[k][1];
    int other[2] = {0, 0}, c = 0;
    for (int v = 0; v < 4; ++v)
      if (v != i && v != j) other[c++] = v;
    const int perm[4] = {i, other[0], other[1], j};
    int inversions = 0;
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) inversions += perm[a] > perm[b] ? 1 : 0;
    if (inversions % 2 == 1) {
      const int s = other[0];
      other[0] = other[1];
      other[1] = s;
    }
    t.i[k] = static_cast<int8_t>(i);
    t.j[k] = static_cast<int8_t>(j);
    t.p[k] = static_cast<int8_t>(other[0]);
    t.q[k] = static_cast<int8_t>(other[1]);
  }
  return t;
}
constexpr CrackQuadTable kCrackQuad = makeCrackQuadTable();

// For each mask of joined local edges: the group (bit mask of local nodes) of each local node,
// i.e. its connected component in K4 restricted to the joined edges.
struct GroupTable {
  uint8_t g[64][4];
};
constexpr GroupTable makeGroupTable() {
  GroupTable t{};
  for (int m = 0; m < 64; ++m)
    for (int v = 0; v < 4; ++v) {
      int group = 1 << v;
      for (int pass = 0; pass < 3; ++pass)
        for (int k = 0; k < 6; ++k) {
          const int a = kTetEdgeNodes[k][0], b = kTetEdgeNodes[k][1];
          if ((m >> k & 1) && (group & ((1 << a) | (1 << b)))) group |= (1 << a) | (1 << b);
        }
      t.g[m][v] = static_cast<uint8_t>(group);
    }
  return t;
}
constexpr GroupTable kGroup = makeGroupTable();

inline int lowestBit(unsigned m) {
  int i = 0;
  while (!(m >> i & 1u)) ++i;
  return i;
}

inline Vec3 load(const double* p, int32_t i) {
  const size_t k = 3 * static_cast<size_t>(i);
  return {p[k], p[k + 1], p[k + 2]};
}

}  // namespace

void CrackSurface::init(const TetMesh& rest, const EdgeGraph& graph,
                        const CrackSurfaceOptions& options) {
  m_rest = &rest;
  m_graph = &graph;
  m_options = options;
  const size_t nt = rest.tetCount();

  // Unique faces: sorted (tet, local face) records, equal keys adjacent.
  const std::vector<FaceRecord> faces = sortedFaces(rest);
  m_tetFace.assign(4 * nt, -1);
  m_faceNodes.clear();
  m_faceEdges.clear();
  m_faceBoundary.clear();
  m_tetHasBoundary.assign(nt, 0);
  int32_t fid = 0;
  for (size_t i = 0; i < faces.size();) {
    size_t j = i + 1;
    while (j < faces.size() && std::equal(faces[j].key, faces[j].key + 3, faces[i].key)) ++j;
    const int32_t* k = faces[i].key;
    m_faceNodes.insert(m_faceNodes.end(), k, k + 3);
    m_faceEdges.push_back(graph.find(k[0], k[1]));
    m_faceEdges.push_back(graph.find(k[0], k[2]));
    m_faceEdges.push_back(graph.find(k[1], k[2]));
    const bool boundary = j - i == 1;
    m_faceBoundary.push_back(boundary ? 1 : 0);
    for (size_t r = i; r < j; ++r) {
      m_tetFace[4 * static_cast<size_t>(faces[r].tet) + static_cast<size_t>(faces[r].local)] = fid;
      if (boundary) m_tetHasBoundary[static_cast<size_t>(faces[r].tet)] = 1;
    }
    ++fid;
    i = j;
  }
  m_faceCount = fid;

  const size_t slots = rest.nodeCount() + 2 * static_cast<size_t>(graph.edgeCount) +
                       3 * static_cast<size_t>(m_faceCount) + 4 * nt;
  m_slotVertex.assign(slots, -1);
  m_usedSlots.clear();
  m_nodeFrame.assign(rest.nodeCount(), -1);
  m_frameNode.clear();
  m_ratio.clear();
}

void CrackSurface::setSplitRatios(const double* ratio) {
  if (!ratio) {
    m_ratio.clear();
    return;
  }
  m_ratio.assign(ratio, ratio + m_graph->edgeCount);
  for (double& t : m_ratio) t = clampSplitRatio(t);
}

double CrackSurface::splitRatio(int32_t edge) const {
  return m_ratio.empty() ? 0.5 : m_ratio[static_cast<size_t>(edge)];
}

void CrackSurface::rebuild(const uint8_t* broken, const int32_t* nodeFragment, const double* x,
                           JobSystem* jobs) {
  const TetMesh& mesh = *m_rest;
  const EdgeGraph& g = *m_graph;
  const double* X = mesh.positions.data();
  const size_t nn = mesh.nodeCount(), ne = static_cast<size_t>(g.edgeCount);
  const size_t edgeBase = nn, faceBase = nn + 2 * ne;
  const size_t tetBase = faceBase + 3 * static_cast<size_t>(m_faceCount);

  for (int32_t s : m_usedSlots) m_slotVertex[static_cast<size_t>(s)] = -1;
  m_usedSlots.clear();
  for (int32_t a : m_frameNode) m_nodeFrame[static_cast<size_t>(a)] = -1;
  m_frameNode.clear();
  m_vParent.clear();
  m_vWeight.clear();
  m_vGroup.clear();
  m_vRest.clear();
  m_vertexNode.clear();
  m_vertexFragment.clear();
  m_indices.clear();
  m_triCrack.clear();
  m_triNode.clear();

  const bool partial = m_options.renderPartialCracks;
  auto joined = [&](int32_t e) {
    if (partial) return broken[e] == 0;
    return nodeFragment[g.edgeNodes[2 * static_cast<size_t>(e)]] ==
           nodeFragment[g.edgeNodes[2 * static_cast<size_t>(e) + 1]];
  };

  // The vertex of `slot`, created on first use from up to 4 parents, their rest weights and
  // the group mask (which parents the vertex follows).
  auto vertex = [&](size_t slot, const int32_t* parents, const double* weights, int count,
                    unsigned group) -> uint32_t {
    const int32_t existing = m_slotVertex[slot];
    if (existing >= 0) return static_cast<uint32_t>(existing);
    const int32_t id = static_cast<int32_t>(m_vertexNode.size());
    m_slotVertex[slot] = id;
    m_usedSlots.push_back(static_cast<int32_t>(slot));
    Vec3 p{};
    int32_t lowest = -1;
    for (int k = 0; k < 4; ++k) {
      const bool used = k < count;
      m_vParent.push_back(used ? parents[k] : -1);
      m_vWeight.push_back(used ? weights[k] : 0.0);
      if (!used) continue;
      p += weights[k] * load(X, parents[k]);
      if ((group >> k & 1u) && (lowest < 0 || parents[k] < lowest)) lowest = parents[k];
    }
    m_vGroup.push_back(static_cast<uint8_t>(group));
    m_vRest.insert(m_vRest.end(), {p.x, p.y, p.z});
    m_vertexNode.push_back(lowest);
    m_vertexFragment.push_back(nodeFragment[lowest]);
    // A vertex that follows only some parents needs their rotations (design note: Motion).
    if (group != (1u << count) - 1) {
      for (int k = 0; k < count; ++k) {
        const int32_t a = parents[k];
        if ((group >> k & 1u) && m_nodeFrame[static_cast<size_t>(a)] < 0) {
          m_nodeFrame[static_cast<size_t>(a)] = static_cast<int32_t>(m_frameNode.size());
          m_frameNode.push_back(a);
        }
      }
    }
    return static_cast<uint32_t>(id);
  };

  auto nodeVertex = [&](int32_t a) {
    const double w = 1.0;
    return vertex(static_cast<size_t>(a), &a, &w, 1, 1u);
  };
  auto edgeVertex = [&](int32_t e, int32_t a) {
    const int32_t* ends = &g.edgeNodes[2 * static_cast<size_t>(e)];
    const double t = splitRatio(e);
    const double w[2] = {1 - t, t};
    const unsigned side = a == ends[0] ? 0u : 1u;
    const unsigned group = joined(e) ? 3u : 1u << side;
    const size_t slot =
        edgeBase + 2 * static_cast<size_t>(e) + static_cast<size_t>(lowestBit(group));
    return vertex(slot, ends, w, 2, group);
  };
  auto faceVertex = [&](int32_t f, int32_t a) {
    const int32_t* k = &m_faceNodes[3 * static_cast<size_t>(f)];
    const int32_t* fe = &m_faceEdges[3 * static_cast<size_t>(f)];
    const double w[3] = {1.0 / 3, 1.0 / 3, 1.0 / 3};
    static constexpr unsigned kPair[3] = {3u, 5u, 6u};  // (0 1), (0 2), (1 2)
    const bool j[3] = {joined(fe[0]), joined(fe[1]), joined(fe[2])};
    unsigned group = a == k[0] ? 1u : (a == k[1] ? 2u : 4u);
    for (int pass = 0; pass < 2; ++pass)
      for (int q = 0; q < 3; ++q)
        if (j[q] && (group & kPair[q])) group |= kPair[q];
    const size_t slot =
        faceBase + 3 * static_cast<size_t>(f) + static_cast<size_t>(lowestBit(group));
    return vertex(slot, k, w, 3, group);
  };

  const size_t nt = mesh.tetCount();
  for (size_t t = 0; t < nt; ++t) {
    const int32_t* n = &mesh.tets[4 * t];
    const int32_t* te = &g.tetEdges[6 * t];
    unsigned jmask = 0;
    for (int k = 0; k < 6; ++k) jmask |= joined(te[k]) ? 1u << k : 0u;
    if (jmask == 63u && !m_tetHasBoundary[t]) continue;

    auto tetVertex = [&](int i) {
      const double w[4] = {0.25, 0.25, 0.25, 0.25};
      const unsigned group = kGroup.g[jmask][i];
      return vertex(tetBase + 4 * t + static_cast<size_t>(lowestBit(group)), n, w, 4, group);
    };
    // Quad (v0 v1 v2 v3) as triangles (v0 v1 v2), (v0 v2 v3): the diagonal leaves v0.
    auto quad = [&](uint32_t v0, uint32_t v1, uint32_t v2, uint32_t v3, uint8_t crack,
                    int32_t corner) {
      m_indices.insert(m_indices.end(), {v0, v1, v2, v0, v2, v3});
      m_triCrack.insert(m_triCrack.end(), {crack, crack});
      m_triNode.insert(m_triNode.end(), {corner, corner});
    };

    // Crack faces: both copies of the inner quad of every unjoined edge, diagonal from e_ij.
    for (int k = 0; k < 6; ++k) {
      if (jmask >> k & 1u) continue;
      const int i = kCrackQuad.i[k], j = kCrackQuad.j[k];
      const int p = kCrackQuad.p[k], q = kCrackQuad.q[k];
      // Face (i j p) is the one opposite q, and the other way round.
      const int32_t fp = m_tetFace[4 * t + static_cast<size_t>(q)];
      const int32_t fq = m_tetFace[4 * t + static_cast<size_t>(p)];
      // Vertices are created in a fixed order (not inside one call's argument list, whose
      // evaluation order is unspecified), so numbering is the same with every compiler.
      for (int side = 0; side < 2; ++side) {
        const int c = side == 0 ? i : j;
        const int32_t f1 = side == 0 ? fp : fq, f2 = side == 0 ? fq : fp;
        const uint32_t v0 = edgeVertex(te[k], n[c]);
        const uint32_t v1 = faceVertex(f1, n[c]);
        const uint32_t v2 = tetVertex(c);
        const uint32_t v3 = faceVertex(f2, n[c]);
        quad(v0, v1, v2, v3, 1, n[c]);
      }
    }

    // Boundary faces: the three outer quads, oriented like the outward face, diagonal from the
    // corner node.
    if (!m_tetHasBoundary[t]) continue;
    for (int l = 0; l < 4; ++l) {
      const int32_t f = m_tetFace[4 * t + static_cast<size_t>(l)];
      if (!m_faceBoundary[static_cast<size_t>(f)]) continue;
      const int* c = kTetFaces[l];
      for (int s = 0; s < 3; ++s) {
        const int a = c[s], b = c[(s + 1) % 3], d = c[(s + 2) % 3];
        const uint32_t v0 = nodeVertex(n[a]);
        const uint32_t v1 = edgeVertex(te[kLocalEdge.e[a][b]], n[a]);
        const uint32_t v2 = faceVertex(f, n[a]);
        const uint32_t v3 = edgeVertex(te[kLocalEdge.e[a][d]], n[a]);
        quad(v0, v1, v2, v3, 0, n[a]);
      }
    }
  }

  for (int32_t a : m_extraFrameNodes) {
    if (m_nodeFrame[static_cast<size_t>(a)] >= 0) continue;
    m_nodeFrame[static_cast<size_t>(a)] = static_cast<int32_t>(m_frameNode.size());
    m_frameNode.push_back(a);
  }

  // Neighbourhoods of the nodes that need a frame: the unbroken 1-ring, grown level by level
  // (over unbroken edges, so within the node's fragment) until it spans a volume, since a
  // flat or collinear set of neighbours cannot tell the affine map (or, if collinear, the twist
  // about the line). Capped at about kMaxRing nodes.
  constexpr size_t kMaxRing = 64;
  m_frameRingStart.assign(1, 0);
  m_frameRing.clear();
  m_frameAffine.clear();
  m_frameCinv.clear();
  m_visit.resize(nn, 0);
  for (int32_t a : m_frameNode) {
    if (++m_visitStamp == 0) {
      std::fill(m_visit.begin(), m_visit.end(), 0u);
      m_visitStamp = 1;
    }
    m_visit[static_cast<size_t>(a)] = m_visitStamp;
    const Vec3 Xa = load(X, a);
    Vec3 d1{}, plane{};
    bool spread2 = false, spread3 = false;
    m_bfs.assign(1, a);
    size_t levelBegin = 0, levelEnd = 1;
    while (levelBegin < levelEnd) {
      for (size_t i = levelBegin; i < levelEnd; ++i) {
        const int32_t u = m_bfs[i];
        for (int32_t s = g.nodeEdgeStart[static_cast<size_t>(u)];
             s < g.nodeEdgeStart[static_cast<size_t>(u) + 1]; ++s) {
          const int32_t e = g.nodeEdges[static_cast<size_t>(s)];
          if (broken[e]) continue;
          const int32_t* ends = &g.edgeNodes[2 * static_cast<size_t>(e)];
          const int32_t w = ends[0] == u ? ends[1] : ends[0];
          if (m_visit[static_cast<size_t>(w)] == m_visitStamp) continue;
          m_visit[static_cast<size_t>(w)] = m_visitStamp;
          m_bfs.push_back(w);
          m_frameRing.push_back(w);
          // Track whether the rest neighbourhood spans a plane, then a volume.
          const Vec3 dX = load(X, w) - Xa;
          if (dot(d1, d1) == 0) {
            d1 = dX;
          } else if (!spread2) {
            const Vec3 c = cross(d1, dX);
            if (norm(c) > 1e-6 * norm(d1) * norm(dX)) {
              spread2 = true;
              plane = c;
            }
          } else if (std::fabs(dot(plane, dX)) > 1e-6 * norm(plane) * norm(dX)) {
            spread3 = true;
          }
        }
      }
      if (spread3 || m_bfs.size() > kMaxRing) break;
      levelBegin = levelEnd;
      levelEnd = m_bfs.size();
    }
    m_frameRingStart.push_back(static_cast<int32_t>(m_frameRing.size()));

    // Inverse rest covariance for the affine fit, kept only when the neighbourhood is well
    // spread in 3D (det against the cube of the mean eigenvalue; 1 for an isotropic ring).
    Mat3 C;
    for (size_t r = m_frameRing.size() - (m_bfs.size() - 1); r < m_frameRing.size(); ++r) {
      const Vec3 dX = load(X, m_frameRing[r]) - Xa;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) C(i, j) += dX[i] * dX[j];
    }
    const double meanEig = trace(C) / 3;
    const bool affine = spread3 && det(C) > 1e-3 * meanEig * meanEig * meanEig;
    const Mat3 Cinv = affine ? inverse(C) : Mat3{};
    m_frameAffine.push_back(affine ? 1 : 0);
    m_frameCinv.insert(m_frameCinv.end(), Cinv.m, Cinv.m + 9);
  }
  m_frameR.resize(9 * m_frameNode.size());

  // Each vertex's triangles, by increasing index: the normals' fixed summation order.
  const size_t nv = m_vertexNode.size();
  m_vertexTriStart.assign(nv + 1, 0);
  for (uint32_t v : m_indices) ++m_vertexTriStart[v + 1];
  for (size_t v = 0; v < nv; ++v) m_vertexTriStart[v + 1] += m_vertexTriStart[v];
  m_vertexTri.resize(m_indices.size());
  std::vector<int32_t> fill(m_vertexTriStart.begin(), m_vertexTriStart.end() - 1);
  for (size_t k = 0; k < m_indices.size(); ++k)
    m_vertexTri[size_t(fill[m_indices[k]]++)] = int32_t(k / 3);

  ++m_topologyVersion;
  m_positionsF.clear();  // new vertices: every one of them is dirty
  updatePositions(x, jobs);
}

void CrackSurface::updatePositions(const double* x, JobSystem* jobs) {
  const double* X = m_rest->positions.data();
  if (!x) x = X;
  const CpuExecutor exec(jobs ? *jobs : serialJobs());
  exec.run(int32_t(m_frameNode.size()), 64,
           SurfaceFrameStage{x, X, m_frameNode.data(), m_frameRingStart.data(), m_frameRing.data(),
                             m_frameAffine.data(), m_frameCinv.data(), m_frameR.data()});
  const int32_t nv = int32_t(m_vertexNode.size());
  m_positions.resize(3 * size_t(nv));
  m_normals.resize(3 * size_t(nv));
  exec.run(
      nv, 512,
      SurfaceVertexStage{x, X, m_vParent.data(), m_vWeight.data(), m_vGroup.data(), m_vRest.data(),
                         m_nodeFrame.data(), m_frameR.data(), m_positions.data()});
  exec.run(nv, 512,
           SurfaceNormalStage{m_positions.data(), m_indices.data(), m_vertexTriStart.data(),
                              m_vertexTri.data(), m_normals.data()});

  // The dirty range grows by the vertices whose float position or normal (what a renderer
  // uploads) changed; vertices that kept both stay out of it.
  const bool sameLayout =
      m_positionsF.size() == 3 * size_t(nv) && m_normalsF.size() == 3 * size_t(nv);
  uint32_t lo = uint32_t(nv), hi = 0;
  if (!sameLayout) {
    lo = 0;
    hi = uint32_t(nv);
    m_positionsF.resize(3 * size_t(nv));
    m_normalsF.resize(3 * size_t(nv));
  } else if (nv > 0) {
    ChangedVertexTerm changed{m_positions.data(), m_normals.data(), m_positionsF.data(),
                              m_normalsF.data(), false};
    const double first = exec.reduce<MinOp>(nv, changed);
    changed.last = true;
    const double end = exec.reduce<MaxOp>(nv, changed);
    if (first < end) {
      lo = uint32_t(first);
      hi = uint32_t(end);
    }
  }
  exec.run(3 * nv, 2048, ToFloatStage{m_positions.data(), m_positionsF.data()});
  exec.run(3 * nv, 2048, ToFloatStage{m_normals.data(), m_normalsF.data()});
  ++m_positionVersion;
  if (lo < hi) {
    m_dirty = m_dirty.begin < m_dirty.end
                  ? DirtyRange{std::min(m_dirty.begin, lo), std::max(m_dirty.end, hi)}
                  : DirtyRange{lo, hi};
  }
}

std::vector<double> CrackSurface::cellRestVolumes() const {
  const TetMesh& mesh = *m_rest;
  const EdgeGraph& g = *m_graph;
  const double* X = mesh.positions.data();
  std::vector<double> out(mesh.nodeCount(), 0.0);
  for (size_t t = 0; t < mesh.tetCount(); ++t) {
    const int32_t* n = &mesh.tets[4 * t];
    const int32_t* te = &g.tetEdges[6 * t];
    Vec3 P[4], c{};
    for (int k = 0; k < 4; ++k) {
      P[k] = load(X, n[k]);
      c += 0.25 * P[k];
    }
    auto edgePoint = [&](int a, int b) {
      const int32_t e = te[kLocalEdge.e[a][b]];
      const double r = splitRatio(e);
      const bool aLow = g.edgeNodes[2 * static_cast<size_t>(e)] == n[a];
      const Vec3 lo = aLow ? P[a] : P[b], hi = aLow ? P[b] : P[a];
      return (1 - r) * lo + r * hi;
    };
    // Cone from the tet centroid over each cell's outer quads; the inner quads contain the
    // centroid and add nothing.
    for (int l = 0; l < 4; ++l) {
      const int* f = kTetFaces[l];
      const Vec3 fc = (1.0 / 3) * (P[f[0]] + P[f[1]] + P[f[2]]);
      for (int s = 0; s < 3; ++s) {
        const int a = f[s], b = f[(s + 1) % 3], d = f[(s + 2) % 3];
        const Vec3 eab = edgePoint(a, b), ead = edgePoint(a, d);
        const double v =
            (dot(P[a] - c, cross(eab - c, fc - c)) + dot(P[a] - c, cross(fc - c, ead - c))) / 6.0;
        out[static_cast<size_t>(n[a])] += v;
      }
    }
  }
  return out;
}

Result<void> CrackSurface::write(const std::string& path) const {
  const std::string ext = lowerExtension(path);
  if (ext != ".obj" && ext != ".ply") {
    return fail(path, ": unknown surface format '", ext, "' (expected .obj or .ply)");
  }
  std::ofstream out(path, std::ios::binary);
  if (!out) return fail(path, ": cannot open for writing");
  const size_t nv = m_vertexNode.size(), ntri = m_triCrack.size();
  std::string s;
  char buf[32];
  auto num = [&](double v) {
    const auto r = std::to_chars(buf, buf + sizeof buf, static_cast<float>(v));
    s.append(buf, r.ptr);
  };
  const bool obj = ext == ".obj";
  if (obj) {
    s += "# crack surface: " + std::to_string(nv) + " vertices, " + std::to_string(ntri) +
         " triangles\n";
  } else {
    s += "ply\nformat ascii 1.0\nelement vertex " + std::to_string(nv) +
         "\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\n"
         "property float ny\nproperty float nz\nelement face " +
         std::to_string(ntri) +
         "\nproperty list uchar int vertex_indices\nproperty uchar crack\nend_header\n";
  }
  for (size_t v = 0; v < nv; ++v) {
    if (obj) s += "v";
    for (int k = 0; k < 3; ++k) {
      if (obj || k > 0) s += ' ';
      num(m_positions[3 * v + static_cast<size_t>(k)]);
    }
    if (obj) s += "\nvn";
    for (int k = 0; k < 3; ++k) {
      s += ' ';
      num(m_normals[3 * v + static_cast<size_t>(k)]);
    }
    s += '\n';
  }
  if (obj) {
    // Boundary faces first, then the crack faces in their own group.
    for (int crack = 0; crack < 2; ++crack) {
      s += crack ? "g crack\n" : "g surface\n";
      for (size_t tri = 0; tri < ntri; ++tri) {
        if (m_triCrack[tri] != crack) continue;
        s += "f";
        for (int k = 0; k < 3; ++k) {
          const std::string idx = std::to_string(m_indices[3 * tri + static_cast<size_t>(k)] + 1);
          s += ' ' + idx + "//" + idx;
        }
        s += '\n';
      }
    }
  } else {
    for (size_t tri = 0; tri < ntri; ++tri) {
      s += "3";
      for (int k = 0; k < 3; ++k)
        s += ' ' + std::to_string(m_indices[3 * tri + static_cast<size_t>(k)]);
      s += m_triCrack[tri] ? " 1\n" : " 0\n";
    }
  }
  out << s;
  out.flush();
  if (!out) return fail(path, ": write failed");
  return {};
}

}  // namespace gf::detail
