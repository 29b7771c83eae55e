// World: body storage (generational slots), validation at the API boundary, stepping.
#include "graphfrac/world.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <limits>
#include <new>
#include <string>
#include <utility>
#include <vector>

#include "fem/fem_body.h"
#include "fem/integrator.h"
#include "fracture/fracture_body.h"
#include "graphfrac/jobs.h"
#include "kernels/edge_stress.h"
#include "kernels/element.h"
#include "kernels/plasticity.h"
#include "step/timing.h"
#include "surface/crack_surface.h"
#include "world/rigid_fragment.h"
#include "world/validation.h"

namespace gf {

namespace {
// Contact penalty stiffness per unit mass when the collider names none: dt^2 k = 100 makes
// contact a hundred times stiffer than inertia, so a node is pushed out within about a step
// and rests g dt^2 / 100 deep.
constexpr double kAutoContactStiffnessDt2 = 100.0;

// Positions [m] and velocities [m/s] beyond this are unit mistakes that overflow squared
// lengths and the float render surface; the commands refuse them.
constexpr double kMaxMagnitude = 1e9;

bool finite3(glm::vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
bool bounded3(glm::vec3 v) {
  return finite3(v) && std::abs(v.x) <= kMaxMagnitude && std::abs(v.y) <= kMaxMagnitude &&
         std::abs(v.z) <= kMaxMagnitude;
}

// Distinguishes worlds so that a snapshot is restored only into the world it was taken of.
std::atomic<uint64_t> g_nextWorldId{1};

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
  std::vector<Grip> grips;                         // node lists for setGripVelocity
  std::vector<double> pendingForce;                // applyForce, next step only; empty: none
  // Fragments handed to rigid physics (detachFragment): id and rest centre of mass, in
  // detach order.
  std::vector<std::pair<int32_t, Vec3>> rigid;
  // A step or setFragmentTransform moved nodes since the render surface was updated; the next
  // surface() call updates it (once per rendered frame, not once per step or substep).
  bool surfaceStale = false;
  std::vector<double> nodeStrain;      // World::nodeStrain's output
  std::vector<double> nodeWeight;      // its scratch
  std::vector<glm::dvec3> gripForces;  // World::gripForces's output
  std::vector<double> nodeForce;       // its scratch
  // The integrator still holds the start of the step that led to the current state, so the
  // grips' forces can be evaluated (false before the first step and after state overwrites).
  bool stepEndValid = false;
  // Every node is in a detached fragment: the body only moves rigidly, so a step just advances
  // the nodes by their prescribed velocities (what the integrator would do, without its cost).
  bool allRigid = false;
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

// Kernel form of a collider; the stiffness is filled in per step (Impl::context).
ColliderData toData(const Collider& c) {
  ColliderData d;
  d.kind = static_cast<int>(c.kind);
  d.point = {c.point.x, c.point.y, c.point.z};
  Vec3 n{c.normal.x, c.normal.y, c.normal.z};
  const double len = norm(n);
  d.normal = len > 0 ? (1.0 / len) * n : Vec3{0, 1, 0};
  d.halfExtents = {c.halfExtents.x, c.halfExtents.y, c.halfExtents.z};
  d.radius = c.radius;
  const glm::dquat q(c.rotation);
  const double ql = glm::length(q);
  const glm::dmat3 R = glm::mat3_cast(ql > 0 ? q / ql : glm::dquat(1, 0, 0, 0));
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) d.rotation(i, j) = R[j][i];  // glm is column-major
  return d;
}

// Builds a body's model, state, solver and fracture from a checked def; throws std::bad_alloc
// when the machine has not the memory for it.
Result<std::unique_ptr<BodyRecord>> buildBody(BodyDef&& def, JobSystem& jobs) {
  auto body = std::make_unique<BodyRecord>();
  body->model = detail::buildFemModel(def);
  body->state.x = body->model.restPositions;
  body->state.v.resize(body->state.x.size());
  for (size_t i = 0; i < body->state.v.size(); ++i)
    body->state.v[i] = def.initialVelocity[int(i % 3)];
  body->integrator = std::make_unique<detail::Integrator>(body->model);
  if (Result<void> r = body->integrator->setupSolver(body->model); !r.ok()) return r.error();
  if (def.fracture.enabled) {
    auto fb = detail::FractureBody::create(body->model, jobs);
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
  const std::vector<Mat3>* plasticInverse =
      def.plasticity.enabled ? &body->state.plasticInverse : nullptr;
  body->integrator->attach(body->fracture.get(), plasticInverse);
  if (body->fracture) body->fracture->attachPlasticity(plasticInverse);

  body->gripForces.assign(def.grips.size(), glm::dvec3(0));
  body->grips = std::move(def.grips);
  return body;
}

struct Slot {
  uint32_t generation = 1;
  std::unique_ptr<BodyRecord> body;  // null when free
};
}  // namespace

struct World::Impl {
  const uint64_t id = g_nextWorldId++;
  WorldDef def;
  std::string defError;  // WorldDef::check's message; non-empty: the world refuses to run
  JobSystem* jobs = nullptr;
  std::vector<Slot> slots;
  std::vector<ColliderData> colliders;  // at their current pose (def.colliders: as given)
  std::vector<double> colliderImpulse;  // 6 per collider, see StepContext::colliderImpulse
  std::vector<glm::dvec3> impulses, angularImpulses;  // of the last step
  StepTimings timings;
  std::vector<FractureEvent> fractureEvents;
  std::vector<FragmentEvent> fragmentEvents;
  std::vector<HandoffEvent> handoffEvents;
  double time = 0;
  double lastSubstep = 1.0 / 60;  // contact stiffness of stats() follows the last step
  // Set while step() runs: calls that change the world are refused then (a job callback
  // re-entering the world would race the step).
  std::atomic<bool> stepping{false};

  // The error of a mutating call made during step(), or empty.
  std::string busy(const char* call) const {
    return stepping.load() ? std::string(call) + ": called while step() runs; nothing changed"
                           : std::string();
  }

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

  // The colliders with their stiffness for substep dt filled in.
  void setColliderStiffness(double dt) {
    for (size_t c = 0; c < colliders.size(); ++c) {
      const double k = def.colliders[c].stiffness;
      colliders[c].stiffness = k > 0 ? k : kAutoContactStiffnessDt2 / (dt * dt);
    }
  }
  // What a body step reads; the colliders' stiffness must be set for dt.
  detail::StepContext context(double dt) const {
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
  if (Result<void> r = def.check(); !r) {
    w.defError = r.error().message + "; the world does not run (check WorldDef before creating it)";
    w.def.colliders.clear();  // nothing of an invalid def is used
    w.def.substeps = 1;
  }
  for (const Collider& c : w.def.colliders) w.colliders.push_back(toData(c));
  w.setColliderStiffness(w.lastSubstep);
  w.impulses.assign(w.colliders.size(), glm::dvec3(0));
  w.angularImpulses = w.impulses;
}

World::~World() = default;

Result<BodyId> World::createBody(BodyDef def) {
  if (std::string e = m_impl->busy("createBody"); !e.empty()) return fail(e);
  if (!m_impl->defError.empty()) return fail("createBody: ", m_impl->defError);
  if (def.mesh.tetCount() == 0) return fail("BodyDef.mesh: has no tetrahedra");
  // No exception crosses the API: a body too large for the machine is an error that says how
  // much it needs, and the world stays as it was.
  Impl& w = *m_impl;
  const size_t tets = def.mesh.tetCount(), nodes = def.mesh.nodeCount();
  const double bytes = detail::estimateBodyBytes(def);
  try {
    int flipped = 0;
    if (auto r = validate(def.mesh, "BodyDef.mesh", &flipped); !r) return r.error();
    if (auto r = detail::checkBodySettings(def); !r) return fail("BodyDef.", r.error().message);
    Result<std::unique_ptr<BodyRecord>> built = buildBody(std::move(def), *w.jobs);
    if (!built) return built.error();
    size_t slot = 0;
    while (slot < w.slots.size() && w.slots[slot].body) ++slot;
    if (slot == w.slots.size()) w.slots.emplace_back();
    w.slots[slot].body = std::move(built.value());
    return BodyId{uint32_t(slot + 1), w.slots[slot].generation};
  } catch (const std::bad_alloc&) {
    return fail("BodyDef.mesh: not enough memory for a body of ", std::to_string(tets),
                " tets and ", std::to_string(nodes), " nodes: it needs about ",
                std::to_string(int64_t(std::ceil(bytes / 1048576.0))), " MiB");
  }
}

Result<void> World::destroyBody(BodyId id) {
  if (std::string e = m_impl->busy("destroyBody"); !e.empty()) return fail(e);
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
  if (!w.defError.empty()) {
    st.flags = kStepInvalidInput;
    st.message = "step: " + w.defError;
    return st;
  }
  if (w.stepping.exchange(true)) {
    st.flags = kStepInvalidInput;
    st.message = "step: called while step() runs; nothing changed";
    return st;
  }
  // Forces of applyForce act over this whole step: swapped in, the constant ones swapped back
  // after (restoring the copy, not subtracting, keeps the constant forces bit-exact).
  std::vector<std::vector<double>> constantForces;
  for (Slot& s : w.slots) {
    if (!s.body || s.body->pendingForce.empty()) continue;
    std::vector<double>& f = s.body->model.externalForce;
    constantForces.push_back(f);
    for (size_t i = 0; i < f.size(); ++i) f[i] += s.body->pendingForce[i];
  }
  const auto t0 = detail::Clock::now();
  w.timings = {};
  w.fractureEvents.clear();
  w.fragmentEvents.clear();
  w.handoffEvents.clear();
  const double h = dt / w.def.substeps;
  w.lastSubstep = h;
  w.setColliderStiffness(h);
  detail::StepContext ctx = w.context(h);
  // Moving colliders: each substep sees them at its end pose; the sums of their impulses are
  // over bodies and substeps.
  std::vector<Vec3> colliderStart(w.colliders.size());
  for (size_t c = 0; c < w.colliders.size(); ++c) colliderStart[c] = w.colliders[c].point;
  w.colliderImpulse.assign(6 * w.colliders.size(), 0.0);
  ctx.colliderImpulse = w.colliders.empty() ? nullptr : w.colliderImpulse.data();
  for (int sub = 0; sub < w.def.substeps; ++sub) {
    for (size_t c = 0; c < w.colliders.size(); ++c) {
      const glm::vec3 v = w.def.colliders[c].velocity;
      w.colliders[c].point = colliderStart[c] + ((sub + 1) * h) * Vec3{v.x, v.y, v.z};
    }
    for (size_t si = 0; si < w.slots.size(); ++si) {
      BodyRecord* b = w.slots[si].body.get();
      if (!b) continue;
      const BodyId id{uint32_t(si + 1), w.slots[si].generation};
      if (b->allRigid) {
        // The integrator's own update of prescribed nodes, x += h v, v = grip velocity.
        for (size_t i = 0; i < b->state.x.size(); ++i) {
          b->state.x[i] += h * b->model.gripVelocity[i];
          b->state.v[i] = b->model.gripVelocity[i];
        }
        continue;
      }
      const detail::BodyStepReport r = b->integrator->step(b->model, b->state, ctx, *w.jobs);
      if (b->fracture) w.collectEvents(id, *b);
      b->stepEndValid = true;
      w.timings.fractureMs += r.fractureMs;
      st.flags |= r.flags;
      if ((r.flags & kStepNanContained) && st.message.empty())
        st.message = "body " + std::to_string(si + 1) + ": " + r.message;
      st.newtonIterations += r.newtonIterations;
      st.linearIterations += r.linearIterations;
      st.residual = std::max(st.residual, r.residual);
      w.timings.elementsMs += r.elementsMs;
      w.timings.assemblyMs += r.assemblyMs;
      w.timings.solveMs += r.solveMs;
      // A rolled-back body is where it was before the substep: nothing flowed.
      if (b->model.plasticity.enabled && !(r.flags & kStepNanContained)) {
        const auto tp = detail::Clock::now();
        w.plasticUpdate(*b, h);
        w.timings.plasticityMs += detail::msSince(tp);
      }
    }
  }
  for (size_t c = 0; c < w.colliders.size(); ++c) {
    const double* j = &w.colliderImpulse[6 * c];
    w.impulses[c] = {j[0], j[1], j[2]};
    w.angularImpulses[c] = {j[3], j[4], j[5]};
    const Vec3 p = w.colliders[c].point;
    w.def.colliders[c].point = glm::vec3(float(p.x), float(p.y), float(p.z));
  }
  // Events sorted by body, then edge / fragment: the same order for any thread count.
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
  size_t swapped = 0;
  for (Slot& s : w.slots) {
    if (!s.body || s.body->pendingForce.empty()) continue;
    s.body->model.externalForce = std::move(constantForces[swapped++]);
    s.body->pendingForce.clear();
  }
  for (Slot& s : w.slots)
    if (s.body && s.body->surface) s.body->surfaceStale = true;
  w.time += dt;
  w.timings.totalMs = detail::msSince(t0);
  if (st.message.empty()) {
    if (st.has(kStepNotConverged))
      st.message = "the solver stopped at its iteration cap";
    else if (st.has(kStepLineSearchFailed))
      st.message =
          "Newton's line search reached its smallest step without lowering the incremental "
          "potential: the time step is too large for the load (try substeps or a smaller dt)";
  }
  w.stepping.store(false);
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
  if (std::string e = m_impl->busy("setVelocity"); !e.empty()) return fail(e);
  if (!b) return fail("setVelocity: stale or null BodyId");
  if (!bounded3(glm::vec3(v)) || !std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
    return fail("setVelocity: velocity must be finite, at most 1e9 m/s");
  for (size_t i = 0; i < b->state.v.size(); ++i) b->state.v[i] = v[int(i % 3)];
  return {};
}

namespace {
Result<void> overwrite(std::vector<double>& dst, std::span<const double> src, const char* what,
                       const char* unit) {
  if (src.size() != dst.size())
    return fail(what, ": expected ", std::to_string(dst.size()), " values, got ",
                std::to_string(src.size()));
  for (size_t i = 0; i < src.size(); ++i)
    if (!(std::isfinite(src[i]) && std::abs(src[i]) <= kMaxMagnitude))
      return fail(what, ": value ", std::to_string(i), " (node ", std::to_string(i / 3), ") is ",
                  std::to_string(src[i]), "; must be finite, at most 1e9 ", unit);
  dst.assign(src.begin(), src.end());
  return {};
}
}  // namespace

Result<void> World::setPositions(BodyId id, std::span<const double> x) {
  BodyRecord* b = m_impl->get(id);
  if (std::string e = m_impl->busy("setPositions"); !e.empty()) return fail(e);
  if (!b) return fail("setPositions: stale or null BodyId");
  if (Result<void> r = overwrite(b->state.x, x, "setPositions", "m"); !r) return r;
  b->surfaceStale = true;
  b->stepEndValid = false;
  return {};
}

Result<void> World::setVelocities(BodyId id, std::span<const double> v) {
  BodyRecord* b = m_impl->get(id);
  if (std::string e = m_impl->busy("setVelocities"); !e.empty()) return fail(e);
  if (!b) return fail("setVelocities: stale or null BodyId");
  return overwrite(b->state.v, v, "setVelocities", "m/s");
}

BodyStats World::stats(BodyId id) const {
  BodyStats s;
  const BodyRecord* b = m_impl->get(id);
  if (!b || m_impl->stepping.load()) return s;
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
  const detail::StepContext ctx = m_impl->context(m_impl->lastSubstep);
  const detail::EnergyBreakdown e = b->integrator->energies(m, x.data(), ctx, *m_impl->jobs);
  s.elasticEnergy = e.elastic;
  s.contactEnergy = e.contact;
  return s;
}

Result<void> World::cut(BodyId id, const Blade& blade) {
  BodyRecord* b = m_impl->get(id);
  if (std::string e = m_impl->busy("cut"); !e.empty()) return fail(e);
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

std::span<const int32_t> World::edges(BodyId id) const {
  const BodyRecord* b = m_impl->get(id);
  if (!b || !b->fracture) return {};
  return b->fracture->graph().edgeNodes;
}

std::span<const uint8_t> World::brokenEdges(BodyId id) const {
  const BodyRecord* b = m_impl->get(id);
  if (!b || !b->fracture) return {};
  return b->fracture->broken();
}

std::span<const glm::dvec3> World::gripForces(BodyId id) {
  BodyRecord* b = m_impl->get(id);
  if (!b || m_impl->stepping.load()) return {};
  std::fill(b->gripForces.begin(), b->gripForces.end(), glm::dvec3(0));
  if (!b->stepEndValid || b->allRigid) return b->gripForces;
  const detail::StepContext ctx = m_impl->context(m_impl->lastSubstep);
  b->integrator->prescribedNodeForces(b->model, b->state, ctx, *m_impl->jobs, b->nodeForce);
  for (size_t g = 0; g < b->grips.size(); ++g)
    for (int32_t n : b->grips[g].nodes)
      b->gripForces[g] += glm::dvec3(b->nodeForce[3 * size_t(n)], b->nodeForce[3 * size_t(n) + 1],
                                     b->nodeForce[3 * size_t(n) + 2]);
  return b->gripForces;
}

std::span<const double> World::nodeStrain(BodyId id) {
  BodyRecord* b = m_impl->get(id);
  if (!b || m_impl->stepping.load()) return {};
  const detail::FemModel& m = b->model;
  b->nodeStrain.assign(size_t(m.nodeCount), 0.0);
  b->nodeWeight.assign(size_t(m.nodeCount), 0.0);
  for (int32_t t = 0; t < m.tetCount; ++t) {
    Vec3 xe[4];
    for (int a = 0; a < 4; ++a) {
      const double* p = &b->state.x[3 * size_t(m.tets[4 * t + a])];
      xe[a] = {p[0], p[1], p[2]};
    }
    const double e = maxPrincipalStrain(deformationGradient(xe, m.restInverse[size_t(t)]));
    for (int a = 0; a < 4; ++a) {
      const size_t n = size_t(m.tets[4 * t + a]);
      b->nodeStrain[n] += m.restVolume[size_t(t)] * e;
      b->nodeWeight[n] += m.restVolume[size_t(t)];
    }
  }
  for (size_t n = 0; n < b->nodeStrain.size(); ++n)
    if (b->nodeWeight[n] > 0) b->nodeStrain[n] /= b->nodeWeight[n];
  return b->nodeStrain;
}

SurfaceView World::surface(BodyId id) {
  BodyRecord* b = m_impl->get(id);
  if (!b || m_impl->stepping.load()) return {};
  // The view's dirty range covers what changed since the previous call.
  if (b->surface) b->surface->surface.clearDirty();
  if (b->surface && b->surfaceStale) {
    const auto t0 = detail::Clock::now();
    m_impl->updateSurface(*b);
    m_impl->timings.surfaceMs += detail::msSince(t0);
  }
  b->surfaceStale = false;
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
  v.vertexNode = s.vertexNode();
  v.topologyVersion = s.topologyVersion();
  v.dirtyBegin = s.dirty().begin;
  v.dirtyEnd = s.dirty().end;
  return v;
}

const StepTimings& World::timings() const { return m_impl->timings; }

double World::time() const { return m_impl->time; }

namespace {
// Corners and weights that spread a point load over a body (World::applyForce): the
// barycentric coordinates of p in the tet that contains it at positions x, or in the tet whose
// weakest coordinate is largest, clamped to >= 0 and renormalised. False for a body whose tets
// are all degenerate at x.
bool pointWeights(const detail::FemModel& m, const std::vector<double>& x, glm::dvec3 p,
                  int32_t corner[4], double w[4]) {
  auto node = [&](int32_t n) { return glm::dvec3(x[3 * n], x[3 * n + 1], x[3 * n + 2]); };
  double best = -std::numeric_limits<double>::infinity();
  for (int32_t t = 0; t < m.tetCount; ++t) {
    const int32_t* tn = &m.tets[4 * size_t(t)];
    const glm::dvec3 x0 = node(tn[0]), a = node(tn[1]) - x0, b = node(tn[2]) - x0,
                     c = node(tn[3]) - x0, d = p - x0;
    const double det = glm::dot(a, glm::cross(b, c));
    if (!(std::abs(det) > 0)) continue;
    // Cramer's rule for a l1 + b l2 + c l3 = p - x0.
    const double l1 = glm::dot(d, glm::cross(b, c)) / det;
    const double l2 = glm::dot(a, glm::cross(d, c)) / det;
    const double l3 = glm::dot(a, glm::cross(b, d)) / det;
    const double l[4] = {1 - l1 - l2 - l3, l1, l2, l3};
    const double weakest = std::min(std::min(l[0], l[1]), std::min(l[2], l[3]));
    if (!(weakest > best)) continue;
    best = weakest;
    for (int k = 0; k < 4; ++k) {
      corner[k] = tn[k];
      w[k] = l[k];
    }
    if (weakest >= 0) break;  // inside (or on a face): exact
  }
  if (best == -std::numeric_limits<double>::infinity()) return false;
  if (best < 0) {
    double sum = 0;
    for (int k = 0; k < 4; ++k) sum += (w[k] = std::max(w[k], 0.0));
    for (int k = 0; k < 4; ++k) w[k] /= sum;
  }
  return true;
}

// Checks of the point commands: live body, not stepping, finite point and vector.
Result<void> checkPointCommand(const std::string& busy, const void* body, const char* call,
                               glm::vec3 point, glm::vec3 vec, const char* vecName) {
  if (!busy.empty()) return fail(busy);
  if (!body) return fail(call, ": stale or null BodyId");
  if (!bounded3(point)) return fail(call, ": point must be finite, within 1e9 m of the origin");
  if (!finite3(vec)) return fail(call, ": ", vecName, " is not finite");
  return {};
}
}  // namespace

Result<void> World::applyForce(BodyId id, glm::vec3 point, glm::vec3 force) {
  BodyRecord* b = m_impl->get(id);
  if (auto r =
          checkPointCommand(m_impl->busy("applyForce"), b, "applyForce", point, force, "force");
      !r)
    return r;
  int32_t corner[4];
  double w[4];
  if (!pointWeights(b->model, b->state.x, glm::dvec3(point), corner, w))
    return fail("applyForce: the body has no tet of non-zero volume to apply the force to");
  if (b->pendingForce.empty()) b->pendingForce.assign(b->state.x.size(), 0.0);
  for (int k = 0; k < 4; ++k)
    for (int i = 0; i < 3; ++i) b->pendingForce[3 * corner[k] + i] += w[k] * double(force[i]);
  return {};
}

Result<void> World::applyImpulse(BodyId id, glm::vec3 point, glm::vec3 impulse) {
  BodyRecord* b = m_impl->get(id);
  if (auto r = checkPointCommand(m_impl->busy("applyImpulse"), b, "applyImpulse", point, impulse,
                                 "impulse");
      !r)
    return r;
  int32_t corner[4];
  double w[4];
  if (!pointWeights(b->model, b->state.x, glm::dvec3(point), corner, w))
    return fail("applyImpulse: the body has no tet of non-zero volume to apply the impulse to");
  for (int k = 0; k < 4; ++k) {
    const double m = b->model.nodeMass[corner[k]];
    if (!(m > 0)) continue;  // a node of zero mass carries no momentum
    for (int i = 0; i < 3; ++i) b->state.v[3 * corner[k] + i] += w[k] * double(impulse[i]) / m;
  }
  return {};
}

Result<void> World::setGripVelocity(BodyId id, int grip, glm::vec3 velocity) {
  if (std::string e = m_impl->busy("setGripVelocity"); !e.empty()) return fail(e);
  BodyRecord* b = m_impl->get(id);
  if (!b) return fail("setGripVelocity: stale or null BodyId");
  if (grip < 0 || size_t(grip) >= b->grips.size())
    return fail("setGripVelocity: grip ", std::to_string(grip), " out of range [0, ",
                std::to_string(b->grips.size()), ")");
  if (!finite3(velocity)) return fail("setGripVelocity: velocity is not finite");
  detail::FemModel& m = b->model;
  for (int32_t n : b->grips[size_t(grip)].nodes)
    for (int i = 0; i < 3; ++i) m.gripVelocity[3 * n + i] = velocity[i];
  m.movingGrips =
      std::any_of(m.gripVelocity.begin(), m.gripVelocity.end(), [](double v) { return v != 0; });
  return {};
}

Result<void> World::setEdgeStrengths(BodyId id, std::span<const double> strength) {
  if (std::string e = m_impl->busy("setEdgeStrengths"); !e.empty()) return fail(e);
  BodyRecord* b = m_impl->get(id);
  if (!b) return fail("setEdgeStrengths: stale or null BodyId");
  if (!b->fracture)
    return fail("setEdgeStrengths: the body was created without fracture (BodyDef.fracture)");
  const size_t edges = b->fracture->strengths().size();
  if (strength.size() != edges)
    return fail("setEdgeStrengths: expected one strength per edge (", std::to_string(edges),
                "), got ", std::to_string(strength.size()));
  for (size_t e = 0; e < strength.size(); ++e)
    if (!(std::isfinite(strength[e]) && strength[e] > 0))
      return fail("setEdgeStrengths: strength[", std::to_string(e),
                  "] = ", std::to_string(strength[e]), " is not a positive finite stress");
  b->fracture->setStrengths(std::vector<double>(strength.begin(), strength.end()));
  return {};
}

Result<void> World::setMaterial(BodyId id, const Material& material) {
  if (std::string e = m_impl->busy("setMaterial"); !e.empty()) return fail(e);
  BodyRecord* b = m_impl->get(id);
  if (!b) return fail("setMaterial: stale or null BodyId");
  if (auto r = material.check(); !r) return fail("setMaterial: ", r.error().message);
  detail::FemModel& m = b->model;
  if (material.model != m.material.model)
    return fail("setMaterial: material.model must stay the body's model (",
                std::to_string(int(m.material.model)), "), got ",
                std::to_string(int(material.model)));
  if ((material.fibreStiffness > 0) != (m.material.fibreStiffness > 0))
    return fail(
        "setMaterial: material.fibreStiffness must stay zero or non-zero as at creation (the "
        "fibre field and fibre strengths are built once)");
  const bool newDensity = material.density != m.material.density;
  m.material = material;
  m.coeffs = detail::toCoeffs(material);
  if (newDensity) {
    // Lumped masses as buildFemModel forms them, in the same order (eq 2.10, row-summed).
    std::fill(m.nodeMass.begin(), m.nodeMass.end(), 0.0);
    for (int32_t e = 0; e < m.tetCount; ++e)
      for (int a = 0; a < 4; ++a)
        m.nodeMass[m.tets[4 * size_t(e) + a]] += 0.25 * material.density * m.restVolume[e];
  }
  return {};
}

// Everything of one body that a step reads and a run changes; the rest of the model is fixed.
struct BodySnapshot {
  uint32_t slot = 0, generation = 0;
  int32_t nodeCount = 0, tetCount = 0;
  detail::FemState state;
  Material material;
  MaterialCoeffs coeffs;
  std::vector<double> nodeMass, gripVelocity, pendingForce;
  bool movingGrips = false;
  bool hasFracture = false;
  detail::FractureBody::State fracture;
  std::vector<int32_t> rebindHistory;
};

struct WorldSnapshot::Data {
  uint64_t world = 0;  // the World it was taken of
  double time = 0, lastSubstep = 0;
  std::vector<Collider> colliderDefs;  // moving colliders are state too
  std::vector<ColliderData> colliders;
  std::vector<glm::dvec3> impulses, angularImpulses;
  std::vector<BodySnapshot> bodies;  // live bodies in slot order
  std::vector<FractureEvent> fractureEvents;
  std::vector<FragmentEvent> fragmentEvents;
};

double WorldSnapshot::time() const { return m_data ? m_data->time : 0.0; }

WorldSnapshot World::snapshot() const {
  const Impl& w = *m_impl;
  auto d = std::make_shared<WorldSnapshot::Data>();
  d->world = w.id;
  d->time = w.time;
  d->lastSubstep = w.lastSubstep;
  d->colliderDefs = w.def.colliders;
  d->colliders = w.colliders;
  d->impulses = w.impulses;
  d->angularImpulses = w.angularImpulses;
  d->fractureEvents = w.fractureEvents;
  d->fragmentEvents = w.fragmentEvents;
  for (size_t si = 0; si < w.slots.size(); ++si) {
    const BodyRecord* b = w.slots[si].body.get();
    if (!b) continue;
    BodySnapshot s;
    s.slot = uint32_t(si);
    s.generation = w.slots[si].generation;
    s.nodeCount = b->model.nodeCount;
    s.tetCount = b->model.tetCount;
    s.state = b->state;
    s.material = b->model.material;
    s.coeffs = b->model.coeffs;
    s.nodeMass = b->model.nodeMass;
    s.gripVelocity = b->model.gripVelocity;
    s.pendingForce = b->pendingForce;
    s.movingGrips = b->model.movingGrips;
    s.hasFracture = b->fracture != nullptr;
    if (b->fracture) s.fracture = b->fracture->saveState();
    s.rebindHistory = b->integrator->rebindHistory();
    d->bodies.push_back(std::move(s));
  }
  WorldSnapshot out;
  out.m_data = std::move(d);
  return out;
}

Result<void> World::restore(const WorldSnapshot& snapshot) {
  if (std::string e = m_impl->busy("restore"); !e.empty()) return fail(e);
  if (snapshot.empty()) return fail("restore: the snapshot is empty");
  Impl& w = *m_impl;
  const WorldSnapshot::Data& d = *snapshot.m_data;
  // All checks first, so a mismatch changes nothing. Another world with the same body slots
  // would pass the checks below and get colliders and states that are not its own.
  if (d.world != w.id) return fail("restore: the snapshot was taken of another World");
  size_t live = 0;
  for (const Slot& s : w.slots) live += s.body ? 1 : 0;
  if (live != d.bodies.size())
    return fail("restore: the world holds ", std::to_string(live), " bodies, the snapshot ",
                std::to_string(d.bodies.size()));
  for (const BodySnapshot& s : d.bodies) {
    const std::string which = "restore: body " + std::to_string(s.slot + 1) + ": ";
    if (s.slot >= w.slots.size() || !w.slots[s.slot].body ||
        w.slots[s.slot].generation != s.generation)
      return fail(which, "not in this world (created or destroyed since the snapshot?)");
    const BodyRecord& b = *w.slots[s.slot].body;
    if (b.model.nodeCount != s.nodeCount || b.model.tetCount != s.tetCount ||
        (b.fracture != nullptr) != s.hasFracture || b.state.Fp.size() != s.state.Fp.size())
      return fail(which, "mesh, fracture or plasticity differ from the snapshot's");
    // The snapshot does not hold which nodes a hand-off prescribed; refuse rather than restore
    // a body half rigid.
    if (!b.rigid.empty())
      return fail(which,
                  "has fragments handed to rigid physics (detachFragment); restoring "
                  "across a hand-off is not supported yet");
  }
  for (const BodySnapshot& s : d.bodies) {
    BodyRecord& b = *w.slots[s.slot].body;
    b.state = s.state;
    b.model.material = s.material;
    b.model.coeffs = s.coeffs;
    b.model.nodeMass = s.nodeMass;
    b.model.gripVelocity = s.gripVelocity;
    b.model.movingGrips = s.movingGrips;
    b.pendingForce = s.pendingForce;
    if (b.fracture) b.fracture->restoreState(s.fracture);
    b.stepEndValid = false;
    // Cannot fail: the same set-up succeeded when the body was created.
    if (Result<void> r = b.integrator->restoreSolver(b.model, s.rebindHistory); !r)
      return fail("restore: body ", std::to_string(s.slot + 1), ": ", r.error().message);
    if (b.surface) {
      b.surface->brokenCount = ~uint64_t(0);  // force a full rebuild
      w.updateSurface(b);
    }
  }
  w.time = d.time;
  w.lastSubstep = d.lastSubstep;
  w.def.colliders = d.colliderDefs;
  w.colliders = d.colliders;
  w.impulses = d.impulses;
  w.angularImpulses = d.angularImpulses;
  w.fractureEvents = d.fractureEvents;
  w.fragmentEvents = d.fragmentEvents;
  return {};
}

uint64_t World::stateHash() const {
  uint64_t h = 14695981039346656037ull;  // FNV-1a 64-bit offset basis
  auto mix = [&h](const void* data, size_t bytes) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
  };
  const Impl& w = *m_impl;
  for (size_t si = 0; si < w.slots.size(); ++si) {
    const BodyRecord* b = w.slots[si].body.get();
    if (!b) continue;
    const uint32_t ids[2] = {uint32_t(si + 1), w.slots[si].generation};
    mix(ids, sizeof ids);
    mix(b->state.x.data(), b->state.x.size() * sizeof(double));
    mix(b->state.v.data(), b->state.v.size() * sizeof(double));
    if (b->fracture) mix(b->fracture->broken().data(), b->fracture->broken().size());
  }
  mix(&w.time, sizeof w.time);
  return h;
}

// ---- Hand-off of fragments to rigid-body physics ----

namespace {
glm::dvec3 toGlm(Vec3 v) { return {v.x, v.y, v.z}; }
glm::dmat3 toGlm(const Mat3& m) {
  glm::dmat3 g;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) g[j][i] = m(i, j);  // glm is column-major
  return g;
}
bool finite3d(glm::dvec3 v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Error of the checks every fragment call shares, or empty.
std::string checkFragment(const BodyRecord* b, const char* call, int32_t fragment) {
  if (!b) return std::string(call) + ": stale or null BodyId";
  if (!b->fracture)
    return std::string(call) + ": the body was created without fracture (BodyDef.fracture)";
  const int32_t count = b->fracture->fragments().count();
  if (fragment < 0 || fragment >= count)
    return std::string(call) + ": fragment " + std::to_string(fragment) + " out of range [0, " +
           std::to_string(count) + ")";
  return {};
}

const Vec3* detachedCentre(const BodyRecord& b, int32_t fragment) {
  for (const auto& r : b.rigid)
    if (r.first == fragment) return &r.second;
  return nullptr;
}

RigidFragmentInfo toInfo(const detail::RigidProperties& p) {
  RigidFragmentInfo info;
  info.nodeCount = p.nodeCount;
  info.mass = p.mass;
  info.volume = p.volume;
  info.centreOfMass = toGlm(p.centre);
  const glm::dmat3 R = toGlm(p.rotation);
  // The rigid body carries the rest shape, so its inertia is the rest one turned to the pose.
  info.inertia = R * toGlm(p.restInertia) * glm::transpose(R);
  info.linearVelocity = toGlm(p.momentum) / p.mass;
  info.angularVelocity =
      R * (glm::inverse(toGlm(p.restInertia)) * (glm::transpose(R) * toGlm(p.angularMomentum)));
  info.rotation = glm::quat_cast(R);
  info.translation = info.centreOfMass - R * toGlm(p.restCentre);
  return info;
}

// Marks the tets whose nodes all lie in detached fragments (FemModel::rigidTet) and whether
// the whole body is rigid now.
void markRigidTets(BodyRecord& b) {
  const std::span<const int32_t> fragmentOf = b.fracture->fragments().nodeFragment();
  std::vector<uint8_t> rigidNode(fragmentOf.size(), 0);
  for (size_t n = 0; n < fragmentOf.size(); ++n)
    rigidNode[n] = detachedCentre(b, fragmentOf[n]) != nullptr;
  detail::FemModel& m = b.model;
  m.rigidTet.assign(size_t(m.tetCount), 0);
  for (int32_t t = 0; t < m.tetCount; ++t)
    m.rigidTet[size_t(t)] =
        rigidNode[size_t(m.tets[4 * t])] && rigidNode[size_t(m.tets[4 * t + 1])] &&
        rigidNode[size_t(m.tets[4 * t + 2])] && rigidNode[size_t(m.tets[4 * t + 3])];
  b.allRigid = std::all_of(rigidNode.begin(), rigidNode.end(), [](uint8_t r) { return r != 0; });
}

// Prescribes the rigid velocity field v + w x (x - c) on a detached fragment's nodes (the
// integrator moves them by it and reports it as their velocity).
void setRigidVelocities(BodyRecord& b, int32_t fragment, glm::dvec3 v, glm::dvec3 w, glm::dvec3 c) {
  detail::FemModel& m = b.model;
  for (int32_t n : b.fracture->fragments().nodes(fragment)) {
    const glm::dvec3 x(b.state.x[3 * n], b.state.x[3 * n + 1], b.state.x[3 * n + 2]);
    const glm::dvec3 vn = v + glm::cross(w, x - c);
    for (int i = 0; i < 3; ++i) m.gripVelocity[3 * n + i] = b.state.v[3 * n + i] = vn[i];
    m.movingGrips |= vn != glm::dvec3(0);
  }
}
}  // namespace

Result<RigidFragmentInfo> World::fragmentInfo(BodyId id, int32_t fragment) const {
  const BodyRecord* b = m_impl->get(id);
  if (std::string e = checkFragment(b, "fragmentInfo", fragment); !e.empty()) return fail(e);
  const detail::RigidProperties p =
      detail::rigidProperties(b->model, b->state.x.data(), b->state.v.data(),
                              b->fracture->fragments().nodeFragment().data(), fragment);
  return toInfo(p);
}

Result<RigidFragmentInfo> World::detachFragment(BodyId id, int32_t fragment) {
  if (std::string e = m_impl->busy("detachFragment"); !e.empty()) return fail(e);
  BodyRecord* b = m_impl->get(id);
  if (std::string e = checkFragment(b, "detachFragment", fragment); !e.empty()) return fail(e);
  if (detachedCentre(*b, fragment))
    return fail("detachFragment: fragment ", std::to_string(fragment), " is already detached");
  const detail::RigidProperties p =
      detail::rigidProperties(b->model, b->state.x.data(), b->state.v.data(),
                              b->fracture->fragments().nodeFragment().data(), fragment);
  if (p.hasFixedNode)
    return fail("detachFragment: fragment ", std::to_string(fragment),
                " holds gripped nodes (BodyDef.grips); a pinned piece cannot move rigidly");
  if (!(p.mass > 0))
    return fail("detachFragment: fragment ", std::to_string(fragment), " has no mass");
  const RigidFragmentInfo info = toInfo(p);
  for (int32_t n : b->fracture->fragments().nodes(fragment)) b->model.fixedNode[size_t(n)] = 1;
  setRigidVelocities(*b, fragment, info.linearVelocity, info.angularVelocity, info.centreOfMass);
  b->integrator->refreshFixedNodes(b->model);
  b->rigid.emplace_back(fragment, p.restCentre);
  markRigidTets(*b);

  HandoffEvent ev;
  ev.body = id;
  ev.fragment = fragment;
  ev.nodeCount = info.nodeCount;
  ev.mass = info.mass;
  ev.centreOfMass = glm::vec3(info.centreOfMass);
  ev.velocity = glm::vec3(info.linearVelocity);
  ev.angularVelocity = glm::vec3(info.angularVelocity);
  // Kept sorted by (body, fragment) as the calls come, whatever order the game detaches in.
  std::vector<HandoffEvent>& events = m_impl->handoffEvents;
  const auto at = std::upper_bound(
      events.begin(), events.end(), ev, [](const HandoffEvent& a, const HandoffEvent& c) {
        return a.body.index != c.body.index ? a.body.index < c.body.index : a.fragment < c.fragment;
      });
  events.insert(at, ev);
  return info;
}

Result<void> World::setFragmentTransform(BodyId id, int32_t fragment, glm::dvec3 translation,
                                         glm::dquat rotation, glm::dvec3 linearVelocity,
                                         glm::dvec3 angularVelocity) {
  if (std::string e = m_impl->busy("setFragmentTransform"); !e.empty()) return fail(e);
  BodyRecord* b = m_impl->get(id);
  if (std::string e = checkFragment(b, "setFragmentTransform", fragment); !e.empty())
    return fail(e);
  const Vec3* restCentre = detachedCentre(*b, fragment);
  if (!restCentre)
    return fail("setFragmentTransform: fragment ", std::to_string(fragment),
                " is not detached (call detachFragment first)");
  if (!finite3d(translation)) return fail("setFragmentTransform: translation is not finite");
  if (!finite3d(linearVelocity)) return fail("setFragmentTransform: linearVelocity is not finite");
  if (!finite3d(angularVelocity))
    return fail("setFragmentTransform: angularVelocity is not finite");
  const double qn = glm::length(rotation);
  if (!(std::isfinite(qn) && qn > 1e-12))
    return fail("setFragmentTransform: rotation must be a finite non-zero quaternion");
  // Normalised in double: a single-precision engine's quaternion is off unity by ~1e-7, which
  // would otherwise show up as strain of the fragment.
  const glm::dmat3 R = glm::mat3_cast(rotation / qn);
  const std::vector<double>& X = b->model.restPositions;
  for (int32_t n : b->fracture->fragments().nodes(fragment)) {
    const glm::dvec3 x = R * glm::dvec3(X[3 * n], X[3 * n + 1], X[3 * n + 2]) + translation;
    for (int i = 0; i < 3; ++i) b->state.x[3 * n + i] = x[i];
  }
  setRigidVelocities(*b, fragment, linearVelocity, angularVelocity,
                     R * toGlm(*restCentre) + translation);
  b->surfaceStale = true;
  return {};
}

std::span<const HandoffEvent> World::handoffEvents() const { return m_impl->handoffEvents; }

// ---- Colliders the game moves between steps (two-way contact with its rigid bodies) ----

Result<void> World::setColliders(std::span<const Collider> colliders) {
  if (std::string e = m_impl->busy("setColliders"); !e.empty()) return fail(e);
  for (size_t i = 0; i < colliders.size(); ++i)
    if (Result<void> r = colliders[i].check(); !r)
      return fail("setColliders: colliders[", std::to_string(i), "].", r.error().message);
  Impl& w = *m_impl;
  w.def.colliders.assign(colliders.begin(), colliders.end());
  w.colliders.clear();
  for (const Collider& c : colliders) w.colliders.push_back(toData(c));
  w.setColliderStiffness(w.lastSubstep);
  w.impulses.assign(w.colliders.size(), glm::dvec3(0));
  w.angularImpulses = w.impulses;
  return {};
}

std::span<const Collider> World::colliders() const { return m_impl->def.colliders; }
std::span<const glm::dvec3> World::colliderImpulses() const { return m_impl->impulses; }
std::span<const glm::dvec3> World::colliderAngularImpulses() const {
  return m_impl->angularImpulses;
}

}  // namespace gf
