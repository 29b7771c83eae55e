// Slow validation (ctest label "slow"): self contact between the pieces of a cut body in free
// fall (issue 15 item 1; docs/validation.md, "Pieces of a cut body falling together").
#include <graphfrac/world.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace gf {
namespace {

// The pieces of a bunny cut by 1, 2 or 3 planes (71, 222 and 373 fragments; at 3 planes 27
// pieces and 346 one-node chips: the cut layers hold slivers whose sides lie within the contact
// thickness) fall together with self contact on: nothing pushes them, so every node keeps the
// free fall's velocity g t. Before, a node deviated by 0.111 and 2.41 m/s within 30 steps (1, 2
// planes) and the 3-plane body diverged (NaN contained at step 25): planes of receding faces
// left one step's fall behind their vertices, a plane ahead of x_n acted in Newton's first step
// as a two-sided spring, and sliver sides that touch in the rest shape pushed each other
// (docs/validation.md).
TEST(BodyContactSlow, PiecesOfACutBodyFallTogether) {
  Result<TetMesh> bunny = TetMesh::fromFile(GF_SOURCE_DIR "/scenes/meshes/bunny_small.msh");
  ASSERT_TRUE(bunny.ok());
  const glm::vec3 normals[3] = {glm::normalize(glm::vec3(1, 0.3f, 0.1f)),
                                glm::normalize(glm::vec3(0.2f, 1, -0.3f)),
                                glm::normalize(glm::vec3(-0.1f, 0.2f, 1))};
  const double dt = 1.0 / 120, g = 9.81;
  for (int planes = 1; planes <= 3; ++planes) {
    World world(WorldDef{glm::vec3(0, float(-g), 0), Backend::Cpu, nullptr, 1, {}});
    BodyDef def;
    def.mesh = bunny.value();
    glm::dvec3 centre(0);
    for (double& c : def.mesh.positions) c *= 0.03;
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
      centre += glm::dvec3(def.mesh.positions[3 * n], def.mesh.positions[3 * n + 1],
                           def.mesh.positions[3 * n + 2]) /
                double(def.mesh.nodeCount());
    def.material = Material::stvk(1e9, 0.3, 2500);
    def.material.stiffnessDamping = 0.002;
    def.solver.linearSolver = LinearSolverKind::Direct;
    def.fracture.enabled = true;
    def.fracture.strength = 1e12;  // only the cuts break
    def.contact = true;
    const BodyId id = world.createBody(def).value();
    for (int p = 0; p < planes; ++p) {
      const glm::vec3 n = normals[p];
      const glm::vec3 t1 = glm::normalize(glm::cross(n, glm::vec3(0.3f, 0.5f, 0.8f)));
      const glm::vec3 t2 = glm::cross(n, t1);
      const glm::vec3 o = glm::vec3(centre) + 0.013f * float(p) * n;
      Blade blade;
      blade.vertices = {o - t1 - t2, o + t1 - t2, o + t1 + t2, o - t1 + t2};
      blade.triangles = {0, 1, 2, 0, 2, 3};
      ASSERT_TRUE(world.cut(id, blade).ok());
    }
    double deviation = 0;
    int64_t pairs = 0;
    for (int s = 1; s <= 30; ++s) {
      const StepStatus st = world.step(dt);
      ASSERT_FALSE(st.has(kStepNanContained)) << planes << " planes, step " << s;
      pairs += world.timings().contactPairs;
      const auto v = world.velocities(id);
      for (size_t i = 0; i < v.size(); ++i)
        deviation = std::max(deviation, std::abs(v[i] - (i % 3 == 1 ? -g * dt * s : 0.0)));
    }
    const FractureStats fs = world.fractureStats(id);
    std::printf(
        "%d planes: %d fragments, %lld contact pairs; largest deviation from free fall "
        "%.3g m/s\n",
        planes, fs.fragments, (long long)pairs, deviation);
    EXPECT_GT(pairs, 0);  // the self pairs are there, and must not push
    EXPECT_LT(deviation, 1e-5);
  }
}

}  // namespace
}  // namespace gf
