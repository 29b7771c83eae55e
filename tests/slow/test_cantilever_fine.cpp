// Slow validation (ctest label "slow"): the cantilever at 8 cells through the thickness.
#include <gtest/gtest.h>

#include <cstdlib>

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

namespace gf {
namespace {

// The full form (GF_FULL_VALIDATION=1; about an hour and 3.5 GB on 2 cores, so CI runs only
// the reduced form above): 16 cells through the thickness, 491 520 tets. Measured 1.53 %.
TEST(CantileverSlow, FullFormSixteenCellsWithinThreePercent) {
  if (std::getenv("GF_FULL_VALIDATION") == nullptr)
    GTEST_SKIP() << "set GF_FULL_VALIDATION=1 to run the 491k-tet cantilever";
  const test::BeamResult r = test::cantilever(320, 16);
  const double err = (r.analytic - r.tip) / r.analytic;
  std::printf("cantilever 320x16x16: %.6e m vs %.6e m (%.2f%%)\n", r.tip, r.analytic, 100 * err);
  EXPECT_GT(err, 0.0);
  EXPECT_LT(err, 0.03);
}

}  // namespace
}  // namespace gf
