// The laboratory tests of `graphfrac report lab` in the reduced form CI's slow stage can afford
// (about a minute): the Brazilian disc's failure load does not depend on the jaws' rate
// (quasi-static), the brittle Charpy bar splits in two, the ductile one bends, stays joined and
// absorbs more energy (issue 19's acceptance; thesis figs 4.20-4.21). The brittle bar runs on the
// report's fine mesh (39k tets, the thesis used 27.8k): on the coarse one the last row of
// ligament edges lies on the halves' hinge line, and whether it breaks depends on the strength
// to within 5 % (docs/RESULTS.md, Charpy), so the coarse bar cannot tell a good model from luck.
// Built only with the tools (the experiments live in the CLI library).
#ifdef GF_SLOW_HAS_CLI
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "cli/report_lab.h"

namespace gf::cli::lab {
namespace {

const std::string kLab = std::string(GF_SOURCE_DIR) + "/scenes/lab/";

TEST(LabExperiments, BrazilianFailureLoadDoesNotDependOnTheJawRate) {
  const Result<scene::Scene> sc = loadLabScene(kLab + "brazilian_disc.json", "{}");
  ASSERT_TRUE(sc.ok()) << sc.error().message;
  const Result<BrazilianResult> fast = runBrazilian(sc.value(), 1.0);
  const Result<BrazilianResult> slow = runBrazilian(sc.value(), 0.5);
  ASSERT_TRUE(fast.ok() && slow.ok());
  const BrazilianResult &f = fast.value(), &s = slow.value();
  std::printf("jaws at %.3g and %.3g m/s: P = %.5g and %.5g N, first break %.5g and %.5g N\n",
              f.jawSpeed, s.jawSpeed, f.peakLoad, s.peakLoad, f.firstBreakLoad, s.firstBreakLoad);
  EXPECT_NEAR(s.peakLoad / f.peakLoad, 1.0, 0.02);
  EXPECT_NEAR(s.firstBreakLoad / f.firstBreakLoad, 1.0, 0.01);
  for (const BrazilianResult* r : {&f, &s}) {
    EXPECT_NEAR(r->indirectStrength / r->strength, 1.0, 0.15);
    EXPECT_LT(r->firstBreakFromCentre, 0.2);
  }
}

TEST(LabExperiments, CharpyBrittleBarSplitsDuctileBarBendsAndAbsorbsMore) {
  ImpactResult result[2];
  const char* names[2] = {"charpy_brittle.json", "charpy_ductile.json"};
  for (int i = 0; i < 2; ++i) {
    const char* overrides = i == 0 ? R"({"cells": [68, 12, 8]})" : "{}";
    const Result<scene::Scene> sc = loadLabScene(kLab + names[i], overrides);
    ASSERT_TRUE(sc.ok()) << sc.error().message;
    const Result<ImpactResult> run = runImpact(sc.value(), ImpactSetup{});
    ASSERT_TRUE(run.ok()) << run.error().message;
    result[i] = run.value();
    const ImpactResult& r = result[i];
    std::printf(
        "%s: peak %.4g N, fracture at %.3g mm, absorbed %.3g J, %d broken edges, fragments' "
        "shares %.2f / %.2f, ligament %.0f %% cut\n",
        names[i], r.peakLoad, 1e3 * r.displacementAtFracture, r.absorbedEnergy, r.broken,
        r.largestShare, r.secondShare, 100 * r.ligamentBroken);
    EXPECT_EQ(r.flaggedSteps, 0) << names[i];
  }
  const ImpactResult &brittle = result[0], &ductile = result[1];
  EXPECT_TRUE(brittle.splitInTwo());
  EXPECT_GT(brittle.ligamentBroken, 0.9);
  EXPECT_GT(brittle.displacementAtFracture, 0);
  EXPECT_FALSE(ductile.splitInTwo());
  EXPECT_GT(ductile.broken, 0);
  EXPECT_LT(ductile.ligamentBroken, 0.5);
  EXPECT_GT(ductile.absorbedEnergy, 2 * brittle.absorbedEnergy);
}

}  // namespace
}  // namespace gf::cli::lab
#endif  // GF_SLOW_HAS_CLI
