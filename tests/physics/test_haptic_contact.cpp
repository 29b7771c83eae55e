// Haptic rendering of a proxy against a body's surface (thesis sec 7.2.3, eq 7.5-7.6): the
// continuous penalty force is smooth where the discrete one jumps (a proxy pressed into a thin
// plate at constant speed), catches a proxy that passes through a plate between two samples,
// and for a proxy held at a fixed depth equals the penalty k d per contact.
#include <graphfrac/sculpt.h>
#include <graphfrac/world.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <vector>

namespace gf {
namespace {

// A closed cube of side s centred at c (12 triangles, counter-clockwise from outside).
struct Cube {
  std::vector<glm::dvec3> v;
  std::vector<uint32_t> tri;
};
Cube cube(glm::dvec3 c, double s) {
  Cube k;
  for (int i = 0; i < 8; ++i)
    k.v.push_back(c + 0.5 * s * glm::dvec3(i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 1 : -1));
  // Faces as quads (outward), split in two.
  const int q[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                       {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : q)
    for (int t : {0, 2}) {
      k.tri.push_back(uint32_t(f[0]));
      k.tri.push_back(uint32_t(f[t == 0 ? 1 : 2]));
      k.tri.push_back(uint32_t(f[t == 0 ? 2 : 3]));
    }
  return k;
}

// A plate [0, 0.2] x [0, t] x [0, 0.2] m as a surface of 12 triangles (the top's and the
// bottom's diagonal run from x = z = 0 to x = z = 0.2), so which features a proxy meets is
// known exactly.
struct Plate {
  std::vector<float> positions;
  std::vector<uint32_t> indices;
  explicit Plate(double t) {
    const Cube box = cube({0.1, 0.5 * t, 0.1}, 1.0);
    for (const glm::dvec3& v : box.v) {
      positions.push_back(float(0.1 + 0.2 * (v.x - 0.1)));
      positions.push_back(float(0.5 * t + t * (v.y - 0.5 * t)));
      positions.push_back(float(0.1 + 0.2 * (v.z - 0.1)));
    }
    indices = box.tri;
  }
  SurfaceView surface() const {
    SurfaceView s;
    s.positions = positions;
    s.indices = indices;
    return s;
  }
};

std::vector<glm::dvec3> moved(const std::vector<glm::dvec3>& v, glm::dvec3 d) {
  std::vector<glm::dvec3> out = v;
  for (glm::dvec3& p : out) p += d;
  return out;
}

struct Trace {
  std::vector<double> fy;  // force on the proxy along y per sample
  double maxJump = 0;
  int maxContacts = 0;
};

// A 2 cm cube, a little turned so its corners arrive one by one, pressed straight down into a
// 1 cm plate at `speed` from 2 mm above, sampled at 1 kHz for `seconds`.
Trace press(bool continuous, double speed, double seconds, double k) {
  Plate plate(0.01);
  // Away from the plate's diagonal edges.
  const glm::dvec3 centre{0.15, 0.01 + 0.002 + 0.01, 0.06};
  Cube c = cube(centre, 0.02);
  const double a = 0.1;  // turn about z, then x, so no edge is parallel to the plate's
  for (glm::dvec3& p : c.v) {
    const glm::dvec3 r = p - centre;
    glm::dvec3 q{std::cos(a) * r.x - std::sin(a) * r.y, std::sin(a) * r.x + std::cos(a) * r.y, r.z};
    q = {q.x, std::cos(a) * q.y - std::sin(a) * q.z, std::sin(a) * q.y + std::cos(a) * q.z};
    p = centre + q;
  }
  HapticContactSettings s;
  s.stiffness = k;
  s.continuous = continuous;
  HapticContact h = HapticContact::create(c.v, c.tri, s).value();
  EXPECT_TRUE(h.setSurface(plate.surface(), 0).ok());
  const double dt = 1e-3;
  Trace tr;
  for (int i = 1; i <= int(std::lround(seconds / dt)); ++i) {
    const Result<glm::dvec3> f = h.sample(moved(c.v, {0, -speed * dt * i, 0}), dt);
    EXPECT_TRUE(f.ok());
    tr.fy.push_back(f.value().y);
    glm::dvec3 pushed(0.0);
    for (const HapticPush& p : h.pushes()) pushed += p.force;
    EXPECT_NEAR(glm::length(pushed + f.value()), 0.0, 1e-9 * (1 + glm::length(f.value())));
    tr.maxContacts = std::max(tr.maxContacts, h.contactCount());
    if (tr.fy.size() > 1)
      tr.maxJump = std::max(tr.maxJump, std::abs(tr.fy.back() - tr.fy[tr.fy.size() - 2]));
  }
  return tr;
}

// The proxy goes 14 mm down: past the plate's mid-plane (7 mm in) and, with its lowest corner,
// out of its bottom. Continuous: each contact's depth, averaged over a sample, changes by at
// most speed * dt between samples and starts from 0, so the force changes by at most
// k * speed * dt per contact alive in either sample. Discrete: past the mid-plane the nearest
// face of a corner is the bottom one, so its force turns round.
TEST(HapticContact, PressedIntoAThinPlateTheContinuousForceHasNoJump) {
  const double k = 2000, speed = 0.05, seconds = 0.32;
  const Trace ccd = press(true, speed, seconds, k);
  const Trace discrete = press(false, speed, seconds, k);
  const double bound = k * speed * 1e-3 * ccd.maxContacts;
  std::printf(
      "continuous: final %.4g N, max jump %.4g N (bound %.4g N, %d contacts); discrete: final "
      "%.4g N, max jump %.4g N\n",
      ccd.fy.back(), ccd.maxJump, bound, ccd.maxContacts, discrete.fy.back(), discrete.maxJump);
  // Continuous: always pushed back up, the way it came. Discrete: pulled through.
  EXPECT_GT(*std::min_element(ccd.fy.begin() + 60, ccd.fy.end()), 0);
  EXPECT_LT(*std::min_element(discrete.fy.begin(), discrete.fy.end()), 0);
  EXPECT_LE(ccd.maxJump, bound * (1 + 1e-9));
  EXPECT_GT(discrete.maxJump, 5 * ccd.maxJump);
}

// A proxy thrown through a 4 mm plate at 6 m/s moves 6 mm per sample: at no sample is a corner
// inside, so the discrete force never sees the plate; continuous collision does and pushes
// the proxy back.
TEST(HapticContact, AProxyPassingThroughBetweenSamplesIsCaught) {
  Plate plate(0.004);
  const Cube c = cube({0.15, 0.004 + 0.003 + 0.01, 0.06}, 0.02);
  for (bool continuous : {true, false}) {
    HapticContactSettings s;
    s.continuous = continuous;
    HapticContact h = HapticContact::create(c.v, c.tri, s).value();
    ASSERT_TRUE(h.setSurface(plate.surface(), 0).ok());
    // The bottom face goes from 3 mm above the plate to 3 mm below it.
    const glm::dvec3 f = h.sample(moved(c.v, {0, -0.010, 0}), 1e-3).value();
    std::printf("%s: %.4g N after passing through\n", continuous ? "continuous" : "discrete", f.y);
    if (continuous) {
      EXPECT_GT(f.y, 0);
      EXPECT_GE(h.contactCount(), 4);
    } else {
      EXPECT_EQ(f.y, 0);
    }
  }
}

// Held still at depth d after pressing in, the continuous force is k d per contact, straight
// up: the four bottom corners behind the top face (no edge of the plate crosses the cube).
TEST(HapticContact, HeldAtADepthTheForceIsThePenaltyOfEachContact) {
  Plate plate(0.02);
  // A 1 cm cube pressed 1.5 mm into the top.
  const Cube c = cube({0.15, 0.02 + 0.001 + 0.005, 0.06}, 0.01);
  const double k = 1000, d = 0.0015, dt = 1e-3;
  HapticContactSettings s;
  s.stiffness = k;
  HapticContact h = HapticContact::create(c.v, c.tri, s).value();
  ASSERT_TRUE(h.setSurface(plate.surface(), 0).ok());
  ASSERT_TRUE(h.sample(moved(c.v, {0, -0.001 - d, 0}), dt).ok());
  const glm::dvec3 held = h.sample(moved(c.v, {0, -0.001 - d, 0}), dt).value();
  std::printf("held at %.3g mm: %.6g N from %d contacts\n", 1e3 * d, held.y, h.contactCount());
  EXPECT_EQ(h.contactCount(), 4);
  // The plate's corners are floats: 0.02 is 4e-10 m off.
  EXPECT_NEAR(held.y, 4 * k * d, 1e-6 * 4 * k * d);
  EXPECT_NEAR(held.x, 0, 1e-9);
  EXPECT_NEAR(held.z, 0, 1e-9);
}

// The multi-rate loop of fig 7.4 on a real body's render surface: a soft block lifted by its
// gripped bottom at 1 cm/s (the top follows, oscillating) against a 2 cm cube lowered at 1 cm/s,
// sampled at 1 kHz while the world steps at 62.5 Hz (16 samples per step). Blending each new
// surface in over one step keeps every contact's depth changing by at most (proxy speed +
// surface speed) * dt per sample. Jumping to it within one sample finds the same contacts and
// ends at the same force, but the force jumps with the surface at every world step.
struct MultiRate {
  double maxJump = 0, bound = 0, finalForce = 0;
};
MultiRate pressRisingBlock(double blend) {
  World world(WorldDef{});
  BodyDef def;
  def.mesh = gen::box(0.1, 0.05, 0.1, 6, 3, 6);
  def.material = Material::stableNeoHookean(2e4, 0.3, 1000);
  def.grips.push_back({});
  for (size_t n = 0; n < def.mesh.nodeCount(); ++n)
    if (def.mesh.positions[3 * n + 1] < 1e-9) def.grips[0].nodes.push_back(int32_t(n));
  const BodyId id = world.createBody(def).value();
  EXPECT_TRUE(world.setGripVelocity(id, 0, {0, 0.01f, 0}).ok());
  const Cube c = cube({0.043, 0.05 + 0.001 + 0.01, 0.057}, 0.02);
  HapticContactSettings s;
  s.stiffness = 500;
  HapticContact h = HapticContact::create(c.v, c.tri, s).value();
  EXPECT_TRUE(h.setSurface(world.surface(id), blend).ok());
  const double dt = 1e-3, stepDt = 16 * dt, speed = 0.01;
  std::vector<float> before(world.surface(id).positions.begin(), world.surface(id).positions.end());
  MultiRate out;
  glm::dvec3 last(0.0);
  double surfaceSpeed = 0;
  int sample = 0, maxContacts = 0;
  for (int step = 0; step < 30; ++step) {
    for (int i = 0; i < 16; ++i) {
      ++sample;
      const glm::dvec3 f = h.sample(moved(c.v, {0, -speed * dt * sample, 0}), dt).value();
      if (sample > 1) out.maxJump = std::max(out.maxJump, glm::length(f - last));
      last = f;
      maxContacts = std::max(maxContacts, h.contactCount());
    }
    EXPECT_TRUE(world.step(stepDt).ok());
    const SurfaceView now = world.surface(id);
    for (size_t v = 0; v < now.positions.size() / 3; ++v) {
      const glm::dvec3 d(now.positions[3 * v] - before[3 * v],
                         now.positions[3 * v + 1] - before[3 * v + 1],
                         now.positions[3 * v + 2] - before[3 * v + 2]);
      surfaceSpeed = std::max(surfaceSpeed, glm::length(d) / stepDt);
    }
    before.assign(now.positions.begin(), now.positions.end());
    EXPECT_TRUE(h.setSurface(now, blend).ok());
  }
  out.bound = s.stiffness * (speed + surfaceSpeed) * dt * maxContacts;
  out.finalForce = last.y;
  std::printf(
      "blend %.3g s: final %.4g N, max jump %.4g N (bound %.4g N: %d contacts, surface "
      "up to %.3g m/s)\n",
      blend, last.y, out.maxJump, out.bound, maxContacts, surfaceSpeed);
  return out;
}

TEST(HapticContact, BlendingTheWorldSurfaceKeepsTheForceSmooth) {
  const MultiRate blended = pressRisingBlock(0.016), jumping = pressRisingBlock(0);
  EXPECT_GT(blended.finalForce, 0);
  EXPECT_LE(blended.maxJump, blended.bound);
  EXPECT_GT(jumping.maxJump, 2 * jumping.bound);
  EXPECT_GT(jumping.maxJump, 2 * blended.maxJump);
  EXPECT_NEAR(jumping.finalForce, blended.finalForce, 0.02 * blended.finalForce);
}

// The cut brush of thesis sec 7.2.3.6 (CutBrush): a flat brush (two triangles in the plane
// x = 5.2 cm, wider than the block) lowered at 2 cm/s into a frozen block (the thesis freezes
// it while marking, so the force can build), its penalty force sampled at 1 kHz. Below the
// threshold it cannot cut; from the first sample whose force passes it, cut() breaks exactly
// the edges the brush overlaps, those crossing its plane above its lower edge, and pressed
// 10 mm deeper it cuts again, down to the new depth.
TEST(CutBrush, CutsWhatItOverlapsOnceItsForcePassesTheThreshold) {
  WorldDef wd;
  wd.gravity = {0, 0, 0};
  World world(wd);
  BodyDef def;
  def.mesh = gen::box(0.1, 0.04, 0.1, 8, 4, 8);
  def.fracture.enabled = true;
  def.fracture.strength = 1e9;  // only the cut breaks edges
  const BodyId id = world.createBody(def).value();
  const double x = 0.052, top = 0.04;
  std::vector<glm::dvec3> brush = {{x, top + 0.005, -0.02},
                                   {x, top + 0.005, 0.12},
                                   {x, top + 0.03, 0.12},
                                   {x, top + 0.03, -0.02}};
  const std::vector<uint32_t> tri = {0, 1, 2, 0, 2, 3};
  CutBrushSettings s;
  s.contact.stiffness = 200;
  s.threshold = 20;
  CutBrush cutter = CutBrush::create(brush, tri, s).value();
  ASSERT_TRUE(cutter.setSurface(world.surface(id), 0).ok());
  const double speed = 0.02, dt = 1e-3;
  const std::vector<double>& rest = def.mesh.positions;
  const std::span<const int32_t> edges = world.edges(id);
  // Broken edges against those crossing the plane x above height `lowest`.
  const auto checkCut = [&](double lowest) {
    int cut = 0;
    const std::span<const uint8_t> broken = world.brokenEdges(id);
    for (size_t e = 0; e < broken.size(); ++e) {
      const size_t a = size_t(edges[2 * e]), b = size_t(edges[2 * e + 1]);
      const double xa = rest[3 * a] - x, xb = rest[3 * b] - x;
      bool over = false;
      if ((xa < 0) != (xb < 0)) {
        const double t = xa / (xa - xb);
        over = rest[3 * a + 1] + t * (rest[3 * b + 1] - rest[3 * a + 1]) > float(lowest);
      }
      cut += broken[e] != 0;
      EXPECT_EQ(broken[e] != 0, over) << "edge " << e << " below " << lowest;
    }
    return cut;
  };
  const auto press = [&](double depth) {
    for (glm::dvec3& p : brush) p.y -= depth;
    return glm::length(cutter.sample(brush, dt).value());
  };
  double last = 0;
  int samples = 0;
  for (; samples < 2000; ++samples) {
    const double f = press(speed * dt);
    EXPECT_GE(f, last - 1e-9) << samples;  // pressing deeper never pushes back less
    if (f < s.threshold) {
      EXPECT_FALSE(cutter.cutting());
      // Below the threshold the brush cannot cut, and the world is left as it was.
      if (samples % 100 == 0) {
        EXPECT_FALSE(cutter.cut(world, id).ok());
      }
    }
    last = f;
    if (cutter.cutting()) break;
  }
  ASSERT_LT(samples, 2000);
  EXPECT_GE(last, s.threshold);
  const double first = brush[0].y;
  std::printf("cut brush: %.4g N at %.2f mm deep after %d samples\n", last, 1e3 * (top - first),
              samples + 1);
  EXPECT_GT(top - first, 0.0);
  ASSERT_TRUE(world.step(1e-3).ok());
  EXPECT_EQ(world.fractureStats(id).brokenEdges, 0);  // the failed calls queued nothing
  ASSERT_TRUE(cutter.cut(world, id).ok());
  ASSERT_TRUE(world.step(1e-3).ok());
  const int cut1 = checkCut(first);
  // 10 mm deeper, past the next layer of nodes (y = 30 mm; the edges between the layers cross
  // its plane at 38.4 mm): the brush is still over the threshold and cuts what it overlaps now.
  for (int k = 0; k < 500; ++k) press(speed * dt);
  ASSERT_TRUE(cutter.cutting());
  ASSERT_TRUE(cutter.setSurface(world.surface(id), 0).ok());
  ASSERT_TRUE(cutter.cut(world, id).ok());
  ASSERT_TRUE(world.step(1e-3).ok());
  const int cut2 = checkCut(brush[0].y);
  std::printf("cut brush: %d edges cut at %.2f mm, %d at %.2f mm\n", cut1, 1e3 * (top - first),
              cut2, 1e3 * (top - brush[0].y));
  EXPECT_GT(cut1, 0);
  EXPECT_GT(cut2, cut1);
}

TEST(CutBrush, BadInputIsAClearErrorAndChangesNothing) {
  const std::vector<glm::dvec3> v = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const std::vector<uint32_t> tri = {0, 1, 2};
  for (double t : {0.0, -1.0, double(NAN), double(INFINITY)}) {
    CutBrushSettings s;
    s.threshold = t;
    const Result<CutBrush> r = CutBrush::create(v, tri, s);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("threshold"), std::string::npos);
  }
  CutBrushSettings s;
  s.contact.stiffness = 0;
  Result<CutBrush> r = CutBrush::create(v, tri, s);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("stiffness"), std::string::npos);
  const std::vector<uint32_t> bad = {0, 1, 3};
  EXPECT_FALSE(CutBrush::create(v, bad, {}).ok());
}

TEST(HapticContact, BadInputIsAClearErrorAndChangesNothing) {
  const Cube c = cube({0, 0, 0}, 0.01);
  HapticContactSettings bad;
  bad.stiffness = -1;
  Result<HapticContact> r = HapticContact::create(c.v, c.tri, bad);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("stiffness"), std::string::npos);
  std::vector<uint32_t> tri = c.tri;
  tri[5] = 8;
  r = HapticContact::create(c.v, tri, {});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("index 5"), std::string::npos);
  HapticContact h = HapticContact::create(c.v, c.tri, {}).value();
  EXPECT_FALSE(h.sample(c.v, 0).ok());
  std::vector<glm::dvec3> v = c.v;
  v[3].x = NAN;
  const Result<glm::dvec3> f = h.sample(v, 1e-3);
  ASSERT_FALSE(f.ok());
  EXPECT_NE(f.error().message.find("vertex 3"), std::string::npos);
  EXPECT_FALSE(h.sample({v.begin(), v.begin() + 4}, 1e-3).ok());
  Plate plate(0.01);
  EXPECT_FALSE(h.setSurface(plate.surface(), -1).ok());
  EXPECT_FALSE(h.setSurface(SurfaceView{}, 0).ok());
}

}  // namespace
}  // namespace gf
