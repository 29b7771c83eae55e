// Severed edges (docs/design.md "Severed edges"): in the degradation model an unbroken edge whose
// every tet is split carries nothing, so it breaks in the batch that split its last tet, whatever
// broke it: the criterion, a blade, a pre-cut or a brittle plane (FractureSettings::
// releaseEveryBatch, on by default) — except, in a blade or pre-cut batch, an edge between two
// nodes with no whole tet that no unbroken edge joins to a node with one: a slice the blades cut
// out thinner than a cell stays one fragment. Checked against a replay on the rest mesh that
// applies each batch's breaks that were not releases (the events' order gives the batches) and
// the rule after each; the fragments are the pieces over unbroken edges, the chips those with
// no whole tet.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <map>
#include <numeric>
#include <string>
#include <vector>

#include "common/impurity_bar.h"
#include "common/render_mesh_checks.h"
#include "graphfrac/mesh.h"
#include "graphfrac/world.h"

namespace gf {
namespace {

// Union-find over nodes.
struct Pieces {
  std::vector<int32_t> parent;
  explicit Pieces(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int32_t find(int32_t a) {
    while (parent[size_t(a)] != a) a = parent[size_t(a)] = parent[size_t(parent[size_t(a)])];
    return a;
  }
  void join(int32_t a, int32_t b) { parent[size_t(find(a))] = find(b); }
};

struct Replay {
  int released = 0;    // edges broken by the replay's releases
  int mismatched = 0;  // edges whose broken flag differs from the world's
  int chips = 0;       // fragments with no whole tet
  int looseNodes = 0;  // of them, one node alone
  bool sameFragments = false;
};

// The rest mesh's edges and their tets, with the replay's broken flags.
struct ReplayMesh {
  std::vector<int32_t> ends;                  // 2 per edge, the world's edge ids
  std::vector<std::vector<int32_t>> tetsOf;   // per edge
  std::vector<std::array<int32_t, 6>> edges;  // per tet, in (01, 02, 03, 12, 13, 23) order
  std::vector<std::vector<int32_t>> edgesOf;  // per node
  std::vector<uint8_t> broken;
  int released = 0;

  ReplayMesh(const World& world, BodyId id, const TetMesh& mesh) {
    const std::span<const int32_t> e = world.edges(id);
    ends.assign(e.begin(), e.end());
    std::map<std::pair<int32_t, int32_t>, int32_t> edgeOf;
    edgesOf.resize(mesh.nodeCount());
    for (size_t k = 0; k < ends.size() / 2; ++k) {
      edgeOf[{std::min(ends[2 * k], ends[2 * k + 1]), std::max(ends[2 * k], ends[2 * k + 1])}] =
          int32_t(k);
      edgesOf[size_t(ends[2 * k])].push_back(int32_t(k));
      edgesOf[size_t(ends[2 * k + 1])].push_back(int32_t(k));
    }
    tetsOf.resize(ends.size() / 2);
    broken.assign(ends.size() / 2, 0);
    edges.resize(mesh.tetCount());
    for (size_t t = 0; t < mesh.tetCount(); ++t) {
      const int32_t* n = &mesh.tets[4 * t];
      int k = 0;
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b, ++k) {
          edges[t][size_t(k)] = edgeOf.at({std::min(n[a], n[b]), std::max(n[a], n[b])});
          tetsOf[size_t(edges[t][size_t(k)])].push_back(int32_t(t));
        }
    }
  }
  // Corners that no unbroken edge of the tet joins (the rule after eq 4.33).
  bool split(size_t t) const {
    int32_t local[4] = {0, 1, 2, 3};
    auto root = [&](int32_t k) {
      while (local[k] != k) k = local[k];
      return k;
    };
    int k = 0;
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b, ++k)
        if (!broken[size_t(edges[t][size_t(k)])]) local[root(a)] = root(b);
    for (int c = 1; c < 4; ++c)
      if (root(c) != root(0)) return true;
    return false;
  }
  bool whole(int32_t node, const std::vector<uint8_t>& tetSplit) const {
    for (int32_t e : edgesOf[size_t(node)])
      for (int32_t t : tetsOf[size_t(e)])
        if (!tetSplit[size_t(t)]) return true;
    return false;
  }
  // One batch: its breaks that were not releases, then the release rule over the whole mesh.
  void batch(const std::vector<int32_t>& primary, bool keepSlices) {
    for (int32_t e : primary) broken[size_t(e)] = 1;
    std::vector<uint8_t> tetSplit(edges.size());
    for (size_t t = 0; t < edges.size(); ++t) tetSplit[t] = split(t) ? 1 : 0;
    const size_t nn = edgesOf.size();
    std::vector<uint8_t> inSlice(nn, 0);
    for (size_t n = 0; n < nn; ++n) {
      if (whole(int32_t(n), tetSplit)) continue;
      bool touches = false;
      for (int32_t e : edgesOf[n]) {
        const int32_t other =
            ends[2 * size_t(e)] == int32_t(n) ? ends[2 * size_t(e) + 1] : ends[2 * size_t(e)];
        touches = touches || (!broken[size_t(e)] && whole(other, tetSplit));
      }
      inSlice[n] = touches ? 0 : 1;
    }
    std::vector<int32_t> release;
    for (size_t e = 0; e < tetsOf.size(); ++e) {
      if (broken[e]) continue;
      bool all = true;
      for (int32_t t : tetsOf[e]) all = all && tetSplit[size_t(t)];
      if (!all) continue;
      if (keepSlices && inSlice[size_t(ends[2 * e])] && inSlice[size_t(ends[2 * e + 1])]) continue;
      release.push_back(int32_t(e));
    }
    for (int32_t e : release) broken[size_t(e)] = 1;
    released += int(release.size());
  }

  // Compares the replay with the world's broken flags, fragments and chips.
  Replay compare(const World& world, BodyId id) const {
    Replay r;
    r.released = released;
    const std::span<const uint8_t> b = world.brokenEdges(id);
    for (size_t e = 0; e < broken.size(); ++e) r.mismatched += (b[e] != 0) != (broken[e] != 0);
    const size_t nn = edgesOf.size();
    Pieces pieces(nn);
    for (size_t e = 0; e < broken.size(); ++e)
      if (!broken[e]) pieces.join(ends[2 * e], ends[2 * e + 1]);
    std::map<int32_t, int> size;
    std::map<int32_t, bool> held;
    for (size_t n = 0; n < nn; ++n) {
      ++size[pieces.find(int32_t(n))];
      held[pieces.find(int32_t(n))] = false;
    }
    for (size_t t = 0; t < edges.size(); ++t)
      if (!split(t)) held[pieces.find(ends[2 * size_t(edges[t][0])])] = true;
    for (const auto& [root, h] : held) {
      r.chips += h ? 0 : 1;
      r.looseNodes += !h && size.at(root) == 1 ? 1 : 0;
    }
    // The same partition: the world's fragment ids and the replay's roots correspond one to one.
    const std::span<const int32_t> fragment = world.nodeFragments(id);
    std::map<int32_t, int32_t> toRoot, toFragment;
    r.sameFragments = true;
    for (size_t n = 0; n < nn; ++n) {
      const int32_t root = pieces.find(int32_t(n));
      const auto a = toRoot.emplace(fragment[n], root).first;
      const auto c = toFragment.emplace(root, fragment[n]).first;
      r.sameFragments = r.sameFragments && a->second == root && c->second == fragment[n];
    }
    return r;
  }
};

// Steps the world (cutting blades[s] before step s, when given) and replays each step. A step
// cuts before the criterion and the brittle planes break (FractureBody::detect), and at most one
// blade is cut a step here, so its batches are: the blade's or pre-cut's breaks, then the
// others; releases without keepSlices are a function of the broken flags alone, so the
// criterion's and the planes' batches replay as one.
void stepAndReplay(World& world, BodyId id, const TetMesh& mesh, int steps, double dt,
                   const char* what, const std::vector<Blade>& blades = {},
                   bool mustRelease = true) {
  ReplayMesh replay(world, id, mesh);
  int severed = 0;
  Replay last;
  for (int s = 0; s < steps; ++s) {
    if (size_t(s) < blades.size()) {
      ASSERT_TRUE(world.cut(id, blades[size_t(s)]).ok());
    }
    (void)world.step(dt);
    std::vector<int32_t> cut, other;
    for (const FractureEvent& ev : world.fractureEvents()) {
      if (ev.cause == FractureEvent::Cause::Severed) {
        ++severed;
      } else {
        (ev.cause == FractureEvent::Cause::Cut ? cut : other).push_back(ev.edge);
      }
    }
    if (!cut.empty()) replay.batch(cut, true);
    if (!other.empty()) replay.batch(other, false);
    last = replay.compare(world, id);
    ASSERT_EQ(last.mismatched, 0) << what << ", step " << s;
    ASSERT_TRUE(last.sameFragments) << what << ", step " << s;
    ASSERT_EQ(world.fractureStats(id).chips, last.chips) << what << ", step " << s;
  }
  std::printf(
      "%s: %d broken edges, %d released (%d severed events), %d fragments, %d of them chips "
      "(%d loose nodes)\n",
      what, world.fractureStats(id).brokenEdges, last.released, severed,
      world.fractureStats(id).fragments, last.chips, last.looseNodes);
  // The case meets the rule: it releases edges, or keeps a slice (a chip of several nodes).
  if (mustRelease) {
    EXPECT_GT(last.released + last.chips - last.looseNodes, 0) << what;
  }
  EXPECT_EQ(severed, last.released) << what;
}

// Blades through a box, in the family of cuts that sever edges: two parallel planes a cell
// apart (the nodes between them lose every tet), the same pair oblique to the cells, and five
// planes crossing in one body (pieces, and chips where they cross).
std::vector<Blade> bladePlanes(int which) {
  const auto plane = [](glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d) {
    Blade blade;
    blade.vertices = {a, b, c, d};
    blade.triangles = {0, 1, 2, 0, 2, 3};
    return blade;
  };
  const auto across = [&](float x0, float x1, float x2, float x3) {
    return plane({x0, -1, -1}, {x1, 1, -1}, {x2, 1, 1}, {x3, -1, 1});
  };
  if (which == 0) return {across(0.17f, 0.17f, 0.17f, 0.17f), across(0.23f, 0.23f, 0.23f, 0.23f)};
  if (which == 1) return {across(0.07f, 0.27f, 0.29f, 0.09f), across(0.13f, 0.33f, 0.35f, 0.15f)};
  return {across(0.12f, 0.14f, 0.13f, 0.11f), across(0.28f, 0.29f, 0.31f, 0.27f),
          plane({-1, 0.04f, -1}, {1, 0.06f, -1}, {1, 0.05f, 1}, {-1, 0.03f, 1}),
          plane({-1, 0.15f, -1}, {1, 0.16f, -1}, {1, 0.14f, 1}, {-1, 0.13f, 1}),
          plane({-1, -1, 0.1f}, {1, -1, 0.09f}, {1, 1, 0.11f}, {-1, 1, 0.1f})};
}
// The box the blades cut: strong enough that the blades alone break edges.
BodyDef bladeBox(bool release) {
  BodyDef def;
  def.mesh = gen::box(0.4, 0.2, 0.2, 8, 4, 4);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  def.fracture.enabled = true;
  def.fracture.strength = 1e9;
  def.fracture.releaseEveryBatch = release;
  return def;
}
const char* const kBladeCases[] = {"two parallel blades", "two oblique parallel blades",
                                   "five crossing blades"};

TEST(SeveredEdges, BladeCutsReleaseSeveredEdgesIntoSeparateFragments) {
  for (int which = 0; which < 3; ++which) {
    const std::vector<Blade> blades = bladePlanes(which);
    const char* what = kBladeCases[which];
    BodyDef def = bladeBox(false);
    EXPECT_TRUE(BodyDef().fracture.releaseEveryBatch);  // on by default
    {
      // Off: a blade's severed edges stay unbroken.
      World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
      const BodyId id = world.createBody(def).value();
      for (const Blade& b : blades) ASSERT_TRUE(world.cut(id, b).ok());
      int severed = 0;
      for (int s = 0; s < 3; ++s) {
        (void)world.step(1e-3);
        for (const FractureEvent& ev : world.fractureEvents())
          severed += ev.cause == FractureEvent::Cause::Severed ? 1 : 0;
      }
      EXPECT_EQ(severed, 0) << what;
    }
    def.fracture.releaseEveryBatch = true;
    World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
    const BodyId id = world.createBody(def).value();
    stepAndReplay(world, id, def.mesh, int(blades.size()) + 1, 1e-3, what, blades);
  }
}

// Potency-0 impurity lines (sharp pre-cuts, sec 5.4) across the impurity bar.
TEST(SeveredEdges, PreCutReleasesSeveredEdges) {
  BodyDef def = test::impurityTensionBar({});
  for (Grip& g : def.grips) g.velocity = glm::vec3(0);
  def.fracture.releaseEveryBatch = true;
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(def).value();
  ImpurityMap cut;
  cut.kind = ImpurityMap::Kind::Image;
  // Two lines 0.06 m apart across the bar (cells of 0.05 m), oblique to the cells.
  cut.segments = {{-0.5, 0.06}, {0.5, 0.09}, {-0.5, -0.06}, {0.5, -0.03}};
  cut.origin = {0.5, 0.05, 0.05};
  cut.rotation = glm::angleAxis(0.5 * 3.14159265358979, glm::dvec3(0, 0, 1));
  cut.scale = 0.5;
  cut.potency = 0;
  ASSERT_TRUE(world.applyImpurityMap(id, cut).ok());
  stepAndReplay(world, id, def.mesh, 3, 1e-2, "pre-cut");
}

// Brittle planes (sec 4.5.1.2) start when the criterion first fires and split tets the
// criterion's own releases did not see; later stress breaks release as before. The brittle bar
// of the render-mesh tests, pulled apart, and the same bar with one and with twelve regions.
TEST(SeveredEdges, BrittlePlanesReleaseSeveredEdges) {
  for (int regions : {1, 6, 12}) {
    BodyDef def = test::brittleBar();
    def.renderMesh.reset();
    def.fracture.regions = regions;
    def.fracture.releaseEveryBatch = true;
    World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
    const BodyId id = world.createBody(def).value();
    const std::string what = "brittle bar, " + std::to_string(regions) + " regions";
    // Several planes release little or nothing now: the nodes they left with no whole tet go
    // to a piece (keepNodesInPieces), and the edges that freed them are Severed events of the
    // planes' batch, which the replay's rule must release too. One plane and the criterion's
    // breaks after it still do.
    stepAndReplay(world, id, def.mesh, 25, 1.0 / 60, what.c_str(), {}, regions == 1);
  }
}

// A chip (a fragment that holds no whole tet: a loose node, or a slice the blades cut out
// thinner than a cell) is free matter with no volume of its own, so the render mesh draws its cells
// with the neighbours that share its tets. Blades cut a box with a render mesh of another
// resolution into pieces and chips; at rest every drawn fragment is closed and 2-manifold, none is
// a chip, and the fragments' signed volumes add up to the render box's (caps between two fragments
// cancel; drawn on their own, the chips' cycles met at junctions and left cores uncovered).
// Slices only: where more than three pieces meet, the flat junction caps leave cores
// uncovered whatever the chips (docs/design.md, "Triple junctions").
TEST(SeveredEdges, ChipsAreDrawnByTheirNeighbours) {
  for (int c = 0; c < 2; ++c) {
    BodyDef def = bladeBox(true);
    def.renderMesh = test::boxSurface(glm::dvec3(0), glm::dvec3(0.4, 0.2, 0.2), 13, 7, 7);
    World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
    const BodyId id = world.createBody(def).value();
    for (const Blade& b : bladePlanes(c)) ASSERT_TRUE(world.cut(id, b).ok());
    (void)world.step(1e-3);
    (void)world.surface(id);
    const std::span<const uint8_t> chip = world.chipFlags(id);
    const int chips = int(std::count(chip.begin(), chip.end(), uint8_t(1)));
    const SurfaceView sv = world.surface(id);
    int open = 0, drawnChips = 0;
    const auto closed = test::closure(sv);
    for (const auto& [f, fc] : closed) {
      open += fc.openEdges;
      drawnChips += chip[size_t(f)];
    }
    double volume = 0;
    for (const auto& [f, v] : test::enclosedVolumes(sv)) volume += v;
    const double want = 0.4 * 0.2 * 0.2;
    const test::Coverage cov = test::coverage(sv, glm::dvec3(0), glm::dvec3(0.4, 0.2, 0.2), 60);
    std::printf(
        "%s: %zu fragments, %d of them chips, %zu drawn (%d chips), %d open edges; "
        "volume %.8g m^3 against %.8g (%.2e relative); covered by none %.3g, twice %.3g of it\n",
        kBladeCases[c], chip.size(), chips, closed.size(), drawnChips, open, volume, want,
        (volume - want) / want, cov.gap / want, cov.overlap / want);
    EXPECT_GT(chips, 0);
    EXPECT_EQ(drawnChips, 0);
    EXPECT_EQ(open, 0);
    EXPECT_NEAR(volume, want, 1e-6 * want);
  }
}

// Once every piece of a cut body has gone to rigid physics, what is left free are its chips: no
// tet can store energy, so each chip node is a particle (the body's step solves them node by
// node). Checked against backward Euler's free fall (v' = v + dt g, x' = x + dt v', exact for
// a node with no force but gravity) and then against a plane the chips land and stay on, for
// each blade case and each linear solver; the detached pieces move exactly as prescribed.
TEST(SeveredEdges, ChipsLeftAloneFallAsParticlesAndLandOnAPlane) {
  const double dt = 1e-3, g = double(-9.81f), floor = -0.05;  // g as WorldDef holds it
  const LinearSolverKind solvers[] = {LinearSolverKind::Direct, LinearSolverKind::Multigrid,
                                      LinearSolverKind::PCG};
  for (int which = 0; which < 3; ++which)
    for (LinearSolverKind solver : solvers) {
      const std::string what =
          std::string(kBladeCases[which]) + ", solver " + std::to_string(int(solver));
      BodyDef def = bladeBox(true);
      def.solver.linearSolver = solver;
      Collider plane;
      plane.point = glm::vec3(0, float(floor), 0);
      WorldDef wd{glm::vec3(0, float(g), 0), Backend::Cpu, nullptr, 1, {plane}};
      World world(wd);
      const BodyId id = world.createBody(def).value();
      for (const Blade& b : bladePlanes(which)) ASSERT_TRUE(world.cut(id, b).ok());
      ASSERT_EQ(world.step(dt).flags, 0u) << what;
      const std::span<const uint8_t> chip = world.chipFlags(id);
      const FractureStats fs = world.fractureStats(id);
      ASSERT_EQ(chip.size(), size_t(fs.fragments)) << what;
      ASSERT_EQ(int(std::count(chip.begin(), chip.end(), uint8_t(1))), fs.chips) << what;
      ASSERT_GT(fs.chips, 0) << what;
      ASSERT_GT(fs.fragments - fs.chips, 1) << what;
      for (int32_t f = 0; f < fs.fragments; ++f)
        ASSERT_TRUE(chip[size_t(f)] || world.detachFragment(id, f).ok()) << what << ", " << f;

      // Free fall: 20 steps, the chips 4 cm above the plane at least.
      const std::vector<int32_t> fragment(world.nodeFragments(id).begin(),
                                          world.nodeFragments(id).end());
      std::vector<double> x(world.positions(id).begin(), world.positions(id).end());
      std::vector<double> v(world.velocities(id).begin(), world.velocities(id).end());
      const std::vector<double> vPiece = v;
      double worst = 0, worstPiece = 0;
      for (int s = 0; s < 20; ++s) {
        ASSERT_EQ(world.step(dt).flags, 0u) << what << ", step " << s;
        const std::span<const double> xs = world.positions(id), vs = world.velocities(id);
        for (size_t n = 0; n < fragment.size(); ++n)
          for (int i = 0; i < 3; ++i) {
            const size_t k = 3 * n + size_t(i);
            if (chip[size_t(fragment[n])]) {
              v[k] += i == 1 ? dt * g : 0.0;
              x[k] += dt * v[k];
              worst = std::max({worst, std::abs(xs[k] - x[k]), dt * std::abs(vs[k] - v[k])});
            } else {
              x[k] += dt * vPiece[k];
              worstPiece = std::max(worstPiece, std::abs(xs[k] - x[k]));
            }
          }
      }
      EXPECT_LT(worst, 1e-12) << what;
      EXPECT_LT(worstPiece, 1e-12) << what;

      // The chips reach the plane (a 5 cm fall takes 0.1 s) and rest on it.
      for (int s = 0; s < 300; ++s) ASSERT_EQ(world.step(dt).flags, 0u) << what;
      const std::span<const double> xs = world.positions(id), vs = world.velocities(id);
      double lowest = 1, fastest = 0;
      for (size_t n = 0; n < fragment.size(); ++n) {
        if (!chip[size_t(fragment[n])]) continue;
        lowest = std::min(lowest, xs[3 * n + 1]);
        fastest = std::max(fastest, std::abs(vs[3 * n + 1]));
      }
      std::printf(
          "%s: %d chips, free fall off by %.2e m, on the plane lowest %.3e m below it, "
          "fastest %.2e m/s\n",
          what.c_str(), fs.chips, worst, floor - lowest, fastest);
      EXPECT_GT(lowest, floor - 1e-3) << what;
      EXPECT_LT(lowest, floor + 1e-3) << what;
      EXPECT_LT(fastest, 1e-3) << what;
    }
}

}  // namespace
}  // namespace gf
