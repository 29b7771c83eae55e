// The force-ratio split point of a broken edge (kernels/split_point.h, thesis fig 4.10): the
// edge's sections are in inverse proportion to its nodes' forces, whatever the forces'
// directions, and every ratio stays inside the clamp, also for missing or broken forces.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "kernels/split_point.h"

namespace gf {
namespace {

TEST(SplitPoint, SectionsAreInInverseProportionToTheNodalForces) {
  // Equal forces: the midpoint, whichever way they point.
  EXPECT_DOUBLE_EQ(forceRatioSplit({3, 0, 0}, {0, -3, 0}), 0.5);
  // |f_b| = 3 |f_a|: the section at a is three times the one at b, t = 3 / 4.
  const double t = forceRatioSplit({0, 0, 2}, {-6, 0, 0});
  EXPECT_DOUBLE_EQ(t, 0.75);
  EXPECT_DOUBLE_EQ(t / (1 - t), 3.0);
  // Swapping the nodes mirrors the point.
  EXPECT_DOUBLE_EQ(forceRatioSplit({-6, 0, 0}, {0, 0, 2}), 0.25);
  // Beyond 9 : 1 the clamp holds the point off the node.
  EXPECT_DOUBLE_EQ(forceRatioSplit({1, 0, 0}, {0, 20, 0}), 1 - kMinSplitRatio);
  EXPECT_DOUBLE_EQ(forceRatioSplit({0, 0, 0}, {0, 1, 0}), 1 - kMinSplitRatio);
  EXPECT_DOUBLE_EQ(forceRatioSplit({0, 1, 0}, {0, 0, 0}), kMinSplitRatio);
}

TEST(SplitPoint, NoForceOrABrokenForceGivesTheMidpoint) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(forceRatioSplit({0, 0, 0}, {0, 0, 0}), 0.5);
  EXPECT_EQ(forceRatioSplit({nan, 0, 0}, {1, 0, 0}), 0.5);
  EXPECT_EQ(forceRatioSplit({inf, 0, 0}, {1, 0, 0}), 0.5);
  EXPECT_EQ(clampSplitRatio(nan), 0.5);
  EXPECT_EQ(clampSplitRatio(-inf), 0.5);
  EXPECT_EQ(clampSplitRatio(-0.3), kMinSplitRatio);
  EXPECT_EQ(clampSplitRatio(1.7), 1 - kMinSplitRatio);
  EXPECT_EQ(clampSplitRatio(0.37), 0.37);
}

}  // namespace
}  // namespace gf
