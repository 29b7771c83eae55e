// World: body storage (generational slots), validation at the API boundary, stepping.
#include "graphfrac/world.h"

#include <chrono>
#include <cmath>
#include <glm/geometric.hpp>
#include <string>
#include <vector>

#include "fem/fem_body.h"
#include "fem/integrator.h"
#include "fracture/fracture_body.h"
#include "graphfrac/jobs.h"
#include "kernels/edge_stress.h"
#include "kernels/element.h"
#include "kernels/plasticity.h"
#include "surface/crack_surface.h"

namespace gf {

namespace {
// Contact penalty stiffness per unit mass when the collider names none: dt^2 k = 100 makes
// contact a hundred times stiffer than inertia, so a node is pushed out within about a step
// and rests g dt^2 / 100 deep.
constexpr double kAutoContactStiffnessDt2 = 100.0;

bool finite3(glm::vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// The render surface of a body, created on the first World::surface() call.
struct SurfaceRecord {
  TetMesh rest;                      // CrackSurface keeps references to these two
  detail::EdgeGraph ownGraph;        // for bodies without fracture
  std::vector<uint8_t> noBreaks;     // idem
  std::vector<int32_t> oneFragment;  // idem
  detail::CrackSurface surface;
  uint64_t brokenCount = 0;
};

struct BodyRecord {
  detail::FemModel model;
  detail::FemState state;
  std::unique_ptr<detail::Integrator> integrator;
  std::unique_ptr<detail::FractureBody> fracture;  // null: no fracture, no edge stresses
  std::unique_ptr<SurfaceRecord> surface;          // null until somebody asks for it
};

detail::BladePose toPose(const glm::mat4& m) {
  detail::BladePose p;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) p.rotation(i, j) = m[j][i];  // glm is column-major
  p.translation = {m[3][0], m[3][1], m[3][2]};
  return p;
}

bool finiteMat(const glm::mat4& m) {
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i)
      if (!std::isfinite(m[j][i])) return false;
  return true;
}

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
  std::vector<FractureEvent> fractureEvents;
  std::vector<FragmentEvent> fragmentEvents;
  double time = 0;
  double lastSubstep = 1.0 / 60;  // contact stiffness of stats() follows the last step
  std::string pendingWarning;

  BodyRecord* get(BodyId id) const {
    if (id.index == 0 || id.index > slots.size()) return nullptr;
    const Slot& s = slots[id.index - 1];
    return (s.body && s.generation == id.generation) ? s.body.get() : nullptr;
  }
  // Converts a body's breaks and splits of the last detect() into public events.
  void collectEvents(BodyId id, const BodyRecord& b) {
    const detail::FractureBody& f = *b.fracture;
    const auto& g = f.graph();
    for (size_t i = 0; i < f.breaks().size(); ++i) {
      const detail::EdgeBreak& e = f.breaks()[i];
      FractureEvent ev;
      ev.body = id;
      ev.edge = e.edge;
      ev.nodeA = g.edgeNodes[2 * e.edge];
      ev.nodeB = g.edgeNodes[2 * e.edge + 1];
      const double* xa = &b.state.x[3 * ev.nodeA];
      const double* xb = &b.state.x[3 * ev.nodeB];
      ev.position = glm::vec3(float(0.5 * (xa[0] + xb[0])), float(0.5 * (xa[1] + xb[1])),
                              float(0.5 * (xa[2] + xb[2])));
      ev.stress = float(e.stress);
      ev.cause = static_cast<FractureEvent::Cause>(f.breakCause()[i]);
      fractureEvents.push_back(ev);
    }
    const detail::FragmentProperties& p = f.splitProperties();
    for (const detail::FragmentSplit& s : f.splits()) {
      FragmentEvent ev;
      ev.body = id;
      ev.fragment = s.created;
      ev.parent = s.parent;
      ev.nodeCount = int32_t(f.fragments().nodes(s.created).size());
      ev.volume = p.volume[s.created];
      ev.mass = p.mass[s.created];
      ev.centreOfMass =
          glm::vec3(float(p.centre[3 * s.created]), float(p.centre[3 * s.created + 1]),
                    float(p.centre[3 * s.created + 2]));
      ev.velocity =
          glm::vec3(float(p.velocity[3 * s.created]), float(p.velocity[3 * s.created + 1]),
                    float(p.velocity[3 * s.created + 2]));
      fragmentEvents.push_back(ev);
    }
  }

  // Multiplicative plasticity after the step (eq 2.3-2.5): only yielding elements change.
  void plasticUpdate(BodyRecord& b, double h) {
    const detail::FemModel& m = b.model;
    detail::FemState& s = b.state;
    const PlasticParams params{m.plasticity.yieldStress, m.plasticity.flowRate,
                               m.plasticity.hardening};
    jobs->parallelFor(uint32_t(m.tetCount), 256, [&](uint32_t lo, uint32_t hi) {
      for (uint32_t t = lo; t < hi; ++t) {
        Vec3 xe[4];
        for (int a = 0; a < 4; ++a) {
          const double* p = &s.x[3 * m.tets[4 * t + a]];
          xe[a] = {p[0], p[1], p[2]};
        }
        MaterialCoeffs c = m.coeffs;
        if (!m.fibreDir.empty()) c.fibreDir = m.fibreDir[t];
        const Mat3 Fe = deformationGradient(xe, s.plasticInverse[t]);
        if (gf::plasticUpdate(params, materialStress(c, Fe), Fe, h, s.Fp[t], s.FpInv[t],
                              s.plasticDelta[t]))
          s.plasticInverse[t] = m.restInverse[t] * s.FpInv[t];
      }
    });
  }

  // Keeps a requested render surface in step with the body: topology only after fractures.
  void updateSurface(BodyRecord& b) {
    SurfaceRecord& r = *b.surface;
    // Partial cracks are rendered too, so every newly broken edge changes the topology.
    if (b.fracture && uint64_t(b.fracture->brokenCount()) != r.brokenCount) {
      r.brokenCount = uint64_t(b.fracture->brokenCount());
      r.surface.rebuild(b.fracture->broken().data(), b.fracture->fragments().nodeFragment().data(),
                        b.state.x.data());
    } else {
      r.surface.updatePositions(b.state.x.data());
    }
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
  if (def.plasticity.enabled) {
    const PlasticitySettings& p = def.plasticity;
    if (!(std::isfinite(p.yieldStress) && p.yieldStress > 0))
      return fail("BodyDef.plasticity.yieldStress: must be positive and finite");
    if (!(p.flowRate >= 0 && p.flowRate <= 1))
      return fail("BodyDef.plasticity.flowRate: must lie in [0, 1]");
    if (!(std::isfinite(p.hardening) && p.hardening >= 0))
      return fail("BodyDef.plasticity.hardening: must be >= 0 and finite");
  }
  if (!def.fibreField.empty()) {
    if (def.fibreField.size() != def.mesh.tetCount())
      return fail("BodyDef.fibreField: expected one direction per tet (",
                  std::to_string(def.mesh.tetCount()), "), got ",
                  std::to_string(def.fibreField.size()));
    for (size_t t = 0; t < def.fibreField.size(); ++t) {
      const glm::vec3 f = def.fibreField[t];
      if (!finite3(f) || double(f.x) * f.x + double(f.y) * f.y + double(f.z) * f.z < 1e-12)
        return fail("BodyDef.fibreField[", std::to_string(t), "]: must be finite and non-zero");
    }
  }
  if (def.fracture.enabled && (def.fracture.regions < 1))
    return fail("BodyDef.fracture.regions: must be >= 1");
  const SolverSettings& s = def.solver;
  if (s.newtonIterations < 1) return fail("BodyDef.solver.newtonIterations: must be >= 1");
  if (!(s.newtonTolerance > 0)) return fail("BodyDef.solver.newtonTolerance: must be > 0");
  if (s.maxLinearIterations < 1) return fail("BodyDef.solver.maxLinearIterations: must be >= 1");
  if (!(s.linearTolerance > 0)) return fail("BodyDef.solver.linearTolerance: must be > 0");
  if (s.linearSolver == LinearSolverKind::Multigrid) {
    const MultigridSettings& mg = s.multigrid;
    if (mg.levels.empty())
      return fail("BodyDef.solver.multigrid.levels: needs at least one coarse level");
    for (size_t i = 0; i < mg.levels.size(); ++i) {
      if (mg.levels[i] < 1 || (i > 0 && mg.levels[i] <= mg.levels[i - 1]))
        return fail(
            "BodyDef.solver.multigrid.levels: handle counts must be >= 1 and strictly "
            "increasing, coarsest first");
    }
    if (mg.preSweeps < 0 || mg.postSweeps < 0 || mg.preSweeps + mg.postSweeps < 1)
      return fail("BodyDef.solver.multigrid: preSweeps and postSweeps must be >= 0, together >= 1");
    if (mg.cycles < 1) return fail("BodyDef.solver.multigrid.cycles: must be >= 1");
    if (mg.coarseRefreshInterval < 1)
      return fail("BodyDef.solver.multigrid.coarseRefreshInterval: must be >= 1");
  }

  auto body = std::make_unique<BodyRecord>();
  body->model = detail::buildFemModel(def);
  body->state.x = body->model.restPositions;
  body->state.v.resize(body->state.x.size());
  for (size_t i = 0; i < body->state.v.size(); ++i)
    body->state.v[i] = def.initialVelocity[int(i % 3)];
  body->integrator = std::make_unique<detail::Integrator>(body->model);
  if (Result<void> r = body->integrator->setupSolver(body->model); !r.ok()) return r.error();
  Impl& w0 = *m_impl;
  if (def.fracture.enabled) {
    auto fb = detail::FractureBody::create(body->model, *w0.jobs);
    if (!fb) return fb.error();
    body->fracture = std::move(fb.value());
  }
  if (def.plasticity.enabled) {
    const size_t nt = body->model.tetCount;
    body->state.Fp.assign(nt, Mat3::identity());
    body->state.FpInv.assign(nt, Mat3::identity());
    body->state.plasticDelta.assign(nt, 0.0);
    body->state.plasticInverse = body->model.restInverse;
  }
  body->integrator->attach(body->fracture.get(),
                           def.plasticity.enabled ? &body->state.plasticInverse : nullptr);

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
  using Clock = std::chrono::steady_clock;
  auto ms = [](Clock::time_point a) {
    return std::chrono::duration<double, std::milli>(Clock::now() - a).count();
  };
  w.timings = {};
  w.fractureEvents.clear();
  w.fragmentEvents.clear();
  const double h = dt / w.def.substeps;
  w.lastSubstep = h;
  const detail::StepContext ctx = w.context(h);
  for (int sub = 0; sub < w.def.substeps; ++sub) {
    for (size_t si = 0; si < w.slots.size(); ++si) {
      BodyRecord* b = w.slots[si].body.get();
      if (!b) continue;
      const BodyId id{uint32_t(si + 1), w.slots[si].generation};
      const detail::BodyStepReport r = b->integrator->step(b->model, b->state, ctx, *w.jobs);
      if (b->fracture) w.collectEvents(id, *b);
      w.timings.fractureMs += r.fractureMs;
      st.flags |= r.flags;
      st.newtonIterations += r.newtonIterations;
      st.linearIterations += r.linearIterations;
      st.residual = std::max(st.residual, r.residual);
      w.timings.elementsMs += r.elementsMs;
      w.timings.assemblyMs += r.assemblyMs;
      w.timings.solveMs += r.solveMs;
      if (b->model.plasticity.enabled) {
        const auto tp = Clock::now();
        w.plasticUpdate(*b, h);
        w.timings.fractureMs += ms(tp);
      }
    }
  }
  // Events sorted by body, then edge / fragment (ARCHITECTURE.md: determinism).
  std::stable_sort(w.fractureEvents.begin(), w.fractureEvents.end(),
                   [](const FractureEvent& a, const FractureEvent& b) {
                     return a.body.index != b.body.index ? a.body.index < b.body.index
                                                         : a.edge < b.edge;
                   });
  std::stable_sort(w.fragmentEvents.begin(), w.fragmentEvents.end(),
                   [](const FragmentEvent& a, const FragmentEvent& b) {
                     return a.body.index != b.body.index ? a.body.index < b.body.index
                                                         : a.fragment < b.fragment;
                   });
  const auto ts = Clock::now();
  for (Slot& s : w.slots)
    if (s.body && s.body->surface) w.updateSurface(*s.body);
  w.timings.surfaceMs = ms(ts);
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

Result<void> World::cut(BodyId id, const Blade& blade) {
  BodyRecord* b = m_impl->get(id);
  if (!b) return fail("cut: stale or null BodyId");
  if (!b->fracture) return fail("cut: the body was created without fracture (BodyDef.fracture)");
  if (blade.triangles.empty() || blade.triangles.size() % 3 != 0)
    return fail("cut: blade.triangles must hold 3 indices per triangle, got ",
                std::to_string(blade.triangles.size()));
  for (size_t i = 0; i < blade.vertices.size(); ++i)
    if (!finite3(blade.vertices[i]))
      return fail("cut: blade.vertices[", std::to_string(i), "] is not finite");
  for (size_t i = 0; i < blade.triangles.size(); ++i)
    if (blade.triangles[i] >= blade.vertices.size())
      return fail("cut: blade.triangles[", std::to_string(i),
                  "] = ", std::to_string(blade.triangles[i]), " is out of range");
  if (!finiteMat(blade.from) || !finiteMat(blade.to))
    return fail("cut: blade.from/to must be finite transforms");
  detail::PendingCut pc;
  for (const glm::vec3& v : blade.vertices) {
    pc.blade.vertices.push_back(v.x);
    pc.blade.vertices.push_back(v.y);
    pc.blade.vertices.push_back(v.z);
  }
  for (uint32_t i : blade.triangles) pc.blade.triangles.push_back(int32_t(i));
  pc.from = toPose(blade.from);
  pc.to = toPose(blade.to);
  b->fracture->queueCut(std::move(pc));
  return {};
}

std::span<const FractureEvent> World::fractureEvents() const { return m_impl->fractureEvents; }

std::span<const FragmentEvent> World::fragmentEvents() const { return m_impl->fragmentEvents; }

FractureStats World::fractureStats(BodyId id) const {
  FractureStats s;
  const BodyRecord* b = m_impl->get(id);
  if (!b) return s;
  if (!b->fracture) return {0, 0, 1};
  s.edgeCount = b->fracture->graph().edgeCount;
  s.brokenEdges = b->fracture->brokenCount();
  s.fragments = b->fracture->fragments().count();
  return s;
}

std::span<const int32_t> World::nodeFragments(BodyId id) const {
  const BodyRecord* b = m_impl->get(id);
  if (!b || !b->fracture) return {};
  return b->fracture->fragments().nodeFragment();
}

SurfaceView World::surface(BodyId id) {
  BodyRecord* b = m_impl->get(id);
  if (!b) return {};
  if (!b->surface) {
    auto r = std::make_unique<SurfaceRecord>();
    r->rest.positions = b->model.restPositions;
    r->rest.tets = b->model.tets;
    const detail::EdgeGraph* graph = nullptr;
    if (b->fracture) {
      graph = &b->fracture->graph();
    } else {
      r->ownGraph =
          detail::EdgeGraph::build(b->model.tets.data(), b->model.tetCount, b->model.nodeCount);
      r->noBreaks.assign(r->ownGraph.edgeCount, 0);
      r->oneFragment.assign(b->model.nodeCount, 0);
      graph = &r->ownGraph;
    }
    r->surface.init(r->rest, *graph);
    if (b->fracture) {
      r->brokenCount = uint64_t(b->fracture->brokenCount());
      r->surface.rebuild(b->fracture->broken().data(),
                         b->fracture->fragments().nodeFragment().data(), b->state.x.data());
    } else {
      r->surface.rebuild(r->noBreaks.data(), r->oneFragment.data(), b->state.x.data());
    }
    b->surface = std::move(r);
  }
  const detail::CrackSurface& s = b->surface->surface;
  SurfaceView v;
  v.positions = s.positions();
  v.normals = s.normals();
  v.indices = s.indices();
  v.crackMask = s.crackFlags();
  v.vertexFragment = s.vertexFragment();
  v.topologyVersion = s.topologyVersion();
  v.dirtyBegin = s.dirty().begin;
  v.dirtyEnd = s.dirty().end;
  return v;
}

const StepTimings& World::timings() const { return m_impl->timings; }

double World::time() const { return m_impl->time; }

}  // namespace gf
