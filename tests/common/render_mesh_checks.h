// Checks on drawn surfaces shared by the render-mesh tests: a welded box surface to embed, the
// per-fragment closure (each edge used once in each direction) and enclosed volume, the vertex
// pairs across a crack and the stretch of render triangles, and the brittle bar they shatter.
#pragma once

#include <graphfrac/world.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <map>
#include <span>
#include <tuple>
#include <vector>

#include "common/sim_helpers.h"

namespace gf::test {

// The welded surface of the lattice [0, n_x] x [0, n_y] x [0, n_z] scaled to the box
// [lo, lo + size], outward counter-clockwise, with normals (p - centre) / |p - centre| (any
// unit field will do; it tests the normal map, not the mesh).
inline RenderMesh boxSurface(glm::dvec3 lo, glm::dvec3 size, int nx, int ny, int nz) {
  RenderMesh m;
  const int n[3] = {nx, ny, nz};
  std::map<std::tuple<int, int, int>, uint32_t> ids;
  auto vertex = [&](int i, int j, int k) {
    auto [it, added] = ids.emplace(std::make_tuple(i, j, k), uint32_t(ids.size()));
    if (added) {
      const glm::dvec3 p = lo + size * glm::dvec3(double(i) / nx, double(j) / ny, double(k) / nz);
      const glm::dvec3 d = glm::normalize(p - (lo + 0.5 * size));
      m.positions.insert(m.positions.end(), {p.x, p.y, p.z});
      m.normals.insert(m.normals.end(), {float(d.x), float(d.y), float(d.z)});
      m.uvs.insert(m.uvs.end(), {float(p.x), float(p.y + p.z)});
    }
    return it->second;
  };
  for (int d = 0; d < 3; ++d) {
    const int u = (d + 1) % 3, v = (d + 2) % 3;  // e_u x e_v = e_d
    for (int side = 0; side < 2; ++side)
      for (int a = 0; a < n[u]; ++a)
        for (int b = 0; b < n[v]; ++b) {
          uint32_t q[4];
          const int du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
          for (int c = 0; c < 4; ++c) {
            int ijk[3];
            ijk[d] = side * n[d];
            ijk[u] = a + du[c];
            ijk[v] = b + dv[c];
            q[c] = vertex(ijk[0], ijk[1], ijk[2]);
          }
          if (side == 1)
            m.indices.insert(m.indices.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
          else
            m.indices.insert(m.indices.end(), {q[0], q[2], q[1], q[0], q[3], q[2]});
        }
  }
  return m;
}

inline glm::dvec3 at(std::span<const double> p, size_t i) {
  return {p[3 * i], p[3 * i + 1], p[3 * i + 2]};
}

// Per fragment of a drawn surface: triangles, render triangles, and undirected edges not used
// exactly once in each direction by that fragment's triangles (0: closed and 2-manifold with
// consistent orientation).
struct FragmentClosure {
  int triangles = 0, renderTriangles = 0, openEdges = 0;
};
inline std::map<int32_t, FragmentClosure> closure(const SurfaceView& s) {
  std::map<int32_t, FragmentClosure> out;
  std::map<int32_t, std::map<std::pair<uint32_t, uint32_t>, int>> edges;  // +1 a<b, -1 a>b
  std::map<int32_t, std::map<std::pair<uint32_t, uint32_t>, int>> uses;
  for (size_t t = 0; t < s.indices.size() / 3; ++t) {
    const uint32_t* id = &s.indices[3 * t];
    const int32_t f = s.vertexFragment[id[0]];
    FragmentClosure& c = out[f];
    ++c.triangles;
    if (!s.crackMask[t]) ++c.renderTriangles;
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = id[k], b = id[(k + 1) % 3];
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      edges[f][key] += a < b ? 1 : -1;
      ++uses[f][key];
    }
  }
  for (auto& [f, e] : edges)
    for (auto& [key, balance] : e)
      if (balance != 0 || uses[f][key] != 2) ++out[f].openEdges;
  return out;
}

// Signed volume enclosed by the triangles of each fragment (divergence theorem; the origin's
// choice cancels on a closed surface).
inline std::map<int32_t, double> enclosedVolumes(const SurfaceView& s) {
  std::map<int32_t, double> out;
  for (size_t t = 0; t < s.indices.size() / 3; ++t) {
    const uint32_t* id = &s.indices[3 * t];
    glm::dvec3 p[3];
    for (int k = 0; k < 3; ++k)
      p[k] = glm::dvec3(s.positions[3 * size_t(id[k])], s.positions[3 * size_t(id[k]) + 1],
                        s.positions[3 * size_t(id[k]) + 2]);
    out[s.vertexFragment[id[0]]] += glm::dot(p[0], glm::cross(p[1], p[2])) / 6;
  }
  return out;
}

// The brittle bar of Fracture.MoreBrittleRegionsMakeMoreFragments (fig 4.19) with a closed
// render mesh on its surface, at a resolution unrelated to the tets' (1/60 m against 1/40 m).
inline BodyDef brittleBar() {
  BodyDef def;
  def.mesh = gen::box(1.0, 0.1, 0.1, 40, 4, 4);
  def.material = Material::stableNeoHookean(1e7, 0.2, 2500);
  def.fracture.enabled = true;
  def.fracture.strength = 1e5;
  def.fracture.brittle = true;
  def.fracture.regions = 6;
  def.renderMesh = boxSurface(glm::dvec3(0), glm::dvec3(1, 0.1, 0.1), 60, 6, 6);
  Grip left, right;
  left.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
  right.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x > 1 - 1e-9; });
  left.velocity = glm::vec3(-0.05f, 0, 0);
  right.velocity = glm::vec3(0.05f, 0, 0);
  def.grips = {left, right};
  return def;
}

// Pulls the brittle bar apart for `steps` steps, asking for its surface every frame as a game
// would.
inline void shatter(World& world, BodyId id, int steps) {
  for (int s = 0; s < steps; ++s) {
    (void)world.step(1.0 / 60);
    (void)world.surface(id);
  }
}

inline glm::dvec3 pos(std::span<const float> p, size_t v) {
  return glm::dvec3(p[3 * v], p[3 * v + 1], p[3 * v + 2]);
}

// Drawn vertices that share a rest point and follow opposite sides of a crack (sideOf their
// nodes' rest positions differ), both nodes at or above minY: how many pairs, their widest gap
// in `opened`, and the largest difference between a gap and `truth` of the rest point.
struct CrackPairs {
  int pairs = 0;
  double widest = 0, worst = 0;
};
template <class Side, class Truth>
CrackPairs crackPairs(std::span<const float> restPos, const SurfaceView& opened,
                      std::span<const double> nodes, double minY, Side sideOf, Truth truth) {
  std::map<std::tuple<float, float, float>, std::vector<uint32_t>> byRest;
  for (uint32_t v = 0; v < restPos.size() / 3; ++v)
    byRest[{restPos[3 * v], restPos[3 * v + 1], restPos[3 * v + 2]}].push_back(v);
  CrackPairs r;
  for (const auto& [key, vs] : byRest)
    for (size_t i = 0; i < vs.size(); ++i)
      for (size_t j = i + 1; j < vs.size(); ++j) {
        const glm::dvec3 Na = at(nodes, size_t(opened.vertexNode[vs[i]]));
        const glm::dvec3 Nb = at(nodes, size_t(opened.vertexNode[vs[j]]));
        if (sideOf(Na) == sideOf(Nb) || std::min(Na.y, Nb.y) < minY) continue;
        const double gap = glm::length(pos(opened.positions, vs[i]) - pos(opened.positions, vs[j]));
        ++r.pairs;
        r.widest = std::max(r.widest, gap);
        r.worst = std::max(r.worst, std::abs(gap - truth(pos(restPos, vs[i]))));
      }
  return r;
}

// Render triangles (not crack faces) whose corners all lie above minY at rest: how many, and the
// largest change of an edge's length in `opened`.
inline std::pair<int, double> stretchAbove(std::span<const float> restPos,
                                           std::span<const uint32_t> restIdx,
                                           const SurfaceView& opened, double minY) {
  int above = 0;
  double stretch = 0;
  for (size_t t = 0; t < restIdx.size() / 3; ++t) {
    if (opened.crackMask[t]) continue;
    const uint32_t* id3 = &restIdx[3 * t];
    bool high = true;
    for (int k = 0; k < 3; ++k) high = high && restPos[3 * size_t(id3[k]) + 1] > minY;
    if (!high) continue;
    ++above;
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = id3[k], b = id3[(k + 1) % 3];
      stretch = std::max(stretch,
                         std::abs(glm::length(pos(opened.positions, a) - pos(opened.positions, b)) -
                                  glm::length(pos(restPos, a) - pos(restPos, b))));
    }
  }
  return {above, stretch};
}

// How the drawn fragments fill a box at rest, along rays parallel to x through a grid of
// (y, z) points (offsets chosen off the render lattices): per ray, each fragment's winding
// number from the signed crossings of its triangles; the box's volume covered by two or more
// fragments at once (caps that overlap) and by none (gaps between caps).
struct Coverage {
  double overlap = 0, gap = 0, volume = 0;
};
inline Coverage coverage(const SurfaceView& s, glm::dvec3 lo, glm::dvec3 hi, int rays) {
  Coverage out;
  const double dy = (hi.y - lo.y) / rays, dz = (hi.z - lo.z) / rays;
  struct Hit {
    double x;
    int32_t fragment;
    int sign;
  };
  std::vector<Hit> hits;
  std::map<int32_t, int> winding;
  for (int j = 0; j < rays; ++j)
    for (int k = 0; k < rays; ++k) {
      const double y = lo.y + (j + 0.5 + 0.0137) * dy, z = lo.z + (k + 0.5 - 0.0213) * dz;
      hits.clear();
      for (size_t t = 0; t < s.indices.size() / 3; ++t) {
        glm::dvec3 p[3];
        for (int c = 0; c < 3; ++c) p[c] = pos(s.positions, s.indices[3 * t + size_t(c)]);
        // The ray meets the triangle where its (y, z) projection holds (y, z).
        const double d =
            (p[1].y - p[0].y) * (p[2].z - p[0].z) - (p[2].y - p[0].y) * (p[1].z - p[0].z);
        if (d == 0) continue;
        const double b1 = ((y - p[0].y) * (p[2].z - p[0].z) - (p[2].y - p[0].y) * (z - p[0].z)) / d;
        const double b2 = ((p[1].y - p[0].y) * (z - p[0].z) - (y - p[0].y) * (p[1].z - p[0].z)) / d;
        if (b1 < 0 || b2 < 0 || b1 + b2 > 1) continue;
        const double x = p[0].x + b1 * (p[1].x - p[0].x) + b2 * (p[2].x - p[0].x);
        // d is the x component of the normal: outward along -x means the ray enters.
        hits.push_back({x, s.vertexFragment[s.indices[3 * t]], d < 0 ? 1 : -1});
      }
      std::sort(hits.begin(), hits.end(), [](const Hit& a, const Hit& b) { return a.x < b.x; });
      winding.clear();
      int inside = 0;
      double last = lo.x;
      auto account = [&](double to) {
        const double a = std::max(last, lo.x), b = std::min(to, hi.x);
        if (b > a) {
          if (inside >= 2) out.overlap += (b - a) * dy * dz;
          if (inside == 0) out.gap += (b - a) * dy * dz;
          if (inside >= 1) out.volume += (b - a) * dy * dz;
        }
        last = std::max(last, to);
      };
      for (const Hit& h : hits) {
        account(h.x);
        int& w = winding[h.fragment];
        inside -= w != 0 ? 1 : 0;
        w += h.sign;
        inside += w != 0 ? 1 : 0;
      }
      account(hi.x);
    }
  return out;
}

}  // namespace gf::test
