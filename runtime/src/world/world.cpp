// World: body storage (generational slots), validation at the API boundary, stepping.
#include "graphfrac/world.h"

#include <chrono>
#include <cmath>
#include <glm/geometric.hpp>
#include <string>
#include <vector>

#include "fem/fem_body.h"
#include "fem/integrator.h"
#include "graphfrac/jobs.h"

namespace gf {

namespace {
// Contact penalty stiffness per unit mass when the collider names none: dt^2 k = 100 makes
// contact a hundred times stiffer than inertia, so a node is pushed out within about a step
// and rests g dt^2 / 100 deep.
constexpr double kAutoContactStiffnessDt2 = 100.0;

bool finite3(glm::vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

struct BodyRecord {
  detail::FemModel model;
  detail::FemState state;
  std::unique_ptr<detail::Integrator> integrator;
};

struct Slot {
  uint32_t generation = 1;
  std::unique_ptr<BodyRecord> body;  // null when free
};
}  // namespace

struct World::Impl {
  WorldDef def;
  JobSystem* jobs = nullptr;
  std::vector<Slot> slots;
  std::vector<ColliderData> colliders;
  StepTimings timings;
  double time = 0;
  double lastSubstep = 1.0 / 60;  // contact stiffness of stats() follows the last step
  std::string pendingWarning;

  BodyRecord* get(BodyId id) const {
    if (id.index == 0 || id.index > slots.size()) return nullptr;
    const Slot& s = slots[id.index - 1];
    return (s.body && s.generation == id.generation) ? s.body.get() : nullptr;
  }
  detail::StepContext context(double dt) {
    for (size_t c = 0; c < colliders.size(); ++c) {
      const double k = def.colliders[c].stiffness;
      colliders[c].stiffness = k > 0 ? k : kAutoContactStiffnessDt2 / (dt * dt);
    }
    detail::StepContext ctx;
    ctx.dt = dt;
    ctx.gravity = {def.gravity.x, def.gravity.y, def.gravity.z};
    ctx.colliders = colliders.data();
    ctx.colliderCount = int(colliders.size());
    return ctx;
  }
};

World::World(const WorldDef& def) : m_impl(std::make_unique<Impl>()) {
  Impl& w = *m_impl;
  w.def = def;
  w.jobs = def.jobs ? def.jobs : &serialJobs();
  if (w.def.substeps < 1) {
    w.pendingWarning =
        "WorldDef.substeps: must be >= 1, got " + std::to_string(def.substeps) + "; using 1";
    w.def.substeps = 1;
  }
  if (!finite3(w.def.gravity)) {
    w.pendingWarning = "WorldDef.gravity: not finite; using zero gravity";
    w.def.gravity = glm::vec3(0);
  }
  for (size_t i = 0; i < w.def.colliders.size(); ++i) {
    const Collider& c = w.def.colliders[i];
    ColliderData d;
    d.kind = static_cast<int>(c.kind);
    d.point = {c.point.x, c.point.y, c.point.z};
    Vec3 n{c.normal.x, c.normal.y, c.normal.z};
    const double len = norm(n);
    d.normal = len > 0 ? (1.0 / len) * n : Vec3{0, 1, 0};
    d.halfExtents = {c.halfExtents.x, c.halfExtents.y, c.halfExtents.z};
    d.radius = c.radius;
    w.colliders.push_back(d);
  }
}

World::~World() = default;

Result<BodyId> World::createBody(BodyDef def) {
  if (def.mesh.tetCount() == 0) return fail("BodyDef.mesh: has no tetrahedra");
  int flipped = 0;
  if (auto r = validate(def.mesh, "BodyDef.mesh", &flipped); !r) return r.error();
  if (auto r = def.material.check(); !r) return fail("BodyDef.", r.error().message);
  const int32_t nn = int32_t(def.mesh.nodeCount());
  for (size_t g = 0; g < def.grips.size(); ++g) {
    if (!finite3(def.grips[g].velocity))
      return fail("BodyDef.grips[", std::to_string(g), "].velocity: not finite");
    for (int32_t n : def.grips[g].nodes)
      if (n < 0 || n >= nn)
        return fail("BodyDef.grips[", std::to_string(g), "].nodes: node ", std::to_string(n),
                    " out of range [0, ", std::to_string(nn), ")");
  }
  for (size_t f = 0; f < def.forces.size(); ++f) {
    if (def.forces[f].node < 0 || def.forces[f].node >= nn)
      return fail("BodyDef.forces[", std::to_string(f),
                  "].node: ", std::to_string(def.forces[f].node), " out of range [0, ",
                  std::to_string(nn), ")");
    if (!finite3(def.forces[f].force))
      return fail("BodyDef.forces[", std::to_string(f), "].force: not finite");
  }
  if (!finite3(def.initialVelocity)) return fail("BodyDef.initialVelocity: not finite");
  const SolverSettings& s = def.solver;
  if (s.newtonIterations < 1) return fail("BodyDef.solver.newtonIterations: must be >= 1");
  if (!(s.newtonTolerance > 0)) return fail("BodyDef.solver.newtonTolerance: must be > 0");
  if (s.maxLinearIterations < 1) return fail("BodyDef.solver.maxLinearIterations: must be >= 1");
  if (!(s.linearTolerance > 0)) return fail("BodyDef.solver.linearTolerance: must be > 0");

  auto body = std::make_unique<BodyRecord>();
  body->model = detail::buildFemModel(def);
  body->state.x = body->model.restPositions;
  body->state.v.resize(body->state.x.size());
  for (size_t i = 0; i < body->state.v.size(); ++i)
    body->state.v[i] = def.initialVelocity[int(i % 3)];
  body->integrator = std::make_unique<detail::Integrator>(body->model);

  Impl& w = *m_impl;
  size_t slot = 0;
  while (slot < w.slots.size() && w.slots[slot].body) ++slot;
  if (slot == w.slots.size()) w.slots.emplace_back();
  w.slots[slot].body = std::move(body);
  return BodyId{uint32_t(slot + 1), w.slots[slot].generation};
}

Result<void> World::destroyBody(BodyId id) {
  if (!m_impl->get(id)) return fail("destroyBody: stale or null BodyId");
  Slot& s = m_impl->slots[id.index - 1];
  s.body.reset();
  ++s.generation;
  return {};
}

bool World::isValid(BodyId id) const { return m_impl->get(id) != nullptr; }

StepStatus World::step(double dt) {
  StepStatus st;
  Impl& w = *m_impl;
  if (!std::isfinite(dt) || dt <= 0) {
    st.flags = kStepInvalidInput;
    st.message = "step: dt must be positive and finite, got " + std::to_string(dt);
    return st;
  }
  if (!w.pendingWarning.empty()) {
    st.message = w.pendingWarning;
    w.pendingWarning.clear();
  }
  const auto t0 = std::chrono::steady_clock::now();
  w.timings = {};
  const double h = dt / w.def.substeps;
  w.lastSubstep = h;
  const detail::StepContext ctx = w.context(h);
  for (int sub = 0; sub < w.def.substeps; ++sub) {
    for (Slot& s : w.slots) {
      if (!s.body) continue;
      const detail::BodyStepReport r =
          s.body->integrator->step(s.body->model, s.body->state, ctx, *w.jobs);
      st.flags |= r.flags;
      st.newtonIterations += r.newtonIterations;
      st.linearIterations += r.linearIterations;
      st.residual = std::max(st.residual, r.residual);
      w.timings.elementsMs += r.elementsMs;
      w.timings.assemblyMs += r.assemblyMs;
      w.timings.solveMs += r.solveMs;
    }
  }
  w.time += dt;
  w.timings.totalMs =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (st.has(kStepNanContained) && st.message.empty())
    st.message = "a body produced a non-finite state and was restored to its previous step";
  else if (st.has(kStepNotConverged) && st.message.empty())
    st.message = "the solver stopped at its iteration cap";
  return st;
}

std::span<const double> World::positions(BodyId id) const {
  const BodyRecord* b = m_impl->get(id);
  return b ? std::span<const double>(b->state.x) : std::span<const double>();
}

std::span<const double> World::velocities(BodyId id) const {
  const BodyRecord* b = m_impl->get(id);
  return b ? std::span<const double>(b->state.v) : std::span<const double>();
}

Result<void> World::setVelocity(BodyId id, glm::dvec3 v) {
  BodyRecord* b = m_impl->get(id);
  if (!b) return fail("setVelocity: stale or null BodyId");
  if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
    return fail("setVelocity: velocity is not finite");
  for (size_t i = 0; i < b->state.v.size(); ++i) b->state.v[i] = v[int(i % 3)];
  return {};
}

namespace {
Result<void> overwrite(std::vector<double>& dst, std::span<const double> src, const char* what) {
  if (src.size() != dst.size())
    return fail(what, ": expected ", std::to_string(dst.size()), " values, got ",
                std::to_string(src.size()));
  for (size_t i = 0; i < src.size(); ++i)
    if (!std::isfinite(src[i])) return fail(what, ": value ", std::to_string(i), " is not finite");
  dst.assign(src.begin(), src.end());
  return {};
}
}  // namespace

Result<void> World::setPositions(BodyId id, std::span<const double> x) {
  BodyRecord* b = m_impl->get(id);
  if (!b) return fail("setPositions: stale or null BodyId");
  return overwrite(b->state.x, x, "setPositions");
}

Result<void> World::setVelocities(BodyId id, std::span<const double> v) {
  BodyRecord* b = m_impl->get(id);
  if (!b) return fail("setVelocities: stale or null BodyId");
  return overwrite(b->state.v, v, "setVelocities");
}

BodyStats World::stats(BodyId id) const {
  BodyStats s;
  BodyRecord* b = m_impl->get(id);
  if (!b) return s;
  const auto& m = b->model;
  const auto& x = b->state.x;
  const auto& v = b->state.v;
  const glm::dvec3 g(m_impl->def.gravity);
  for (int32_t n = 0; n < m.nodeCount; ++n) {
    const glm::dvec3 xi(x[3 * n], x[3 * n + 1], x[3 * n + 2]);
    const glm::dvec3 vi(v[3 * n], v[3 * n + 1], v[3 * n + 2]);
    const double mi = m.nodeMass[n];
    s.mass += mi;
    s.kineticEnergy += 0.5 * mi * glm::dot(vi, vi);
    s.gravityEnergy -= mi * glm::dot(g, xi);
    s.linearMomentum += mi * vi;
    s.angularMomentum += glm::cross(xi, mi * vi);
  }
  // The element buffers are scratch between steps, so evaluating energies here is safe.
  const detail::StepContext ctx = m_impl->context(m_impl->lastSubstep);
  const detail::EnergyBreakdown e = b->integrator->energies(m, x.data(), ctx, *m_impl->jobs);
  s.elasticEnergy = e.elastic;
  s.contactEnergy = e.contact;
  return s;
}

const StepTimings& World::timings() const { return m_impl->timings; }

double World::time() const { return m_impl->time; }

}  // namespace gf
