// The scene loader against the runtime's rules and the initial state it builds: a scene is
// rejected by exactly the checks World::createBody and World::setColliders apply (reported at
// the scene key), the generator caps count the cells the generators really build, and
// addBody starts a body spinning (angular momentum I w) or pre-stretched (the analytic StVK
// energy).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <span>
#include <string>
#include <vector>

#include "common/mesh_checks.h"
#include "scene/scene.h"

namespace gf::scene {
namespace {

/// One box body with the given extra body keys (a JSON fragment starting with ',' or empty)
/// and extra top-level keys.
std::string boxScene(const std::string& bodyKeys, const std::string& topKeys = "") {
  return R"({"gravity": [0, 0, 0])" + topKeys + R"(, "bodies": [{"name": "box",
      "mesh": {"generator": "box", "size": [0.4, 0.2, 0.3], "cells": [4, 2, 3]},
      "translate": [1, 2, 3],
      "material": {"model": "stvk", "E": 1e6, "nu": 0.3, "rho": 1000})" +
         bodyKeys + "}]}";
}

std::string errorOf(const std::string& text) {
  const Result<Scene> r = parseScene(text, "inline", "");
  return r.ok() ? std::string("(loaded)") : r.error().message;
}

TEST(SceneState, SlabCapCountsTheLayersTheGeneratorBuilds) {
  // gen::slab sizes its layers by the smaller in-plane cell, min(sx/nx, sz/nz) = 0.01 here:
  // 5000 layers of 20 x 1 cells (600k tets). A cap that divides by sx/nx = 1 saw 50 layers.
  const std::string text = R"({"bodies": [{"mesh": {"generator": "slab", "size": [20, 0.01],
      "thickness": 50, "cells": [20, 1]}, "material": {"E": 1e6, "nu": 0.3, "rho": 1000}}]})";
  const std::string err = errorOf(text);
  EXPECT_NE(err.find("inline: bodies[0].mesh.cells: gives 5000 cells across the thickness"),
            std::string::npos)
      << err;
  // The same slab with a thickness of 3 cells builds, with the layers the cap predicted.
  const std::string ok = R"({"bodies": [{"mesh": {"generator": "slab", "size": [2, 0.1],
      "thickness": 0.3, "cells": [20, 1]}, "material": {"E": 1e6, "nu": 0.3, "rho": 1000}}]})";
  const Result<Scene> r = parseScene(ok, "inline", "");
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r.value().bodies[0].def.mesh.tetCount(), 6u * 20 * 1 * 3);
}

TEST(SceneState, CollidersFollowTheRulesOfSetColliders) {
  struct Case {
    std::string collider;
    std::string error;  // empty: accepted
  };
  const std::vector<Case> cases = {
      {R"({"type": "sphere", "center": [0, 0, 0], "radius": 0.5, "velocity": [1, 0, 0]})", ""},
      {R"({"type": "plane", "normal": [0, 2, 0], "stiffness": 1e18})", ""},
      // Finite, but beyond what the penalty can hold without overflowing.
      {R"({"type": "plane", "stiffness": 1e19})", "inline: colliders[0].stiffness: must lie in"},
      {R"({"type": "sphere", "center": [0, 0, 0], "radius": 2e9})",
       "inline: colliders[0].radius: must be positive and at most 1e9 m"},
      {R"({"type": "box", "center": [0, 5e9, 0], "half_extents": [1, 1, 1]})",
       "inline: colliders[0].center: must be finite, within 1e9 m"},
      {R"({"type": "box", "center": [0, 0, 0], "half_extents": [1, 0, 1]})",
       "inline: colliders[0].half_extents: must be positive"},
      {R"({"type": "plane", "normal": [0, 0, 0]})", "inline: colliders[0].normal: must be"},
      {R"({"type": "plane", "velocity": [0, 2e9, 0]})", "inline: colliders[0].velocity: must be"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.collider);
    const Result<Scene> r =
        parseScene(boxScene("", R"(, "colliders": [)" + c.collider + "]"), "inline", "");
    if (c.error.empty()) {
      ASSERT_TRUE(r.ok()) << r.error().message;
      // What the loader accepts, the world accepts.
      World world;
      EXPECT_TRUE(world.setColliders(r.value().world.colliders).ok());
    } else {
      ASSERT_FALSE(r.ok());
      EXPECT_NE(r.error().message.find(c.error), std::string::npos) << r.error().message;
    }
  }
  // The velocity is read (a moving obstacle).
  const Result<Scene> moving = parseScene(boxScene("", R"(, "colliders": [{"type": "sphere",
      "center": [0, 0, 0], "radius": 0.5, "velocity": [1, -2, 0.5]}])"),
                                          "inline", "");
  ASSERT_TRUE(moving.ok()) << moving.error().message;
  EXPECT_EQ(moving.value().world.colliders[0].velocity, glm::vec3(1, -2, 0.5f));
}

TEST(SceneState, SettingsAreRejectedByTheRuntimeChecks) {
  // Each of these passed the loader's own ranges before and failed only in createBody (or
  // not at all): zero sweeps on both sides, a zero multigrid level.
  EXPECT_NE(errorOf(boxScene(R"(, "solver": {"linear": "multigrid",
                "multigrid": {"pre_sweeps": 0, "post_sweeps": 0}})"))
                .find("inline: bodies[0].solver.multigrid: preSweeps, postSweeps: must be >= 0 "
                      "and together >= 1"),
            std::string::npos);
  EXPECT_NE(errorOf(boxScene(R"(, "solver": {"multigrid": {"levels": "0/all"}})"))
                .find("inline: bodies[0].solver.multigrid: levels[0]: handle count 0"),
            std::string::npos);
  EXPECT_NE(errorOf(boxScene(R"(, "solver": {"newton_iterations": 0})"))
                .find("inline: bodies[0].solver.newton_iterations: must be >= 1, got 0"),
            std::string::npos);
  // Syntax stays the loader's.
  EXPECT_NE(
      errorOf(boxScene(R"(, "solver": {"multigrid": {"levels": "50/x/all"}})"))
          .find("inline: bodies[0].solver.multigrid.levels: expected \"auto\" or coarse handle"),
      std::string::npos);
}

TEST(SceneState, AngularVelocitySpinsTheBodyAboutItsCentreOfMass) {
  const glm::dvec3 w(0.5, -1.0, 2.0), v0(1, 0, 0);
  const Result<Scene> r =
      parseScene(boxScene(R"(, "initial_velocity": [1, 0, 0], "angular_velocity": [0.5, -1, 2])"),
                 "inline", "");
  ASSERT_TRUE(r.ok()) << r.error().message;
  const SceneBody& sb = r.value().bodies[0];
  EXPECT_EQ(sb.angularVelocity, w);

  // Independent truth: centre of mass and inertia tensor of the lumped masses.
  const TetMesh& mesh = sb.def.mesh;
  const std::vector<double> m = test::lumpedMasses(mesh, 1000);
  double M = 0;
  glm::dvec3 c(0);
  for (size_t n = 0; n < m.size(); ++n) {
    M += m[n];
    c += m[n] *
         glm::dvec3(mesh.positions[3 * n], mesh.positions[3 * n + 1], mesh.positions[3 * n + 2]);
  }
  c /= M;
  glm::dmat3 I(0.0);
  for (size_t n = 0; n < m.size(); ++n) {
    const glm::dvec3 x(mesh.positions[3 * n] - c.x, mesh.positions[3 * n + 1] - c.y,
                       mesh.positions[3 * n + 2] - c.z);
    I += m[n] * (glm::dot(x, x) * glm::dmat3(1.0) - glm::outerProduct(x, x));
  }

  World world;
  const Result<BodyId> id = addBody(world, sb);
  ASSERT_TRUE(id.ok()) << id.error().message;
  const BodyStats s = world.stats(id.value());
  // About the origin: the centre's motion plus the spin, L = M c x v0 + I w.
  const glm::dvec3 want = M * glm::cross(c, v0) + I * w;
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.angularMomentum[k], want[k], 1e-9 * glm::length(want));
  // The spin adds no momentum: sum m (w x r) = 0 about the centre of mass.
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.linearMomentum[k], M * v0[k], 1e-9 * M);
  EXPECT_NEAR(s.kineticEnergy, 0.5 * M * glm::dot(v0, v0) + 0.5 * glm::dot(w, I * w),
              1e-9 * s.kineticEnergy);
}

TEST(SceneState, InitialDeformationStoresTheAnalyticStVKEnergy) {
  // A uniform stretch x = c + F (X - c), F = diag(1 + e, 1, 1): the Green strain is uniform,
  // E_xx = e + e^2 / 2, and StVK stores exactly (lambda / 2 + mu) E_xx^2 per unit volume.
  const double e = 1e-3, E = 1e6, nu = 0.3;
  const Result<Scene> r = parseScene(
      boxScene(R"(, "initial_deformation": [[1.001, 0, 0], [0, 1, 0], [0, 0, 1]])"), "inline", "");
  ASSERT_TRUE(r.ok()) << r.error().message;
  World world;
  const Result<BodyId> id = addBody(world, r.value().bodies[0]);
  ASSERT_TRUE(id.ok()) << id.error().message;
  const double lambda = E * nu / ((1 + nu) * (1 - 2 * nu)), mu = E / (2 * (1 + nu));
  const double Exx = e + 0.5 * e * e, volume = 0.4 * 0.2 * 0.3;
  const double want = volume * (0.5 * lambda + mu) * Exx * Exx;
  EXPECT_NEAR(world.stats(id.value()).elasticEnergy, want, 1e-6 * want);

  // About the centroid: the centre (1.2, 2.1, 3.15) stays; the ends move by -+ e * 0.2.
  const std::span<const double> x = world.positions(id.value());
  double xmin = 1e9, xmax = -1e9;
  for (size_t n = 0; 3 * n < x.size(); ++n) xmin = std::min(xmin, x[3 * n]);
  for (size_t n = 0; 3 * n < x.size(); ++n) xmax = std::max(xmax, x[3 * n]);
  EXPECT_NEAR(xmin, 1.2 - 0.2 * (1 + e), 1e-12);
  EXPECT_NEAR(xmax, 1.2 + 0.2 * (1 + e), 1e-12);

  // A matrix that turns the body inside out is refused.
  EXPECT_NE(errorOf(boxScene(R"(, "initial_deformation": [[-1, 0, 0], [0, 1, 0], [0, 0, 1]])"))
                .find("inline: bodies[0].initial_deformation: expected a matrix with a positive "
                      "determinant"),
            std::string::npos);
}

TEST(SceneState, GripNamesFollowTheSceneEntries) {
  // pins[0] and grips[0] make grips; grips[1] holds only nodes already held at that velocity,
  // so it makes none and the names stay aligned with BodyDef::grips.
  const Result<Scene> r = parseScene(boxScene(R"(,
      "pins": [{"region": {"min": [1, 2, 3], "max": [1, 2.2, 3.3]}}],
      "grips": [{"region": {"min": [1.4, 2, 3], "max": [1.4, 2.2, 3.3]}, "velocity": [1, 0, 0]},
                {"nodes": [0], "velocity": [0, 0, 0]}])"),
                                     "inline", "");
  ASSERT_TRUE(r.ok()) << r.error().message;
  const SceneBody& b = r.value().bodies[0];
  ASSERT_EQ(b.def.grips.size(), 2u);
  EXPECT_EQ(b.gripNames, (std::vector<std::string>{"pins[0]", "grips[0]"}));
}

}  // namespace
}  // namespace gf::scene
