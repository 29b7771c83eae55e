// Small fixed-size linear algebra for per-element kernels (double precision: stiff materials
// at game time steps need it, see docs/design.md). Matrices are row-major.
#pragma once

#include "gf_hd.h"

namespace gf {

struct Vec3 {
  double x = 0, y = 0, z = 0;
  GF_HD double& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
  GF_HD double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
};

GF_HD Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
GF_HD Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
GF_HD Vec3 operator-(Vec3 a) { return {-a.x, -a.y, -a.z}; }
GF_HD Vec3 operator*(double s, Vec3 a) { return {s * a.x, s * a.y, s * a.z}; }
GF_HD Vec3 operator*(Vec3 a, double s) { return {s * a.x, s * a.y, s * a.z}; }
GF_HD Vec3& operator+=(Vec3& a, Vec3 b) {
  a.x += b.x;
  a.y += b.y;
  a.z += b.z;
  return a;
}
GF_HD Vec3& operator-=(Vec3& a, Vec3 b) {
  a.x -= b.x;
  a.y -= b.y;
  a.z -= b.z;
  return a;
}
GF_HD double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
GF_HD Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
GF_HD double norm(Vec3 a) { return sqrt(dot(a, a)); }

/// Fixed-size row-major matrix; Mat<3,3> is the deformation gradient, Mat<9,9> dP/dF,
/// Mat<12,12> an element Hessian.
template <int R, int C>
struct Mat {
  double m[R * C] = {};
  GF_HD double& operator()(int i, int j) { return m[i * C + j]; }
  GF_HD double operator()(int i, int j) const { return m[i * C + j]; }
  GF_HD static Mat identity() {
    Mat a;
    for (int i = 0; i < (R < C ? R : C); ++i) a(i, i) = 1.0;
    return a;
  }
};
using Mat3 = Mat<3, 3>;
using Mat9 = Mat<9, 9>;
using Mat12 = Mat<12, 12>;

template <int R, int C>
GF_HD Mat<R, C> operator+(const Mat<R, C>& a, const Mat<R, C>& b) {
  Mat<R, C> c;
  for (int i = 0; i < R * C; ++i) c.m[i] = a.m[i] + b.m[i];
  return c;
}
template <int R, int C>
GF_HD Mat<R, C> operator-(const Mat<R, C>& a, const Mat<R, C>& b) {
  Mat<R, C> c;
  for (int i = 0; i < R * C; ++i) c.m[i] = a.m[i] - b.m[i];
  return c;
}
template <int R, int C>
GF_HD Mat<R, C> operator*(double s, const Mat<R, C>& a) {
  Mat<R, C> c;
  for (int i = 0; i < R * C; ++i) c.m[i] = s * a.m[i];
  return c;
}
template <int R, int K, int C>
GF_HD Mat<R, C> operator*(const Mat<R, K>& a, const Mat<K, C>& b) {
  Mat<R, C> c;
  for (int i = 0; i < R; ++i)
    for (int k = 0; k < K; ++k) {
      const double aik = a(i, k);
      for (int j = 0; j < C; ++j) c(i, j) += aik * b(k, j);
    }
  return c;
}
template <int R, int C>
GF_HD Mat<C, R> transpose(const Mat<R, C>& a) {
  Mat<C, R> t;
  for (int i = 0; i < R; ++i)
    for (int j = 0; j < C; ++j) t(j, i) = a(i, j);
  return t;
}
GF_HD Vec3 operator*(const Mat3& a, Vec3 v) {
  return {a(0, 0) * v.x + a(0, 1) * v.y + a(0, 2) * v.z,
          a(1, 0) * v.x + a(1, 1) * v.y + a(1, 2) * v.z,
          a(2, 0) * v.x + a(2, 1) * v.y + a(2, 2) * v.z};
}
GF_HD Mat3 fromColumns(Vec3 a, Vec3 b, Vec3 c) {
  Mat3 m;
  m(0, 0) = a.x;
  m(0, 1) = b.x;
  m(0, 2) = c.x;
  m(1, 0) = a.y;
  m(1, 1) = b.y;
  m(1, 2) = c.y;
  m(2, 0) = a.z;
  m(2, 1) = b.z;
  m(2, 2) = c.z;
  return m;
}
GF_HD Vec3 column(const Mat3& m, int j) { return {m(0, j), m(1, j), m(2, j)}; }
GF_HD double trace(const Mat3& a) { return a(0, 0) + a(1, 1) + a(2, 2); }
GF_HD double det(const Mat3& a) {
  return a(0, 0) * (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1)) -
         a(0, 1) * (a(1, 0) * a(2, 2) - a(1, 2) * a(2, 0)) +
         a(0, 2) * (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0));
}
/// Inverse; the caller guarantees det != 0 (rest shapes are validated on load).
GF_HD Mat3 inverse(const Mat3& a) {
  Mat3 r;
  const double id = 1.0 / det(a);
  r(0, 0) = (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1)) * id;
  r(0, 1) = (a(0, 2) * a(2, 1) - a(0, 1) * a(2, 2)) * id;
  r(0, 2) = (a(0, 1) * a(1, 2) - a(0, 2) * a(1, 1)) * id;
  r(1, 0) = (a(1, 2) * a(2, 0) - a(1, 0) * a(2, 2)) * id;
  r(1, 1) = (a(0, 0) * a(2, 2) - a(0, 2) * a(2, 0)) * id;
  r(1, 2) = (a(0, 2) * a(1, 0) - a(0, 0) * a(1, 2)) * id;
  r(2, 0) = (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0)) * id;
  r(2, 1) = (a(0, 1) * a(2, 0) - a(0, 0) * a(2, 1)) * id;
  r(2, 2) = (a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0)) * id;
  return r;
}
template <int R, int C>
GF_HD double frobeniusDot(const Mat<R, C>& a, const Mat<R, C>& b) {
  double s = 0;
  for (int i = 0; i < R * C; ++i) s += a.m[i] * b.m[i];
  return s;
}

}  // namespace gf
