// Moment-fitting quadrature on the cells of a cut tet and on their cut faces (thesis eqs
// 3.8-3.12, after Mueller et al. 2013): fixed points, weights solved once per cell so the rule
// integrates every polynomial up to kCutRuleDegree exactly.
//
// Design: the thesis fixes the points in the tet and solves eq 3.9 for the weights. Fixed in the
// tet, the points of a sliver cell (a cut 1e-6 of the height from a vertex) lie far outside it and
// the weights cancel to integrate a 1e-18 volume from O(1) values: exact in exact arithmetic, but
// rounding then leaves the tiny enriched masses that decide the conditioning of classic XFEM
// (eq 3.14-3.16) with no correct digit. So the points are fixed in the cell's own frame instead:
// the affine map that gives the cell the covariance of a reference regular tetrahedron (computed
// from the cell's exact second moments) carries the principal lattice of degree kCutRuleDegree on
// that tetrahedron (35 points, unisolvent for the 35 monomials) into the cell. In that frame the
// moment matrix of eq 3.9 is the same well-conditioned 35 x 35 matrix for every cell, and the
// weights keep their relative precision for cells of any size (measured: 4e-15 of the cell's
// volume on 1e-18 corner slivers). A flat cell (1e-6 thin) is limited by its vertices, stored in
// the tet's coordinates: its thickness is known only to eps / flatness (2e-10 measured). The
// frame only conditions the solve: the rule is exact whatever frame rounding produces.
// The right-hand side of eq 3.9 is the cell's exact moments (cut_polytope.h): the divergence
// theorem of eqs 3.9-3.10 applied to a cell whose faces are planar polygons. The cut faces are
// planar (a blade is a triangle mesh), so the surface rule of eqs 3.11-3.12 reduces to the same
// fitting in the plane, against the polygon's exact area moments.
#pragma once

#include "cut_polytope.h"
#include "eigen_sym.h"

namespace gf {

/// Polynomial degree integrated exactly: the Is-XFEM mass with k > 0 has integrands of degree 4
/// ((psi N)^2 with psi linear in a cell, eqs 3.2-3.5); the linear-elastic stiffness needs 2.
constexpr int kCutRuleDegree = 4;
constexpr int kVolumeRulePoints = monomialCount(3, kCutRuleDegree);   // 35
constexpr int kSurfaceRulePoints = monomialCount(2, kCutRuleDegree);  // 15

/// Points and weights of one cell (eq 3.8); count == 0 for an empty cell.
struct VolumeRule {
  Vec3 points[kVolumeRulePoints];
  double weights[kVolumeRulePoints] = {};
  int count = 0;
};

/// Points and area weights on one planar polygon (eq 3.11); normal is the polygon's unit normal.
struct SurfaceRule {
  Vec3 points[kSurfaceRulePoints];
  double weights[kSurfaceRulePoints] = {};
  Vec3 normal;
  int count = 0;
};

namespace detail {

/// Solves a x = b in place (b becomes x) by Gaussian elimination with partial pivoting; a is
/// n x n row-major and is destroyed. Returns false on a zero pivot.
GF_HD bool solveDense(double* a, double* b, int n) {
  for (int k = 0; k < n; ++k) {
    int p = k;
    for (int i = k + 1; i < n; ++i)
      if (fabs(a[i * n + k]) > fabs(a[p * n + k])) p = i;
    if (a[p * n + k] == 0) return false;
    if (p != k) {
      for (int j = 0; j < n; ++j) {
        const double t = a[k * n + j];
        a[k * n + j] = a[p * n + j];
        a[p * n + j] = t;
      }
      const double t = b[k];
      b[k] = b[p];
      b[p] = t;
    }
    for (int i = k + 1; i < n; ++i) {
      const double f = a[i * n + k] / a[k * n + k];
      if (f == 0) continue;
      for (int j = k; j < n; ++j) a[i * n + j] -= f * a[k * n + j];
      b[i] -= f * b[k];
    }
  }
  for (int k = n - 1; k >= 0; --k) {
    double s = b[k];
    for (int j = k + 1; j < n; ++j) s -= a[k * n + j] * b[j];
    b[k] = s / a[k * n + k];
  }
  return true;
}

/// Principal lattice of degree D on the regular tetrahedron with vertices (1,1,1), (1,-1,-1),
/// (-1,1,-1), (-1,-1,1): centroid 0, covariance I/5.
template <int D>
GF_HD void referenceLattice3(Vec3 out[monomialCount(3, D)]) {
  const Vec3 v[4] = {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}};
  int m = 0;
  for (int a = D; a >= 0; --a)
    for (int b = D - a; b >= 0; --b)
      for (int c = D - a - b; c >= 0; --c) {
        const int d = D - a - b - c;
        out[m++] =
            (1.0 / D) * (double(a) * v[0] + double(b) * v[1] + double(c) * v[2] + double(d) * v[3]);
      }
}
constexpr double kReferenceTetVariance = 0.2;

/// Principal lattice of degree D on the equilateral triangle inscribed in the unit circle:
/// centroid 0, covariance I/8.
template <int D>
GF_HD void referenceLattice2(double u[monomialCount(2, D)], double v[monomialCount(2, D)]) {
  const double s = 0.8660254037844386;  // sin(60 degrees)
  const double vu[3] = {1, -0.5, -0.5}, vv[3] = {0, s, -s};
  int m = 0;
  for (int a = D; a >= 0; --a)
    for (int b = D - a; b >= 0; --b) {
      const int c = D - a - b;
      u[m] = (a * vu[0] + b * vu[1] + c * vu[2]) / D;
      v[m] = (a * vv[0] + b * vv[1] + c * vv[2]) / D;
      ++m;
    }
}
constexpr double kReferenceTriangleVariance = 0.125;

}  // namespace detail

/// Moment-fitted rule of degree kCutRuleDegree for one cell (eqs 3.8-3.9): exact for every
/// polynomial of that degree over the cell. Empty for an empty cell or a failed solve.
GF_HD VolumeRule fitVolumeRule(const CutPolytope& cell) {
  constexpr int D = kCutRuleDegree, M = kVolumeRulePoints;
  VolumeRule rule;
  if (cell.faceCount == 0) return rule;
  // Isotropic frame first (vertex average, largest extent) so the covariance is not lost to
  // cancellation for a small cell far from the origin.
  Vec3 origin;
  int n = 0;
  for (int f = 0; f < cell.faceCount; ++f)
    for (int i = 0; i < cell.faces[f].count; ++i, ++n) origin += cell.faces[f].v[i];
  origin = (1.0 / n) * origin;
  double extent = 0;
  for (int f = 0; f < cell.faceCount; ++f)
    for (int i = 0; i < cell.faces[f].count; ++i) {
      const double r = norm(cell.faces[f].v[i] - origin);
      extent = r > extent ? r : extent;
    }
  if (!(extent > 0)) return rule;
  double m2[monomialCount(3, 2)];
  polytopeMoments<2>(cell, origin, (1.0 / extent) * Mat3::identity(), m2);
  if (!(m2[0] > 0)) return rule;
  // Monomial order 1, x, y, z, x2, xy, xz, y2, yz, z2.
  const Vec3 mean{m2[1] / m2[0], m2[2] / m2[0], m2[3] / m2[0]};
  Mat3 cov;
  const int second[3][3] = {{4, 5, 6}, {5, 7, 8}, {6, 8, 9}};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) cov(i, j) = m2[second[i][j]] / m2[0] - mean[i] * mean[j];
  double lambda[3];
  Mat3 q;
  symmetricEigen(cov, lambda, q);
  // Rounding can leave the thin direction of a flat cell at or below zero; any positive
  // stand-in keeps the frame invertible and the rule exact.
  const double floor = 1e-24 * lambda[0];
  if (!(lambda[0] > 0)) return rule;
  // xi = W (x - centre), W = diag(sqrt(var / lambda)) Q^T / extent; x = centre + Winv xi.
  Mat3 W, Winv;
  for (int k = 0; k < 3; ++k) {
    const double l = lambda[k] > floor ? lambda[k] : floor;
    const double s = sqrt(detail::kReferenceTetVariance / l);
    for (int c = 0; c < 3; ++c) {
      W(k, c) = s * q(c, k) / extent;
      Winv(c, k) = q(c, k) * extent / s;
    }
  }
  const Vec3 centre = origin + extent * mean;
  double moments[M];
  polytopeMoments<D>(cell, centre, W, moments);
  Vec3 xi[M];
  detail::referenceLattice3<D>(xi);
  // Eq 3.9: row k is monomial k at every point; the right-hand side is its exact integral.
  double a[M * M];
  for (int p = 0; p < M; ++p) {
    double mono[M];
    monomials3<D>(xi[p], mono);
    for (int k = 0; k < M; ++k) a[k * M + p] = mono[k];
  }
  if (!detail::solveDense(a, moments, M)) return rule;
  // dx = |det Winv| dxi; the moments were summed over signed cones, so a mirrored frame
  // negates them and the signed determinant undoes it.
  const double jacobian = det(Winv);
  for (int p = 0; p < M; ++p) {
    rule.points[p] = centre + Winv * xi[p];
    rule.weights[p] = jacobian * moments[p];
  }
  rule.count = M;
  return rule;
}

/// The rule of a whole tet X (no cut through it): the Grundmann-Moeller rule of degree
/// kCutRuleDegree + 1 (15 points) mapped affinely, `volume` its (positive) volume. Moment fitting
/// would only rediscover a rule exact on the simplex, so the fitted cell frame, eq 3.9's solve
/// and the exact moments are skipped: most tets of a cut body are not cut.
GF_HD VolumeRule standardTetRule(const Vec3 X[4], double volume) {
  // s = 2: degree 5 on 10 + 4 + 1 points.
  static_assert(kCutRuleDegree <= 5 && 15 <= kVolumeRulePoints, "Grundmann-Moeller s = 2");
  VolumeRule rule;
  grundmannMoellerTet(2, [&](double w, const double l[4]) {
    rule.points[rule.count] = l[0] * X[0] + l[1] * X[1] + l[2] * X[2] + l[3] * X[3];
    rule.weights[rule.count] = w * volume;
    ++rule.count;
  });
  return rule;
}

/// Moment-fitted rule of degree kCutRuleDegree on a planar convex polygon (eqs 3.11-3.12 for a
/// planar cut): exact for every polynomial of that degree over its area. Empty for a polygon of
/// zero area.
GF_HD SurfaceRule fitSurfaceRule(const CutPolygon& g) {
  constexpr int D = kCutRuleDegree, M = kSurfaceRulePoints;
  SurfaceRule rule;
  if (g.count < 3) return rule;
  Vec3 origin;
  for (int i = 0; i < g.count; ++i) origin += g.v[i];
  origin = (1.0 / g.count) * origin;
  Vec3 n;
  for (int i = 1; i + 1 < g.count; ++i) n += cross(g.v[i] - g.v[0], g.v[i + 1] - g.v[0]);
  const double nn = norm(n);
  if (!(nn > 0)) return rule;
  n = (1.0 / nn) * n;
  // In-plane orthonormal axes, scaled by the largest extent.
  Vec3 e0 = g.v[0] - origin;
  for (int i = 1; i < g.count && dot(e0, e0) < dot(g.v[i] - origin, g.v[i] - origin); ++i)
    e0 = g.v[i] - origin;
  const double extent = norm(e0);
  if (!(extent > 0)) return rule;
  e0 = (1.0 / extent) * e0;
  const Vec3 e1 = cross(n, e0);
  double pu[kCutPolygonMaxVertices], pv[kCutPolygonMaxVertices];
  for (int i = 0; i < g.count; ++i) {
    pu[i] = dot(g.v[i] - origin, e0) / extent;
    pv[i] = dot(g.v[i] - origin, e1) / extent;
  }
  // Area moments up to degree 2 in (pu, pv), for the frame.
  // Signed fan areas: a mirrored frame negates the moments and its Jacobian together.
  auto areaMoments = [&](const double* u, const double* v, double* out, int count) {
    for (int k = 0; k < count; ++k) out[k] = 0;
    for (int i = 1; i + 1 < g.count; ++i) {
      const double area =
          0.5 * ((u[i] - u[0]) * (v[i + 1] - v[0]) - (u[i + 1] - u[0]) * (v[i] - v[0]));
      grundmannMoellerTriangle(D / 2, [&](double w, const double l[3]) {
        double m[M];
        monomials2<D>(l[0] * u[0] + l[1] * u[i] + l[2] * u[i + 1],
                      l[0] * v[0] + l[1] * v[i] + l[2] * v[i + 1], m);
        for (int k = 0; k < count; ++k) out[k] += area * w * m[k];
      });
    }
  };
  double m2[M];
  areaMoments(pu, pv, m2, monomialCount(2, 2));
  if (!(m2[0] > 0)) return rule;
  // Order 1, u, v, u2, uv, v2.
  const double mu = m2[1] / m2[0], mv = m2[2] / m2[0];
  Mat<2, 2> cov;
  cov(0, 0) = m2[3] / m2[0] - mu * mu;
  cov(0, 1) = cov(1, 0) = m2[4] / m2[0] - mu * mv;
  cov(1, 1) = m2[5] / m2[0] - mv * mv;
  double lambda[2];
  Mat<2, 2> q;
  symmetricEigen(cov, lambda, q);
  if (!(lambda[0] > 0)) return rule;
  const double floor = 1e-24 * lambda[0];
  // Whitened coordinates (a, b) = S Q^T ((pu, pv) - mean), S = diag(sqrt(var / lambda)).
  double s[2];
  for (int k = 0; k < 2; ++k)
    s[k] = sqrt(detail::kReferenceTriangleVariance / (lambda[k] > floor ? lambda[k] : floor));
  double wa[kCutPolygonMaxVertices], wb[kCutPolygonMaxVertices];
  for (int i = 0; i < g.count; ++i) {
    const double du = pu[i] - mu, dv = pv[i] - mv;
    wa[i] = s[0] * (q(0, 0) * du + q(1, 0) * dv);
    wb[i] = s[1] * (q(0, 1) * du + q(1, 1) * dv);
  }
  double moments[M];
  areaMoments(wa, wb, moments, M);
  double ra[M], rb[M];
  detail::referenceLattice2<D>(ra, rb);
  double a[M * M];
  for (int p = 0; p < M; ++p) {
    double m[M];
    monomials2<D>(ra[p], rb[p], m);
    for (int k = 0; k < M; ++k) a[k * M + p] = m[k];
  }
  if (!detail::solveDense(a, moments, M)) return rule;
  // dA = extent^2 dpu dpv = extent^2 |det Q| / (s0 s1) da db; the sign undoes a mirrored Q.
  const double jacobian = extent * extent * (q(0, 0) * q(1, 1) - q(0, 1) * q(1, 0)) / (s[0] * s[1]);
  for (int p = 0; p < M; ++p) {
    const double du = q(0, 0) * ra[p] / s[0] + q(0, 1) * rb[p] / s[1];
    const double dv = q(1, 0) * ra[p] / s[0] + q(1, 1) * rb[p] / s[1];
    rule.points[p] = origin + extent * ((mu + du) * e0 + (mv + dv) * e1);
    rule.weights[p] = jacobian * moments[p];
  }
  rule.normal = n;
  rule.count = M;
  return rule;
}

}  // namespace gf
