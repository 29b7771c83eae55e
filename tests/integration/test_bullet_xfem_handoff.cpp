// Hand-off of Is-XFEM pieces to Bullet (issue 21 item 4): a block cut by a slanted blade, the
// cut-off piece given to Bullet through the bridge. Checked against the cut box's own volume
// integrals (mass, centre, principal moments), the momenta of a rigid velocity field carried
// into the btRigidBody, and the piece falling under Bullet's gravity onto Bullet's floor with
// its exact cut surface following the rigid body.
#include <btBulletDynamicsCommon.h>
#include <graphfrac/bullet/bridge.h>
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "common/bullet_world.h"
#include "common/xfem_cut_box.h"

namespace gf {
namespace {

using test::SlantedCut;

glm::dvec3 toGlm(const btVector3& v) { return {v.x(), v.y(), v.z()}; }

TEST(BulletXfemHandoff, CutOffPieceGoesToBulletAndLandsOnTheFloor) {
  const SlantedCut cut;
  World world{WorldDef{}};
  BodyDef def;
  def.mesh = gen::box(2, 1, 1, 6, 3, 3);
  for (size_t i = 0; i < def.mesh.nodeCount(); ++i) def.mesh.positions[3 * i + 1] += 1.0;
  def.material = Material::stableNeoHookean(1e8, 0.3, 1000);
  def.cutMode = CutMode::Xfem;
  Grip g;  // the right end is held: only the cut-off piece can go
  for (int32_t n = 0; n < int32_t(def.mesh.nodeCount()); ++n)
    if (def.mesh.positions[3 * size_t(n)] == 2) g.nodes.push_back(n);
  def.grips.push_back(g);
  const BodyId id = world.createBody(def).value();
  test::BulletWorld dyn(btVector3(0, -9.81f, 0));
  bullet::Bridge bridge(world, dyn.world);
  ASSERT_TRUE(bridge.setPolicy(id, bullet::HandoffPolicy::EveryFragment).ok());
  ASSERT_TRUE(world.cut(id, cut.blade()).ok());
  ASSERT_EQ(world.fractureStats(id).fragments, 2);

  // The first frame hands the free piece over (the held one refuses); its rigid body against
  // the cut box (Bullet holds floats: 1e-6).
  ASSERT_FALSE(bridge.step(1.0 / 60).has(kStepInvalidInput));
  ASSERT_EQ(bridge.fragments().size(), 1u);
  ASSERT_EQ(world.handoffEvents().size(), 1u);
  const int32_t piece = bridge.fragments()[0].fragment;
  const btRigidBody& rb = *bridge.fragments()[0].rigidBody;
  const test::MassProperties exact = test::cutOffPart(cut, 1000);
  const double mass = exact.mass;
  const glm::dvec3 centre = exact.centre;
  const glm::dmat3 inertia = exact.inertia;
  EXPECT_NEAR(world.handoffEvents()[0].mass, mass, 1e-9 * mass);
  EXPECT_NEAR(1.0 / rb.getInvMass(), mass, 1e-6 * mass);
  Eigen::Matrix3d I;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) I(i, j) = inertia[j][i];
  const Eigen::Vector3d moments = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(I).eigenvalues();
  std::vector<double> bt = {rb.getLocalInertia().x(), rb.getLocalInertia().y(),
                            rb.getLocalInertia().z()};
  std::sort(bt.begin(), bt.end());
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(bt[size_t(k)], moments[k], 1e-6 * moments[2]);
  // One frame: the FEM step's free fall (implicit Euler: v = -g dt, the centre down g dt^2),
  // handed over with that momentum, then Bullet's step (v -= g dt, the centre down v dt).
  const double dt = 1.0 / 60, gv = 9.81;
  const glm::dvec3 c1 = toGlm(rb.getCenterOfMassPosition()), v1 = toGlm(rb.getLinearVelocity());
  const HandoffEvent& ev = world.handoffEvents()[0];
  std::printf(
      "piece %d: mass %.6f (exact %.6f); handed over at v = (%.2e %.6f %.2e) (free fall "
      "%.6f); centre after the frame (%.5f %.5f %.5f), at rest (%.5f %.5f %.5f)\n",
      piece, 1.0 / rb.getInvMass(), mass, ev.velocity.x, ev.velocity.y, ev.velocity.z, -gv * dt,
      c1.x, c1.y, c1.z, centre.x, centre.y, centre.z);
  EXPECT_NEAR(ev.velocity.x, 0, 1e-6);
  EXPECT_NEAR(ev.velocity.y, -gv * dt, 1e-6);
  EXPECT_NEAR(ev.velocity.z, 0, 1e-6);
  // A small spin from the FEM step (not traced: the held part pulls on the piece through the
  // cut during the step), carried into Bullet unchanged (gravity exerts no torque).
  const glm::dvec3 w1 = toGlm(rb.getAngularVelocity());
  std::printf("spin handed over %.3e rad/s, Bullet's after its step differs by %.1e\n",
              glm::length(ev.angularVelocity), glm::length(w1 - glm::dvec3(ev.angularVelocity)));
  EXPECT_LT(glm::length(ev.angularVelocity) * 1.0, 0.02 * gv * dt);  // < 2% of v across 1 m
  EXPECT_LT(glm::length(w1 - glm::dvec3(ev.angularVelocity)), 1e-6);
  EXPECT_NEAR(v1.y, -2 * gv * dt, 1e-5);
  EXPECT_NEAR(c1.x, centre.x, 1e-5);
  EXPECT_NEAR(c1.z, centre.z, 1e-5);
  EXPECT_NEAR(c1.y, centre.y - 3 * gv * dt * dt, 1e-5);

  // Two seconds: the piece falls 1 m onto Bullet's floor and rests; its surface (exact cut face
  // included) follows the rigid body.
  for (int frame = 1; frame < 120; ++frame)
    ASSERT_FALSE(bridge.step(1.0 / 60).has(kStepInvalidInput));
  const SurfaceView s = world.surface(id);
  double lowest = 1e300;
  for (size_t i = 0; i < s.vertexFragment.size(); ++i)
    if (s.vertexFragment[i] == piece) lowest = std::min<double>(lowest, s.positions[3 * i + 1]);
  const double speed = rb.getLinearVelocity().length();
  std::printf("after 2 s: the piece's lowest surface vertex at y = %.4f, speed %.3g m/s\n", lowest,
              speed);
  EXPECT_GT(lowest, -0.005);  // on the floor, not through it
  EXPECT_LT(lowest, 0.03);    // resting on it (hull margin <= 2 cm)
  EXPECT_LT(speed, 0.05);
}

}  // namespace
}  // namespace gf
