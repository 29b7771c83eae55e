#include "fracture/cutting.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <utility>

namespace gf::detail {

namespace {

struct Box {
  Vec3 lo{std::numeric_limits<double>::max(), std::numeric_limits<double>::max(),
          std::numeric_limits<double>::max()};
  Vec3 hi{-std::numeric_limits<double>::max(), -std::numeric_limits<double>::max(),
          -std::numeric_limits<double>::max()};
  void add(const Vec3& p) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], p[a]);
      hi[a] = std::max(hi[a], p[a]);
    }
  }
  bool empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
};

Vec3 transform(const BladePose& pose, const double* p) {
  return pose.rotation * Vec3{p[0], p[1], p[2]} + pose.translation;
}

bool samePose(const BladePose& a, const BladePose& b) {
  return std::memcmp(a.rotation.m, b.rotation.m, sizeof(a.rotation.m)) == 0 &&
         a.translation.x == b.translation.x && a.translation.y == b.translation.y &&
         a.translation.z == b.translation.z;
}

// Uniform grid over the domain; cells are cubes no finer than the target count allows.
struct Grid {
  Vec3 lo;
  double cell = 1;
  int32_t dims[3] = {1, 1, 1};
  int32_t coord(double v, int axis) const {
    const double c = std::floor((v - lo[axis]) / cell);
    if (!(c > 0)) return 0;
    return c >= double(dims[axis] - 1) ? dims[axis] - 1 : int32_t(c);
  }
  size_t index(int32_t x, int32_t y, int32_t z) const {
    return (size_t(z) * size_t(dims[1]) + size_t(y)) * size_t(dims[0]) + size_t(x);
  }
};

}  // namespace

bool segmentCrossesTriangle(const Vec3& a, const Vec3& b, const CutWorkspace::Triangle& tri,
                            double& s, double tolerance) {
  const double da = dot(tri.n, a - tri.p0), db = dot(tri.n, b - tri.p0);
  // Side rule: a point on the plane counts as the front side, so exactly one of two edges
  // meeting at a node on the blade can cross, and coplanar edges never do.
  if ((da >= 0) == (db >= 0)) return false;
  s = da / (da - db);
  const Vec3 q = a + s * (b - a);
  // Barycentric weights times |n|^2; inside when none is below -tolerance |n|^2, which also
  // closes the seams between a blade's adjacent triangles.
  const double limit = -tolerance * tri.nn;
  return dot(tri.n, cross(tri.p1 - q, tri.p2 - q)) >= limit &&
         dot(tri.n, cross(tri.p2 - q, tri.p0 - q)) >= limit &&
         dot(tri.n, cross(tri.p0 - q, tri.p1 - q)) >= limit;
}

Result<int32_t> cutEdges(const EdgeGraph& graph, const double* positions, const Blade& blade,
                         const BladePose& start, const BladePose& end, std::vector<uint8_t>& broken,
                         std::vector<EdgeBreak>& events, CutWorkspace& ws, JobSystem& jobs,
                         CutStats* stats) {
  if (broken.size() != size_t(graph.edgeCount))
    return fail("cutEdges: ", std::to_string(broken.size()), " broken flags for ",
                std::to_string(graph.edgeCount), " edges");
  const int32_t vertexCount = int32_t(blade.vertices.size() / 3);
  if (blade.triangles.size() % 3 != 0 || blade.vertices.size() % 3 != 0)
    return fail("Blade: vertices and triangles must come in triples");
  for (size_t i = 0; i < blade.vertices.size(); ++i)
    if (!std::isfinite(blade.vertices[i]))
      return fail("Blade.vertices[", std::to_string(i / 3), "]: non-finite coordinate");
  for (size_t i = 0; i < blade.triangles.size(); ++i)
    if (blade.triangles[i] < 0 || blade.triangles[i] >= vertexCount)
      return fail("Blade.triangles[", std::to_string(i / 3), "]: vertex ",
                  std::to_string(blade.triangles[i]), " out of range [0, ",
                  std::to_string(vertexCount), ")");

  // World triangles of the swept surface: end pose, start pose, swept blade edges.
  ws.triangles.clear();
  const auto addTriangle = [&](const Vec3& p0, const Vec3& p1, const Vec3& p2) {
    CutWorkspace::Triangle t{p0, p1, p2, cross(p1 - p0, p2 - p0), 0};
    t.nn = dot(t.n, t.n);
    const double scale =
        std::max({dot(p1 - p0, p1 - p0), dot(p2 - p0, p2 - p0), dot(p2 - p1, p2 - p1)});
    // Slivers (and the zero-area quads of edges moving along themselves) cut nothing.
    if (t.nn > 1e-24 * scale * scale && std::isfinite(t.nn)) ws.triangles.push_back(t);
  };
  const size_t triCount = blade.triangles.size() / 3;
  const int32_t* tv = blade.triangles.data();
  const double* bv = blade.vertices.data();
  for (size_t i = 0; i < triCount; ++i)
    addTriangle(transform(end, bv + 3 * tv[3 * i]), transform(end, bv + 3 * tv[3 * i + 1]),
                transform(end, bv + 3 * tv[3 * i + 2]));
  if (!samePose(start, end)) {
    for (size_t i = 0; i < triCount; ++i)
      addTriangle(transform(start, bv + 3 * tv[3 * i]), transform(start, bv + 3 * tv[3 * i + 1]),
                  transform(start, bv + 3 * tv[3 * i + 2]));
    // Unique blade edges as (min, max) pairs, sorted for a deterministic triangle order.
    ws.bladeEdges.clear();
    for (size_t i = 0; i < triCount; ++i)
      for (int k = 0; k < 3; ++k) {
        const int32_t a = tv[3 * i + k], b = tv[3 * i + (k + 1) % 3];
        ws.bladeEdges.push_back(std::min(a, b));
        ws.bladeEdges.push_back(std::max(a, b));
      }
    const size_t edgeCount = ws.bladeEdges.size() / 2;
    std::vector<std::pair<int32_t, int32_t>> pairs(edgeCount);
    for (size_t i = 0; i < edgeCount; ++i)
      pairs[i] = {ws.bladeEdges[2 * i], ws.bladeEdges[2 * i + 1]};
    std::sort(pairs.begin(), pairs.end());
    pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
    for (const auto& [a, b] : pairs) {
      // Quad a0 b0 b1 a1 as two triangles: approximates the bilinear patch of the swept edge.
      const Vec3 a0 = transform(start, bv + 3 * a), b0 = transform(start, bv + 3 * b);
      const Vec3 a1 = transform(end, bv + 3 * a), b1 = transform(end, bv + 3 * b);
      addTriangle(a0, b0, b1);
      addTriangle(a0, b1, a1);
    }
  }

  const int32_t edgeCount = graph.edgeCount;
  ws.hitSplit.assign(size_t(edgeCount), -1.0);
  ws.hitTriangle.assign(size_t(edgeCount), -1);
  if (stats) *stats = CutStats{int32_t(ws.triangles.size()), 0, 0, 0};
  if (ws.triangles.empty() || edgeCount == 0) return 0;

  // Domain: the blade's box clipped to the body's box, padded so touching counts.
  Box bladeBox, bodyBox, domain;
  for (const auto& t : ws.triangles) {
    bladeBox.add(t.p0);
    bladeBox.add(t.p1);
    bladeBox.add(t.p2);
  }
  for (int32_t v = 0; v < graph.nodeCount; ++v)
    bodyBox.add({positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]});
  double extent = 0;
  for (int a = 0; a < 3; ++a) {
    domain.lo[a] = std::max(bladeBox.lo[a], bodyBox.lo[a]);
    domain.hi[a] = std::min(bladeBox.hi[a], bodyBox.hi[a]);
    extent = std::max({extent, bladeBox.hi[a] - bladeBox.lo[a], bodyBox.hi[a] - bodyBox.lo[a]});
  }
  const double pad = 1e-9 * extent + 1e-300;
  for (int a = 0; a < 3; ++a) {
    domain.lo[a] -= pad;
    domain.hi[a] += pad;
  }
  if (domain.empty()) return 0;

  // Grid resolution: about 4 cells per triangle (at least 64, at most 2^20), cubic cells,
  // shrunk step by step while the count stays under the target.
  Grid grid;
  grid.lo = domain.lo;
  const double target = std::clamp(4.0 * double(ws.triangles.size()), 64.0, double(1 << 20));
  const auto dimsFor = [&](double cell, int32_t* dims) {
    double cells = 1;
    for (int a = 0; a < 3; ++a) {
      dims[a] = int32_t(std::floor((domain.hi[a] - domain.lo[a]) / cell)) + 1;
      cells *= double(dims[a]);
    }
    return cells;
  };
  double maxSide = 0;
  for (int a = 0; a < 3; ++a) maxSide = std::max(maxSide, domain.hi[a] - domain.lo[a]);
  grid.cell = maxSide;
  dimsFor(grid.cell, grid.dims);
  for (int it = 0; it < 200; ++it) {
    int32_t dims[3];
    if (dimsFor(grid.cell * 0.8, dims) > target) break;
    grid.cell *= 0.8;
    std::copy(dims, dims + 3, grid.dims);
  }
  const size_t cellCount = size_t(grid.dims[0]) * size_t(grid.dims[1]) * size_t(grid.dims[2]);

  // Triangles into the cells their plane crosses within their box (count, then fill).
  ws.cellStart.assign(cellCount + 1, 0);
  const double half = 0.5 * grid.cell;
  for (int pass = 0; pass < 2; ++pass) {
    if (pass == 1) {
      for (size_t c = 0; c < cellCount; ++c) ws.cellStart[c + 1] += ws.cellStart[c];
      ws.cellTriangles.resize(size_t(ws.cellStart[cellCount]));
    }
    std::vector<int32_t> fill;
    if (pass == 1) fill.assign(ws.cellStart.begin(), ws.cellStart.end() - 1);
    for (size_t i = 0; i < ws.triangles.size(); ++i) {
      const auto& t = ws.triangles[i];
      Box tb;
      tb.add(t.p0);
      tb.add(t.p1);
      tb.add(t.p2);
      int32_t lo[3], hi[3];
      bool outside = false;
      for (int a = 0; a < 3; ++a) {
        if (tb.hi[a] < domain.lo[a] || tb.lo[a] > domain.hi[a]) outside = true;
        lo[a] = grid.coord(tb.lo[a] - pad, a);
        hi[a] = grid.coord(tb.hi[a] + pad, a);
      }
      if (outside) continue;
      const double reach = (std::fabs(t.n.x) + std::fabs(t.n.y) + std::fabs(t.n.z)) * half;
      for (int32_t z = lo[2]; z <= hi[2]; ++z)
        for (int32_t y = lo[1]; y <= hi[1]; ++y)
          for (int32_t x = lo[0]; x <= hi[0]; ++x) {
            const Vec3 centre{grid.lo.x + (x + 0.5) * grid.cell, grid.lo.y + (y + 0.5) * grid.cell,
                              grid.lo.z + (z + 0.5) * grid.cell};
            // Plane-box overlap (conservative by 1e-6 of the reach).
            if (std::fabs(dot(t.n, centre - t.p0)) > reach * (1 + 1e-6)) continue;
            const size_t c = grid.index(x, y, z);
            if (pass == 0) {
              ++ws.cellStart[c + 1];
            } else {
              ws.cellTriangles[size_t(fill[c]++)] = int32_t(i);
            }
          }
    }
  }

  // Edges against the triangles of the cells their box overlaps; the crossing nearest the
  // edge's first node wins (lowest triangle index on ties), per edge, so threads never race.
  std::atomic<int64_t> tests{0};
  std::atomic<int32_t> inRange{0};
  jobs.parallelFor(uint32_t(edgeCount), 1024, [&](uint32_t b, uint32_t e) {
    int64_t localTests = 0;
    int32_t localRange = 0;
    for (uint32_t edge = b; edge < e; ++edge) {
      if (broken[edge]) continue;
      const double* xa = positions + 3 * size_t(graph.edgeNodes[2 * size_t(edge)]);
      const double* xb = positions + 3 * size_t(graph.edgeNodes[2 * size_t(edge) + 1]);
      const Vec3 a{xa[0], xa[1], xa[2]}, bb{xb[0], xb[1], xb[2]};
      int32_t lo[3], hi[3];
      bool outside = false;
      for (int k = 0; k < 3; ++k) {
        const double l = std::min(a[k], bb[k]), h = std::max(a[k], bb[k]);
        if (h < domain.lo[k] || l > domain.hi[k]) outside = true;
        lo[k] = grid.coord(l, k);
        hi[k] = grid.coord(h, k);
      }
      if (outside) continue;
      ++localRange;
      double best = std::numeric_limits<double>::infinity();
      int32_t bestTri = -1;
      for (int32_t z = lo[2]; z <= hi[2]; ++z)
        for (int32_t y = lo[1]; y <= hi[1]; ++y)
          for (int32_t x = lo[0]; x <= hi[0]; ++x) {
            const size_t c = grid.index(x, y, z);
            for (int32_t s = ws.cellStart[c]; s < ws.cellStart[c + 1]; ++s) {
              const int32_t tri = ws.cellTriangles[size_t(s)];
              ++localTests;
              double param;
              if (!segmentCrossesTriangle(a, bb, ws.triangles[size_t(tri)], param)) continue;
              if (param < best || (param == best && tri < bestTri)) {
                best = param;
                bestTri = tri;
              }
            }
          }
      if (bestTri >= 0) {
        ws.hitSplit[edge] = best;
        ws.hitTriangle[edge] = bestTri;
      }
    }
    tests.fetch_add(localTests, std::memory_order_relaxed);
    inRange.fetch_add(localRange, std::memory_order_relaxed);
  });
  if (stats) {
    stats->cells = int32_t(cellCount);
    stats->edgesInRange = inRange.load();
    stats->triangleTests = tests.load();
  }

  // Serial emission in edge order.
  int32_t count = 0;
  for (int32_t edge = 0; edge < edgeCount; ++edge) {
    if (ws.hitTriangle[size_t(edge)] < 0) continue;
    const double s = ws.hitSplit[size_t(edge)];
    const double* xa = positions + 3 * size_t(graph.edgeNodes[2 * size_t(edge)]);
    const double* xb = positions + 3 * size_t(graph.edgeNodes[2 * size_t(edge) + 1]);
    broken[size_t(edge)] = 1;
    EdgeBreak ev;
    ev.edge = edge;
    ev.tet = -1;
    ev.stress = 0;
    ev.split = s;
    ev.position = {xa[0] + s * (xb[0] - xa[0]), xa[1] + s * (xb[1] - xa[1]),
                   xa[2] + s * (xb[2] - xa[2])};
    events.push_back(ev);
    ++count;
  }
  return count;
}

}  // namespace gf::detail
