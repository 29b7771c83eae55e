// Slow validation (ctest label "slow"): the cantilever at 8 cells through the thickness.
#include <gtest/gtest.h>

#include "common/beams.h"

namespace gf {
namespace {

// 8 and 12 cells through the thickness (61k and 207k tets): the error keeps falling and the
// finer mesh is within 3 % of the Timoshenko tip deflection.
TEST(CantileverSlow, FineMeshesWithinThreePercent) {
  const test::BeamResult r8 = test::cantilever(160, 8);
  const test::BeamResult r12 = test::cantilever(240, 12);
  const double e8 = (r8.analytic - r8.tip) / r8.analytic;
  const double e12 = (r12.analytic - r12.tip) / r12.analytic;
  std::printf("cantilever: analytic %.6e m; 160x8x8: %.6e (%.2f%%); 240x12x12: %.6e (%.2f%%)\n",
              r8.analytic, r8.tip, 100 * e8, r12.tip, 100 * e12);
  EXPECT_GT(e12, 0.0);
  EXPECT_LT(e12, e8);
  EXPECT_LT(e8, 0.06);
  EXPECT_LT(e12, 0.03);
}

}  // namespace
}  // namespace gf
