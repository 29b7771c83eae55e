// Hyperelastic energy densities, first Piola-Kirchhoff stress and dP/dF (SPEC §1).
//
// Design. All four isotropic models are written as functions of four invariants of the
// signed singular values s of F (svd3.h):
//   I1 = s0 + s1 + s2 = tr S,  I2 = sum s_i^2 = I_C,  I3 = s0 s1 s2 = J,  I4 = sum s_i^4 = II_C.
// Each model supplies only psi(I) with its first and second derivatives in I; one generic
// code path turns them into dpsi/ds, d2psi/ds2, P = U diag(dpsi/ds) V^T and dP/dF through
// the analytic eigen-system of isotropic energies (Smith et al. 2019 "Analytic eigensystems
// for isotropic distortion energies"; Kim & Eberle "Dynamic Deformables" ch. 7):
//   - 3 scaling modes U diag(e) V^T, e an eigenvector of the 3x3 d2psi/ds2;
//   - per pair (i,j) with third index k, a twist mode U (e_i e_j^T - e_j e_i^T) V^T / sqrt2
//     with eigenvalue (psi_i + psi_j)/(s_i + s_j) and a flip mode U (e_i e_j^T + e_j e_i^T)
//     V^T / sqrt2 with eigenvalue (psi_i - psi_j)/(s_i - s_j).
// Writing psi_i = psi_I1 + 2 s_i psi_I2 + psi_I3 s_j s_k + 4 s_i^3 psi_I4 makes both
// quotients closed-form:
//   flip  = 2 psi_I2 - psi_I3 s_k + 4 psi_I4 (s_i^2 + s_i s_j + s_j^2)
//   twist = 2 psi_I1 / (s_i + s_j) + 2 psi_I2 + psi_I3 s_k + 4 psi_I4 (s_i^2 - s_i s_j + s_j^2)
// so repeated singular values need no special case (the flip limit A_ii - A_ij comes out
// exactly), and only a psi_I1 term (co-rotational) can divide by s_i + s_j -> 0, where that
// energy really has a kink; there the denominator is bounded by kTwistDenominatorMin. The
// signed SVD (s0 >= s1 >= |s2|) keeps s_i + s_j >= 0 for inverted elements too.
// Clamping negative eigenvalues to zero gives the PSD projection that keeps the implicit
// system SPD; without projection the sum of the modes is the exact Hessian. The modes are
// handed on as rank-1 terms (HessianModes), not summed into a 9x9 matrix, so the element
// kernel maps 9 terms to nodes instead of a dense dP/dF. The 3x3 scaling block is split by
// its Cholesky factor where it is positive definite (any split into rank-1 terms sums to the
// same matrix; the eigen-solve, 4-6 Jacobi sweeps, cost a third of the element pass) and by
// its eigen-decomposition only where it is not.
//
// The anisotropic fibre term (Kim et al. 2019, eq 2.2/4.36) is added on top when
// fibreMu > 0 with its own analytic eigen-system (see detail::addFibre). Each term is
// projected on its own, as Kim et al. do: the sum of two PSD matrices is PSD and costs no 9x9
// eigen-solve, but where one term is indefinite and the other compensates, the result is
// stiffer than the nearest PSD matrix of the sum (projectPSD<9> would give that one).
//
// Vectorisation of 3x3 matrices is row-major throughout: vec(F)[3*i + j] = F(i, j).
#pragma once

#include "eigen_sym.h"
#include "math.h"
#include "svd3.h"

namespace gf {

/// Isotropic energy model; same order as gf::MaterialModel in graphfrac/defs.h.
enum EnergyModel : int { kCorotated = 0, kStVK = 1, kNeoHookean = 2, kStableNeoHookean = 3 };

/// Below this J the Neo-Hookean log J is replaced by its second-order Taylor expansion at
/// J = kNeoHookeanJMin, so the energy is finite and C2 for degenerate and inverted elements.
constexpr double kNeoHookeanJMin = 0.1;
/// Lower bound on s_i + s_j in the co-rotational twist eigenvalue (see the file comment).
constexpr double kTwistDenominatorMin = 1e-6;
/// Lower bound on |F a| in the fibre Hessian, whose curvature grows like 1/|F a| near F a = 0.
constexpr double kFibreStretchMin = 1e-8;

/// Per-element material coefficients as the kernels use them. mu and lambda are the model's
/// own parameters: for stable Neo-Hookean they are already reparametrised (eq 4.30).
/// T as in math.h: a batch carries one tet's (mu, lambda) a lane and no fibre term.
template <class T>
struct MaterialCoeffsT {
  int model = kStableNeoHookean;  ///< An EnergyModel.
  T mu = 0;                       ///< Shear parameter [Pa].
  T lambda = 0;                   ///< Bulk parameter [Pa].
  double fibreMu = 0;             ///< Fibre stiffness mu_f [Pa]; 0 = no fibre term.
  Vec3 fibreDir{1, 0, 0};         ///< Unit rest-space fibre direction a.
};
using MaterialCoeffs = MaterialCoeffsT<double>;

/// Coefficients from Young's modulus E and Poisson ratio nu. Lamé parameters by eq 4.29;
/// stable Neo-Hookean takes Smith et al. 2018's mu' = 4/3 mu, lambda' = lambda + 5/6 mu
/// (sec 4.2.5.1) so its small-strain stress equals linear elasticity (eq 4.28). The fibre
/// direction is normalised; a zero direction disables the fibre term rather than giving NaN.
GF_HD MaterialCoeffs makeMaterialCoeffs(int model, double E, double nu, double fibreMu,
                                        Vec3 fibreDir) {
  MaterialCoeffs c;
  c.model = model;
  const double mu = E / (2.0 * (1.0 + nu));                        // eq 4.29
  const double lambda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));  // eq 4.29
  if (model == kStableNeoHookean) {
    c.mu = 4.0 / 3.0 * mu;
    c.lambda = lambda + 5.0 / 6.0 * mu;
  } else {
    c.mu = mu;
    c.lambda = lambda;
  }
  const double len = norm(fibreDir);
  if (fibreMu > 0 && len > 0) {
    c.fibreMu = fibreMu;
    c.fibreDir = (1.0 / len) * fibreDir;
  }
  return c;
}

/// Most rank-1 terms of a material's dP/dF: 3 scaling, 3 twist and 3 flip modes of the
/// isotropic model, 4 of the fibre term.
constexpr int kMaxHessianModes = 13;

/// dP/dF as a sum of rank-1 terms sum_m w_m vec(Q_m) vec(Q_m)^T: the analytic eigen-systems
/// give it in this form, and the element kernel maps each Q_m to nodes (element.h) instead of
/// forming the 9x9 matrix. Terms of weight zero (clamped by the PSD projection) are not kept.
/// In a batch a term is kept unless its weight is zero in every lane.
template <class T>
struct HessianModesT {
  int count = 0;
  T w[kMaxHessianModes];
  T q[kMaxHessianModes][9];  ///< vec(Q_m), row-major

  GF_HD void add(T weight, const Mat3T<T>& Q) {
    if (Lanes<T>::all(weight == 0)) return;
    w[count] = weight;
    for (int k = 0; k < 9; ++k) q[count][k] = Q.m[k];
    ++count;
  }

  /// The 9x9 matrix sum_m w_m vec(Q_m) vec(Q_m)^T.
  GF_HD Mat<9, 9, T> matrix() const {
    Mat<9, 9, T> h;
    for (int m = 0; m < count; ++m)
      for (int a = 0; a < 9; ++a) {
        const T la = w[m] * q[m][a];
        for (int b = 0; b < 9; ++b) h.m[a * 9 + b] += la * q[m][b];
      }
    return h;
  }
};
using HessianModes = HessianModesT<double>;

namespace detail {

/// psi and its first and second derivatives in the invariants (I1, I2, I3, I4) = (tr S,
/// I_C, J, II_C).
template <class T>
struct InvariantDerivs {
  T psi = 0;
  T d[4] = {};
  T dd[4][4] = {};
};

/// Neo-Hookean log J, continued below kNeoHookeanJMin by its Taylor polynomial; returns the
/// value and its first two derivatives in J.
template <class T>
GF_HD T neoHookeanLog(T J, T& d1, T& d2) {
  using L = Lanes<T>;
  const double j0 = kNeoHookeanJMin;
  const T x = J - j0;
  d1 = 1.0 / j0 - x / (j0 * j0);
  d2 = T(-1.0 / (j0 * j0));
  T l = log(j0) + x / j0 - 0.5 * x * x / (j0 * j0);
  const MaskOf<T> above = J >= j0;
  if (L::any(above)) {
    d1 = L::select(above, 1.0 / J, d1);
    d2 = L::select(above, -1.0 / (J * J), d2);
    l = L::select(above, T(log(J)), l);
  }
  return l;
}

/// The isotropic model written in invariants of the signed singular values s.
template <class T>
GF_HD InvariantDerivs<T> isotropicInvariants(const MaterialCoeffsT<T>& c, Vec3T<T> s) {
  const T mu = c.mu, lambda = c.lambda;
  const T i1 = s.x + s.y + s.z;
  const T i2 = s.x * s.x + s.y * s.y + s.z * s.z;
  const T i3 = s.x * s.y * s.z;
  const T i4 = s.x * s.x * s.x * s.x + s.y * s.y * s.y * s.y + s.z * s.z * s.z * s.z;
  InvariantDerivs<T> r;
  switch (c.model) {
    case kCorotated: {
      // mu sum (s_i - 1)^2 + lambda/2 (tr S - 3)^2 = mu |F - R|^2 + lambda/2 tr(S - I)^2
      // (Müller & Gross 2004; the thesis lists no co-rotational energy).
      r.psi = mu * (i2 - 2.0 * i1 + 3.0) + 0.5 * lambda * (i1 - 3.0) * (i1 - 3.0);
      r.d[0] = -2.0 * mu + lambda * (i1 - 3.0);
      r.d[1] = mu;
      r.dd[0][0] = lambda;
      break;
    }
    case kStVK: {
      // lambda/8 (I_C - 3)^2 + mu/4 (II_C - 2 I_C + 3)  (eq 4.31; eq 2.1 drops the 2, which
      // would leave stress at rest).
      r.psi = 0.125 * lambda * (i2 - 3.0) * (i2 - 3.0) + 0.25 * mu * (i4 - 2.0 * i2 + 3.0);
      r.d[1] = 0.25 * lambda * (i2 - 3.0) - 0.5 * mu;
      r.d[3] = 0.25 * mu;
      r.dd[1][1] = 0.25 * lambda;
      break;
    }
    case kNeoHookean: {
      // mu/2 (I_C - 3) - mu log J + lambda/2 (log J)^2 (eq 2.1), log J continued below J_min.
      T l1, l2;
      const T l = neoHookeanLog(i3, l1, l2);
      r.psi = 0.5 * mu * (i2 - 3.0) - mu * l + 0.5 * lambda * l * l;
      r.d[1] = 0.5 * mu;
      r.d[2] = (lambda * l - mu) * l1;
      r.dd[2][2] = lambda * l1 * l1 + (lambda * l - mu) * l2;
      break;
    }
    default: {  // kStableNeoHookean
      // mu/2 (I_C - 3) + lambda/2 (J - alpha)^2 - mu/2 log(I_C + 1)  (eq 2.1, 4.30), minus its
      // value at F = I so that the rest energy is zero (forces are unchanged).
      // alpha = 1 + 3 mu / (4 lambda) makes F = I stress-free; lambda > 0 always holds for
      // the reparametrised coefficients with nu in (-1, 0.5).
      const T alpha = Lanes<T>::select(lambda > 0, 1.0 + 0.75 * mu / lambda, T(1.0));
      const T rest = 0.5 * lambda * (1.0 - alpha) * (1.0 - alpha) - 0.5 * mu * log(4.0);
      r.psi = 0.5 * mu * (i2 - 3.0) + 0.5 * lambda * (i3 - alpha) * (i3 - alpha) -
              0.5 * mu * log(i2 + 1.0) - rest;
      r.d[1] = 0.5 * mu - 0.5 * mu / (i2 + 1.0);
      r.d[2] = lambda * (i3 - alpha);
      r.dd[1][1] = 0.5 * mu / ((i2 + 1.0) * (i2 + 1.0));
      r.dd[2][2] = lambda;
      break;
    }
  }
  return r;
}

/// dI/ds_a for the four invariants.
template <class T>
GF_HD void invariantGradient(Vec3T<T> s, int a, T g[4]) {
  const T sa = s[a], sb = s[(a + 1) % 3], sc = s[(a + 2) % 3];
  g[0] = 1.0;
  g[1] = 2.0 * sa;
  g[2] = sb * sc;
  g[3] = 4.0 * sa * sa * sa;
}

template <class T>
GF_HD Vec3T<T> gradientFromInvariants(const InvariantDerivs<T>& r, Vec3T<T> s) {
  Vec3T<T> g;
  for (int a = 0; a < 3; ++a) {
    T dI[4];
    invariantGradient(s, a, dI);
    g[a] = r.d[0] * dI[0] + r.d[1] * dI[1] + r.d[2] * dI[2] + r.d[3] * dI[3];
  }
  return g;
}

template <class T>
GF_HD Mat3T<T> hessianFromInvariants(const InvariantDerivs<T>& r, Vec3T<T> s) {
  T dI[3][4];
  for (int a = 0; a < 3; ++a) invariantGradient(s, a, dI[a]);
  Mat3T<T> h;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) {
      T v = 0;
      for (int p = 0; p < 4; ++p)
        for (int q = 0; q < 4; ++q) v += r.dd[p][q] * dI[a][p] * dI[b][q];
      // Second derivatives of the invariants themselves.
      if (a == b) {
        v += 2.0 * r.d[1] + 12.0 * s[a] * s[a] * r.d[3];
      } else {
        v += r.d[2] * s[3 - a - b];
      }
      h(a, b) = v;
    }
  return h;
}

/// u_a v_b^T for columns of U and V.
template <class T>
GF_HD Mat3T<T> outerUV(const Svd3T<T>& svd, int a, int b) {
  Mat3T<T> q;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) q(i, j) = svd.U(i, a) * svd.V(j, b);
  return q;
}

/// Scaling modes of an isotropic energy: the 3x3 d2psi/ds2 A split into rank-1 terms
/// w_m k_m k_m^T over span{u_a v_a^T}, each added as the mode U diag(k_m) V^T. A positive
/// definite A (the common case) is split by its Cholesky factor, which is cheaper than an
/// eigen-solve and exact to round-off; an indefinite A takes the eigen-decomposition, with
/// negative eigenvalues dropped when projecting (then the sum is the nearest PSD matrix).
template <class T>
GF_HD void addScalingModes(const Mat3T<T>& A, const Svd3T<T>& svd, HessianModesT<T>& modes,
                           bool projectPsd) {
  using L = Lanes<T>;
  Mat3T<T> k;  // columns k_m
  T w[3] = {1, 1, 1};
  // Cholesky; a pivot that is not positive (or a NaN from the one before) marks A indefinite.
  const T d0 = A(0, 0);
  const T l00 = sqrt(d0);
  const T l10 = A(1, 0) / l00, l20 = A(2, 0) / l00;
  const T d1 = A(1, 1) - l10 * l10;
  const T l11 = sqrt(d1);
  const T l21 = (A(2, 1) - l20 * l10) / l11;
  const T d2 = A(2, 2) - l20 * l20 - l21 * l21;
  const MaskOf<T> pd = d0 > 0 && d1 > 0 && d2 > 0;
  k(0, 0) = l00;
  k(1, 0) = l10;
  k(2, 0) = l20;
  k(1, 1) = l11;
  k(2, 1) = l21;
  k(2, 2) = sqrt(d2);
  if (!L::all(pd)) {
    // Indefinite blocks are rare (strongly compressed tets): each such lane on its own.
    for (int l = 0; l < L::kWidth; ++l) {
      if (L::lane(pd, l)) continue;
      Mat3 a, kl;
      double wl[3];
      for (int e = 0; e < 9; ++e) a.m[e] = L::lane(A.m[e], l);
      if constexpr (L::kWidth == 1) {
        symmetricEigen<3>(a, wl, kl);
      } else {
        L::eigen3(a, wl, kl);  // out of line: see fem/element_lanes_batch.h
      }
      for (int e = 0; e < 9; ++e) L::setLane(k.m[e], l, kl.m[e]);
      for (int m = 0; m < 3; ++m) L::setLane(w[m], l, wl[m]);
    }
  }
  for (int m = 0; m < 3; ++m) {
    const T wm = projectPsd ? L::select(w[m] <= 0, T(0), w[m]) : w[m];
    if (L::all(wm == 0)) continue;
    Mat3T<T> q;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        q(i, j) = svd.U(i, 0) * k(0, m) * svd.V(j, 0) + svd.U(i, 1) * k(1, m) * svd.V(j, 1) +
                  svd.U(i, 2) * k(2, m) * svd.V(j, 2);
    modes.add(wm, q);
  }
}

/// Isotropic psi (returned), P = U diag(dpsi/ds) V^T (overwritten) and, when modes is
/// non-null, the analytic eigen-system of dP/dF added to it.
template <class T>
GF_HD T isotropicEvaluate(const MaterialCoeffsT<T>& c, const Svd3T<T>& svd, Mat3T<T>& P,
                          HessianModesT<NoDeduce<T>>* modes, bool projectPsd) {
  using L = Lanes<T>;
  const Vec3T<T> s = svd.s;
  const InvariantDerivs<T> r = isotropicInvariants(c, s);
  const Vec3T<T> g = gradientFromInvariants(r, s);

  P = Mat3T<T>{};
  for (int a = 0; a < 3; ++a) P = P + g[a] * outerUV(svd, a, a);
  if (modes == nullptr) return r.psi;

  addScalingModes(hessianFromInvariants(r, s), svd, *modes, projectPsd);

  // Twist and flip modes of each pair (i, j); k is the remaining index. The modes are
  // U (e_i e_j^T -+ e_j e_i^T) V^T / sqrt2: the 1/2 of their squares goes to the weights.
  for (int k = 2; k >= 0; --k) {
    const int i = k == 0 ? 1 : 0;
    const int j = k == 2 ? 1 : 2;
    const T si = s[i], sj = s[j], sk = s[k];
    const T flip = 2.0 * r.d[1] - r.d[2] * sk + 4.0 * r.d[3] * (si * si + si * sj + sj * sj);
    T twist = 2.0 * r.d[1] + r.d[2] * sk + 4.0 * r.d[3] * (si * si - si * sj + sj * sj);
    const MaskOf<T> kink = r.d[0] != 0;
    if (L::any(kink)) {
      // svd3 puts the sign of det F on the singular value of smallest magnitude, so
      // s_i + s_j >= 0 even for inverted elements; a negative sum is round-off at the kink
      // s_j = -s_i, whose side is the positive one.
      const T den = L::select(si + sj < kTwistDenominatorMin, T(kTwistDenominatorMin), si + sj);
      twist = L::select(kink, twist + 2.0 * r.d[0] / den, twist);
    }
    const Mat3T<T> uij = outerUV(svd, i, j);
    const Mat3T<T> uji = outerUV(svd, j, i);
    // A weight of zero drops the term (HessianModesT::add).
    modes->add(projectPsd ? L::select(twist < 0, T(0), 0.5 * twist) : 0.5 * twist, uij - uji);
    modes->add(projectPsd ? L::select(flip < 0, T(0), 0.5 * flip) : 0.5 * flip, uij + uji);
  }
  return r.psi;
}

/// I4 = a^T S a with S = V diag(s) V^T (eq 4.35); only its sign is used.
GF_HD double fibreSign(const MaterialCoeffs& c, const Svd3& svd) {
  double i4 = 0;
  for (int a = 0; a < 3; ++a) {
    const double va = dot(column(svd.V, a), c.fibreDir);
    i4 += svd.s[a] * va * va;
  }
  return i4 >= 0 ? 1.0 : -1.0;
}

/// psi_AA = mu_f/2 (sqrt(I5) - sign(I4))^2, I5 = |F a|^2 (eq 4.36).
GF_HD double fibreEnergy(const MaterialCoeffs& c, const Mat3& F, const Svd3& svd) {
  const double sign = fibreSign(c, svd);
  const double r = norm(F * c.fibreDir) - sign;
  return 0.5 * c.fibreMu * r * r;
}

/// Adds the fibre term's P = mu_f (1 - sign/sqrt(I5)) F a a^T and, when H is non-null, its
/// Hessian mu_f (1 - sign/sqrt(I5)) (I (x) a a^T) + mu_f sign I5^(-3/2) g g^T, g = vec(F a a^T).
/// On the 3-D subspace {vec(w a^T)} its eigenvalues are mu_f on g and mu_f (1 - sign/sqrt(I5))
/// on the two directions orthogonal to g, zero elsewhere, so the projection clamps only that
/// one (Kim et al. 2019).
GF_HD void addFibre(const MaterialCoeffs& c, const Mat3& F, const Svd3& svd, Mat3& P,
                    HessianModes* modes, bool projectPsd) {
  const Vec3 a = c.fibreDir;
  const Vec3 fa = F * a;
  const double sign = fibreSign(c, svd);
  const double len = norm(fa);
  // F a / |F a|, zero at F a = 0 where the energy has a cone point (a subgradient).
  const Vec3 dir = len > 0 ? (1.0 / len) * fa : Vec3{0, 0, 0};
  const Vec3 pa = c.fibreMu * (fa - sign * dir);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) P(i, j) += pa[i] * a[j];
  if (modes == nullptr) return;

  const double l = len > kFibreStretchMin ? len : kFibreStretchMin;
  const double coefIso = c.fibreMu * (1.0 - sign / l);
  if (!projectPsd || coefIso >= 0) {
    // coefIso (I (x) a a^T) = coefIso sum_i vec(e_i a^T) vec(e_i a^T)^T.
    for (int i = 0; i < 3; ++i) {
      Mat3 e;
      for (int j = 0; j < 3; ++j) e(i, j) = a[j];
      modes->add(coefIso, e);
    }
    const double coefG = c.fibreMu * sign / (l * l * l);
    Mat3 g;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) g(i, j) = fa[i] * a[j];
    modes->add(coefG, g);
  } else {
    // Only the g direction (eigenvalue mu_f) survives: mu_f ghat ghat^T, ghat = vec(dir a^T).
    Mat3 gh;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) gh(i, j) = dir[i] * a[j];
    modes->add(c.fibreMu, gh);
  }
}

}  // namespace detail

/// Isotropic energy density psi(s) at signed singular values s.
template <class T>
GF_HD T isotropicEnergy(const MaterialCoeffsT<T>& c, Vec3T<T> s) {
  return detail::isotropicInvariants(c, s).psi;
}

/// dpsi/ds at signed singular values s.
GF_HD Vec3 isotropicGradient(const MaterialCoeffs& c, Vec3 s) {
  return detail::gradientFromInvariants(detail::isotropicInvariants(c, s), s);
}

/// d2psi/ds2 (3x3, symmetric) at signed singular values s.
GF_HD Mat3 isotropicHessian(const MaterialCoeffs& c, Vec3 s) {
  return detail::hessianFromInvariants(detail::isotropicInvariants(c, s), s);
}

/// Energy density psi(F) [J/m^3], P = dpsi/dF and, when modes is non-null, dP/dF as rank-1
/// terms added to it, all from svd = svd3(F) (e.g. from an SVD cache, svd3.h); the isotropic
/// model plus the fibre term when fibreMu > 0. See firstPiolaAndHessian for projectPsd.
/// A batch (T not double) evaluates the isotropic model alone: its lanes carry no fibre term.
template <class T>
GF_HD T evaluateMaterialModes(const MaterialCoeffsT<T>& c, const Mat3T<T>& F, const Svd3T<T>& svd,
                              Mat3T<T>& P, HessianModesT<NoDeduce<T>>* modes, bool projectPsd) {
  T psi = detail::isotropicEvaluate(c, svd, P, modes, projectPsd);
  if constexpr (Lanes<T>::kWidth == 1) {
    if (c.fibreMu > 0) {
      psi += detail::fibreEnergy(c, F, svd);
      detail::addFibre(c, F, svd, P, modes, projectPsd);
    }
  }
  return psi;
}

/// evaluateMaterialModes with dP/dF formed as a 9x9 matrix (when dPdF is non-null).
GF_HD double evaluateMaterialSvd(const MaterialCoeffs& c, const Mat3& F, const Svd3& svd, Mat3& P,
                                 Mat9* dPdF, bool projectPsd) {
  if (dPdF == nullptr) return evaluateMaterialModes(c, F, svd, P, nullptr, projectPsd);
  HessianModes modes;
  const double psi = evaluateMaterialModes(c, F, svd, P, &modes, projectPsd);
  *dPdF = modes.matrix();
  return psi;
}

GF_HD double evaluateMaterial(const MaterialCoeffs& c, const Mat3& F, Mat3& P, Mat9* dPdF,
                              bool projectPsd, Svd3* svdOut = nullptr) {
  const Svd3 svd = svd3(F);
  if (svdOut != nullptr) *svdOut = svd;
  return evaluateMaterialSvd(c, F, svd, P, dPdF, projectPsd);
}

/// energyDensity with svd = svd3(F) already known: psi alone, no stress. The same operations
/// as evaluateMaterial's psi, so the same bits.
template <class T>
GF_HD T energyDensitySvd(const MaterialCoeffsT<T>& c, const Mat3T<T>& F, const Svd3T<T>& svd) {
  T psi = isotropicEnergy(c, svd.s);
  if constexpr (Lanes<T>::kWidth == 1) {
    if (c.fibreMu > 0) psi += detail::fibreEnergy(c, F, svd);
  }
  return psi;
}

/// Energy density psi(F) [J/m^3]: the isotropic model plus the fibre term when fibreMu > 0.
GF_HD double energyDensity(const MaterialCoeffs& c, const Mat3& F) {
  return energyDensitySvd(c, F, svd3(F));
}

/// First Piola-Kirchhoff stress P = dpsi/dF.
GF_HD Mat3 firstPiola(const MaterialCoeffs& c, const Mat3& F) {
  Mat3 P;
  evaluateMaterial(c, F, P, nullptr, false);
  return P;
}

/// P and dP/dF (9x9, row-major vec: index 3*i+j is F(i,j)). With projectPsd every negative
/// eigenvalue of each term's analytic eigen-system is clamped to zero, so dPdF is positive
/// semi-definite (for an isotropic model it is then the nearest PSD matrix); without it dPdF
/// is the exact Hessian of psi.
GF_HD void firstPiolaAndHessian(const MaterialCoeffs& c, const Mat3& F, Mat3& P, Mat9& dPdF,
                                bool projectPsd) {
  evaluateMaterial(c, F, P, &dPdF, projectPsd);
}

}  // namespace gf
