// Small fixed-size linear algebra for per-element kernels (double precision: stiff materials
// at game time steps need it, see docs/design.md). Matrices are row-major.
#pragma once

#include "lanes.h"

namespace gf {

/// T is double, or on the CPU's element pass a SIMD batch of one value per tet (lanes.h).
template <class T>
struct Vec3T {
  T x = 0, y = 0, z = 0;
  GF_HD T& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
  GF_HD T operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
};
using Vec3 = Vec3T<double>;

/// The scalar type of a kernel argument without deducing from it, so a double literal or a
/// double factor combines with a batch.
template <class T>
struct ScalarOf {
  using type = T;
};
template <class T>
using NoDeduce = typename ScalarOf<T>::type;

template <class T>
GF_HD Vec3T<T> operator+(Vec3T<T> a, Vec3T<T> b) {
  return {a.x + b.x, a.y + b.y, a.z + b.z};
}
template <class T>
GF_HD Vec3T<T> operator-(Vec3T<T> a, Vec3T<T> b) {
  return {a.x - b.x, a.y - b.y, a.z - b.z};
}
template <class T>
GF_HD Vec3T<T> operator-(Vec3T<T> a) {
  return {-a.x, -a.y, -a.z};
}
template <class T>
GF_HD Vec3T<T> operator*(NoDeduce<T> s, Vec3T<T> a) {
  return {s * a.x, s * a.y, s * a.z};
}
template <class T>
GF_HD Vec3T<T> operator*(Vec3T<T> a, NoDeduce<T> s) {
  return {s * a.x, s * a.y, s * a.z};
}
template <class T>
GF_HD Vec3T<T>& operator+=(Vec3T<T>& a, Vec3T<T> b) {
  a.x += b.x;
  a.y += b.y;
  a.z += b.z;
  return a;
}
template <class T>
GF_HD Vec3T<T>& operator-=(Vec3T<T>& a, Vec3T<T> b) {
  a.x -= b.x;
  a.y -= b.y;
  a.z -= b.z;
  return a;
}
template <class T>
GF_HD T dot(Vec3T<T> a, Vec3T<T> b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
template <class T>
GF_HD Vec3T<T> cross(Vec3T<T> a, Vec3T<T> b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
template <class T>
GF_HD T norm(Vec3T<T> a) {
  return sqrt(dot(a, a));
}

/// Fixed-size row-major matrix; Mat<3,3> is the deformation gradient, Mat<9,9> dP/dF,
/// Mat<12,12> an element Hessian.
template <int R, int C, class T = double>
struct Mat {
  T m[R * C] = {};
  GF_HD T& operator()(int i, int j) { return m[i * C + j]; }
  GF_HD T operator()(int i, int j) const { return m[i * C + j]; }
  GF_HD static Mat identity() {
    Mat a;
    for (int i = 0; i < (R < C ? R : C); ++i) a(i, i) = 1.0;
    return a;
  }
};
using Mat3 = Mat<3, 3>;
template <class T>
using Mat3T = Mat<3, 3, T>;
using Mat9 = Mat<9, 9>;
using Mat12 = Mat<12, 12>;

/// A tet's 12x12 element matrix (node-major, symmetric) as the element buffers store it for
/// assembly: its 10 upper node blocks (a <= b) in the order (0,0) (0,1) (0,2) (0,3) (1,1) ...
/// (3,3), each 3x3 row-major; block (b, a) is the transpose of block (a, b). 90 doubles
/// against 144 (issue 14): the diagonal blocks are kept whole so assembly copies them as is.
constexpr int kElementMatrixSize = 90;

/// Offset in that storage of node block (a, b), a <= b.
GF_HD int upperBlockOffset(int a, int b) { return 9 * (a * (7 - a) / 2 + b); }

/// Writes the upper node blocks of the row-major 12x12 `full` into `out` (kElementMatrixSize).
GF_HD void storeUpperBlocks(const double* full, double* out) {
  for (int a = 0; a < 4; ++a)
    for (int b = a; b < 4; ++b)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) *out++ = full[12 * (3 * a + i) + 3 * b + j];
}

template <int R, int C, class T>
GF_HD Mat<R, C, T> operator+(const Mat<R, C, T>& a, const Mat<R, C, T>& b) {
  Mat<R, C, T> c;
  for (int i = 0; i < R * C; ++i) c.m[i] = a.m[i] + b.m[i];
  return c;
}
template <int R, int C, class T>
GF_HD Mat<R, C, T> operator-(const Mat<R, C, T>& a, const Mat<R, C, T>& b) {
  Mat<R, C, T> c;
  for (int i = 0; i < R * C; ++i) c.m[i] = a.m[i] - b.m[i];
  return c;
}
template <int R, int C, class T>
GF_HD Mat<R, C, T> operator*(NoDeduce<T> s, const Mat<R, C, T>& a) {
  Mat<R, C, T> c;
  for (int i = 0; i < R * C; ++i) c.m[i] = s * a.m[i];
  return c;
}
template <int R, int K, int C, class T>
GF_HD Mat<R, C, T> operator*(const Mat<R, K, T>& a, const Mat<K, C, T>& b) {
  Mat<R, C, T> c;
  for (int i = 0; i < R; ++i)
    for (int k = 0; k < K; ++k) {
      const T aik = a(i, k);
      for (int j = 0; j < C; ++j) c(i, j) += aik * b(k, j);
    }
  return c;
}
template <int R, int C, class T>
GF_HD Mat<C, R, T> transpose(const Mat<R, C, T>& a) {
  Mat<C, R, T> t;
  for (int i = 0; i < R; ++i)
    for (int j = 0; j < C; ++j) t(j, i) = a(i, j);
  return t;
}
template <class T>
GF_HD Vec3T<T> operator*(const Mat3T<T>& a, Vec3T<T> v) {
  return {a(0, 0) * v.x + a(0, 1) * v.y + a(0, 2) * v.z,
          a(1, 0) * v.x + a(1, 1) * v.y + a(1, 2) * v.z,
          a(2, 0) * v.x + a(2, 1) * v.y + a(2, 2) * v.z};
}
template <class T>
GF_HD Mat3T<T> fromColumns(Vec3T<T> a, Vec3T<T> b, Vec3T<T> c) {
  Mat3T<T> m;
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
template <class T>
GF_HD Vec3T<T> column(const Mat3T<T>& m, int j) {
  return {m(0, j), m(1, j), m(2, j)};
}
template <class T>
GF_HD T trace(const Mat3T<T>& a) {
  return a(0, 0) + a(1, 1) + a(2, 2);
}
template <class T>
GF_HD T det(const Mat3T<T>& a) {
  return a(0, 0) * (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1)) -
         a(0, 1) * (a(1, 0) * a(2, 2) - a(1, 2) * a(2, 0)) +
         a(0, 2) * (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0));
}
/// Inverse; the caller guarantees det != 0 (rest shapes are validated on load).
template <class T>
GF_HD Mat3T<T> inverse(const Mat3T<T>& a) {
  Mat3T<T> r;
  const T id = 1.0 / det(a);
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
template <int R, int C, class T>
GF_HD T frobeniusDot(const Mat<R, C, T>& a, const Mat<R, C, T>& b) {
  T s = 0;
  for (int i = 0; i < R * C; ++i) s += a.m[i] * b.m[i];
  return s;
}

}  // namespace gf
