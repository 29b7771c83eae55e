#include "xfem/blade_path.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <map>
#include <string>
#include <utility>

#include "kernels/tri_tri.h"

namespace gf::detail {

namespace {

struct Box {
  Vec3 lo{INFINITY, INFINITY, INFINITY}, hi{-INFINITY, -INFINITY, -INFINITY};
  void add(Vec3 p) {
    for (int i = 0; i < 3; ++i) {
      lo[i] = std::min(lo[i], p[i]);
      hi[i] = std::max(hi[i], p[i]);
    }
  }
  bool overlaps(const Box& o, double margin) const {
    for (int i = 0; i < 3; ++i)
      if (lo[i] > o.hi[i] + margin || o.lo[i] > hi[i] + margin) return false;
    return true;
  }
};

// The part of triangle t inside the closed tet: the triangle clipped against the four
// barycentric half-spaces l_k >= 0 (Sutherland-Hodgman; at most 3 + 4 vertices).
int clipTriangleToTet(const Vec3 X[4], const Vec3 t[3], Vec3 out[8]) {
  Vec3 poly[8], next[8];
  double l[8][4];
  int count = 3;
  for (int k = 0; k < 3; ++k) poly[k] = t[k];
  for (int face = 0; face < 4 && count > 0; ++face) {
    for (int k = 0; k < count; ++k) tetBarycentric(X, poly[k], l[k]);
    int n = 0;
    for (int k = 0; k < count; ++k) {
      const int k1 = (k + 1) % count;
      const double da = l[k][face], db = l[k1][face];
      if (da >= 0) next[n++] = poly[k];
      if ((da > 0 && db < 0) || (da < 0 && db > 0))
        next[n++] = poly[k] + (da / (da - db)) * (poly[k1] - poly[k]);
    }
    count = n;
    for (int k = 0; k < count; ++k) poly[k] = next[k];
  }
  for (int k = 0; k < count; ++k) out[k] = poly[k];
  return count;
}

}  // namespace

std::vector<double> nodeSnapDistances(const TetMesh& mesh) {
  std::vector<double> shortest(mesh.nodeCount(), INFINITY);
  for (size_t t = 0; t < mesh.tetCount(); ++t)
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        const int32_t i = mesh.tets[4 * t + size_t(a)], j = mesh.tets[4 * t + size_t(b)];
        double l2 = 0;
        for (int k = 0; k < 3; ++k) {
          const double d =
              mesh.positions[3 * size_t(i) + size_t(k)] - mesh.positions[3 * size_t(j) + size_t(k)];
          l2 += d * d;
        }
        const double l = std::sqrt(l2);
        shortest[size_t(i)] = std::min(shortest[size_t(i)], l);
        shortest[size_t(j)] = std::min(shortest[size_t(j)], l);
      }
  for (size_t n = 0; n < shortest.size(); ++n) {
    double far = 0;
    for (int k = 0; k < 3; ++k) far = std::max(far, std::abs(mesh.positions[3 * n + size_t(k)]));
    shortest[n] =
        std::isfinite(shortest[n]) ? kXfemNodeSnap * shortest[n] + 64 * DBL_EPSILON * far : 0.0;
  }
  return shortest;
}

Result<Blade> bladeSurface(const XfemBlade& xb) {
  const Blade& blade = xb.blade;
  const int32_t vertexCount = int32_t(blade.vertices.size() / 3);
  const int32_t triCount = int32_t(blade.triangles.size() / 3);
  if (triCount == 0) return fail("blade: no triangles");
  for (int32_t i = 0; i < 3 * vertexCount; ++i)
    if (!std::isfinite(blade.vertices[size_t(i)]))
      return fail("blade: vertex ", std::to_string(i / 3), ": not finite");
  for (int32_t k = 0; k < 3 * triCount; ++k)
    if (blade.triangles[size_t(k)] < 0 || blade.triangles[size_t(k)] >= vertexCount)
      return fail("blade: triangle ", std::to_string(k / 3), ": vertex index out of range");
  const auto place = [&](const BladePose& pose, int32_t i) {
    return pose.rotation * Vec3{blade.vertices[3 * size_t(i)], blade.vertices[3 * size_t(i) + 1],
                                blade.vertices[3 * size_t(i) + 2]} +
           pose.translation;
  };
  for (const BladePose* pose : {&xb.pose, xb.to ? &*xb.to : nullptr})
    if (pose)
      for (int32_t i = 0; i < vertexCount; ++i) {
        const Vec3 x = place(*pose, i);
        if (!std::isfinite(x.x) || !std::isfinite(x.y) || !std::isfinite(x.z))
          return fail("blade: vertex ", std::to_string(i), ": not finite at its pose");
      }
  Blade out;
  const auto addVertex = [&](Vec3 x) { out.vertices.insert(out.vertices.end(), {x.x, x.y, x.z}); };
  for (int32_t i = 0; i < vertexCount; ++i) addVertex(place(xb.pose, i));
  out.triangles = blade.triangles;
  Vec3 move;
  if (xb.to)
    for (int32_t i = 0; i < vertexCount; ++i) move += place(*xb.to, i) - place(xb.pose, i);
  if (!xb.to || norm(move) == 0) return out;

  // Swept: start vertices 0..V-1, end vertices V..2V-1; the blade at both poses, and the quad
  // each boundary edge (a -> b, as its triangle runs) sweeps.
  move = (1.0 / vertexCount) * move;
  for (int32_t i = 0; i < vertexCount; ++i) addVertex(place(*xb.to, i));
  std::map<std::pair<int32_t, int32_t>, int> directed;
  Vec3 normal;
  for (int32_t t = 0; t < triCount; ++t) {
    const int32_t* v = &blade.triangles[3 * size_t(t)];
    out.triangles.insert(out.triangles.end(),
                         {v[0] + vertexCount, v[1] + vertexCount, v[2] + vertexCount});
    normal +=
        cross(place(*xb.to, v[1]) - place(*xb.to, v[0]), place(*xb.to, v[2]) - place(*xb.to, v[0]));
    for (int k = 0; k < 3; ++k) ++directed[{v[k], v[(k + 1) % 3]}];
  }
  for (const auto& [e, n] : directed) {
    if (directed.count({e.second, e.first})) continue;  // interior edge
    const int32_t a0 = e.first, b0 = e.second, a1 = a0 + vertexCount, b1 = b0 + vertexCount;
    out.triangles.insert(out.triangles.end(), {a0, b0, b1, a0, b1, a1});
  }
  // Orientation: out of the swept volume ((b - a) x d of a boundary quad is outward when the
  // blade moves along its normal: then the start blade faces in); within the blade's plane, all
  // along the blade's normal.
  const double along = dot(normal, move) / (norm(normal) * norm(move));
  const auto flip = [&](size_t t) {
    std::swap(out.triangles[3 * t + 1], out.triangles[3 * t + 2]);
  };
  const auto at = [&](int32_t i) {
    return Vec3{out.vertices[3 * size_t(i)], out.vertices[3 * size_t(i) + 1],
                out.vertices[3 * size_t(i) + 2]};
  };
  for (size_t t = 0; 3 * t < out.triangles.size(); ++t) {
    const bool start = t < size_t(triCount);
    if (std::abs(along) <= 1e-9) {
      const int32_t* v = &out.triangles[3 * t];
      if (dot(cross(at(v[1]) - at(v[0]), at(v[2]) - at(v[0])), normal) < 0) flip(t);
    } else if (along > 0 ? start : !start) {
      flip(t);
    }
  }
  return out;
}

Result<BladePath> traceBlade(const TetMesh& mesh, const XfemBlade& xb) {
  auto surface = bladeSurface(xb);
  if (!surface.ok()) return fail(surface.error().message);
  const Blade& blade = surface.value();
  const int32_t vertexCount = int32_t(blade.vertices.size() / 3);
  const int32_t triCount = int32_t(blade.triangles.size() / 3);
  std::vector<Vec3> v(static_cast<size_t>(vertexCount));
  for (int32_t i = 0; i < vertexCount; ++i)
    v[size_t(i)] = {blade.vertices[3 * size_t(i)], blade.vertices[3 * size_t(i) + 1],
                    blade.vertices[3 * size_t(i) + 2]};

  // World-space triangles, their unit normals and boxes; degenerate ones cover nothing.
  struct Tri {
    Vec3 p[3], n;
    Box box;
  };
  std::vector<Tri> tris;
  std::map<std::pair<int32_t, int32_t>, int> edgeUse;
  double bladeArea = 0;
  for (int32_t t = 0; t < triCount; ++t) {
    Tri tri;
    for (int k = 0; k < 3; ++k) {
      tri.p[k] = v[size_t(blade.triangles[3 * size_t(t) + k])];
      tri.box.add(tri.p[k]);
    }
    const Vec3 n = cross(tri.p[1] - tri.p[0], tri.p[2] - tri.p[0]);
    if (norm(n) == 0) continue;
    bladeArea += 0.5 * norm(n);
    tri.n = (1.0 / norm(n)) * n;
    tris.push_back(tri);
    for (int k = 0; k < 3; ++k) {
      const int32_t a = blade.triangles[3 * size_t(t) + k],
                    b = blade.triangles[3 * size_t(t) + (k + 1) % 3];
      ++edgeUse[{std::min(a, b), std::max(a, b)}];
    }
  }
  if (bladeArea == 0) return fail("blade: every triangle has zero area");
  // The blade's boundary: edges not shared by exactly two triangles (where it ends).
  std::vector<std::pair<Vec3, Vec3>> boundary;
  for (const auto& [e, uses] : edgeUse)
    if (uses != 2) boundary.emplace_back(v[size_t(e.first)], v[size_t(e.second)]);

  BladePath path;
  const int32_t tets = int32_t(mesh.tetCount());
  const std::vector<double> snap = nodeSnapDistances(mesh);
  const int faces[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  const int edges[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  std::vector<int32_t> hits;
  for (int32_t t = 0; t < tets; ++t) {
    Vec3 X[4];
    double snapX[4];
    Box box;
    double size = 0;
    for (int a = 0; a < 4; ++a) {
      const int32_t n = mesh.tets[4 * size_t(t) + a];
      X[a] = {mesh.positions[3 * size_t(n)], mesh.positions[3 * size_t(n) + 1],
              mesh.positions[3 * size_t(n) + 2]};
      snapX[a] = snap[size_t(n)];
      box.add(X[a]);
    }
    for (int i = 0; i < 3; ++i) size = std::max(size, box.hi[i] - box.lo[i]);
    hits.clear();
    for (size_t k = 0; k < tris.size(); ++k) {
      const Tri& tri = tris[k];
      if (!box.overlaps(tri.box, 1e-9 * size)) continue;
      ++path.triangleTests;
      bool meets = pointInTet(X, tri.p[0]);
      for (int f = 0; f < 4 && !meets; ++f) {
        const Vec3 face[3] = {X[faces[f][0]], X[faces[f][1]], X[faces[f][2]]};
        // Touching within the snap distance counts: a node snapped onto the blade must find it.
        meets = trianglesIntersect(face, tri.p, kXfemNodeSnap);
      }
      if (meets) hits.push_back(int32_t(k));
    }
    if (hits.empty()) continue;

    // The local plane: area-weighted normal and centroid of the blade's pieces in the tet.
    Vec3 normalSum, centroidSum;
    double area = 0;
    std::vector<Vec3> pieceVertices;
    for (int32_t k : hits) {
      Vec3 poly[8];
      const int count = clipTriangleToTet(X, tris[size_t(k)].p, poly);
      for (int i = 1; i + 1 < count; ++i) {
        const double a = 0.5 * norm(cross(poly[i] - poly[0], poly[i + 1] - poly[0]));
        area += a;
        centroidSum += (a / 3.0) * (poly[0] + poly[i] + poly[i + 1]);
        normalSum += a * tris[size_t(k)].n;
      }
      for (int i = 0; i < count; ++i) pieceVertices.push_back(poly[i]);
    }
    // Where the blade crosses each tet edge (a crossing through a blade edge shared by two
    // triangles counts once).
    int count[6] = {0, 0, 0, 0, 0, 0};
    double at[6] = {0, 0, 0, 0, 0, 0};
    for (int e = 0; e < 6; ++e)
      for (int32_t k : hits) {
        double s;
        const int e0 = edges[e][0], e1 = edges[e][1];
        if (!segmentCrossesTriangleSnapped(X[e0], X[e1], snapX[e0], snapX[e1], tris[size_t(k)].p[0],
                                           tris[size_t(k)].p[1], tris[size_t(k)].p[2], s))
          continue;
        if (count[e] > 0 && std::abs(at[e] - s) <= 1e-9) continue;
        at[e] = s;
        ++count[e];
      }
    const int crossed = count[0] + count[1] + count[2] + count[3] + count[4] + count[5];
    bool ends = false;  // a blade boundary edge meets the tet
    for (const auto& [a, b] : boundary)
      if (segmentMeetsTet(X, a, b)) {
        ends = true;
        break;
      }
    if (crossed == 0 && (!ends || area <= 1e-12 * size * size)) {
      ++path.touched;  // along a face, through a node or an edge only
      continue;
    }
    BladeTetCrossing c;
    c.tet = t;
    c.area = area;
    c.triangles = int32_t(hits.size());
    // Node sides from the crossings: node 0 on side 0, a crossed edge flips. Consistent when
    // every face has 0 or 2 crossed edges and no edge is crossed twice (the blade folds back).
    int side[4] = {0, count[0] & 1, count[1] & 1, count[2] & 1};
    bool full = !ends && crossed > 0;
    for (int e = 0; e < 6 && full; ++e)
      full = count[e] <= 1 && count[e] == (side[edges[e][0]] ^ side[edges[e][1]]);
    // The local plane through the crossing points: exact through three (one node cut off);
    // through four (two and two) the plane of the quad's diagonals, which is the blade's when
    // the blade is planar there. Sharing the edge points with its neighbours, the cut lines on
    // a shared face agree wherever three points define the plane.
    Vec3 p[6];
    int np = 0;
    int order[6];
    if (full) {
      for (int e = 0; e < 6; ++e)
        if (count[e]) {
          order[np] = e;
          // A crossing at a node is the node, bit for bit (the plane is anchored on it below).
          p[np++] = at[e] == 1 ? X[edges[e][1]]
                               : X[edges[e][0]] + at[e] * (X[edges[e][1]] - X[edges[e][0]]);
        }
      Vec3 n, centre;
      if (np == 3) {
        n = cross(p[1] - p[0], p[2] - p[0]);
      } else {
        // Quad order: consecutive crossed edges share a node; the opposite pairs are diagonals.
        int q[4] = {0, -1, -1, -1};
        for (int k = 1; k < 4; ++k)
          for (int i = 0; i < 4; ++i) {
            bool used = false;
            for (int j = 0; j < k; ++j) used = used || q[j] == i;
            const int e0 = order[q[k - 1]], e1 = order[i];
            const bool shares = edges[e0][0] == edges[e1][0] || edges[e0][0] == edges[e1][1] ||
                                edges[e0][1] == edges[e1][0] || edges[e0][1] == edges[e1][1];
            if (!used && shares && q[k] < 0) q[k] = i;
          }
        n = cross(p[q[2]] - p[q[0]], p[q[3]] - p[q[1]]);
      }
      for (int k = 0; k < np; ++k) centre += p[k];
      centre = (1.0 / np) * centre;
      // Crossing points that (nearly) coincide or line up, as where the blade passes through
      // or next to a node, define no plane: take the blade's own normal there (its pieces'
      // area-weighted normal, or its triangles' where it only touches the tet).
      if (!(norm(n) > 1e-8 * size * size)) {
        n = normalSum;
        if (!(norm(n) > 0))
          for (int32_t k : hits) n += tris[size_t(k)].n;
      }
      if (dot(n, normalSum) < 0) n = -n;  // along the blade's orientation
      full = norm(n) > 0;
      if (full) {
        c.plane.normal = (1.0 / norm(n)) * n;
        c.plane.offset = dot(c.plane.normal, centre);
        // The positive group holds the node farthest along the normal. A positive node
        // within its snap distance below the plane (on the blade, to rounding) gets the plane
        // lowered onto it, so it is exactly on the plane's positive side as in its other tets.
        int top = 0;
        for (int a = 1; a < 4; ++a)
          if (planeDistance(c.plane, X[a]) > planeDistance(c.plane, X[top])) top = a;
        for (int a = 0; a < 4; ++a) {
          const double d = planeDistance(c.plane, X[a]);
          if (side[a] == side[top] && d < 0 && d >= -snapX[a])
            c.plane.offset = std::min(c.plane.offset, dot(c.plane.normal, X[a]));
        }
        // The plane must reproduce the crossing's node sides (zero counts as positive).
        for (int a = 0; a < 4 && full; ++a) {
          const double d = planeDistance(c.plane, X[a]);
          full = side[a] == side[top] ? d >= 0 : d < 0;
        }
      }
    }
    if (!full) {
      // Partial: a plane for the record only (the blade's mean plane in the tet).
      const double nl = norm(normalSum);
      if (nl > 0) {
        c.plane.normal = (1.0 / nl) * normalSum;
        c.plane.offset = dot(c.plane.normal, (1.0 / area) * centroidSum);
      }
    }
    for (const Vec3& q : pieceVertices)
      c.deviation = std::max(c.deviation, std::abs(planeDistance(c.plane, q)));
    c.full = full;
    if (full) {
      ++path.fullCount;
      path.maxDeviation = std::max(path.maxDeviation, c.deviation);
    } else {
      ++path.partialCount;
    }
    path.crossings.push_back(c);
  }
  return path;
}

}  // namespace gf::detail
