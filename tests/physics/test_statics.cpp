// Static validation against analytic answers: patch test, cantilever, hanging column.
// Statics come from the implicit integrator with a time step so long that inertia is
// negligible (its relative weight is rho L^2 / (E dt^2) < 1e-9) and full Newton to 1e-10.
#include <gtest/gtest.h>

#include <cmath>

#include "common/beams.h"
#include "common/sim_helpers.h"

namespace gf {
namespace {

// Patch test: boundary nodes follow the affine field of uniaxial stress; the interior must
// reproduce it exactly, i.e. every element has the same F.
TEST(PatchTest, UniaxialStretchReproducesAffineField) {
  for (MaterialModel model : {MaterialModel::Corotated, MaterialModel::StVK,
                              MaterialModel::NeoHookean, MaterialModel::StableNeoHookean}) {
    // Dyadic values keep the float grip velocities exact, so the boundary field is exactly affine.
    const double eps = 0.0625, nu = 0.25, dt = 1024;
    const double F0[3] = {1 + eps, 1 - nu * eps, 1 - nu * eps};
    BodyDef def;
    def.mesh = gen::box(1, 1, 1, 4, 4, 4);
    def.material = Material::stableNeoHookean(1e6, nu, 1000);
    def.material.model = model;
    def.solver = test::staticSolver();
    for (int32_t n : test::selectNodes(def.mesh, [](double x, double y, double z) {
           auto onFace = [](double c) { return c < 1e-9 || c > 1 - 1e-9; };
           return onFace(x) || onFace(y) || onFace(z);
         })) {
      Grip g;
      g.nodes = {n};
      const double* p = &def.mesh.positions[3 * n];
      g.velocity = glm::vec3(float((F0[0] - 1) * p[0] / dt), float((F0[1] - 1) * p[1] / dt),
                             float((F0[2] - 1) * p[2] / dt));
      def.grips.push_back(g);
    }
    World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
    const TetMesh rest = def.mesh;
    auto id = world.createBody(def);
    ASSERT_TRUE(id.ok()) << id.error().message;
    ASSERT_TRUE(world.step(dt).ok());
    const auto x = world.positions(id.value());
    double worst = 0;
    for (size_t e = 0; e < rest.tetCount(); ++e) {
      const Mat3 F = test::tetDeformationGradient(rest, x, e);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          const double want = i == j ? F0[i] : 0.0;
          worst = std::max(worst, std::abs(F(i, j) - want));
        }
    }
    std::printf("patch test model %d: max |F - F_exact| = %.3e\n", int(model), worst);
    EXPECT_LT(worst, 1e-8) << "model " << int(model);
  }
}

// Linear tetrahedra lock in bending: the error is set by the cells through the thickness
// (docs/validation.md): 39.6 % at 40x2x2 cells, 14.7 % at 80x4x4, 4.5 % at 160x8x8 and 2.3 %
// at 240x12x12. This fast test checks the convergence; tests/slow checks the fine meshes.
TEST(Cantilever, TipDeflectionConvergesToTimoshenko) {
  const test::BeamResult coarse = test::cantilever(40, 2);
  const test::BeamResult fine = test::cantilever(80, 4);
  const double errCoarse = (coarse.analytic - coarse.tip) / coarse.analytic;
  const double errFine = (fine.analytic - fine.tip) / fine.analytic;
  std::printf("cantilever: analytic %.6e m; 40x2x2: %.6e (%.2f%%); 80x4x4: %.6e (%.2f%%)\n",
              coarse.analytic, coarse.tip, 100 * errCoarse, fine.tip, 100 * errFine);
  // Too stiff, never too soft (locking), and the error more than halves per refinement.
  EXPECT_GT(errCoarse, 0.0);
  EXPECT_GT(errFine, 0.0);
  EXPECT_LT(errFine, 0.5 * errCoarse);
  EXPECT_LT(errFine, 0.25);
}

TEST(HangingColumn, StretchMatchesRhoGL2Over2E) {
  const double L = 1.0, w = 0.1, E = 1e8, rho = 1000, g = 9.81;
  for (double nu : {0.0, 0.3}) {
    BodyDef def;
    def.mesh = gen::box(w, L, w, 2, 20, 2);
    def.material = Material::stableNeoHookean(E, nu, rho);
    def.solver = test::staticSolver();
    Grip top;
    top.nodes = test::selectNodes(def.mesh, [&](double, double y, double) { return y > L - 1e-9; });
    def.grips.push_back(top);
    const TetMesh rest = def.mesh;
    World world(WorldDef{glm::vec3(0, -g, 0), Backend::Cpu, nullptr, 1, {}});
    auto id = world.createBody(def);
    ASSERT_TRUE(id.ok());
    for (int s = 0; s < 2; ++s) {
      const StepStatus st = world.step(1e3);
      ASSERT_TRUE(st.ok()) << st.flags << " " << st.message;
    }
    const auto bottom = test::selectNodes(rest, [](double, double y, double) { return y < 1e-9; });
    const double stretch = -test::meanDisplacement(world, id.value(), rest, bottom, 1);
    const double analytic = rho * g * L * L / (2 * E);
    const double err = std::abs(stretch - analytic) / analytic;
    std::printf("hanging column nu=%.1f: %.6e m vs rho g L^2/2E = %.6e m (%.3f%%)\n", nu, stretch,
                analytic, 100 * err);
    // nu = 0 is exactly one-dimensional; with nu = 0.3 the clamped top face stiffens a little.
    EXPECT_LT(err, nu == 0.0 ? 0.005 : 0.03);
  }
}

}  // namespace
}  // namespace gf
