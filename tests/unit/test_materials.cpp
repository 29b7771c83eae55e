// Material kernels (SPEC §1) against independent truths: central finite differences of the
// energy and of P, Eigen's SVD and eigen-solver, linear elasticity at small strain (eq 4.28),
// and invariance under rotations.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "common/random_rotation.h"
#include "kernels/eigen_sym.h"
#include "kernels/materials.h"
#include "kernels/svd3.h"

namespace {

using gf::Mat3;
using gf::Mat9;
using gf::MaterialCoeffs;
using gf::Vec3;
using gf::test::frob;
using gf::test::frob9;
using gf::test::randomRotation;

constexpr double kE = 1e6;
constexpr double kNu = 0.3;
const char* const kModelNames[] = {"corotated", "stvk", "neohookean", "stable-neohookean"};

Mat3 diag(double a, double b, double c) {
  Mat3 m;
  m(0, 0) = a;
  m(1, 1) = b;
  m(2, 2) = c;
  return m;
}

struct NamedF {
  std::string name;
  Mat3 F;
};

/// The deformation gradients every derivative check runs on: random, near-inverted
/// (det ~ 1e-3), inverted (det < 0), rotated, stretched and with repeated singular values.
std::vector<NamedF> testDeformations() {
  std::mt19937 rng(20240611);
  std::normal_distribution<double> n(0, 1);
  std::vector<NamedF> out;
  for (int k = 0; k < 6; ++k) {
    Mat3 f = Mat3::identity();
    for (double& v : f.m) v += 0.3 * n(rng);
    if (gf::det(f) <= 0.2) {
      --k;  // keep this group non-inverted; inversion has its own cases
      continue;
    }
    out.push_back({"random" + std::to_string(k), f});
  }
  for (int k = 0; k < 3; ++k) {
    const double s0 = 1.2 + 0.1 * k, s1 = 0.9 - 0.05 * k;
    out.push_back(
        {"near-inverted" + std::to_string(k),
         randomRotation(rng) * diag(s0, s1, 1e-3 / (s0 * s1)) * transpose(randomRotation(rng))});
  }
  out.push_back(
      {"inverted-a", randomRotation(rng) * diag(1.1, 0.8, -0.4) * transpose(randomRotation(rng))});
  out.push_back(
      {"inverted-b", randomRotation(rng) * diag(0.9, 0.7, -0.05) * transpose(randomRotation(rng))});
  out.push_back(
      {"inverted-c", randomRotation(rng) * diag(1.5, 1.0, -0.6) * transpose(randomRotation(rng))});
  // The inverted axis is not the shortest: a naive signed SVD would give s1 + s2 = -0.3, where
  // the co-rotational twist eigenvalue 2 psi_I1 / (s1 + s2) changes sign; svd3 moves the sign
  // to the smallest magnitude instead, and the exact Hessian must still match differences.
  out.push_back({"inverted-long",
                 randomRotation(rng) * diag(1.0, 0.3, -0.6) * transpose(randomRotation(rng))});
  out.push_back({"inverted-most",
                 randomRotation(rng) * diag(0.5, 0.3, -1.4) * transpose(randomRotation(rng))});
  out.push_back({"rotated", randomRotation(rng) * diag(1.05, 0.97, 1.02)});
  out.push_back(
      {"stretched", randomRotation(rng) * diag(1.6, 1.4, 1.3) * transpose(randomRotation(rng))});
  out.push_back(
      {"repeated", randomRotation(rng) * diag(1.2, 1.2, 0.8) * transpose(randomRotation(rng))});
  out.push_back({"uniform", 1.1 * randomRotation(rng)});
  {
    // Inverted along the fibre: V's third column is the fibre direction, so I4 = s2 < 0.
    const Vec3 a = Vec3{0.48, 0.6, 0.64};
    const Vec3 b = gf::detail::anyOrthogonal(a);
    const Mat3 v = gf::fromColumns(b, gf::cross(a, b), a);
    out.push_back({"fibre-inverted", randomRotation(rng) * diag(1.1, 0.9, -0.5) * transpose(v)});
  }
  out.push_back(
      {"compressed", randomRotation(rng) * diag(0.8, 0.6, 0.5) * transpose(randomRotation(rng))});
  return out;
}

MaterialCoeffs coeffs(int model, bool fibre) {
  return gf::makeMaterialCoeffs(model, kE, kNu, fibre ? 2e5 : 0.0, Vec3{0.48, 0.6, 0.64});
}

/// |I4| of the fibre term; finite differences are meaningless across its sign switch.
double fibreI4(const MaterialCoeffs& c, const Mat3& F) {
  const gf::Svd3 svd = gf::svd3(F);
  double i4 = 0;
  for (int a = 0; a < 3; ++a) {
    const double va = gf::dot(gf::column(svd.V, a), c.fibreDir);
    i4 += svd.s[a] * va * va;
  }
  return i4;
}

Eigen::Matrix<double, 9, 9> toEigen(const Mat9& a) {
  Eigen::Matrix<double, 9, 9> e;
  for (int i = 0; i < 9; ++i)
    for (int j = 0; j < 9; ++j) e(i, j) = a(i, j);
  return e;
}

TEST(Svd, ReconstructsWithProperRotations) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0, 1);
  std::vector<NamedF> cases;
  for (int k = 0; k < 200; ++k) {
    Mat3 f;
    for (double& v : f.m) v = n(rng);
    cases.push_back({"random", f});
  }
  const Mat3 r1 = randomRotation(rng), r2 = randomRotation(rng);
  cases.push_back({"identity", Mat3::identity()});
  cases.push_back({"zero", Mat3{}});
  cases.push_back({"rotation", r1});
  cases.push_back({"reflection", r1 * diag(1, 1, -1)});
  cases.push_back({"repeated-2", r1 * diag(2, 2, 1) * transpose(r2)});
  cases.push_back({"repeated-3", r1 * diag(1.5, 1.5, 1.5) * transpose(r2)});
  cases.push_back({"repeated-inverted", r1 * diag(1, 1, -1) * transpose(r2)});
  cases.push_back({"rank-2", r1 * diag(2, 0.5, 0) * transpose(r2)});
  cases.push_back({"rank-1", r1 * diag(3, 0, 0) * transpose(r2)});
  cases.push_back({"rank-1-axis", diag(0, 0, 2)});
  cases.push_back({"tiny-pair", r1 * diag(1, 1e-9, 3e-10) * transpose(r2)});
  cases.push_back({"tiny-inverted", r1 * diag(1, 1e-7, -1e-8) * transpose(r2)});
  cases.push_back({"flat", diag(1, 1, 1e-14)});
  cases.push_back({"scaled", 1e6 * (r1 * diag(3, 2, 1) * transpose(r2))});
  double maxRecon = 0, maxDet = 0, maxOrtho = 0, maxSigma = 0;
  for (const NamedF& c : cases) {
    const gf::Svd3 svd = gf::svd3(c.F);
    const Mat3 rec = svd.U * diag(svd.s.x, svd.s.y, svd.s.z) * transpose(svd.V);
    const double scale = std::max(1.0, frob(c.F));
    const double recon = frob(rec - c.F) / scale;
    const double detErr = std::max(std::fabs(gf::det(svd.U) - 1), std::fabs(gf::det(svd.V) - 1));
    const double ortho = std::max(frob(transpose(svd.U) * svd.U - Mat3::identity()),
                                  frob(transpose(svd.V) * svd.V - Mat3::identity()));
    EXPECT_LT(recon, 1e-12) << c.name;
    EXPECT_LT(detErr, 1e-12) << c.name;
    EXPECT_LT(ortho, 1e-12) << c.name;
    EXPECT_GE(svd.s.x, svd.s.y) << c.name;
    EXPECT_GE(svd.s.y, std::fabs(svd.s.z)) << c.name;
    // The sign of det F sits on the smallest singular value.
    const double d = gf::det(c.F);
    if (std::fabs(d) > 1e-10 * scale * scale * scale) {
      EXPECT_EQ(d > 0, svd.s.z > 0) << c.name;
    }
    // Magnitudes agree with Eigen's SVD.
    Eigen::Matrix3d e;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) e(i, j) = c.F(i, j);
    const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::Matrix3d>(e).singularValues();
    const double sigmaErr = std::max({std::fabs(sv(0) - svd.s.x), std::fabs(sv(1) - svd.s.y),
                                      std::fabs(sv(2) - std::fabs(svd.s.z))}) /
                            scale;
    EXPECT_LT(sigmaErr, 1e-12) << c.name;
    maxRecon = std::max(maxRecon, recon);
    maxDet = std::max(maxDet, detErr);
    maxOrtho = std::max(maxOrtho, ortho);
    maxSigma = std::max(maxSigma, sigmaErr);
  }
  std::printf(
      "[svd3] %zu cases: max reconstruction %.2e, |det-1| %.2e, orthogonality %.2e, "
      "singular values vs Eigen %.2e\n",
      cases.size(), maxRecon, maxDet, maxOrtho, maxSigma);
}

/// The rotation formulas of svd3's Jacobi sweep have three branches: rotations too small to
/// change c from 1 (near-diagonal and near-rotation F, the last sweeps), the product form for
/// ordinary column lengths, and the zeta form where squares of the column lengths' squares
/// would over- or underflow (|F| near 1e+-60). Each family, with repeated, zero and negative
/// singular values and equal-length columns (d = 0, where the rotation's sign convention
/// matters), must reconstruct F to round-off relative to |F| itself, with singular values
/// equal to Eigen's to round-off of |F| and proper rotations.
TEST(Svd, EveryRotationBranchIsAccurateAtEveryScale) {
  std::mt19937 rng(19);
  std::normal_distribution<double> n(0, 1);
  std::vector<NamedF> base;
  const Mat3 r1 = randomRotation(rng), r2 = randomRotation(rng);
  base.push_back({"near-diagonal", diag(3, 2, 1)});
  base.push_back({"near-rotation", r1 * diag(1 + 1e-9, 1, 1 - 1e-9) * transpose(r2)});
  base.push_back({"near-reflection", r1 * diag(1 + 1e-9, 1, -1 + 1e-9) * transpose(r2)});
  base.push_back({"repeated", r1 * diag(2, 2, 1) * transpose(r2)});
  base.push_back({"repeated-inverted", r1 * diag(1, 1, -1) * transpose(r2)});
  base.push_back({"rank-1", r1 * diag(3, 0, 0) * transpose(r2)});
  base.push_back({"rank-2", r1 * diag(2, 0.5, 0) * transpose(r2)});
  Mat3 equal;  // columns (1,1,0), (1,0,1), (0,1,-1): equal lengths, not orthogonal
  equal(0, 0) = equal(1, 0) = equal(0, 1) = equal(2, 1) = equal(1, 2) = 1;
  equal(2, 2) = -1;
  base.push_back({"equal-columns", equal});
  for (int k = 0; k < 20; ++k) {
    Mat3 f;
    for (double& v : f.m) v = n(rng);
    base.push_back({"random", f});
  }
  std::vector<NamedF> cases;
  for (const NamedF& b : base) {
    Mat3 f = b.F;
    if (b.name == std::string("near-diagonal")) {
      for (double& v : f.m) v += 1e-10 * n(rng);
    }
    for (double scale : {1e-60, 1e-30, 1.0, 1e30, 1e60})
      cases.push_back(
          {b.name + std::string(" x") + std::to_string(int(std::log10(scale))), scale * f});
  }
  double worst = 0;
  for (const NamedF& c : cases) {
    const gf::Svd3 svd = gf::svd3(c.F);
    const double scale = frob(c.F);
    const Mat3 rec = svd.U * diag(svd.s.x, svd.s.y, svd.s.z) * transpose(svd.V);
    const double recon = scale > 0 ? frob(rec - c.F) / scale : frob(rec);
    const double ortho = std::max(frob(transpose(svd.U) * svd.U - Mat3::identity()),
                                  frob(transpose(svd.V) * svd.V - Mat3::identity()));
    EXPECT_LT(recon, 1e-13) << c.name;
    EXPECT_LT(ortho, 1e-13) << c.name;
    EXPECT_NEAR(gf::det(svd.U), 1, 1e-13) << c.name;
    EXPECT_NEAR(gf::det(svd.V), 1, 1e-13) << c.name;
    // Sorted, up to round-off between equal singular values.
    EXPECT_GE(svd.s.x, svd.s.y - 1e-14 * scale) << c.name;
    EXPECT_GE(svd.s.y, std::fabs(svd.s.z) - 1e-14 * scale) << c.name;
    Eigen::Matrix3d e;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) e(i, j) = c.F(i, j);
    const Eigen::Vector3d sv = Eigen::JacobiSVD<Eigen::Matrix3d>(e).singularValues();
    for (int a = 0; a < 3; ++a)
      EXPECT_LE(std::fabs(sv(a) - std::fabs(svd.s[a])), 1e-13 * scale) << c.name << " s" << a;
    worst = std::max({worst, recon, ortho});
  }
  std::printf("[svd3] %zu cases at scales 1e-60..1e60: worst relative error %.2e\n", cases.size(),
              worst);
}

TEST(Svd, SymmetricEigenMatchesEigen) {
  std::mt19937 rng(11);
  std::normal_distribution<double> n(0, 1);
  for (int k = 0; k < 20; ++k) {
    gf::Mat12 a;
    for (int i = 0; i < 12; ++i)
      for (int j = i; j < 12; ++j) a(i, j) = a(j, i) = n(rng);
    double w[12];
    gf::Mat12 q;
    gf::symmetricEigen<12>(a, w, q);
    Eigen::Matrix<double, 12, 12> e;
    for (int i = 0; i < 12; ++i)
      for (int j = 0; j < 12; ++j) e(i, j) = a(i, j);
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> es(e);
    for (int i = 0; i < 12; ++i) EXPECT_NEAR(w[i], es.eigenvalues()(11 - i), 1e-12);
    // A q_k = w_k q_k
    for (int kk = 0; kk < 12; ++kk)
      for (int i = 0; i < 12; ++i) {
        double r = -w[kk] * q(i, kk);
        for (int j = 0; j < 12; ++j) r += a(i, j) * q(j, kk);
        EXPECT_NEAR(r, 0, 1e-12);
      }
  }
}

/// Central-difference checks of P against psi and of dP/dF against P, for every model, with
/// and without the fibre term, over testDeformations().
TEST(Material, FiniteDifferenceGradientAndHessian) {
  const double h = 1e-6;
  const std::vector<NamedF> cases = testDeformations();
  double worstP = 0, worstH = 0;
  int skipped = 0, negativeI4 = 0;
  for (int model = 0; model < 4; ++model) {
    for (int fibre = 0; fibre < 2; ++fibre) {
      const MaterialCoeffs c = coeffs(model, fibre != 0);
      double maxP = 0, maxH = 0;
      for (const NamedF& nf : cases) {
        if (fibre && std::fabs(fibreI4(c, nf.F)) < 1e-3) {
          ++skipped;
          continue;
        }
        if (fibre && fibreI4(c, nf.F) < 0) ++negativeI4;
        Mat3 P;
        Mat9 H;
        gf::firstPiolaAndHessian(c, nf.F, P, H, false);
        const Mat3 P2 = gf::firstPiola(c, nf.F);
        EXPECT_LT(frob(P - P2), 1e-12 * frob(P)) << nf.name;
        Mat3 fdP;
        Mat9 fdH;
        for (int k = 0; k < 9; ++k) {
          Mat3 fp = nf.F, fm = nf.F;
          fp.m[k] += h;
          fm.m[k] -= h;
          fdP.m[k] = (gf::energyDensity(c, fp) - gf::energyDensity(c, fm)) / (2 * h);
          const Mat3 dp = gf::firstPiola(c, fp) - gf::firstPiola(c, fm);
          for (int r = 0; r < 9; ++r) fdH(r, k) = dp.m[r] / (2 * h);
        }
        const double errP = frob(fdP - P) / frob(P);
        const double errH = frob9(fdH - H) / frob9(H);
        EXPECT_LT(errP, 1e-5) << kModelNames[model] << " fibre=" << fibre << " " << nf.name;
        EXPECT_LT(errH, 1e-5) << kModelNames[model] << " fibre=" << fibre << " " << nf.name;
        EXPECT_LT(frob9(H - transpose(H)), 1e-10 * frob9(H)) << nf.name;
        maxP = std::max(maxP, errP);
        maxH = std::max(maxH, errH);
      }
      std::printf("[material] %-17s fibre=%d: max rel FD error  P %.2e  dP/dF %.2e\n",
                  kModelNames[model], fibre, maxP, maxH);
      worstP = std::max(worstP, maxP);
      worstH = std::max(worstH, maxH);
    }
  }
  std::printf(
      "[material] worst over all models: P %.2e, dP/dF %.2e (%d fibre cases with I4 < 0, "
      "%d skipped at |I4| < 1e-3)\n",
      worstP, worstH, negativeI4, skipped);
  EXPECT_GT(negativeI4, 0);
}

TEST(Material, RestStateIsStressAndEnergyFree) {
  for (int model = 0; model < 4; ++model) {
    for (int fibre = 0; fibre < 2; ++fibre) {
      const MaterialCoeffs c = coeffs(model, fibre != 0);
      const Mat3 I = Mat3::identity();
      EXPECT_NEAR(gf::energyDensity(c, I), 0, 1e-9 * kE) << kModelNames[model];
      EXPECT_LT(frob(gf::firstPiola(c, I)), 1e-9 * kE) << kModelNames[model];
    }
  }
}

TEST(Material, RotationInvariance) {
  std::mt19937 rng(3);
  const std::vector<NamedF> cases = testDeformations();
  for (int model = 0; model < 4; ++model) {
    for (int fibre = 0; fibre < 2; ++fibre) {
      const MaterialCoeffs c = coeffs(model, fibre != 0);
      for (const NamedF& nf : cases) {
        const Mat3 R = randomRotation(rng);
        const double psi = gf::energyDensity(c, nf.F);
        const double tol = 1e-10 * std::max(std::fabs(psi), kE);
        // Frame indifference: psi(R F) = psi(F), P(R F) = R P(F).
        EXPECT_NEAR(gf::energyDensity(c, R * nf.F), psi, tol) << kModelNames[model] << nf.name;
        const Mat3 P = gf::firstPiola(c, nf.F);
        EXPECT_LT(frob(gf::firstPiola(c, R * nf.F) - R * P), 1e-9 * std::max(frob(P), kE))
            << kModelNames[model] << " " << nf.name;
        // Isotropy: psi(F R) = psi(F) holds without the fibre.
        if (!fibre) {
          EXPECT_NEAR(gf::energyDensity(c, nf.F * R), psi, tol) << kModelNames[model];
        }
      }
    }
  }
}

/// Every model linearises to sigma = 2 mu eps + lambda tr(eps) I (eq 4.28) with the Lamé
/// parameters of eq 4.29, computed here independently of makeMaterialCoeffs.
TEST(Material, SmallStrainMatchesLinearElasticity) {
  const double E = 3.5e7, nu = 0.42;
  const double muL = E / (2 * (1 + nu));
  const double lambdaL = E * nu / ((1 + nu) * (1 - 2 * nu));
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0, 1);
  const double delta = 1e-6;
  for (int model = 0; model < 4; ++model) {
    const MaterialCoeffs c = gf::makeMaterialCoeffs(model, E, nu, 0, Vec3{1, 0, 0});
    double maxErr = 0;
    for (int k = 0; k < 10; ++k) {
      Mat3 H;
      for (double& v : H.m) v = n(rng);
      const Mat3 P = gf::firstPiola(c, Mat3::identity() + delta * H);
      const Mat3 eps = 0.5 * (H + transpose(H));
      const Mat3 sigma = 2 * muL * eps + lambdaL * gf::trace(eps) * Mat3::identity();
      const double err = frob((1 / delta) * P - sigma) / frob(sigma);
      maxErr = std::max(maxErr, err);
    }
    EXPECT_LT(maxErr, 1e-4) << kModelNames[model];
    std::printf("[material] %-17s small-strain stress vs eq 4.28: rel error %.2e\n",
                kModelNames[model], maxErr);
  }
}

bool isPsd(const Eigen::Matrix<double, 9, 9>& m) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> es(m);
  return es.eigenvalues().minCoeff() >= -1e-10 * es.eigenvalues().cwiseAbs().maxCoeff();
}

/// The projection clamps each energy term's analytic eigen-system: for an isotropic model that
/// is exactly the nearest PSD matrix; with the fibre term, each of the two terms is projected
/// on its own (Kim et al. 2019), so the sum is PSD and is left alone whenever both terms are.
TEST(Material, ProjectedHessianIsPsdAndExactWherePossible) {
  const std::vector<NamedF> cases = testDeformations();
  int indefinite = 0, psdSumOfIndefiniteTerms = 0;
  for (int model = 0; model < 4; ++model) {
    for (int fibre = 0; fibre < 2; ++fibre) {
      const MaterialCoeffs c = coeffs(model, fibre != 0);
      MaterialCoeffs iso = c;
      iso.fibreMu = 0;
      for (const NamedF& nf : cases) {
        Mat3 P, Pp;
        Mat9 H, Hp, Hiso;
        gf::firstPiolaAndHessian(c, nf.F, P, H, false);
        gf::firstPiolaAndHessian(c, nf.F, Pp, Hp, true);
        gf::firstPiolaAndHessian(iso, nf.F, P, Hiso, false);
        EXPECT_LT(frob(gf::firstPiola(c, nf.F) - Pp), 1e-12 * frob(Pp));
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> es(toEigen(H));
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> esp(toEigen(Hp));
        const double scale = es.eigenvalues().cwiseAbs().maxCoeff();
        EXPECT_GE(esp.eigenvalues().minCoeff(), -1e-10 * scale)
            << kModelNames[model] << " " << nf.name;
        const bool termsPsd = isPsd(toEigen(Hiso)) && isPsd(toEigen(H) - toEigen(Hiso));
        if (termsPsd) {
          // Already PSD: projection must leave it alone.
          EXPECT_LT(frob9(H - Hp), 1e-10 * frob9(H)) << kModelNames[model] << " " << nf.name;
        } else if (isPsd(toEigen(H))) {
          ++psdSumOfIndefiniteTerms;
        }
        if (!isPsd(toEigen(H))) ++indefinite;
        if (!fibre) {
          // The analytic eigen-system is the exact one, so clamping it equals clamping the
          // eigenvalues Eigen finds in the unprojected Hessian.
          Eigen::VectorXd w = es.eigenvalues().cwiseMax(0.0);
          const Eigen::Matrix<double, 9, 9> ref =
              es.eigenvectors() * w.asDiagonal() * es.eigenvectors().transpose();
          EXPECT_LT((ref - toEigen(Hp)).norm(), 1e-9 * ref.norm())
              << kModelNames[model] << " " << nf.name;
        }
      }
    }
  }
  // The cases must include indefinite Hessians or this test proves little.
  EXPECT_GT(indefinite, 10);
  std::printf(
      "[material] %d of %zu Hessians were indefinite before projection; %d PSD sums of "
      "an indefinite term were made stiffer by per-term projection\n",
      indefinite, 8 * cases.size(), psdSumOfIndefiniteTerms);
}

TEST(Material, StretchedHessianIsAlreadyPsd) {
  // Pure stretch beyond rest: every model is convex there, so projection is the identity.
  const Mat3 F = diag(1.3, 1.2, 1.1);
  for (int model = 0; model < 4; ++model) {
    const MaterialCoeffs c = coeffs(model, true);
    Mat3 P;
    Mat9 H, Hp;
    gf::firstPiolaAndHessian(c, F, P, H, false);
    gf::firstPiolaAndHessian(c, F, P, Hp, true);
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 9, 9>> es(toEigen(H));
    EXPECT_GT(es.eigenvalues().minCoeff(), 0) << kModelNames[model];
    EXPECT_LT(frob9(H - Hp), 1e-12 * frob9(H)) << kModelNames[model];
  }
}

TEST(Material, StableNeoHookeanRestoresInvertedElement) {
  const MaterialCoeffs c = gf::makeMaterialCoeffs(gf::kStableNeoHookean, 1.0, 0.3, 0, Vec3{});
  std::mt19937 rng(9);
  for (int k = 0; k < 5; ++k) {
    Mat3 F = randomRotation(rng) * diag(1.0, 0.7, -0.3 - 0.1 * k) * transpose(randomRotation(rng));
    ASSERT_LT(gf::det(F), 0);
    const Mat3 P = gf::firstPiola(c, F);
    // d(det F) along the force direction -P is -cof(F) : P; it must be positive.
    const Mat3 cof = gf::det(F) * transpose(gf::inverse(F));
    EXPECT_GT(-gf::frobeniusDot(cof, P), 0);
    // Gradient flow from the inverted state ends at a rotation (det = 1, psi = 0).
    const double step = 0.2 / (c.mu + c.lambda);
    for (int it = 0; it < 5000; ++it) F = F - step * gf::firstPiola(c, F);
    EXPECT_NEAR(gf::det(F), 1.0, 1e-6);
    EXPECT_NEAR(gf::energyDensity(c, F), 0.0, 1e-9);
  }
}

TEST(Material, DegenerateDeformationsStayFinite) {
  std::mt19937 rng(13);
  const Mat3 r = randomRotation(rng);
  const Mat3 cases[] = {Mat3{},
                        r * diag(2, 0, 0),
                        r * diag(1, 0.5, 0),
                        r * diag(1, 1, -1),
                        r * diag(1, 0.5, -0.5),
                        r * diag(1e3, 1e-3, 1e-3),
                        diag(0, 0, 1)};
  for (int model = 0; model < 4; ++model) {
    for (int fibre = 0; fibre < 2; ++fibre) {
      const MaterialCoeffs c = coeffs(model, fibre != 0);
      for (const Mat3& F : cases) {
        for (int project = 0; project < 2; ++project) {
          Mat3 P;
          Mat9 H;
          gf::firstPiolaAndHessian(c, F, P, H, project != 0);
          EXPECT_TRUE(std::isfinite(gf::energyDensity(c, F))) << kModelNames[model];
          for (double v : P.m) EXPECT_TRUE(std::isfinite(v)) << kModelNames[model];
          for (double v : H.m) EXPECT_TRUE(std::isfinite(v)) << kModelNames[model];
        }
      }
    }
  }
}

TEST(Material, NeoHookeanContinuationIsFiniteAndSmooth) {
  const MaterialCoeffs c = coeffs(gf::kNeoHookean, false);
  // Across J = kNeoHookeanJMin the energy and its first derivative stay continuous.
  const double j0 = gf::kNeoHookeanJMin;
  const auto psiAt = [&](double J) { return gf::isotropicEnergy(c, Vec3{1, 1, J}); };
  const double eps = 1e-7;
  EXPECT_NEAR(psiAt(j0 + eps), psiAt(j0 - eps), 1e-5 * std::fabs(psiAt(j0)));
  const double slopeAbove = (psiAt(j0 + 2 * eps) - psiAt(j0 + eps)) / eps;
  const double slopeBelow = (psiAt(j0 - eps) - psiAt(j0 - 2 * eps)) / eps;
  EXPECT_NEAR(slopeAbove, slopeBelow, 1e-4 * std::fabs(slopeAbove));
  // Finite for degenerate and inverted J, and the energy keeps rising into inversion.
  EXPECT_TRUE(std::isfinite(psiAt(0.0)));
  EXPECT_GT(psiAt(-0.5), psiAt(0.0));
  EXPECT_GT(psiAt(0.0), psiAt(j0));
}

}  // namespace
