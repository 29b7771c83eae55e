// `graphfrac bench peer`: graphfrac beside Bullet's deformable FEM (Debian's Bullet 3.24,
// btDeformableMultiBodyDynamicsWorld with btDeformableNeoHookeanForce) on the same tet mesh,
// material, time step and load, in one process.
//
// Bullet runs in three of its own configurations, each with its defaults unless said here:
// - bullet-implicit: setImplicit(true) with setUseProjection(true) and setLineSearch(false), i.e.
//   Bullet's default of one Newton iteration (a linearised backward Euler step, CG capped at 300
//   iterations; constants read from libBulletSoftBody's btDeformableBodySolver constructor). The
//   projection is not optional: without it (Bullet's default, which takes the Lagrange-multiplier
//   path) the implicit solve leaves every node at rest, with or without line search (measured:
//   the 60-tet cantilever's tip moved 7e-10 m in 0.5 s). Line search is off because it is Bullet's
//   default and, with one Newton iteration, it only shortens the step (measured: 5.7e-2 cantilever
//   error against 8.1e-3 without it at dt 1/240).
// - bullet-explicit: setImplicit(false), setLineSearch(false), as Bullet's deformable demos
//   (DeformableDemo, DeformableMultibody at 240 Hz): elastic forces explicit, so the time step is
//   bounded by the time sound takes to cross an element, h / sqrt((lambda + 2 mu) / rho).
// - bullet-implicit-linear: bullet-implicit with btDeformableLinearElasticityForce (small-strain
//   linear elasticity, the same E and nu, no damping) instead of the Neo-Hookean force: a
//   different material, kept because it is the one with which Bullet's cube rests on the ground
//   (with the Neo-Hookean force, implicit or explicit, it comes apart).
// All take the contact solver settings of Bullet's multibody deformable demo (deformable ERP 0.3,
// max error reduction 200, 100 iterations, split impulse, least-squares threshold 1e-3) and no
// material damping, as graphfrac's bodies here (Rayleigh terms 0).
// Each tet edge is also appended as a btSoftBody link, as btSoftBodyHelpers::CreateFromTetGenData
// does: the first step builds the node tree by merging nodes along links (btSoftBody::
// rebuildNodeTree) and never finishes when there are none (the hang of the first version of this
// tool). Links are not an elastic force in this world (that would take a
// btDeformableMassSpringForce): the 480-tet cantilever's sag at E 1e8 agrees with graphfrac's
// static one to 8e-6.
// Each Bullet run goes in a child process that reports every finished step: one that takes longer
// than --bullet-step-limit seconds for a step or --bullet-run-limit for the run is stopped and
// reported "too slow", so no Bullet setting can hang the tool.
//
// Both engines run Smith et al.'s stable Neo-Hookean energy. Bullet takes the energy's own
// constants; it is given the reparametrised mu' = 4/3 mu, lambda' = lambda + 5/6 mu that make
// the energy's small-strain E and nu the requested ones (graphfrac's kernel does the same,
// kernels/materials.h), so a difference in the result is the method's, not the units'.
//
// Cases:
// - cantilever: a 1 x 0.1 x 0.1 m beam clamped at x = 0 sagging under gravity for `--seconds`;
//   the measure is the tip's mean vertical displacement over the second half of the run (the
//   mean of an oscillation is its equilibrium, whatever each method's numerical damping), and
//   the reference graphfrac's static solution on the same mesh (one full-Newton step with a
//   time step so long that inertia is negligible; tests/common/beams.h).
// - drop: a 0.2 m cube dropped from 0.3 m onto the ground; the measure is the mean node height
//   at the end, the reference h / 2 - rho g h^2 / (3 E) (a column resting under its own weight).
// A run is unstable when a position becomes non-finite, a node ends more than one body length
// from where the reference puts it, or the final kinetic energy exceeds the work gravity has done
// (the potential energy lost): elastic energy is never negative and contact, damping and the
// integrators can only take energy out, so more kinetic energy than that was made by the method;
// or a tet has inverted (no element of these bodies comes near inversion under its own weight).
// The sweep runs both cases over E from 1e5 to 1e10 Pa and dt of 1/240, 1/60 and 1/30 s: the
// range in which each method stays stable.
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "cli/bench_args.h"
#include "cli/commands.h"
#include "graphfrac/mesh.h"
#include "graphfrac/world.h"

#ifdef GF_CLI_HAS_BULLET_SOFTBODY
// Bullet's btSoftBody::TetraScratch has no constructor; resizing its array copies an
// uninitialised default, which Bullet's own CreateFromTetGenData does too.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <BulletSoftBody/btDeformableBodySolver.h>
#include <BulletSoftBody/btDeformableGravityForce.h>
#include <BulletSoftBody/btDeformableLinearElasticityForce.h>
#include <BulletSoftBody/btDeformableMultiBodyConstraintSolver.h>
#include <BulletSoftBody/btDeformableMultiBodyDynamicsWorld.h>
#include <BulletSoftBody/btDeformableNeoHookeanForce.h>
#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyHelpers.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <btBulletDynamicsCommon.h>
#endif

namespace gf::cli {

namespace {

using Clock = std::chrono::steady_clock;
constexpr double kGravity = 9.81, kDensity = 1000, kPoisson = 0.3;

enum class CaseKind { Cantilever, Drop };

struct Setup {
  CaseKind kind;
  TetMesh mesh;                   // at its start position
  std::vector<int32_t> clamped;   // nodes held still
  std::vector<int32_t> measured;  // tip nodes (cantilever) or all nodes (drop)
  double length = 1;              // the body's size, for the stability bound
  double seconds = 2;
  std::vector<double> mass;  // lumped rho V / 4 per node, for the energy bound
};

// Six times the signed volume of tet t with its nodes where position(n, k) puts them.
template <class Position>
double signedVolume6(const TetMesh& mesh, size_t t, Position position) {
  const int32_t* v = &mesh.tets[4 * t];
  double e[3][3];
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) e[i][k] = position(v[i + 1], k) - position(v[0], k);
  return e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) -
         e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
         e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
}

// Tets whose volume has changed sign or vanished since the start: under its own weight no
// element of these bodies comes anywhere near inversion, so each one is the method's failure.
template <class Position>
int invertedTets(const TetMesh& mesh, Position position) {
  const auto rest = [&](int32_t n, int k) { return mesh.positions[3 * size_t(n) + size_t(k)]; };
  int count = 0;
  for (size_t t = 0; t < mesh.tetCount(); ++t)
    if (!(signedVolume6(mesh, t, position) * signedVolume6(mesh, t, rest) > 0)) ++count;
  return count;
}

// Lumped masses rho V / 4, as graphfrac's (eq 2.10, row-summed); Bullet is given the same.
std::vector<double> lumpedMasses(const TetMesh& mesh) {
  std::vector<double> mass(mesh.nodeCount(), 0);
  const auto at = [&](int32_t n, int k) { return mesh.positions[3 * size_t(n) + size_t(k)]; };
  for (size_t t = 0; t < mesh.tetCount(); ++t) {
    const double volume = std::abs(signedVolume6(mesh, t, at)) / 6;
    for (int k = 0; k < 4; ++k) mass[size_t(mesh.tets[4 * t + size_t(k)])] += kDensity * volume / 4;
  }
  return mass;
}

// Final kinetic energy over the work gravity has done since the start (infinite when the body
// has gained potential energy); position(n, k) and velocity(n, k) read node n's coordinate k.
template <class Position, class Velocity>
double energyRatio(const Setup& s, Position position, Velocity velocity) {
  double kinetic = 0, work = 0;
  for (size_t n = 0; n < s.mass.size(); ++n) {
    const int32_t i = int32_t(n);
    double v2 = 0;
    for (int k = 0; k < 3; ++k) v2 += velocity(i, k) * velocity(i, k);
    kinetic += 0.5 * s.mass[n] * v2;
    work += s.mass[n] * kGravity * (s.mesh.positions[3 * n + 1] - position(i, 1));
  }
  if (work > 0) return kinetic / work;
  return kinetic > 0 || work < 0 ? INFINITY : 0;  // energy from nowhere, or at rest
}

// Ran: the run finished (stable or not); the others: no result, and why.
enum class Status { Ran, TooSlowStep, TooSlowRun, Crashed };

struct Outcome {
  Status status = Status::Ran;
  bool stable = false;
  double msPerStep = 0;
  double measure = 0;      // cantilever: mean tip displacement [m]; drop: final mean height [m]
  double energyRatio = 0;  // final kinetic energy / work done by gravity
  int inverted = 0;        // tets inverted or flat at the end
};

Setup cantilever(int cells, double seconds) {
  Setup s{CaseKind::Cantilever,
          gen::box(1.0, 0.1, 0.1, 10 * cells, cells, cells),
          {},
          {},
          1.0,
          seconds,
          {}};
  for (int32_t n = 0; n < int32_t(s.mesh.nodeCount()); ++n) {
    const double x = s.mesh.positions[3 * size_t(n)];
    if (x < 1e-9) s.clamped.push_back(n);
    if (x > 1.0 - 1e-9) s.measured.push_back(n);
  }
  s.mass = lumpedMasses(s.mesh);
  return s;
}

Setup drop(int cells, double seconds) {
  Setup s{CaseKind::Drop, gen::box(0.2, 0.2, 0.2, cells, cells, cells), {}, {}, 0.2, seconds, {}};
  for (size_t n = 0; n < s.mesh.nodeCount(); ++n) {
    s.mesh.positions[3 * n] -= 0.1;
    s.mesh.positions[3 * n + 1] += 0.3;
    s.mesh.positions[3 * n + 2] -= 0.1;
    s.measured.push_back(int32_t(n));
  }
  s.mass = lumpedMasses(s.mesh);
  return s;
}

// Mean y of the measured nodes relative to their rest y (cantilever) or absolute (drop).
template <class PositionY>
double measureOf(const Setup& s, PositionY y) {
  double sum = 0;
  for (int32_t n : s.measured)
    sum += y(n) - (s.kind == CaseKind::Cantilever ? s.mesh.positions[3 * size_t(n) + 1] : 0.0);
  return sum / double(s.measured.size());
}

// What the measure is at equilibrium.
double reference(const Setup& s, double E) {
  if (s.kind == CaseKind::Drop) return 0.1 - kDensity * kGravity * 0.04 / (3 * E);
  BodyDef def;
  def.mesh = s.mesh;
  def.material = Material::stableNeoHookean(E, kPoisson, kDensity);
  def.solver.newtonIterations = 50;
  def.solver.newtonTolerance = 1e-10;
  def.solver.linearSolver = LinearSolverKind::Direct;
  Grip clamp;
  clamp.nodes = s.clamped;
  def.grips.push_back(clamp);
  World world(WorldDef{glm::vec3(0, -kGravity, 0), Backend::Cpu, nullptr, 1, {}});
  const BodyId id = world.createBody(def).value();
  (void)world.step(1e3);  // inertia weight rho L^2 / (E dt^2) < 1e-9: the static solve
  const std::span<const double> x = world.positions(id);
  return measureOf(s, [&](int32_t n) { return x[3 * size_t(n) + 1]; });
}

// Finite, within one body length of the reference, with no more kinetic energy than gravity's
// work (1 % slack for single-precision Bullet) and no inverted tet (file comment).
bool plausible(const Setup& s, const Outcome& o, double ref) {
  return o.stable && std::isfinite(o.measure) && std::abs(o.measure - ref) < s.length &&
         o.energyRatio <= 1.01 && o.inverted == 0;
}

Outcome runGraphfrac(const Setup& s, double E, double dt, LinearSolverKind solver) {
  BodyDef def;
  def.mesh = s.mesh;
  def.material = Material::stableNeoHookean(E, kPoisson, kDensity);
  def.solver.linearSolver = solver;
  if (!s.clamped.empty()) {
    Grip clamp;
    clamp.nodes = s.clamped;
    def.grips.push_back(clamp);
  }
  WorldDef wd{glm::vec3(0, -kGravity, 0), Backend::Cpu, nullptr, 1, {}};
  if (s.kind == CaseKind::Drop) wd.colliders.push_back(Collider{});  // the ground plane y = 0
  World world(wd);
  Result<BodyId> id = world.createBody(def);
  if (!id) {
    std::fprintf(stderr, "graphfrac bench peer: %s\n", id.error().message.c_str());
    Outcome failed;
    failed.status = Status::Crashed;
    return failed;
  }
  const int steps = int(std::lround(s.seconds / dt));
  Outcome o;
  double sum = 0;
  int counted = 0;
  const auto t0 = Clock::now();
  for (int k = 0; k < steps; ++k) {
    (void)world.step(dt);
    if (s.kind == CaseKind::Cantilever && k >= steps / 2) {
      const std::span<const double> x = world.positions(id.value());
      sum += measureOf(s, [&](int32_t n) { return x[3 * size_t(n) + 1]; });
      ++counted;
    }
  }
  o.msPerStep = std::chrono::duration<double, std::milli>(Clock::now() - t0).count() / steps;
  const std::span<const double> x = world.positions(id.value());
  o.measure = s.kind == CaseKind::Cantilever
                  ? sum / std::max(counted, 1)
                  : measureOf(s, [&](int32_t n) { return x[3 * size_t(n) + 1]; });
  o.stable = true;
  for (double v : x) o.stable = o.stable && std::isfinite(v);
  const std::span<const double> v = world.velocities(id.value());
  o.energyRatio = energyRatio(
      s, [&](int32_t n, int k) { return x[3 * size_t(n) + size_t(k)]; },
      [&](int32_t n, int k) { return v[3 * size_t(n) + size_t(k)]; });
  o.inverted = invertedTets(s.mesh, [&](int32_t n, int k) { return x[3 * size_t(n) + size_t(k)]; });
  return o;
}

struct Limits {
  double stepSeconds = 2;   // one Bullet step
  double runSeconds = 120;  // one Bullet run, setup included
};

#ifdef GF_CLI_HAS_BULLET_SOFTBODY
// Which of Bullet's integrators and elastic forces a run uses (file comment).
struct BulletModel {
  bool implicit = true;
  bool linear = false;  // btDeformableLinearElasticityForce instead of the Neo-Hookean one
};

// One Bullet deformable world holding the setup's body (and the ground for the drop).
class BulletRun {
 public:
  BulletRun(const Setup& s, double E, BulletModel model)
      : m_solver(new btDeformableBodySolver),
        m_constraints(new btDeformableMultiBodyConstraintSolver) {
    m_constraints->setDeformableSolver(m_solver.get());
    m_world = std::make_unique<btDeformableMultiBodyDynamicsWorld>(
        &m_dispatcher, &m_broadphase, m_constraints.get(), &m_config, m_solver.get());
    const btVector3 g(0, btScalar(-kGravity), 0);
    m_world->setGravity(g);
    m_world->getWorldInfo().m_gravity = g;
    m_world->setImplicit(model.implicit);
    m_world->setUseProjection(model.implicit);  // the implicit solve does nothing without it
    m_world->setLineSearch(false);
    m_world->getSolverInfo().m_deformable_erp = 0.3;
    m_world->getSolverInfo().m_deformable_maxErrorReduction = btScalar(200);
    m_world->getSolverInfo().m_leastSquaresResidualThreshold = btScalar(1e-3);
    m_world->getSolverInfo().m_splitImpulse = true;
    m_world->getSolverInfo().m_numIterations = 100;

    const size_t nn = s.mesh.nodeCount();
    std::vector<btScalar> mass(nn);
    std::vector<btVector3> pos(nn);
    for (size_t n = 0; n < nn; ++n) {
      pos[n] = btVector3(btScalar(s.mesh.positions[3 * n]), btScalar(s.mesh.positions[3 * n + 1]),
                         btScalar(s.mesh.positions[3 * n + 2]));
      mass[n] = btScalar(s.mass[n]);
    }
    m_body = new btSoftBody(&m_world->getWorldInfo(), int(nn), pos.data(), mass.data());
    for (size_t t = 0; t < s.mesh.tetCount(); ++t) {
      const int32_t* v = &s.mesh.tets[4 * t];
      m_body->appendTetra(v[0], v[1], v[2], v[3]);
      // The node tree is built along links (file comment); bcheckexist skips shared edges.
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) m_body->appendLink(v[a], v[b], nullptr, true);
    }
    m_body->initializeDmInverse();
    m_body->m_tetraScratches.resize(m_body->m_tetras.size());
    m_body->m_tetraScratchesTn.resize(m_body->m_tetras.size());
    for (int32_t n : s.clamped) m_body->setMass(n, 0);
    m_body->getCollisionShape()->setMargin(btScalar(0.005));
    m_body->m_cfg.kKHR = 1;
    m_body->m_cfg.kCHR = 1;
    m_body->m_cfg.kDF = btScalar(0.5);
    m_body->m_cfg.collisions = btSoftBody::fCollision::SDF_RD | btSoftBody::fCollision::SDF_RDN;
    m_body->m_sleepingThreshold = 0;
    btSoftBodyHelpers::generateBoundaryFaces(m_body);
    m_world->addSoftBody(m_body);
    m_gravity = std::make_unique<btDeformableGravityForce>(g);
    m_world->addForce(m_body, m_gravity.get());
    // Smith et al.'s constants for the requested small-strain E and nu (file comment).
    const double mu = E / (2 * (1 + kPoisson)),
                 lambda = E * kPoisson / ((1 + kPoisson) * (1 - 2 * kPoisson));
    if (model.linear) {
      m_elastic = std::make_unique<btDeformableLinearElasticityForce>(
          btScalar(mu), btScalar(lambda), btScalar(0), btScalar(0));
    } else {
      m_elastic = std::make_unique<btDeformableNeoHookeanForce>(
          btScalar(4.0 / 3.0 * mu), btScalar(lambda + 5.0 / 6.0 * mu), btScalar(0));
    }
    m_world->addForce(m_body, m_elastic.get());

    if (s.kind == CaseKind::Drop) {
      m_groundShape = std::make_unique<btBoxShape>(btVector3(50, 50, 50));
      btTransform at;
      at.setIdentity();
      at.setOrigin(btVector3(0, -50, 0));
      m_groundMotion = std::make_unique<btDefaultMotionState>(at);
      btRigidBody::btRigidBodyConstructionInfo info(0, m_groundMotion.get(), m_groundShape.get());
      m_ground = std::make_unique<btRigidBody>(info);
      m_ground->setFriction(1);
      m_world->addRigidBody(m_ground.get());
    }
  }
  ~BulletRun() {
    if (m_ground) m_world->removeRigidBody(m_ground.get());
    m_world->removeSoftBody(m_body);
    delete m_body;
  }
  BulletRun(const BulletRun&) = delete;
  BulletRun& operator=(const BulletRun&) = delete;

  void step(double dt) { m_world->stepSimulation(btScalar(dt), 0); }
  double y(int32_t n) const { return double(m_body->m_nodes[n].m_x.y()); }
  double x(int32_t n, int k) const { return double(m_body->m_nodes[n].m_x[k]); }
  double v(int32_t n, int k) const { return double(m_body->m_nodes[n].m_v[k]); }
  bool finite() const {
    for (int n = 0; n < m_body->m_nodes.size(); ++n)
      for (int k = 0; k < 3; ++k)
        if (!std::isfinite(double(m_body->m_nodes[n].m_x[k]))) return false;
    return true;
  }

 private:
  btSoftBodyRigidBodyCollisionConfiguration m_config;
  btCollisionDispatcher m_dispatcher{&m_config};
  btDbvtBroadphase m_broadphase;
  std::unique_ptr<btDeformableBodySolver> m_solver;
  std::unique_ptr<btDeformableMultiBodyConstraintSolver> m_constraints;
  std::unique_ptr<btDeformableMultiBodyDynamicsWorld> m_world;
  btSoftBody* m_body = nullptr;  // owned; removed from the world before it is deleted
  std::unique_ptr<btDeformableGravityForce> m_gravity;
  std::unique_ptr<btDeformableLagrangianForce> m_elastic;
  std::unique_ptr<btCollisionShape> m_groundShape;
  std::unique_ptr<btDefaultMotionState> m_groundMotion;
  std::unique_ptr<btRigidBody> m_ground;
};

Outcome runBullet(const Setup& s, double E, double dt, BulletModel model,
                  const std::function<void()>& stepDone) {
  BulletRun run(s, E, model);
  const int steps = int(std::lround(s.seconds / dt));
  Outcome o;
  double sum = 0;
  int counted = 0;
  const auto t0 = Clock::now();
  for (int k = 0; k < steps; ++k) {
    run.step(dt);
    stepDone();
    if (s.kind == CaseKind::Cantilever && k >= steps / 2) {
      sum += measureOf(s, [&](int32_t n) { return run.y(n); });
      ++counted;
    }
  }
  o.msPerStep = std::chrono::duration<double, std::milli>(Clock::now() - t0).count() / steps;
  o.measure = s.kind == CaseKind::Cantilever ? sum / std::max(counted, 1)
                                             : measureOf(s, [&](int32_t n) { return run.y(n); });
  o.stable = run.finite();
  o.energyRatio = energyRatio(
      s, [&](int32_t n, int k) { return run.x(n, k); },
      [&](int32_t n, int k) { return run.v(n, k); });
  o.inverted = invertedTets(s.mesh, [&](int32_t n, int k) { return run.x(n, k); });
  return o;
}

bool writeAll(int fd, const void* data, size_t size) {
  const char* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = write(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    size -= size_t(n);
  }
  return true;
}

bool readAll(int fd, void* data, size_t size) {
  char* p = static_cast<char*>(data);
  while (size > 0) {
    const ssize_t n = read(fd, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    p += n;
    size -= size_t(n);
  }
  return true;
}

// runBullet in a child process, stopped when a step or the run exceeds its limit: Bullet's loops
// cannot be interrupted from inside, and a stalled run must not stall the comparison.
Outcome runBulletBounded(const Setup& s, double E, double dt, BulletModel model,
                         const Limits& limits) {
  Outcome failed;
  failed.status = Status::Crashed;
  int fd[2];
  if (pipe(fd) != 0) return failed;
  const pid_t pid = fork();
  if (pid < 0) {
    close(fd[0]);
    close(fd[1]);
    return failed;
  }
  if (pid == 0) {
    close(fd[0]);
    const char tick = 's', result = 'r';
    const Outcome o = runBullet(s, E, dt, model, [&] { (void)writeAll(fd[1], &tick, 1); });
    const bool ok = writeAll(fd[1], &result, 1) && writeAll(fd[1], &o, sizeof o);
    _exit(ok ? 0 : 1);  // not exit: the parent's stdio buffers and objects are the parent's
  }
  close(fd[1]);
  Outcome o = failed;
  const auto start = Clock::now();
  bool done = false;
  while (!done) {
    const double left =
        limits.runSeconds - std::chrono::duration<double>(Clock::now() - start).count();
    const double wait = std::min(limits.stepSeconds, left);
    if (wait <= 0) {
      o.status = Status::TooSlowRun;
      break;
    }
    pollfd p{fd[0], POLLIN, 0};
    const int ready = poll(&p, 1, int(std::ceil(wait * 1000)));
    if (ready < 0 && errno == EINTR) continue;
    if (ready == 0) {
      o.status = wait < limits.stepSeconds ? Status::TooSlowRun : Status::TooSlowStep;
      break;
    }
    char c = 0;
    if (ready < 0 || !readAll(fd[0], &c, 1)) break;  // the child died: Crashed
    if (c == 'r') done = readAll(fd[0], &o, sizeof o);
  }
  if (!done) kill(pid, SIGKILL);
  waitpid(pid, nullptr, 0);
  close(fd[0]);
  if (!done && o.status == Status::Ran) o.status = Status::Crashed;
  return o;
}
#endif

struct Method {
  const char* name;
  std::function<Outcome(const Setup&, double E, double dt)> run;
};

Outcome ours(const Setup& s, double E, double dt) {
  return runGraphfrac(s, E, dt, LinearSolverKind::Multigrid);
}
Outcome oursDirect(const Setup& s, double E, double dt) {
  return runGraphfrac(s, E, dt, LinearSolverKind::Direct);
}
Outcome oursPcg(const Setup& s, double E, double dt) {
  return runGraphfrac(s, E, dt, LinearSolverKind::PCG);
}

void printRow(const char* kase, const char* method, double E, double dt, int tets, const Outcome& o,
              double ref, const Setup& s, const Limits& limits) {
  if (o.status != Status::Ran) {
    char why[64] = "crashed";
    if (o.status == Status::TooSlowStep)
      std::snprintf(why, sizeof why, "too slow (> %g s/step)", limits.stepSeconds);
    if (o.status == Status::TooSlowRun)
      std::snprintf(why, sizeof why, "too slow (> %g s/run)", limits.runSeconds);
    std::printf("%s,%s,%.0e,%.5f,%d,%s,-,-,%.6g,-,-,-\n", kase, method, E, dt, tets, why, ref);
    std::fflush(stdout);
    return;
  }
  const bool ok = plausible(s, o, ref);
  const double scale = s.kind == CaseKind::Cantilever ? std::abs(ref) : s.length;
  std::printf("%s,%s,%.0e,%.5f,%d,%s,%.3f,%.6g,%.6g,%.3e,%.3g,%d\n", kase, method, E, dt, tets,
              ok ? "stable" : "unstable", o.msPerStep, o.measure, ref,
              ok ? std::abs(o.measure - ref) / scale : NAN, o.energyRatio, o.inverted);
  std::fflush(stdout);
}

}  // namespace

int benchPeer(int argc, char** argv) {
  int cells = 2;
  double seconds = 2;
  bool noSweep = false;
  Limits limits;
  if (const int e = parseBenchArgs("peer", argc, argv,
                                   {{"--cells", &cells, 1, 16},
                                    {"--seconds", &seconds},
                                    {"--bullet-step-limit", &limits.stepSeconds},
                                    {"--bullet-run-limit", &limits.runSeconds},
                                    {"--no-sweep", &noSweep}});
      e != kExitOk)
    return e;
  const bool sweep = !noSweep;
  std::vector<Method> methods = {
      {"graphfrac-multigrid", ours}, {"graphfrac-direct", oursDirect}, {"graphfrac-pcg", oursPcg}};
#ifdef GF_CLI_HAS_BULLET_SOFTBODY
  const struct {
    const char* name;
    BulletModel model;
  } bullets[] = {{"bullet-implicit", {true, false}},
                 {"bullet-explicit", {false, false}},
                 {"bullet-implicit-linear", {true, true}}};
  for (const auto& b : bullets)
    methods.push_back({b.name, [&limits, model = b.model](const Setup& s, double E, double dt) {
                         return runBulletBounded(s, E, dt, model, limits);
                       }});
#else
  std::printf("# Bullet's soft-body library was not found at build time: graphfrac only\n");
#endif
  const Setup beam = cantilever(cells, seconds), box = drop(2 * cells, seconds);
  std::printf(
      "# cantilever 1 x 0.1 x 0.1 m, %zu tets; drop 0.2 m cube, %zu tets; stable "
      "Neo-Hookean, nu %.2f, rho %.0f; %.2f s simulated per run; error: |measure - "
      "reference| / |reference| (cantilever) or / body size (drop)\n",
      beam.mesh.tetCount(), box.mesh.tetCount(), kPoisson, kDensity, seconds);
  std::printf(
      "case,method,E_Pa,dt_s,tets,outcome,ms_per_step,measure_m,reference_m,error,"
      "kinetic_over_gravity_work,inverted_tets\n");
  const double dts[] = {1.0 / 240, 1.0 / 60, 1.0 / 30};
  for (double dt : {1.0 / 240, 1.0 / 60}) {
    for (const Setup* s : {&beam, &box}) {
      const double E = s->kind == CaseKind::Cantilever ? 1e7 : 1e6;
      const double ref = reference(*s, E);
      for (const Method& m : methods)
        printRow(s->kind == CaseKind::Cantilever ? "cantilever" : "drop", m.name, E, dt,
                 int(s->mesh.tetCount()), m.run(*s, E, dt), ref, *s, limits);
    }
  }
  if (!sweep) return kExitOk;
  std::printf("# stable range: each case over E and dt\n");
  for (const Setup* s : {&beam, &box}) {
    for (double E : {1e5, 1e6, 1e7, 1e8, 1e9, 1e10}) {
      const double ref = reference(*s, E);
      for (double dt : dts)
        for (const Method& m : methods)
          printRow(s->kind == CaseKind::Cantilever ? "cantilever-sweep" : "drop-sweep", m.name, E,
                   dt, int(s->mesh.tetCount()), m.run(*s, E, dt), ref, *s, limits);
    }
  }
  return kExitOk;
}

}  // namespace gf::cli
