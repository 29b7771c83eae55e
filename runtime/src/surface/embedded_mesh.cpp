// Render meshes embedded in the tets: binding at creation, cut and capped per fragment at
// fracture, positions every frame (see the design note in embedded_mesh.h).
#include "surface/embedded_mesh.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <queue>
#include <unordered_map>

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
// A render edge is cut no closer than this fraction of its length to either end.
constexpr double kMinCut = 0.05;
// The grid has at most this many cells along an axis.
constexpr int kMaxGridCells = 256;
// Midpoint rounds of EmbeddedBinding::refined: each halves the longest edges, so this bounds a
// render edge at 2^16 times the target length.
constexpr int kMaxRefineRounds = 16;
// After fracture, render edges are split until none is longer than this fraction of the tets'
// mean edge, so an edge seldom crosses more than one fragment boundary (design note: refinement;
// the fraction is measured there and in docs/validation.md).
constexpr double kRefineEdge = 1.0;
// The local edge (kTetEdgeNodes) between two local nodes of a tet.
constexpr int kTetEdge[4][4] = {{-1, 0, 1, 2}, {0, -1, 3, 4}, {1, 3, -1, 5}, {2, 4, 5, -1}};

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

using Triple = std::array<int32_t, 3>;

Triple sorted(int32_t a, int32_t b, int32_t c) {
  Triple t{a, b, c};
  std::sort(t.begin(), t.end());
  return t;
}

// The lines inside the tets where three fragments' cells meet (design note: junctions), at
// rest: segments between face centroids, tet centroids and chips' nodes, each with the three
// fragments whose cells meet there, and the scratch of the shortest paths along them.
struct TripleLines {
  std::vector<Vec3> point;
  std::vector<int32_t> ends;                             // 2 per segment
  std::vector<Triple> labels;                            // per segment, ascending
  std::vector<int32_t> start, segments;                  // per point: its segments (CSR)
  std::map<Triple, std::vector<int32_t>> onLine;         // per triple: the points of its segments
  std::map<std::pair<int32_t, int32_t>, int32_t> tetOf;  // (point, fragment): a tet with its node
  std::vector<double> dist;
  std::vector<int32_t> from, via, touched;
};

}  // namespace

Result<EmbeddedBinding> EmbeddedBinding::bind(const TetMesh& rest, const RenderMesh& mesh,
                                              const std::string& field) {
  const size_t nv = mesh.vertexCount();
  EmbeddedBinding b;
  b.rest = mesh.positions;
  b.uv = mesh.uvs;
  b.indices = mesh.indices;
  b.material = mesh.materials;

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

  Result<void> located = locate(rest, b, field, true);
  if (!located.ok()) return located.error();
  return b;
}

Result<void> EmbeddedBinding::locate(const TetMesh& rest, EmbeddedBinding& b,
                                     const std::string& field, bool limitDistance) {
  const size_t nt = rest.tetCount(), nv = b.rest.size() / 3;
  const double* X = rest.positions.data();
  b.outsideCount = 0;
  b.maxOutside = 0;
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
      if (limitDistance && !(bestDist <= 2 * longest)) {
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
  return {};
}

EmbeddedBinding EmbeddedBinding::refined(const TetMesh& tets, double maxEdge) const {
  EmbeddedBinding r;
  r.rest = rest;
  r.restNormal = restNormal;
  r.uv = uv;
  r.indices = indices;
  r.material = material;
  const double max2 = maxEdge * maxEdge;
  std::unordered_map<uint64_t, uint32_t> mid;
  std::vector<uint32_t> next;
  std::vector<uint16_t> nextMaterial;
  for (int round = 0; round < kMaxRefineRounds; ++round) {
    // Each long edge gets one midpoint, keyed by its two vertices, so the two triangles of the
    // edge share it and the surface stays conforming (no T-junction opens it).
    mid.clear();
    auto midpoint = [&](uint32_t a, uint32_t c) -> int64_t {
      const Vec3 Pa = load(r.rest.data(), a), Pc = load(r.rest.data(), c);
      const Vec3 d = Pc - Pa;
      if (dot(d, d) <= max2) return -1;
      const uint64_t key = uint64_t(std::min(a, c)) << 32 | std::max(a, c);
      auto [it, added] = mid.emplace(key, uint32_t(r.rest.size() / 3));
      if (added) {
        const Vec3 P = 0.5 * (Pa + Pc);
        Vec3 N = load(r.restNormal.data(), a) + load(r.restNormal.data(), c);
        N = norm(N) > 0 ? (1 / norm(N)) * N : load(r.restNormal.data(), a);
        r.rest.insert(r.rest.end(), {P.x, P.y, P.z});
        r.restNormal.insert(r.restNormal.end(), {N.x, N.y, N.z});
        if (!r.uv.empty())
          for (int k = 0; k < 2; ++k)
            r.uv.push_back(0.5f *
                           (r.uv[2 * size_t(a) + size_t(k)] + r.uv[2 * size_t(c) + size_t(k)]));
      }
      return int64_t(it->second);
    };
    next.clear();
    nextMaterial.clear();
    const size_t ntri = r.indices.size() / 3;
    for (size_t t = 0; t < ntri; ++t) {
      const uint32_t id[3] = {r.indices[3 * t], r.indices[3 * t + 1], r.indices[3 * t + 2]};
      // m[i]: the midpoint of the edge from corner i to corner i + 1, or -1.
      const int64_t m[3] = {midpoint(id[0], id[1]), midpoint(id[1], id[2]), midpoint(id[2], id[0])};
      const int marked = int(m[0] >= 0) + int(m[1] >= 0) + int(m[2] >= 0);
      auto emit = [&](int64_t a, int64_t b, int64_t c) {
        next.insert(next.end(), {uint32_t(a), uint32_t(b), uint32_t(c)});
        if (!r.material.empty()) nextMaterial.push_back(r.material[t]);
      };
      if (marked == 0) {
        emit(id[0], id[1], id[2]);
      } else if (marked == 1) {
        const int i = m[0] >= 0 ? 0 : m[1] >= 0 ? 1 : 2, j = (i + 1) % 3, k = (i + 2) % 3;
        emit(id[i], m[i], id[k]);
        emit(m[i], id[j], id[k]);
      } else if (marked == 2) {
        // Edge a-b whole: a triangle at corner c, and the quad (a, b, m1, m2) split along its
        // shorter diagonal.
        const int u = m[0] < 0 ? 0 : m[1] < 0 ? 1 : 2;
        const uint32_t a = id[u], b = id[(u + 1) % 3], c = id[(u + 2) % 3];
        const int64_t m1 = m[(u + 1) % 3], m2 = m[(u + 2) % 3];
        emit(m1, c, m2);
        const Vec3 Pa = load(r.rest.data(), a), Pb = load(r.rest.data(), b);
        const Vec3 P1 = load(r.rest.data(), size_t(m1)), P2 = load(r.rest.data(), size_t(m2));
        if (norm(P1 - Pa) <= norm(P2 - Pb)) {
          emit(a, b, m1);
          emit(a, m1, m2);
        } else {
          emit(a, b, m2);
          emit(b, m1, m2);
        }
      } else {
        emit(id[0], m[0], m[2]);
        emit(m[0], id[1], m[1]);
        emit(m[2], m[1], id[2]);
        emit(m[0], m[1], m[2]);
      }
    }
    r.indices.swap(next);
    if (!r.material.empty()) r.material.swap(nextMaterial);
    if (mid.empty()) break;
  }
  // The new points lie on the artist's triangles, whose corners passed bind()'s distance check.
  // A mesh already fine enough is returned as is, unbound: the caller keeps the original.
  if (r.indices.size() != indices.size()) (void)locate(tets, r, "", false);
  return r;
}

void EmbeddedSurface::init(const EmbeddedBinding& binding, const TetMesh& rest,
                           const EdgeGraph& graph, const Mat3* restInverse) {
  m_original = &binding;
  m_binding = &binding;
  m_refined.reset();
  m_refineChecked = false;
  m_rest = &rest;
  m_graph = &graph;
  m_restInverse = restInverse;
  m_frameMark.assign(rest.nodeCount(), 0);
  m_nodeInside.assign(rest.nodeCount(), -1);
  m_nodeTet.clear();
  double sum = 0;
  for (int32_t e = 0; e < graph.edgeCount; ++e)
    sum += norm(load(rest.positions.data(), size_t(graph.edgeNodes[2 * size_t(e)])) -
                load(rest.positions.data(), size_t(graph.edgeNodes[2 * size_t(e) + 1])));
  m_meanEdge = sum / double(std::max(graph.edgeCount, 1));
  m_composed = false;
}

uint32_t EmbeddedSurface::addCopy(int32_t source, int32_t tet, const double* w, unsigned group,
                                  int32_t fragment, Vec3 rest, Vec3 restNormal, const float* uv) {
  const uint32_t id = uint32_t(m_vTet.size());
  const int32_t* n = &m_rest->tets[4 * size_t(tet)];
  // A chip given to this fragment is drawn, not followed (its node flies off alone): the copy
  // follows the fragment's nodes in its group, or, with none there, the fragment's node next to
  // the tet nearest to it.
  unsigned chips = 0;
  for (int k = 0; k < 4; ++k) chips |= m_chipNode[size_t(n[k])] ? 1u << k : 0u;
  double wa[4];
  if (group & ~chips) {
    group &= ~chips;
  } else if (const int32_t a = chips ? nearestNode(n, fragment, rest) : -1; a >= 0) {
    tet = m_nodeTet[size_t(a)];
    n = &m_rest->tets[4 * size_t(tet)];
    barycentric(m_restInverse[tet], load(m_rest->positions.data(), size_t(n[0])), rest, wa);
    w = wa;
    group = 0;
    for (int k = 0; k < 4; ++k) group |= n[k] == a ? 1u << k : 0u;
  }
  m_vTet.push_back(tet);
  m_vSource.push_back(source);
  m_vSeparated.push_back(0);
  m_vJunction.push_back(-1);
  m_vAcross.push_back(-1);
  m_vWeight.insert(m_vWeight.end(), w, w + 4);
  m_vGroup.push_back(uint8_t(group));
  m_vNode.push_back(n[strongest(w, group)]);
  m_vFragment.push_back(fragment);
  m_vRest.insert(m_vRest.end(), {rest.x, rest.y, rest.z});
  m_vRestNormal.insert(m_vRestNormal.end(), {restNormal.x, restNormal.y, restNormal.z});
  if (!m_binding->uv.empty()) m_vUv.insert(m_vUv.end(), uv, uv + 2);
  // A copy that follows only part of its tet needs the local maps of the nodes it follows.
  if (group != 15u)
    for (int k = 0; k < 4; ++k)
      if ((group >> k & 1u) && !m_frameMark[size_t(n[k])]) {
        m_frameMark[size_t(n[k])] = 1;
        m_frameNodes.push_back(n[k]);
      }
  return id;
}

int32_t EmbeddedSurface::nearestNode(const int32_t* n, int32_t fragment, Vec3 P) const {
  const EdgeGraph& g = *m_graph;
  const double* X = m_rest->positions.data();
  int32_t best = -1;
  double bestDist = HUGE_VAL;
  for (int k = 0; k < 4; ++k) {
    for (int32_t i = g.nodeEdgeStart[n[k]]; i < g.nodeEdgeStart[n[k] + 1]; ++i) {
      const int32_t e = g.nodeEdges[size_t(i)];
      const int32_t o = g.edgeNodes[2 * size_t(e)] == n[k] ? g.edgeNodes[2 * size_t(e) + 1]
                                                           : g.edgeNodes[2 * size_t(e)];
      if (m_chipNode[size_t(o)] || m_drawLabel[size_t(o)] != fragment) continue;
      const double d = norm(load(X, size_t(o)) - P);
      if (d < bestDist) {
        bestDist = d;
        best = o;
      }
    }
  }
  return best;
}

uint32_t EmbeddedSurface::homeCopy(uint32_t v) {
  if (m_homeCopy[v] < 0) {
    const EmbeddedBinding& b = *m_binding;
    const float* uv = b.uv.empty() ? nullptr : &b.uv[2 * size_t(v)];
    m_homeCopy[v] =
        int32_t(addCopy(int32_t(v), b.tet[v], &b.weight[4 * size_t(v)], m_homeGroup[v], m_home[v],
                        load(b.rest.data(), v), load(b.restNormal.data(), v), uv));
  }
  return uint32_t(m_homeCopy[v]);
}

uint32_t EmbeddedSurface::pointCopy(Vec3 P, Vec3 N, const float* uv, uint32_t side) {
  // Bound like the render vertex `side`: its tet (extrapolated) and its group.
  const int32_t t = m_binding->tet[side];
  double w[4];
  barycentric(m_restInverse[t], load(m_rest->positions.data(), size_t(m_rest->tets[4 * size_t(t)])),
              P, w);
  return addCopy(-1, t, w, m_homeGroup[side], m_home[side], P, N, uv);
}

uint32_t EmbeddedSurface::cutCopy(uint32_t u, uint32_t v, uint32_t side) {
  const uint32_t lo = std::min(u, v), hi = std::max(u, v);
  const uint64_t key = uint64_t(lo) << 32 | hi;
  auto found = m_cut.find(key);
  if (found == m_cut.end()) {
    const EmbeddedBinding& b = *m_binding;
    const Vec3 Plo = load(b.rest.data(), lo), Phi = load(b.rest.data(), hi);
    // Where the boundary w_a = w_b between the two ends' cells crosses the edge, in the lower
    // end's tet (a: its node of the largest weight; b: the other end's node of the largest
    // weight among the tet's nodes on the other side: in the other fragment, or, within one
    // fragment, outside the lower end's group).
    double s = 0.5;
    const int32_t t = b.tet[lo];
    const int32_t* n = &m_rest->tets[4 * size_t(t)];
    unsigned other = 0;
    if (m_home[lo] != m_home[hi]) {
      for (int k = 0; k < 4; ++k) other |= m_nodeFragment[n[k]] == m_home[hi] ? 1u << k : 0u;
    } else {
      other = ~unsigned(m_homeGroup[lo]) & 15u;
    }
    if (other) {
      const double* wl = &b.weight[4 * size_t(lo)];
      double wh[4];
      barycentric(m_restInverse[t], load(m_rest->positions.data(), size_t(n[0])), Phi, wh);
      const unsigned drawn = drawnNodes(t);
      if (other & drawn) other &= drawn;
      const int ka = strongest(wl, drawn), kb = strongest(wh, other);
      const double dl = wl[ka] - wl[kb], dh = wh[ka] - wh[kb];
      if (dl - dh > 0) s = dl / (dl - dh);
    }
    // Away from the ends, so no cut piece degenerates.
    s = std::clamp(s, kMinCut, 1 - kMinCut);
    const Vec3 P = (1 - s) * Plo + s * Phi;
    Vec3 N = (1 - s) * load(b.restNormal.data(), lo) + s * load(b.restNormal.data(), hi);
    N = norm(N) > 0 ? (1 / norm(N)) * N : load(b.restNormal.data(), lo);
    float uv[2] = {0, 0};
    if (!b.uv.empty())
      for (int c = 0; c < 2; ++c)
        uv[c] = float((1 - s) * double(b.uv[2 * size_t(lo) + size_t(c)]) +
                      s * double(b.uv[2 * size_t(hi) + size_t(c)]));
    const uint32_t cl = pointCopy(P, N, uv, lo);
    const uint32_t ch = pointCopy(P, N, uv, hi);
    if (m_home[lo] != m_home[hi]) {
      m_vSeparated[cl] = m_vSeparated[ch] = 1;
      m_vAcross[cl] = m_home[hi];
      m_vAcross[ch] = m_home[lo];
    }
    found = m_cut.emplace(key, std::make_pair(cl, ch)).first;
  }
  return side == lo ? found->second.first : found->second.second;
}

bool EmbeddedSurface::apart(uint32_t u, uint32_t v) const {
  if (m_home[u] != m_home[v]) return true;
  const int32_t a = m_homeNode[u], c = m_homeNode[v];
  // A tet holds its nodes pairwise joined by its edges, so two nodes can be in different groups
  // of a tet only when the edge between them is broken: most edges end here.
  if (a == c || !m_nodeCracked[size_t(a)] || !m_nodeCracked[size_t(c)]) return false;
  // Within a fragment the groups that move the copies decide: the two ends' cell nodes are
  // apart when an end's tet holds the other's cell node outside its group. A tet whose nodes
  // are all joined (a lone broken edge) sees nothing apart, so a crack is cut only where it
  // splits tets, as the copies move.
  const std::vector<int32_t>& tets = m_rest->tets;
  bool shared = false;
  for (const auto& [w, node] : {std::pair{u, c}, std::pair{v, a}}) {
    const int32_t* n = &tets[4 * size_t(m_binding->tet[w])];
    for (int k = 0; k < 4; ++k)
      if (n[k] == node) {
        if (!(m_homeGroup[w] >> k & 1u)) return true;
        shared = true;
      }
  }
  if (shared) return false;
  // A render edge that leaves both ends' tets: the nodes are on one side when an unbroken path
  // of at most two graph edges joins them (through a node of a tet they both touch), which
  // holds across a crack only near its front, where the two sides are still joined.
  const EdgeGraph& g = *m_graph;
  auto other = [&](int32_t e, int32_t n) {
    return g.edgeNodes[2 * size_t(e)] == n ? g.edgeNodes[2 * size_t(e) + 1]
                                           : g.edgeNodes[2 * size_t(e)];
  };
  for (int32_t i = g.nodeEdgeStart[a]; i < g.nodeEdgeStart[a + 1]; ++i) {
    const int32_t ea = g.nodeEdges[i];
    if (m_broken[ea]) continue;
    const int32_t m = other(ea, a);
    if (m == c) return false;
    for (int32_t j = g.nodeEdgeStart[c]; j < g.nodeEdgeStart[c + 1]; ++j) {
      const int32_t ec = g.nodeEdges[j];
      if (!m_broken[ec] && other(ec, c) == m) return false;
    }
  }
  return true;
}

unsigned EmbeddedSurface::drawnNodes(int32_t t) const {
  const int32_t* n = &m_rest->tets[4 * size_t(t)];
  unsigned m = 0;
  for (int k = 0; k < 4; ++k) m |= m_wholeTet[size_t(m_nodeFragment[n[k]])] ? 1u << k : 0u;
  return m ? m : 15u;
}

unsigned EmbeddedSurface::joinedMask(int32_t t) const {
  const int32_t* te = &m_graph->tetEdges[6 * size_t(t)];
  unsigned m = 0;
  for (int j = 0; j < 6; ++j) m |= m_realBroken[te[j]] ? 0u : 1u << j;
  // A chip given to a fragment joins, in each tet, that fragment's node there nearest to it (the
  // lowest on a tie): joined to all, it would join the groups on two sides of a crack between them.
  const int32_t* n = &m_rest->tets[4 * size_t(t)];
  const double* X = m_rest->positions.data();
  for (int k = 0; k < 4; ++k) {
    if (!m_chipNode[size_t(n[k])]) continue;
    int best = -1;
    double bestDist = HUGE_VAL;
    for (int o = 0; o < 4; ++o) {
      if (o == k || m_chipNode[size_t(n[o])] ||
          m_drawLabel[size_t(n[o])] != m_drawLabel[size_t(n[k])])
        continue;
      const double d = norm(load(X, size_t(n[o])) - load(X, size_t(n[k])));
      if (d < bestDist || (d == bestDist && n[o] < n[best])) {
        bestDist = d;
        best = o;
      }
    }
    if (best >= 0) m |= 1u << kTetEdge[k][best];
  }
  return m;
}

bool EmbeddedSurface::nodeInside(int32_t node) {
  int8_t& inside = m_nodeInside[size_t(node)];
  if (inside < 0) {
    // Generalised winding number (solid angles, Van Oosterom and Strackee): 1 inside a closed
    // mesh, 0 outside, and a robust in-between for open ones.
    const EmbeddedBinding& b = *m_original;
    const Vec3 p = load(m_rest->positions.data(), size_t(node));
    double omega = 0;
    for (size_t t = 0; t < b.indices.size() / 3; ++t) {
      const Vec3 A = load(b.rest.data(), b.indices[3 * t]) - p;
      const Vec3 B = load(b.rest.data(), b.indices[3 * t + 1]) - p;
      const Vec3 C = load(b.rest.data(), b.indices[3 * t + 2]) - p;
      const double la = norm(A), lb = norm(B), lc = norm(C);
      omega += 2 * std::atan2(dot(A, cross(B, C)),
                              la * lb * lc + dot(A, B) * lc + dot(B, C) * la + dot(C, A) * lb);
    }
    inside = int8_t(omega >= 2 * std::numbers::pi ? 1 : 0);  // winding number >= 1/2
  }
  return inside == 1;
}

void EmbeddedSurface::makeNodeTets() {
  if (!m_nodeTet.empty()) return;
  m_nodeTet.assign(m_rest->nodeCount(), -1);
  for (size_t t = 0; t < m_rest->tetCount(); ++t)
    for (int k = 0; k < 4; ++k) {
      int32_t& at = m_nodeTet[size_t(m_rest->tets[4 * t + size_t(k)])];
      if (at < 0) at = int32_t(t);
    }
}

void EmbeddedSurface::giveChipsToNeighbours(const int32_t* nodeFragment) {
  const size_t nn = m_rest->nodeCount();
  const EdgeGraph& g = *m_graph;
  auto other = [&](int32_t e, int32_t a) {
    return g.edgeNodes[2 * size_t(e)] == a ? g.edgeNodes[2 * size_t(e) + 1]
                                           : g.edgeNodes[2 * size_t(e)];
  };
  m_drawLabel.assign(nodeFragment, nodeFragment + nn);
  bool given = false;
  if (m_chipsByNeighbours) {
    // Each chip goes whole to the fragment that drew most of its cells when they were shared
    // out tet by tet: in a tet, each node's corner cell (a quarter of it) split evenly among the
    // tet's nodes of fragments with a whole tet; the lowest id on a tie. Counting graph edges to
    // each fragment instead, the shattered bunny's pieces covered 0.863 of it, counting tets
    // shared 0.903, now 0.915. A chip among chips only keeps its label (given along chains of
    // chips, 0.856 with edges counted).
    std::map<std::pair<int32_t, int32_t>, double> share;
    const double* X = m_rest->positions.data();
    for (size_t t = 0; t < m_rest->tetCount(); ++t) {
      const int32_t* tn = &m_rest->tets[4 * t];
      int drawn = 0;  // the tet's nodes in fragments with a whole tet
      for (int q = 0; q < 4; ++q) drawn += m_wholeTet[size_t(nodeFragment[tn[q]])] ? 1 : 0;
      if (drawn == 0 || drawn == 4) continue;
      const Vec3 x0 = load(X, size_t(tn[0]));
      const double v =
          std::abs(dot(load(X, size_t(tn[1])) - x0,
                       cross(load(X, size_t(tn[2])) - x0, load(X, size_t(tn[3])) - x0))) /
          6;
      for (int p = 0; p < 4; ++p)
        for (int q = 0; q < 4; ++q)
          if (!m_wholeTet[size_t(nodeFragment[tn[p]])] && m_wholeTet[size_t(nodeFragment[tn[q]])])
            share[{nodeFragment[tn[p]], nodeFragment[tn[q]]}] += v / (4 * drawn);
    }
    std::unordered_map<int32_t, int32_t> to;
    std::unordered_map<int32_t, double> most;
    for (const auto& [key, v] : share) {
      auto [it, added] = most.emplace(key.first, v);
      if (added || v > it->second) {
        it->second = v;
        to[key.first] = key.second;
      }
    }
    // Not across a crack within that fragment: a chip whose neighbours there lie on two sides
    // (not joined among themselves by unbroken edges) would be drawn with one side, and its
    // cells would stretch across the crack as it opens (RenderMesh.ObliquePartialCracksAreClosed).
    std::vector<int32_t> near, root;
    auto find = [&](int32_t k) {
      while (root[size_t(k)] != k) k = root[size_t(k)] = root[size_t(root[size_t(k)])];
      return k;
    };
    for (size_t c = 0; c < nn; ++c) {
      const auto it = to.find(nodeFragment[c]);
      if (it == to.end()) continue;
      near.clear();
      for (int32_t i = g.nodeEdgeStart[c]; i < g.nodeEdgeStart[c + 1]; ++i) {
        const int32_t o = other(g.nodeEdges[size_t(i)], int32_t(c));
        if (nodeFragment[o] == it->second) near.push_back(o);
      }
      std::sort(near.begin(), near.end());
      root.resize(near.size());
      for (size_t k = 0; k < near.size(); ++k) root[k] = int32_t(k);
      size_t parts = near.size();
      for (size_t k = 0; k < near.size(); ++k)
        for (int32_t i = g.nodeEdgeStart[near[k]]; i < g.nodeEdgeStart[near[k] + 1]; ++i) {
          const int32_t e = g.nodeEdges[size_t(i)], o = other(e, near[k]);
          const auto q = std::lower_bound(near.begin(), near.end(), o);
          if (m_broken[e] || q == near.end() || *q != o) continue;
          const int32_t ra = find(int32_t(k)), rb = find(int32_t(q - near.begin()));
          if (ra != rb) {
            root[size_t(ra)] = rb;
            --parts;
          }
        }
      if (parts > 1) to.erase(it);
    }
    for (size_t n = 0; n < nn; ++n)
      if (const auto it = to.find(nodeFragment[n]); it != to.end()) {
        m_drawLabel[n] = it->second;
        m_chipNode[n] = 1;
        given = true;
      }
  }
  if (given) makeNodeTets();
  // Drawn, a chip's edges to the fragment that takes it are not cracks.
  m_drawBroken.assign(m_broken, m_broken + g.edgeCount);
  m_nodeCracked.assign(nn, 0);
  for (int32_t e = 0; e < g.edgeCount; ++e) {
    const int32_t a = g.edgeNodes[2 * size_t(e)], c = g.edgeNodes[2 * size_t(e) + 1];
    if ((m_chipNode[size_t(a)] || m_chipNode[size_t(c)]) &&
        m_drawLabel[size_t(a)] == m_drawLabel[size_t(c)])
      m_drawBroken[size_t(e)] = 0;
    if (m_drawBroken[size_t(e)]) m_nodeCracked[size_t(a)] = m_nodeCracked[size_t(c)] = 1;
  }
}

void EmbeddedSurface::rebuild(const uint8_t* broken, const int32_t* nodeFragment) {
  m_nodeFragment = nodeFragment;
  m_broken = broken;
  m_realBroken = broken;
  bool anyBroken = false;
  for (int32_t e = 0; e < m_graph->edgeCount && !anyBroken; ++e) anyBroken = broken[e] != 0;
  // A render edge is cut once, so once the body breaks the mesh is drawn with its edges split
  // to the tets' mean edge (made on the first break, kept); a whole body is drawn as given.
  if (anyBroken && !m_refineChecked) {
    m_refineChecked = true;
    EmbeddedBinding r = m_original->refined(*m_rest, kRefineEdge * m_meanEdge);
    if (r.indices.size() != m_original->indices.size())
      m_refined = std::make_unique<EmbeddedBinding>(std::move(r));
  }
  m_binding = anyBroken && m_refined ? m_refined.get() : m_original;
  const EmbeddedBinding& b = *m_binding;
  const size_t nv = b.tet.size();

  // Chips: fragments that hold no whole tet (in the degradation model, a node whose every tet
  // is split). Such a fragment is free matter with no volume of its own: drawn as a piece, each
  // one made its neighbours' cycles meet at more junctions and the cores between them went
  // uncovered (design note: chips).
  const size_t nn = m_rest->nodeCount();
  int32_t fragments = 0;
  for (size_t n = 0; n < nn; ++n) fragments = std::max(fragments, nodeFragment[n] + 1);
  m_chipNode.assign(nn, 0);
  m_wholeTet.assign(size_t(fragments), m_chipsByNeighbours ? 0 : 1);
  for (size_t t = 0; t < m_rest->tetCount() && m_chipsByNeighbours; ++t)
    if (component(0, joinedMask(int32_t(t))) == 15u)
      m_wholeTet[size_t(nodeFragment[m_rest->tets[4 * t]])] = 1;
  giveChipsToNeighbours(nodeFragment);
  // From here on the labels and cracks are the drawn ones (broken: the real cracks, for groups).
  nodeFragment = m_drawLabel.data();
  m_nodeFragment = nodeFragment;
  m_broken = m_drawBroken.data();

  // Each vertex's label and group: those of its tet's node of the largest weight, whose corner
  // cell holds it, among the nodes not in chips (a chip's cells go to the neighbours that share
  // its tets), or among all four when every one is.
  m_home.resize(nv);
  m_homeGroup.resize(nv);
  m_homeNode.resize(nv);
  for (size_t v = 0; v < nv; ++v) {
    const int32_t t = b.tet[v];
    const int k = strongest(&b.weight[4 * v], drawnNodes(t));
    m_homeNode[v] = m_rest->tets[4 * size_t(t) + size_t(k)];
    m_home[v] = nodeFragment[m_homeNode[v]];
    m_homeGroup[v] = uint8_t(component(k, joinedMask(t)));
  }

  m_homeCopy.assign(nv, -1);
  m_cut.clear();
  m_segments.clear();
  for (int32_t a : m_frameNodes) m_frameMark[size_t(a)] = 0;
  m_frameNodes.clear();
  m_vTet.clear();
  m_vSource.clear();
  m_vSeparated.clear();
  m_vJunction.clear();
  m_vAcross.clear();
  m_vWeight.clear();
  m_vRest.clear();
  m_vRestNormal.clear();
  m_vUv.clear();
  m_vGroup.clear();
  m_vNode.clear();
  m_vFragment.clear();
  m_renderIndices.clear();
  m_renderMaterial.clear();

  // Marching triangles on the cut edges (design note: cutting the render triangles). Each
  // piece's side of a cut, in the piece's orientation, is a segment of its side's rim.
  size_t tri = 0;
  auto emit = [&](uint32_t a, uint32_t c1, uint32_t c2) {
    m_renderIndices.insert(m_renderIndices.end(), {a, c1, c2});
    if (!b.material.empty()) m_renderMaterial.push_back(b.material[tri]);
  };
  auto rim = [&](uint32_t from, uint32_t to) { m_segments.push_back({from, to}); };
  const size_t ntri = b.indices.size() / 3;
  for (tri = 0; tri < ntri; ++tri) {
    const uint32_t* id = &b.indices[3 * tri];
    // cut[i]: the edge from corner i to corner i + 1.
    const bool cut[3] = {apart(id[0], id[1]), apart(id[1], id[2]), apart(id[2], id[0])};
    const int cuts = int(cut[0]) + int(cut[1]) + int(cut[2]);
    if (cuts == 0) {
      // Copies are made in a fixed order (function arguments have none).
      const uint32_t a = homeCopy(id[0]), b1 = homeCopy(id[1]), c = homeCopy(id[2]);
      emit(a, b1, c);
    } else if (cuts == 1) {
      // The crack ends in this triangle: its cut edge ij opens towards corner k, where the two
      // sides meet (the front, design note).
      const int i = cut[0] ? 0 : cut[1] ? 1 : 2, j = (i + 1) % 3, k = (i + 2) % 3;
      const uint32_t ijA = cutCopy(id[i], id[j], id[i]), ijB = cutCopy(id[i], id[j], id[j]);
      const uint32_t hi = homeCopy(id[i]), hj = homeCopy(id[j]), hk = homeCopy(id[k]);
      emit(hi, ijA, hk);
      emit(ijB, hj, hk);
      rim(ijA, hk);
      rim(hk, ijB);
    } else if (cuts == 2) {
      // Vertex i alone on its side: a triangle there, a quad on the other side.
      const int i = !cut[1] ? 0 : !cut[2] ? 1 : 2, j = (i + 1) % 3, k = (i + 2) % 3;
      const uint32_t ijA = cutCopy(id[i], id[j], id[i]), ikA = cutCopy(id[i], id[k], id[i]);
      const uint32_t ijB = cutCopy(id[i], id[j], id[j]), ikB = cutCopy(id[i], id[k], id[k]);
      const uint32_t hi = homeCopy(id[i]), hj = homeCopy(id[j]), hk = homeCopy(id[k]);
      emit(hi, ijA, ikA);
      emit(ijB, hj, hk);
      emit(ijB, hk, ikB);
      rim(ijA, ikA);
      rim(ikB, ijB);
    } else {
      // Three sides: a centre point and a quad per corner.
      Vec3 P{}, N{};
      float uv[2] = {0, 0};
      for (int c = 0; c < 3; ++c) {
        P += (1.0 / 3) * load(b.rest.data(), id[c]);
        N += load(b.restNormal.data(), id[c]);
        if (!b.uv.empty())
          for (int d = 0; d < 2; ++d) uv[d] += b.uv[2 * size_t(id[c]) + size_t(d)] / 3;
      }
      N = norm(N) > 0 ? (1 / norm(N)) * N : load(b.restNormal.data(), id[0]);
      for (int i = 0; i < 3; ++i) {
        const int j = (i + 1) % 3, k = (i + 2) % 3;
        const uint32_t c1 = cutCopy(id[i], id[j], id[i]), c2 = cutCopy(id[k], id[i], id[i]);
        const uint32_t m = pointCopy(P, N, uv, id[i]), h = homeCopy(id[i]);
        // Three fragments meet here: the caps are split at this point (below).
        if (m_home[id[0]] != m_home[id[1]] && m_home[id[1]] != m_home[id[2]] &&
            m_home[id[2]] != m_home[id[0]])
          m_vJunction[m] = int32_t(tri);
        emit(h, c1, m);
        emit(h, m, c2);
        rim(c1, m);
        rim(m, c2);
      }
    }
  }

  // The rim segments split into cycles, each capped; a walk that returns to a vertex already on
  // it closes a cycle there, so a vertex on two cycles (two crack ends in its star) gets two
  // caps. A cut that runs into a hole of an open render mesh is a chain from one cut point on
  // the hole's rim to another: walked from its start (more segments leave than enter), it is
  // capped like a cycle, so the fan's closing edge runs across the hole and the piece stays open
  // only there, where the artist's mesh is.
  m_capStart.assign(1, 0);
  m_capRim.clear();
  m_openCuts = 0;
  const size_t ncopy = m_vTet.size(), nseg = m_segments.size();
  // Segments by their first copy (counting sort, in emission order), in buffers that keep
  // their capacity.
  std::vector<int32_t>& outStart = m_outStart;
  std::vector<int32_t>& out = m_out;
  std::vector<int32_t>& nextOut = m_nextOut;
  std::vector<int32_t>& onPath = m_onPath;
  std::vector<int32_t>& path = m_path;
  std::vector<int32_t>& surplus = m_surplus;  // per copy: segments leaving minus entering
  outStart.assign(ncopy + 1, 0);
  surplus.assign(ncopy, 0);
  out.resize(nseg);
  for (const auto& sg : m_segments) {
    ++outStart[sg.first + 1];
    ++surplus[sg.first];
    --surplus[sg.second];
  }
  for (size_t c = 0; c < ncopy; ++c) outStart[c + 1] += outStart[c];
  nextOut.assign(outStart.begin(), outStart.end() - 1);
  for (size_t g = 0; g < nseg; ++g) out[size_t(nextOut[m_segments[g].first]++)] = int32_t(g);
  nextOut.assign(outStart.begin(), outStart.end() - 1);  // per copy: its first unused segment
  onPath.assign(ncopy, -1);
  auto cap = [&](size_t from) {
    for (size_t k = from; k < path.size(); ++k) {
      m_capRim.push_back(path[k]);
      if (k > from) onPath[size_t(path[k])] = -1;
    }
    m_capStart.push_back(int32_t(m_capRim.size()));
  };
  auto walk = [&](size_t c) {
    path.assign(1, int32_t(c));
    onPath[c] = 0;
    for (;;) {
      const int32_t p = path.back();
      if (nextOut[size_t(p)] == outStart[size_t(p) + 1]) {
        // Stuck: the end of a chain (chain starts are walked first, so this is all of it). A
        // chain of one segment encloses nothing and is left open.
        ++m_openCuts;
        if (path.size() >= 3) {
          onPath[size_t(path[0])] = -1;
          cap(0);
          path.resize(1);
        }
        break;
      }
      const int32_t q = int32_t(m_segments[size_t(out[size_t(nextOut[size_t(p)]++)])].second);
      if (onPath[size_t(q)] < 0) {
        onPath[size_t(q)] = int32_t(path.size());
        path.push_back(q);
        continue;
      }
      // Back at q: path[onPath[q]..] is a cycle.
      const size_t from = size_t(onPath[size_t(q)]);
      cap(from);
      path.resize(from + 1);
      if (from == 0 && nextOut[size_t(q)] == outStart[size_t(q) + 1]) break;
    }
    for (int32_t p : path) onPath[size_t(p)] = -1;
  };
  for (size_t c = 0; c < ncopy; ++c)
    while (surplus[c] > 0 && nextOut[c] < outStart[c + 1]) {
      --surplus[c];
      walk(c);
    }
  for (size_t c = 0; c < ncopy; ++c)
    while (nextOut[c] < outStart[c + 1]) walk(c);

  splitAtJunctions();

  // Fragments without a render vertex: drawn with their tet faces when inside the render mesh.
  // Chips are not: their cells are drawn by the neighbours whose caps enclose them.
  std::vector<uint8_t> hasRender(size_t(fragments), 0);
  for (size_t v = 0; v < nv; ++v) hasRender[size_t(m_home[v])] = 1;
  m_crackDrawn.assign(size_t(fragments), 0);
  std::vector<uint8_t> asked(size_t(fragments), 0);
  for (size_t n = 0; n < nn; ++n) {
    const size_t f = size_t(nodeFragment[n]);
    if (hasRender[f] || asked[f] || !m_wholeTet[f]) continue;
    asked[f] = 1;  // the fragment's lowest node stands for it
    m_crackDrawn[f] = nodeInside(int32_t(n)) ? 1 : 0;
  }
  m_nodeFragment = nullptr;
  m_broken = nullptr;
  m_composed = false;
}

void EmbeddedSurface::splitAtJunctions() {
  const EmbeddedBinding& bd = *m_binding;
  const double* X = m_rest->positions.data();
  TripleLines lines;
  bool built = false;
  // The triple lines of the cells {w_k = max over the drawn nodes} (the labels): where all four
  // nodes are drawn, three fragments' cells meet on the segment from the centroid of a face whose
  // nodes are in three fragments to the tet centroid (crack_surface.h: corner cells); where one is
  // a chip, on the segment from the face of the other three to the chip's node, where all three
  // have weight 0; where two are, on the edge between the two chips, with the cells of every tet
  // around it. Only made when a cycle has two junctions or more.
  auto build = [&] {
    built = true;
    std::map<std::array<int32_t, 4>, int32_t> key;
    auto point = [&](std::array<int32_t, 4> k, Vec3 P) {
      auto [it, added] = key.emplace(k, int32_t(lines.point.size()));
      if (added) lines.point.push_back(P);
      return it->second;
    };
    auto segment = [&](int32_t a, int32_t b, Triple l) {
      lines.ends.insert(lines.ends.end(), {a, b});
      lines.labels.push_back(l);
    };
    std::map<std::pair<int32_t, int32_t>, std::map<int32_t, int32_t>> chipEdges;
    for (size_t t = 0; t < m_rest->tetCount(); ++t) {
      const int32_t* n = &m_rest->tets[4 * t];
      const unsigned drawn = drawnNodes(int32_t(t));
      const int count = std::popcount(drawn);
      int32_t f[4];
      for (int k = 0; k < 4; ++k) f[k] = m_nodeFragment[n[k]];
      if (count <= 2) {
        // One or two drawn nodes: every drawn node's weight is 0 on an edge between two chips,
        // so there their cells meet those of the other tets around the edge.
        for (int j = 0; j < 6; ++j) {
          const int a = kTetEdgeNodes[j][0], c = kTetEdgeNodes[j][1];
          if ((drawn >> a & 1u) || (drawn >> c & 1u)) continue;
          auto& around = chipEdges[{std::min(n[a], n[c]), std::max(n[a], n[c])}];
          for (int k = 0; k < 4; ++k)
            if (drawn >> k & 1u) around.emplace(f[k], int32_t(t));
        }
        continue;
      }
      for (int l = 0; l < 4; ++l) {
        const int* c = kTetFaces[l];
        if ((drawn >> l & 1u) && count == 3) continue;  // only the face opposite the chip
        if (f[c[0]] == f[c[1]] || f[c[1]] == f[c[2]] || f[c[2]] == f[c[0]]) continue;
        const Triple face = sorted(n[c[0]], n[c[1]], n[c[2]]);
        const int32_t a = point({0, face[0], face[1], face[2]},
                                (1.0 / 3) * (load(X, size_t(face[0])) + load(X, size_t(face[1])) +
                                             load(X, size_t(face[2]))));
        const int32_t b = count == 4 ? point({1, int32_t(t), 0, 0},
                                             0.25 * (load(X, size_t(n[0])) + load(X, size_t(n[1])) +
                                                     load(X, size_t(n[2])) + load(X, size_t(n[3]))))
                                     : point({2, n[l], 0, 0}, load(X, size_t(n[l])));
        segment(a, b, sorted(f[c[0]], f[c[1]], f[c[2]]));
        for (int q = 0; q < 3; ++q)
          for (int32_t v : {a, b}) lines.tetOf.emplace(std::pair{v, f[c[q]]}, int32_t(t));
      }
    }
    // An edge between two chips around which three fragments or more draw cells: a segment for
    // every three of them.
    for (const auto& [edge, around] : chipEdges) {
      if (around.size() < 3) continue;
      const int32_t a = point({2, edge.first, 0, 0}, load(X, size_t(edge.first)));
      const int32_t b = point({2, edge.second, 0, 0}, load(X, size_t(edge.second)));
      for (auto p = around.begin(); p != around.end(); ++p)
        for (auto q = std::next(p); q != around.end(); ++q)
          for (auto r = std::next(q); r != around.end(); ++r)
            segment(a, b, Triple{p->first, q->first, r->first});
      for (const auto& [fragment, t] : around)
        for (int32_t v : {a, b}) lines.tetOf.emplace(std::pair{v, fragment}, t);
    }
    const size_t np = lines.point.size(), ns = lines.labels.size();
    lines.start.assign(np + 1, 0);
    for (int32_t v : lines.ends) ++lines.start[size_t(v) + 1];
    for (size_t v = 0; v < np; ++v) lines.start[v + 1] += lines.start[v];
    lines.segments.resize(2 * ns);
    std::vector<int32_t> fill(lines.start.begin(), lines.start.end() - 1);
    for (size_t s = 0; s < ns; ++s)
      for (int e = 0; e < 2; ++e) {
        const int32_t v = lines.ends[2 * s + size_t(e)];
        lines.segments[size_t(fill[size_t(v)]++)] = int32_t(s);
        lines.onLine[lines.labels[s]].push_back(v);
      }
    lines.dist.assign(np, HUGE_VAL);
    lines.from.assign(np, -1);
    lines.via.assign(np, -1);
  };
  auto has = [](const Triple& l, int32_t f) { return l[0] == f || l[1] == f || l[2] == f; };
  // The point of the triple line through junction j (a render triangle's centroid) nearest to
  // it, on a line of the triangle's three fragments, which must include f and g; -1 when none is
  // within two mean tet edges.
  auto labelsOf = [&](uint32_t j) {
    const uint32_t* id = &bd.indices[3 * size_t(m_vJunction[j])];
    return sorted(m_home[id[0]], m_home[id[1]], m_home[id[2]]);
  };
  auto entry = [&](uint32_t j, int32_t f, int32_t g) {
    const Triple l = labelsOf(j);
    int32_t best = -1;
    const auto it = lines.onLine.find(l);
    if (!has(l, f) || !has(l, g) || it == lines.onLine.end()) return best;
    const Vec3 P = load(m_vRest.data(), j);
    double bestDist = 2 * m_meanEdge;
    for (int32_t v : it->second) {
      const double d = norm(lines.point[size_t(v)] - P);
      if (d < bestDist) {
        bestDist = d;
        best = v;
      }
    }
    return best;
  };
  // The shortest path (rest length) from point a to point b along the lines that bound f's and
  // g's cells, into `out` (a first); whether it runs along lines of the three fragments `plain`
  // alone. Searched from the lower of the two, so both fragments get the same points.
  auto path = [&](int32_t a, int32_t b, int32_t f, int32_t g, const Triple& plain,
                  std::vector<int32_t>& out, bool& alongPlain) {
    out.clear();
    const bool flip = a > b;
    if (flip) std::swap(a, b);
    for (int32_t v : lines.touched) lines.dist[size_t(v)] = HUGE_VAL;
    lines.touched.assign(1, a);
    using Item = std::pair<double, int32_t>;
    std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
    lines.dist[size_t(a)] = 0;
    lines.from[size_t(a)] = -1;
    queue.push({0.0, a});
    while (!queue.empty()) {
      const auto [d, v] = queue.top();
      queue.pop();
      if (v == b) break;
      if (d > lines.dist[size_t(v)]) continue;
      for (int32_t i = lines.start[size_t(v)]; i < lines.start[size_t(v) + 1]; ++i) {
        const size_t s = size_t(lines.segments[size_t(i)]);
        if (!has(lines.labels[s], f) || !has(lines.labels[s], g)) continue;
        const int32_t w = lines.ends[2 * s] == v ? lines.ends[2 * s + 1] : lines.ends[2 * s];
        const double dw = d + norm(lines.point[size_t(w)] - lines.point[size_t(v)]);
        if (dw >= lines.dist[size_t(w)]) continue;
        if (lines.dist[size_t(w)] == HUGE_VAL) lines.touched.push_back(w);
        lines.dist[size_t(w)] = dw;
        lines.from[size_t(w)] = v;
        lines.via[size_t(w)] = int32_t(s);
        queue.push({dw, w});
      }
    }
    if (lines.dist[size_t(b)] == HUGE_VAL) return false;
    alongPlain = true;
    for (int32_t v = b; v >= 0; v = lines.from[size_t(v)]) {
      out.push_back(v);
      if (v != a) alongPlain = alongPlain && lines.labels[size_t(lines.via[size_t(v)])] == plain;
    }
    if (!flip) std::reverse(out.begin(), out.end());
    return true;
  };

  // Per cycle with two junction points or more: its junction offsets, each run's neighbour key
  // and closing path (CSR), and whether all its runs have one.
  struct Cycle {
    int32_t begin = 0, end = 0, fragment = 0;
    std::vector<int32_t> at, closing, closingStart{0};
    std::vector<std::array<int32_t, 4>> keys;  // per run: (fragments, junction triangles)
    bool complete = true;                      // every run has a path
    bool chords = false;                       // a run is closed by its chord
  };
  std::vector<Cycle> cycles;
  std::vector<int32_t> found;
  const size_t ncap = m_capStart.size() - 1;
  for (size_t c = 0; c < ncap; ++c) {
    Cycle cy;
    cy.begin = m_capStart[c];
    cy.end = m_capStart[c + 1];
    cy.fragment = m_vFragment[size_t(m_capRim[size_t(cy.begin)])];
    const int32_t n = cy.end - cy.begin;
    for (int32_t k = cy.begin; k < cy.end; ++k)
      if (m_vJunction[size_t(m_capRim[size_t(k)])] >= 0) cy.at.push_back(k - cy.begin);
    if (cy.at.size() >= 2) {
      if (!built) build();
      const int32_t f = cy.fragment;
      auto copyAt = [&](int32_t k) { return m_capRim[size_t(cy.begin + k % n)]; };
      for (size_t j = 0; j < cy.at.size(); ++j) {
        const int32_t from = cy.at[j], to = j + 1 < cy.at.size() ? cy.at[j + 1] : cy.at[0] + n;
        // The run's neighbour: the other fragment of its cut points, when they agree.
        int32_t g = -2;
        for (int32_t k = from + 1; k < to; ++k) {
          const int32_t across = m_vAcross[size_t(copyAt(k))];
          if (across >= 0) g = g == -2 || g == across ? across : -1;
        }
        const uint32_t ja = uint32_t(copyAt(from)), jb = uint32_t(copyAt(to));
        const int32_t ta = m_vJunction[ja], tb = m_vJunction[jb];
        cy.keys.push_back({std::min(f, g), std::max(f, g), std::min(ta, tb), std::max(ta, tb)});
        const int32_t ea = g >= 0 ? entry(ja, f, g) : -1, eb = g >= 0 ? entry(jb, f, g) : -1;
        const Triple la = labelsOf(ja);
        bool plain = false;
        if (ea >= 0 && eb >= 0 && path(eb, ea, f, g, la, found, plain)) {
          // A path along one triple line between two junctions of the same three fragments is
          // closed by the chord, as all three fragments' runs there are: it encloses no fourth.
          if (!(plain && la == labelsOf(jb)))
            cy.closing.insert(cy.closing.end(), found.begin(), found.end());
        } else {
          cy.complete = false;
        }
        cy.closingStart.push_back(int32_t(cy.closing.size()));
      }
    }
    cycles.push_back(std::move(cy));
  }
  // A run is closed by its path only when both cycles that hold it (the same fragments and
  // junction triangles) have a path for every run, so the two caps stay the same fan reversed;
  // other runs are closed by their chords. Not carried further: when a cycle with a run without
  // a path also sent the cycles across its runs to chords, and theirs, most cycles of a
  // shattered body were reached (four blades through a cube: 10 of 54 runs without a path, all
  // 12 cycles closed by chords).
  std::map<std::array<int32_t, 4>, std::pair<int, int>> runs;  // key -> (runs, in complete cycles)
  for (const Cycle& cy : cycles)
    for (const auto& k : cy.keys) {
      auto& r = runs[k];
      ++r.first;
      r.second += cy.complete ? 1 : 0;
    }
  std::vector<int32_t> kept, keptStart;
  for (Cycle& cy : cycles) {
    if (cy.at.size() < 2) continue;
    kept.clear();
    keptStart.assign(1, 0);
    for (size_t j = 0; j < cy.keys.size(); ++j) {
      const auto& k = cy.keys[j];
      if (k[0] >= 0 && runs[k].first == 2 && runs[k].second == 2)
        kept.insert(kept.end(), cy.closing.begin() + cy.closingStart[j],
                    cy.closing.begin() + cy.closingStart[j + 1]);
      else
        cy.chords = true;
      keptStart.push_back(int32_t(kept.size()));
    }
    cy.closing.swap(kept);
    cy.closingStart.swap(keptStart);
  }

  // Runs closed by chords leave the polygon of their junction points, whose flat cap cuts off the
  // fragment's cells behind it (on the shattered bunny, such polygons of the pieces bounded the
  // 8.5 % of its volume that no piece covered). The polygon is closed instead by a cone to
  // an apex that is a node of the fragment, so it moves with it: among the fragment's nodes (not
  // chips given to it) beyond the polygon (on its cap's outer side) and within its radius r of
  // its centroid c, the one nearest to c + r/2 n (n: the cap's unit normal); the flat cap where
  // there is none. The radius and half of it were measured (docs/validation.md).
  std::vector<int32_t> fragmentStart, fragmentNodes;
  auto coneApex = [&](const int64_t* loop, int32_t count, int32_t f, Vec3& normal) -> int32_t {
    if (fragmentStart.empty()) {
      // The nodes of each fragment (CSR), made when first needed.
      const size_t nn = m_rest->nodeCount();
      int32_t fragments = 0;
      for (size_t a = 0; a < nn; ++a) fragments = std::max(fragments, m_nodeFragment[a] + 1);
      fragmentStart.assign(size_t(fragments) + 1, 0);
      for (size_t a = 0; a < nn; ++a)
        if (!m_chipNode[a]) ++fragmentStart[size_t(m_nodeFragment[a]) + 1];
      for (int32_t g = 0; g < fragments; ++g)
        fragmentStart[size_t(g) + 1] += fragmentStart[size_t(g)];
      fragmentNodes.resize(size_t(fragmentStart.back()));
      std::vector<int32_t> fill(fragmentStart.begin(), fragmentStart.end() - 1);
      for (size_t a = 0; a < nn; ++a)
        if (!m_chipNode[a]) fragmentNodes[size_t(fill[size_t(m_nodeFragment[a])]++)] = int32_t(a);
    }
    Vec3 c{};
    for (int32_t k = 0; k < count; ++k) c += load(m_vRest.data(), size_t(loop[k]));
    c = (1.0 / double(count)) * c;
    Vec3 area{};
    double radius = 0;
    for (int32_t k = 0; k < count; ++k) {
      const Vec3 p = load(m_vRest.data(), size_t(loop[k]));
      area += cross(load(m_vRest.data(), size_t(loop[(k + 1) % count])) - c, p - c);
      radius = std::max(radius, norm(p - c));
    }
    if (!(norm(area) > 0)) return -1;
    normal = (1 / norm(area)) * area;
    const Vec3 target = c + (0.5 * radius) * normal;
    int32_t best = -1;
    double bestDist = HUGE_VAL;
    for (int32_t i = fragmentStart[size_t(f)]; i < fragmentStart[size_t(f) + 1]; ++i) {
      const int32_t a = fragmentNodes[size_t(i)];
      const Vec3 d = load(X, size_t(a)) - c;
      if (dot(d, normal) <= 0 || norm(d) > radius) continue;
      const double dist = norm(load(X, size_t(a)) - target);
      if (dist < bestDist) {
        bestDist = dist;
        best = a;
      }
    }
    return best;
  };

  // Caps are first written with line points as -(point + 1), checked, then given copies.
  std::vector<int32_t> start{0}, rim, capsStart;
  std::vector<int64_t> caps, sequence, stack;
  std::map<int64_t, size_t> onStack;
  std::map<std::pair<int64_t, int64_t>, int> edges;
  std::map<int32_t, uint32_t> made;
  std::vector<int64_t> ids;
  for (Cycle& cy : cycles) {
    const int32_t b = cy.begin, e = cy.end, n = e - b;
    const std::vector<int32_t>& at = cy.at;
    if (at.size() < 2) {
      rim.insert(rim.end(), m_capRim.begin() + b, m_capRim.begin() + e);
      start.push_back(int32_t(rim.size()));
      continue;
    }
    auto copyAt = [&](int32_t k) { return m_capRim[size_t(b + k % n)]; };
    const int32_t f = cy.fragment;
    const size_t runCount = at.size();
    // Attempt 0 closes the runs as chosen above, attempt 1 (a cycle whose caps would not close)
    // each run by the chord between its junction points.
    for (int attempt = 0; attempt < 2; ++attempt) {
      if (attempt == 1) {
        cy.closing.clear();
        cy.closingStart.assign(runCount + 1, 0);
      }
      const std::vector<int32_t>& closing = cy.closing;
      const std::vector<int32_t>& closingStart = cy.closingStart;
      // Each run, from its junction point to the next, back along its closing path; then what
      // the paths leave, walked from the junction points back along each path and split into
      // loops where it comes back to a point (a path there and back encloses nothing).
      caps.clear();
      capsStart.assign(1, 0);
      sequence.clear();
      for (size_t j = 0; j < runCount; ++j) {
        const int32_t from = at[j], to = j + 1 < runCount ? at[j + 1] : at[0] + n;
        for (int32_t k = from; k <= to; ++k) caps.push_back(copyAt(k));
        for (int32_t i = closingStart[j]; i < closingStart[j + 1]; ++i)
          caps.push_back(-int64_t(closing[size_t(i)]) - 1);
        capsStart.push_back(int32_t(caps.size()));
        sequence.push_back(copyAt(from));
        for (int32_t i = closingStart[j + 1] - 1; i >= closingStart[j]; --i)
          sequence.push_back(-int64_t(closing[size_t(i)]) - 1);
      }
      stack.clear();
      onStack.clear();
      auto loop = [&](size_t from) {
        if (stack.size() - from >= 3) {
          caps.insert(caps.end(), stack.begin() + ptrdiff_t(from), stack.end());
          capsStart.push_back(int32_t(caps.size()));
        }
        for (size_t k = from + 1; k < stack.size(); ++k) onStack.erase(stack[k]);
        stack.resize(from + 1);
      };
      for (int64_t v : sequence) {
        const auto it = onStack.find(v);
        if (it != onStack.end()) {
          loop(it->second);
        } else {
          onStack.emplace(v, stack.size());
          stack.push_back(v);
        }
      }
      loop(0);
      // Closed: the cycle's own edges once, in its direction; every other edge once each way.
      edges.clear();
      for (size_t q = 0; q + 1 < capsStart.size(); ++q)
        for (int32_t k = capsStart[q]; k < capsStart[q + 1]; ++k) {
          const int32_t next = k + 1 < capsStart[q + 1] ? k + 1 : capsStart[q];
          ++edges[{caps[size_t(k)], caps[size_t(next)]}];
        }
      bool closed = true;
      for (int32_t k = 0; k < n && closed; ++k) {
        const int64_t u = copyAt(k), v = copyAt(k + 1);
        closed = edges[{u, v}] == 1 && !edges.count({v, u});
        edges.erase({u, v});
      }
      for (const auto& [uv, count] : edges) {
        const auto back = edges.find({uv.second, uv.first});
        closed = closed && uv.first != uv.second && count == 1 && back != edges.end() &&
                 back->second == 1;
      }
      if (!closed && attempt == 0) continue;
      // Copies of the line points for this cycle's fragment, bound in a tet of one of their
      // segments that holds a node of it, following that node's group.
      made.clear();
      const Vec3 normal = load(m_vRestNormal.data(), size_t(copyAt(at[0])));
      const float uv[2] = {0, 0};
      for (size_t q = 0; q + 1 < capsStart.size(); ++q) {
        ids.clear();
        for (int32_t k = capsStart[q]; k < capsStart[q + 1]; ++k) {
          const int64_t v = caps[size_t(k)];
          if (v >= 0) {
            ids.push_back(v);
            continue;
          }
          const int32_t p = int32_t(-v - 1);
          auto [it, added] = made.emplace(p, 0u);
          if (added) {
            const int32_t t = lines.tetOf.at({p, f});
            const int32_t* nd = &m_rest->tets[4 * size_t(t)];
            const Vec3 P = lines.point[size_t(p)];
            double w[4];
            barycentric(m_restInverse[t], load(X, size_t(nd[0])), P, w);
            unsigned mine = 0;
            for (int j = 0; j < 4; ++j) mine |= m_nodeFragment[nd[j]] == f ? 1u << j : 0u;
            if (mine & drawnNodes(t)) mine &= drawnNodes(t);
            const int strong = strongest(w, mine);
            it->second = addCopy(-1, t, w, component(strong, joinedMask(t)), f, P, normal, uv);
          }
          ids.push_back(int64_t(it->second));
        }
        // With a run closed by its chord, the loops after the runs' caps hold the polygon of
        // junction points: each edge of one gets a triangle to the apex, a cap of three rim
        // vertices (centred on its own centroid, so flat). Such a cycle's loops along paths, faces
        // shared with a fourth fragment, get cones too, which the fourth's caps need not match
        // (measured with the rest: docs/validation.md). Without, those faces are capped flat by
        // both.
        Vec3 n{};
        const int32_t count = int32_t(ids.size());
        const int32_t apex =
            (attempt == 1 || cy.chords) && q >= runCount ? coneApex(ids.data(), count, f, n) : -1;
        if (apex >= 0) {
          makeNodeTets();
          const int32_t t = m_nodeTet[size_t(apex)];
          const int32_t* nd = &m_rest->tets[4 * size_t(t)];
          const Vec3 P = load(X, size_t(apex));
          double w[4];
          barycentric(m_restInverse[t], load(X, size_t(nd[0])), P, w);
          int local = 0;
          for (int j = 0; j < 4; ++j) local = nd[j] == apex ? j : local;
          const int32_t top =
              int32_t(addCopy(-1, t, w, component(local, joinedMask(t)), f, P, n, uv));
          for (int32_t k = 0; k < count; ++k) {
            rim.insert(rim.end(),
                       {int32_t(ids[size_t(k)]), int32_t(ids[size_t((k + 1) % count)]), top});
            start.push_back(int32_t(rim.size()));
          }
          continue;
        }
        for (int64_t v : ids) rim.push_back(int32_t(v));
        start.push_back(int32_t(rim.size()));
      }
      break;
    }
  }
  m_capStart.swap(start);
  m_capRim.swap(rim);
}

void EmbeddedSurface::compose(const CrackSurface& crack) {
  const uint32_t ne = uint32_t(m_vTet.size()), ncap = capCount();
  const std::span<const uint32_t> ci = crack.indices();
  const std::span<const uint8_t> flags = crack.crackFlags();
  const std::span<const int32_t> crackFragment = crack.vertexFragment();
  m_crackMap.assign(crack.vertexCount(), -1);
  m_crackFrom.clear();
  m_indices.assign(m_renderIndices.begin(), m_renderIndices.end());
  m_triCrack.assign(m_renderIndices.size() / 3, 0);
  m_triMaterial.assign(m_renderMaterial.begin(), m_renderMaterial.end());
  const bool materials = !m_binding->material.empty();
  for (uint32_t c = 0; c < ncap; ++c) {
    const int32_t b = m_capStart[c], e = m_capStart[c + 1];
    for (int32_t k = b; k < e; ++k) {
      const int32_t next = k + 1 < e ? k + 1 : b;
      m_indices.insert(m_indices.end(),
                       {ne + c, uint32_t(m_capRim[size_t(next)]), uint32_t(m_capRim[size_t(k)])});
      m_triCrack.push_back(1);
      if (materials) m_triMaterial.push_back(kInteriorMaterial);
    }
  }
  for (size_t t = 0; t < flags.size(); ++t) {
    const size_t f = size_t(crackFragment[ci[3 * t]]);
    if (f >= m_crackDrawn.size() || !m_crackDrawn[f]) continue;
    for (int c = 0; c < 3; ++c) {
      const uint32_t cv = ci[3 * t + size_t(c)];
      if (m_crackMap[cv] < 0) {
        m_crackMap[cv] = int32_t(ne + ncap + m_crackFrom.size());
        m_crackFrom.push_back(int32_t(cv));
      }
      m_indices.push_back(uint32_t(m_crackMap[cv]));
    }
    m_triCrack.push_back(flags[t]);
    // A piece drawn with its tet faces has no artist's triangle to take a material from: its
    // outer faces show material 0.
    if (materials) m_triMaterial.push_back(flags[t] ? kInteriorMaterial : uint16_t(0));
  }
  const size_t nv = ne + ncap + m_crackFrom.size();
  m_vertexNode.assign(m_vNode.begin(), m_vNode.end());
  m_vertexFragment.assign(m_vFragment.begin(), m_vFragment.end());
  for (uint32_t c = 0; c < ncap; ++c) {
    // A centre goes with the node of its cap's first rim vertex.
    const size_t r = size_t(m_capRim[size_t(m_capStart[c])]);
    m_vertexNode.push_back(m_vNode[r]);
    m_vertexFragment.push_back(m_vFragment[r]);
  }
  for (int32_t cv : m_crackFrom) {
    m_vertexNode.push_back(crack.vertexNode()[size_t(cv)]);
    m_vertexFragment.push_back(crack.vertexFragment()[size_t(cv)]);
  }
  m_uv.clear();
  if (!m_binding->uv.empty()) {
    m_uv.assign(2 * nv, 0.0f);
    std::copy(m_vUv.begin(), m_vUv.end(), m_uv.begin());
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
  const int32_t ne = int32_t(m_vTet.size()), ncap = int32_t(capCount()),
                nc = int32_t(m_crackFrom.size());
  exec.run(ne, 256,
           EmbeddedVertexStage{x, m_rest->positions.data(), m_rest->tets.data(), m_restInverse,
                               m_vTet.data(), m_vWeight.data(), m_vGroup.data(), m_vRest.data(),
                               m_vRestNormal.data(), crack.nodeFrame().data(),
                               crack.frameMaps().data(), m_positions.data(), m_normals.data()});
  exec.run(ncap, 64,
           CapCenterStage{m_capStart.data(), m_capRim.data(), m_vSource.data(), m_vSeparated.data(),
                          ne, m_positions.data(), m_normals.data()});
  const size_t off = 3 * size_t(ne + ncap);
  exec.run(nc, 512,
           GatherVec3Stage{crack.positionsDouble().data(), m_crackFrom.data(),
                           m_positions.data() + off});
  exec.run(
      nc, 512,
      GatherVec3Stage{crack.normalsDouble().data(), m_crackFrom.data(), m_normals.data() + off});
  const int32_t n3 = int32_t(m_positions.size());
  exec.run(n3, 2048, ToFloatStage{m_positions.data(), m_positionsF.data()});
  exec.run(n3, 2048, ToFloatStage{m_normals.data(), m_normalsF.data()});
}

}  // namespace gf::detail
