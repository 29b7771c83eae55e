// Worlds on the CUDA backend (WorldDef::backend = Cuda: each body's element pass and PCG and
// multigrid solves on its device, gpu/body_device.h) against the same worlds on the CPU, 100
// steps of tearing, shattering, cutting and plastic scenes, with every material and both damage
// models: the same broken edges and fragments, positions within a stated tolerance. Built
// twice: here the device is the host build of the device sources (detail::setTestDevice), so
// CI runs it; in gf_gpu_tests it is the CUDA device, and the cases are skipped, and reported
// so, where there is none.
#include <graphfrac/world.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "common/sim_helpers.h"
#include "fem/element_stage.h"
#include "gpu/body_device.h"
#include "gpu/device.h"
#include "graphfrac/jobs.h"
#include "kernels/math.h"
#include "solver/block_sparse.h"
#include "world/backend.h"

namespace gf {
namespace {

// What the comparison reads of a run.
struct Outcome {
  std::vector<double> x, v;
  std::vector<uint8_t> broken;
  int32_t fragments = 0, brokenCount = 0;
  double size = 0;  // the body's extent at the start, the positions' scale
  std::string description;
  std::vector<std::string> messages;
};

// A scene: the world def, the body, and what happens at each step before it (cuts, grips);
// `second`, when set, adds a second body, and the outcome holds both bodies' arrays.
struct Scene {
  std::string name;
  std::function<void(WorldDef&, BodyDef&)> build;
  std::function<void(World&, BodyId, int step)> act;
  double dt = 1.0 / 60;
  std::function<void(BodyDef&)> second;
};

#if defined(GF_GPU_CUDA)
// The CUDA build's cases are skipped where no device runs them, saying why.
#define GF_SKIP_WITHOUT_DEVICE()                                                      \
  do {                                                                                \
    const World probe(WorldDef{glm::vec3(0), Backend::Cuda, nullptr, 1, {}});         \
    if (probe.backend() != Backend::Cuda) GTEST_SKIP() << probe.backendDescription(); \
  } while (false)
#else
#define GF_SKIP_WITHOUT_DEVICE() \
  do {                           \
  } while (false)
// The host build of the device sources as the device of Backend::Cuda, for one test.
struct HostDevice {
  HostDevice() { detail::setTestDevice(&gpu::makeBodyDevice, "host emulation"); }
  ~HostDevice() { detail::setTestDevice(nullptr, nullptr); }
};
#endif

// Runs `scene` for `steps` steps on `backend` (with `jobs`, null: serial); an empty outcome
// when the backend cannot run.
Outcome run(const Scene& scene, Backend backend, int steps, JobSystem* jobs = nullptr) {
  WorldDef wd;
  BodyDef def;
  scene.build(wd, def);
  wd.backend = backend;
  wd.jobs = jobs;
  Outcome o;
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (size_t i = 0; i < def.mesh.positions.size(); ++i) {
    lo[i % 3] = std::min(lo[i % 3], def.mesh.positions[i]);
    hi[i % 3] = std::max(hi[i % 3], def.mesh.positions[i]);
  }
  o.size = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  World world(wd);
  std::vector<BodyDef> defs{def};
  if (scene.second) scene.second(defs.emplace_back());
  std::vector<BodyId> ids;
  for (BodyDef& d : defs) {
    const Result<BodyId> id = world.createBody(d);
    if (!id.ok()) {
      o.description = id.error().message;
      return o;
    }
    ids.push_back(id.value());
  }
  for (int s = 0; s < steps; ++s) {
    if (scene.act) scene.act(world, ids[0], s);
    const StepStatus st = world.step(scene.dt);
    EXPECT_FALSE(st.has(kStepNanContained)) << scene.name << " step " << s << ": " << st.message;
    if (!st.message.empty()) o.messages.push_back(st.message);
  }
  for (BodyId id : ids) {
    const auto x = world.positions(id);
    const auto v = world.velocities(id);
    o.x.insert(o.x.end(), x.begin(), x.end());
    o.v.insert(o.v.end(), v.begin(), v.end());
    const auto b = world.brokenEdges(id);
    o.broken.insert(o.broken.end(), b.begin(), b.end());
    const FractureStats fs = world.fractureStats(id);
    o.fragments += fs.fragments;
    o.brokenCount += fs.brokenEdges;
  }
  o.description = world.backendDescription();
  return o;
}

double maxDifference(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0;
  for (size_t i = 0; i < a.size(); ++i) d = std::max(d, std::fabs(a[i] - b[i]));
  return d;
}

// Positions within this fraction of the body's size of the CPU's after 100 steps. The host
// build runs the CPU's sources on the same host: the same bits, but for NeoHookean, whose log
// the CPU's element pass takes in SIMD batches, rounded otherwise (docs/validation.md, "The
// element pass"). A device sums in another order, with fused multiply-adds.
#if defined(GF_GPU_CUDA)
constexpr double kExact = 1e-6, kNeoHookean = 1e-6;
#else
constexpr double kExact = 0, kNeoHookean = 1e-8;
#endif

// Returns the CPU's outcome, for what a test checks of the scene itself. The CPU runs
// serially, the device world with `jobs` (the host's part of its step on those threads).
Outcome compare(const Scene& scene, double tolerance, JobSystem* jobs = nullptr) {
#if !defined(GF_GPU_CUDA)
  const HostDevice device;
#endif
  const int steps = 100;
  const Outcome cpu = run(scene, Backend::Cpu, steps);
  const Outcome dev = run(scene, Backend::Cuda, steps, jobs);
  if (dev.x.empty()) {
    ADD_FAILURE_AT(__FILE__, __LINE__) << "no device world: " << dev.description;
    return cpu;
  }
  EXPECT_EQ(dev.x.size(), cpu.x.size());
  if (dev.x.size() != cpu.x.size()) return cpu;
  EXPECT_EQ(dev.description.rfind("cuda: ", 0), 0u) << dev.description;
  for (const std::string& m : dev.messages)
    EXPECT_EQ(m.find("runs on the CPU from now on"), std::string::npos) << m;
  const double dx = maxDifference(dev.x, cpu.x) / cpu.size;
  const double dv = maxDifference(dev.v, cpu.v);
  std::printf(
      "  %s on %s: %d broken edges, %d fragments (CPU %d, %d); positions within %.1e of "
      "the size, velocities within %.1e m/s\n",
      scene.name.c_str(), dev.description.c_str(), dev.brokenCount, dev.fragments, cpu.brokenCount,
      cpu.fragments, dx, dv);
  EXPECT_EQ(dev.broken, cpu.broken);
  EXPECT_EQ(dev.fragments, cpu.fragments);
  EXPECT_LE(dx, tolerance);
  return cpu;
}

const char* const kMaterialName[] = {"Corotated", "StVK", "NeoHookean", "StableNeoHookean"};

// A bar whose ends grips pull apart until it tears.
Scene tearing(MaterialModel model, DamageModel damage, LinearSolverKind solver) {
  Scene s;
  s.name = std::string("tear ") + kMaterialName[int(model)] +
           (damage == DamageModel::Projection ? " projection" : " degradation") +
           (solver == LinearSolverKind::PCG ? " pcg" : " multigrid");
  s.dt = 1.0 / 120;
  s.build = [=](WorldDef& wd, BodyDef& def) {
    wd.gravity = glm::vec3(0);
    def.mesh = gen::box(0.4, 0.1, 0.1, 12, 3, 3);
    def.material.model = model;
    def.material.youngsModulus = 1e6;
    def.material.poissonRatio = 0.3;
    def.material.density = 1000;
    def.fracture.enabled = true;
    def.fracture.strength = 1.2e5;
    def.fracture.model = damage;
    def.solver.linearSolver = solver;
    def.solver.multigrid.directBelowNodes = 0;  // the multigrid, not its direct fallback
    def.solver.linearTolerance = 1e-10;
    Grip left, right;
    left.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
    right.nodes =
        test::selectNodes(def.mesh, [](double x, double, double) { return x > 0.4 - 1e-9; });
    left.velocity = {-0.2f, 0, 0};
    right.velocity = {0.2f, 0, 0};
    def.grips = {left, right};
  };
  return s;
}

class WorldBackendTear
    : public testing::TestWithParam<std::tuple<MaterialModel, DamageModel, LinearSolverKind>> {};

TEST_P(WorldBackendTear, SameCracksAndPositionsAsTheCpu) {
  GF_SKIP_WITHOUT_DEVICE();
  const auto [model, damage, solver] = GetParam();
  const Outcome cpu = compare(tearing(model, damage, solver),
                              model == MaterialModel::NeoHookean ? kNeoHookean : kExact);
  EXPECT_GE(cpu.fragments, 2) << "the bar tears";
}

const auto kTearCases =
    testing::Combine(testing::Values(MaterialModel::Corotated, MaterialModel::StVK,
                                     MaterialModel::NeoHookean, MaterialModel::StableNeoHookean),
                     testing::Values(DamageModel::Projection, DamageModel::Degradation),
                     testing::Values(LinearSolverKind::Multigrid, LinearSolverKind::PCG));
#if defined(GF_GPU_CUDA)
INSTANTIATE_TEST_SUITE_P(Device, WorldBackendTear, kTearCases);
#define GF_SCENE_TEST(name) TEST(DeviceWorldBackend, name)
#else
INSTANTIATE_TEST_SUITE_P(HostBuild, WorldBackendTear, kTearCases);
#define GF_SCENE_TEST(name) TEST(WorldBackend, name)
#endif

// The host's part of a device world's step on two threads: the CPU's bits still.
GF_SCENE_TEST(TearOnTwoThreadsSameAsTheCpu) {
  GF_SKIP_WITHOUT_DEVICE();
  ThreadPoolJobSystem two(2);
  compare(tearing(MaterialModel::StableNeoHookean, DamageModel::Degradation,
                  LinearSolverKind::Multigrid),
          kExact, &two);
}

// The tear with Rayleigh damping and full Newton: the device keeps the step's K(x_n) from its
// first assembly and adds it to every later one.
GF_SCENE_TEST(DampedTearSameAsTheCpu) {
  GF_SKIP_WITHOUT_DEVICE();
  Scene s = tearing(MaterialModel::StableNeoHookean, DamageModel::Projection,
                    LinearSolverKind::Multigrid);
  const Scene undamped = s;
  s.name = "damped tear";
  s.build = [&undamped](WorldDef& wd, BodyDef& def) {
    undamped.build(wd, def);
    def.material.massDamping = 0.5;
    def.material.stiffnessDamping = 2e-3;
    def.solver.newtonIterations = 3;
  };
  const Outcome cpu = compare(s, kExact);
  EXPECT_GE(cpu.fragments, 2) << "the bar tears";
  // The damping acts: the same bar without it ends elsewhere.
  EXPECT_GT(maxDifference(run(undamped, Backend::Cpu, 100).x, cpu.x), 1e-3 * cpu.size);
}

// The element Hessians, the Newton matrix and the fracture criterion's stresses stay on the
// device: what a Newton iteration copies each way is per node (positions, gradients, the node
// blocks' inputs), not per tet or per matrix block. Counted by the device's own copy totals
// over 10 steps of a bar stretched by a grip, its fracture judged each step (nothing breaks).
GF_SCENE_TEST(TheHessiansAndTheMatrixStayOnTheDevice) {
  GF_SKIP_WITHOUT_DEVICE();
#if !defined(GF_GPU_CUDA)
  const HostDevice device;
#endif
  for (const LinearSolverKind solver : {LinearSolverKind::PCG, LinearSolverKind::Multigrid}) {
    WorldDef wd;
    wd.gravity = glm::vec3(0);
    wd.backend = Backend::Cuda;
    BodyDef def;
    def.mesh = gen::box(0.4, 0.1, 0.1, 24, 6, 6);
    def.material = Material::stableNeoHookean(1e6, 0.3, 1000);
    def.solver.linearSolver = solver;
    def.solver.multigrid.directBelowNodes = 0;
    def.fracture.enabled = true;
    def.fracture.strength = 1e9;
    Grip left, right;
    left.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
    right.nodes =
        test::selectNodes(def.mesh, [](double x, double, double) { return x > 0.4 - 1e-9; });
    right.velocity = {0.05f, 0, 0};
    def.grips = {left, right};
    const uint64_t heldBefore = gpu::memoryTotals().current;
    World world(wd);
    ASSERT_TRUE(world.createBody(def).ok());
    for (int s = 0; s < 3; ++s) ASSERT_TRUE(world.step(1.0 / 60).ok());  // the model's copies
    const gpu::CopyTotals before = gpu::copyTotals();
    int iterations = 0;
    for (int s = 0; s < 10; ++s) {
      const StepStatus st = world.step(1.0 / 60);
      ASSERT_FALSE(st.has(kStepNanContained)) << st.message;
      iterations += st.newtonIterations;
    }
    const gpu::CopyTotals after = gpu::copyTotals();
    const double toHost = double(after.toHost - before.toHost) / iterations;
    const double toDevice = double(after.toDevice - before.toDevice) / iterations;
    const size_t tets = def.mesh.tetCount(), nodes = def.mesh.nodeCount();
    const double hessians = double(tets) * kElementMatrixSize * sizeof(double);
    const double matrix =
        double(detail::BlockSparseMatrix::fromTets(def.mesh.tets.data(), tets, nodes).col.size()) *
        9 * sizeof(double);
    const double stresses = double(tets) * 6 * sizeof(double);
    std::printf(
        "  %s, %zu tets, %zu nodes: %.0f bytes to the host and %.0f to the device per "
        "Newton iteration (%d); the element Hessians are %.0f, the matrix %.0f, the stresses "
        "%.0f\n",
        solver == LinearSolverKind::PCG ? "PCG" : "multigrid", tets, nodes, toHost, toDevice,
        iterations, hessians, matrix, stresses);
    const double held = double(gpu::memoryTotals().current - heldBefore);
    std::printf("  device memory of the body: %.2f MB, %.0f bytes a tet\n", held / 1e6,
                held / double(tets));
    EXPECT_LT(toHost, 0.5 * stresses);
    EXPECT_LT(toHost, 0.1 * hessians);
    EXPECT_LT(toDevice, 0.1 * hessians);
    if (solver == LinearSolverKind::PCG) {
      EXPECT_LT(toHost, 0.5 * matrix);
      EXPECT_LT(toDevice, 0.5 * matrix);
    }
  }
}

// A smoothed prolongator, which only the host prepares: the device's matrix goes to the host
// for it, and the levels come back.
GF_SCENE_TEST(SmoothedProlongationTearSameAsTheCpu) {
  GF_SKIP_WITHOUT_DEVICE();
  Scene s =
      tearing(MaterialModel::Corotated, DamageModel::Degradation, LinearSolverKind::Multigrid);
  const auto build = s.build;
  s.name = "tear, smoothed prolongation";
  s.build = [build](WorldDef& wd, BodyDef& def) {
    build(wd, def);
    def.solver.multigrid.smoothedProlongation = true;
  };
  const Outcome cpu = compare(s, kExact);
  EXPECT_GE(cpu.fragments, 2) << "the bar tears";
}

// A fragment handed to rigid physics mid-run: its nodes become fixed and the multigrid is set
// up again, so the device mirrors the new levels.
GF_SCENE_TEST(DetachedFragmentSameAsTheCpu) {
  GF_SKIP_WITHOUT_DEVICE();
  Scene s = tearing(MaterialModel::Corotated, DamageModel::Projection, LinearSolverKind::Multigrid);
  s.name = "tear, a fragment detached";
  s.act = [](World& world, BodyId id, int step) {
    if (step != 60) return;
    bool detached = false;
    for (int32_t f = 0; f < world.fractureStats(id).fragments && !detached; ++f)
      detached = world.detachFragment(id, f).ok();
    EXPECT_TRUE(detached) << "a free fragment at step 60";
  };
  compare(s, kExact);
}

// The criterion on the device (stresses and candidates there, only the candidates back),
// non-local and brittle: a brittle body's first break reads the stresses back for its planes.
GF_SCENE_TEST(NonlocalAndBrittleTearSameAsTheCpu) {
  GF_SKIP_WITHOUT_DEVICE();
  for (const bool brittle : {false, true}) {
    Scene s = tearing(MaterialModel::StVK, DamageModel::Projection, LinearSolverKind::Multigrid);
    const auto build = s.build;
    s.name = brittle ? "tear, brittle" : "tear, non-local";
    s.build = [build, brittle](WorldDef& wd, BodyDef& def) {
      build(wd, def);
      if (brittle) {
        def.fracture.brittle = true;
        def.fracture.regions = 2;
      } else {
        def.fracture.nonlocalLength = 0.03;
      }
    };
    const Outcome cpu = compare(s, kExact);
    EXPECT_GE(cpu.fragments, 2) << s.name << ": the bar breaks";
  }
}

// A snapshot of a device world restores its steps bit for bit (World::restore): the coarse
// operators the device prepared come back to the host for the snapshot. Restored once between
// two refreshes and after 40 steps, the run ends where the CPU's uninterrupted one does.
GF_SCENE_TEST(ARestoredWorldRepeatsItsSteps) {
  GF_SKIP_WITHOUT_DEVICE();
#if !defined(GF_GPU_CUDA)
  const HostDevice device;
#endif
  const Scene s = tearing(MaterialModel::StableNeoHookean, DamageModel::Projection,
                          LinearSolverKind::Multigrid);
  const Outcome cpu = run(s, Backend::Cpu, 80);
  WorldDef wd;
  BodyDef def;
  s.build(wd, def);
  wd.backend = Backend::Cuda;
  World world(wd);
  const Result<BodyId> id = world.createBody(def);
  ASSERT_TRUE(id.ok()) << id.error().message;
  auto steps = [&](int n) {
    for (int k = 0; k < n; ++k) ASSERT_FALSE(world.step(s.dt).has(kStepNanContained));
  };
  steps(35);
  const WorldSnapshot at35 = world.snapshot();
  steps(10);
  const std::vector<double> first(world.positions(id.value()).begin(),
                                  world.positions(id.value()).end());
  ASSERT_TRUE(world.restore(at35).ok());
  steps(10);
  const std::vector<double> again(world.positions(id.value()).begin(),
                                  world.positions(id.value()).end());
  EXPECT_EQ(first, again);
  steps(35);
  const auto end = world.positions(id.value());
  EXPECT_LE(maxDifference(std::vector<double>(end.begin(), end.end()), cpu.x) / cpu.size, kExact);
  EXPECT_EQ(world.fractureStats(id.value()).fragments, cpu.fragments);
}

// A weak brittle block dropped onto the ground at 6 m/s: it shatters on impact.
GF_SCENE_TEST(ShatteringBlockSameAsTheCpu) {
  GF_SKIP_WITHOUT_DEVICE();
  Scene s;
  s.name = "shatter";
  s.build = [](WorldDef& wd, BodyDef& def) {
    wd.colliders.push_back(Collider{Collider::Kind::Plane, glm::vec3(0)});
    def.mesh = gen::box(0.2, 0.2, 0.2, 5, 5, 5);
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n) def.mesh.positions[3 * n + 1] += 0.01;
    def.material = Material::stvk(2e6, 0.3, 1000);
    def.initialVelocity = glm::vec3(0, -6, 0);
    def.fracture.enabled = true;
    def.fracture.strength = 3e3;
    def.fracture.brittle = true;
    def.fracture.regions = 4;
  };
  const Outcome cpu = compare(s, kExact);
  EXPECT_GE(cpu.fragments, 3) << "the block shatters";
}

// A bar cut through by a blade at its first step, whose two halves fall onto the ground.
GF_SCENE_TEST(CutBarSameAsTheCpu) {
  GF_SKIP_WITHOUT_DEVICE();
  Scene s;
  s.name = "cut";
  s.build = [](WorldDef& wd, BodyDef& def) {
    wd.colliders.push_back(Collider{Collider::Kind::Plane, glm::vec3(0)});
    def.mesh = gen::box(0.4, 0.1, 0.1, 12, 3, 3);
    for (size_t n = 0; n < def.mesh.nodeCount(); ++n) def.mesh.positions[3 * n + 1] += 0.05;
    def.material = Material::stableNeoHookean(5e5, 0.3, 1000);
    def.fracture.enabled = true;
    def.fracture.strength = 1e12;  // only the blade breaks edges
  };
  s.act = [](World& world, BodyId id, int step) {
    if (step != 0) return;
    Blade blade;
    blade.vertices = {{0.21f, -1, -1}, {0.21f, 1, -1}, {0.21f, 1, 1}, {0.21f, -1, 1}};
    blade.triangles = {0, 1, 2, 0, 2, 3};
    ASSERT_TRUE(world.cut(id, blade).ok());
  };
  const Outcome cpu = compare(s, kExact);
  EXPECT_EQ(cpu.fragments, 2) << "the blade cuts the bar in two";
}

// A plastic cantilever whose tip a grip lifts for half a second and then holds.
GF_SCENE_TEST(PlasticCantileverSameAsTheCpu) {
  GF_SKIP_WITHOUT_DEVICE();
  Scene s;
  s.name = "plastic";
  s.build = [](WorldDef&, BodyDef& def) {
    def.mesh = gen::box(0.5, 0.05, 0.05, 20, 2, 2);
    def.material = Material::stableNeoHookean(2e6, 0.3, 1000);
    def.plasticity.enabled = true;
    def.plasticity.yieldStress = 2e4;
    def.plasticity.flowRate = 0.5;
    Grip clamp, tip;
    clamp.nodes = test::selectNodes(def.mesh, [](double x, double, double) { return x < 1e-9; });
    tip.nodes =
        test::selectNodes(def.mesh, [](double x, double, double) { return x > 0.5 - 1e-9; });
    tip.velocity = {0, 0.5f, 0};
    def.grips = {clamp, tip};
  };
  s.act = [](World& world, BodyId id, int step) {
    if (step == 30) {
      ASSERT_TRUE(world.setGripVelocity(id, 1, glm::vec3(0)).ok());
    }
  };
  const Outcome cpu = compare(s, kExact);
  // The bar flowed: without plasticity it ends elsewhere.
  Scene elastic = s;
  elastic.build = [&s](WorldDef& wd, BodyDef& def) {
    s.build(wd, def);
    def.plasticity.enabled = false;
  };
  EXPECT_GT(maxDifference(run(elastic, Backend::Cpu, 100).x, cpu.x), 1e-3 * cpu.size);
}

// A block dropped onto another that lies on the ground, with body contact, lagged and coupled
// (WorldDef::coupledContact: the bodies' Newton systems solved jointly, each body's own solver
// as the preconditioner, on its device).
GF_SCENE_TEST(StackedBlocksSameAsTheCpu) {
  GF_SKIP_WITHOUT_DEVICE();
  for (const bool coupled : {false, true}) {
    Scene s;
    s.name = coupled ? "stack coupled" : "stack lagged";
    auto block = [](BodyDef& def, double y) {
      def.mesh = gen::box(0.2, 0.1, 0.2, 4, 2, 4);
      for (size_t n = 0; n < def.mesh.nodeCount(); ++n) def.mesh.positions[3 * n + 1] += y;
      def.material = Material::stableNeoHookean(2e5, 0.3, 1000);
      def.contact = true;
      def.friction = 0.4;
      def.solver.multigrid.directBelowNodes = 0;
    };
    s.build = [&](WorldDef& wd, BodyDef& def) {
      wd.colliders.push_back(Collider{Collider::Kind::Plane, glm::vec3(0)});
      wd.coupledContact = coupled;
      block(def, 0);
    };
    s.second = [&](BodyDef& def) {
      block(def, 0.12);
      def.initialVelocity = glm::vec3(0, -1, 0);
    };
    const Outcome cpu = compare(s, kExact);
    // The upper block rests on the lower one: its lowest node a little above y = 0.1.
    double lowest = 1e300;
    for (size_t i = cpu.x.size() / 2 + 1; i < cpu.x.size(); i += 3)
      lowest = std::min(lowest, cpu.x[i]);
    EXPECT_NEAR(lowest, 0.1, 0.01) << s.name;
  }
}

#if !defined(GF_GPU_CUDA)
// The host build's device whose calls fail from the `failAt`-th call of one kind on, as a
// device that runs out of memory or loses its context would.
enum class FailingCall {
  kElementPass,
  kLineSearchPass,  // an energy-only pass, after the iteration's matrix was assembled
  kCriterion,
  kCandidates,
  kAssemble,
  kMatrixRead,
  kMultiply,
  kPcg,
  kMultigrid
};
struct Failing {
  static inline FailingCall call = FailingCall::kElementPass;
  static inline int failAt = 0;
};
class FailingDevice final : public detail::BodyDevice {
 public:
  bool elementPass(const detail::ElementStage& stage, const detail::GatherStage& gather,
                   int32_t tets, int32_t nodes, bool stateChanged, double& psi,
                   double* nodeGrad) override {
    if (fails(stage.grad ? FailingCall::kElementPass : FailingCall::kLineSearchPass)) return false;
    return m_device->elementPass(stage, gather, tets, nodes, stateChanged, psi, nodeGrad);
  }
  bool criterionStresses(const detail::ElementStage& body, const detail::GatherStage& gather,
                         int32_t tets, int32_t nodes, bool stateChanged,
                         const detail::CriterionStressStage& criterion) override {
    if (fails(FailingCall::kCriterion)) return false;
    return m_device->criterionStresses(body, gather, tets, nodes, stateChanged, criterion);
  }
  int32_t criterionCandidates(const detail::CriterionView& host, double weakest) override {
    if (fails(FailingCall::kCandidates)) return -1;
    return m_device->criterionCandidates(host, weakest);
  }
  bool readCriterionStresses(double* stress) override {
    return m_device->readCriterionStresses(stress);
  }
  bool downloadHessians(double* hess) override { return m_device->downloadHessians(hess); }
  bool assemble(const detail::DeviceAssembly& assembly) override {
    if (fails(FailingCall::kAssemble)) return false;
    return m_device->assemble(assembly);
  }
  bool downloadMatrix(double* values) override {
    if (fails(FailingCall::kMatrixRead)) return false;
    return m_device->downloadMatrix(values);
  }
  bool readLevel(uint64_t version, int level, double* values, size_t count) override {
    return m_device->readLevel(version, level, values, count);
  }
  bool multiply(const double* x, double* y) override {
    if (fails(FailingCall::kMultiply)) return false;
    return m_device->multiply(x, y);
  }
  bool pcgSolve(const detail::BlockSparseMatrix& A, bool assembled, const double* b, double* x,
                int maxIterations, double tolerance, detail::SolveReport& report) override {
    if (fails(FailingCall::kPcg)) return false;
    return m_device->pcgSolve(A, assembled, b, x, maxIterations, tolerance, report);
  }
  bool multigridSolve(const detail::BlockSparseMatrix& A, bool assembled,
                      const detail::CycleSettings& settings,
                      const std::function<const detail::MultigridMirror*()>& prepare,
                      const double* b, double* x, int maxIterations, double tolerance,
                      detail::MultigridRun& run, detail::SolveReport& report) override {
    // Fails after the levels were prepared and x half written, the worst place.
    if (fails(FailingCall::kMultigrid)) {
      (void)prepare();
      x[0] = std::nan("");
      return false;
    }
    return m_device->multigridSolve(A, assembled, settings, prepare, b, x, maxIterations, tolerance,
                                    run, report);
  }
  const std::string& error() const override { return m_error; }

 private:
  bool fails(FailingCall c) { return c == Failing::call && m_calls[int(c)]++ >= Failing::failAt; }
  std::unique_ptr<detail::BodyDevice> m_device = gpu::makeBodyDevice();
  int m_calls[9] = {};
  std::string m_error = "injected failure";
};
std::unique_ptr<detail::BodyDevice> makeFailingDevice() {
  return std::make_unique<FailingDevice>();
}

// A device call that fails hands the body back to the CPU for good: the step says so once, the
// world's backend description keeps it, and the body goes on as the CPU steps it, with no NaN
// from the failed call. Failing at the first call of the step, nothing ran on the device: the
// CPU's bits.
TEST(WorldBackend, AFailedDeviceCallHandsTheBodyToTheCpu) {
  struct Case {
    FailingCall call;
    int failAt;
    LinearSolverKind solver;
    bool smoothed = false;  // a smoothed prolongator, which the host prepares
  };
  for (const Case c : {Case{FailingCall::kElementPass, 0, LinearSolverKind::Multigrid},
                       Case{FailingCall::kElementPass, 7, LinearSolverKind::Multigrid},
                       Case{FailingCall::kLineSearchPass, 60, LinearSolverKind::PCG},
                       Case{FailingCall::kLineSearchPass, 60, LinearSolverKind::Multigrid},
                       Case{FailingCall::kCriterion, 0, LinearSolverKind::Multigrid},
                       Case{FailingCall::kCriterion, 30, LinearSolverKind::PCG},
                       Case{FailingCall::kCandidates, 40, LinearSolverKind::Multigrid},
                       Case{FailingCall::kAssemble, 0, LinearSolverKind::PCG},
                       Case{FailingCall::kAssemble, 6, LinearSolverKind::Multigrid},
                       Case{FailingCall::kMatrixRead, 4, LinearSolverKind::Multigrid, true},
                       Case{FailingCall::kMultiply, 2, LinearSolverKind::PCG},
                       Case{FailingCall::kPcg, 3, LinearSolverKind::PCG},
                       Case{FailingCall::kMultigrid, 0, LinearSolverKind::Multigrid},
                       Case{FailingCall::kMultigrid, 5, LinearSolverKind::Multigrid}}) {
    Failing::call = c.call;
    Failing::failAt = c.failAt;
    Scene scene = tearing(MaterialModel::StableNeoHookean, DamageModel::Projection, c.solver);
    if (c.smoothed) {
      const auto build = scene.build;
      scene.build = [build](WorldDef& wd, BodyDef& def) {
        build(wd, def);
        def.solver.multigrid.smoothedProlongation = true;
      };
    }
    const Outcome cpu = run(scene, Backend::Cpu, 100);
    detail::setTestDevice(&makeFailingDevice, "a failing device");
    const Outcome dev = run(scene, Backend::Cuda, 100);
    detail::setTestDevice(nullptr, nullptr);
    SCOPED_TRACE(std::to_string(int(c.call)) + " at call " + std::to_string(c.failAt));
    ASSERT_EQ(dev.messages.size(), 1u);
    EXPECT_NE(dev.messages[0].find("body 1 runs on the CPU from now on: the device failed "
                                   "(injected failure)"),
              std::string::npos)
        << dev.messages[0];
    EXPECT_NE(dev.description.find("runs on the CPU from now on"), std::string::npos);
    for (double x : dev.x) ASSERT_TRUE(std::isfinite(x));
    EXPECT_GE(dev.fragments, 2);
    if (c.failAt == 0 &&
        (c.call == FailingCall::kElementPass || c.call == FailingCall::kCriterion)) {
      EXPECT_EQ(dev.x, cpu.x);
      EXPECT_EQ(dev.broken, cpu.broken);
    }
  }
}
#endif

}  // namespace
}  // namespace gf
