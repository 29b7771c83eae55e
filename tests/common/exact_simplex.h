// Exact integrals of polynomials over tets and triangles, independent of the runtime's
// quadrature: expand each monomial in barycentric coordinates and use
// integral over a simplex of prod lambda_i^k_i = n! |T| prod k_i! / (sum k_i + n)!,
// plus an independent clip of tets by planes (the classic 1-3, 2-2, 3-1 vertex cases into tets).
// For tests of the Is-XFEM moment-fitting rules.
#pragma once

#include <array>
#include <cmath>
#include <vector>

#include "kernels/math.h"

namespace gf::test {

using Exponent = std::array<int, 3>;

/// All exponents of total degree <= d.
inline std::vector<Exponent> exponentsUpTo(int d) {
  std::vector<Exponent> e;
  for (int t = 0; t <= d; ++t)
    for (int a = t; a >= 0; --a)
      for (int b = t - a; b >= 0; --b) e.push_back({a, b, t - a - b});
  return e;
}

inline double factorial(int n) { return n <= 1 ? 1.0 : n * factorial(n - 1); }

/// Exact integral of prod_k ((x - o)_k / L)^e_k over the simplex with vertices v[0..n]
/// (n = 3: tet, n = 2: triangle in 3-space), of measure `measure`.
template <int N>
double simplexMonomialIntegral(const std::array<Vec3, N + 1>& v, double measure, Vec3 o, double L,
                               const Exponent& e) {
  // Polynomial in the N + 1 barycentric coordinates: coefficient per exponent vector, dense.
  const int deg = e[0] + e[1] + e[2];
  const int side = deg + 1;
  int size = 1;
  for (int k = 0; k <= N; ++k) size *= side;
  std::vector<double> poly(static_cast<size_t>(size), 0.0), next(static_cast<size_t>(size));
  poly[0] = 1;
  auto index = [&](const int* k) {
    int i = 0;
    for (int j = N; j >= 0; --j) i = i * side + k[j];
    return i;
  };
  for (int axis = 0; axis < 3; ++axis)
    for (int p = 0; p < e[axis]; ++p) {
      std::fill(next.begin(), next.end(), 0.0);
      for (int i = 0; i < size; ++i) {
        if (poly[size_t(i)] == 0) continue;
        int k[N + 1];
        for (int j = 0, r = i; j <= N; ++j, r /= side) k[j] = r % side;
        for (int j = 0; j <= N; ++j) {
          int kk[N + 1];
          for (int t = 0; t <= N; ++t) kk[t] = k[t];
          ++kk[j];
          next[size_t(index(kk))] += poly[size_t(i)] * (v[size_t(j)][axis] - o[axis]) / L;
        }
      }
      poly.swap(next);
    }
  double sum = 0;
  for (int i = 0; i < size; ++i) {
    if (poly[size_t(i)] == 0) continue;
    int k[N + 1], total = 0;
    double f = 1;
    for (int j = 0, r = i; j <= N; ++j, r /= side) {
      k[j] = r % side;
      total += k[j];
      f *= factorial(k[j]);
    }
    sum += poly[size_t(i)] * factorial(N) * f / factorial(total + N);
  }
  return measure * sum;
}

using Tet = std::array<Vec3, 4>;

inline double tetVolume(const Tet& t) {
  return std::abs(dot(t[1] - t[0], cross(t[2] - t[0], t[3] - t[0]))) / 6.0;
}

/// The part of `t` where side * (n.x - offset) >= 0, as tets (the classic vertex cases).
inline void clipTetIntoTets(const Tet& t, Vec3 n, double offset, double side,
                            std::vector<Tet>& out) {
  double d[4];
  int in[4], outv[4], ni = 0, no = 0;
  for (int a = 0; a < 4; ++a) {
    d[a] = side * (dot(n, t[size_t(a)]) - offset);
    if (d[a] >= 0)
      in[ni++] = a;
    else
      outv[no++] = a;
  }
  auto cut = [&](int a, int b) {
    return t[size_t(a)] + (d[a] / (d[a] - d[b])) * (t[size_t(b)] - t[size_t(a)]);
  };
  // Prism (bottom p0 p1 p2, top q0 q1 q2 with lateral edges p_i q_i) as three tets.
  auto prism = [&](Vec3 p0, Vec3 p1, Vec3 p2, Vec3 q0, Vec3 q1, Vec3 q2) {
    out.push_back({p0, p1, p2, q0});
    out.push_back({p1, p2, q0, q1});
    out.push_back({p2, q0, q1, q2});
  };
  if (ni == 4) {
    out.push_back(t);
  } else if (ni == 1) {
    const int a = in[0];
    out.push_back({t[size_t(a)], cut(a, outv[0]), cut(a, outv[1]), cut(a, outv[2])});
  } else if (ni == 3) {
    const int c = outv[0];
    prism(t[size_t(in[0])], t[size_t(in[1])], t[size_t(in[2])], cut(in[0], c), cut(in[1], c),
          cut(in[2], c));
  } else if (ni == 2) {
    const int a = in[0], b = in[1], c = outv[0], e = outv[1];
    prism(t[size_t(a)], cut(a, c), cut(a, e), t[size_t(b)], cut(b, c), cut(b, e));
  }
}

}  // namespace gf::test
