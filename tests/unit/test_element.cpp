// Linear tetrahedron kernels (SPEC §1): rest precompute against hand-computed values, the
// element gradient and Hessian against finite differences of the element energy, a dense
// D^T dPdF D reference, and translation/rotation invariance (zero net force and torque).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cstdio>
#include <random>

#include "kernels/element.h"

namespace {

using gf::Mat12;
using gf::Mat3;
using gf::MaterialCoeffs;
using gf::Vec3;

const char* const kModelNames[] = {"corotated", "stvk", "neohookean", "stable-neohookean"};

struct Tet {
  Vec3 X[4];  // rest
  Vec3 x[4];  // deformed
};

/// A well-shaped random rest tet and a deformed state that is either a moderate random
/// deformation or an inversion (node 3 pushed through the opposite face).
Tet randomTet(std::mt19937& rng, bool invert) {
  std::normal_distribution<double> n(0, 1);
  Tet t;
  const Vec3 base[4] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  for (int a = 0; a < 4; ++a) {
    t.X[a] = 0.1 * (base[a] + 0.1 * Vec3{n(rng), n(rng), n(rng)});
    t.x[a] = t.X[a] + 0.02 * Vec3{n(rng), n(rng), n(rng)} + Vec3{0.3, -0.2, 0.5};
  }
  if (invert) {
    t.x[3] = t.x[0] + 0.4 * ((t.x[3] - t.x[0]) - 2.0 * Vec3{0, 0, t.x[3].z - t.x[0].z});
  }
  return t;
}

double elementEnergy(const MaterialCoeffs& c, const Mat3& dmInv, double vol, const double* xs) {
  Vec3 x[4];
  for (int a = 0; a < 4; ++a) x[a] = Vec3{xs[3 * a], xs[3 * a + 1], xs[3 * a + 2]};
  double g[12];
  return gf::elementForces(c, x, dmInv, vol, g, nullptr, false);
}

TEST(Element, RestShapeAndDeformationGradient) {
  // Unit corner tet: Dm = I, volume 1/6.
  const Vec3 unit[4] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  double vol = 0;
  const Mat3 inv = gf::restShapeInverse(unit, vol);
  EXPECT_NEAR(vol, 1.0 / 6.0, 1e-15);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(inv(i, j), i == j ? 1 : 0, 1e-15);

  // An affine map x = A X + b has F = A on any rest tet.
  std::mt19937 rng(1);
  std::normal_distribution<double> n(0, 1);
  const Tet t = randomTet(rng, false);
  Mat3 A;
  for (double& v : A.m) v = n(rng);
  Vec3 x[4];
  for (int a = 0; a < 4; ++a) x[a] = A * t.X[a] + Vec3{1, 2, 3};
  double v = 0;
  const Mat3 dmInv = gf::restShapeInverse(t.X, v);
  EXPECT_GT(v, 0);
  const Mat3 F = gf::deformationGradient(x, dmInv);
  for (int k = 0; k < 9; ++k) EXPECT_NEAR(F.m[k], A.m[k], 1e-12);

  // Degenerate rest tet: zero volume, zero inverse, no NaN.
  const Vec3 flat[4] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
  const Mat3 z = gf::restShapeInverse(flat, v);
  EXPECT_EQ(v, 0);
  for (double e : z.m) EXPECT_EQ(e, 0);
}

TEST(Element, FiniteDifferenceGradientAndHessian) {
  std::mt19937 rng(2024);
  const double h = 1e-7;  // positions are ~0.1 m, so F moves by ~1e-6
  double worstG = 0, worstH = 0;
  for (int model = 0; model < 4; ++model) {
    for (int fibre = 0; fibre < 2; ++fibre) {
      const MaterialCoeffs c =
          gf::makeMaterialCoeffs(model, 2e6, 0.35, fibre ? 5e5 : 0.0, Vec3{1, 1, 0});
      double maxG = 0, maxH = 0;
      for (int k = 0; k < 8; ++k) {
        const Tet t = randomTet(rng, k >= 5);
        double vol = 0;
        const Mat3 dmInv = gf::restShapeInverse(t.X, vol);
        ASSERT_GT(vol, 0);
        if (k >= 5) {
          ASSERT_LT(gf::det(gf::deformationGradient(t.x, dmInv)), 0);
        }
        double g[12];
        Mat12 H;
        gf::elementForces(c, t.x, dmInv, vol, g, &H, false);
        double xs[12];
        for (int a = 0; a < 4; ++a)
          for (int i = 0; i < 3; ++i) xs[3 * a + i] = t.x[a][i];
        double fdG[12];
        Mat12 fdH;
        for (int q = 0; q < 12; ++q) {
          double xp[12], xm[12];
          std::copy(xs, xs + 12, xp);
          std::copy(xs, xs + 12, xm);
          xp[q] += h;
          xm[q] -= h;
          fdG[q] = (elementEnergy(c, dmInv, vol, xp) - elementEnergy(c, dmInv, vol, xm)) / (2 * h);
          Vec3 yp[4], ym[4];
          for (int a = 0; a < 4; ++a) {
            yp[a] = Vec3{xp[3 * a], xp[3 * a + 1], xp[3 * a + 2]};
            ym[a] = Vec3{xm[3 * a], xm[3 * a + 1], xm[3 * a + 2]};
          }
          double gp[12], gm[12];
          gf::elementForces(c, yp, dmInv, vol, gp, nullptr, false);
          gf::elementForces(c, ym, dmInv, vol, gm, nullptr, false);
          for (int r = 0; r < 12; ++r) fdH(r, q) = (gp[r] - gm[r]) / (2 * h);
        }
        double eg = 0, ng = 0;
        for (int q = 0; q < 12; ++q) {
          eg += (fdG[q] - g[q]) * (fdG[q] - g[q]);
          ng += g[q] * g[q];
        }
        const double errG = std::sqrt(eg / ng);
        const double errH = std::sqrt(gf::frobeniusDot(fdH - H, fdH - H) / gf::frobeniusDot(H, H));
        EXPECT_LT(errG, 1e-5) << kModelNames[model] << " fibre=" << fibre << " case " << k;
        EXPECT_LT(errH, 1e-5) << kModelNames[model] << " fibre=" << fibre << " case " << k;
        maxG = std::max(maxG, errG);
        maxH = std::max(maxH, errH);
      }
      std::printf("[element] %-17s fibre=%d: max rel FD error  grad %.2e  Hessian %.2e\n",
                  kModelNames[model], fibre, maxG, maxH);
      worstG = std::max(worstG, maxG);
      worstH = std::max(worstH, maxH);
    }
  }
  std::printf("[element] worst over all models: grad %.2e, Hessian %.2e\n", worstG, worstH);
}

TEST(Element, HessianMatchesDenseReference) {
  // V D^T dPdF D with D = dvec(F)/dx formed densely, against the blocked kernel.
  std::mt19937 rng(77);
  for (int model = 0; model < 4; ++model) {
    const MaterialCoeffs c = gf::makeMaterialCoeffs(model, 1e6, 0.3, 1e5, Vec3{0, 1, 0});
    const Tet t = randomTet(rng, false);
    double vol = 0;
    const Mat3 dmInv = gf::restShapeInverse(t.X, vol);
    for (int project = 0; project < 2; ++project) {
      double g[12];
      Mat12 H;
      gf::elementForces(c, t.x, dmInv, vol, g, &H, project != 0);
      Mat3 P;
      gf::Mat9 dPdF;
      gf::firstPiolaAndHessian(c, gf::deformationGradient(t.x, dmInv), P, dPdF, project != 0);
      Eigen::Matrix<double, 9, 12> D = Eigen::Matrix<double, 9, 12>::Zero();
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          for (int k = 0; k < 3; ++k) {
            // F(i,j) = sum_k (x_{k+1} - x_0)_i DmInv(k,j)
            D(3 * i + j, 3 * (k + 1) + i) += dmInv(k, j);
            D(3 * i + j, i) -= dmInv(k, j);
          }
      Eigen::Matrix<double, 9, 9> K;
      for (int i = 0; i < 9; ++i)
        for (int j = 0; j < 9; ++j) K(i, j) = dPdF(i, j);
      const Eigen::Matrix<double, 12, 12> ref = vol * D.transpose() * K * D;
      Eigen::Matrix<double, 12, 1> refG;
      Eigen::Matrix<double, 9, 1> p;
      for (int k = 0; k < 9; ++k) p(k) = P.m[k];
      refG = vol * D.transpose() * p;
      double err = 0;
      for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j) err = std::max(err, std::fabs(H(i, j) - ref(i, j)));
      EXPECT_LT(err, 1e-12 * ref.cwiseAbs().maxCoeff()) << kModelNames[model];
      for (int i = 0; i < 12; ++i) EXPECT_NEAR(g[i], refG(i), 1e-12 * refG.cwiseAbs().maxCoeff());
      if (project) {
        Eigen::Matrix<double, 12, 12> e;
        for (int i = 0; i < 12; ++i)
          for (int j = 0; j < 12; ++j) e(i, j) = H(i, j);
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> es(e);
        EXPECT_GE(es.eigenvalues().minCoeff(), -1e-10 * es.eigenvalues().cwiseAbs().maxCoeff());
      }
    }
  }
}

TEST(Element, HessianIsExactlySymmetric) {
  // The Hessian is assembled from its upper triangle (hessianFromModes), so H(i,j) and H(j,i)
  // must agree to the bit for every model, with and without the fibre term and projection,
  // across stretched, compressed, inverted and nearly flat elements. The states must reach
  // both splits of d2psi/ds2 (Cholesky where it is positive definite, the eigen-solve where
  // not), or half of the scaling-mode code goes untested.
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0, 1);
  int pdScaling = 0, indefiniteScaling = 0, checked = 0;
  for (int model = 0; model < 4; ++model)
    for (int fibre = 0; fibre < 2; ++fibre) {
      const MaterialCoeffs c =
          gf::makeMaterialCoeffs(model, 1e6, 0.3, fibre ? 3e5 : 0, Vec3{0.6, 0.8, 0});
      for (int k = 0; k < 12; ++k) {
        Tet t = randomTet(rng, k % 4 == 3);
        const double stretch = 0.3 + 0.25 * k;  // 0.3 (compressed) .. 3.05 (stretched)
        for (int a = 1; a < 4; ++a) t.x[a] = t.x[0] + stretch * (t.x[a] - t.x[0]);
        if (k == 10) t.x[3] = (1.0 / 3.0) * (t.x[0] + t.x[1] + t.x[2]) + 1e-9 * t.x[3];
        double vol = 0;
        const Mat3 dmInv = gf::restShapeInverse(t.X, vol);
        const Mat3 A = gf::isotropicHessian(c, gf::svd3(gf::deformationGradient(t.x, dmInv)).s);
        Eigen::Matrix3d a;
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) a(i, j) = A(i, j);
        (Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(a).eigenvalues().minCoeff() > 0
             ? pdScaling
             : indefiniteScaling)++;
        for (int project = 0; project < 2; ++project) {
          double g[12];
          Mat12 H;
          gf::elementForces(c, t.x, dmInv, vol, g, &H, project != 0);
          int asymmetric = 0;
          for (int i = 0; i < 12; ++i)
            for (int j = i + 1; j < 12; ++j) asymmetric += H(i, j) != H(j, i);
          EXPECT_EQ(asymmetric, 0) << kModelNames[model] << " fibre " << fibre << " case " << k
                                   << " project " << project;
          ++checked;
        }
      }
    }
  EXPECT_GT(pdScaling, 10);
  EXPECT_GT(indefiniteScaling, 10);
  std::printf("[element] %d Hessians bit-symmetric; d2psi/ds2 definite in %d states, not in %d\n",
              checked, pdScaling, indefiniteScaling);
}

TEST(Element, ZeroNetForceAndTorque) {
  std::mt19937 rng(31);
  double maxF = 0, maxT = 0;
  for (int model = 0; model < 4; ++model) {
    const MaterialCoeffs c = gf::makeMaterialCoeffs(model, 1e6, 0.3, 3e5, Vec3{0, 0, 1});
    for (int k = 0; k < 6; ++k) {
      const Tet t = randomTet(rng, k >= 4);
      double vol = 0;
      const Mat3 dmInv = gf::restShapeInverse(t.X, vol);
      double g[12];
      Mat12 H;
      gf::elementForces(c, t.x, dmInv, vol, g, &H, false);
      Vec3 force{}, torque{};
      double scale = 0;
      for (int a = 0; a < 4; ++a) {
        const Vec3 f{-g[3 * a], -g[3 * a + 1], -g[3 * a + 2]};
        force += f;
        torque += gf::cross(t.x[a], f);
        scale = std::max(scale, gf::norm(f));
      }
      // Torque is measured about the origin, ~0.5 m from the tet, so scale with the lever.
      double lever = 0;
      for (int a = 0; a < 4; ++a) lever = std::max(lever, gf::norm(t.x[a]));
      const double ef = gf::norm(force) / scale, et = gf::norm(torque) / (scale * lever);
      EXPECT_LT(ef, 1e-12) << kModelNames[model];
      EXPECT_LT(et, 1e-12) << kModelNames[model];
      maxF = std::max(maxF, ef);
      maxT = std::max(maxT, et);
      // Rigid translations are in the Hessian's null space.
      double hs = 0, ht = 0;
      for (int r = 0; r < 12; ++r)
        for (int i = 0; i < 3; ++i) {
          double s = 0;
          for (int b = 0; b < 4; ++b) s += H(r, 3 * b + i);
          ht = std::max(ht, std::fabs(s));
          for (int q = 0; q < 12; ++q) hs = std::max(hs, std::fabs(H(r, q)));
        }
      EXPECT_LT(ht, 1e-10 * hs) << kModelNames[model];
    }
  }
  std::printf("[element] relative net force %.2e, net torque %.2e\n", maxF, maxT);
}

}  // namespace
