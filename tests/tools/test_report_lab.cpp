// The laboratory tests of `graphfrac report lab` (tools/cli/report_lab.h): their scenes load, bad
// input names the file and field, and the Brazilian disc, on a coarser disc than the report's,
// splits along its loaded diameter from near its centre at 2 P / (pi D t) within 15 % of the
// granite's sigma_th (issue 19's acceptance). The same disc judged by the local criterion starts
// breaking at a jaw instead (docs/design.md, "Mesh-independent first break"), which shows the
// assertions can fail. The coarse brittle Charpy bar falls in two at its notch; the other
// impact tests and the rate check take longer: tests/slow.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "cli/report_lab.h"

namespace gf::cli::lab {
namespace {

const std::string kLab = std::string(GF_SOURCE_DIR) + "/scenes/lab/";
// Half the scene's layers through the thickness: 6144 tets, a few seconds.
constexpr const char* kCoarseDisc = R"({"layers": 4})";

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(LabReport, ScenesLoadAndBadInputNamesTheFileAndField) {
  for (const char* name : {"brazilian_disc.json", "charpy_brittle.json", "charpy_ductile.json",
                           "izod_brittle.json", "izod_ductile.json"}) {
    const Result<scene::Scene> s = loadLabScene(kLab + name, R"({})");
    EXPECT_TRUE(s.ok()) << name << ": " << (s.ok() ? "" : s.error().message);
  }
  // A resolution override goes through the scene loader, which names the key it landed on.
  const Result<scene::Scene> bad =
      loadLabScene(kLab + "brazilian_disc.json", R"({"segments": "many"})");
  ASSERT_FALSE(bad.ok());
  EXPECT_TRUE(contains(bad.error().message, "brazilian_disc.json")) << bad.error().message;
  EXPECT_TRUE(contains(bad.error().message, "bodies[0].mesh.segments")) << bad.error().message;
  const Result<scene::Scene> notObject = loadLabScene(kLab + "brazilian_disc.json", "[64]");
  ASSERT_FALSE(notObject.ok());
  EXPECT_TRUE(contains(notObject.error().message, "mesh resolution override"));
  const Result<scene::Scene> missing = loadLabScene(kLab + "no_such_test.json", kCoarseDisc);
  ASSERT_FALSE(missing.ok());
  EXPECT_TRUE(contains(missing.error().message, "no_such_test.json")) << missing.error().message;

  // Each experiment says what its scene lacks.
  const Result<scene::Scene> charpy = loadLabScene(kLab + "charpy_brittle.json", "{}");
  const Result<scene::Scene> disc = loadLabScene(kLab + "brazilian_disc.json", "{}");
  ASSERT_TRUE(charpy.ok() && disc.ok());
  const Result<BrazilianResult> noJaws = runBrazilian(charpy.value());
  ASSERT_FALSE(noJaws.ok());
  EXPECT_TRUE(contains(noJaws.error().message, "bodies[0].grips")) << noJaws.error().message;
  const Result<ImpactResult> noStriker = runImpact(disc.value(), ImpactSetup{});
  ASSERT_FALSE(noStriker.ok());
  EXPECT_TRUE(contains(noStriker.error().message, "colliders")) << noStriker.error().message;
  EXPECT_FALSE(runBrazilian(disc.value(), 0.0).ok());

  // The command line: usage errors, and a scene directory without the lab scenes.
  auto report = [](std::vector<std::string> args) {
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    return runReportCommand(int(argv.size()), argv.data());
  };
  EXPECT_EQ(report({"report", "lab", "--bogus"}), kExitUsage);
  EXPECT_EQ(report({"report", "lab", "--only", "pendulum"}), kExitUsage);
  EXPECT_EQ(report({"report", "lab", "--out"}), kExitUsage);
  const std::string out = (std::filesystem::temp_directory_path() / "gf_lab_report_test").string();
  EXPECT_EQ(report({"report", "lab", "--quick", "--only", "brazilian", "--scenes", "/nonexistent",
                    "--out", out}),
            kExitScene);
}

TEST(LabReport, BrazilianDiscSplitsAlongItsDiameterAtTheGranitesStrength) {
  const Result<scene::Scene> sc = loadLabScene(kLab + "brazilian_disc.json", kCoarseDisc);
  ASSERT_TRUE(sc.ok()) << sc.error().message;
  const Result<BrazilianResult> run = runBrazilian(sc.value());
  ASSERT_TRUE(run.ok()) << run.error().message;
  const BrazilianResult& r = run.value();
  std::printf(
      "coarse disc, %zu tets: first break at %.4g N, P = %.4g N, 2P/(pi D t) = %.4g sigma_th, "
      "first "
      "break %.3f D from the centre, %d broken edges, %.0f %% within 0.1 D of the diameter\n",
      r.tets, r.firstBreakLoad, r.peakLoad, r.indirectStrength / r.strength, r.firstBreakFromCentre,
      r.broken, 100 * r.onDiameter);
  EXPECT_EQ(r.flaggedSteps, 0);
  EXPECT_NEAR(r.diameter, 0.05, 1e-9);
  EXPECT_NEAR(r.thickness, 0.02, 1e-9);
  EXPECT_NEAR(r.indirectStrength / r.strength, 1.0, 0.15);
  EXPECT_LT(r.firstBreakFromCentre, 0.2);
  // Failure means the load gave way, and most of the crack then lies along the diameter.
  EXPECT_LT(r.curve.load.back(), 0.3 * r.peakLoad);
  EXPECT_GT(r.onDiameter, 0.5);

  // Judged locally, the jaws' edges are stress singularities: it breaks there first, early.
  scene::Scene local = sc.value();
  local.bodies[0].def.fracture.nonlocalLength = 0;
  const Result<BrazilianResult> atJaw = runBrazilian(local);
  ASSERT_TRUE(atJaw.ok()) << atJaw.error().message;
  std::printf("judged locally: first break at %.4g N, %.3f D from the centre\n",
              atJaw.value().firstBreakLoad, atJaw.value().firstBreakFromCentre);
  EXPECT_GT(atJaw.value().firstBreakFromCentre, 0.3);
  EXPECT_LT(atJaw.value().firstBreakLoad, 0.85 * r.firstBreakLoad);
}

// Brittle A516 is split by cleavage, which crosses the 8 mm ligament in a few microseconds
// (1-3 km/s) while the striker moves a few tens of micrometres: the bar must fall in two in
// the step its first edge breaks, at the notch (a bar cut at mid-length leaves half its nodes
// on each side). The scene's brittle mode (sec 4.5.1.2) does this; before it, judged edge by
// edge, this coarse bar's crack stopped at a hinge row and it stayed one piece (this test then
// fails). Izod, the fine bar and other strengths and steps: tests/slow.
TEST(LabReport, BrittleCharpyBarFallsInTwoAtTheNotchOnTheCoarseMesh) {
  const Result<scene::Scene> sc = loadLabScene(kLab + "charpy_brittle.json", "{}");
  ASSERT_TRUE(sc.ok()) << sc.error().message;
  ImpactSetup setup;
  setup.maxDisplacement = 0.3e-3;  // the first break comes at about 0.2 mm
  const Result<ImpactResult> run = runImpact(sc.value(), setup);
  ASSERT_TRUE(run.ok()) << run.error().message;
  const ImpactResult& r = run.value();
  std::printf(
      "coarse brittle bar, %zu tets: first break at %.4g N, %.3f mm; split at %.3f mm "
      "(%.2f / %.2f of the nodes), %d broken edges\n",
      r.tets, r.firstBreakLoad, 1e3 * r.firstBreakDisplacement, 1e3 * r.displacementAtSplit,
      r.largestShare, r.secondShare, r.broken);
  EXPECT_EQ(r.flaggedSteps, 0);
  ASSERT_GT(r.firstBreakDisplacement, 0);
  EXPECT_TRUE(r.splitInTwo());
  EXPECT_NEAR(r.largestShare, 0.5, 0.05);
  EXPECT_NEAR(r.secondShare, 0.5, 0.05);
  EXPECT_EQ(r.displacementAtSplit, r.firstBreakDisplacement);
  EXPECT_EQ(r.displacementAtFracture, r.displacementAtSplit);
}

}  // namespace
}  // namespace gf::cli::lab
