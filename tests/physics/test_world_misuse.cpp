// Misuse of the engine API: invalid definitions, absurd values, foreign snapshots, time steps
// that make the solve diverge and bodies too large for the machine. Each must give an error
// that names the field and leave the world as it was, never a crash or a non-finite state.
#include <graphfrac/jobs.h>
#include <gtest/gtest.h>
#include <malloc.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <string>

#include "common/sim_helpers.h"
#include "fem/fem_body.h"

namespace gf {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

BodyDef cube() {
  BodyDef def;
  def.mesh = gen::box(0.2, 0.2, 0.2, 3, 3, 3);
  def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
  return def;
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// One bad WorldDef per field: the world refuses to run, naming the field, from createBody and
// from every step, and WorldDef::check says the same up front.
TEST(WorldMisuse, InvalidWorldDefRefusesToRun) {
  struct Case {
    const char* field;
    WorldDef def;
  };
  std::vector<Case> cases;
  auto add = [&](const char* field, auto change) {
    WorldDef d;
    change(d);
    cases.push_back({field, d});
  };
  add("WorldDef.substeps", [](WorldDef& d) { d.substeps = 0; });
  add("WorldDef.contactSweeps", [](WorldDef& d) { d.contactSweeps = 0; });
  add("WorldDef.contactSweeps", [](WorldDef& d) { d.contactSweeps = 65; });
  add("WorldDef.gravity", [](WorldDef& d) { d.gravity.y = float(kInf); });
  add("WorldDef.backend", [](WorldDef& d) { d.backend = static_cast<Backend>(7); });
  add("WorldDef.colliders[1].stiffness", [](WorldDef& d) {
    d.colliders.resize(2);
    d.colliders[1].stiffness = kInf;  // made colliderImpulses() NaN before it was checked
  });
  add("WorldDef.colliders[0].kind", [](WorldDef& d) {
    d.colliders.resize(1);
    d.colliders[0].kind = static_cast<Collider::Kind>(9);
  });
  add("WorldDef.colliders[0].velocity", [](WorldDef& d) {
    d.colliders.resize(1);
    d.colliders[0].velocity.x = 1e30f;
  });
  for (const Case& c : cases) {
    const Result<void> checked = c.def.check();
    ASSERT_FALSE(checked.ok()) << c.field;
    EXPECT_TRUE(contains(checked.error().message, c.field)) << checked.error().message;
    World world(c.def);
    const Result<BodyId> body = world.createBody(cube());
    ASSERT_FALSE(body.ok()) << c.field;
    EXPECT_TRUE(contains(body.error().message, c.field)) << body.error().message;
    const StepStatus st = world.step(0.01);
    EXPECT_TRUE(st.has(kStepInvalidInput)) << c.field;
    EXPECT_TRUE(contains(st.message, c.field)) << st.message;
    EXPECT_EQ(world.time(), 0.0);
  }
  EXPECT_TRUE(WorldDef{}.check().ok());
}

// Backend::Cuda is a valid def; where it cannot run (no CUDA in the build, no driver, no device:
// this machine) the world refuses to run, saying why, and Auto and Cpu run on the CPU and say
// so. Where it runs: tests/backend/test_world_backend.cpp.
TEST(WorldMisuse, CudaBackendThatCannotRunRefusesToRun) {
  WorldDef def;
  def.backend = Backend::Cuda;
  EXPECT_TRUE(def.check().ok());
  World cuda(def);
  if (cuda.backend() == Backend::Cuda)
    GTEST_SKIP() << "it runs here: " << cuda.backendDescription();
  const Result<BodyId> body = cuda.createBody(cube());
  ASSERT_FALSE(body.ok());
  EXPECT_TRUE(contains(body.error().message, "WorldDef.backend: Cuda cannot run: "))
      << body.error().message;
  const StepStatus st = cuda.step(0.01);
  EXPECT_TRUE(st.has(kStepInvalidInput));
  EXPECT_TRUE(contains(st.message, "WorldDef.backend")) << st.message;
  EXPECT_EQ(cuda.time(), 0.0);
  for (Backend b : {Backend::Auto, Backend::Cpu}) {
    def.backend = b;
    World world(def);
    EXPECT_EQ(world.backend(), Backend::Cpu);
    EXPECT_EQ(world.backendDescription().rfind("cpu: ", 0), 0u) << world.backendDescription();
    std::printf("  Backend::%s: %s\n", b == Backend::Auto ? "Auto" : "Cpu",
                world.backendDescription().c_str());
    EXPECT_TRUE(world.createBody(cube()).ok());
  }
}

// World::setColliders and a WorldDef judge colliders by the same rule.
TEST(WorldMisuse, CollidersAreCheckedAlikeEverywhere) {
  std::vector<Collider> bad(10);
  bad[0].stiffness = kInf;
  bad[1].stiffness = -1;
  bad[2].point.x = std::nanf("");
  bad[3].velocity.z = 1e30f;  // finite, but the render surface would hold +inf
  bad[4].normal = glm::vec3(0);
  bad[5].kind = Collider::Kind::Box;
  bad[5].halfExtents.y = 0;
  bad[6].kind = Collider::Kind::Sphere;
  bad[6].radius = -0.1f;
  bad[7].kind = Collider::Kind::Box;
  bad[7].rotation = glm::quat(0, 0, 0, 0);
  bad[8].kind = Collider::Kind::Capsule;
  bad[8].halfLength = -0.01f;
  bad[9].kind = Collider::Kind::Capsule;
  bad[9].radius = 0;
  World world(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(cube()).value();
  for (size_t i = 0; i < bad.size(); ++i) {
    const Result<void> own = bad[i].check();
    ASSERT_FALSE(own.ok()) << i;
    const Result<void> set = world.setColliders(std::span<const Collider>(&bad[i], 1));
    ASSERT_FALSE(set.ok()) << i;
    EXPECT_EQ(set.error().message, "setColliders: colliders[0]." + own.error().message);
    WorldDef def;
    def.colliders = {bad[i]};
    ASSERT_FALSE(def.check().ok()) << i;
    EXPECT_EQ(def.check().error().message, "WorldDef.colliders[0]." + own.error().message);
  }
  EXPECT_TRUE(world.colliders().empty());  // nothing was replaced
  EXPECT_TRUE(world.step(0.01).ok());
  EXPECT_TRUE(test::stateFinite(world, id));
}

// Enum fields hold whatever an engine casts into them: out-of-range values are errors.
TEST(WorldMisuse, UnknownEnumValuesAreRejected) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  struct Case {
    const char* field;
    BodyDef def;
  };
  std::vector<Case> cases;
  auto add = [&](const char* field, auto change) {
    BodyDef d = cube();
    change(d);
    cases.push_back({field, d});
  };
  add("BodyDef.solver.linearSolver",
      [](BodyDef& d) { d.solver.linearSolver = static_cast<LinearSolverKind>(5); });
  add("BodyDef.solver.multigrid.smoother",
      [](BodyDef& d) { d.solver.multigrid.smoother = static_cast<Smoother>(5); });
  add("BodyDef.fracture.model", [](BodyDef& d) {
    d.fracture.enabled = true;
    d.fracture.model = static_cast<DamageModel>(5);
  });
  add("BodyDef.material.model",
      [](BodyDef& d) { d.material.model = static_cast<MaterialModel>(5); });
  add("BodyDef.solver.multigrid.levels[1]", [](BodyDef& d) {
    d.solver.multigrid.levels = {50, 50};
  });
  add("BodyDef.plasticity.flowRate", [](BodyDef& d) {
    d.plasticity.enabled = true;
    d.plasticity.flowRate = 2;
  });
  add("BodyDef.initialVelocity", [](BodyDef& d) { d.initialVelocity.x = 1e30f; });
  for (const Case& c : cases) {
    const Result<BodyId> r = world.createBody(c.def);
    ASSERT_FALSE(r.ok()) << c.field;
    EXPECT_TRUE(contains(r.error().message, c.field)) << r.error().message;
    // BodyDef::check is the same rule, without the World's prefix.
    ASSERT_FALSE(c.def.check().ok()) << c.field;
    EXPECT_TRUE(contains("BodyDef." + c.def.check().error().message, c.field));
  }
  EXPECT_TRUE(cube().check().ok());
}

// Finite but absurd values (a unit mistake) would overflow the float render surface to +inf.
TEST(WorldMisuse, AbsurdPositionsAndVelocitiesAreRejected) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(cube()).value();
  (void)world.surface(id);
  const uint64_t hash = world.stateHash();
  std::vector<double> x(world.positions(id).begin(), world.positions(id).end());
  x[7] = 1e300;
  const Result<void> r = world.setPositions(id, x);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "value 7 (node 2)")) << r.error().message;
  std::vector<double> v(x.size(), 0.0);
  v[0] = -1e300;
  EXPECT_FALSE(world.setVelocities(id, v).ok());
  EXPECT_FALSE(world.setVelocity(id, glm::dvec3(0, 1e300, 0)).ok());
  EXPECT_FALSE(world.applyImpulse(id, glm::vec3(1e30f, 0, 0), glm::vec3(1)).ok());
  EXPECT_EQ(world.stateHash(), hash);
  for (float p : world.surface(id).positions) ASSERT_TRUE(std::isfinite(p));
}

// A snapshot restores only into the world it was taken of, even when another world has the
// same bodies in the same slots.
TEST(WorldMisuse, SnapshotOfAnotherWorldIsRejected) {
  WorldDef withFloor{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}};
  withFloor.colliders.resize(1);
  withFloor.colliders[0].point = glm::vec3(0, -1, 0);
  World a(withFloor);
  World b(WorldDef{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}});
  const BodyId ia = a.createBody(cube()).value();
  const BodyId ib = b.createBody(cube()).value();
  ASSERT_EQ(ia.index, ib.index);
  ASSERT_EQ(ia.generation, ib.generation);
  for (int s = 0; s < 10; ++s) (void)a.step(0.01);
  const WorldSnapshot snapA = a.snapshot();
  const uint64_t hashB = b.stateHash();
  const Result<void> r = b.restore(snapA);
  ASSERT_FALSE(r.ok());
  EXPECT_TRUE(contains(r.error().message, "another World")) << r.error().message;
  EXPECT_EQ(b.stateHash(), hashB);
  EXPECT_TRUE(b.colliders().empty());
  EXPECT_TRUE(a.restore(snapA).ok());  // its own world takes it
}

void translate(TetMesh& m, double x, double y, double z) {
  for (size_t n = 0; n < m.nodeCount(); ++n) {
    m.positions[3 * n] += x;
    m.positions[3 * n + 1] += y;
    m.positions[3 * n + 2] += z;
  }
}

// The README's default scene, a clamped rubber beam with stiffness damping beside a soft block
// that drops onto a floor, run at absurd time steps.
struct AbsurdScene {
  World world;
  BodyId beam, block;
  explicit AbsurdScene(int newtonIterations)
      : world([] {
          WorldDef d{glm::vec3(0, -9.81f, 0), Backend::Cpu, nullptr, 1, {}};
          d.colliders.resize(1);  // the floor plane y = 0
          return d;
        }()) {
    BodyDef b;
    b.mesh = gen::box(1.0, 0.1, 0.1, 40, 4, 4);
    translate(b.mesh, 0, 1.0, -0.05);
    b.material = Material::stableNeoHookean(1e7, 0.4, 1100);
    b.material.massDamping = 0.5;
    b.material.stiffnessDamping = 0.002;
    b.solver.newtonIterations = newtonIterations;
    b.solver.linearSolver = LinearSolverKind::Direct;
    Grip pin;
    pin.nodes = test::selectNodes(b.mesh, [](double x, double, double) { return x < 1e-9; });
    b.grips = {pin};
    beam = world.createBody(b).value();
    BodyDef k;
    k.mesh = gen::box(0.3, 0.3, 0.3, 6, 6, 6);
    translate(k.mesh, 1.4, 0.8, -0.15);
    k.material = Material::stableNeoHookean(2e5, 0.4, 1000);
    k.material.massDamping = 0.2;
    k.material.stiffnessDamping = 0.002;
    k.solver.newtonIterations = newtonIterations;
    k.solver.linearSolver = LinearSolverKind::PCG;
    k.solver.maxLinearIterations = 300;
    block = world.createBody(k).value();
  }
};

// Absurd time steps: a step either stays physical (elastic energy bounded) or is rolled back
// and says why; the world never holds an exploded or non-finite body, and every flagged step
// carries a message.
TEST(WorldMisuse, DivergenceIsRolledBackAndExplained) {
  int rolledBack = 0;
  for (const int newton : {1, 50}) {
    for (const double dt : {1.0, 1000.0, 1e6}) {
      AbsurdScene scene(newton);
      World& world = scene.world;
      for (int s = 0; s < 3; ++s) {
        const StepStatus st = world.step(dt);
        for (const BodyId id : {scene.beam, scene.block}) {
          const BodyStats bs = world.stats(id);
          std::printf("dt %-7g newton %2d step %d body %u: flags %u elastic %.3e J%s%s\n", dt,
                      newton, s, id.index, st.flags, bs.elasticEnergy,
                      st.message.empty() ? "" : ": ", st.message.c_str());
          ASSERT_TRUE(test::stateFinite(world, id));
          EXPECT_LT(bs.elasticEnergy, 1e6 * 1e7 * 0.01) << "dt " << dt;
        }
        if (!st.ok()) {
          EXPECT_FALSE(st.message.empty()) << "flags " << st.flags;
        }
        rolledBack += st.has(kStepNanContained);
      }
    }
  }
  std::printf("%d of 18 absurd steps were rolled back\n", rolledBack);
}

// A step rolled back for a NaN leaves the plastic state alone: the elastic energy at the same
// positions is unchanged (it used to take a plastic flow step from the restored state).
TEST(WorldMisuse, RolledBackStepLeavesPlasticityAlone) {
  World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
  BodyDef def = cube();
  def.plasticity.enabled = true;
  def.plasticity.yieldStress = 1e3;
  const BodyId id = world.createBody(def).value();
  // Stretch it well past yield so a flow step would change Fp.
  std::vector<double> x(world.positions(id).begin(), world.positions(id).end());
  for (size_t i = 0; i < x.size(); i += 3) x[i] *= 1.2;
  ASSERT_TRUE(world.setPositions(id, x).ok());
  const double before = world.stats(id).elasticEnergy;
  ASSERT_TRUE(world.applyForce(id, glm::vec3(0.1f), glm::vec3(3e38f, 0, 0)).ok());
  const StepStatus st = world.step(0.01);
  ASSERT_TRUE(st.has(kStepNanContained)) << st.flags << " " << st.message;
  EXPECT_EQ(world.stats(id).elasticEnergy, before);
  const StepStatus next = world.step(0.01);  // and the body runs on
  EXPECT_FALSE(next.has(kStepNanContained));
  EXPECT_GT(world.timings().plasticityMs, 0.0);
  EXPECT_EQ(world.timings().fractureMs, 0.0);  // plastic flow is not fracture
}

// Resident memory of this process [bytes], from /proc (Linux).
double residentBytes() {
  std::ifstream statm("/proc/self/statm");
  double pages = 0, resident = 0;
  statm >> pages >> resident;
  return resident * double(sysconf(_SC_PAGESIZE));
}

#if defined(__SANITIZE_ADDRESS__)
constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif
#else
constexpr bool kSanitized = false;
#endif

// The estimate createBody reports when memory runs out matches what a body really takes.
TEST(WorldMisuse, BodyMemoryEstimateMatchesTheProcess) {
  if (kSanitized) GTEST_SKIP() << "the sanitizer's shadow memory distorts resident sizes";
  // Without fracture, with it, and with a non-local average over 0.06 m (about 75 neighbours
  // per tet).
  for (const int variant : {0, 1, 2}) {
    const bool fracture = variant > 0;
    BodyDef def;
    def.mesh = gen::box(1, 1, 1, 24, 24, 24);
    def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
    def.fracture.enabled = fracture;
    if (variant == 2) def.fracture.nonlocalLength = 0.06;
    World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
    // The previous variant's freed pages go back to the system, so this body's growth is not
    // hidden by heap reuse.
    malloc_trim(0);
    const double before = residentBytes();
    const BodyId id = world.createBody(def).value();
    (void)world.step(1.0 / 60);  // the first step touches every buffer
    const double grown = residentBytes() - before;
    const double estimate = detail::estimateBodyBytes(def);
    std::printf("memory: %zu tets, %s: estimate %.1f MiB, process grew %.1f MiB\n",
                def.mesh.tetCount(),
                variant == 0   ? "no fracture"
                : variant == 1 ? "fracture"
                               : "non-local fracture",
                estimate / 1048576, grown / 1048576);
    EXPECT_GT(estimate, 0.75 * grown);
    EXPECT_LT(estimate, 1.25 * grown);
    EXPECT_TRUE(world.isValid(id));
  }
}

// A body larger than the memory the process may use is an error that says how much it needs,
// not an exception through the API (run in a child process under an address-space limit).
TEST(WorldMisuse, BodyTooLargeForMemoryIsAnError) {
  if (kSanitized) GTEST_SKIP() << "the sanitizer reserves more address space than the limit";
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        BodyDef def;
        def.mesh = gen::box(1, 1, 1, 60, 60, 60);  // 1.3 M tets: about 2 GB
        def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
        const double need = detail::estimateBodyBytes(def);
        rlimit limit{};
        limit.rlim_cur = limit.rlim_max = rlim_t(0.4 * need) + (rlim_t(1) << 28);
        setrlimit(RLIMIT_AS, &limit);
        World world(WorldDef{glm::vec3(0), Backend::Cpu, nullptr, 1, {}});
        const Result<BodyId> r = world.createBody(def);
        if (r.ok()) std::exit(2);
        std::fprintf(stderr, "%s\n", r.error().message.c_str());
        // The world is still usable.
        std::exit(world.createBody(cube()).ok() && world.step(0.01).ok() ? 0 : 3);
      },
      ::testing::ExitedWithCode(0), "BodyDef.mesh: not enough memory .* it needs about [0-9]+ MiB");
}

}  // namespace
}  // namespace gf
