// Scene keys of the demo (tools/scene): Bullet rigid bodies, hand-off policies, render colours
// and the camera load with exactly the values written, normalised where the format says so;
// their errors are in the bad corpus of test_scene.cpp.
#include <gtest/gtest.h>

#include <filesystem>
#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>

#include "scene/scene.h"

namespace gf::scene {
namespace {

namespace fs = std::filesystem;

const fs::path kSceneData = fs::path(GF_SOURCE_DIR) / "tests" / "data" / "scenes";

void expectVec(glm::dvec3 a, glm::dvec3 b, const char* what) {
  EXPECT_LT(glm::length(a - b), 1e-12) << what << ": (" << a.x << ", " << a.y << ", " << a.z
                                       << ") vs (" << b.x << ", " << b.y << ", " << b.z << ")";
}

TEST(SceneDemoKeys, LoadEveryValue) {
  const Result<Scene> r = loadScene((kSceneData / "good" / "demo_keys.json").string());
  ASSERT_TRUE(r.ok()) << r.error().message;
  const Scene& s = r.value();
  EXPECT_TRUE(needsBullet(s));

  // Hand-off and colours per body; a body without "colour" takes a palette colour distinct
  // from the others, and the crack colour defaults to MeshFrame's orange.
  ASSERT_EQ(s.bodies.size(), 3u);
  EXPECT_EQ(s.bodies[0].handoff.policy, SceneHandoff::Policy::BelowVolume);
  EXPECT_DOUBLE_EQ(s.bodies[0].handoff.maxVolume, 0.25);
  EXPECT_EQ(s.bodies[1].handoff.policy, SceneHandoff::Policy::Every);
  EXPECT_EQ(s.bodies[2].handoff.policy, SceneHandoff::Policy::Never);
  expectVec(s.bodies[0].colour, {0.1f, 0.2f, 0.3f}, "colour");
  expectVec(s.bodies[0].crackColour, {1, 0.5, 0}, "crack_colour");
  expectVec(s.bodies[1].crackColour, {0.95f, 0.55f, 0.3f}, "default crack_colour");
  EXPECT_GT(glm::length(s.bodies[1].colour - s.bodies[2].colour), 0.1f);

  ASSERT_EQ(s.rigidBodies.size(), 4u);
  const SceneRigidBody& floor = s.rigidBodies[0];
  EXPECT_EQ(floor.name, "floor");
  EXPECT_EQ(floor.shape, SceneRigidBody::Shape::Plane);
  expectVec(floor.normal, {0, 1, 0}, "normalised normal");
  EXPECT_DOUBLE_EQ(floor.offset, -0.5);  // normal . point
  EXPECT_DOUBLE_EQ(floor.renderSize, 6);
  EXPECT_DOUBLE_EQ(floor.mass, 0);
  EXPECT_DOUBLE_EQ(floor.friction, 1.5);
  EXPECT_DOUBLE_EQ(floor.rollingFriction, 0.1);
  EXPECT_DOUBLE_EQ(floor.restitution, 0.2);
  EXPECT_TRUE(floor.touchesBodies);
  expectVec(floor.colour, {0.4f, 0.4f, 0.4f}, "floor colour");

  const SceneRigidBody& wall = s.rigidBodies[1];
  EXPECT_EQ(wall.name, "rigid1");  // default name: its index
  EXPECT_DOUBLE_EQ(wall.offset, -3);
  EXPECT_FALSE(wall.touchesBodies);
  EXPECT_DOUBLE_EQ(wall.friction, 0.5);  // Bullet's default
  EXPECT_DOUBLE_EQ(wall.renderSize, 4);

  const SceneRigidBody& ball = s.rigidBodies[2];
  EXPECT_EQ(ball.shape, SceneRigidBody::Shape::Sphere);
  EXPECT_DOUBLE_EQ(ball.radius, 0.1);
  EXPECT_DOUBLE_EQ(ball.mass, 2);
  expectVec(ball.position, {0, 2, 0}, "position");
  expectVec(ball.velocity, {1, -2, 3}, "velocity");
  expectVec(ball.angularVelocity, {0, 4, 0}, "angular_velocity");
  // 90 degrees about +z (axis normalised) turns +x into +y.
  expectVec(ball.orientation * glm::dvec3(1, 0, 0), {0, 1, 0}, "axis-angle");

  const SceneRigidBody& crate = s.rigidBodies[3];
  EXPECT_EQ(crate.shape, SceneRigidBody::Shape::Box);
  expectVec(crate.halfExtents, {0.1, 0.2, 0.3}, "half of size");
  EXPECT_DOUBLE_EQ(crate.mass, 0);
  EXPECT_DOUBLE_EQ(glm::length(crate.orientation), 1);  // [2, 0, 0, 0] normalised
  EXPECT_DOUBLE_EQ(crate.orientation.w, 1);

  ASSERT_TRUE(s.camera.has_value());
  expectVec(s.camera->eye, {1, 2, 3}, "eye");
  expectVec(s.camera->target, {0, 0.5, 0}, "target");
  expectVec(s.camera->up, {0, 0, 1}, "up");
  EXPECT_DOUBLE_EQ(s.camera->fovDegrees, 30);
}

TEST(SceneDemoKeys, AbsentKeysNeedNoBullet) {
  const Result<Scene> r = loadScene((kSceneData / "good" / "minimal.json").string());
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_FALSE(needsBullet(r.value()));
  EXPECT_FALSE(r.value().camera.has_value());
  EXPECT_TRUE(r.value().rigidBodies.empty());
  EXPECT_EQ(r.value().bodies[0].handoff.policy, SceneHandoff::Policy::Never);
}

}  // namespace
}  // namespace gf::scene
