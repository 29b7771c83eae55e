// Body-body and self contact (contact/body_contact.h), checked against geometry and
// conservation laws that do not use the contact code: how deep a node lies inside the tets of
// another body or fragment (point-in-tet), the analytic support of a stack, linear momentum
// and energy of a free collision.
#include <graphfrac/jobs.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "common/sim_helpers.h"

namespace gf {
namespace {

glm::dvec3 at(std::span<const double> x, int32_t n) {
  return {x[3 * n], x[3 * n + 1], x[3 * n + 2]};
}

// How deep p lies inside tet (a, b, c, d): the smallest distance to its four face planes,
// negative outside.
double insideDepth(glm::dvec3 p, const glm::dvec3 q[4]) {
  double depth = HUGE_VAL;
  for (int l = 0; l < 4; ++l) {
    const glm::dvec3 a = q[(l + 1) % 4], b = q[(l + 2) % 4], c = q[(l + 3) % 4];
    glm::dvec3 n = glm::cross(b - a, c - a);
    const double len = glm::length(n);
    if (!(len > 0)) return -HUGE_VAL;
    n /= len;
    if (glm::dot(n, q[l] - a) < 0) n = -n;  // towards the opposite corner: inwards
    depth = std::min(depth, glm::dot(p - a, n));
  }
  return depth;
}

// A part of a body: its nodes (as vertices) and its tets (all four nodes in the part).
struct Part {
  BodyId body;
  std::vector<int32_t> nodes;
  std::vector<int32_t> tets;  // tet indices into the body's mesh
};

// Distance from p to triangle abc: to its plane where p projects inside it, else to the
// nearest edge.
double triangleDistance(glm::dvec3 p, glm::dvec3 a, glm::dvec3 b, glm::dvec3 c) {
  const glm::dvec3 n = glm::normalize(glm::cross(b - a, c - a));
  const glm::dvec3 q = p - glm::dot(p - a, n) * n;
  const bool inside = glm::dot(glm::cross(b - a, q - a), n) >= 0 &&
                      glm::dot(glm::cross(c - b, q - b), n) >= 0 &&
                      glm::dot(glm::cross(a - c, q - c), n) >= 0;
  if (inside) return std::abs(glm::dot(p - a, n));
  auto segment = [&](glm::dvec3 u, glm::dvec3 v) {
    const double t = std::clamp(glm::dot(p - u, v - u) / glm::dot(v - u, v - u), 0.0, 1.0);
    return glm::length(p - (u + t * (v - u)));
  };
  return std::min({segment(a, b), segment(b, c), segment(c, a)});
}

// How deep the nodes of `p` lie inside the part `q` [m]: for every node inside one of q's tets,
// its distance to q's boundary (the faces of q's tets that only one of them has); the deepest.
double deepestInside(const World& world, const TetMesh& meshP, const Part& p, const TetMesh& meshQ,
                     const Part& q) {
  const auto xp = world.positions(p.body), xq = world.positions(q.body);
  std::vector<std::array<int32_t, 4>> faces;  // sorted nodes, then a tie-breaking zero
  for (int32_t t : q.tets)
    for (int l = 0; l < 4; ++l) {
      std::array<int32_t, 4> f{};
      int k = 0;
      for (int i = 0; i < 4; ++i)
        if (i != l) f[size_t(k++)] = meshQ.tets[4 * size_t(t) + size_t(i)];
      std::sort(f.begin(), f.begin() + 3);
      faces.push_back(f);
    }
  std::sort(faces.begin(), faces.end());
  std::vector<std::array<int32_t, 4>> boundary;
  for (size_t i = 0; i < faces.size();) {
    size_t j = i + 1;
    while (j < faces.size() && faces[j] == faces[i]) ++j;
    if (j == i + 1) boundary.push_back(faces[i]);
    i = j;
  }
  double deepest = 0;
  std::vector<uint8_t> inside(meshP.nodeCount(), 0);
  for (int32_t t : q.tets) {
    glm::dvec3 c[4], lo(HUGE_VAL), hi(-HUGE_VAL);
    for (int k = 0; k < 4; ++k) {
      c[k] = at(xq, meshQ.tets[4 * size_t(t) + size_t(k)]);
      lo = glm::min(lo, c[k]);
      hi = glm::max(hi, c[k]);
    }
    for (int32_t n : p.nodes) {
      const glm::dvec3 v = at(xp, n);
      if (inside[size_t(n)] || glm::any(glm::lessThan(v, lo)) || glm::any(glm::greaterThan(v, hi)))
        continue;
      if (insideDepth(v, c) > 0) inside[size_t(n)] = 1;
    }
  }
  for (int32_t n : p.nodes) {
    if (!inside[size_t(n)]) continue;
    const glm::dvec3 v = at(xp, n);
    double d = HUGE_VAL;
    for (const auto& f : boundary)
      d = std::min(d, triangleDistance(v, at(xq, f[0]), at(xq, f[1]), at(xq, f[2])));
    deepest = std::max(deepest, d);
  }
  return deepest;
}

Part wholeBody(BodyId id, const TetMesh& mesh) {
  Part p{id, {}, {}};
  for (int32_t n = 0; n < int32_t(mesh.nodeCount()); ++n) p.nodes.push_back(n);
  for (int32_t t = 0; t < int32_t(mesh.tetCount()); ++t) p.tets.push_back(t);
  return p;
}

TetMesh movedBox(double sx, double sy, double sz, int nx, int ny, int nz, glm::dvec3 offset) {
  TetMesh m = gen::box(sx, sy, sz, nx, ny, nz);
  for (size_t n = 0; n < m.nodeCount(); ++n)
    for (int k = 0; k < 3; ++k) m.positions[3 * n + k] += offset[k];
  return m;
}

// Two soft blocks (20 and 15 cm, cells of 5 cm) dropped on each other onto the ground come to
// rest stacked: the ground carries both weights (the upper one's through the contact) and,
// once at rest, neither lies inside the other by more than 1 % of a
// cell, with no growth over 5 s.
TEST(BodyContact, TwoBlocksComeToRestStacked) {
  WorldDef wd{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}};
  Collider ground;  // y = 0
  ground.friction = 0.5;
  wd.colliders.push_back(ground);
  World world(wd);
  const double cell = 0.05;
  BodyDef lower, upper;
  lower.mesh = movedBox(0.2, 0.2, 0.2, 4, 4, 4, {0, 0.01, 0});
  // Smaller and centred, so that it is carried whole (contact is frictionless between bodies:
  // an overhang sagging over the lower block's edge would push it off sideways).
  upper.mesh = movedBox(0.15, 0.15, 0.15, 3, 3, 3, {0.025, 0.25, 0.025});
  for (BodyDef* d : {&lower, &upper}) {
    d->material = Material::stableNeoHookean(2e5, 0.3, 1000);
    d->material.stiffnessDamping = 0.02;
    d->contact = true;
  }
  const BodyId a = world.createBody(lower).value(), b = world.createBody(upper).value();
  const Part pa = wholeBody(a, lower.mesh), pb = wholeBody(b, upper.mesh);
  // Landing in the first 2 s, then 5 s at rest.
  double landing = 0, worstRest = 0, firstRest = 0, last = 0, groundImpulse = 0;
  int64_t pairs = 0;
  for (int s = 1; s <= 420; ++s) {
    ASSERT_TRUE(world.step(1.0 / 60).ok());
    pairs += world.timings().contactPairs;
    const double depth = std::max(deepestInside(world, upper.mesh, pb, lower.mesh, pa),
                                  deepestInside(world, lower.mesh, pa, upper.mesh, pb));
    if (s <= 120) landing = std::max(landing, depth);
    if (s > 120) worstRest = std::max(worstRest, depth);
    if (s > 120 && s <= 180) firstRest = std::max(firstRest, depth);
    if (s > 360) last = std::max(last, depth);
    if (s > 360) groundImpulse += world.colliderImpulses()[0].y;
  }
  const BodyStats sa = world.stats(a), sb = world.stats(b);
  // At rest: the upper block's centre is one block height plus its own sag above the ground.
  double minUpper = HUGE_VAL, maxLower = -HUGE_VAL;
  for (size_t n = 0; n < upper.mesh.nodeCount(); ++n)
    minUpper = std::min(minUpper, world.positions(b)[3 * n + 1]);
  for (size_t n = 0; n < lower.mesh.nodeCount(); ++n)
    maxLower = std::max(maxLower, world.positions(a)[3 * n + 1]);
  std::printf(
      "stack: %lld pairs over 7 s; deepest node inside the other block: %.3g m while landing "
      "(0-2 s), %.3g m at rest (2-7 s, %.3g %% of a cell), %.3g m over 2-3 s, %.3g m over 6-7 s; "
      "upper bottom %.4f m, lower top %.4f m; speeds %.2e %.2e m/s\n",
      (long long)pairs, landing, worstRest, 100 * worstRest / cell, firstRest, last, minUpper,
      maxLower, glm::length(sa.linearMomentum) / sa.mass, glm::length(sb.linearMomentum) / sb.mass);
  EXPECT_GT(pairs, 0);
  EXPECT_LT(landing, 0.05 * cell);  // the impact at 0.8 m/s, one step of 1.3 cm
  EXPECT_LT(worstRest, 0.01 * cell);
  EXPECT_LE(last, 1.5 * firstRest + 1e-5);  // no growth
  // Over the last second: the contact settles into a two-step rhythm of the lagged planes.
  const double support = groundImpulse, weight = (sa.mass + sb.mass) * 9.81;
  std::printf("stack: ground force over the last second %.3f N, both weights %.3f N\n", support,
              weight);
  EXPECT_NEAR(support, weight, 0.02 * weight);
  // Resting on the lower block, not fallen through it nor floating above it.
  EXPECT_GT(minUpper, 0.18);
  EXPECT_NEAR(minUpper, maxLower, 0.01 * cell + 1e-3);
  EXPECT_LT(glm::length(sb.linearMomentum) / sb.mass, 1e-2);
}

// Two free bodies of different sizes and meshes meet head-on without gravity: the total
// linear momentum stays what it was to 1e-6 of its scale, the mechanical energy never rises,
// the bodies part again in the right order, and momentum changed hands.
TEST(BodyContact, HeadOnCollisionConservesMomentumAndLosesEnergy) {
  WorldDef wd{glm::vec3(0, 0, 0), Backend::Cpu, nullptr, 1, {}};
  World world(wd);
  BodyDef left, right;
  left.mesh = movedBox(0.2, 0.2, 0.2, 4, 4, 4, {0, 0, 0});
  right.mesh = movedBox(0.3, 0.3, 0.3, 5, 5, 5, {0.22, -0.04, -0.05});
  left.initialVelocity = glm::vec3(2, 0, 0);
  right.initialVelocity = glm::vec3(-1, 0, 0);
  for (BodyDef* d : {&left, &right}) {
    d->material = Material::stableNeoHookean(1e6, 0.3, 1000);
    d->solver.linearSolver = LinearSolverKind::Direct;
    d->contact = true;
  }
  const BodyId a = world.createBody(left).value(), b = world.createBody(right).value();
  auto momentum = [&] { return world.stats(a).linearMomentum + world.stats(b).linearMomentum; };
  auto energy = [&] {
    const BodyStats sa = world.stats(a), sb = world.stats(b);
    return sa.kineticEnergy + sa.elasticEnergy + sb.kineticEnergy + sb.elasticEnergy;
  };
  const glm::dvec3 p0 = momentum();
  const double scale =
      glm::length(world.stats(a).linearMomentum) + glm::length(world.stats(b).linearMomentum);
  const double e0 = energy();
  double worstMomentum = 0, maxEnergy = e0;
  int64_t pairs = 0;
  for (int s = 0; s < 30; ++s) {
    ASSERT_TRUE(world.step(1.0 / 60).ok());
    pairs += world.timings().contactPairs;
    worstMomentum = std::max(worstMomentum, glm::length(momentum() - p0) / scale);
    maxEnergy = std::max(maxEnergy, energy());
  }
  const double va = world.stats(a).linearMomentum.x / world.stats(a).mass;
  const double vb = world.stats(b).linearMomentum.x / world.stats(b).mass;
  std::printf(
      "head-on: %lld pairs; momentum error %.3g of |p1| + |p2|; energy %.4f J -> max %.4f J, "
      "end %.4f J; velocities 2, -1 -> %.3f, %.3f m/s\n",
      (long long)pairs, worstMomentum, e0, maxEnergy, energy(), va, vb);
  EXPECT_GT(pairs, 0);
  EXPECT_LT(worstMomentum, 1e-6);
  EXPECT_LE(maxEnergy, e0 * (1 + 1e-9));
  EXPECT_LT(va, vb + 0.01);  // they stuck or bounced apart, not passed through
  const Part pa = wholeBody(a, left.mesh), pb = wholeBody(b, right.mesh);
  EXPECT_LT(deepestInside(world, left.mesh, pa, right.mesh, pb), 1e-3);
}

// Blocks whose edges cross: the lower one turned 45 degrees about x (an edge on top, along x),
// the upper one turned 45 degrees about z (an edge below, along z), dropped edge on edge. No
// edge-edge test runs: the nodes along each edge meet the faces beside the other's edge.
TEST(BodyContact, CrossedEdgesDoNotPassThrough) {
  WorldDef wd{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}};
  Collider ground;
  ground.friction = 0.5;
  wd.colliders.push_back(ground);
  World world(wd);
  auto turned = [](TetMesh m, int axis, glm::dvec3 centre) {
    const double c = std::cos(M_PI / 4), s = std::sin(M_PI / 4);
    for (size_t n = 0; n < m.nodeCount(); ++n) {
      double* p = &m.positions[3 * n];
      glm::dvec3 r(p[0] - 0.1, p[1] - 0.1, p[2] - 0.1);
      const int i = (axis + 1) % 3, j = (axis + 2) % 3;
      const double a = c * r[i] - s * r[j], b = s * r[i] + c * r[j];
      r[i] = a;
      r[j] = b;
      for (int k = 0; k < 3; ++k) p[k] = centre[k] + r[k];
    }
    return m;
  };
  BodyDef lower, upper;
  const double half = 0.1 * std::sqrt(2.0);
  lower.mesh = turned(gen::box(0.2, 0.2, 0.2, 4, 4, 4), 0, {0, half, 0});
  upper.mesh = turned(gen::box(0.2, 0.2, 0.2, 4, 4, 4), 2, {0, 2 * half + half + 0.02, 0});
  for (BodyDef* d : {&lower, &upper}) {
    d->material = Material::stableNeoHookean(1e6, 0.3, 1000);
    d->material.stiffnessDamping = 0.02;
    d->contact = true;
  }
  const BodyId a = world.createBody(lower).value(), b = world.createBody(upper).value();
  const Part pa = wholeBody(a, lower.mesh), pb = wholeBody(b, upper.mesh);
  double deepest = 0, highest = 0;
  int64_t pairs = 0;
  for (int s = 0; s < 45; ++s) {
    ASSERT_TRUE(world.step(1.0 / 60).ok());
    pairs += world.timings().contactPairs;
    deepest = std::max({deepest, deepestInside(world, upper.mesh, pb, lower.mesh, pa),
                        deepestInside(world, lower.mesh, pa, upper.mesh, pb)});
  }
  double lowestUpper = HUGE_VAL;
  for (size_t n = 0; n < upper.mesh.nodeCount(); ++n)
    lowestUpper = std::min(lowestUpper, world.positions(b)[3 * n + 1]);
  for (size_t n = 0; n < lower.mesh.nodeCount(); ++n)
    highest = std::max(highest, world.positions(a)[3 * n + 1]);
  std::printf(
      "crossed edges: %lld pairs; deepest node inside the other %.3g m; upper's lowest node %.4f "
      "m, lower's highest %.4f m\n",
      (long long)pairs, deepest, lowestUpper, highest);
  EXPECT_GT(pairs, 0);
  // Without contact the upper block would fall onto the ground (lowest node near 0).
  EXPECT_GT(lowestUpper, highest - 0.01);
  EXPECT_LT(deepest, 0.005);
}

// A column cut across in two; the upper piece is thrown up and sideways and lands half on the
// lower one (fragment self contact through the crack). Checked with the point-in-tet test of
// each fragment's nodes against the other's tets, and against the same run without contact,
// in which the upper piece falls into the lower one.
double thrownPiece(bool contact, int64_t* pairsOut, int32_t* fragmentsOut) {
  WorldDef wd{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}};
  Collider ground;
  ground.friction = 0.5;
  wd.colliders.push_back(ground);
  World world(wd);
  BodyDef def;
  def.mesh = gen::box(0.1, 0.4, 0.1, 4, 16, 4);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.material.stiffnessDamping = 0.02;
  def.fracture.enabled = true;
  def.fracture.strength = 1e9;  // only the cut breaks
  def.contact = contact;
  const BodyId id = world.createBody(def).value();
  // The plane y = 0.206, off the nodes so that no edge lies in it.
  Blade blade;
  blade.vertices = {{-1, 0.206f, -1}, {1, 0.206f, -1}, {1, 0.206f, 1}, {-1, 0.206f, 1}};
  blade.triangles = {0, 2, 1, 0, 3, 2};
  EXPECT_TRUE(world.cut(id, blade).ok());
  EXPECT_TRUE(world.step(1.0 / 60).ok());
  // Throw the upper piece: up at 2 m/s and sideways at 0.15 m/s, so it comes down 6 cm over.
  std::vector<double> v(world.velocities(id).begin(), world.velocities(id).end());
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
    if (def.mesh.positions[3 * n + 1] > 0.21) {
      v[3 * n] = 0.15;
      v[3 * n + 1] = 2;
    }
  EXPECT_TRUE(world.setVelocities(id, v).ok());
  double deepest = 0;
  int64_t pairs = 0;
  std::vector<Part> parts;
  for (int s = 0; s < 60; ++s) {
    EXPECT_TRUE(world.step(1.0 / 60).ok());
    pairs += world.timings().contactPairs;
    const auto frag = world.nodeFragments(id);
    const int32_t count = world.fractureStats(id).fragments;
    parts.assign(size_t(count), Part{id, {}, {}});
    for (int32_t n = 0; n < int32_t(frag.size()); ++n) parts[size_t(frag[n])].nodes.push_back(n);
    for (int32_t t = 0; t < int32_t(def.mesh.tetCount()); ++t) {
      const int32_t* k = &def.mesh.tets[4 * size_t(t)];
      if (frag[k[0]] == frag[k[1]] && frag[k[0]] == frag[k[2]] && frag[k[0]] == frag[k[3]])
        parts[size_t(frag[k[0]])].tets.push_back(t);
    }
    for (size_t i = 0; i < parts.size(); ++i)
      for (size_t j = 0; j < parts.size(); ++j)
        if (i != j && parts[i].nodes.size() > 1 && parts[j].tets.size() > 0)
          deepest = std::max(deepest, deepestInside(world, def.mesh, parts[i], def.mesh, parts[j]));
  }
  *pairsOut = pairs;
  *fragmentsOut = world.fractureStats(id).fragments;
  return deepest;
}

TEST(BodyContact, FragmentsOfACutBodyDoNotPassThroughEachOther) {
  int64_t pairsOn = 0, pairsOff = 0;
  int32_t fragmentsOn = 0, fragmentsOff = 0;
  const double on = thrownPiece(true, &pairsOn, &fragmentsOn);
  const double off = thrownPiece(false, &pairsOff, &fragmentsOff);
  const double cell = 0.05;
  std::printf(
      "thrown piece: %d fragments; deepest node of one fragment inside another's tets: %.3g m "
      "with contact (%lld pairs), %.3g m without\n",
      fragmentsOn, on, (long long)pairsOn, off);
  EXPECT_GE(fragmentsOn, 2);
  EXPECT_EQ(pairsOff, 0);
  EXPECT_GT(pairsOn, 0);
  EXPECT_LT(on, 0.02 * cell);
  EXPECT_GT(off, 10 * on);  // the scene does need the contact
}

// The pair lists are built serially in slot and node order, so the contact step gives the same
// bits for any thread count (tests/physics/test_determinism.cpp).
std::vector<double> stackState(JobSystem* jobs) {
  WorldDef wd{glm::vec3(0, -9.81f, 0), Backend::Cpu, jobs, 1, {}};
  wd.colliders.push_back(Collider{});
  World world(wd);
  BodyDef lower, upper;
  lower.mesh = movedBox(0.2, 0.2, 0.2, 4, 4, 4, {0, 0.01, 0});
  upper.mesh = movedBox(0.15, 0.15, 0.15, 3, 3, 3, {0.025, 0.25, 0.025});
  std::vector<BodyId> ids;
  for (BodyDef* d : {&lower, &upper}) {
    d->material = Material::stableNeoHookean(2e5, 0.3, 1000);
    d->contact = true;
    ids.push_back(world.createBody(*d).value());
  }
  int64_t pairs = 0;
  for (int s = 0; s < 40; ++s) {
    (void)world.step(1.0 / 60);
    pairs += world.timings().contactPairs;
  }
  EXPECT_GT(pairs, 0);
  std::vector<double> out;
  for (BodyId id : ids) {
    const auto x = world.positions(id), v = world.velocities(id);
    out.insert(out.end(), x.begin(), x.end());
    out.insert(out.end(), v.begin(), v.end());
  }
  return out;
}

TEST(BodyContact, SameBitsForAnyThreadCount) {
  ThreadPoolJobSystem pool2(2), pool4(4);
  const std::vector<double> serial = stackState(nullptr);
  const std::vector<double> two = stackState(&pool2), four = stackState(&pool4);
  ASSERT_EQ(serial.size(), two.size());
  EXPECT_EQ(0, std::memcmp(serial.data(), two.data(), serial.size() * sizeof(double)));
  EXPECT_EQ(0, std::memcmp(serial.data(), four.data(), serial.size() * sizeof(double)));
}

}  // namespace
}  // namespace gf
