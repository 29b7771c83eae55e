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
#include <cstdlib>
#include <cstring>
#include <deque>
#include <ostream>
#include <string>

#include "common/sim_helpers.h"
#include "kernels/contact.h"

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

// The fragments of a body as parts: each fragment's nodes and its whole tets.
std::vector<Part> fragmentParts(const World& world, BodyId id, const TetMesh& mesh) {
  const auto frag = world.nodeFragments(id);
  std::vector<Part> parts(size_t(world.fractureStats(id).fragments), Part{id, {}, {}});
  for (int32_t n = 0; n < int32_t(frag.size()); ++n) parts[size_t(frag[n])].nodes.push_back(n);
  for (int32_t t = 0; t < int32_t(mesh.tetCount()); ++t) {
    const int32_t* k = &mesh.tets[4 * size_t(t)];
    if (frag[k[0]] == frag[k[1]] && frag[k[0]] == frag[k[2]] && frag[k[0]] == frag[k[3]])
      parts[size_t(frag[k[0]])].tets.push_back(t);
  }
  return parts;
}

// Gravity and the ground y = 0 (friction 0.5), one thread.
WorldDef groundWorld() {
  WorldDef wd{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}};
  Collider ground;
  ground.friction = 0.5;
  wd.colliders.push_back(ground);
  return wd;
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
  WorldDef wd = groundWorld();
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

// Stacks (issue 15): boxes dropped onto each other onto the ground, checked with the
// point-in-tet depth of each box's nodes inside its neighbours, the ground's force against the
// weights, the mechanical energy against its start and where each box ends. One case of the
// family per row; the boxes are centred over each other.
struct StackBox {
  double size = 0.2;  // edge [m]
  int cells = 4;      // per edge
  double youngs = 2e5;
};
struct StackCase {
  const char* name = "";
  std::vector<StackBox> boxes;  // bottom first
  double dt = 1.0 / 60;
  double gap = 0.02;     // each box starts this far above the one below [m]
  double friction = -1;  // every box's BodyDef::friction; negative: the default
  double perturb = 0;    // the top box's start moved sideways by this fraction of its offset
  int sweeps = 1;        // WorldDef::contactSweeps
  bool coupled = false;  // WorldDef::coupledContact
  // Every box with fracture and plasticity on, neither ever reached: its steps must take the
  // sweeps a plain box's take (before, such a body kept one sweep).
  bool fractureAndPlasticity = false;
};
struct StackResult {
  double landing = 0, rest = 0, firstRest = 0, lastRest = 0;  // deepest node [m]
  double restCell = 0;                                        // rest / the finer cell
  double support = 0, weight = 0;                             // over the last second [N]
  double energyGain = 0, energyScale = 0;                     // max E(t) - E(0); m g h [J]
  double worstSeat = 0;    // max over boxes of (the lower's top - this one's bottom) [m]
  double worstOffset = 0;  // max sideways offset from the one below / its size
  double worstSpeed = 0;   // at the end [m/s]
  bool ok = true;
  int64_t pairs = 0;
};

StackResult runStack(const StackCase& c) {
  WorldDef wd = groundWorld();
  wd.contactSweeps = c.sweeps;
  wd.coupledContact = c.coupled;
  World world(wd);
  std::vector<BodyDef> defs(c.boxes.size());
  std::vector<BodyId> ids;
  std::vector<Part> parts;
  double y = 0.01, cell = HUGE_VAL;
  for (size_t i = 0; i < c.boxes.size(); ++i) {
    const StackBox& b = c.boxes[i];
    const int n = b.cells;
    const double x0 = -b.size / 2 * (i + 1 == c.boxes.size() ? 1 + c.perturb : 1.0);
    defs[i].mesh = movedBox(b.size, b.size, b.size, n, n, n, {x0, y, -b.size / 2});
    defs[i].material = Material::stableNeoHookean(b.youngs, 0.3, 1000);
    defs[i].material.stiffnessDamping = 0.02;
    defs[i].contact = true;
    if (c.friction >= 0) defs[i].friction = c.friction;
    if (c.fractureAndPlasticity) {
      defs[i].fracture.enabled = true;
      defs[i].fracture.strength = 1e12;
      defs[i].plasticity.enabled = true;
      defs[i].plasticity.yieldStress = 1e12;
    }
    ids.push_back(world.createBody(defs[i]).value());
    parts.push_back(wholeBody(ids.back(), defs[i].mesh));
    y += b.size + c.gap;
    cell = std::min(cell, b.size / n);
  }
  auto energy = [&] {
    double e = 0;
    for (BodyId id : ids) {
      const BodyStats s = world.stats(id);
      e += s.kineticEnergy + s.elasticEnergy + s.gravityEnergy + s.contactEnergy;
    }
    return e;
  };
  StackResult r;
  for (BodyId id : ids) r.weight += world.stats(id).mass * 9.81;
  // The drop's scale: every box's weight times the height it starts above its resting place.
  r.energyScale = r.weight * (c.gap * double(ids.size()) + 0.01);
  const double e0 = energy();
  const int landingSteps = int(std::lround(2.0 / c.dt)), steps = int(std::lround(6.0 / c.dt));
  const int second = int(std::lround(1.0 / c.dt));
  for (int s = 1; s <= steps; ++s) {
    const StepStatus st = world.step(c.dt);
    if (!st.ok()) {
      r.ok = false;
      break;
    }
    r.pairs += world.timings().contactPairs;
    double depth = 0;
    for (size_t i = 1; i < ids.size(); ++i)
      depth = std::max(
          {depth, deepestInside(world, defs[i].mesh, parts[i], defs[i - 1].mesh, parts[i - 1]),
           deepestInside(world, defs[i - 1].mesh, parts[i - 1], defs[i].mesh, parts[i])});
    if (s <= landingSteps) r.landing = std::max(r.landing, depth);
    if (s > landingSteps) r.rest = std::max(r.rest, depth);
    if (s > landingSteps && s <= landingSteps + second) r.firstRest = std::max(r.firstRest, depth);
    if (s > steps - second) {
      r.lastRest = std::max(r.lastRest, depth);
      r.support += world.colliderImpulses()[0].y;
    }
    r.energyGain = std::max(r.energyGain, energy() - e0);
  }
  r.restCell = r.rest / cell;
  for (size_t i = 0; i < ids.size(); ++i) {
    const auto x = world.positions(ids[i]);
    const BodyStats st = world.stats(ids[i]);
    r.worstSpeed = std::max(r.worstSpeed, glm::length(st.linearMomentum) / st.mass);
    if (i == 0) continue;
    const auto xl = world.positions(ids[i - 1]);
    double bottom = HUGE_VAL, top = -HUGE_VAL;
    glm::dvec3 centre(0), centreLower(0);
    for (size_t n = 0; n < x.size() / 3; ++n) {
      bottom = std::min(bottom, x[3 * n + 1]);
      centre += at(x, int32_t(n));
    }
    for (size_t n = 0; n < xl.size() / 3; ++n) {
      top = std::max(top, xl[3 * n + 1]);
      centreLower += at(xl, int32_t(n));
    }
    centre /= double(x.size() / 3);
    centreLower /= double(xl.size() / 3);
    r.worstSeat = std::max(r.worstSeat, top - bottom);
    r.worstOffset =
        std::max(r.worstOffset,
                 std::hypot(centre.x - centreLower.x, centre.z - centreLower.z) / c.boxes[i].size);
  }
  std::printf(
      "%s: %lld pairs; deepest node inside a neighbour %.3g m landing, %.3g m at rest (%.3g %% "
      "of a cell), %.3g m over 2-3 s, %.3g m over 5-6 s; ground %.4f N for weights %.4f N; "
      "energy gain %.3g J of %.3g J; seat %.3g m, offset %.3g, speed %.2e m/s\n",
      c.name, (long long)r.pairs, r.landing, r.rest, 100 * r.restCell, r.firstRest, r.lastRest,
      r.support, r.weight, r.energyGain, r.energyScale, r.worstSeat, r.worstOffset, r.worstSpeed);
  return r;
}

void PrintTo(const StackCase& c, std::ostream* os) { *os << c.name; }

class BodyContactStack : public ::testing::TestWithParam<StackCase> {};

// Each stack comes to rest stacked: no box inside another by more than 1 % of the finer cell
// once at rest, and no growth over the last seconds; the ground carries every weight; the
// mechanical energy never rises above its start; each box sits on the one below, centred, still.
TEST_P(BodyContactStack, ComesToRestStacked) {
  const StackCase& c = GetParam();
  const StackResult r = runStack(c);
  ASSERT_TRUE(r.ok);
  EXPECT_GT(r.pairs, 0);
  EXPECT_LT(r.restCell, 0.01);
  EXPECT_LE(r.lastRest, 1.5 * r.firstRest + 1e-5);  // no growth
  EXPECT_NEAR(r.support, r.weight, 0.02 * r.weight);
  EXPECT_LE(r.energyGain, 1e-3 * r.energyScale);
  EXPECT_LT(r.worstSeat, 1e-3);    // not sunk into the one below
  EXPECT_GT(r.worstSeat, -1e-3);   // nor floating above it
  EXPECT_LT(r.worstOffset, 0.05);  // not knocked off
  EXPECT_LT(r.worstSpeed, 1e-2);
}

// The cases that come to rest stacked today.
std::vector<StackCase> stackCases() {
  const StackBox box{}, soft{0.2, 4, 2e5};
  return {
      {"two_equal_60", {box, box}, 1.0 / 60, 0.02},
      {"two_equal_120", {box, box}, 1.0 / 120, 0.02},
      {"sizes_stiffness_60", {{0.25, 5, 1e6}, soft, {0.15, 3, 5e5}}, 1.0 / 60, 0.02},
  };
}

// The rest of the family, which fails today (docs/validation.md, "Body-body and self contact":
// the numbers of each and the diagnosis); run with --gtest_also_run_disabled_tests.
std::vector<StackCase> failingStackCases() {
  const StackBox box{}, soft{0.2, 4, 2e5}, stiff{0.2, 4, 1e6}, small{0.1, 4, 2e5};
  return {
      {"two_equal_small_60", {small, small}, 1.0 / 60, 0.01},
      {"three_equal_small_60", {small, small, small}, 1.0 / 60, 0.01},
      {"three_equal_60", {box, box, box}, 1.0 / 60, 0.02},
      {"three_equal_120", {box, box, box}, 1.0 / 120, 0.02},
      {"four_equal_60", {box, box, box, box}, 1.0 / 60, 0.02},
      {"sizes_stiffness_120", {stiff, {0.15, 3, 2e5}, {0.1, 2, 1e6}}, 1.0 / 120, 0.02},
      {"dropped_30cm_three_120", {box, soft, stiff}, 1.0 / 120, 0.3},
      // Passed or failed by the last bits of the run (DISABLED_PerturbedFriction: shifted by
      // 1e-15 it slides off); with sweeps it rests (Swept/..., below).
      {"dropped_30cm_60", {box, box}, 1.0 / 60, 0.3},
  };
}

auto stackName = [](const ::testing::TestParamInfo<StackCase>& i) {
  return std::string(i.param.name);
};

// A start moved sideways by a last-bit amount (1e-15 and 1e-12 of the offset) must not decide
// whether a dropped box stays on its seat. Without friction between the boxes it does not (here
// the normal contact, its lagged planes and the exchange are not chaotic); the frictional family
// below still is (docs/validation.md, "Body-body and self contact": the lagged body-body
// friction during the post-impact chatter multiplies a 1e-16 m asymmetry to a slide off).
std::vector<StackCase> perturbedStackCases(double friction, int sweeps = 1) {
  const StackBox box{};
  std::vector<StackCase> out;
  struct Drop {
    const char* name;
    double dt, gap;
  };
  const Drop drops[] = {{"10cm_60", 1.0 / 60, 0.1},
                        {"30cm_60", 1.0 / 60, 0.3},
                        {"50cm_60", 1.0 / 60, 0.5},
                        {"30cm_120", 1.0 / 120, 0.3}};
  static std::deque<std::string> names;  // StackCase holds a plain pointer into it
  for (const Drop& d : drops)
    for (double e : {1e-15, 1e-12}) {
      names.push_back(std::string("dropped_") + d.name + (e > 1e-14 ? "_shift1e12" : "_shift1e15"));
      out.push_back({names.back().c_str(), {box, box}, d.dt, d.gap, friction, e, sweeps});
    }
  return out;
}
INSTANTIATE_TEST_SUITE_P(PerturbedFrictionless, BodyContactStack,
                         ::testing::ValuesIn(perturbedStackCases(0.0)), stackName);
INSTANTIATE_TEST_SUITE_P(DISABLED_PerturbedFriction, BodyContactStack,
                         ::testing::ValuesIn(perturbedStackCases(-1)), stackName);
INSTANTIATE_TEST_SUITE_P(Family, BodyContactStack, ::testing::ValuesIn(stackCases()), stackName);
INSTANTIATE_TEST_SUITE_P(DISABLED_Failing, BodyContactStack,
                         ::testing::ValuesIn(failingStackCases()), stackName);

// The same stacks with the bodies that touch stepped up to four times per step, each against
// the others' latest end-of-step positions (WorldDef::contactSweeps, docs/design.md, Contact).
// These failed with one sweep (DISABLED_Failing, DISABLED_PerturbedFriction: the same scenes).
// The 120 Hz ones take 20-50 s each, so they run only with GF_FULL_VALIDATION=1.
std::vector<StackCase> sweptStackCases() {
  const StackBox box{}, soft{0.2, 4, 2e5}, stiff{0.2, 4, 1e6}, small{0.1, 4, 2e5};
  std::vector<StackCase> out = {
      {"two_equal_small_60", {small, small}, 1.0 / 60, 0.01},
      {"three_equal_small_60", {small, small, small}, 1.0 / 60, 0.01},
      {"three_equal_60", {box, box, box}, 1.0 / 60, 0.02},
      {"dropped_30cm_60", {box, box}, 1.0 / 60, 0.3},
  };
  if (std::getenv("GF_FULL_VALIDATION")) {
    out.push_back({"three_equal_120", {box, box, box}, 1.0 / 120, 0.02});
    out.push_back({"dropped_30cm_three_120", {box, soft, stiff}, 1.0 / 120, 0.3});
  }
  for (StackCase& c : out) c.sweeps = 4;
  StackCase unbroken = out[0];
  unbroken.name = "two_equal_small_60_fracture_plasticity";
  unbroken.fractureAndPlasticity = true;
  out.push_back(unbroken);
  // The frictional drops whose outcome a last-bit shift decided with one sweep.
  for (const StackCase& c : perturbedStackCases(-1, 4))
    if (std::string(c.name).find("_60_") != std::string::npos &&
        std::string(c.name).find("10cm") == std::string::npos)
      out.push_back(c);
  return out;
}
// Still failing with sweeps (docs/validation.md): four boxes fall through while landing; the
// mixed-size stacks keep a phantom velocity of 0.03-0.05 m/s from the exchange (action and
// reaction of the converged half-spaces differ by ~50 N there, which the exchange takes off the
// cluster as a velocity and the ground takes back each step).
std::vector<StackCase> sweptFailingStackCases() {
  const StackBox box{}, soft{0.2, 4, 2e5}, stiff{0.2, 4, 1e6};
  std::vector<StackCase> out = {
      {"four_equal_60", {box, box, box, box}, 1.0 / 60, 0.02},
      {"sizes_stiffness_60", {{0.25, 5, 1e6}, soft, {0.15, 3, 5e5}}, 1.0 / 60, 0.02},
      {"sizes_stiffness_120", {stiff, {0.15, 3, 2e5}, {0.1, 2, 1e6}}, 1.0 / 120, 0.02},
  };
  for (StackCase& c : out) c.sweeps = 4;
  return out;
}
INSTANTIATE_TEST_SUITE_P(Swept, BodyContactStack, ::testing::ValuesIn(sweptStackCases()),
                         stackName);
INSTANTIATE_TEST_SUITE_P(DISABLED_SweptFailing, BodyContactStack,
                         ::testing::ValuesIn(sweptFailingStackCases()), stackName);

// Every stack above with the touching boxes stepped as one system (WorldDef::coupledContact):
// each pair acts on both sides, so nothing is evened out after the step.
std::vector<StackCase> coupledStackCases() {
  std::vector<StackCase> out;
  static std::deque<std::string> names;  // StackCase holds a plain pointer into it
  const std::pair<const char*, std::vector<StackCase>> families[] = {
      {"", stackCases()},
      {"", failingStackCases()},
      {"friction_", perturbedStackCases(-1)},
      {"frictionless_", perturbedStackCases(0.0)}};
  for (const auto& [prefix, family] : families)
    for (StackCase c : family) {
      // The 120 Hz ones take 10-25 s each: with GF_FULL_VALIDATION=1 only.
      if (c.dt < 1.0 / 100 && !std::getenv("GF_FULL_VALIDATION")) continue;
      names.push_back(std::string(prefix) + c.name);
      c.name = names.back().c_str();
      c.coupled = true;
      out.push_back(c);
    }
  return out;
}
INSTANTIATE_TEST_SUITE_P(Coupled, BodyContactStack, ::testing::ValuesIn(coupledStackCases()),
                         stackName);

// Without friction, a block set sliding over a slab that rests on a frictionless floor keeps its
// velocity and the slab stays still: only vertical half-spaces act. Slab top nodes under the
// block's bottom face must not also be pushed out through its leading face (their surface
// meets it at right angles, where the facing test's sign is round-off's: a 2 m/s block kept a
// third of its speed after one step and gave the rest to the slab). Cells of 2.5 cm over 10 cm;
// speeds 0.2 to 4 m/s along x and diagonally.
TEST(BodyContact, FrictionlessBlockSlidesOverASlabAtConstantVelocity) {
  for (const glm::dvec3 v :
       {glm::dvec3(0.2, 0, 0), glm::dvec3(2, 0, 0), glm::dvec3(-4, 0, 0), glm::dvec3(1, 0, 1)}) {
    WorldDef wd{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}};
    wd.colliders.push_back(Collider{});  // the floor, frictionless
    World world(wd);
    BodyDef slab, block;
    slab.mesh = movedBox(2.4, 0.1, 1.2, 24, 2, 12, {-1.2, 0, -0.6});
    block.mesh = movedBox(0.1, 0.04, 0.1, 4, 2, 4, {-0.05, 0.1, -0.05});
    for (BodyDef* d : {&slab, &block}) {
      d->material = Material::stableNeoHookean(1e7, 0.3, 1000);
      d->friction = 0;
      d->contact = true;
      d->solver.linearSolver = LinearSolverKind::Direct;
    }
    const BodyId s = world.createBody(slab).value(), b = world.createBody(block).value();
    for (int k = 0; k < 30; ++k) ASSERT_TRUE(world.step(1.0 / 60).ok());
    ASSERT_TRUE(world.setVelocity(b, v).ok());
    const double m = world.stats(b).mass;
    double worstSpeed = 0, worstSlab = 0;
    for (int k = 0; k < 24; ++k) {
      ASSERT_TRUE(world.step(1.0 / 60).ok());
      const glm::dvec3 vb = world.stats(b).linearMomentum / m, ps = world.stats(s).linearMomentum;
      worstSpeed = std::max(worstSpeed, glm::length(glm::dvec3(vb.x, 0, vb.z) - v));
      worstSlab = std::max(worstSlab, glm::length(glm::dvec3(ps.x, 0, ps.z)));
    }
    std::printf(
        "block at (%.1f, 0, %.1f) m/s over a slab: its velocity off by at most %.2e m/s, the "
        "slab's horizontal momentum at most %.2e of the block's\n",
        v.x, v.z, worstSpeed, worstSlab / (m * glm::length(v)));
    EXPECT_LT(worstSpeed, 0.01 * glm::length(v));
    EXPECT_LT(worstSlab, 0.01 * m * glm::length(v));
  }
}

// A world with a floor of friction floorMu, and a 10 cm block (4 x 2 x 4 cells) put at x = blockX
// on a 1.2 m slab of one layer of 10 cm cells (its top at y = 0.1), both E = 1e7 with friction mu
// and body contact. Returns the block.
WorldDef floorWorld(double floorMu) {
  WorldDef wd{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}};
  Collider floor{};
  floor.friction = floorMu;
  wd.colliders.push_back(floor);
  return wd;
}
BodyId putBlockOnCoarseSlab(World& world, double mu, double blockX, BodyId* slabId = nullptr) {
  BodyDef slab, block;
  slab.mesh = movedBox(1.2, 0.1, 0.4, 12, 1, 4, {-0.6, 0, -0.2});
  block.mesh = movedBox(0.1, 0.04, 0.1, 4, 2, 4, {blockX, 0.1, -0.05});
  for (BodyDef* d : {&slab, &block}) {
    d->material = Material::stableNeoHookean(1e7, 0.3, 1000);
    d->friction = mu;
    d->contact = true;
    d->solver.linearSolver = LinearSolverKind::Direct;
  }
  const BodyId s = world.createBody(slab).value();
  if (slabId) *slabId = s;
  return world.createBody(block).value();
}

// The block at rest on the slab, both with friction, the slab on a floor
// (frictionless, or with friction 1), stepped in the default one-Newton-step mode: it stays where
// it was put. A step with friction against another body's face goes on to convergence where its
// first linearisation was a poor model; with that one linearisation the block was thrown up at
// 4.2 m/s (mu 0.1), and at 861 m/s (and 7e6 m/s, 33 steps rolled back) with the slab on the
// frictional floor. On that floor a stick-slip cycle of 8 steps remains (docs/validation.md), at
// up to 0.017 m/s and 0.49 mm.
TEST(BodyContact, BlockRestsOnACoarseSlabWithFriction) {
  for (const double floorMu : {0.0, 1.0})
    for (const double mu : {0.1, 0.5, 1.0}) {
      World world(floorWorld(floorMu));
      const BodyId b = putBlockOnCoarseSlab(world, mu, -0.4);
      const double m = world.stats(b).mass;
      const auto mean = [&] {
        const std::span<const double> x = world.positions(b);
        glm::dvec3 c(0);
        for (size_t i = 0; i < x.size(); i += 3) c += glm::dvec3(x[i], x[i + 1], x[i + 2]);
        return c * (3.0 / double(x.size()));
      };
      const glm::dvec3 put = mean();
      int notOk = 0;
      double fastest = 0, farthest = 0;
      for (int k = 0; k < 60; ++k) {
        notOk += !world.step(1.0 / 60).ok();
        fastest = std::max(fastest, glm::length(world.stats(b).linearMomentum) / m);
        farthest = std::max(farthest, glm::length(mean() - put));
      }
      std::printf(
          "floor friction %.0f, mu %.1f: block at most %.3g m/s and %.3g mm from where "
          "it was put, %d steps not ok\n",
          floorMu, mu, fastest, 1e3 * farthest, notOk);
      EXPECT_EQ(notOk, 0);
      EXPECT_LT(fastest, 0.05);
      EXPECT_LT(farthest, 1e-3);
    }
}

// The block set sliding at 1.5 m/s over the slab, the slab on a frictionless or a frictional
// floor: it decelerates at mu g and stops. Measured on the block's mean velocity, over the steps
// until it is down to a tenth; after the stop it moves with the slab (which the frictionless floor
// lets the block's friction push along). Its path is v0^2 / (2 mu g) short by backward Euler's
// lag (about v0 dt / 2), printed. Before, the block stopped after 11-66 % of it (docs/
// validation.md, "Friction between two bodies"): the lagged load of each pair was its penalty's
// force against this step's plane, up to ten times the block's weight.
TEST(BodyContact, BlockSlidingOverASlabDeceleratesAtMuG) {
  const double dt = 1.0 / 60, v0 = 1.5, g = 9.81;
  for (const double floorMu : {0.0, 1.0})
    for (const double mu : {0.1, 0.2, 0.5, 1.0}) {
      World world(floorWorld(floorMu));
      BodyId slab;
      const BodyId b = putBlockOnCoarseSlab(world, mu, -0.58, &slab);
      for (int k = 0; k < 30; ++k) ASSERT_TRUE(world.step(dt).ok());
      ASSERT_TRUE(world.setVelocity(b, glm::dvec3(v0, 0, 0)).ok());
      const auto meanX = [&] {
        const std::span<const double> x = world.positions(b);
        double sum = 0;
        for (size_t i = 0; i < x.size(); i += 3) sum += x[i];
        return 3 * sum / double(x.size());
      };
      const auto velocity = [&](BodyId id) {
        return world.stats(id).linearMomentum.x / world.stats(id).mass;
      };
      const double x0 = meanX();
      int sliding = 0;  // steps until the block is down to a tenth of v0
      double slowed = 0, relative = 0;
      for (int k = 1; k <= 60; ++k) {
        ASSERT_TRUE(world.step(dt).ok());
        const double v = velocity(b);
        if (v >= 0.1 * v0 && sliding == k - 1) {
          sliding = k;
          slowed = v0 - v;
        }
        relative = v - velocity(slab);
      }
      ASSERT_GT(sliding, 0);
      const double a = slowed / (sliding * dt), stopAfter = v0 / (mu * g);
      const double slid = meanX() - x0;
      const double coulomb = stopAfter < 1 ? v0 * v0 / (2 * mu * g) : v0 - mu * g / 2;
      std::printf(
          "floor friction %.0f, mu %.1f: decelerates at %.4f m/s^2 over %d steps, mu g %.4f "
          "(%+.2f %%); at 1 s %.2g m/s on the slab; slid %.4f m, Coulomb %.4f m (%+.4f m, v0 dt / "
          "2 = %.4f m)\n",
          floorMu, mu, a, sliding, mu * g, 100 * (a / (mu * g) - 1), relative, slid, coulomb,
          slid - coulomb, v0 * dt / 2);
      EXPECT_NEAR(a, mu * g, 0.02 * mu * g);
      if (stopAfter < 0.9) {
        EXPECT_LT(std::abs(relative), 1e-3);
      }
      EXPECT_NEAR(slid, coulomb, v0 * dt);
    }
}

// Two free bodies without gravity meeting head-on: a 20 cm block (4^3 cells) at `speed` along x
// into a 30 cm one of `cells` a side at -1 m/s, offset so that they meet off-centre; the second
// may fracture. Their total linear momentum and mechanical energy, for the laws they keep.
struct HeadOn {
  BodyDef left, right;
  World world;
  BodyId a, b;

  static WorldDef def(int sweeps, bool coupled) {
    WorldDef wd{glm::vec3(0, 0, 0), Backend::Cpu, nullptr, 1, {}};
    wd.contactSweeps = sweeps;
    wd.coupledContact = coupled;
    return wd;
  }
  HeadOn(int sweeps, double speed, int cells, const FractureSettings& fracture,
         bool coupled = false)
      : world(def(sweeps, coupled)) {
    left.mesh = movedBox(0.2, 0.2, 0.2, 4, 4, 4, {0, 0, 0});
    right.mesh = movedBox(0.3, 0.3, 0.3, cells, cells, cells, {0.22, -0.04, -0.05});
    left.initialVelocity = glm::vec3(float(speed), 0, 0);
    right.initialVelocity = glm::vec3(-1, 0, 0);
    for (BodyDef* d : {&left, &right}) {
      d->material = Material::stableNeoHookean(1e6, 0.3, 1000);
      d->solver.linearSolver = LinearSolverKind::Direct;
      d->contact = true;
    }
    right.fracture = fracture;
    a = world.createBody(left).value();
    b = world.createBody(right).value();
  }
  glm::dvec3 momentum() const {
    return world.stats(a).linearMomentum + world.stats(b).linearMomentum;
  }
  // |p1| + |p2|: the scale a momentum error is measured against.
  double momentumScale() const {
    return glm::length(world.stats(a).linearMomentum) + glm::length(world.stats(b).linearMomentum);
  }
  double energy() const {
    const BodyStats sa = world.stats(a), sb = world.stats(b);
    return sa.kineticEnergy + sa.elasticEnergy + sb.kineticEnergy + sb.elasticEnergy;
  }
};

// The head-on collision: the total linear momentum stays what it was to 1e-6 of its scale, the
// mechanical energy never rises, the bodies part again in the right order, and momentum
// changed hands.
void headOnCollision(int sweeps, bool coupled = false) {
  HeadOn h(sweeps, 2, 5, FractureSettings{}, coupled);
  const glm::dvec3 p0 = h.momentum();
  const double scale = h.momentumScale(), e0 = h.energy();
  double worstMomentum = 0, maxEnergy = e0;
  int64_t pairs = 0;
  for (int s = 0; s < 30; ++s) {
    ASSERT_TRUE(h.world.step(1.0 / 60).ok());
    pairs += h.world.timings().contactPairs;
    worstMomentum = std::max(worstMomentum, glm::length(h.momentum() - p0) / scale);
    maxEnergy = std::max(maxEnergy, h.energy());
  }
  const double va = h.world.stats(h.a).linearMomentum.x / h.world.stats(h.a).mass;
  const double vb = h.world.stats(h.b).linearMomentum.x / h.world.stats(h.b).mass;
  std::printf(
      "head-on, %d sweeps%s: %lld pairs; momentum error %.3g of |p1| + |p2|; energy %.4f J -> "
      "max %.4f J, end %.4f J; velocities 2, -1 -> %.3f, %.3f m/s\n",
      sweeps, coupled ? ", coupled" : "", (long long)pairs, worstMomentum, e0, maxEnergy,
      h.energy(), va, vb);
  EXPECT_GT(pairs, 0);
  EXPECT_LT(worstMomentum, 1e-6);
  EXPECT_LE(maxEnergy, e0 * (1 + 1e-9));
  EXPECT_LT(va, vb + 0.01);  // they stuck or bounced apart, not passed through
  const Part pa = wholeBody(h.a, h.left.mesh), pb = wholeBody(h.b, h.right.mesh);
  EXPECT_LT(deepestInside(h.world, h.left.mesh, pa, h.right.mesh, pb), 1e-3);
}
TEST(BodyContact, HeadOnCollisionConservesMomentumAndLosesEnergy) { headOnCollision(1); }
// With sweeps the last sweep's half-spaces are against the others' previous iterate, not an
// exact action-reaction pair either: the exchange must still make the momentum exact.
TEST(BodyContact, HeadOnCollisionConservesMomentumAndLosesEnergyWithSweeps) { headOnCollision(4); }
// Coupled, the pairs are exact action and reaction; what momentum is lost is Newton's residual.
TEST(BodyContact, CoupledHeadOnCollisionConservesMomentumAndLosesEnergy) {
  headOnCollision(1, true);
}

// A body that breaks while it touches another: the step relabels its fragments after the pairs
// were found, and the momentum exchange must still sum and share out over the groups the pairs
// were found with (it read the new labels past its group count: out of bounds, a crash on a
// shattering bunny). The head-on collision's laws still hold: momentum to 1e-6 and no energy
// gained, with 1 and 4 sweeps, brittle (new fragments in the steps that touch) at two speeds.
TEST(BodyContact, ABodyThatBreaksWhileTouchingKeepsMomentumAndEnergy) {
  for (const int sweeps : {1, 4})
    for (const auto& [speed, strength] : {std::pair{10.0, 1e4}, std::pair{6.0, 5e3}}) {
      FractureSettings fracture;
      fracture.enabled = true;
      fracture.strength = strength;
      fracture.brittle = true;
      fracture.regions = 4;
      HeadOn h(sweeps, speed, 6, fracture);
      const glm::dvec3 p0 = h.momentum();
      const double scale = h.momentumScale(), e0 = h.energy();
      double worstMomentum = 0, maxEnergy = e0;
      int32_t fragments = 1, brokeWhileTouching = 0;
      for (int s = 0; s < 40; ++s) {
        const StepStatus st = h.world.step(1.0 / 60);
        ASSERT_FALSE(st.has(kStepNanContained)) << st.message;
        const int32_t now = h.world.fractureStats(h.b).fragments;
        if (h.world.timings().contactPairs > 0) brokeWhileTouching += now - fragments;
        fragments = now;
        worstMomentum = std::max(worstMomentum, glm::length(h.momentum() - p0) / scale);
        maxEnergy = std::max(maxEnergy, h.energy());
      }
      std::printf(
          "%d sweeps, %.0f m/s into a brittle block of strength %.0e: %d fragments (%d new in "
          "steps with contact pairs); momentum error %.3g; energy %.2f J -> max %.2f J\n",
          sweeps, speed, strength, fragments, brokeWhileTouching, worstMomentum, e0, maxEnergy);
      EXPECT_GT(brokeWhileTouching, 0);  // the case this test is for
      EXPECT_LT(worstMomentum, 1e-6);
      EXPECT_LE(maxEnergy, e0 * (1 + 1e-9));
    }
}

// A body that breaks while it touches, swept: a restore repeats its steps bit for bit (the
// sweeps re-step it from the substep's start with the first sweep's damage; nothing of that
// outlives the step) and reports the same breaks once each.
TEST(BodyContact, RestoreRepeatsTheSweepsOfABodyThatBreaks) {
  FractureSettings fracture;
  fracture.enabled = true;
  fracture.strength = 1e4;
  fracture.brittle = true;
  fracture.regions = 4;
  HeadOn h(4, 10, 6, fracture);
  ASSERT_TRUE(h.world.step(1.0 / 60).ok());
  const WorldSnapshot snap = h.world.snapshot();
  const int32_t brokenAtSnapshot = h.world.fractureStats(h.b).brokenEdges;
  const auto run = [&](std::vector<int32_t>* brokenEdges) {
    for (int s = 0; s < 12; ++s) {
      EXPECT_FALSE(h.world.step(1.0 / 60).has(kStepNanContained));
      for (const FractureEvent& e : h.world.fractureEvents()) brokenEdges->push_back(e.edge);
    }
    return h.world.stateHash();
  };
  std::vector<int32_t> first, again;
  const uint64_t hash = run(&first);
  ASSERT_TRUE(h.world.restore(snap).ok());
  EXPECT_EQ(run(&again), hash);
  EXPECT_EQ(again, first);
  // Each edge broke once.
  std::vector<int32_t> sorted = first;
  std::sort(sorted.begin(), sorted.end());
  EXPECT_EQ(std::adjacent_find(sorted.begin(), sorted.end()), sorted.end());
  // One event per edge broken since the snapshot.
  EXPECT_EQ(int32_t(first.size()), h.world.fractureStats(h.b).brokenEdges - brokenAtSnapshot);
  EXPECT_GT(first.size(), 0u);
}

// A cube of `size` and `cells` a side, turned 45 degrees about `axis`, centred at `centre`.
TetMesh turnedCube(double size, int cells, int axis, glm::dvec3 centre) {
  TetMesh m = gen::box(size, size, size, cells, cells, cells);
  const double c = std::cos(M_PI / 4), s = std::sin(M_PI / 4);
  for (size_t n = 0; n < m.nodeCount(); ++n) {
    double* p = &m.positions[3 * n];
    glm::dvec3 r(p[0] - size / 2, p[1] - size / 2, p[2] - size / 2);
    const int i = (axis + 1) % 3, j = (axis + 2) % 3;
    const double a = c * r[i] - s * r[j], b = s * r[i] + c * r[j];
    r[i] = a;
    r[j] = b;
    for (int k = 0; k < 3; ++k) p[k] = centre[k] + r[k];
  }
  return m;
}

// Blocks whose edges cross: the lower one turned 45 degrees about x (an edge on top, along x),
// the upper one turned 45 degrees about z (an edge below, along z), dropped edge on edge. No
// edge-edge test runs: the nodes along each edge meet the faces beside the other's edge.
TEST(BodyContact, CrossedEdgesDoNotPassThrough) {
  WorldDef wd = groundWorld();
  World world(wd);
  BodyDef lower, upper;
  const double half = 0.1 * std::sqrt(2.0);
  lower.mesh = turnedCube(0.2, 4, 0, {0, half, 0});
  upper.mesh = turnedCube(0.2, 4, 2, {0, 2 * half + half + 0.02, 0});
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

// Edge on edge (issue 15): the same two turned blocks, the upper one turned 90 degrees about
// the vertical from the lower, both of 5 cells (4 cm) a side so that their ridges cross midway
// between nodes: no vertex of either meets a face of the other there, only the edges meet.
// Measured on the ridges themselves: where the two ridge polylines cross seen from above, how
// far the lower's lies above the upper's (a vertex-in-tet test sees nothing here). Balanced on
// one point the upper block tips off after a while, as it should; the bound holds while the
// ridges cross, which must last well past the landing.
struct EdgeResult {
  double deepest = -HUGE_VAL;  // overlap of the ridges while they cross [m]
  int crossings = 0;           // steps, counted until they first stop crossing
  int64_t pairs = 0;
};

EdgeResult edgeOnEdge(double dt) {
  WorldDef wd = groundWorld();
  World world(wd);
  const double size = 0.2, half = 0.5 * size * std::sqrt(2.0);
  BodyDef lower, upper;
  lower.mesh = turnedCube(size, 5, 0, {0, half, 0});             // ridge on top along x
  upper.mesh = turnedCube(size, 5, 2, {0, 3 * half + 0.01, 0});  // ridge below along z
  for (BodyDef* d : {&lower, &upper}) {
    d->material = Material::stableNeoHookean(1e6, 0.3, 1000);
    d->material.stiffnessDamping = 0.02;
    d->contact = true;
  }
  // The ridges: the lower's highest nodes (sorted along x), the upper's lowest (along z).
  auto ridge = [](const TetMesh& m, bool top, int along) {
    double extreme = top ? -HUGE_VAL : HUGE_VAL;
    for (size_t n = 0; n < m.nodeCount(); ++n)
      extreme = top ? std::max(extreme, m.positions[3 * n + 1])
                    : std::min(extreme, m.positions[3 * n + 1]);
    std::vector<int32_t> nodes;
    for (size_t n = 0; n < m.nodeCount(); ++n)
      if (std::abs(m.positions[3 * n + 1] - extreme) < 1e-9) nodes.push_back(int32_t(n));
    std::sort(nodes.begin(), nodes.end(), [&](int32_t a, int32_t b) {
      return m.positions[3 * size_t(a) + size_t(along)] <
             m.positions[3 * size_t(b) + size_t(along)];
    });
    return nodes;
  };
  const std::vector<int32_t> ridgeLower = ridge(lower.mesh, true, 0);
  const std::vector<int32_t> ridgeUpper = ridge(upper.mesh, false, 2);
  EXPECT_EQ(ridgeLower.size(), 6u);
  EXPECT_EQ(ridgeUpper.size(), 6u);
  const BodyId a = world.createBody(lower).value(), b = world.createBody(upper).value();
  // Over every pair of ridge segments that cross seen from above: the lower's height minus the
  // upper's there (> 0: the edges have passed into each other).
  auto overlapAtCrossing = [&](bool* crossed) {
    const auto xa = world.positions(a), xb = world.positions(b);
    double worst = -HUGE_VAL;
    for (size_t i = 0; i + 1 < ridgeLower.size(); ++i)
      for (size_t j = 0; j + 1 < ridgeUpper.size(); ++j) {
        const glm::dvec3 p0 = at(xa, ridgeLower[i]), p1 = at(xa, ridgeLower[i + 1]);
        const glm::dvec3 q0 = at(xb, ridgeUpper[j]), q1 = at(xb, ridgeUpper[j + 1]);
        // p0 + s (p1 - p0) = q0 + t (q1 - q0) in x and z.
        const double ax = p1.x - p0.x, az = p1.z - p0.z, bx = q1.x - q0.x, bz = q1.z - q0.z;
        const double det = ax * (-bz) - az * (-bx);
        if (std::abs(det) < 1e-12) continue;
        const double rx = q0.x - p0.x, rz = q0.z - p0.z;
        const double s = (rx * (-bz) - rz * (-bx)) / det, t = (ax * rz - az * rx) / det;
        if (s < 0 || s > 1 || t < 0 || t > 1) continue;
        *crossed = true;
        worst = std::max(worst, (p0.y + s * (p1.y - p0.y)) - (q0.y + t * (q1.y - q0.y)));
      }
    return worst;
  };
  EdgeResult r;
  const int steps = int(std::lround(1.0 / dt));
  bool stillCrossing = true;
  for (int s = 1; s <= steps; ++s) {
    EXPECT_TRUE(world.step(dt).ok());
    r.pairs += world.timings().contactPairs;
    bool crossed = false;
    const double d = overlapAtCrossing(&crossed);
    stillCrossing = stillCrossing && crossed;
    if (!stillCrossing) continue;
    ++r.crossings;
    r.deepest = std::max(r.deepest, d);
  }
  std::printf(
      "edge on edge, dt 1/%.0f: %lld pairs; ridges crossing for %d of %d steps, the lower's "
      "ridge at most %.3g m above the upper's there (%.3g %% of a cell)\n",
      1 / dt, (long long)r.pairs, r.crossings, steps, r.deepest, 100 * r.deepest / (size / 5));
  return r;
}

TEST(BodyContact, EdgeOnEdgeMidwayBetweenNodes) {
  const double cell = 0.04;
  for (double dt : {1.0 / 60, 1.0 / 120}) {
    const EdgeResult r = edgeOnEdge(dt);
    EXPECT_GT(r.pairs, 0);
    // Landing takes about 0.05 s; the ridges still cross at 0.25 s.
    EXPECT_GT(r.crossings * dt, 0.25);
    // Without the edge test the upper block fell through the lower one: 6.8 cm (171 % of a
    // cell) of ridge overlap at 60 Hz.
    EXPECT_LT(r.deepest, 0.03 * cell);
  }
}

// The edge-edge pairs' closest points (kernels/contact.h) against sampling both segments: the
// kernel's pair is never farther apart than any sampled pair, and the finest sample comes
// within the sampling's resolution of it.
TEST(BodyContact, ClosestPointsOfSegmentsMatchSampling) {
  uint64_t seed = 12345;
  auto uniform = [&] {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return double(seed >> 11) / double(1ull << 53) * 2 - 1;
  };
  auto point = [&] { return Vec3{uniform(), uniform(), uniform()}; };
  int solved = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const Vec3 p0 = point(), p1 = point(), q0 = point(), q1 = point();
    double s = -1, t = -1;
    if (!closestOnSegments(p0, p1, q0, q1, s, t)) continue;
    ++solved;
    ASSERT_TRUE(s >= 0 && s <= 1 && t >= 0 && t <= 1);
    const double exact = norm((p0 + s * (p1 - p0)) - (q0 + t * (q1 - q0)));
    double sampled = HUGE_VAL;
    constexpr int kSamples = 200;
    for (int i = 0; i <= kSamples; ++i)
      for (int j = 0; j <= kSamples; ++j) {
        const double a = double(i) / kSamples, b = double(j) / kSamples;
        sampled = std::min(sampled, norm((p0 + a * (p1 - p0)) - (q0 + b * (q1 - q0))));
      }
    EXPECT_LE(exact, sampled + 1e-12) << "trial " << trial;
    EXPECT_LT(sampled - exact, 2.0 * (norm(p1 - p0) + norm(q1 - q0)) / kSamples)
        << "trial " << trial;
  }
  EXPECT_GT(solved, 190);
  // Parallel segments have no single closest pair.
  double s = 0, t = 0;
  EXPECT_FALSE(closestOnSegments({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 1, 0}, s, t));
}

// A column cut across in two; the upper piece is thrown up and sideways and lands half on the
// lower one (fragment self contact through the crack). Checked with the point-in-tet test of
// each fragment's nodes against the other's tets, and against the same run without contact,
// in which the upper piece falls into the lower one.
double thrownPiece(bool contact, int64_t* pairsOut, int32_t* fragmentsOut) {
  WorldDef wd = groundWorld();
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
  for (int s = 0; s < 60; ++s) {
    EXPECT_TRUE(world.step(1.0 / 60).ok());
    pairs += world.timings().contactPairs;
    const std::vector<Part> parts = fragmentParts(world, id, def.mesh);
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

// A 20 x 30 x 20 cm block (6 x 9 x 6 cells) of Young's modulus E cut by `planes` (1 to 3)
// planes through its middle (2, 4, 8 pieces) and dropped 30 cm onto the ground for 1 s at
// steps of dt with `sweeps` contact sweeps: the deepest node of one piece inside another's
// tets (point-in-tet, over the whole run) and how far the mechanical energy rose above its
// start.
struct CutBlockLanding {
  double deepest = 0, gained = 0, e0 = 0;
  int64_t newton = 0, steps = 0, unconverged = 0, searchFailed = 0;
  bool contained = true;  // no step rolled back
  std::string message;
};
CutBlockLanding cutBlockLanding(double E, int planes, int sweeps, double dt) {
  const glm::vec3 normals[3] = {glm::normalize(glm::vec3(1, 0.3f, 0.1f)),
                                glm::normalize(glm::vec3(0.2f, 1, -0.3f)),
                                glm::normalize(glm::vec3(-0.1f, 0.2f, 1))};
  WorldDef wd = groundWorld();
  wd.contactSweeps = sweeps;
  World world(wd);
  BodyDef def;
  def.mesh = movedBox(0.2, 0.3, 0.2, 6, 9, 6, {0, 0.31, 0});
  def.material = Material::stableNeoHookean(E, 0.3, 1000);
  def.fracture.enabled = true;
  def.fracture.strength = 1e12;  // only the cuts break
  def.contact = true;
  const BodyId id = world.createBody(def).value();
  for (int p = 0; p < planes; ++p) {
    const glm::vec3 n = normals[p], o(0.1f, 0.46f, 0.1f);
    const glm::vec3 t1 = glm::normalize(glm::cross(n, glm::vec3(0.3f, 0.5f, 0.8f)));
    const glm::vec3 t2 = glm::cross(n, t1);
    Blade blade;
    blade.vertices = {o - t1 - t2, o + t1 - t2, o + t1 + t2, o - t1 + t2};
    blade.triangles = {0, 1, 2, 0, 2, 3};
    EXPECT_TRUE(world.cut(id, blade).ok());
  }
  const auto mechanical = [&] {
    const BodyStats s = world.stats(id);
    return s.kineticEnergy + s.elasticEnergy + s.gravityEnergy + s.contactEnergy;
  };
  CutBlockLanding r;
  r.e0 = mechanical();
  const int steps = int(std::lround(1.0 / dt));
  for (int s = 0; s < steps; ++s) {
    const StepStatus st = world.step(dt);
    r.newton += st.newtonIterations;
    ++r.steps;
    r.unconverged += st.has(kStepNotConverged);
    r.searchFailed += st.has(kStepLineSearchFailed);
    if (st.has(kStepNanContained)) {
      r.contained = false;
      r.message = st.message;
      break;
    }
    r.gained = std::max(r.gained, mechanical() - r.e0);
    const std::vector<Part> parts = fragmentParts(world, id, def.mesh);
    for (size_t i = 0; i < parts.size(); ++i)
      for (size_t j = 0; j < parts.size(); ++j)
        if (i != j && !parts[i].tets.empty() && !parts[j].tets.empty())
          r.deepest =
              std::max(r.deepest, deepestInside(world, def.mesh, parts[i], def.mesh, parts[j]));
  }
  const double cell = 0.2 / 6;
  std::printf(
      "%d planes, E %.0e, %.0f Hz, %d sweeps: deepest node in another piece %.3g m (%.1f %% of a "
      "cell), mechanical energy at most %.3g J above its start, %.2f Newton iterations a "
      "step (%lld not converged, %lld line search failed)%s%s\n",
      planes, E, 1 / dt, sweeps, r.deepest, 100 * r.deepest / cell, r.gained,
      double(r.newton) / double(r.steps), (long long)r.unconverged, (long long)r.searchFailed,
      r.contained ? "" : "; rolled back: ", r.message.c_str());
  return r;
}

// The cut block's pieces land together, at 60 and 120 Hz, and should not pass into each other
// (under 2 % of a cell) nor gain mechanical energy. DISABLED, fails with one sweep
// (docs/validation.md, "Pieces of a cut block landing together"): with the self pairs solved
// inside the body's Newton step, re-linearised at the iterate, no case gains energy, but a node of
// one piece still lies up to 10.7 % of a cell in another (4 of the 12 cases above 2 %, all at
// 60 Hz; "Friction between the pieces of one body").
TEST(BodyContact, DISABLED_PiecesOfACutBlockLandTogether) {
  for (const double dt : {1.0 / 60, 1.0 / 120})
    for (const double E : {1e6, 1e7})
      for (int planes = 1; planes <= 3; ++planes) {
        const CutBlockLanding r = cutBlockLanding(E, planes, 1, dt);
        ASSERT_TRUE(r.contained) << planes << " planes, E " << E << ": " << r.message;
        EXPECT_LT(r.deepest, 0.02 * 0.2 / 6);
        EXPECT_LE(r.gained, 1e-3 * std::abs(r.e0));
      }
}

// The same with four contact sweeps, at 60 and 120 Hz. DISABLED, fails too (docs/validation.md,
// "Pieces of a cut block landing together": sweeps lower the energy gain in most cases but no
// case passes).
TEST(BodyContact, DISABLED_PiecesOfACutBlockLandTogetherWithSweeps) {
  for (const double dt : {1.0 / 60, 1.0 / 120})
    for (const double E : {1e6, 1e7})
      for (int planes = 1; planes <= 3; ++planes) {
        const CutBlockLanding r = cutBlockLanding(E, planes, 4, dt);
        ASSERT_TRUE(r.contained) << planes << " planes, E " << E << ": " << r.message;
        EXPECT_LT(r.deepest, 0.02 * 0.2 / 6);
        EXPECT_LE(r.gained, 1e-3 * std::abs(r.e0));
      }
}

// Pieces of one body resting on each other (issue 15): their contacts are self pairs, solved
// inside the body's Newton step, with friction between the pieces acting on both sides' nodes
// (HalfSpaceContacts::slide). A body made of separate boxes, with fracture on and never
// reached, has them as its pieces from the start. Before, a self pair's friction had no normal
// force where a piece rested (its depth was measured from the face, not from the plane a skin in
// front that the pair pushes from) and slid against the face's predicted motion: a stack of such
// pieces crept apart and fell (docs/validation.md, "Friction between the pieces of one body").
struct PieceBox {
  glm::dvec3 size, origin;  // [m], the lowest corner
  glm::ivec3 cells;
  bool heldBase = false;  // its bottom nodes gripped at rest
};
struct PiecesBody {
  BodyDef def;
  std::vector<int32_t> first;  // each box's first node, then the node count
};
PiecesBody piecesBody(const std::vector<PieceBox>& boxes, double E, double mu) {
  PiecesBody out;
  Grip base;
  for (const PieceBox& b : boxes) {
    const TetMesh m =
        movedBox(b.size.x, b.size.y, b.size.z, b.cells.x, b.cells.y, b.cells.z, b.origin);
    const int32_t offset = int32_t(out.def.mesh.nodeCount());
    out.first.push_back(offset);
    out.def.mesh.positions.insert(out.def.mesh.positions.end(), m.positions.begin(),
                                  m.positions.end());
    for (int32_t k : m.tets) out.def.mesh.tets.push_back(k + offset);
    for (int32_t n = 0; b.heldBase && n < int32_t(m.nodeCount()); ++n)
      if (m.positions[3 * size_t(n) + 1] == b.origin.y) base.nodes.push_back(n + offset);
  }
  out.first.push_back(int32_t(out.def.mesh.nodeCount()));
  if (!base.nodes.empty()) out.def.grips.push_back(base);
  out.def.material = Material::stableNeoHookean(E, 0.3, 1000);
  out.def.material.stiffnessDamping = 0.02;
  out.def.friction = mu;
  out.def.contact = true;
  out.def.fracture.enabled = true;
  out.def.fracture.strength = 1e12;
  return out;
}
// Mean position and velocity of box i's nodes.
glm::dvec3 boxMean(std::span<const double> x, const PiecesBody& p, size_t i) {
  glm::dvec3 sum(0);
  for (int32_t n = p.first[i]; n < p.first[i + 1]; ++n) sum += at(x, n);
  return sum / double(p.first[i + 1] - p.first[i]);
}

// 20 cm boxes of 4 cells, each 2 cm above the one below, dropped onto the ground as one body
// and left for 6 s at 60 Hz: they come to rest stacked, as the separate bodies of
// BodyContactStack do. Before, three boxes crept apart (an offset of 0.17 mm, growing at
// 0.45 mm/s after 6 s) and four slid off each other and fell at 2.5 s.
TEST(BodyContact, PiecesOfOneBodyRestStacked) {
  struct Case {
    int boxes;
    double E;
  };
  for (const Case c : {Case{3, 2e5}, Case{4, 2e5}}) {
    std::vector<PieceBox> boxes;
    for (int i = 0; i < c.boxes; ++i)
      boxes.push_back({glm::dvec3(0.2), glm::dvec3(-0.1, 0.01 + 0.22 * i, -0.1), glm::ivec3(4)});
    PiecesBody p = piecesBody(boxes, c.E, 0.6);
    // The direct solver: the multigrid's coupled solve gives the same rest (docs/validation.md)
    // at four times the test's time.
    p.def.solver.linearSolver = LinearSolverKind::Direct;
    World world(groundWorld());
    const BodyId id = world.createBody(p.def).value();
    const double dt = 1.0 / 60, cell = 0.05;
    double deepest = 0, ground = 0;
    int notOk = 0;
    const int steps = 360;
    for (int s = 1; s <= steps; ++s) {
      notOk += !world.step(dt).ok();
      if (s > steps - 60) ground += world.colliderImpulses()[0].y;
      const std::vector<Part> parts = fragmentParts(world, id, p.def.mesh);
      for (size_t i = 0; i < parts.size(); ++i)
        for (size_t j = 0; j < parts.size(); ++j)
          if (i != j)
            deepest =
                std::max(deepest, deepestInside(world, p.def.mesh, parts[i], p.def.mesh, parts[j]));
    }
    ASSERT_EQ(world.fractureStats(id).fragments, c.boxes);
    const auto x = world.positions(id), v = world.velocities(id);
    double offset = 0, speed = 0, seat = 0;
    for (int i = 0; i < c.boxes; ++i) {
      speed = std::max(speed, glm::length(boxMean(v, p, size_t(i))));
      if (i == 0) continue;
      const glm::dvec3 d = boxMean(x, p, size_t(i)) - boxMean(x, p, size_t(i - 1));
      offset = std::max(offset, std::hypot(d.x, d.z) / 0.2);
      double bottom = HUGE_VAL, top = -HUGE_VAL;
      for (int32_t n = p.first[size_t(i)]; n < p.first[size_t(i) + 1]; ++n)
        bottom = std::min(bottom, x[3 * size_t(n) + 1]);
      for (int32_t n = p.first[size_t(i) - 1]; n < p.first[size_t(i)]; ++n)
        top = std::max(top, x[3 * size_t(n) + 1]);
      seat = std::max(seat, std::abs(top - bottom));
    }
    const double weight = world.stats(id).mass * 9.81;
    std::printf(
        "%d boxes, E %.0e: after 6 s offset %.2e of a box, box speed %.2e m/s, seat %.2e m, "
        "deepest %.2f %% of a cell, ground %.3f N for %.3f N, %d steps not ok\n",
        c.boxes, c.E, offset, speed, seat, 100 * deepest / cell, ground, weight, notOk);
    EXPECT_EQ(notOk, 0);
    EXPECT_LT(offset, 1e-4);
    EXPECT_LT(speed, 1e-4);
    EXPECT_LT(seat, 0.05 * cell);  // a self pair's plane lies 2.5 % of a cell in front
    EXPECT_LT(deepest, 0.01 * cell);
    EXPECT_NEAR(ground, weight, 0.02 * weight);
  }
}

// A 10 cm block (4 x 2 x 4 cells) resting on a 1 m slab of the same body (its base gripped),
// under gravity tilted by `angle` about z, both with friction mu (the pair has mu), stepped at
// `rate` Hz: the incline of the collider test (test_friction.cpp) between two pieces. It lands
// from 1 cm (pieces that touch in the rest shape are not paired), then its velocity down the
// slope between 0.2 s and 0.6 s gives the acceleration, before it reaches the slab's end.
struct Slide {
  double acceleration = 0;  // down the slope [m/s^2]
  double travel = 0;        // down the slope from 0.2 s to 0.6 s [m]
  double endSpeed = 0;
  double fastest = 0;
};
PiecesBody blockOnSlab(double mu) {
  return piecesBody({{{1.0, 0.05, 0.3}, {-0.5, 0, -0.15}, {20, 1, 6}, true},
                     {{0.1, 0.04, 0.1}, {-0.45, 0.06, -0.05}, {4, 2, 4}, false}},
                    1e7, mu);
}
WorldDef inclined(double angle) {
  return {glm::vec3(float(9.81 * std::sin(angle)), float(-9.81 * std::cos(angle)), 0),
          Backend::Cpu,
          nullptr,
          1,
          {}};
}
Slide pieceOnInclinedPiece(double angle, double mu, int rate = 60) {
  const PiecesBody p = blockOnSlab(mu);
  World world(inclined(angle));
  const BodyId id = world.createBody(p.def).value();
  const double dt = 1.0 / rate;
  const int from = rate / 5, to = 3 * rate / 5;
  double v1 = 0, x1 = 0;
  Slide out;
  for (int s = 1; s <= to; ++s) {
    const StepStatus st = world.step(dt);
    EXPECT_TRUE(st.ok()) << st.message;
    if (s == from) {
      v1 = boxMean(world.velocities(id), p, 1).x;
      x1 = boxMean(world.positions(id), p, 1).x;
    }
  }
  out.endSpeed = boxMean(world.velocities(id), p, 1).x;
  out.acceleration = (out.endSpeed - v1) / ((to - from) * dt);
  out.travel = boxMean(world.positions(id), p, 1).x - x1;
  return out;
}

// At half the friction angle's tangent the piece stays put, creeping at the smoothing's
// (1 mm/s) tan / (2 mu), as on a collider. Before, a resting piece had no friction at all.
TEST(BodyContact, PieceOnAnInclinedPieceRestsBelowTheFrictionAngle) {
  for (const double mu : {0.2, 0.6}) {
    const double gentle = std::atan(0.5 * mu);
    const Slide stays = pieceOnInclinedPiece(gentle, mu);
    std::printf("mu %.1f, %.1f deg: moved %.3f mm over 0.4 s, end speed %.2e m/s\n", mu,
                gentle * 180 / M_PI, 1e3 * stays.travel, stays.endSpeed);
    EXPECT_LT(std::abs(stays.travel), 1e-3);
    EXPECT_LT(std::abs(stays.endSpeed), 1e-3);
  }
}

// 15 degrees past the friction angle the piece slides at g (sin - mu cos): within 5 % at 60 Hz,
// and within 2 % at 120 Hz, since friction's load is a substep late where the pairs change under
// the sliding piece (design.md). When each pair's own depth at x_n was its load, the piece slid
// 26 % (mu 0.2) and 38 % (mu 0.6) slower: a vertex sliding over the other piece's cells pairs
// with a changing number of coplanar faces, each counting the vertex's load again.
void expectSlidesAsCoulombSays(Slide (*slide)(double angle, double mu, int rate)) {
  for (const int rate : {60, 120})
    for (const double mu : {0.2, 0.6}) {
      const double steep = std::atan(mu) + 15 * M_PI / 180;
      const Slide slides = slide(steep, mu, rate);
      const double expected = 9.81 * (std::sin(steep) - mu * std::cos(steep));
      std::printf(
          "%d Hz, mu %.1f, %.1f deg: acceleration %.4f m/s^2, g (sin - mu cos) %.4f "
          "(%+.2f %%)\n",
          rate, mu, steep * 180 / M_PI, slides.acceleration, expected,
          100 * (slides.acceleration / expected - 1));
      EXPECT_NEAR(slides.acceleration, expected, (rate == 60 ? 0.05 : 0.02) * expected);
    }
}
TEST(BodyContact, PieceOnAnInclinedPieceSlidesAsCoulombSays) {
  expectSlidesAsCoulombSays(pieceOnInclinedPiece);
}

// A 10 cm block (2.5 cm cells) put at rest on a 1 m slab body, the slab gripped at its base or
// not (then the world's floor must hold it), of `layers` layers of 5 / layers cm cells; the
// block's id.
struct SlabCase {
  bool gripped;
  int layers;
  double damping, mu;
};
BodyId putBlockOnSlabBody(World& world, const SlabCase& c) {
  BodyDef slab, block;
  slab.mesh = movedBox(1.0, 0.05, 0.3, 20 * c.layers, c.layers, 6 * c.layers, {-0.5, 0, -0.15});
  block.mesh = movedBox(0.1, 0.04, 0.1, 4, 2, 4, {-0.45, 0.05, -0.05});
  Grip base;
  for (int32_t n = 0; n < int32_t(slab.mesh.nodeCount()); ++n)
    if (slab.mesh.positions[3 * size_t(n) + 1] == 0) base.nodes.push_back(n);
  if (c.gripped) slab.grips.push_back(base);
  for (BodyDef* d : {&slab, &block}) {
    d->material = Material::stableNeoHookean(1e7, 0.3, 1000);
    d->material.stiffnessDamping = c.damping;
    d->friction = c.mu;
    d->contact = true;
  }
  world.createBody(slab).value();
  return world.createBody(block).value();
}

// The same incline between two bodies: the slab a body of its own (its base gripped), the
// block another, put on it at rest. Before, the exchange spread the lagged planes' mismatch over
// the gripped cluster's free nodes and threw the block off at up to 10 m/s, resting or sliding
// (accelerations -98 to +138 % off Coulomb's).
Slide blockOnInclinedBody(double angle, double mu, int rate) {
  World world(inclined(angle));
  const BodyId b = putBlockOnSlabBody(world, {true, 1, 0.02, mu});
  const auto meanX = [&] {
    const std::span<const double> x = world.positions(b);
    double sum = 0;
    for (size_t i = 0; i < x.size(); i += 3) sum += x[i];
    return 3 * sum / double(x.size());
  };
  const auto velocity = [&] { return world.stats(b).linearMomentum.x / world.stats(b).mass; };
  const double dt = 1.0 / rate;
  const int from = rate / 5, to = 3 * rate / 5;
  double v1 = 0, x1 = 0, fastest = 0;
  for (int s = 1; s <= to; ++s) {
    const StepStatus st = world.step(dt);
    EXPECT_TRUE(st.ok()) << st.message;
    fastest = std::max(fastest, glm::length(world.stats(b).linearMomentum) / world.stats(b).mass);
    if (s == from) {
      v1 = velocity();
      x1 = meanX();
    }
  }
  Slide out;
  out.endSpeed = velocity();
  out.acceleration = (out.endSpeed - v1) / ((to - from) * dt);
  out.travel = meanX() - x1;
  out.fastest = fastest;
  return out;
}

// Below the friction angle the block stays; 15 degrees past it, it slides at g (sin - mu cos)
// within 5 % at 60 Hz and 2 % at 120 Hz.
TEST(BodyContact, BlockOnAnInclinedBodyObeysCoulomb) {
  for (const double mu : {0.2, 0.6}) {
    const double gentle = std::atan(0.5 * mu);
    const Slide stays = blockOnInclinedBody(gentle, mu, 60);
    std::printf(
        "mu %.1f, %.1f deg: moved %.3f mm over 0.4 s, end speed %.2e m/s, at most %.2e m/s\n", mu,
        gentle * 180 / M_PI, 1e3 * stays.travel, stays.endSpeed, stays.fastest);
    EXPECT_LT(std::abs(stays.travel), 1e-3);
    EXPECT_LT(std::abs(stays.endSpeed), 1e-3);
    // Friction's load is a substep late where pairs begin: in its first step on the slab the
    // block slides freely, g sin dt, and never faster after.
    EXPECT_LT(stays.fastest, 1.05 * 9.81 * std::sin(gentle) / 60);
  }
  expectSlidesAsCoulombSays(blockOnInclinedBody);
}

// The block on the slab body of `c`, on the floor where the slab is not gripped: its largest
// speed over 1 s at 60 Hz.
double fastestBlockOnSlab(const SlabCase& c) {
  WorldDef wd{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}};
  if (!c.gripped) wd.colliders.push_back(Collider{});
  World world(wd);
  const BodyId b = putBlockOnSlabBody(world, c);
  double fastest = 0;
  for (int s = 0; s < 60; ++s) {
    const StepStatus st = world.step(1.0 / 60);
    EXPECT_TRUE(st.ok()) << st.message;
    fastest = std::max(fastest, glm::length(world.stats(b).linearMomentum) / world.stats(b).mass);
  }
  std::printf("%s, %d layer(s), damping %.2f s, mu %.1f: block at most %.3g m/s\n",
              c.gripped ? "gripped" : "on the floor", c.layers, c.damping, c.mu, fastest);
  return fastest;
}

// Every case rests, the block at most 0.015 m/s (the floor's penalty settling under the slab).
// On a gripped slab it was thrown at 1-10 m/s before the exchange left gripped clusters alone.
// On the floor, one layer, damping and friction, it was thrown at 18 m/s before a step that the
// line search shortened kept backward Euler's velocities: the end spin read the moment of the
// contact impulses as linearised against planes 13 mm deep and turned the block at 16 rad/s.
TEST(BodyContact, BlockRestsOnASlabBody) {
  for (const bool gripped : {true, false})
    for (const int layers : {1, 2})
      for (const double damping : {0.0, 0.02})
        for (const double mu : {0.0, 0.5})
          EXPECT_LT(fastestBlockOnSlab({gripped, layers, damping, mu}), 0.02);
}

// A block dropped 2 mm onto a slab body on the floor (the slab's cells 10, 5 or 2.5 cm, the
// block's 2.5 cm; undamped and frictionless, or damped with friction on a frictional floor):
// how far its centre of mass rose above where it was dropped from, and its fastest after 0.5 s.
struct Drop {
  double rise = -HUGE_VAL, speed = 0;
};
Drop dropOnSlab(double E, int rate, int cells, bool damped) {
  World world(floorWorld(damped ? 1 : 0));
  BodyDef slab, block;
  slab.mesh = movedBox(0.6, 0.05, 0.3, cells, 1, cells / 2, {-0.3, 0, -0.15});
  block.mesh = movedBox(0.1, 0.04, 0.1, 4, 2, 4, {-0.037, 0.052, -0.05});
  for (BodyDef* d : {&slab, &block}) {
    d->material = Material::stableNeoHookean(E, 0.3, 1000);
    d->material.stiffnessDamping = damped ? 0.02 : 0;
    d->friction = damped ? 0.5 : 0;
    d->contact = true;
  }
  world.createBody(slab).value();
  const BodyId b = world.createBody(block).value();
  // The centre of mass's height, from the potential energy -sum m_i g . x_i.
  const auto height = [&] {
    const BodyStats st = world.stats(b);
    return st.gravityEnergy / (st.mass * double(9.81f));
  };
  const double start = height(), step = 1.0 / rate;
  Drop out;
  for (int k = 0; k < rate; ++k) {
    const StepStatus st = world.step(step);
    EXPECT_TRUE(st.ok()) << st.message;
    out.rise = std::max(out.rise, height() - start);
    if (k * step >= 0.5)
      out.speed =
          std::max(out.speed, glm::length(world.stats(b).linearMomentum) / world.stats(b).mass);
  }
  std::printf(
      "E %.0e, %d Hz, slab cells %.1f cm%s: rose %.3g mm above its start, then at most "
      "%.3g m/s\n",
      E, rate, 60.0 / cells, damped ? ", damped, mu 0.5" : "", 1e3 * out.rise, out.speed);
  return out;
}

// It never rises above where it was dropped from (no energy gained), over stiffness, time step
// (30, 60, 120 Hz) and the slab's cells, and at 60 and 120 Hz it comes to rest. Before the
// approach was shared by the groups' masses, 11 of the 18 cases at 60 Hz gained energy, all on
// slabs of 5 or 2.5 cm cells (the block rose up to 15 m, at up to 27 m/s): the slab's vertices
// were pushed a quarter of the block's approach into the floor, and the exchange handed the
// slab's 4.4 N s back to both as a bounce. At 30 Hz the block, put 2 mm above the slab, fell 11
// mm in its first step, found no pair (its prediction, at rest, leaves gravity out) and went
// through the slab before pairs were kept from |g . n| dt^2 in front of a face.
TEST(BodyContact, BlockDroppedOnASlabBodyGainsNoEnergy) {
  for (const double E : {1e6, 1e7, 1e8})
    for (const int rate : {30, 60, 120})
      for (const int cells : {6, 12, 24})
        for (const bool damped : {false, true}) {
          const Drop d = dropOnSlab(E, rate, cells, damped);
          EXPECT_LT(d.rise, 0.5e-3);
          if (rate >= 60) {
            EXPECT_LT(d.speed, 0.05);
          }
        }
}

// Fails: at 30 Hz it also comes to rest, except on the slab of 2.5 cm cells (the block's own)
// damped and with friction, at E 1e7 and 1e8, where block and slab chatter at 0.057 and 0.065
// m/s after 0.5 s, bouncing by about 1 mm a step without gaining energy.
TEST(BodyContact, DISABLED_BlockDroppedOnASlabBodyRestsAt30Hz) {
  for (const double E : {1e6, 1e7, 1e8})
    for (const int cells : {6, 12, 24})
      for (const bool damped : {false, true})
        EXPECT_LT(dropOnSlab(E, 30, cells, damped).speed, 0.05);
}

// A block sliding over the coarse slab (10 cm cells under its 2.5 cm ones) with friction, the
// slab on a frictional floor: while the block is on it, the slab stays where it is. The block's
// trailing face passes over the slab's top nodes; where a node was behind its plane at the
// step's start and in front of it at the prediction, the face's plane at its start pushed it
// along the slide (at 1 m/s the slab was thrown at 0.2 m/s in one step). Speeds 0.5-2 m/s.
TEST(BodyContact, BlockSlidingOverACoarseSlabLeavesItAtRest) {
  for (int tenths = 5; tenths <= 20; ++tenths) {
    const double v0 = 0.1 * tenths;
    World world(floorWorld(1.0));
    BodyId slab;
    const BodyId b = putBlockOnCoarseSlab(world, 0.1, -0.5, &slab);
    for (int k = 0; k < 30; ++k) ASSERT_TRUE(world.step(1.0 / 60).ok());
    ASSERT_TRUE(world.setVelocity(b, glm::dvec3(v0, 0, 0)).ok());
    double fastest = 0;
    int steps = 0;
    for (; steps < 120; ++steps) {
      const std::span<const double> x = world.positions(b);
      double rear = HUGE_VAL;
      for (size_t i = 0; i < x.size(); i += 3) rear = std::min(rear, x[i]);
      if (rear > 0.45) break;  // its last 5 cm on the slab: from here it may tip off the end
      EXPECT_TRUE(world.step(1.0 / 60).ok());
      fastest =
          std::max(fastest, glm::length(world.stats(slab).linearMomentum) / world.stats(slab).mass);
    }
    std::printf("sliding at %.1f m/s: %d steps on the slab, the slab at most %.3g m/s\n", v0, steps,
                fastest);
    EXPECT_GT(steps, 20);
    EXPECT_LT(fastest, 0.01);
  }
}

// Fails: a block set sliding at 1 m/s off the coarse slab's end, mu 0.1, the slab on a floor of
// friction 1, tips over the end and tumbles back against the slab's lower corner, and the slab
// (48 kg) moves at 0.032 m/s: the slab's corner vertices pushed by the block's tilted face gave it
// 1.7 N s in one step for the block's 0.12 N s of momentum. (Before the trailing-face rule and
// the groups' share of the approach: 0.22 m/s at 1 m/s and 3.04 m/s at 1.5 m/s.)
TEST(BodyContact, DISABLED_BlockSlidingOffASlabLeavesItAtRest) {
  for (const double v0 : {0.5, 1.0, 1.5}) {
    World world(floorWorld(1.0));
    BodyId slab;
    const BodyId b = putBlockOnCoarseSlab(world, 0.1, 0.3, &slab);
    for (int k = 0; k < 30; ++k) ASSERT_TRUE(world.step(1.0 / 60).ok());
    ASSERT_TRUE(world.setVelocity(b, glm::dvec3(v0, 0, 0)).ok());
    double fastest = 0;
    for (int k = 0; k < 90; ++k) {
      EXPECT_TRUE(world.step(1.0 / 60).ok());
      fastest =
          std::max(fastest, glm::length(world.stats(slab).linearMomentum) / world.stats(slab).mass);
    }
    std::printf("sliding off at %.1f m/s: the slab at most %.3g m/s\n", v0, fastest);
    EXPECT_LT(fastest, 0.02);
  }
}

// Friction's load is part of the state: a restore mid-slide repeats the slide bit for bit.
void expectRestoreRepeats(World& world, BodyId id) {
  const WorldSnapshot snap = world.snapshot();
  const auto run = [&] {
    for (int s = 0; s < 10; ++s) EXPECT_TRUE(world.step(1.0 / 60).ok());
    const std::span<const double> v = world.velocities(id);
    return std::make_pair(world.stateHash(), std::vector<double>(v.begin(), v.end()));
  };
  const auto first = run();
  ASSERT_TRUE(world.restore(snap).ok());
  const auto again = run();
  EXPECT_EQ(again.first, first.first);
  EXPECT_EQ(again.second, first.second);
}
TEST(BodyContact, RestoreRepeatsAPieceSlidingOnAnother) {
  World world(inclined(std::atan(0.6) + 15 * M_PI / 180));
  const BodyId id = world.createBody(blockOnSlab(0.6).def).value();
  for (int s = 0; s < 15; ++s) ASSERT_TRUE(world.step(1.0 / 60).ok());
  expectRestoreRepeats(world, id);
}
// The same between two bodies: the block sliding over the coarse slab.
TEST(BodyContact, RestoreRepeatsABlockSlidingOverAnotherBody) {
  World world(floorWorld(1.0));
  const BodyId b = putBlockOnCoarseSlab(world, 0.5, -0.58);
  for (int s = 0; s < 30; ++s) ASSERT_TRUE(world.step(1.0 / 60).ok());
  ASSERT_TRUE(world.setVelocity(b, glm::dvec3(1.5, 0, 0)).ok());
  for (int s = 0; s < 3; ++s) ASSERT_TRUE(world.step(1.0 / 60).ok());
  expectRestoreRepeats(world, b);
}

// The pair lists are built serially in slot and node order, so the contact step gives the same
// bits for any thread count (tests/physics/test_determinism.cpp).
std::vector<double> stackState(JobSystem* jobs, int sweeps = 1) {
  WorldDef wd{glm::vec3(0, -9.81f, 0), Backend::Cpu, jobs, 1, {}};
  wd.contactSweeps = sweeps;
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

// The contact sweeps step the bodies again in the same partition (large bodies one after
// another, small ones side by side) and judge convergence in slot and node order.
TEST(BodyContact, SameBitsForAnyThreadCountWithSweeps) {
  ThreadPoolJobSystem pool2(2), pool4(4);
  const std::vector<double> serial = stackState(nullptr, 4);
  const std::vector<double> two = stackState(&pool2, 4), four = stackState(&pool4, 4);
  ASSERT_EQ(serial.size(), two.size());
  EXPECT_EQ(0, std::memcmp(serial.data(), two.data(), serial.size() * sizeof(double)));
  EXPECT_EQ(0, std::memcmp(serial.data(), four.data(), serial.size() * sizeof(double)));
  // The sweeps ran: the state is not the single pass's.
  const std::vector<double> once = stackState(nullptr, 1);
  EXPECT_NE(0, std::memcmp(serial.data(), once.data(), serial.size() * sizeof(double)));
}

// Many groups at once: a cut body whose upper piece is thrown onto its lower one (self contact
// between fragments) beside two stacks of two blocks, so the broad phase, the hash, the pair
// lists and the exchange's clusters (three of them) all run with several slots and groups.
// `plastic`: the lower block of the first stack yields where the upper one lands on it.
std::vector<double> manyGroupsState(JobSystem* jobs, int64_t* pairsOut, int32_t* fragmentsOut,
                                    int sweeps = 1, bool plastic = false, bool coupled = false) {
  WorldDef wd{glm::vec3(0, -9.81f, 0), Backend::Cpu, jobs, 1, {}};
  wd.contactSweeps = sweeps;
  wd.coupledContact = coupled;
  Collider ground;
  ground.friction = 0.5;
  wd.colliders.push_back(ground);
  World world(wd);
  BodyDef cut;
  cut.mesh = gen::box(0.1, 0.4, 0.1, 4, 16, 4);
  cut.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  cut.material.stiffnessDamping = 0.02;
  cut.fracture.enabled = true;
  cut.fracture.strength = 1e9;  // only the cut breaks
  cut.contact = true;
  std::vector<BodyId> ids{world.createBody(cut).value()};
  for (double x : {0.4, 0.8}) {
    BodyDef lower, upper;
    lower.mesh = movedBox(0.2, 0.2, 0.2, 4, 4, 4, {x, 0.01, 0});
    upper.mesh = movedBox(0.15, 0.15, 0.15, 3, 3, 3, {x + 0.025, 0.25, 0.025});
    for (BodyDef* d : {&lower, &upper}) {
      d->material = Material::stableNeoHookean(2e5, 0.3, 1000);
      d->contact = true;
    }
    if (plastic && x < 0.5) {
      lower.plasticity.enabled = true;
      lower.plasticity.yieldStress = 2e3;
    }
    for (BodyDef* d : {&lower, &upper}) ids.push_back(world.createBody(*d).value());
  }
  Blade blade;  // the plane y = 0.206, off the nodes
  blade.vertices = {{-1, 0.206f, -1}, {1, 0.206f, -1}, {1, 0.206f, 1}, {-1, 0.206f, 1}};
  blade.triangles = {0, 2, 1, 0, 3, 2};
  EXPECT_TRUE(world.cut(ids[0], blade).ok());
  EXPECT_TRUE(world.step(1.0 / 60).ok());
  std::vector<double> v(world.velocities(ids[0]).begin(), world.velocities(ids[0]).end());
  for (size_t n = 0; n < cut.mesh.nodeCount(); ++n)
    if (cut.mesh.positions[3 * n + 1] > 0.21) {
      v[3 * n] = 0.15;
      v[3 * n + 1] = 2;
    }
  EXPECT_TRUE(world.setVelocities(ids[0], v).ok());
  int64_t pairs = 0;
  for (int s = 0; s < 45; ++s) {
    const StepStatus st = world.step(1.0 / 60);
    EXPECT_FALSE(st.has(kStepNanContained)) << st.message;
    // With sweeps the cut body's self pairs stop one step at the Newton cap (the iterates
    // still contract, by 0.75 an iteration); what this harness checks is the bits.
    if (sweeps == 1) {
      EXPECT_TRUE(st.ok()) << st.message;
    }
    pairs += world.timings().contactPairs;
  }
  *pairsOut = pairs;
  *fragmentsOut = world.fractureStats(ids[0]).fragments;
  std::vector<double> out;
  for (BodyId id : ids) {
    const auto x = world.positions(id), vel = world.velocities(id);
    out.insert(out.end(), x.begin(), x.end());
    out.insert(out.end(), vel.begin(), vel.end());
  }
  return out;
}

// The many-groups scene on 1, 2 and 4 threads gives the same pairs and bits; returns the state.
std::vector<double> expectSameBitsForAnyThreadCount(int sweeps, bool plastic,
                                                    bool coupled = false) {
  ThreadPoolJobSystem pool2(2), pool4(4);
  int64_t pairs[3] = {};
  int32_t fragments[3] = {};
  const std::vector<double> serial =
      manyGroupsState(nullptr, &pairs[0], &fragments[0], sweeps, plastic, coupled);
  const std::vector<double> two =
      manyGroupsState(&pool2, &pairs[1], &fragments[1], sweeps, plastic, coupled);
  const std::vector<double> four =
      manyGroupsState(&pool4, &pairs[2], &fragments[2], sweeps, plastic, coupled);
  std::printf("many groups, %d sweep(s): %lld pairs, %d fragments of the cut body\n", sweeps,
              (long long)pairs[0], fragments[0]);
  EXPECT_GT(pairs[0], 0);
  EXPECT_GE(fragments[0], 2);
  EXPECT_EQ(pairs[1], pairs[0]);
  EXPECT_EQ(pairs[2], pairs[0]);
  EXPECT_EQ(serial.size(), two.size());
  EXPECT_EQ(serial.size(), four.size());
  if (serial.size() == two.size() && serial.size() == four.size()) {
    EXPECT_EQ(0, std::memcmp(serial.data(), two.data(), serial.size() * sizeof(double)));
    EXPECT_EQ(0, std::memcmp(serial.data(), four.data(), serial.size() * sizeof(double)));
  }
  return serial;
}

TEST(BodyContact, SameBitsForAnyThreadCountWithManyBodiesAndFragments) {
  expectSameBitsForAnyThreadCount(1, false);
}

// Coupled contact over the same scene (two clusters of stacked blocks, one of them plastic, and
// the cut body's pieces): the joint numbering, the clusters' solves and their sums are in slot
// order, so any thread count gives the same bits.
TEST(BodyContact, SameBitsForAnyThreadCountWithCoupledContact) {
  expectSameBitsForAnyThreadCount(1, true, true);
}

// The same with four sweeps and a block that yields: the cut body and the plastic block are
// stepped again in the sweeps (fracture judged in the first, plastic flow after the last).
TEST(BodyContact, SameBitsForAnyThreadCountWithSweepsOverCutAndPlasticBodies) {
  const std::vector<double> swept = expectSameBitsForAnyThreadCount(4, true);
  // The sweeps ran on these bodies: the state is not the single pass's.
  int64_t pairs = 0;
  int32_t fragments = 0;
  const std::vector<double> once = manyGroupsState(nullptr, &pairs, &fragments, 1, true);
  ASSERT_EQ(swept.size(), once.size());
  EXPECT_NE(0, std::memcmp(swept.data(), once.data(), swept.size() * sizeof(double)));
}

}  // namespace
}  // namespace gf
