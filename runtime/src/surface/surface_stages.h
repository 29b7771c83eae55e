// The render surface's per-frame work as stages (step/executor.h): the local maps of the nodes
// in partial groups, the vertex positions and the vertex normals, over the flat buffers
// CrackSurface builds at each rebuild. Each item writes only its own outputs and sums its
// terms in a fixed order (a vertex's triangles by increasing index), so every executor and
// thread count gives the same bits.
#pragma once

#include <cstdint>

#include "kernels/gf_hd.h"
#include "kernels/math.h"
#include "kernels/svd3.h"

namespace gf::detail {

/// An affine fit that stretches or squashes a direction beyond this comes from a neighbourhood
/// that is thin or being torn apart, not from the material: the best rotation stands in for it.
constexpr double kMaxFrameStretch = 3.0;

/// Smallest rotation turning unit vector u into unit vector w.
GF_HD Mat3 minimalRotation(Vec3 u, Vec3 w) {
  const Vec3 v = cross(u, w);
  const double c = dot(u, w);
  Mat3 r = Mat3::identity();
  if (c < -1 + 1e-12) {
    // Half turn about any axis orthogonal to u.
    const Vec3 k = anyOrthogonal(u);
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) r(a, b) = 2 * k[a] * k[b] - (a == b ? 1.0 : 0.0);
    return r;
  }
  // Rodrigues with the half-angle factor 1 / (1 + c): R = I + [v]x + [v]x^2 / (1 + c).
  const Mat3 vx = fromColumns(Vec3{0, v.z, -v.y}, Vec3{-v.z, 0, v.x}, Vec3{v.y, -v.x, 0});
  const Mat3 vx2 = vx * vx;
  for (int a = 0; a < 9; ++a) r.m[a] += vx.m[a] + vx2.m[a] / (1 + c);
  return r;
}

GF_HD Vec3 loadVec3(const double* p, int64_t i) { return {p[3 * i], p[3 * i + 1], p[3 * i + 2]}; }

/// The current map of one frame (a node in a partial group): the least-squares affine map of
/// its neighbourhood where that is usable, else the best rotation (polar part of the
/// covariance of current against rest edges), or the minimal turn of the line its neighbours
/// lie on. Row-major 3x3 into R.
struct SurfaceFrameStage {
  const double* x = nullptr;  ///< current node positions
  const double* X = nullptr;  ///< rest node positions
  const int32_t* frameNode = nullptr;
  const int32_t* ringStart = nullptr;
  const int32_t* ring = nullptr;
  const uint8_t* affine = nullptr;  ///< the affine fit is usable (well-spread neighbours)
  const double* cinv = nullptr;     ///< 9 per frame: inverse rest covariance
  double* R = nullptr;              ///< 9 per frame

  GF_HD void operator()(int32_t fr) const {
    const int32_t a = frameNode[fr];
    const Vec3 xa = loadVec3(x, a), Xa = loadVec3(X, a);
    Mat3 A;
    for (int32_t s = ringStart[fr]; s < ringStart[fr + 1]; ++s) {
      const int32_t b = ring[s];
      const Vec3 dx = loadVec3(x, b) - xa, dX = loadVec3(X, b) - Xa;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) A(r, c) += dx[r] * dX[c];
    }
    Mat3 M = Mat3::identity();
    bool done = false;
    if (affine[fr]) {
      Mat3 Cinv;
      for (int k = 0; k < 9; ++k) Cinv.m[k] = cinv[9 * int64_t(fr) + k];
      const Mat3 F = A * Cinv;
      if (det(F) > 1e-2) {
        const Svd3 fs = svd3(F);
        if (fs.s.x < kMaxFrameStretch && fs.s.z > 1 / kMaxFrameStretch) {
          M = F;
          done = true;
        }
      }
    }
    if (!done) {
      const Svd3 svd = svd3(A);
      if (svd.s.x > 1e-300) {
        if (fabs(svd.s.y) > 1e-8 * svd.s.x) {
          M = svd.U * transpose(svd.V);
        } else {
          // All usable neighbours on one line: turn that line, no twist about it.
          M = minimalRotation(column(svd.V, 0), column(svd.U, 0));
        }
      }
    }
    for (int k = 0; k < 9; ++k) R[9 * int64_t(fr) + k] = M.m[k];
  }
};

/// One vertex's position: the element's own (affine) interpolation of its parents when its
/// group holds them all, else the mean of the group nodes' predictions through their maps.
struct SurfaceVertexStage {
  const double* x = nullptr;
  const double* X = nullptr;
  const int32_t* parent = nullptr;  ///< 4 per vertex, -1 unused
  const double* weight = nullptr;   ///< 4 per vertex
  const uint8_t* group = nullptr;   ///< mask over the parents
  const double* rest = nullptr;     ///< 3 per vertex
  const int32_t* nodeFrame = nullptr;
  const double* frameR = nullptr;  ///< 9 per frame
  double* positions = nullptr;     ///< 3 per vertex

  GF_HD void operator()(int32_t v) const {
    const int32_t* par = parent + 4 * int64_t(v);
    const double* w = weight + 4 * int64_t(v);
    const unsigned g = group[v];
    int count = 0;
    while (count < 4 && par[count] >= 0) ++count;
    Vec3 p{};
    if (g == (1u << count) - 1) {
      for (int k = 0; k < count; ++k) p += w[k] * loadVec3(x, par[k]);
    } else {
      const Vec3 P = loadVec3(rest, v);
      int members = 0;
      for (int k = 0; k < count; ++k) {
        if (!(g >> k & 1u)) continue;
        const int32_t a = par[k];
        Mat3 R;
        for (int j = 0; j < 9; ++j) R.m[j] = frameR[9 * int64_t(nodeFrame[a]) + j];
        p += loadVec3(x, a) + R * (P - loadVec3(X, a));
        ++members;
      }
      p = (1.0 / members) * p;
    }
    positions[3 * int64_t(v)] = p.x;
    positions[3 * int64_t(v) + 1] = p.y;
    positions[3 * int64_t(v) + 2] = p.z;
  }
};

/// One triangle's area vector (twice its area along its normal) and that vector's length, 4
/// per triangle: computed once here rather than once per corner by the vertices that share it.
struct TriangleNormalStage {
  const double* positions = nullptr;
  const uint32_t* indices = nullptr;  ///< 3 per triangle
  double* areaNormals = nullptr;      ///< 4 per triangle: the area vector, then its length

  GF_HD void operator()(int32_t tri) const {
    const uint32_t* id = indices + 3 * int64_t(tri);
    const Vec3 p0 = loadVec3(positions, id[0]);
    const Vec3 n = cross(loadVec3(positions, id[1]) - p0, loadVec3(positions, id[2]) - p0);
    double* out = areaNormals + 4 * int64_t(tri);
    out[0] = n.x;
    out[1] = n.y;
    out[2] = n.z;
    out[3] = norm(n);
  }
};

/// A vertex's unit normal: the area-weighted sum of its triangles' normals, or, where opposite
/// sides cancel (crack fronts), the normal of its first triangle.
struct SurfaceNormalStage {
  const double* areaNormals = nullptr;      ///< 4 per triangle (TriangleNormalStage)
  const int32_t* vertexTriStart = nullptr;  ///< per vertex, its triangles by increasing index
  const int32_t* vertexTri = nullptr;
  double* normals = nullptr;

  GF_HD void operator()(int32_t v) const {
    Vec3 sum{};
    double weight = 0;
    for (int32_t k = vertexTriStart[v]; k < vertexTriStart[v + 1]; ++k) {
      const double* n = areaNormals + 4 * int64_t(vertexTri[k]);
      sum += Vec3{n[0], n[1], n[2]};
      weight += n[3];
    }
    const double len = norm(sum);
    Vec3 out;
    if (len > 1e-6 * weight && len > 0) {
      out = {sum.x / len, sum.y / len, sum.z / len};
    } else if (vertexTriStart[v] < vertexTriStart[v + 1]) {
      const double* n = areaNormals + 4 * int64_t(vertexTri[vertexTriStart[v]]);
      const double l = n[3];
      out = l > 0 ? (1.0 / l) * Vec3{n[0], n[1], n[2]} : Vec3{0, 0, 1};
    } else {
      out = sum;  // a vertex no triangle uses keeps the zero the sum gave it
    }
    normals[3 * int64_t(v)] = out.x;
    normals[3 * int64_t(v) + 1] = out.y;
    normals[3 * int64_t(v) + 2] = out.z;
  }
};

/// Whether vertex v's float position or normal (what a renderer uploads) changes: v (first)
/// or v + 1 (last) where it does, for a MinOp and a MaxOp reduction of the dirty range.
struct ChangedVertexTerm {
  const double* positions = nullptr;
  const double* normals = nullptr;
  const float* positionsF = nullptr;  ///< the last upload's
  const float* normalsF = nullptr;
  bool last = false;  ///< false: v or +inf; true: v + 1 or -inf

  GF_HD double operator()(int32_t v) const {
    bool changed = false;
    for (int64_t k = 3 * int64_t(v); k < 3 * int64_t(v) + 3 && !changed; ++k)
      changed = float(positions[k]) != positionsF[k] || float(normals[k]) != normalsF[k];
    if (!changed) return last ? -HUGE_VAL : HUGE_VAL;
    return last ? double(v) + 1 : double(v);
  }
};

/// cof(F) v = det(F) F^-T v, from the columns f_j of F: cof(F) = [f1 x f2, f2 x f0, f0 x f1].
/// It maps a rest normal to the current one (Nanson's formula) without inverting F, so it
/// stays defined, and keeps its direction, for flattened tets.
GF_HD Vec3 cofactorTimes(const Mat3& F, Vec3 v) {
  const Vec3 f0 = column(F, 0), f1 = column(F, 1), f2 = column(F, 2);
  return v.x * cross(f1, f2) + v.y * cross(f2, f0) + v.z * cross(f0, f1);
}

/// One vertex of the embedded render mesh (surface/embedded_mesh.h): where its group holds all
/// four nodes of its tet, the tet's own affine interpolation sum_k w_k x_k, and its normal
/// mapped by the cofactor of the tet's deformation gradient; otherwise the prediction
/// x_a + M_a (P - X_a) of the group node a of the largest weight (its cell node) through its
/// local map, and the normal through M_a's cofactor.
struct EmbeddedVertexStage {
  const double* x = nullptr;
  const double* X = nullptr;
  const int32_t* tets = nullptr;       ///< 4 per tet
  const Mat3* restInverse = nullptr;   ///< Dm^-1 per tet
  const int32_t* tet = nullptr;        ///< per vertex
  const double* weight = nullptr;      ///< 4 per vertex
  const uint8_t* group = nullptr;      ///< mask over the tet's local nodes
  const double* rest = nullptr;        ///< 3 per vertex: its rest position
  const double* restNormal = nullptr;  ///< 3 per vertex, unit
  const int32_t* nodeFrame = nullptr;
  const double* frameR = nullptr;  ///< 9 per frame
  double* positions = nullptr;     ///< 3 per vertex
  double* normals = nullptr;       ///< 3 per vertex

  GF_HD void operator()(int32_t v) const {
    const int32_t t = tet[v];
    const int32_t* n = tets + 4 * int64_t(t);
    const double* w = weight + 4 * int64_t(v);
    const unsigned g = group[v];
    const Vec3 N = loadVec3(restNormal, v);
    Vec3 p{}, nn{};
    if (g == 15u) {
      Vec3 xe[4];
      for (int k = 0; k < 4; ++k) {
        xe[k] = loadVec3(x, n[k]);
        p += w[k] * xe[k];
      }
      const Mat3 F = fromColumns(xe[1] - xe[0], xe[2] - xe[0], xe[3] - xe[0]) * restInverse[t];
      nn = cofactorTimes(F, N);
    } else {
      // One node, not the mean over the group: a group's nodes are joined by unbroken edges,
      // but where every tet around such an edge is split nothing holds it (degradation model),
      // and the mean put the shattered bunny's vertices up to 10.7 cells from their fragment.
      const Vec3 P = loadVec3(rest, v);
      int a = -1;
      for (int k = 0; k < 4; ++k)
        if ((g >> k & 1u) && (a < 0 || w[k] > w[a])) a = k;
      Mat3 R;
      for (int j = 0; j < 9; ++j) R.m[j] = frameR[9 * int64_t(nodeFrame[n[a]]) + j];
      p = loadVec3(x, n[a]) + R * (P - loadVec3(X, n[a]));
      nn = cofactorTimes(R, N);
    }
    // A tet flattened to nothing has no normal map; the rest normal is the best guess left.
    const double len = norm(nn);
    nn = len > 0 ? (1.0 / len) * nn : N;
    for (int c = 0; c < 3; ++c) {
      positions[3 * int64_t(v) + c] = p[c];
      normals[3 * int64_t(v) + c] = nn[c];
    }
  }
};

/// out[3 i + c] = in[3 from[i] + c]: the crack-face vertices the embedded surface borrows.
struct GatherVec3Stage {
  const double* in = nullptr;
  const int32_t* from = nullptr;
  double* out = nullptr;

  GF_HD void operator()(int32_t i) const {
    for (int c = 0; c < 3; ++c) out[3 * int64_t(i) + c] = in[3 * int64_t(from[i]) + c];
  }
};

/// The centre of a cap that closes a cut through the render mesh: the mean of its rim's cut
/// points between two fragments when it has any (the neighbour's cap over the same cut then has
/// the same centre at rest, so the two cancel even where the cycle also runs around an
/// unseparated crack), else of its front vertices (whole render vertices, where a crack that has
/// not separated the body ends and its two sides meet) when it has any, else of all its rim
/// vertices (placed before this stage); and, as the normal of all its triangles, the unit area
/// vector of its fan (center, rim[k + 1], rim[k]).
struct CapCenterStage {
  const int32_t* rimStart = nullptr;   ///< per cap, CSR into rim
  const int32_t* rim = nullptr;        ///< rim vertices, in the order the cut runs for the fragment
  const int32_t* source = nullptr;     ///< per vertex: >= 0 for a front vertex, < 0 otherwise
  const uint8_t* separated = nullptr;  ///< per vertex: 1 for a cut point between two fragments
  int32_t firstCenter = 0;             ///< the vertex of cap 0's centre; the others follow
  double* positions = nullptr;         ///< 3 per vertex
  double* normals = nullptr;           ///< 3 per vertex

  GF_HD void operator()(int32_t c) const {
    const int32_t b = rimStart[c], e = rimStart[c + 1];
    // The two crack faces of an unseparated crack meet at its front, so the fan folds there;
    // a cycle that also runs along a separation is centred on it instead: a centre at the front
    // of a crack that meets a separation would make a cone over the separation's section that
    // the neighbour's cap does not cancel (16 % of the bar's volume left uncovered in
    // RenderMesh.PartialCrackMeetingAFragmentCutIsClosed).
    Vec3 m{}, front{}, apart{};
    int32_t fronts = 0, aparts = 0;
    for (int32_t k = b; k < e; ++k) {
      const Vec3 p = loadVec3(positions, rim[k]);
      m += p;
      if (source[rim[k]] >= 0) {
        front += p;
        ++fronts;
      }
      if (separated[rim[k]]) {
        apart += p;
        ++aparts;
      }
    }
    m = aparts > 0   ? (1.0 / double(aparts)) * apart
        : fronts > 0 ? (1.0 / double(fronts)) * front
                     : (1.0 / double(e - b)) * m;
    Vec3 area{};
    for (int32_t k = b; k < e; ++k) {
      const int32_t next = k + 1 < e ? k + 1 : b;
      area += cross(loadVec3(positions, rim[next]) - m, loadVec3(positions, rim[k]) - m);
    }
    const double len = norm(area);
    const Vec3 n = len > 0 ? (1.0 / len) * area : Vec3{0, 0, 1};
    const int64_t v = int64_t(firstCenter) + c;
    for (int i = 0; i < 3; ++i) {
      positions[3 * v + i] = m[i];
      normals[3 * v + i] = n[i];
    }
  }
};

/// A stage run over the listed items only: item i is stage item items[i].
template <class Stage>
struct ListedStage {
  const int32_t* items = nullptr;
  Stage stage;

  GF_HD void operator()(int32_t i) const { stage(items[i]); }
};

/// out[i] = float(in[i]).
struct ToFloatStage {
  const double* in = nullptr;
  float* out = nullptr;

  GF_HD void operator()(int32_t i) const { out[i] = float(in[i]); }
};

}  // namespace gf::detail
