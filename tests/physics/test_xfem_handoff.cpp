// The hand-off of an Is-XFEM piece to rigid physics (issue 21 item 4, "fragments to Bullet as
// usual"): World::fragmentInfo / detachFragment / setFragmentTransform on a body in
// CutMode::Xfem. Checked against independent truths: the mass, centre and inertia of the piece a
// slanted plane cuts off a box against the cut box's own volume integrals (tensor Gauss-Legendre,
// exact for the polynomials involved); a rigid velocity field's momentum and angular velocity
// carried over exactly; the body's momenta conserved across the hand-off; the rest of the body
// stepping on as if the piece were still there (the pieces' fields share no DOF combination); and
// misuse refused with the field named and the world unchanged.
#include <graphfrac/world.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "common/xfem_cut_box.h"

namespace gf {
namespace {

using test::cutOffPart;
using test::SlantedCut;

BodyDef xfemBox(double youngs) {
  BodyDef def;
  def.mesh = gen::box(2, 1, 1, 6, 3, 3);
  for (size_t i = 0; i < def.mesh.nodeCount(); ++i) def.mesh.positions[3 * i + 1] += 1.0;
  def.material = Material::stableNeoHookean(youngs, 0.3, 1000);
  def.cutMode = CutMode::Xfem;
  return def;
}

double relDiff(glm::dvec3 a, glm::dvec3 b) { return glm::length(a - b) / glm::length(b); }
double relDiff(const glm::dmat3& a, const glm::dmat3& b) {
  double d = 0, n = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      d = std::max(d, std::abs(a[i][j] - b[i][j]));
      n = std::max(n, std::abs(b[i][j]));
    }
  return d / n;
}

// A rigid velocity field v0 + w x (x - c0) on every node (standard DOFs; enriched ones zero), so
// each piece's field is exactly that rigid motion (it is linear).
void setRigidVelocity(World& world, BodyId id, glm::dvec3 v0, glm::dvec3 w, glm::dvec3 c0) {
  const std::span<const double> x = world.positions(id);
  std::vector<double> v(x.size());
  for (size_t n = 0; 3 * n < x.size(); ++n) {
    const glm::dvec3 vn = v0 + glm::cross(w, glm::dvec3(x[3 * n], x[3 * n + 1], x[3 * n + 2]) - c0);
    for (int i = 0; i < 3; ++i) v[3 * n + size_t(i)] = vn[i];
  }
  ASSERT_TRUE(world.setVelocities(id, v).ok());
}

// The fragment whose centre lies left of the cut (x < 0.7).
int32_t leftFragment(const World& world, BodyId id) {
  for (int32_t f = 0; f < world.fractureStats(id).fragments; ++f)
    if (world.fragmentInfo(id, f).value().centreOfMass.x < 0.7) return f;
  return -1;
}

TEST(XfemHandoff, RigidPropertiesOfTheCutOffPieceAreTheCutBoxs) {
  const SlantedCut cut;
  const test::MassProperties exact = cutOffPart(cut, 1000);
  for (double youngs : {1e7, 1e9}) {
    World world{WorldDef{}};
    const BodyId id = world.createBody(xfemBox(youngs)).value();
    ASSERT_TRUE(world.cut(id, cut.blade()).ok());
    const glm::dvec3 v0(0.3, -0.2, 0.1), w(0.5, -1.5, 2.0), c0(1, 1.5, 0.5);
    setRigidVelocity(world, id, v0, w, c0);
    const int32_t left = leftFragment(world, id);
    ASSERT_GE(left, 0);
    const RigidFragmentInfo info = world.fragmentInfo(id, left).value();
    const double massErr = std::abs(info.mass - exact.mass) / exact.mass;
    const double centreErr = relDiff(info.centreOfMass, exact.centre);
    const double inertiaErr = relDiff(info.inertia, exact.inertia);
    const glm::dvec3 vc = v0 + glm::cross(w, exact.centre - c0);
    const double velErr = relDiff(info.linearVelocity, vc);
    const double spinErr = relDiff(info.angularVelocity, w);
    std::printf(
        "E %.0e: cut-off piece mass %.12f (exact %.12f) rel %.1e; centre rel %.1e; inertia rel "
        "%.1e; velocity rel %.1e; angular velocity rel %.1e\n",
        youngs, info.mass, exact.mass, massErr, centreErr, inertiaErr, velErr, spinErr);
    EXPECT_LT(massErr, 1e-9);
    EXPECT_LT(centreErr, 1e-9);
    EXPECT_LT(inertiaErr, 1e-9);
    EXPECT_LT(velErr, 1e-9);
    EXPECT_LT(spinErr, 1e-9);
    EXPECT_LT(glm::length(info.translation), 1e-12);  // at rest: the identity pose
    EXPECT_NEAR(std::abs(info.rotation.w), 1.0, 1e-12);
  }
}

TEST(XfemHandoff, DetachConservesMomentaAndLeavesTheRestAlone) {
  const SlantedCut cut;
  for (double dt : {1.0 / 60, 1.0 / 240}) {
    for (double youngs : {1e7, 1e9}) {
      // Two identical worlds; B hands the cut-off piece over, A keeps it.
      World a{WorldDef{}}, b{WorldDef{}};
      const BodyId ia = a.createBody(xfemBox(youngs)).value();
      const BodyId ib = b.createBody(xfemBox(youngs)).value();
      for (auto [w, id] : {std::pair<World*, BodyId>{&a, ia}, {&b, ib}}) {
        ASSERT_TRUE(w->cut(id, cut.blade()).ok());
        setRigidVelocity(*w, id, {0.3, 0.5, -0.1}, {0.2, -0.4, 0.6}, {1, 1.5, 0.5});
        for (int s = 0; s < 5; ++s) ASSERT_FALSE(w->step(dt).has(kStepNanContained));
      }
      const int32_t left = leftFragment(b, ib);
      const int32_t right = 1 - left;
      const BodyStats before = b.stats(ib);
      const SurfaceView sb0 = b.surface(ib);
      const std::vector<float> restBefore(sb0.positions.begin(), sb0.positions.end());
      const std::vector<int32_t> fragOf(sb0.vertexFragment.begin(), sb0.vertexFragment.end());
      const auto info = b.detachFragment(ib, left);
      ASSERT_TRUE(info.ok()) << info.error().message;
      const RigidFragmentInfo& f = info.value();
      ASSERT_EQ(b.handoffEvents().size(), 1u);
      EXPECT_EQ(b.handoffEvents()[0].fragment, left);

      // Momenta: what stays plus the rigid body's equal what was there.
      const BodyStats after = b.stats(ib);
      const glm::dvec3 p = after.linearMomentum + f.mass * f.linearVelocity;
      const glm::dvec3 L = after.angularMomentum +
                           glm::cross(f.centreOfMass, f.mass * f.linearVelocity) +
                           f.inertia * f.angularVelocity;
      const double pErr = relDiff(p, before.linearMomentum);
      const double LErr = relDiff(L, before.angularMomentum);
      EXPECT_LT(pErr, 1e-12);
      EXPECT_LT(LErr, 1e-12);
      EXPECT_NEAR(after.mass + f.mass, before.mass, 1e-12 * before.mass);

      // The surface at the hand-off: every vertex where it was (the piece at its best-fit pose,
      // to its strain's size; the rest exactly).
      const SurfaceView sb1 = b.surface(ib);
      ASSERT_EQ(sb1.positions.size(), restBefore.size());
      double restMoved = 0, pieceMoved = 0;
      for (size_t i = 0; i < fragOf.size(); ++i) {
        double d = 0;
        for (int k = 0; k < 3; ++k)
          d = std::max(d, double(std::abs(sb1.positions[3 * i + size_t(k)] -
                                          restBefore[3 * i + size_t(k)])));
        (fragOf[i] == left ? pieceMoved : restMoved) =
            std::max(fragOf[i] == left ? pieceMoved : restMoved, d);
      }
      EXPECT_EQ(restMoved, 0.0);
      // The piece snaps to its best-fit rigid pose: its linear-elastic field turned by theta
      // is off a rigid turn by about |r| theta^2 / 2 (|r| < 1 m here).
      const double theta = glm::length(glm::dvec3(0.2, -0.4, 0.6)) * 5 * dt;
      std::printf("piece moved %.2e m onto its rigid pose (theta^2 = %.2e)\n", pieceMoved,
                  theta * theta);
      EXPECT_LT(pieceMoved, theta * theta);

      // Stepping on: the rest of B follows A's right piece; B's piece stays where the rigid
      // pose holds it (nobody moves it here).
      for (int s = 0; s < 30; ++s) {
        ASSERT_FALSE(a.step(dt).has(kStepNanContained));
        ASSERT_FALSE(b.step(dt).has(kStepNanContained));
      }
      const SurfaceView va = a.surface(ia), vb = b.surface(ib);
      ASSERT_EQ(va.positions.size(), vb.positions.size());
      double diff = 0, fall = 0, pieceDrift = 0;
      for (size_t i = 0; i < fragOf.size(); ++i)
        for (int k = 0; k < 3; ++k) {
          const size_t j = 3 * i + size_t(k);
          if (fragOf[i] == right) {
            diff = std::max(diff, double(std::abs(va.positions[j] - vb.positions[j])));
            fall = std::max(fall, double(std::abs(va.positions[j] - restBefore[j])));
          } else {
            pieceDrift = std::max(pieceDrift, double(std::abs(vb.positions[j] - sb1.positions[j])));
          }
        }
      const RigidFragmentInfo ra = a.fragmentInfo(ia, right).value();
      const BodyStats sb = b.stats(ib);
      const double pRest = relDiff(sb.linearMomentum, ra.mass * ra.linearVelocity);
      std::printf(
          "dt 1/%.0f E %.0e: momentum rel %.1e, angular rel %.1e; after 30 steps the rest "
          "differs from the run without hand-off by %.1e m (moved %.2f m), its momentum rel "
          "%.1e; the detached piece drifted %.1e m\n",
          1 / dt, youngs, pErr, LErr, diff, fall, pRest, pieceDrift);
      EXPECT_LT(diff, 1e-5 * fall);  // float surface: a few ulps of the position
      EXPECT_LT(pRest, 1e-9);
      EXPECT_EQ(pieceDrift, 0.0);
    }
  }
}

TEST(XfemHandoff, SetFragmentTransformMovesThePieceRigidly) {
  const SlantedCut cut;
  World world{WorldDef{}};
  const BodyId id = world.createBody(xfemBox(1e8)).value();
  ASSERT_TRUE(world.cut(id, cut.blade()).ok());
  const int32_t left = leftFragment(world, id);
  const SurfaceView s0 = world.surface(id);
  const std::vector<float> rest(s0.positions.begin(), s0.positions.end());
  const std::vector<int32_t> fragOf(s0.vertexFragment.begin(), s0.vertexFragment.end());
  const RigidFragmentInfo f = world.detachFragment(id, left).value();
  const glm::dquat q = glm::angleAxis(0.7, glm::normalize(glm::dvec3(1, 2, 3)));
  const glm::dvec3 t(0.5, -1.0, 2.0), v(1, 2, 3), w(0.1, 0.2, 0.3);
  ASSERT_TRUE(world.setFragmentTransform(id, left, t, q, v, w).ok());
  const SurfaceView s1 = world.surface(id);
  const glm::dmat3 R = glm::mat3_cast(q);
  double err = 0;
  for (size_t i = 0; i < fragOf.size(); ++i) {
    if (fragOf[i] != left) continue;
    const glm::dvec3 X(rest[3 * i], rest[3 * i + 1], rest[3 * i + 2]);
    const glm::dvec3 x(s1.positions[3 * i], s1.positions[3 * i + 1], s1.positions[3 * i + 2]);
    err = std::max(err, glm::length(x - (R * X + t)));
  }
  EXPECT_LT(err, 1e-6);
  const RigidFragmentInfo g = world.fragmentInfo(id, left).value();
  EXPECT_LT(relDiff(g.centreOfMass, R * (f.centreOfMass - f.translation) + t), 1e-12);
  EXPECT_LT(relDiff(g.linearVelocity, v), 1e-15);
  EXPECT_LT(relDiff(g.angularVelocity, w), 1e-15);
  EXPECT_LT(relDiff(g.inertia, R * f.inertia * glm::transpose(R)), 1e-12);
  EXPECT_NEAR(g.mass, f.mass, 1e-15 * f.mass);
}

TEST(XfemHandoff, MisuseIsRefusedNamingTheFieldAndChangesNothing) {
  const SlantedCut cut;
  World world{WorldDef{}};
  const BodyId id = world.createBody(xfemBox(1e8)).value();
  const auto refused = [&](int32_t fragment, const char* words) {
    const uint64_t hash = world.stateHash();
    const size_t events = world.handoffEvents().size();
    const auto r = world.detachFragment(id, fragment);
    ASSERT_FALSE(r.ok()) << "fragment " << fragment;
    EXPECT_NE(r.error().message.find("detachFragment: fragment"), std::string::npos)
        << r.error().message;
    EXPECT_NE(r.error().message.find(words), std::string::npos) << r.error().message;
    EXPECT_EQ(world.stateHash(), hash);
    EXPECT_EQ(world.handoffEvents().size(), events);
  };
  refused(0, "whole body");  // uncut: one piece
  refused(-1, "out of range");
  ASSERT_TRUE(world.cut(id, cut.blade()).ok());
  refused(2, "out of range");
  const int32_t left = leftFragment(world, id);
  ASSERT_TRUE(world.detachFragment(id, left).ok());
  refused(left, "already detached");
  refused(1 - left, "whole body");  // the last piece left in the system
  const auto moved = world.setFragmentTransform(id, 1 - left, {0, 0, 0}, {1, 0, 0, 0}, {}, {});
  ASSERT_FALSE(moved.ok());
  EXPECT_NE(moved.error().message.find("not detached"), std::string::npos);

  // A gripped piece cannot move rigidly.
  BodyDef held = xfemBox(1e8);
  Grip g;
  for (int32_t n = 0; n < int32_t(held.mesh.nodeCount()); ++n)
    if (held.mesh.positions[3 * size_t(n)] == 0) g.nodes.push_back(n);
  held.grips.push_back(g);
  const BodyId hid = world.createBody(held).value();
  ASSERT_TRUE(world.cut(hid, cut.blade()).ok());
  const auto r = world.detachFragment(hid, leftFragment(world, hid));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("BodyDef.grips"), std::string::npos) << r.error().message;
}

}  // namespace
}  // namespace gf
