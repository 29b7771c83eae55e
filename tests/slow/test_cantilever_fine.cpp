// Slow validation (ctest label "slow"): the cantilever at 8 cells through the thickness.
#include <gtest/gtest.h>

#include "common/beams.h"

namespace gf {
namespace {

TEST(CantileverSlow, FineMeshWithinEightPercent) {
  const test::BeamResult r = test::cantilever(160, 8);
  const double err = (r.analytic - r.tip) / r.analytic;
  std::printf("cantilever 160x8x8: %.6e m vs %.6e m (%.2f%%)\n", r.tip, r.analytic, 100 * err);
  EXPECT_GT(err, 0.0);
  EXPECT_LT(err, 0.08);
}

}  // namespace
}  // namespace gf
