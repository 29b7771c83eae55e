// The per-tet SVD cache (kernels/svd3.h, issue 14): a criterion or element pass that takes
// svd3(F) from the cache must give the same bits as one that recomputes it, on random
// deformed, inverted and degenerate tets, for every material model; the energy-only element
// pass must give the same energy bits as the full one. The truth is the plain kernels
// (materialStress, elementForces) without any cache.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "common/tet_set.h"
#include "fem/element_stage.h"
#include "fracture/fracture_stages.h"
#include "kernels/edge_stress.h"
#include "kernels/element.h"

namespace {

using gf::Mat3;
using gf::MaterialCoeffs;
using gf::Vec3;
using gf::test::TetSet;

bool sameBits(const double* a, const double* b, size_t n) {
  return std::memcmp(a, b, n * sizeof(double)) == 0;
}

// randomTets: separate tets deformed in every way the cache has to survive: moderate random
// deformations, inversions, flattened, collapsed to a line or a point, and a pure rotation (F
// with exact zeros).
TetSet randomTets(uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0, 1);
  TetSet set;
  const Vec3 base[4] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  for (int k = 0; k < 240; ++k) {
    Vec3 X[4], xd[4];
    for (int a = 0; a < 4; ++a) X[a] = 0.1 * (base[a] + 0.15 * Vec3{n(rng), n(rng), n(rng)});
    const double strain = k % 3 == 0 ? 0.3 : 0.03;
    for (int a = 0; a < 4; ++a)
      xd[a] = X[a] + strain * 0.1 * Vec3{n(rng), n(rng), n(rng)} + Vec3{0.3, -0.2, 0.5};
    switch (k % 8) {
      case 1:  // inverted: node 3 through the opposite face
        xd[3] = xd[0] + 0.4 * ((xd[3] - xd[0]) - 2.0 * Vec3{0, 0, xd[3].z - xd[0].z});
        break;
      case 2:  // flat: node 3 in the plane of the others
        xd[3] = xd[0] + 0.3 * (xd[1] - xd[0]) + 0.5 * (xd[2] - xd[0]);
        break;
      case 3:  // collapsed to a line
        xd[2] = xd[0] + 0.5 * (xd[1] - xd[0]);
        xd[3] = xd[0] + 2.0 * (xd[1] - xd[0]);
        break;
      case 4:  // collapsed to a point
        for (int a = 1; a < 4; ++a) xd[a] = xd[0];
        break;
      case 5:  // rest shape, rigidly moved by a quarter turn about z: F has exact zeros
        for (int a = 0; a < 4; ++a) xd[a] = Vec3{-X[a].y, X[a].x, X[a].z};
        break;
      default:
        break;
    }
    set.add(X, xd);
  }
  return set;
}

std::vector<MaterialCoeffs> allModels() {
  std::vector<MaterialCoeffs> out;
  for (int model = gf::kCorotated; model <= gf::kStableNeoHookean; ++model)
    out.push_back(gf::makeMaterialCoeffs(model, 1e7, 0.3, 0, Vec3{1, 0, 0}));
  // With a fibre term, which reads F and the SVD's V.
  out.push_back(gf::makeMaterialCoeffs(gf::kStableNeoHookean, 1e7, 0.3, 3e6, Vec3{1, 2, 0.5}));
  return out;
}

std::vector<double> freshCache(int32_t tets) {
  std::vector<double> cache(size_t(gf::kSvdCacheStride) * size_t(tets));
  for (int32_t t = 0; t < tets; ++t)
    gf::initSvdCacheEntry(cache.data() + gf::kSvdCacheStride * size_t(t));
  return cache;
}

gf::detail::CriterionStressStage criterionStage(const TetSet& set, const MaterialCoeffs& c,
                                                const std::vector<uint8_t>& mask, double* stress,
                                                double* cache) {
  gf::detail::CriterionStressStage s;
  s.tets = set.tets.data();
  s.x = set.x.data();
  s.restInverse = set.restInverse.data();
  s.coeffs = c;
  s.tetMask = mask.data();
  s.undamagedToo = true;
  s.stress = stress;
  s.svdCache = cache;
  return s;
}

TEST(SvdCache, CriterionStressFromTheCacheHasTheBitsOfARecomputation) {
  const TetSet set = randomTets(7);
  const size_t T = size_t(set.count);
  const std::vector<uint8_t> mask(T, 0);
  int models = 0;
  for (const MaterialCoeffs& c : allModels()) {
    ++models;
    // The truth: materialStress recomputing svd3 (the criterion before the cache).
    std::vector<double> truth(6 * T);
    for (int32_t t = 0; t < set.count; ++t) {
      Vec3 xe[4];
      gf::detail::tetCorners(set.tets.data(), set.x.data(), t, xe);
      gf::toVoigt(gf::materialStress(c, gf::deformationGradient(xe, set.restInverse[size_t(t)])),
                  truth.data() + 6 * t);
    }
    std::vector<double> cache = freshCache(set.count);
    std::vector<double> miss(6 * T), hit(6 * T);
    const auto fill = criterionStage(set, c, mask, miss.data(), cache.data());
    for (int32_t t = 0; t < set.count; ++t) fill(t);
    // Every entry now holds its tet's F: the second pass reads each SVD from the cache.
    const std::vector<double> filled = cache;
    const auto reuse = criterionStage(set, c, mask, hit.data(), cache.data());
    for (int32_t t = 0; t < set.count; ++t) reuse(t);
    EXPECT_TRUE(sameBits(miss.data(), truth.data(), 6 * T)) << "model " << c.model;
    EXPECT_TRUE(sameBits(hit.data(), truth.data(), 6 * T)) << "model " << c.model;
    EXPECT_TRUE(sameBits(cache.data(), filled.data(), cache.size()))
        << "a hit must not rewrite its entry";
  }
  EXPECT_EQ(models, 5);
}

TEST(SvdCache, AStoredSvdIsReadOnlyForTheSameBitsOfF) {
  // F = I (rest shape), whose off-diagonal entries are +0; a key that differs only in the
  // sign of one zero, or is NaN, must not match, and an exact key must be read (shown by a
  // planted wrong SVD that then comes back).
  Mat3 F = Mat3::identity();
  double entry[gf::kSvdCacheStride];
  gf::initSvdCacheEntry(entry);
  const gf::Svd3 truth = gf::svd3(F);
  (void)gf::cachedSvd3(F, entry);  // stores F and its SVD
  entry[18] = 2.0;                 // plant a wrong s0
  EXPECT_EQ(gf::cachedSvd3(F, entry).s.x, 2.0) << "an exact key must be read";

  entry[1] = -0.0;  // key F(0,1) = -0: not F's bits
  entry[18] = 2.0;
  const gf::Svd3 r = gf::cachedSvd3(F, entry);
  EXPECT_TRUE(sameBits(r.U.m, truth.U.m, 9) && sameBits(&r.s.x, &truth.s.x, 1) &&
              sameBits(r.V.m, truth.V.m, 9))
      << "a key differing in a zero's sign must miss";
  EXPECT_FALSE(std::signbit(entry[1])) << "the miss stores F's own bits as the key";

  Mat3 G = F;
  G(2, 1) = std::nan("");
  const gf::Svd3 g1 = gf::cachedSvd3(G, entry);
  entry[18] = 2.0;  // a NaN key never matches, so the planted value is never read
  EXPECT_NE(gf::cachedSvd3(G, entry).s.x, 2.0);
  (void)g1;
}

TEST(SvdCache, ElementPassWithTheCacheHasTheBitsOfOneWithout) {
  const TetSet set = randomTets(11);
  const size_t T = size_t(set.count);
  // Some tets damaged (degradation model, lagged chi), one handed to rigid physics.
  std::vector<uint8_t> mask(T, 0), rigid(T, 0);
  std::vector<double> chi(T, 1.0);
  for (size_t t = 0; t < T; t += 17) {
    mask[t] = uint8_t(1u << (t % 6));
    chi[t] = 0.25;
  }
  rigid[5] = 1;
  for (const MaterialCoeffs& c : allModels()) {
    gf::detail::ElementStage s;
    s.tets = set.tets.data();
    s.x = set.x.data();
    s.restInverse = set.restInverse.data();
    s.restVolume = set.restVolume.data();
    s.coeffs = c;
    s.tetMask = mask.data();
    s.damageModel = gf::kDamageDegradation;
    s.chi = chi.data();
    s.rigidTet = rigid.data();
    struct Out {
      std::vector<double> energy, grad, hess, stress;
    };
    auto run = [&](double* cache, bool full) {
      Out o{std::vector<double>(T), std::vector<double>(12 * T),
            std::vector<double>(gf::kElementMatrixSize * T), std::vector<double>(6 * T)};
      gf::detail::ElementStage p = s;
      p.energy = o.energy.data();
      p.grad = full ? o.grad.data() : nullptr;
      p.hess = full ? o.hess.data() : nullptr;
      p.stress = full ? o.stress.data() : nullptr;
      p.svdCache = cache;
      for (int32_t t = 0; t < set.count; ++t) p(t);
      return o;
    };
    const Out plain = run(nullptr, true);
    std::vector<double> cache = freshCache(set.count);
    const Out miss = run(cache.data(), true);
    const Out hit = run(cache.data(), true);
    const Out energyOnlyHit = run(cache.data(), false);
    std::vector<double> cold = freshCache(set.count);
    const Out energyOnlyMiss = run(cold.data(), false);
    for (const Out* o : {&miss, &hit}) {
      EXPECT_TRUE(sameBits(o->energy.data(), plain.energy.data(), T)) << "model " << c.model;
      EXPECT_TRUE(sameBits(o->grad.data(), plain.grad.data(), 12 * T)) << "model " << c.model;
      EXPECT_TRUE(sameBits(o->hess.data(), plain.hess.data(), gf::kElementMatrixSize * T))
          << "model " << c.model;
      EXPECT_TRUE(sameBits(o->stress.data(), plain.stress.data(), 6 * T)) << "model " << c.model;
    }
    EXPECT_TRUE(sameBits(energyOnlyHit.energy.data(), plain.energy.data(), T))
        << "model " << c.model;
    EXPECT_TRUE(sameBits(energyOnlyMiss.energy.data(), plain.energy.data(), T))
        << "model " << c.model;
    // The energy-only pass filled the cold cache as the full pass filled the other.
    EXPECT_TRUE(sameBits(cold.data(), cache.data(), cache.size())) << "model " << c.model;
    // And the energies are the plain kernel's, not something both paths got wrong alike.
    Vec3 xe[4];
    gf::detail::tetCorners(set.tets.data(), set.x.data(), 1, xe);  // tet 1: intact
    double g[12];
    const double e1 = gf::elementForces(gf::detail::tetCoeffs(c, nullptr, 1), xe,
                                        set.restInverse[1], set.restVolume[1], g, nullptr, true);
    EXPECT_EQ(e1, plain.energy[1]);
  }
}

}  // namespace
