// The stability suite (issue 19 item 2): every material model x both damage models x every
// linear solver x each backend, over the abuse cases a game throws at a fracture simulator:
// stiff steel at game time steps, nearly incompressible material, inverted and sliver elements
// in the rest mesh, a 100 m/s impact, every edge broken at once and a 300 m/s shot at a thin
// plate. Every case asserts, after every step:
//  - a finite state (positions and velocities);
//  - total energy (kinetic + elastic + gravity + contact) never above E0 + W + tol, where E0 is
//    the energy after set-up and W the work put in by grips and colliders. Every grip here is a
//    pin and every collider static, so W = 0: the bound is the energy the body starts with.
//    Backward Euler with a line search on the incremental potential, and breaking an edge, can
//    only take energy out; tol (per case, kTightTol or kContactTol below) covers round-off and
//    the penalty contact's energy exchange within a step;
//  - a truthful status: a flagged step carries a message; a step not flagged kStepNotConverged
//    reports a linear residual within SolverSettings::linearTolerance; no step needs the NaN
//    rollback (kStepNanContained), which would freeze the body rather than simulate it.
// Default (CI): a representative subset, every case with every solver, the materials and damage
// models rotating over the cases; GF_FULL_VALIDATION=1 runs every combination. The others are
// skipped, with the reason. Results and the reproducing commands: docs/RESULTS.md, "Stability
// suite".
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <ostream>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "common/beams.h"
#include "common/sim_helpers.h"

namespace gf {
namespace {

enum class Case {
  SteelDt5ms,
  SteelDt50ms,
  Nu049,
  Nu04999,
  InvertedRestTets,
  SliverRestTets,
  Impact100,
  AllEdgesCut,
  AllEdgesZeroStrength,
  Thrown300ThroughPlate,
};
constexpr Case kCases[] = {
    Case::SteelDt5ms,           Case::SteelDt50ms,          Case::Nu049,     Case::Nu04999,
    Case::InvertedRestTets,     Case::SliverRestTets,       Case::Impact100, Case::AllEdgesCut,
    Case::AllEdgesZeroStrength, Case::Thrown300ThroughPlate};

const char* caseName(Case c) {
  switch (c) {
    case Case::SteelDt5ms:
      return "SteelDt5ms";
    case Case::SteelDt50ms:
      return "SteelDt50ms";
    case Case::Nu049:
      return "Nu0p49";
    case Case::Nu04999:
      return "Nu0p4999";
    case Case::InvertedRestTets:
      return "InvertedRestTets";
    case Case::SliverRestTets:
      return "SliverRestTets";
    case Case::Impact100:
      return "Impact100mps";
    case Case::AllEdgesCut:
      return "AllEdgesCut";
    case Case::AllEdgesZeroStrength:
      return "AllEdgesZeroStrength";
    case Case::Thrown300ThroughPlate:
      return "Thrown300mpsThroughPlate";
  }
  return "?";
}

const char* materialName(MaterialModel m) {
  switch (m) {
    case MaterialModel::Corotated:
      return "Corotated";
    case MaterialModel::StVK:
      return "StVK";
    case MaterialModel::NeoHookean:
      return "NeoHookean";
    case MaterialModel::StableNeoHookean:
      return "StableNeoHookean";
  }
  return "?";
}

const char* solverName(LinearSolverKind s) {
  switch (s) {
    case LinearSolverKind::Direct:
      return "Direct";
    case LinearSolverKind::PCG:
      return "PCG";
    case LinearSolverKind::Multigrid:
      return "Multigrid";
  }
  return "?";
}

Material makeMaterial(MaterialModel m, double E, double nu, double rho) {
  switch (m) {
    case MaterialModel::Corotated:
      return Material::corotated(E, nu, rho);
    case MaterialModel::StVK:
      return Material::stvk(E, nu, rho);
    case MaterialModel::NeoHookean:
      return Material::neoHookean(E, nu, rho);
    case MaterialModel::StableNeoHookean:
      return Material::stableNeoHookean(E, nu, rho);
  }
  return {};
}

constexpr MaterialModel kMaterials[] = {MaterialModel::Corotated, MaterialModel::StVK,
                                        MaterialModel::NeoHookean, MaterialModel::StableNeoHookean};
constexpr DamageModel kDamage[] = {DamageModel::Projection, DamageModel::Degradation};
constexpr LinearSolverKind kSolvers[] = {LinearSolverKind::Direct, LinearSolverKind::PCG,
                                         LinearSolverKind::Multigrid};

// Energy tolerances. Without contact every step's backward Euler with line search cannot raise
// the incremental potential, so only round-off is allowed. A penalty collider exchanges energy
// with the body within a step (its stiffness is picked per step, and the contact energy of the
// accepted positions is a linearisation's), so contact cases get 0.1 % of E0, the bound the
// existing stiff-case tests use (tests/physics/test_stiff.cpp).
constexpr double kTightTol = 1e-6;
constexpr double kContactTol = 1e-3;

void translate(TetMesh& m, double x, double y, double z) {
  for (size_t n = 0; n < m.nodeCount(); ++n) {
    m.positions[3 * n] += x;
    m.positions[3 * n + 1] += y;
    m.positions[3 * n + 2] += z;
  }
}

// A blade of axis-aligned planes between every pair of neighbouring node layers of a
// gen::box grid: every edge of the Kuhn split joins nodes one layer apart along at least one
// axis, so it crosses one of the planes, and no node lies on a plane.
Blade everyEdgeBlade(double sx, double sy, double sz, int nx, int ny, int nz) {
  Blade b;
  const double pad = 0.5 * std::max({sx, sy, sz});
  auto quad = [&b](glm::vec3 a, glm::vec3 c, glm::vec3 d, glm::vec3 e) {
    const uint32_t base = uint32_t(b.vertices.size());
    b.vertices.insert(b.vertices.end(), {a, c, d, e});
    b.triangles.insert(b.triangles.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
  };
  const float lo = float(-pad);
  for (int i = 0; i < nx; ++i) {
    const float x = float((i + 0.5) * sx / nx), hy = float(sy + pad), hz = float(sz + pad);
    quad({x, lo, lo}, {x, hy, lo}, {x, hy, hz}, {x, lo, hz});
  }
  for (int j = 0; j < ny; ++j) {
    const float y = float((j + 0.5) * sy / ny), hx = float(sx + pad), hz = float(sz + pad);
    quad({lo, y, lo}, {hx, y, lo}, {hx, y, hz}, {lo, y, hz});
  }
  for (int k = 0; k < nz; ++k) {
    const float z = float((k + 0.5) * sz / nz), hx = float(sx + pad), hy = float(sy + pad);
    quad({lo, lo, z}, {hx, lo, z}, {hx, hy, z}, {lo, hy, z});
  }
  return b;
}

using Param = std::tuple<Case, MaterialModel, DamageModel, LinearSolverKind, Backend>;

bool fullValidation() {
  const char* v = std::getenv("GF_FULL_VALIDATION");
  return v && std::strcmp(v, "1") == 0;
}

// The reduced form: each case with each solver once, the material and damage model rotating
// with (case + solver) so that every material meets every damage model and every solver over
// the cases; about 30 runs that fit CI's budget.
// Combinations that once failed are kept in it too: the projection-damaged beams of
// InvertedRestTets and SliverRestTets gained up to 0.76 J over E0 = 4.9 J after the closed-crack
// retry of issue 19 changed their path (Integrator::solve, kModelAgreement).
bool inReducedForm(const Param& p) {
  const int c = int(std::get<0>(p)), m = int(std::get<1>(p)), d = int(std::get<2>(p)),
            s = int(std::get<3>(p));
  const std::tuple<Case, MaterialModel, DamageModel, LinearSolverKind> regressions[] = {
      {Case::InvertedRestTets, MaterialModel::StVK, DamageModel::Projection,
       LinearSolverKind::Multigrid},
      {Case::SliverRestTets, MaterialModel::Corotated, DamageModel::Projection,
       LinearSolverKind::Direct}};
  for (const auto& [rc, rm, rd, rs] : regressions)
    if (std::get<0>(p) == rc && std::get<1>(p) == rm && std::get<2>(p) == rd &&
        std::get<3>(p) == rs)
      return true;
  const int k = c + s;
  return m == k % 4 && d == (k / 4) % 2;
}

// One scene: the world, the body, the steps, and what the case checks beyond the common rules.
struct Scene {
  WorldDef world{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}};
  BodyDef body;
  double dt = 1.0 / 60;
  int steps = 60;
  double energyTol = kTightTol;
  /// A known failure of the physical rules (knownFailure): reported, not failed.
  bool knownToFail = false;
};

// Combinations that break a physical rule today (the energy bound, or for Impact100mps the
// ground), measured with this file (docs/RESULTS.md, "Stability suite"). They run and are
// checked like the others: a violation of those rules is reported as a skip that says
// "KNOWN FAILURE" and why (GF_STABILITY_STRICT=1 makes it a failure), and every other rule
// (finite state, no rollback, truthful status) still fails them. None is left.
// Fixed: the nu = 0.49 StVK degradation run (+21 E0), whose needle-like fragments took I^-1 L of
// a near-singular inertia (kThinAxis, fem/rigid_stage.h; ShatteredBlocks below is its family);
// the nu = 0.4999 StVK projection multigrid run (+7.8 E0), whose shattered block's turned
// Newton start pressed it into the ground (a cracked body's piece so pressed is now stepped by
// plain backward Euler: Integrator::predictRigidMotion; ShatteredBlocks.Projection* below is its
// family); and the projection damage failures of the steel beam, the nearly incompressible
// blocks and the 100 m/s impact (kernels/damage.h; Integrator::groupPieces and solve).
bool knownFailure(Case, MaterialModel, DamageModel) { return false; }

bool strict() {
  const char* v = std::getenv("GF_STABILITY_STRICT");
  return v && std::strcmp(v, "1") == 0;
}

using test::clampedBeam;

class Stability : public ::testing::TestWithParam<Param> {
 protected:
  MaterialModel material() const { return std::get<1>(GetParam()); }

  // Material, damage model and solver of this combination on a body; multigrid is kept at
  // every size (these bodies are below the default directBelowNodes, which would otherwise
  // hand them to the direct solver and test it twice).
  void apply(BodyDef& def, double E, double nu, double rho, double strength) const {
    def.material = makeMaterial(material(), E, nu, rho);
    def.fracture.enabled = true;
    def.fracture.strength = strength;
    def.fracture.model = std::get<2>(GetParam());
    def.solver.linearSolver = std::get<3>(GetParam());
    def.solver.multigrid.directBelowNodes = 0;
  }

  // A world for the backend under test; skips when it cannot run here (the reason is the
  // world's own words).
  bool makeWorld(const Scene& s, std::unique_ptr<World>& world, BodyId& id) {
    WorldDef wd = s.world;
    wd.backend = std::get<4>(GetParam());
    world = std::make_unique<World>(wd);
    Result<BodyId> r = world->createBody(s.body);
    if (!r.ok() && wd.backend == Backend::Cuda) {
      m_skipReason = r.error().message;
      return false;
    }
    EXPECT_TRUE(r.ok()) << r.error().message;
    if (!r.ok()) return false;
    id = r.value();
    return true;
  }

  struct Run {
    double e0 = 0, maxExcess = -1e300;  // max over steps of E - E0 [J]
    uint32_t flags = 0;
    int flaggedSteps = 0, rolledBack = 0, notConverged = 0;
    double worstResidual = 0;  // of the steps not flagged kStepNotConverged
    std::string firstMessage;
    std::string energyViolation;  // the first step over the energy bound, in words
  };

  // Steps the world, checking the common rules after every step. Each rule fails the test
  // once, at the first step that breaks it, so a diverging run names its first bad step
  // instead of flooding the log; report() prints the worst values.
  Run runChecked(World& world, BodyId id, const Scene& s) {
    Run r;
    r.e0 = test::totalEnergy(world.stats(id));
    const double tol = s.body.solver.linearTolerance;
    const double bound = r.e0 + s.energyTol * std::abs(r.e0) + 1e-9;
    bool silentStep = false, rollback = false, invalid = false, residual = false, energy = false;
    for (int i = 0; i < s.steps; ++i) {
      const int brokenBefore = world.fractureStats(id).brokenEdges;
      const double elasticBefore = world.stats(id).elasticEnergy;
      const std::vector<double> xBefore(world.positions(id).begin(), world.positions(id).end());
      const StepStatus st = world.step(s.dt);
      r.flags |= st.flags;
      if (!st.ok()) {
        ++r.flaggedSteps;
        if (r.firstMessage.empty()) r.firstMessage = st.message;
        if (st.message.empty() && !std::exchange(silentStep, true))
          ADD_FAILURE() << "step " << i << ": flags " << st.flags << " without a message";
      }
      r.rolledBack += st.has(kStepNanContained);
      r.notConverged += st.has(kStepNotConverged);
      if (st.has(kStepNanContained) && !std::exchange(rollback, true))
        ADD_FAILURE() << "step " << i << " diverged and was rolled back: " << st.message;
      if (st.has(kStepInvalidInput) && !std::exchange(invalid, true))
        ADD_FAILURE() << "step " << i << " was rejected: " << st.message;
      if (!st.has(kStepNotConverged) && !st.has(kStepNanContained)) {
        r.worstResidual = std::max(r.worstResidual, st.residual);
        if (!(st.residual <= tol) && !std::exchange(residual, true))
          ADD_FAILURE() << "step " << i << " is not flagged kStepNotConverged but its residual "
                        << st.residual << " is above the solver's tolerance " << tol;
      }
      if (!test::stateFinite(world, id)) {
        ADD_FAILURE() << "non-finite state after step " << i;
        return r;
      }
      const double e = test::totalEnergy(world.stats(id));
      r.maxExcess = std::max(r.maxExcess, e - r.e0);
      if (!(e <= bound) && !std::exchange(energy, true)) {
        // What the step's damage change alone did: the elastic energy at the step's starting
        // positions with the damage after it, against the same before it (the world is put
        // back from a snapshot, so the run goes on unchanged).
        const WorldSnapshot after = world.snapshot();
        const bool moved = world.setPositions(id, xBefore).ok();
        const double damageJump = world.stats(id).elasticEnergy - elasticBefore;
        EXPECT_TRUE(world.restore(after).ok());
        std::ostringstream why;
        why << "step " << i << ": energy " << e << " J above what was put in (E0 " << r.e0
            << " J, tolerance " << s.energyTol
            << " E0); edges broken in this step: " << world.fractureEvents().size()
            << ", before it: " << brokenBefore;
        if (moved)
          why << "; the damage change alone, at the step's starting positions, changed the "
              << "elastic energy by " << damageJump << " J";
        r.energyViolation = why.str();
        physicalRule(s, r.energyViolation);
      }
    }
    return r;
  }

  void report(const Run& r, World& world, BodyId id, double ms) const {
    const FractureStats fs = world.fractureStats(id);
    std::printf(
        "stability %s: E0 %.4e J, max(E - E0) %+.3e J (%+.2e E0), flags %u on %d steps "
        "(%d not converged, %d rolled back), worst unflagged residual %.1e, broken %d/%d, "
        "fragments %d, %.0f ms%s%s\n",
        name().c_str(), r.e0, r.maxExcess, r.e0 != 0 ? r.maxExcess / std::abs(r.e0) : 0.0, r.flags,
        r.flaggedSteps, r.notConverged, r.rolledBack, r.worstResidual, fs.brokenEdges, fs.edgeCount,
        fs.fragments, ms,
        r.firstMessage.empty() ? "" : "; first message: ", r.firstMessage.c_str());
  }

  // The same figures as properties of the test, for the GF_STABILITY_CSV rows (below).
  void recordFigures(const Run& r, World& world, BodyId id, double ms) const {
    const FractureStats fs = world.fractureStats(id);
    auto num = [](double v) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.6g", v);
      return std::string(buf);
    };
    RecordProperty("e0_J", num(r.e0));
    RecordProperty("max_excess_J", num(r.maxExcess));
    RecordProperty("max_excess_over_e0", num(r.e0 != 0 ? r.maxExcess / std::abs(r.e0) : 0.0));
    RecordProperty("flags", int(r.flags));
    RecordProperty("flagged_steps", r.flaggedSteps);
    RecordProperty("not_converged", r.notConverged);
    RecordProperty("rolled_back", r.rolledBack);
    RecordProperty("broken_edges", fs.brokenEdges);
    RecordProperty("edges", fs.edgeCount);
    RecordProperty("fragments", fs.fragments);
    RecordProperty("ms", num(ms));
  }

  std::string name() const {
    return ::testing::UnitTest::GetInstance()->current_test_info()->name();
  }

  // A broken physical rule (energy bound, ground): a failure, or for a known failure
  // (knownFailure) noted for the skip that ends the test.
  void physicalRule(const Scene& s, const std::string& why) {
    if (!s.knownToFail || strict())
      ADD_FAILURE() << why;
    else
      m_known += (m_known.empty() ? "" : "; ") + why;
  }

  std::string m_skipReason, m_known;
};

TEST_P(Stability, Case) {
  if (!fullValidation() && !inReducedForm(GetParam()))
    GTEST_SKIP() << "not in the reduced form; GF_FULL_VALIDATION=1 runs every combination";
  const auto t0 = std::chrono::steady_clock::now();
  const Case c = std::get<0>(GetParam());
  Scene s;
  // Reference run for InvertedRestTets: the same body with every tet ordered correctly.
  Scene reference;
  bool compareWithReference = false;
  switch (c) {
    case Case::SteelDt5ms:
    case Case::SteelDt50ms: {
      // A clamped 1 m steel cantilever (E 2e11, rho 7850) under gravity. Its root's bending
      // stress is about 2.3 MPa in theory, less in the elements of a 2-cell-high beam; a
      // strength of 0.5 MPa makes it crack at the clamp, so both damage models act on a stiff
      // body.
      s.body = clampedBeam(Material{}, 20, 2);
      apply(s.body, 2e11, 0.3, 7850, 5e5);
      s.dt = c == Case::SteelDt5ms ? 5e-3 : 5e-2;
      s.steps = c == Case::SteelDt5ms ? 100 : 40;
      break;
    }
    case Case::Nu049:
    case Case::Nu04999: {
      // A nearly incompressible block hitting the ground at 5 m/s: the impact stress (about
      // E v / c = 1.6e5 Pa) is three times the strength, so it cracks while volume locking is
      // worst.
      s.body.mesh = gen::box(0.2, 0.2, 0.2, 3, 3, 3);
      translate(s.body.mesh, 0, 0.01, 0);
      apply(s.body, 1e6, c == Case::Nu049 ? 0.49 : 0.4999, 1000, 1e4);
      s.body.initialVelocity = glm::vec3(0, -5, 0);
      s.world.colliders.push_back(Collider{});  // ground plane y = 0
      s.energyTol = kContactTol;
      break;
    }
    case Case::InvertedRestTets: {
      // validate() documents that tets given with a negative orientation are reordered (two
      // nodes swapped) and run; a degenerate one is rejected. So a beam whose every other tet
      // is listed inverted must run as the correctly ordered beam does.
      reference.body = clampedBeam(Material{}, 10, 2);
      apply(reference.body, 1e7, 0.3, 1000, 5e4);
      // The two bodies differ in round-off only, which PCG stopping at its default relative
      // residual of 1e-6 turns into micrometres once a crack sits at its open/closed switch
      // (projection damage: 5e-6 m); both solve to a residual the comparison can resolve.
      reference.body.solver.linearTolerance = 1e-10;
      reference.body.solver.maxLinearIterations = 2000;
      reference.steps = 60;
      s = reference;
      for (size_t e = 0; e < s.body.mesh.tetCount(); e += 2)
        std::swap(s.body.mesh.tets[4 * e], s.body.mesh.tets[4 * e + 1]);
      compareWithReference = true;
      break;
    }
    case Case::SliverRestTets: {
      // The x = 0.9 layer of a clamped beam moved to 10 um from the tip: the last layer of
      // tets has 1e-4 of a regular one's volume (above validate()'s zero-volume threshold of
      // 1e-12 L^3), which ruins the conditioning.
      s.body = clampedBeam(Material{}, 10, 2);
      for (size_t n = 0; n < s.body.mesh.nodeCount(); ++n) {
        double& x = s.body.mesh.positions[3 * n];
        if (std::abs(x - 0.9) < 1e-9) x = 1.0 - 1e-5;
      }
      apply(s.body, 1e7, 0.3, 1000, 5e4);
      // Squashed flat, the same layer makes tets of zero volume: rejected at creation, naming
      // the mesh, the element and the reason, and the world is unchanged.
      BodyDef flat = s.body;
      for (size_t n = 0; n < flat.mesh.nodeCount(); ++n) {
        double& x = flat.mesh.positions[3 * n];
        if (std::abs(x - (1.0 - 1e-5)) < 1e-12) x = 1.0 - 1e-14;
      }
      World probe(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
      const Result<BodyId> rejected = probe.createBody(flat);
      ASSERT_FALSE(rejected.ok());
      EXPECT_NE(rejected.error().message.find("BodyDef.mesh: element "), std::string::npos)
          << rejected.error().message;
      EXPECT_NE(rejected.error().message.find("zero volume"), std::string::npos)
          << rejected.error().message;
      break;
    }
    case Case::Impact100: {
      // A 30 cm block at 100 m/s into the ground.
      s.body.mesh = gen::box(0.3, 0.3, 0.3, 3, 3, 3);
      translate(s.body.mesh, 0, 0.5, 0);
      apply(s.body, 1e7, 0.4, 1000, 2e4);
      s.body.initialVelocity = glm::vec3(0, -100, 0);
      s.world.colliders.push_back(Collider{});
      s.energyTol = kContactTol;
      break;
    }
    case Case::AllEdgesCut:
    case Case::AllEdgesZeroStrength: {
      // A block in free flight, stretched by 5 % (elastic energy to release) and spinning. Either
      // a cut through every edge or strengths of ~0 (every edge of a dilated body is in
      // tension) break every edge in one step: each node becomes its own fragment.
      s.body.mesh = gen::box(0.2, 0.2, 0.2, 3, 3, 3);
      apply(s.body, 1e6, 0.3, 1000, 1e5);
      s.steps = 30;
      break;
    }
    case Case::Thrown300ThroughPlate: {
      // A 10 cm block thrown at 300 m/s (5 m per step at 60 Hz) at a 1 cm plate.
      s.body.mesh = gen::box(0.1, 0.1, 0.1, 2, 2, 2);
      translate(s.body.mesh, -1.0, 0, 0);
      apply(s.body, 1e7, 0.3, 1000, 1e5);
      s.body.initialVelocity = glm::vec3(300, 0, 0);
      Collider plate;
      plate.kind = Collider::Kind::Box;
      plate.point = {0, 0.05f, 0.05f};
      plate.halfExtents = {0.005f, 1, 1};
      s.world.colliders.push_back(plate);
      s.world.gravity = glm::vec3(0);
      s.steps = 30;
      s.energyTol = kContactTol;
      break;
    }
  }

  std::unique_ptr<World> world;
  BodyId id;
  if (!makeWorld(s, world, id)) {
    if (!m_skipReason.empty()) GTEST_SKIP() << m_skipReason;
    return;
  }

  if (c == Case::AllEdgesCut || c == Case::AllEdgesZeroStrength) {
    std::vector<double> x(world->positions(id).begin(), world->positions(id).end());
    for (double& v : x) v = 0.1 + 1.05 * (v - 0.1);
    ASSERT_TRUE(world->setPositions(id, x).ok());
    std::vector<double> v(x.size());
    for (size_t n = 0; n < x.size() / 3; ++n) {  // 2 m/s up, 10 rad/s about z
      v[3 * n] = -10 * (x[3 * n + 1] - 0.1);
      v[3 * n + 1] = 2 + 10 * (x[3 * n] - 0.1);
      v[3 * n + 2] = 0;
    }
    ASSERT_TRUE(world->setVelocities(id, v).ok());
    if (c == Case::AllEdgesCut) {
      ASSERT_TRUE(world->cut(id, everyEdgeBlade(0.21, 0.21, 0.21, 3, 3, 3)).ok());
    } else {
      const std::vector<double> tiny(size_t(world->fractureStats(id).edgeCount), 1e-6);
      ASSERT_TRUE(world->setEdgeStrengths(id, tiny).ok());
    }
  }

  s.knownToFail = knownFailure(c, material(), std::get<2>(GetParam()));
  const Run r = runChecked(*world, id, s);
  const FractureStats fs = world->fractureStats(id);
  if (c == Case::AllEdgesCut || c == Case::AllEdgesZeroStrength) {
    EXPECT_EQ(fs.brokenEdges, fs.edgeCount);
    EXPECT_EQ(size_t(fs.fragments), s.body.mesh.nodeCount());
  }
  if (c == Case::Thrown300ThroughPlate) {
    // No node may end past the plate's far face (x = 0.005), nor keep flying on towards +x.
    const auto x = world->positions(id);
    const auto v = world->velocities(id);
    double farthest = -1e300, meanVx = 0;
    for (size_t n = 0; n < x.size() / 3; ++n) {
      farthest = std::max(farthest, x[3 * n]);
      meanVx += v[3 * n] / double(x.size() / 3);
    }
    EXPECT_LT(farthest, 0.005) << "a node passed through the plate";
    EXPECT_LE(meanVx, 1.0) << "the body keeps flying towards the plate's far side";
    EXPECT_TRUE(r.flags & kStepContactSwept) << "a 5 m step through a 1 cm plate must be swept";
  }
  if (c == Case::Impact100) {
    double lowest = 1e300;
    const auto x = world->positions(id);
    for (size_t n = 0; n < x.size() / 3; ++n) lowest = std::min(lowest, x[3 * n + 1]);
    if (!(lowest > -0.05))
      physicalRule(s, "the block went through the ground: lowest node at y = " +
                          std::to_string(lowest) + " m");
  }
  if (compareWithReference) {
    // The reordered tets give the same element quantities up to round-off, so the body must
    // end where the correctly ordered one does, 1 um on a beam that sags by centimetres, or
    // where that one ends from a start moved by round-off: a crack at its open/closed switch
    // can take either branch (NeoHookean, projection, direct: rest positions scaled by
    // 1 + 1e-15, 2e-15 or 3e-15 end 6.2e-6 m from the unscaled run, by 1 - 1e-15, 1 - 2e-15
    // or 1 +- 5e-15 within 6e-8 m).
    double best = 1e300;
    int bestBroken = -1;
    for (double eps : {0.0, 1e-15, -1e-15, 2e-15, -2e-15}) {
      Scene ref = reference;
      for (size_t k = 0; k < ref.body.mesh.positions.size(); ++k)
        ref.body.mesh.positions[k] *= 1 + eps * double(int(k % 3) - 1);
      std::unique_ptr<World> refWorld;
      BodyId refId;
      ASSERT_TRUE(makeWorld(ref, refWorld, refId));
      for (int i = 0; i < ref.steps; ++i) (void)refWorld->step(ref.dt);
      const auto a = world->positions(id), b = refWorld->positions(refId);
      double worst = 0;
      for (size_t i = 0; i < a.size(); ++i) worst = std::max(worst, std::abs(a[i] - b[i]));
      std::printf(
          "stability %s: largest difference from the correctly ordered body (start "
          "scaled by 1 %+.0e) %.2e m\n",
          name().c_str(), eps, worst);
      if (worst < best) {
        best = worst;
        bestBroken = refWorld->fractureStats(refId).brokenEdges;
      }
      if (best < 1e-6) break;
    }
    EXPECT_LT(best, 1e-6) << "reordered tets do not run as the correctly ordered body";
    EXPECT_EQ(fs.brokenEdges, bestBroken);
  }
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  report(r, *world, id, ms);
  recordFigures(r, *world, id, ms);
  if (!m_known.empty() && !HasFailure())
    GTEST_SKIP() << "KNOWN FAILURE (docs/RESULTS.md, Stability suite): " << m_known;
}

// GF_STABILITY_CSV=FILE writes one row per run of the matrix to FILE: its verdict (passed,
// known_failure, skipped, failed), gtest's message and the figures recordFigures() attached.
// `graphfrac report all` builds docs/RESULTS.md's stability table from it. The report cannot
// link these cases (they are gtest fixtures) and a case list shared through a library would
// still need gtest's verdicts, so the report runs this binary and reads the file; a listener
// writes the rows because only it sees the final verdict, skips and failures included. Rows are
// flushed one by one, so a run that dies leaves the rows before it.
class CsvRows : public ::testing::EmptyTestEventListener {
 public:
  explicit CsvRows(std::FILE* f) : m_file(f) {
    std::fputs(
        "test,case,material,damage,solver,backend,outcome,e0_J,max_excess_J,max_excess_over_e0,"
        "flags,flagged_steps,not_converged,rolled_back,broken_edges,edges,fragments,ms,message\n",
        m_file);
    std::fflush(m_file);
  }
  ~CsvRows() override { std::fclose(m_file); }

  void OnTestEnd(const ::testing::TestInfo& info) override {
    if (std::strcmp(info.test_suite_name(), "Matrix/Stability") != 0) return;
    const ::testing::TestResult& r = *info.result();
    std::string message;
    for (int i = 0; i < r.total_part_count() && message.empty(); ++i)
      if (r.GetTestPartResult(i).failed() || r.GetTestPartResult(i).skipped())
        message = r.GetTestPartResult(i).message();
    const char* outcome = r.Failed()                                           ? "failed"
                          : !r.Skipped()                                       ? "passed"
                          : message.find("KNOWN FAILURE") != std::string::npos ? "known_failure"
                                                                               : "skipped";
    // The parameter part of the name: CASE_MATERIAL_DAMAGE_SOLVER_BACKEND, no '_' inside them.
    std::string name = info.name();
    name = name.substr(name.find('/') + 1);
    std::string fields = name;
    std::replace(fields.begin(), fields.end(), '_', ',');
    std::fprintf(m_file, "%s,%s,%s", name.c_str(), fields.c_str(), outcome);
    for (const char* key :
         {"e0_J", "max_excess_J", "max_excess_over_e0", "flags", "flagged_steps", "not_converged",
          "rolled_back", "broken_edges", "edges", "fragments", "ms"}) {
      std::string value;
      for (int i = 0; i < r.test_property_count(); ++i)
        if (std::strcmp(r.GetTestProperty(i).key(), key) == 0) value = r.GetTestProperty(i).value();
      std::fprintf(m_file, ",%s", value.c_str());
    }
    // Quoted: messages hold commas; a quote inside is doubled, line breaks become blanks.
    std::string quoted = "\"";
    for (char ch : message) {
      if (ch == '"') quoted += '"';
      quoted += ch == '\n' ? ' ' : ch;
    }
    std::fprintf(m_file, ",%s\"\n", quoted.c_str());
    std::fflush(m_file);
  }

 private:
  std::FILE* m_file;
};

bool installCsvRows() {
  const char* path = std::getenv("GF_STABILITY_CSV");
  if (!path || !*path) return false;
  std::FILE* f = std::fopen(path, "w");
  if (!f) {
    std::fprintf(stderr, "GF_STABILITY_CSV: cannot write %s\n", path);
    std::exit(2);
  }
  ::testing::UnitTest::GetInstance()->listeners().Append(new CsvRows(f));
  return true;
}
[[maybe_unused]] const bool kCsvRowsInstalled = installCsvRows();

// gtest prints a parameter's enums as raw bytes (ctest's test list shows them); words instead.
void PrintTo(Case c, std::ostream* os) { *os << caseName(c); }

std::string paramName(const ::testing::TestParamInfo<Param>& info) {
  const auto& [c, m, d, s, b] = info.param;
  return std::string(caseName(c)) + "_" + materialName(m) + "_" +
         (d == DamageModel::Projection ? "Projection" : "Degradation") + "_" + solverName(s) + "_" +
         (b == Backend::Cpu ? "Cpu" : "Cuda");
}

INSTANTIATE_TEST_SUITE_P(Matrix, Stability,
                         ::testing::Combine(::testing::ValuesIn(kCases),
                                            ::testing::ValuesIn(kMaterials),
                                            ::testing::ValuesIn(kDamage),
                                            ::testing::ValuesIn(kSolvers),
                                            ::testing::Values(Backend::Cpu, Backend::Cuda)),
                         paramName);

// A 20 cm block dropped on the ground at `speed` and run for a second: the largest rise of its
// energy above the start's, and its fragments at the end.
struct DroppedBlock {
  double excess = -1e300;
  int32_t fragments = 0;
};

DroppedBlock dropBlock(MaterialModel m, double nu, double strength, DamageModel model,
                       LinearSolverKind solver, double speed, double dt, double* e0) {
  WorldDef wd{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}};
  wd.colliders.push_back(Collider{});  // ground plane y = 0
  World world(wd);
  BodyDef def;
  def.mesh = gen::box(0.2, 0.2, 0.2, 3, 3, 3);
  translate(def.mesh, 0, 0.01, 0);
  def.material = makeMaterial(m, 1e6, nu, 1000);
  def.fracture.enabled = true;
  def.fracture.strength = strength;
  def.fracture.model = model;
  def.solver.linearSolver = solver;
  def.solver.multigrid.directBelowNodes = 0;  // multigrid at this size too
  def.initialVelocity = glm::vec3(0, float(-speed), 0);
  const Result<BodyId> id = world.createBody(def);
  EXPECT_TRUE(id.ok()) << id.error().message;
  DroppedBlock r;
  if (!id.ok()) return r;
  *e0 = test::totalEnergy(world.stats(id.value()));
  for (int i = 0; i < int(1.0 / dt); ++i) {
    (void)world.step(dt);
    r.excess = std::max(r.excess, test::totalEnergy(world.stats(id.value())) - *e0);
  }
  r.fragments = world.fractureStats(id.value()).fragments;
  return r;
}

// The family of the Nu0p49 StVK failure: a block shattered on the ground leaves needle-like
// fragments (nodes nearly on one line), whose turning frame once took I^-1 L of a near-singular
// inertia and spun them up to thousands of rad/s (kThinAxis, fem/rigid_stage.h; before the fix
// two of these runs gained 21 and 25 E0). Every material, two Poisson ratios, strengths, impact
// speeds and time steps, degradation damage (the one that leaves free fragments); the energy may
// never rise above the start's beyond the contact tolerance. One run (StVK, nu 0.49, 2e3 Pa,
// 5 m/s, dt 1/60) gained 0.30 E0 until a cracked body's piece that its turn presses into the
// ground was stepped by plain backward Euler (Integrator::predictRigidMotion).
TEST(ShatteredBlocks, FragmentsNeverGainEnergy) {
  int runs = 0, shattered = 0;
  double worst = -1e300;
  for (MaterialModel m : kMaterials)
    for (double nu : {0.3, 0.49})
      for (double strength : {2e3, 1e4})
        for (double speed : {5.0, 10.0})
          for (double dt : {1.0 / 60, 1.0 / 120}) {
            double e0 = 0;
            const DroppedBlock r = dropBlock(m, nu, strength, DamageModel::Degradation,
                                             LinearSolverKind::Direct, speed, dt, &e0);
            EXPECT_LE(r.excess, kContactTol * e0)
                << materialName(m) << ", nu " << nu << ", strength " << strength << " Pa, " << speed
                << " m/s, dt " << dt << ": max(E - E0) " << r.excess / e0 << " E0";
            worst = std::max(worst, r.excess / e0);
            ++runs;
            shattered += r.fragments >= 8;
          }
  std::printf("shattered blocks: %d runs, %d in 8 or more fragments, max(E - E0) %+.2e E0\n", runs,
              shattered, worst);
  EXPECT_GE(shattered, runs / 3);  // the family is about shattered bodies (24 of 64 today)
}

// The family of the Nu0p4999 failure: with projection damage the fragments that share damaged
// tets turn as one piece (Integrator::groupPieces), a heap of rubble whose I^-1 L is no rigid
// spin, and its turn about the centre pressed it into the ground (2.7 J of penalty energy where
// x_n had 6e-4 J); one Newton step only lowers the potential from where it starts, and the
// contact impulses spun the heap up (+7.8 E0). Every material and linear solver at nu 0.4999,
// 5 and 10 m/s, dt 1/60; GF_FULL_VALIDATION=1 adds nu 0.3 and 0.49 and dt 1/120 (144 runs).
// Before the fix 3 of the 24 reduced runs gained up to 7.8 E0 (10 of the 144, up to 7.8 E0);
// starting the pressed heap from x_n with its turned inertia target instead gained 8.8 E0.
TEST(ShatteredBlocks, ProjectionPiecesNeverGainEnergy) {
  int runs = 0, shattered = 0;
  double worst = -1e300;
  const std::vector<double> nus =
      fullValidation() ? std::vector<double>{0.3, 0.49, 0.4999} : std::vector<double>{0.4999};
  const std::vector<double> dts =
      fullValidation() ? std::vector<double>{1.0 / 60, 1.0 / 120} : std::vector<double>{1.0 / 60};
  for (MaterialModel m : kMaterials)
    for (double nu : nus)
      for (LinearSolverKind solver : kSolvers)
        for (double speed : {5.0, 10.0})
          for (double dt : dts) {
            double e0 = 0;
            const DroppedBlock r =
                dropBlock(m, nu, 1e4, DamageModel::Projection, solver, speed, dt, &e0);
            EXPECT_LE(r.excess, kContactTol * e0)
                << materialName(m) << ", nu " << nu << ", " << solverName(solver) << ", " << speed
                << " m/s, dt " << dt << ": max(E - E0) " << r.excess / e0 << " E0";
            worst = std::max(worst, r.excess / e0);
            ++runs;
            shattered += r.fragments >= 8;
          }
  std::printf(
      "shattered projection blocks: %d runs, %d in 8 or more fragments, max(E - E0) %+.2e E0\n",
      runs, shattered, worst);
  EXPECT_GE(shattered, runs / 3);  // about shattered bodies
}

// The family of the InvertedRestTets and SliverRestTets projection failures (issue 19): a
// clamped beam that cracks at its root under gravity, with projection damage. Its fragments'
// cracks close within a step, and a single Newton step built on the open crack's softness
// overshoots into the closed crack's stiffness while still lowering the incremental potential:
// the beam's energy rose by up to 3.9 J in one step (0.76 J above E0) without a broken edge.
// Every material and linear solver, two resolutions and three time steps; no pin or collider does
// work, so the energy may never rise above the start's beyond round-off. CI runs every material
// with the direct solver at dt 1/60 and 1/120 on the 10-cell beam; GF_FULL_VALIDATION=1 adds the
// iterative solvers, dt 1/30 and the 14-cell beam.
TEST(ProjectionBeams, CrackedBeamNeverGainsEnergy) {
  const bool full = fullValidation();
  const std::vector<LinearSolverKind> solvers =
      full ? std::vector<LinearSolverKind>(std::begin(kSolvers), std::end(kSolvers))
           : std::vector<LinearSolverKind>{LinearSolverKind::Direct};
  const std::vector<double> dts = full ? std::vector<double>{1.0 / 30, 1.0 / 60, 1.0 / 120}
                                       : std::vector<double>{1.0 / 60, 1.0 / 120};
  const std::vector<int> cells = full ? std::vector<int>{10, 14} : std::vector<int>{10};
  int runs = 0, cracked = 0;
  double worst = -1e300;
  for (MaterialModel m : kMaterials)
    for (LinearSolverKind solver : solvers)
      for (double dt : dts)
        for (int nx : cells) {
          BodyDef def = clampedBeam(makeMaterial(m, 1e7, 0.3, 1000), nx, 2);
          def.fracture.enabled = true;
          def.fracture.strength = 5e4;
          def.fracture.model = DamageModel::Projection;
          def.solver.linearSolver = solver;
          def.solver.multigrid.directBelowNodes = 0;
          World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
          const Result<BodyId> id = world.createBody(def);
          ASSERT_TRUE(id.ok()) << id.error().message;
          const double e0 = test::totalEnergy(world.stats(id.value()));
          double excess = -1e300;
          for (int i = 0; i < int(std::lround(1.0 / dt)); ++i) {
            (void)world.step(dt);
            excess = std::max(excess, test::totalEnergy(world.stats(id.value())) - e0);
          }
          EXPECT_LE(excess, kTightTol * e0 + 1e-9)
              << materialName(m) << ", " << solverName(solver) << ", dt " << dt << ", " << nx
              << " cells: max(E - E0) " << excess << " J of E0 " << e0 << " J";
          worst = std::max(worst, excess / e0);
          ++runs;
          cracked += world.fractureStats(id.value()).fragments >= 2;
        }
  std::printf(
      "cracked projection beams: %d runs, %d in 2 or more fragments, max(E - E0) %+.2e E0\n", runs,
      cracked, worst);
  EXPECT_EQ(cracked, runs);  // about cracked beams
}

}  // namespace

// In namespace gf, where argument-dependent lookup finds them for the public enums.
void PrintTo(MaterialModel m, std::ostream* os) { *os << materialName(m); }
void PrintTo(DamageModel d, std::ostream* os) {
  *os << (d == DamageModel::Projection ? "Projection" : "Degradation");
}
void PrintTo(LinearSolverKind s, std::ostream* os) { *os << solverName(s); }
void PrintTo(Backend b, std::ostream* os) { *os << (b == Backend::Cpu ? "Cpu" : "Cuda"); }

}  // namespace gf
