// Impurities (thesis sec 5.2, eq 5.1-5.3) against independent truths: h of eq 5.3 against its
// definition, the draws' moments against N(0, sigma^2) and U of equal variance, the
// monotonicity eq 5.1 promises (more impurity or a more damaged neighbourhood: more likely to
// break when degrading), and the incremental strength update against a full recomputation.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "fracture/impurity.h"
#include "graphfrac/mesh.h"
#include "kernels/impurity.h"
#include "mesh/edge_graph.h"

namespace gf {
namespace {

TEST(Impurity, OneMinusHMatchesEq53) {
  for (double x : {0.01, 0.5, 1.0, 2.0, 5.0, 20.0}) {
    const double h = (std::exp(x) - 1) / (std::exp(x) + 1);  // eq 5.3
    EXPECT_NEAR(oneMinusH(x), 1 - h, 1e-15 + 1e-12 * (1 - h)) << x;
  }
  EXPECT_EQ(oneMinusH(HUGE_VAL), 0.0);
  EXPECT_GT(oneMinusH(800.0), -1e-300);  // no NaN where e^x overflows
}

TEST(Impurity, DrawsHaveTheRequestedMomentsAndNoZeros) {
  const int n = 200000;
  const double sigma = 1.7;
  for (int noise = 0; noise < 2; ++noise) {
    double sum = 0, sum2 = 0, sum4 = 0;
    for (int k = 0; k < n; ++k) {
      const double a = noise == 0 ? impurityGaussian(42, k, sigma) : impurityUniform(42, k, sigma);
      ASSERT_NE(a, 0.0);
      sum += a;
      sum2 += a * a;
      sum4 += a * a * a * a;
    }
    const double mean = sum / n, var = sum2 / n - mean * mean, kurt = (sum4 / n) / (var * var);
    // Standard error of the mean sigma / sqrt(n) = 0.0038; of the variance ~0.3 %.
    EXPECT_LT(std::fabs(mean), 5 * sigma / std::sqrt(double(n))) << noise;
    EXPECT_NEAR(var, sigma * sigma, 0.02 * sigma * sigma) << noise;
    // Kurtosis tells the two apart: 3 for a Gaussian, 9/5 for a uniform distribution.
    EXPECT_NEAR(kurt, noise == 0 ? 3.0 : 1.8, 0.05) << noise;
  }
}

TEST(Impurity, DrawsArePureFunctionsOfSeedAndNode) {
  int differ = 0;
  for (int k = 0; k < 1000; ++k) {
    EXPECT_EQ(impurityGaussian(7, k, 1), impurityGaussian(7, k, 1));
    differ += impurityGaussian(7, k, 1) != impurityGaussian(8, k, 1);
  }
  EXPECT_EQ(differ, 1000);
}

TEST(Impurity, Eq51IsMonotoneInImpurityAndDegree) {
  // Degradation: more impurity or fewer intact neighbours -> higher break probability.
  double last = -1;
  for (double a : {0.1, 0.5, 1.0, 3.0, 10.0}) {
    const double p = impurityBreakProbability(1, 1, a, a, false);
    EXPECT_GT(p, last) << a;
    last = p;
  }
  last = -1;
  for (double d : {1.0, 0.8, 0.5, 0.2}) {
    const double p = impurityBreakProbability(d, d, 2, 2, false);
    EXPECT_GT(p, last) << d;
    last = p;
  }
  // Upgradation: more impurity -> lower probability, a damaged neighbourhood -> higher.
  EXPECT_LT(impurityBreakProbability(1, 1, 2, 2, true), impurityBreakProbability(1, 1, 1, 1, true));
  EXPECT_GT(impurityBreakProbability(0.5, 0.5, 1, 1, true),
            impurityBreakProbability(1, 1, 1, 1, true));
  // A pure intact edge keeps the material's strength in both modes; the sign of alpha is
  // irrelevant (eq 5.1 uses |alpha|).
  EXPECT_EQ(impurityStrengthFactor(1, 1, 0, 0, false), 1.0);
  EXPECT_NEAR(impurityStrengthFactor(1, 1, 0, 0, true), 1.0, 1e-15);
  EXPECT_EQ(impurityStrengthFactor(1, 1, -2, 3, false), impurityStrengthFactor(1, 1, 2, -3, false));
  EXPECT_LT(impurityStrengthFactor(1, 1, 3, 3, false), 1.0);
  EXPECT_GT(impurityStrengthFactor(1, 1, 3, 3, true), 1.0);
}

TEST(Impurity, IncrementalStrengthsMatchAFullRecomputation) {
  const TetMesh mesh = gen::box(1, 0.3, 0.3, 8, 3, 3);
  const detail::EdgeGraph g =
      detail::EdgeGraph::build(mesh.tets.data(), mesh.tetCount(), mesh.nodeCount());
  for (ImpurityMode mode : {ImpurityMode::Degradation, ImpurityMode::Upgradation}) {
    ImpuritySettings s;
    s.enabled = true;
    s.sigma = 2;
    s.mode = mode;
    detail::ImpurityField f;
    std::vector<double> strength(size_t(g.edgeCount), 1e6);
    f.init(g, s, strength);
    std::vector<uint8_t> broken(size_t(g.edgeCount), 0);
    f.refreshAll(g, broken.data(), strength);
    std::vector<int32_t> cut;
    for (int32_t e = 0; e < g.edgeCount; e += 7) cut.push_back(e);
    for (int32_t e : cut) broken[size_t(e)] = 1;
    f.onBreaks(g, cut.data(), cut.size(), broken.data(), strength);
    // From scratch: degrees counted from the broken flags.
    detail::ImpurityField ref = f;
    ref.degree = ref.restDegree;
    for (int32_t e = 0; e < g.edgeCount; ++e)
      if (broken[size_t(e)]) {
        --ref.degree[size_t(g.edgeNodes[2 * e])];
        --ref.degree[size_t(g.edgeNodes[2 * e + 1])];
      }
    EXPECT_EQ(ref.degree, f.degree);
    int weaker = 0;
    for (int32_t e = 0; e < g.edgeCount; ++e) {
      if (broken[size_t(e)]) continue;
      EXPECT_EQ(strength[size_t(e)], ref.effectiveStrength(g, e)) << e;
      const int32_t i = g.edgeNodes[2 * e], j = g.edgeNodes[2 * e + 1];
      const double intact =
          1e6 * impurityStrengthFactor(1, 1, f.alpha[size_t(i)], f.alpha[size_t(j)],
                                       mode == ImpurityMode::Upgradation);
      weaker += strength[size_t(e)] < intact;
    }
    EXPECT_GT(weaker, 0);  // the damage around the cut edges lowered some strengths
  }
}

}  // namespace
}  // namespace gf
