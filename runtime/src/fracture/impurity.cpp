#include "fracture/impurity.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <limits>
#include <queue>
#include <string>

#include "kernels/contact.h"
#include "kernels/impurity.h"
#include "mesh/mesh_internal.h"

namespace gf::detail {

namespace {

using V3 = glm::dvec3;

V3 node(const ImpurityRest& r, int32_t i) {
  return {r.positions[3 * i], r.positions[3 * i + 1], r.positions[3 * i + 2]};
}

double pointSegmentDistance(const V3& p, const V3& a, const V3& b) {
  const V3 ab = b - a;
  const double l2 = glm::dot(ab, ab);
  const double t = l2 > 0 ? std::clamp(glm::dot(p - a, ab) / l2, 0.0, 1.0) : 0.0;
  return glm::length(p - (a + t * ab));
}

// Depth under the surface of every node: Dijkstra over the edge graph from the boundary nodes
// (an upper bound of the straight distance, exact along straight runs of edges).
std::vector<double> nodeDepths(const EdgeGraph& g, const ImpurityRest& r,
                               const std::vector<int32_t>& faces) {
  std::vector<double> d(size_t(r.nodeCount), std::numeric_limits<double>::infinity());
  using Item = std::pair<double, int32_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> q;
  for (int32_t n : faces)
    if (d[size_t(n)] != 0) {
      d[size_t(n)] = 0;
      q.push({0, n});
    }
  while (!q.empty()) {
    const auto [dn, n] = q.top();
    q.pop();
    if (dn > d[size_t(n)]) continue;
    for (int32_t s = g.nodeEdgeStart[n]; s < g.nodeEdgeStart[n + 1]; ++s) {
      const int32_t e = g.nodeEdges[s];
      const int32_t m = g.edgeNodes[2 * e] == n ? g.edgeNodes[2 * e + 1] : g.edgeNodes[2 * e];
      const double dm = dn + glm::length(node(r, m) - node(r, n));
      if (dm < d[size_t(m)]) {
        d[size_t(m)] = dm;
        q.push({dm, m});
      }
    }
  }
  return d;
}

double orient(const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& c) {
  return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

// Crossing of segments ab and cd with half-open sides: a point exactly on the line counts as
// on its positive side, so of the edges that meet a stroke at a node only those on one side
// cross it (else the node would be cut loose), and an edge along a stroke does not cross it.
bool segmentsCross(const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& c,
                   const glm::dvec2& d) {
  const double d1 = orient(c, d, a), d2 = orient(c, d, b);
  const double d3 = orient(a, b, c), d4 = orient(a, b, d);
  return (d1 >= 0) != (d2 >= 0) && (d3 >= 0) != (d4 >= 0);
}

Result<std::vector<int32_t>> polylineEdges(const EdgeGraph& g, const ImpurityRest& r,
                                           const ImpurityMap& map) {
  const std::vector<int32_t> faces = boundaryFaces(r.tets, size_t(r.tetCount));
  const double tol = 0.5 * r.meanEdgeLength;
  for (size_t i = 0; i < map.points.size(); ++i) {
    const V3 p = map.points[i];
    double best = std::numeric_limits<double>::infinity();
    for (size_t f = 0; f < faces.size(); f += 3) {
      const V3 a = node(r, faces[f]), b = node(r, faces[f + 1]), c = node(r, faces[f + 2]);
      const Vec3 w = closestOnTriangle(Vec3{p.x, p.y, p.z}, Vec3{a.x, a.y, a.z},
                                       Vec3{b.x, b.y, b.z}, Vec3{c.x, c.y, c.z});
      best = std::min(best, glm::length(p - (w.x * a + w.y * b + w.z * c)));
    }
    if (!(best <= tol))
      return fail("points[", std::to_string(i), "]: ", std::to_string(best),
                  " m from the body's rest surface; a painted polyline must lie on it (within "
                  "half a mean edge length, ",
                  std::to_string(tol), " m)");
  }
  const std::vector<double> depth = nodeDepths(g, r, faces);
  std::vector<int32_t> out;
  const double half = 0.5 * map.width;
  for (int32_t e = 0; e < g.edgeCount; ++e) {
    const int32_t a = g.edgeNodes[2 * e], b = g.edgeNodes[2 * e + 1];
    const double t = 0.5 * (depth[size_t(a)] + depth[size_t(b)]);
    if (t > map.depth) continue;
    const V3 m = 0.5 * (node(r, a) + node(r, b));
    double dl = std::numeric_limits<double>::infinity();
    for (size_t i = 0; i + 1 < map.points.size(); ++i)
      dl = std::min(dl, pointSegmentDistance(m, map.points[i], map.points[i + 1]));
    // The band's cross-section is width x depth: the lateral offset is what remains of the
    // distance to the line once the depth is taken out.
    if (dl * dl - t * t <= half * half) out.push_back(e);
  }
  return out;
}

std::vector<int32_t> imageEdges(const EdgeGraph& g, const ImpurityRest& r, const ImpurityMap& map) {
  const glm::dquat q = glm::normalize(map.rotation);
  const glm::dquat qi = glm::conjugate(q);
  std::vector<glm::dvec2> uv(size_t(r.nodeCount));
  for (int32_t n = 0; n < r.nodeCount; ++n) {
    const V3 l = qi * (node(r, n) - map.origin) / map.scale;
    uv[size_t(n)] = {l.x, l.y};
  }
  // Segments bucketed on a grid over their bounding box, so each edge tests only its cells.
  const size_t ns = map.segments.size() / 2;
  glm::dvec2 lo(HUGE_VAL), hi(-HUGE_VAL);
  for (const glm::dvec2& p : map.segments) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  const int G = std::max(1, int(std::sqrt(double(ns))));
  const glm::dvec2 span = glm::max(hi - lo, glm::dvec2(1e-12));
  auto cellOf = [&](double v, int axis) {
    return std::clamp(int((v - lo[axis]) / span[axis] * G), 0, G - 1);
  };
  std::vector<std::vector<int32_t>> cells(size_t(G) * size_t(G));
  for (size_t s = 0; s < ns; ++s) {
    const glm::dvec2 a = map.segments[2 * s], b = map.segments[2 * s + 1];
    for (int y = cellOf(std::min(a.y, b.y), 1); y <= cellOf(std::max(a.y, b.y), 1); ++y)
      for (int x = cellOf(std::min(a.x, b.x), 0); x <= cellOf(std::max(a.x, b.x), 0); ++x)
        cells[size_t(y) * size_t(G) + size_t(x)].push_back(int32_t(s));
  }
  std::vector<int32_t> out;
  for (int32_t e = 0; e < g.edgeCount; ++e) {
    const glm::dvec2 a = uv[size_t(g.edgeNodes[2 * e])], b = uv[size_t(g.edgeNodes[2 * e + 1])];
    const glm::dvec2 elo = glm::min(a, b), ehi = glm::max(a, b);
    if (elo.x > hi.x || elo.y > hi.y || ehi.x < lo.x || ehi.y < lo.y) continue;
    bool hit = false;
    for (int y = cellOf(elo.y, 1); y <= cellOf(ehi.y, 1) && !hit; ++y)
      for (int x = cellOf(elo.x, 0); x <= cellOf(ehi.x, 0) && !hit; ++x)
        for (int32_t s : cells[size_t(y) * size_t(G) + size_t(x)])
          if (segmentsCross(a, b, map.segments[2 * size_t(s)], map.segments[2 * size_t(s) + 1])) {
            hit = true;
            break;
          }
    if (hit) out.push_back(e);
  }
  return out;
}

}  // namespace

void ImpurityField::init(const EdgeGraph& graph, const ImpuritySettings& settings,
                         const std::vector<double>& strength) {
  upgrade = settings.mode == ImpurityMode::Upgradation;
  randomGraph = settings.randomGraph;
  alpha.assign(size_t(graph.nodeCount), 0.0);
  if (settings.enabled && settings.sigma > 0)
    for (int32_t k = 0; k < graph.nodeCount; ++k)
      alpha[size_t(k)] = settings.noise == ImpurityNoise::Gaussian
                             ? impurityGaussian(settings.seed, k, settings.sigma)
                             : impurityUniform(settings.seed, k, settings.sigma);
  baseStrength = strength;
  restDegree.resize(size_t(graph.nodeCount));
  for (int32_t k = 0; k < graph.nodeCount; ++k)
    restDegree[size_t(k)] = graph.nodeEdgeStart[k + 1] - graph.nodeEdgeStart[k];
  degree = restDegree;
  pendingPrecut.clear();
}

double ImpurityField::effectiveStrength(const EdgeGraph& graph, int32_t e) const {
  if (!randomGraph) return baseStrength[size_t(e)];
  const int32_t i = graph.edgeNodes[2 * e], j = graph.edgeNodes[2 * e + 1];
  const double di = double(degree[size_t(i)]) / double(restDegree[size_t(i)]);
  const double dj = double(degree[size_t(j)]) / double(restDegree[size_t(j)]);
  return baseStrength[size_t(e)] *
         impurityStrengthFactor(di, dj, alpha[size_t(i)], alpha[size_t(j)], upgrade);
}

void ImpurityField::refreshAll(const EdgeGraph& graph, const uint8_t* broken,
                               std::vector<double>& strength) {
  for (int32_t e = 0; e < graph.edgeCount; ++e)
    if (!broken[e]) strength[size_t(e)] = effectiveStrength(graph, e);
}

void ImpurityField::onBreaks(const EdgeGraph& graph, const int32_t* edges, size_t count,
                             const uint8_t* broken, std::vector<double>& strength) {
  for (size_t b = 0; b < count; ++b) {
    --degree[size_t(graph.edgeNodes[2 * edges[b]])];
    --degree[size_t(graph.edgeNodes[2 * edges[b] + 1])];
  }
  if (!randomGraph) return;
  for (size_t b = 0; b < count; ++b)
    for (int side = 0; side < 2; ++side) {
      const int32_t n = graph.edgeNodes[2 * edges[b] + side];
      for (int32_t s = graph.nodeEdgeStart[n]; s < graph.nodeEdgeStart[n + 1]; ++s) {
        const int32_t e = graph.nodeEdges[s];
        if (!broken[e]) strength[size_t(e)] = effectiveStrength(graph, e);
      }
    }
}

Result<std::vector<int32_t>> ImpurityField::mapEdges(const EdgeGraph& graph,
                                                     const ImpurityRest& rest,
                                                     const ImpurityMap& map) {
  if (map.kind == ImpurityMap::Kind::Polyline) return polylineEdges(graph, rest, map);
  return imageEdges(graph, rest, map);
}

void ImpurityField::applyMap(const EdgeGraph& graph, const std::vector<int32_t>& edges,
                             double potency) {
  // More potent = weaker (sec 5.4); potency 0 is a sharp cut, so 1 / 0 = inf is wanted.
  const double a = 1.0 / potency;
  for (int32_t e : edges) {
    if (potency == 0) {
      pendingPrecut.push_back(e);
    } else {
      baseStrength[size_t(e)] *= potency;
    }
    for (int side = 0; side < 2; ++side) {
      double& an = alpha[size_t(graph.edgeNodes[2 * e + side])];
      if (!(std::fabs(an) >= a)) an = a;
    }
  }
  std::sort(pendingPrecut.begin(), pendingPrecut.end());
  pendingPrecut.erase(std::unique(pendingPrecut.begin(), pendingPrecut.end()), pendingPrecut.end());
}

}  // namespace gf::detail
