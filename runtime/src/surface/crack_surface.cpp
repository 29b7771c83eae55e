// Corner-cell render surface: topology from broken edges, positions every frame (see the
// design note in crack_surface.h).
#include "surface/crack_surface.h"

#include <algorithm>
#include <atomic>
#include <bit>
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

// Tets per chunk and frames per chunk of rebuild(); fixed, so nothing depends on the threads.
constexpr size_t kTetChunk = 512;
constexpr size_t kFrameChunk = 64;
constexpr uint32_t kVertexBlock = 2048;  // vertices per block of buildVertexTriangles()
constexpr int32_t kNoChunk = INT32_MAX;
constexpr int64_t kNoKey = INT64_MAX;

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
  m_slotChunk.assign(slots, kNoChunk);
  m_chunks.assign((nt + kTetChunk - 1) / kTetChunk, TetChunk{});
  m_edgeJoined.clear();
  m_nodeKey.assign(rest.nodeCount(), kNoKey);
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
  const size_t nn = mesh.nodeCount();
  const size_t edgeBase = nn, faceBase = nn + 2 * static_cast<size_t>(g.edgeCount);
  const size_t tetBase = faceBase + 3 * static_cast<size_t>(m_faceCount);
  const size_t nt = mesh.tetCount();
  JobSystem& js = jobs ? *jobs : serialJobs();
  const uint32_t chunks = static_cast<uint32_t>(m_chunks.size());
  auto eachChunk = [&](const auto& f) {
    js.parallelFor(chunks, 1, [&](uint32_t b, uint32_t e) {
      for (uint32_t c = b; c < e; ++c) f(static_cast<int32_t>(c), m_chunks[c]);
    });
  };

  for (int32_t a : m_frameNode) {
    m_nodeFrame[static_cast<size_t>(a)] = -1;
    m_nodeKey[static_cast<size_t>(a)] = kNoKey;
  }
  m_frameNode.clear();

  // A chunk's quads depend only on which of its tets' edges are joined, so only the chunks with
  // an edge that changed since the last rebuild list them again.
  const bool partial = m_options.renderPartialCracks;
  const bool first = m_edgeJoined.empty();
  if (first) m_edgeJoined.assign(static_cast<size_t>(g.edgeCount), 0);
  for (int32_t e = 0; e < g.edgeCount; ++e) {
    const size_t es = static_cast<size_t>(e);
    const uint8_t j =
        partial ? broken[e] == 0
                : nodeFragment[g.edgeNodes[2 * es]] == nodeFragment[g.edgeNodes[2 * es + 1]];
    if (!first && j == m_edgeJoined[es]) continue;
    m_edgeJoined[es] = j;
    for (int32_t k = g.edgeTetStart[es]; k < g.edgeTetStart[es + 1]; ++k)
      m_chunks[static_cast<size_t>(g.edgeTets[static_cast<size_t>(k)] / 6) / kTetChunk].stale = 1;
  }
  auto joined = [&](int32_t e) { return m_edgeJoined[static_cast<size_t>(e)] != 0; };
  // A surface that lends none of its faces (setDrawnFragments) needs only the other vertices'
  // local maps (setExtraFrameNodes): a map depends on its node's neighbourhood alone.
  const bool mapsOnly = m_drawnOnly && std::none_of(m_drawnFragment.begin(), m_drawnFragment.end(),
                                                    [](uint8_t d) { return d != 0; });
  auto addExtraFrames = [&] {
    for (int32_t a : m_extraFrameNodes) {
      if (m_nodeFrame[static_cast<size_t>(a)] >= 0) continue;
      m_nodeFrame[static_cast<size_t>(a)] = static_cast<int32_t>(m_frameNode.size());
      m_frameNode.push_back(a);
    }
  };

  // Each chunk's quads as vertex slots, after freeing the slots its vertices took last time.
  eachChunk([&](int32_t c, TetChunk& ch) {
    for (int32_t r : ch.owned) {
      const size_t s = static_cast<size_t>(ch.slot[static_cast<size_t>(r)]);
      m_slotVertex[s] = -1;
      m_slotChunk[s] = kNoChunk;
    }
    if (mapsOnly) ch.owned.clear();
    if (!ch.stale || mapsOnly) return;
    ch.stale = 0;
    ch.slot.clear();
    ch.group.clear();
    ch.crack.clear();
    ch.corner.clear();
    auto use = [&](size_t slot, unsigned group) {
      ch.slot.push_back(static_cast<int32_t>(slot));
      ch.group.push_back(static_cast<uint8_t>(group));
    };
    auto edgeVertex = [&](int32_t e, int32_t a) {
      const unsigned side = a == g.edgeNodes[2 * static_cast<size_t>(e)] ? 0u : 1u;
      const unsigned group = joined(e) ? 3u : 1u << side;
      use(edgeBase + 2 * static_cast<size_t>(e) + static_cast<size_t>(lowestBit(group)), group);
    };
    auto faceVertex = [&](int32_t f, int32_t a) {
      const int32_t* k = &m_faceNodes[3 * static_cast<size_t>(f)];
      const int32_t* fe = &m_faceEdges[3 * static_cast<size_t>(f)];
      static constexpr unsigned kPair[3] = {3u, 5u, 6u};  // (0 1), (0 2), (1 2)
      const bool j[3] = {joined(fe[0]), joined(fe[1]), joined(fe[2])};
      unsigned group = a == k[0] ? 1u : (a == k[1] ? 2u : 4u);
      for (int pass = 0; pass < 2; ++pass)
        for (int q = 0; q < 3; ++q)
          if (j[q] && (group & kPair[q])) group |= kPair[q];
      use(faceBase + 3 * static_cast<size_t>(f) + static_cast<size_t>(lowestBit(group)), group);
    };
    const size_t tEnd = std::min(nt, (static_cast<size_t>(c) + 1) * kTetChunk);
    for (size_t t = static_cast<size_t>(c) * kTetChunk; t < tEnd; ++t) {
      const int32_t* n = &mesh.tets[4 * t];
      const int32_t* te = &g.tetEdges[6 * t];
      unsigned jmask = 0;
      for (int k = 0; k < 6; ++k) jmask |= joined(te[k]) ? 1u << k : 0u;
      if (jmask == 63u && !m_tetHasBoundary[t]) continue;
      auto tetVertex = [&](int i) {
        const unsigned group = kGroup.g[jmask][i];
        use(tetBase + 4 * t + static_cast<size_t>(lowestBit(group)), group);
      };

      // Crack faces: both copies of the inner quad of every unjoined edge, diagonal from e_ij.
      for (int k = 0; k < 6; ++k) {
        if (jmask >> k & 1u) continue;
        const int i = kCrackQuad.i[k], j = kCrackQuad.j[k];
        const int p = kCrackQuad.p[k], q = kCrackQuad.q[k];
        // Face (i j p) is the one opposite q, and the other way round.
        const int32_t fp = m_tetFace[4 * t + static_cast<size_t>(q)];
        const int32_t fq = m_tetFace[4 * t + static_cast<size_t>(p)];
        for (int side = 0; side < 2; ++side) {
          const int cn = side == 0 ? i : j;
          edgeVertex(te[k], n[cn]);
          faceVertex(side == 0 ? fp : fq, n[cn]);
          tetVertex(cn);
          faceVertex(side == 0 ? fq : fp, n[cn]);
          ch.crack.push_back(1);
          ch.corner.push_back(n[cn]);
        }
      }

      // Boundary faces: the three outer quads, oriented like the outward face, diagonal from
      // the corner node.
      if (!m_tetHasBoundary[t]) continue;
      for (int l = 0; l < 4; ++l) {
        const int32_t f = m_tetFace[4 * t + static_cast<size_t>(l)];
        if (!m_faceBoundary[static_cast<size_t>(f)]) continue;
        const int* fl = kTetFaces[l];
        for (int s = 0; s < 3; ++s) {
          const int a = fl[s], b = fl[(s + 1) % 3], d = fl[(s + 2) % 3];
          use(static_cast<size_t>(n[a]), 1u);
          edgeVertex(te[kLocalEdge.e[a][b]], n[a]);
          faceVertex(f, n[a]);
          edgeVertex(te[kLocalEdge.e[a][d]], n[a]);
          ch.crack.push_back(0);
          ch.corner.push_back(n[a]);
        }
      }
    }
  });
  if (mapsOnly) {
    m_vertexNode.clear();
    m_vertexFragment.clear();
    m_indices.clear();
    m_triCrack.clear();
    m_triNode.clear();
    m_drawnVertices.clear();
    m_drawnTriangles.clear();
    addExtraFrames();
    buildFrames(broken, js);
    ++m_topologyVersion;
    m_positionsF.clear();
    updatePositions(x, jobs);
    return;
  }
  // A slot's vertex belongs to the first chunk that uses it (the least chunk whatever the
  // order the chunks ran in)...
  eachChunk([&](int32_t c, TetChunk& ch) {
    for (int32_t s : ch.slot) {
      std::atomic_ref<int32_t> first(m_slotChunk[static_cast<size_t>(s)]);
      int32_t seen = first.load(std::memory_order_relaxed);
      while (c < seen && !first.compare_exchange_weak(seen, c, std::memory_order_relaxed)) {
      }
    }
  });
  // ... which numbers its vertices by first use; only the owner touches a slot's vertex.
  eachChunk([&](int32_t c, TetChunk& ch) {
    ch.owned.clear();
    for (size_t r = 0; r < ch.slot.size(); ++r) {
      const size_t s = static_cast<size_t>(ch.slot[r]);
      if (m_slotChunk[s] != c || m_slotVertex[s] >= 0) continue;
      m_slotVertex[s] = static_cast<int32_t>(ch.owned.size());
      ch.owned.push_back(static_cast<int32_t>(r));
    }
  });
  int32_t nv = 0, nq = 0;
  for (TetChunk& ch : m_chunks) {
    ch.vertexBase = nv;
    ch.quadBase = nq;
    nv += static_cast<int32_t>(ch.owned.size());
    nq += static_cast<int32_t>(ch.crack.size());
  }
  const size_t nvs = static_cast<size_t>(nv), nqs = static_cast<size_t>(nq);
  m_vParent.resize(4 * nvs);
  m_vWeight.resize(4 * nvs);
  m_vGroup.resize(nvs);
  m_vRest.resize(3 * nvs);
  m_vertexNode.resize(nvs);
  m_vertexFragment.resize(nvs);
  m_indices.resize(6 * nqs);
  m_triCrack.resize(2 * nqs);
  m_triNode.resize(2 * nqs);

  // The vertices: up to 4 parents, their rest weights and the group mask (which parents the
  // vertex follows).
  eachChunk([&](int32_t, TetChunk& ch) {
    ch.framing.clear();
    for (size_t i = 0; i < ch.owned.size(); ++i) {
      const size_t r = static_cast<size_t>(ch.owned[i]);
      const size_t slot = static_cast<size_t>(ch.slot[r]);
      const unsigned group = ch.group[r];
      const int32_t id = ch.vertexBase + static_cast<int32_t>(i);
      m_slotVertex[slot] = id;
      int32_t parents[4] = {-1, -1, -1, -1};
      double weights[4] = {0, 0, 0, 0};
      int count = 0;
      if (slot < edgeBase) {
        parents[0] = static_cast<int32_t>(slot);
        weights[0] = 1;
        count = 1;
      } else if (slot < faceBase) {
        const int32_t e = static_cast<int32_t>((slot - edgeBase) / 2);
        const double t = splitRatio(e);
        parents[0] = g.edgeNodes[2 * static_cast<size_t>(e)];
        parents[1] = g.edgeNodes[2 * static_cast<size_t>(e) + 1];
        weights[0] = 1 - t;
        weights[1] = t;
        count = 2;
      } else if (slot < tetBase) {
        const size_t f = (slot - faceBase) / 3;
        for (int k = 0; k < 3; ++k) {
          parents[k] = m_faceNodes[3 * f + static_cast<size_t>(k)];
          weights[k] = 1.0 / 3;
        }
        count = 3;
      } else {
        const size_t t = (slot - tetBase) / 4;
        for (int k = 0; k < 4; ++k) {
          parents[k] = mesh.tets[4 * t + static_cast<size_t>(k)];
          weights[k] = 0.25;
        }
        count = 4;
      }
      const size_t v = static_cast<size_t>(id);
      Vec3 p{};
      int32_t lowest = -1;
      for (int k = 0; k < 4; ++k) {
        m_vParent[4 * v + static_cast<size_t>(k)] = parents[k];
        m_vWeight[4 * v + static_cast<size_t>(k)] = weights[k];
        if (k >= count) continue;
        p += weights[k] * load(X, parents[k]);
        if ((group >> k & 1u) && (lowest < 0 || parents[k] < lowest)) lowest = parents[k];
      }
      m_vGroup[v] = static_cast<uint8_t>(group);
      m_vRest[3 * v] = p.x;
      m_vRest[3 * v + 1] = p.y;
      m_vRest[3 * v + 2] = p.z;
      m_vertexNode[v] = lowest;
      m_vertexFragment[v] = nodeFragment[lowest];
      // A vertex that follows only some parents needs their rotations (design note: Motion);
      // a node's map is numbered by the first (vertex, parent) that needs it.
      if (group == (1u << count) - 1) continue;
      for (int k = 0; k < count; ++k) {
        if (!(group >> k & 1u)) continue;
        const int64_t key = 4 * int64_t(id) + k;
        std::atomic_ref<int64_t> first(m_nodeKey[static_cast<size_t>(parents[k])]);
        int64_t seen = first.load(std::memory_order_relaxed);
        while (key < seen && !first.compare_exchange_weak(seen, key, std::memory_order_relaxed)) {
        }
        ch.framing.insert(ch.framing.end(), {int64_t(parents[k]), key});
      }
    }
  });
  // Quad (v0 v1 v2 v3) as triangles (v0 v1 v2), (v0 v2 v3): the diagonal leaves v0.
  eachChunk([&](int32_t, TetChunk& ch) {
    for (size_t q = 0; q < ch.crack.size(); ++q) {
      uint32_t v[4];
      for (int k = 0; k < 4; ++k)
        v[k] = static_cast<uint32_t>(m_slotVertex[static_cast<size_t>(ch.slot[4 * q + k])]);
      const size_t o = static_cast<size_t>(ch.quadBase) + q;
      const uint32_t tri[6] = {v[0], v[1], v[2], v[0], v[2], v[3]};
      std::copy(tri, tri + 6, &m_indices[6 * o]);
      m_triCrack[2 * o] = m_triCrack[2 * o + 1] = ch.crack[q];
      m_triNode[2 * o] = m_triNode[2 * o + 1] = ch.corner[q];
    }
  });
  for (const TetChunk& ch : m_chunks)
    for (size_t i = 0; i < ch.framing.size(); i += 2) {
      const size_t a = static_cast<size_t>(ch.framing[i]);
      if (m_nodeKey[a] != ch.framing[i + 1]) continue;
      m_nodeFrame[a] = static_cast<int32_t>(m_frameNode.size());
      m_frameNode.push_back(static_cast<int32_t>(a));
    }
  addExtraFrames();

  buildFrames(broken, js);
  if (m_drawnOnly) {
    auto drawn = [&](int32_t v) {
      const size_t f = static_cast<size_t>(m_vertexFragment[static_cast<size_t>(v)]);
      return f < m_drawnFragment.size() && m_drawnFragment[f] != 0;
    };
    m_drawnVertices.clear();
    m_drawnTriangles.clear();
    for (int32_t v = 0; v < nv; ++v)
      if (drawn(v)) m_drawnVertices.push_back(v);
    for (int32_t t = 0; t < 2 * nq && !m_drawnVertices.empty(); ++t)
      if (drawn(static_cast<int32_t>(m_indices[3 * static_cast<size_t>(t)])))
        m_drawnTriangles.push_back(t);
  }
  if (!m_drawnOnly || !m_drawnVertices.empty()) buildVertexTriangles(js);

  ++m_topologyVersion;
  m_positionsF.clear();  // new vertices: every one of them is dirty
  updatePositions(x, jobs);
}

void CrackSurface::buildFrames(const uint8_t* broken, JobSystem& js) {
  const EdgeGraph& g = *m_graph;
  const double* X = m_rest->positions.data();
  const size_t nf = m_frameNode.size();
  const uint32_t chunks = static_cast<uint32_t>((nf + kFrameChunk - 1) / kFrameChunk);
  if (m_frameChunks.size() < chunks) m_frameChunks.resize(chunks);
  m_frameRingStart.assign(nf + 1, 0);
  m_frameAffine.resize(nf);
  m_frameCinv.resize(9 * nf);
  m_frameR.resize(9 * nf);

  // Neighbourhoods of the nodes that need a frame: the unbroken 1-ring, grown level by level
  // (over unbroken edges, so within the node's fragment) until it spans a volume, since a
  // flat or collinear set of neighbours cannot tell the affine map (or, if collinear, the twist
  // about the line). Capped at about kMaxRing nodes.
  constexpr size_t kMaxRing = 64;
  js.parallelFor(chunks, 1, [&](uint32_t cb, uint32_t ce) {
    for (uint32_t c = cb; c < ce; ++c) {
      FrameChunk& ch = m_frameChunks[c];
      ch.ring.clear();
      const size_t fEnd = std::min(nf, (size_t(c) + 1) * kFrameChunk);
      for (size_t fr = size_t(c) * kFrameChunk; fr < fEnd; ++fr) {
        const int32_t a = m_frameNode[fr];
        if (++ch.stamp == 0) {
          std::fill(ch.seenStamp.begin(), ch.seenStamp.end(), 0u);
          ch.stamp = 1;
        }
        // A visited set over the few nodes a neighbourhood reaches: open addressing, its
        // entries live while they carry this frame's stamp.
        auto visit = [&ch](int32_t w) {
          if (2 * (ch.bfs.size() + 1) > ch.seen.size()) {
            const size_t cap = std::bit_ceil(std::max<size_t>(16, 4 * (ch.bfs.size() + 1)));
            ch.seen.assign(cap, -1);
            ch.seenStamp.assign(cap, 0u);
            ch.stamp = 1;
            for (int32_t u : ch.bfs) {
              size_t h = (uint32_t(u) * 2654435761u) & (cap - 1);
              while (ch.seenStamp[h] == ch.stamp) h = (h + 1) & (cap - 1);
              ch.seen[h] = u;
              ch.seenStamp[h] = ch.stamp;
            }
          }
          const size_t mask = ch.seen.size() - 1;
          for (size_t h = (uint32_t(w) * 2654435761u) & mask;; h = (h + 1) & mask) {
            if (ch.seenStamp[h] != ch.stamp) {
              ch.seen[h] = w;
              ch.seenStamp[h] = ch.stamp;
              return true;
            }
            if (ch.seen[h] == w) return false;
          }
        };
        ch.bfs.clear();
        visit(a);
        ch.bfs.push_back(a);
        const size_t ringBegin = ch.ring.size();
        const Vec3 Xa = load(X, a);
        Vec3 d1{}, plane{};
        bool spread2 = false, spread3 = false;
        size_t levelBegin = 0, levelEnd = 1;
        while (levelBegin < levelEnd) {
          for (size_t i = levelBegin; i < levelEnd; ++i) {
            const int32_t u = ch.bfs[i];
            for (int32_t s = g.nodeEdgeStart[static_cast<size_t>(u)];
                 s < g.nodeEdgeStart[static_cast<size_t>(u) + 1]; ++s) {
              const int32_t e = g.nodeEdges[static_cast<size_t>(s)];
              if (broken[e]) continue;
              const int32_t* ends = &g.edgeNodes[2 * static_cast<size_t>(e)];
              const int32_t w = ends[0] == u ? ends[1] : ends[0];
              if (!visit(w)) continue;
              ch.bfs.push_back(w);
              ch.ring.push_back(w);
              // Track whether the rest neighbourhood spans a plane, then a volume.
              const Vec3 dX = load(X, w) - Xa;
              if (dot(d1, d1) == 0) {
                d1 = dX;
              } else if (!spread2) {
                const Vec3 cr = cross(d1, dX);
                if (norm(cr) > 1e-6 * norm(d1) * norm(dX)) {
                  spread2 = true;
                  plane = cr;
                }
              } else if (std::fabs(dot(plane, dX)) > 1e-6 * norm(plane) * norm(dX)) {
                spread3 = true;
              }
            }
          }
          if (spread3 || ch.bfs.size() > kMaxRing) break;
          levelBegin = levelEnd;
          levelEnd = ch.bfs.size();
        }
        m_frameRingStart[fr + 1] = static_cast<int32_t>(ch.ring.size() - ringBegin);

        // Inverse rest covariance for the affine fit, kept only when the neighbourhood is well
        // spread in 3D (det against the cube of the mean eigenvalue; 1 for an isotropic ring).
        Mat3 C;
        for (size_t r = ringBegin; r < ch.ring.size(); ++r) {
          const Vec3 dX = load(X, ch.ring[r]) - Xa;
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) C(i, j) += dX[i] * dX[j];
        }
        const double meanEig = trace(C) / 3;
        const bool affine = spread3 && det(C) > 1e-3 * meanEig * meanEig * meanEig;
        const Mat3 Cinv = affine ? inverse(C) : Mat3{};
        m_frameAffine[fr] = affine ? 1 : 0;
        std::copy(Cinv.m, Cinv.m + 9, &m_frameCinv[9 * fr]);
      }
    }
  });
  for (size_t fr = 0; fr < nf; ++fr) m_frameRingStart[fr + 1] += m_frameRingStart[fr];
  m_frameRing.resize(static_cast<size_t>(m_frameRingStart[nf]));
  js.parallelFor(chunks, 1, [&](uint32_t cb, uint32_t ce) {
    for (uint32_t c = cb; c < ce; ++c) {
      const std::vector<int32_t>& ring = m_frameChunks[c].ring;
      std::copy(ring.begin(), ring.end(),
                m_frameRing.begin() + m_frameRingStart[size_t(c) * kFrameChunk]);
    }
  });
}

void CrackSurface::buildVertexTriangles(JobSystem& js) {
  // Each vertex's triangles, by increasing index: the normals' fixed summation order. A
  // counting sort by blocks of vertices: each chunk's (vertex, triangle) pairs go to their
  // block's bucket in chunk order, then each block sorts its bucket by vertex, stably.
  const size_t nv = m_vertexNode.size();
  if (js.threadCount() == 1) {
    // On one thread a plain counting sort over the triangle list does it in two passes.
    m_vertexTriStart.assign(nv + 1, 0);
    for (const uint32_t v : m_indices) ++m_vertexTriStart[size_t(v) + 1];
    for (size_t v = 0; v < nv; ++v) m_vertexTriStart[v + 1] += m_vertexTriStart[v];
    m_vertexTriFill.assign(m_vertexTriStart.begin(), m_vertexTriStart.end() - 1);
    m_vertexTri.resize(m_indices.size());
    for (size_t k = 0; k < m_indices.size(); ++k)
      m_vertexTri[size_t(m_vertexTriFill[m_indices[k]]++)] = int32_t(k / 3);
    return;
  }
  const size_t chunks = m_chunks.size(), blocks = (nv + kVertexBlock - 1) / kVertexBlock;
  m_blockAt.assign(chunks * blocks + 1, 0);
  auto eachChunk = [&](const auto& f) {
    js.parallelFor(uint32_t(chunks), 1, [&](uint32_t b, uint32_t e) {
      for (uint32_t c = b; c < e; ++c) {
        const TetChunk& ch = m_chunks[c];
        f(&m_blockAt[c * blocks], 6 * size_t(ch.quadBase),
          6 * (size_t(ch.quadBase) + ch.crack.size()));
      }
    });
  };
  eachChunk([&](int32_t* at, size_t kb, size_t ke) {
    for (size_t k = kb; k < ke; ++k) ++at[m_indices[k] / kVertexBlock];
  });
  // Bucket offsets, block by block and chunk by chunk within a block.
  size_t sum = 0;
  for (size_t b = 0; b < blocks; ++b)
    for (size_t c = 0; c < chunks; ++c) {
      const int32_t n = m_blockAt[c * blocks + b];
      m_blockAt[c * blocks + b] = int32_t(sum);
      sum += size_t(n);
    }
  m_pairs.resize(2 * sum);
  m_blockStart.resize(blocks + 1);
  for (size_t b = 0; b < blocks; ++b) m_blockStart[b] = chunks > 0 ? m_blockAt[b] : 0;
  m_blockStart[blocks] = int32_t(sum);
  eachChunk([&](int32_t* at, size_t kb, size_t ke) {
    for (size_t k = kb; k < ke; ++k) {
      const size_t i = size_t(at[m_indices[k] / kVertexBlock]++);
      m_pairs[2 * i] = int32_t(m_indices[k]);
      m_pairs[2 * i + 1] = int32_t(k / 3);
    }
  });
  m_vertexTriStart.resize(nv + 1);
  m_vertexTriStart[nv] = int32_t(sum);
  m_vertexTri.resize(sum);
  m_vertexTriFill.resize(nv);
  js.parallelFor(uint32_t(blocks), 1, [&](uint32_t bb, uint32_t be) {
    for (size_t b = bb; b < be; ++b) {
      const size_t v0 = b * kVertexBlock, v1 = std::min(nv, v0 + kVertexBlock);
      std::fill(&m_vertexTriFill[v0], &m_vertexTriFill[0] + v1, 0);
      const size_t pb = size_t(m_blockStart[b]), pe = size_t(m_blockStart[b + 1]);
      for (size_t i = pb; i < pe; ++i) ++m_vertexTriFill[size_t(m_pairs[2 * i])];
      int32_t at = int32_t(pb);
      for (size_t v = v0; v < v1; ++v) {
        m_vertexTriStart[v] = at;
        at += m_vertexTriFill[v];
        m_vertexTriFill[v] = m_vertexTriStart[v];
      }
      for (size_t i = pb; i < pe; ++i)
        m_vertexTri[size_t(m_vertexTriFill[size_t(m_pairs[2 * i])]++)] = m_pairs[2 * i + 1];
    }
  });
}

void CrackSurface::updatePositions(const double* x, JobSystem* jobs) {
  const double* X = m_rest->positions.data();
  if (!x) x = X;
  const CpuExecutor exec(jobs ? *jobs : serialJobs(), &m_partials);
  exec.run(int32_t(m_frameNode.size()), 64,
           SurfaceFrameStage{x, X, m_frameNode.data(), m_frameRingStart.data(), m_frameRing.data(),
                             m_frameAffine.data(), m_frameCinv.data(), m_frameR.data()});
  const int32_t nv = int32_t(m_vertexNode.size());
  m_positions.resize(3 * size_t(nv));
  m_normals.resize(3 * size_t(nv));
  if (m_drawnOnly) {
    const int32_t nd = int32_t(m_drawnVertices.size());
    ++m_positionVersion;
    if (nd == 0) return;
    exec.run(nd, 512,
             ListedStage<SurfaceVertexStage>{
                 m_drawnVertices.data(),
                 {x, X, m_vParent.data(), m_vWeight.data(), m_vGroup.data(), m_vRest.data(),
                  m_nodeFrame.data(), m_frameR.data(), m_positions.data()}});
    m_triAreaNormals.resize(4 * m_triCrack.size());
    exec.run(int32_t(m_drawnTriangles.size()), 1024,
             ListedStage<TriangleNormalStage>{
                 m_drawnTriangles.data(),
                 {m_positions.data(), m_indices.data(), m_triAreaNormals.data()}});
    exec.run(nd, 512,
             ListedStage<SurfaceNormalStage>{m_drawnVertices.data(),
                                             {m_triAreaNormals.data(), m_vertexTriStart.data(),
                                              m_vertexTri.data(), m_normals.data()}});
    return;
  }
  exec.run(
      nv, 512,
      SurfaceVertexStage{x, X, m_vParent.data(), m_vWeight.data(), m_vGroup.data(), m_vRest.data(),
                         m_nodeFrame.data(), m_frameR.data(), m_positions.data()});
  const int32_t ntri = int32_t(m_triCrack.size());
  m_triAreaNormals.resize(4 * size_t(ntri));
  exec.run(ntri, 1024,
           TriangleNormalStage{m_positions.data(), m_indices.data(), m_triAreaNormals.data()});
  exec.run(nv, 512,
           SurfaceNormalStage{m_triAreaNormals.data(), m_vertexTriStart.data(), m_vertexTri.data(),
                              m_normals.data()});

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
