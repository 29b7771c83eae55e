// The CPU element pass in SIMD lanes (fem/element_lanes.h, issue 14): every undamaged tet's
// energy, gradient, projected Hessian and criterion stress from the lanes must be the scalar
// kernels' (ElementStage one tet at a time, the GPU's path) to round-off, for every isotropic
// model and per-tet (mu, lambda), on tets whose lanes take different branches: sheared,
// rotated, flattened, inverted, strongly compressed (an indefinite scaling block), collapsed.
// The lanes' bits must not depend on the range a thread is given, nor on the SVD cache.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "common/tet_set.h"
#include "fem/element_lanes.h"
#include "fem/element_stage.h"
#include "kernels/element.h"

namespace {

using gf::Mat3;
using gf::MaterialCoeffs;
using gf::Vec3;
using gf::test::TetSet;

Mat3 rotation(Vec3 axis, double angle) {
  const Vec3 a = (1.0 / gf::norm(axis)) * axis;
  const double c = std::cos(angle), s = std::sin(angle);
  Mat3 r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r(i, j) = (1 - c) * a[i] * a[j] + (i == j ? c : 0.0);
  r(0, 1) -= s * a.z;
  r(1, 0) += s * a.z;
  r(0, 2) += s * a.y;
  r(2, 0) -= s * a.y;
  r(1, 2) -= s * a.x;
  r(2, 1) += s * a.x;
  return r;
}

/// Tets of a random rest shape, deformed by F = R * (one of the cases below).
TetSet generalTets() {
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0, 1);
  TetSet set;
  const Vec3 base[4] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  constexpr int kCases = 9;
  for (int k = 0; k < 7 * kCases; ++k) {
    Vec3 X[4];
    for (int a = 0; a < 4; ++a) X[a] = 0.1 * (base[a] + 0.15 * Vec3{n(rng), n(rng), n(rng)});
    Mat3 F = Mat3::identity();
    switch (k % kCases) {
      case 0:  // small random strain
        for (int e = 0; e < 9; ++e) F.m[e] += 0.02 * n(rng);
        break;
      case 1:  // sheared in every plane
        F(0, 1) = 0.3;
        F(1, 2) = -0.2;
        F(2, 0) = 0.25;
        break;
      case 2:  // large random strain
        for (int e = 0; e < 9; ++e) F.m[e] += 0.4 * n(rng);
        break;
      case 3:  // nearly flat
        F(2, 2) = 1e-7;
        F(0, 2) = 0.1;
        break;
      case 4:  // inverted
        F(1, 1) = -0.7;
        F(0, 1) = 0.2;
        break;
      case 5:  // strongly compressed: Neo-Hookean scaling blocks go indefinite
        F = 0.2 * F;
        F(0, 0) = 0.3;
        break;
      case 6:  // two equal singular values (a repeated-value flip mode)
        F(0, 0) = 1.2;
        F(1, 1) = 1.2;
        F(2, 2) = 0.9;
        break;
      case 7:  // collapsed to a line
        F = Mat3{};
        F(0, 0) = 1.1;
        F(1, 0) = 0.3;
        break;
      default:  // stretched
        F(0, 0) = 1.6;
        F(1, 1) = 0.8;
        break;
    }
    F = rotation(Vec3{n(rng), n(rng), n(rng)}, 3.0 * n(rng)) * F;
    Vec3 xd[4];
    for (int a = 0; a < 4; ++a) xd[a] = F * X[a] + Vec3{0.3, -0.2, 0.5};
    set.add(X, xd);
  }
  return set;
}

struct Out {
  std::vector<double> energy, grad, hess, stress;
  explicit Out(size_t T)
      : energy(T), grad(12 * T), hess(gf::kElementMatrixSize * T), stress(6 * T) {}
};

gf::detail::ElementStage stageFor(const TetSet& set, const MaterialCoeffs& c, Out& o) {
  gf::detail::ElementStage s;
  s.tets = set.tets.data();
  s.x = set.x.data();
  s.restInverse = set.restInverse.data();
  s.restVolume = set.restVolume.data();
  s.coeffs = c;
  s.energy = o.energy.data();
  s.grad = o.grad.data();
  s.hess = o.hess.data();
  s.stress = o.stress.data();
  return s;
}

/// Largest difference of a and b over n values, relative to a's largest magnitude.
double relDiff(const double* a, const double* b, int n) {
  double scale = 0, diff = 0;
  for (int k = 0; k < n; ++k) {
    scale = std::max(scale, std::fabs(a[k]));
    diff = std::max(diff, std::fabs(a[k] - b[k]));
  }
  return scale > 0 ? diff / scale : diff;
}

bool sameBits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

std::vector<MaterialCoeffs> isotropicModels() {
  std::vector<MaterialCoeffs> out;
  for (int model = gf::kCorotated; model <= gf::kStableNeoHookean; ++model)
    out.push_back(gf::makeMaterialCoeffs(model, 1e7, 0.35, 0, Vec3{1, 0, 0}));
  return out;
}

TEST(ElementLanes, MatchTheScalarKernelsToRoundOff) {
  const TetSet set = generalTets();
  const size_t T = size_t(set.count);
  std::printf("lanes: %d tets at a time\n", gf::detail::elementLaneWidth());
  // Per-tet (mu, lambda) as a wet body has them: lanes of one batch differ in material too.
  std::vector<double> lame(2 * T);
  for (size_t t = 0; t < T; ++t) {
    lame[2 * t] = 1e6 * (1.0 + 0.37 * double(t % 5));
    lame[2 * t + 1] = 4e6 * (1.0 + 0.21 * double(t % 3));
  }
  for (const MaterialCoeffs& c : isotropicModels()) {
    for (const bool wet : {false, true}) {
      Out scalar(T), lanes(T);
      gf::detail::ElementStage s = stageFor(set, c, scalar);
      gf::detail::ElementStage v = stageFor(set, c, lanes);
      if (wet) s.tetLame = v.tetLame = lame.data();
      for (int32_t t = 0; t < set.count; ++t) s(t);
      gf::detail::evaluateElementRange(v, 0, set.count);
      double worst[4] = {0, 0, 0, 0};
      for (size_t t = 0; t < T; ++t) {
        const double d[4] = {
            relDiff(&scalar.energy[t], &lanes.energy[t], 1),
            relDiff(&scalar.grad[12 * t], &lanes.grad[12 * t], 12),
            relDiff(&scalar.hess[gf::kElementMatrixSize * t],
                    &lanes.hess[gf::kElementMatrixSize * t], gf::kElementMatrixSize),
            relDiff(&scalar.stress[6 * t], &lanes.stress[6 * t], 6)};
        for (int q = 0; q < 4; ++q) {
          worst[q] = std::max(worst[q], d[q]);
          EXPECT_LE(d[q], 1e-12) << "model " << c.model << (wet ? " wet" : "") << " tet " << t
                                 << " output " << q << " (energy, gradient, Hessian, stress)";
        }
      }
      std::printf(
          "model %d%s: largest relative difference energy %.1e gradient %.1e Hessian "
          "%.1e stress %.1e\n",
          c.model, wet ? " wet" : "", worst[0], worst[1], worst[2], worst[3]);
    }
  }
}

TEST(ElementLanes, BitsDoNotDependOnTheRangeNorTheCache) {
  const TetSet set = generalTets();
  const size_t T = size_t(set.count);
  // A damaged tet and a rigid one among the others: both go the scalar way.
  std::vector<uint8_t> mask(T, 0), rigid(T, 0);
  std::vector<double> chi(T, 1.0);
  mask[4] = 3;
  chi[4] = 0.5;
  rigid[9] = 1;
  for (const MaterialCoeffs& c : isotropicModels()) {
    auto run = [&](int grain, double* cache, bool full) {
      Out o(T);
      gf::detail::ElementStage s = stageFor(set, c, o);
      s.tetMask = mask.data();
      s.damageModel = gf::kDamageDegradation;
      s.chi = chi.data();
      s.rigidTet = rigid.data();
      s.svdCache = cache;
      if (!full) s.grad = s.hess = s.stress = nullptr;
      for (int32_t b = 0; b < set.count; b += grain)
        gf::detail::evaluateElementRange(s, b, std::min(set.count, b + grain));
      return o;
    };
    const Out whole = run(set.count, nullptr, true);
    for (int grain : {1, 3, 7}) {
      const Out split = run(grain, nullptr, true);
      EXPECT_TRUE(sameBits(split.energy, whole.energy) && sameBits(split.grad, whole.grad) &&
                  sameBits(split.hess, whole.hess) && sameBits(split.stress, whole.stress))
          << "model " << c.model << " ranges of " << grain;
    }
    std::vector<double> cache(size_t(gf::kSvdCacheStride) * T);
    for (size_t t = 0; t < T; ++t) gf::initSvdCacheEntry(cache.data() + gf::kSvdCacheStride * t);
    for (int pass = 0; pass < 2; ++pass) {  // misses, then hits
      const Out cached = run(5, cache.data(), true);
      EXPECT_TRUE(sameBits(cached.energy, whole.energy) && sameBits(cached.grad, whole.grad) &&
                  sameBits(cached.hess, whole.hess) && sameBits(cached.stress, whole.stress))
          << "model " << c.model << " cache pass " << pass;
    }
    const Out energyOnly = run(3, cache.data(), false);
    EXPECT_TRUE(sameBits(energyOnly.energy, whole.energy)) << "model " << c.model;
    // The damaged and the rigid tet are the scalar path's to the bit.
    Out scalar(T);
    gf::detail::ElementStage s = stageFor(set, c, scalar);
    s.tetMask = mask.data();
    s.damageModel = gf::kDamageDegradation;
    s.chi = chi.data();
    s.rigidTet = rigid.data();
    for (int32_t t : {4, 9}) {
      s(t);
      EXPECT_EQ(scalar.energy[size_t(t)], whole.energy[size_t(t)]);
      const size_t h = gf::kElementMatrixSize * size_t(t);
      EXPECT_EQ(
          0, std::memcmp(&scalar.hess[h], &whole.hess[h], gf::kElementMatrixSize * sizeof(double)));
    }
  }
}

}  // namespace
