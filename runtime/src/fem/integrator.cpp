#include "fem/integrator.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <span>
#include <tuple>
#include <utility>

#include "contact/body_contact.h"
#include "fem/element_lanes.h"
#include "fem/newton.h"
#include "fem/piece_merge.h"
#include "kernels/damage.h"
#include "kernels/edge_stress.h"
#include "kernels/element.h"
#include "kernels/tet_inertia.h"
#include "solver/pcg_stages.h"
#include "solver/vector_stages.h"
#include "step/executor.h"
#include "step/timing.h"

namespace gf::detail {

namespace {

constexpr uint32_t kElementGrain = 128;
constexpr uint32_t kNodeGrain = 512;
constexpr uint32_t kPieceGrain = 64;
// Projection damage, one-step mode: a Newton step whose decrease of the incremental potential
// falls short of this fraction of its quadratic model's prediction is continued by another
// Newton iteration, at most kMaxModelIterations times per step (Integrator::solve). On the
// stability suite's cracked beam (InvertedRestTets, co-rotated, direct) the steps that gained
// energy, up to 3.9 J in one step as their elastic energy jumped, measured 0.52-0.87 of the
// prediction; the others 0.96-1.06. With friction against another body such a step goes on to
// convergence instead.
constexpr double kModelAgreement = 0.9;
constexpr int kMaxModelIterations = 4;
// In the one-step mode, extra Newton iterations are spent only when a node entered a collider
// that the linearisation did not see (an impact), at most this many.
constexpr int kMaxContactIterations = 2;
// A step whose swept contacts stopped a node that would have passed a thin collider iterates
// until the Newton step falls below kSweptTolerance of the first one, at most this many times:
// the node met the face with the whole step's motion still to absorb, and the penalty takes
// a fraction of its depth per iteration.
constexpr int kMaxSweptIterations = 12;
// A face's entry into a collider (FaceEntryNodeStage) clamps the nodes that cross its plane
// within this many times the face's size of the entry point: the face's own nodes and the ring
// around them.
constexpr double kFaceEntrySpread = 3;
// Pushed contacts are stiffened (DeepContactTerm) at most this many times per step.
constexpr int kMaxContactStiffenings = 8;
// Round-off of the incremental potential relative to the summed size of its terms.
constexpr double kEnergyRoundOff = 1e-11;
// Round-off of an element energy's own cancellation relative to (mu + lambda) V: a few ulps
// of each term, summed over the elements.
constexpr double kElementRoundOff = 1e-14;
// A step whose elastic energy exceeds this times Young's modulus times the body's volume (a
// mean stretch of about a thousand) diverged: no material holds together there, so it is
// rolled back like a NaN instead of handing the game an exploded body.
constexpr double kBlowUpEnergyDensity = 1e6;

Tether tetherOf(const FemState& state) {
  if (state.tether.empty()) return {};
  return {state.tether.data(), state.tetherTarget.data()};
}

}  // namespace

Integrator::Integrator(const FemModel& model) {
  const size_t nt = model.tetCount, nn = model.nodeCount;
  m_A = BlockSparseMatrix::fromTets(model.tets.data(), nt, nn);
  m_gather = ElementGather::build(model.tets.data(), nt, m_A);
  // Node -> (element, corner) references, in element order so sums are deterministic.
  m_nodeRefStart.assign(nn + 1, 0);
  for (int32_t t : model.tets) ++m_nodeRefStart[t + 1];
  for (size_t i = 0; i < nn; ++i) m_nodeRefStart[i + 1] += m_nodeRefStart[i];
  m_nodeRef.resize(model.tets.size());
  std::vector<int32_t> fill(m_nodeRefStart.begin(), m_nodeRefStart.end() - 1);
  for (size_t k = 0; k < model.tets.size(); ++k) m_nodeRef[fill[model.tets[k]]++] = int32_t(k);

  m_elemEnergy.resize(nt);
  m_elemGrad.resize(12 * nt);
  m_elemHess.resize(kElementMatrixSize * nt);
  m_svdCache.resize(kSvdCacheStride * nt);
  for (size_t t = 0; t < nt; ++t) initSvdCacheEntry(m_svdCache.data() + kSvdCacheStride * t);
  for (auto* v :
       {&m_elasticGrad, &m_grad, &m_x, &m_y, &m_dx, &m_rhs, &m_tmp, &m_adx, &m_diff, &m_kdiff})
    v->assign(3 * nn, 0.0);
  m_contactHess.resize(nn);
  m_diagonalBlock.resize(nn);
  for (size_t n = 0; n < nn; ++n) m_diagonalBlock[n] = m_A.diagonal(int32_t(n));
  m_nodeTerms.resize(kNodeTerms * nn);
  for (double v : model.restVolume) m_restVolume += v;
  // The edge of a regular tet of the mean volume, V = L^3 / (6 sqrt 2), as body contact's.
  if (nt > 0) m_cellSize = std::cbrt(6 * std::sqrt(2.0) * m_restVolume / double(nt));
  m_contactSeen.assign(nn, 0);
  if (model.solver.linearSolver == LinearSolverKind::Direct) {
    m_cholesky = std::make_unique<CholeskySolver>();
    // Symbolic analysis only fails on a corrupt pattern; PCG still solves the body then.
    if (!m_cholesky->analyze(m_A).ok()) m_cholesky.reset();
  }
}

Integrator::~Integrator() = default;

Result<void> Integrator::setupSolver(const FemModel& model, const FemState& state) {
  if (model.solver.linearSolver != LinearSolverKind::Multigrid) return {};
  m_multigrid = std::make_unique<MultigridSolver>();
  Result<void> r = m_multigrid->setup(model.solver.multigrid, model.restPositions.data(),
                                      state.fixedNode.data(), m_A);
  if (!r.ok()) {
    m_multigrid.reset();
    return fail("BodyDef.solver.multigrid: ", r.error().message);
  }
  return {};
}

void Integrator::refreshFixedNodes(const FemModel& model, const FemState& state) {
  if (!m_multigrid) return;
  (void)setupSolver(model, state);  // on failure m_multigrid is null and PCG takes over
  m_boundBrokenCount = 0;
}

detail::MultigridState Integrator::solverState() const {
  if (!m_multigrid) return {};
  // A device's coarse operators come back to the host solver, which holds the snapshot's copy
  // (a cache of the same values: the integrator's state does not change).
  if (m_device)
    m_multigrid->takeValues([this](uint64_t version, int level, double* values, size_t count) {
      return m_device->readLevel(version, level, values, count);
    });
  return m_multigrid->state();
}

Result<void> Integrator::restoreSolver(const FemModel& model, const FemState& state,
                                       const detail::MultigridState& solver) {
  // The restored fragments may be another partition under the same version number.
  m_piecesKey = kNoPieces;
  m_facesKey = kNoPieces;
  if (!m_multigrid) return {};
  if (!m_multigrid->canRestore(solver))
    if (Result<void> r = setupSolver(model, state); !r.ok()) return r;
  const EdgeGraph* g = m_fracture ? &m_fracture->graph() : nullptr;
  const std::vector<int32_t> none;
  const std::vector<int32_t>& order = m_fracture ? m_fracture->breakOrder() : none;
  if (Result<void> r =
          m_multigrid->restore(solver, m_A, g ? g->edgeNodes.data() : nullptr, g ? g->edgeCount : 0,
                               order.data(), static_cast<int32_t>(order.size()));
      !r.ok())
    return r;
  m_boundBrokenCount = solver.pendingRebind >= 0 ? solver.pendingRebind
                       : solver.rebinds.empty()  ? 0
                                                 : solver.rebinds.back();
  return {};
}

ElementStage Integrator::elementStage(const FemModel& model, const FemState& state, const double* x,
                                      double* energy, double* grad, double* hess,
                                      double* stress) const {
  ElementStage s = bodyElementStage(model, state, m_fracture, x);
  s.energy = energy;
  s.grad = grad;
  s.hess = hess;
  s.stress = stress;
  return s;
}

void Integrator::findInert(const FemModel& model, const FemState& state, JobSystem& jobs) {
  m_inert = false;
  if (!m_fracture && state.rigidTet.empty()) return;
  const LiveTetTerm live{state.rigidTet.empty() ? nullptr : state.rigidTet.data(),
                         m_fracture ? m_fracture->tetMask() : nullptr,
                         m_fracture ? m_fracture->chi() : nullptr,
                         m_fracture && m_fracture->damageModel() == kDamageDegradation};
  m_inert = CpuExecutor(jobs).reduce<MaxOp>(model.tetCount, live) == 0;
}

double Integrator::elementPass(const FemModel& model, const FemState& state, const double* x,
                               bool withGradient, bool withHessian, JobSystem& jobs) {
  const CpuExecutor exec(jobs);
  if (m_inert) {
    if (m_stressOut) exec.run(6 * model.tetCount, 4096, FillStage{0.0, m_stressOut});
    if (withGradient)
      exec.run(3 * model.nodeCount, kNodeGrain, FillStage{0.0, m_elasticGrad.data()});
    return 0.0;
  }
  const bool withHess = withGradient && withHessian;
  ElementStage stage =
      elementStage(model, state, x, m_elemEnergy.data(), withGradient ? m_elemGrad.data() : nullptr,
                   withHess ? m_elemHess.data() : nullptr, m_stressOut);
  stage.closedCrackHessian = m_closedCrackHessian;
  if (m_device) {
    // Its state arrays change with a step (plasticity, commands, a restored snapshot) and with
    // breaks; the SVD cache is the host's scratch. The device gathers the node gradient and
    // keeps the Hessians for its assembly.
    const int32_t broken = m_fracture ? m_fracture->brokenCount() : 0;
    double psi = 0;
    if (m_device->elementPass(stage, gatherStage(nullptr, nullptr), model.tetCount, model.nodeCount,
                              m_deviceStale || broken != m_deviceBroken, psi,
                              m_elasticGrad.data())) {
      m_deviceStale = false;
      m_deviceBroken = broken;
      if (withHess) m_hessOnDevice = true;
      return psi;
    }
    dropDevice();
  }
  stage.svdCache = m_svdCache.data();
  exec.runRanges(model.tetCount, kElementGrain,
                 [&stage](int32_t b, int32_t e) { evaluateElementRange(stage, b, e); });
  if (withHess) m_hessOnDevice = false;
  if (withGradient)
    exec.run(model.nodeCount, kNodeGrain, gatherStage(m_elemGrad.data(), m_elasticGrad.data()));
  return exec.sum(m_elemEnergy.data(), model.tetCount);
}

void Integrator::dropDevice() {
  m_deviceFailure = m_device->error();
  m_device.reset();
}

// The fracture criterion on the body's device (FractureBody::detect): the stresses at x and the
// candidate edges there; a failure hands the body to the CPU and detect() goes on on the host.
class Integrator::CriterionOnDevice final : public CriterionDevice {
 public:
  CriterionOnDevice(Integrator& in, const FemModel& model, const FemState& state, const double* x)
      : m_in(in), m_model(model), m_state(state), m_x(x) {}
  bool stresses(const CriterionStressStage& stage) override {
    // Cuts and pre-cuts may have broken edges before the criterion runs: state compared.
    return m_in.m_device &&
           (m_in.m_device->criterionStresses(
                m_in.elementStage(m_model, m_state, m_x, nullptr, nullptr, nullptr, nullptr),
                m_in.gatherStage(nullptr, nullptr), m_model.tetCount, m_model.nodeCount, true,
                stage) ||
            drop());
  }
  int32_t candidates(const CriterionView& host, double weakest) override {
    const int32_t count = m_in.m_device ? m_in.m_device->criterionCandidates(host, weakest) : -1;
    if (count < 0 && m_in.m_device) drop();
    return count;
  }
  bool readStresses(double* stress) override {
    return m_in.m_device && (m_in.m_device->readCriterionStresses(stress) || drop());
  }

 private:
  bool drop() {
    m_in.dropDevice();
    return false;
  }
  Integrator& m_in;
  const FemModel& m_model;
  const FemState& m_state;
  const double* m_x;
};

double Integrator::incrementalPotential(const FemModel& model, const FemState& state,
                                        const double* xn, const double* x, const StepContext& ctx,
                                        bool withGradient, bool withHessian, JobSystem& jobs) {
  const double dt = ctx.dt, dt2 = dt * dt;
  const double r1 = state.material.massDamping, r2 = state.material.stiffnessDamping;
  const double psi = elementPass(model, state, x, withGradient, withHessian, jobs);
  m_lastPsi = psi;
  const CpuExecutor exec(jobs);
  // Face contacts: their half-spaces are placed at each linearisation and held through its
  // line search, so the potential the search compares is one smooth function.
  double faceContact = 0;
  if (m_faceOn && withGradient) m_faceAny = findFaceContacts(model, state, x, ctx, jobs);
  if (m_faceOn && m_faceAny) {
    const int32_t nf = m_faceCount;
    exec.run(nf, kElementGrain,
             FaceEnergyStage{x, xn, ctx.colliders, ctx.dt, faceContacts(), m_faceEnergy.data(),
                             withGradient ? m_faceGrad.data() : nullptr,
                             withGradient && withHessian ? m_faceHess.data() : nullptr});
    faceContact = exec.sum(m_faceEnergy.data(), nf);
    if (withGradient) {
      exec.run(model.nodeCount, kNodeGrain,
               GatherStage{m_faceRefStart.data(), m_faceRef.data(), m_faceGrad.data(),
                           m_faceNodeGrad.data()});
      exec.run(3 * model.nodeCount, kNodeGrain,
               AxpyStage{m_elasticGrad.data(), m_faceNodeGrad.data(), 1.0, m_elasticGrad.data()});
    }
  }

  // Contact, inertia, gravity and constant forces are per node.
  NodePotentialStage nodes;
  nodes.x = x;
  nodes.xn = xn;
  nodes.y = m_y.data();
  nodes.nodeMass = state.nodeMass.data();
  nodes.externalForce = state.externalForce.data();
  nodes.gravity = ctx.gravity;
  nodes.colliders = ctx.colliders;
  nodes.colliderCount = ctx.colliderCount;
  nodes.swept = m_swept;
  nodes.bodies = ctx.bodyContacts.at(x);
  if (!nodes.bodies.joint) nodes.bodies.Xn = xn;
  nodes.friction = m_friction;
  nodes.dt = dt;
  nodes.massDamping = r1;
  nodes.drag = state.drag.empty() ? nullptr : state.drag.data();
  nodes.tether = tetherOf(state);
  nodes.lengthScale = model.lengthScale;
  nodes.nodeCount = model.nodeCount;
  nodes.terms = m_nodeTerms.data();
  if (withGradient) {
    nodes.elasticGrad = m_elasticGrad.data();
    nodes.grad = m_grad.data();
    nodes.contactHess = m_contactHess.data();
    nodes.contactSeen = m_contactSeen.data();
  }
  exec.run(model.nodeCount, kNodeGrain, nodes);
  auto termSum = [&](NodeTerm k) {
    return exec.sum(m_nodeTerms.data() + size_t(k) * size_t(model.nodeCount), model.nodeCount);
  };
  const double nodeTerms = termSum(kNodeEnergy), contact = termSum(kNodeContact) + faceContact;
  const double magnitude = termSum(kNodeMagnitude);
  const double gradMagnitude = withGradient ? termSum(kNodeGradMagnitude) : 0.0;
  const double damping = (r2 > 0 && m_dampKValid)
                             ? dampingTerm(state, m_dampRef.data(), x, dt, withGradient, jobs)
                             : 0.0;
  // The terms cancel (gravity work against elastic energy), so E's round-off follows the
  // size of its parts, not of E itself. Each element's energy density cancels too: near the
  // rest shape its terms are of order mu + lambda while their sum is near zero, so a body at
  // rest still carries a few ulps of (mu + lambda + mu_f) V.
  if (withGradient) {
    const MaterialCoeffs& c = state.coeffs;
    m_energyRoundOff =
        kEnergyRoundOff *
            (magnitude + gradMagnitude + std::abs(damping) + dt2 * (std::abs(psi) + contact)) +
        kElementRoundOff * dt2 * (std::abs(c.mu) + std::abs(c.lambda) + std::abs(c.fibreMu)) *
            m_restVolume;
  }
  return nodeTerms + damping + dt2 * (psi + contact);
}

double Integrator::dampingTerm(const FemState& state, const double* xn, const double* x, double dt,
                               bool withGradient, JobSystem& jobs) {
  const double r2 = state.material.stiffnessDamping;
  const int32_t n3 = int32_t(m_diff.size());
  const CpuExecutor exec(jobs);
  exec.run(n3, kNodeGrain, AxpyStage{x, xn, -1.0, m_diff.data()});
  m_dampK.multiply(m_diff.data(), m_kdiff.data(), jobs);
  if (withGradient)
    exec.run(n3, kNodeGrain, AxpyStage{m_grad.data(), m_kdiff.data(), dt * r2, m_grad.data()});
  return 0.5 * dt * r2 * exec.dot(m_diff.data(), m_kdiff.data(), n3);
}

bool Integrator::enteredUnseenContact(const FemModel& model, const FemState& state,
                                      const StepContext& ctx, JobSystem& jobs) const {
  const UnseenContactTerm unseen{m_x.data(),
                                 m_contactSeen.data(),
                                 state.fixedNode.data(),
                                 ctx.colliders,
                                 ctx.colliderCount,
                                 m_swept,
                                 ctx.bodyContacts.at(m_x.data())};
  const CpuExecutor exec(jobs);
  if (m_faceOn && m_faceAny &&
      exec.reduce<MaxOp>(m_faceCount, FaceUnseenTerm{m_x.data(), faceContacts()}) > 0)
    return true;
  return exec.reduce<MaxOp>(model.nodeCount, unseen) > 0;
}

bool Integrator::bodyFriction(const FemModel& model, const FemState& state, const StepContext& ctx,
                              JobSystem& jobs) const {
  if (!ctx.bodyContacts.start || !ctx.bodyContacts.muLambda) return false;
  return CpuExecutor(jobs).reduce<MaxOp>(
             model.nodeCount, BodyFrictionTerm{state.fixedNode.data(), ctx.bodyContacts}) > 0;
}

bool Integrator::releasedBodyContact(const FemModel& model, const FemState& state,
                                     const StepContext& ctx, JobSystem& jobs) const {
  if (!ctx.bodyContacts.start) return false;
  return CpuExecutor(jobs).reduce<MaxOp>(
             model.nodeCount, ReleasedContactTerm{m_x.data(), m_xLin.data(), state.fixedNode.data(),
                                                  ctx.bodyContacts}) > 0;
}

void Integrator::prepareFaces(const FemModel& model, const StepContext& ctx, bool crossed) {
  m_faceOn = false;
  m_faceAny = false;
  bool any = false;
  for (int c = 0; c < ctx.colliderCount; ++c) any |= ctx.colliders[c].kind != kColliderPlane;
  if (!any) return;
  // The faces that meet colliders follow the fragments (issue 15, item 3): a piece's crack
  // faces take part like the outer boundary, as body contact's surface defines them.
  const size_t nn = size_t(model.nodeCount);
  const Fragments* fragments = m_fracture ? &m_fracture->fragments() : nullptr;
  if (fragments && fragments->nodeFragment().size() != nn) fragments = nullptr;
  const uint64_t key = fragments ? fragments->version() : kNoPieces - 1;
  if (!m_faceSurface || key != m_facesKey) {
    if (!m_faceSurface) {
      m_faceSurface = std::make_unique<ContactSurface>();
      m_faceSurface->init(model);
    }
    m_facesKey = key;
    // Its own count: a restore may bring back another partition under the same version.
    m_faceSurface->update(model, fragments ? fragments->nodeFragment().data() : nullptr,
                          fragments ? fragments->count() : 1, nullptr, ++m_faceSurfaceKey);
    const std::span<const int32_t> faces = m_faceSurface->faces(), inner = m_faceSurface->inner();
    const int32_t nf = int32_t(inner.size());
    m_faceNodes.resize(4 * size_t(nf));
    for (int32_t f = 0; f < nf; ++f) {
      for (int i = 0; i < 3; ++i) m_faceNodes[4 * size_t(f) + i] = faces[3 * size_t(f) + i];
      m_faceNodes[4 * size_t(f) + 3] = inner[size_t(f)];
    }
    m_faceCount = nf;
    m_faceGather = ElementGather::build(m_faceNodes.data(), size_t(nf), m_A);
    m_faceRefStart.assign(nn + 1, 0);
    for (int32_t v : m_faceNodes) ++m_faceRefStart[v + 1];
    for (size_t i = 0; i < nn; ++i) m_faceRefStart[i + 1] += m_faceRefStart[i];
    m_faceRef.resize(m_faceNodes.size());
    std::vector<int32_t> fill(m_faceRefStart.begin(), m_faceRefStart.end() - 1);
    for (size_t k = 0; k < m_faceNodes.size(); ++k) m_faceRef[fill[m_faceNodes[k]]++] = int32_t(k);
    m_faceCollider.assign(size_t(nf), -1);
    for (auto* v : {&m_faceWeight, &m_facePoint, &m_faceNormal}) v->assign(size_t(nf), Vec3{});
    m_faceK.assign(size_t(nf), 0.0);
    m_faceMuLambda.assign(size_t(nf), 0.0);
    m_faceSeen.assign(size_t(nf), 0);
    m_faceEnergy.assign(size_t(nf), 0.0);
    m_faceGrad.assign(12 * size_t(nf), 0.0);
    m_faceHess.assign(kElementMatrixSize * size_t(nf), 0.0);
    m_faceTotal.assign(6 * size_t(nf), 0.0);
    m_faceNodeGrad.assign(3 * nn, 0.0);
  }
  m_faceOn = m_faceCount > 0;
  // A collider that a node's path would have passed through this step (an impact at a cell or
  // more per step) is left to the nodes' swept faces and their stiffened penalty: face
  // contacts placed where Newton linearises such a step, on a body far from where it ends,
  // only added forces (a block at 100 m/s on a 1 cm rod ended 1.2 m/s across it, 0.19 without).
  m_faceSkip.assign(size_t(ctx.colliderCount), 0);
  if (m_faceOn && crossed && m_swept.collider)
    for (int32_t n = 0; n < model.nodeCount; ++n)
      if (m_sweptCrossed[n] > 0 && m_sweptCollider[n] >= 0) m_faceSkip[m_sweptCollider[n]] = 1;
}

void Integrator::sweepFaces(const FemModel& model, const FemState& state, const StepContext& ctx,
                            JobSystem& jobs, BodyStepReport& rep) {
  m_faceEntries.clear();
  if (!m_faceOn || !m_swept.collider) return;
  // FaceSweepStage keeps a face only where the collider would end more than half its thickness
  // (or of half a cell, maxDepth) past it, which takes relative motion beyond that.
  const CpuExecutor exec(jobs);
  const double speed = std::sqrt(
      exec.reduce<MaxOp>(model.nodeCount, NodeSpeedTerm{state.v.data(), state.fixedNode.data()}));
  bool fast = false;
  for (int c = 0; c < ctx.colliderCount; ++c) {
    const ColliderData& col = ctx.colliders[c];
    if (col.kind == kColliderPlane) continue;
    const Vec3 h = col.halfExtents;
    const double thinnest =
        col.kind == kColliderBox ? 2 * std::min({h.x, h.y, h.z}) : 2 * col.radius;
    fast |= ctx.dt * (speed + norm(col.velocity)) > 0.5 * std::min(thinnest, 0.5 * m_cellSize);
  }
  if (!fast) return;
  const size_t nf = size_t(m_faceCount);
  m_faceSweptCollider.resize(nf);
  m_faceSweptPoint.resize(nf);
  m_faceSweptNormal.resize(nf);
  m_faceSweptRadius.resize(nf);
  m_faceSweptCrossed.resize(nf);
  const FacePlaneStage plane = facePlaneStage(model, state, state.x.data(), ctx);
  FaceSweepStage sweep;
  sweep.faces = m_faceNodes.data();
  sweep.x = state.x.data();
  sweep.v = state.v.data();
  sweep.fixedNode = state.fixedNode.data();
  sweep.dt = ctx.dt;
  sweep.colliders = ctx.colliders;
  sweep.colliderCount = ctx.colliderCount;
  sweep.maxDepth = plane.maxDepth;
  sweep.band = plane.band;
  sweep.collider = m_faceSweptCollider.data();
  sweep.point = m_faceSweptPoint.data();
  sweep.normal = m_faceSweptNormal.data();
  sweep.radius = m_faceSweptRadius.data();
  sweep.crossed = m_faceSweptCrossed.data();
  exec.run(m_faceCount, kElementGrain, sweep);
  if (!(exec.max(m_faceSweptCrossed.data(), m_faceCount) > 0)) return;
  // Few faces cross in a step: their entries in face order, for the node pass.
  for (size_t f = 0; f < nf; ++f)
    if (m_faceSweptCollider[f] >= 0)
      m_faceEntries.push_back(FaceEntry{m_faceSweptCollider[f], m_faceSweptPoint[f],
                                        m_faceSweptNormal[f], m_faceSweptRadius[f]});
  FaceEntryNodeStage nodes;
  nodes.x = state.x.data();
  nodes.v = state.v.data();
  nodes.fixedNode = state.fixedNode.data();
  nodes.dt = ctx.dt;
  nodes.cell = m_cellSize;
  nodes.spread = kFaceEntrySpread;
  nodes.colliders = ctx.colliders;
  nodes.entries = m_faceEntries.data();
  nodes.entryCount = int32_t(m_faceEntries.size());
  nodes.collider = m_sweptCollider.data();
  nodes.point = m_sweptPoint.data();
  nodes.normal = m_sweptNormal.data();
  nodes.stiffness = m_sweptStiffness.data();
  nodes.crossed = m_sweptCrossed.data();
  nodes.bound = m_sweptBound.data();
  exec.run(model.nodeCount, kNodeGrain, nodes);
  // As for a node's crossing (prepareFaces): the collider is left to the swept nodes.
  for (const FaceEntry& e : m_faceEntries) m_faceSkip[size_t(e.collider)] = 1;
  rep.flags |= kStepContactSwept;
}

FacePlaneStage Integrator::facePlaneStage(const FemModel& model, const FemState& state,
                                          const double* x, const StepContext& ctx) const {
  FacePlaneStage plane;
  plane.x = x;
  plane.xn = m_xStart.data();
  plane.dt = ctx.dt;
  plane.nodeMass = state.nodeMass.data();
  plane.fixedNode = state.fixedNode.data();
  plane.colliders = ctx.colliders;
  plane.colliderCount = ctx.colliderCount;
  plane.swept = m_swept;
  // A cell ahead: a face meets its half-space within the step, not after it has passed in.
  plane.margin = m_cellSize;
  // Half a cell: a collider that far past a face has passed it anyway (its nodes no longer
  // hold it either), and a twentieth of a cell covers the wedges between bent faces' prisms
  // (faceContact).
  plane.maxDepth = 0.5 * m_cellSize;
  plane.band = 0.05 * m_cellSize;
  plane.bodyFriction = model.friction;
  return plane;
}

bool Integrator::findFaceContacts(const FemModel& model, const FemState& state, const double* x,
                                  const StepContext& ctx, JobSystem& jobs) {
  FacePlaneStage plane = facePlaneStage(model, state, x, ctx);
  plane.fc = faceContacts();
  if (m_faceSkip.size() != size_t(ctx.colliderCount))
    m_faceSkip.assign(size_t(ctx.colliderCount), 0);
  plane.skip = m_faceSkip.data();
  return CpuExecutor(jobs).reduce<MaxOp>(m_faceCount, plane) > 0;
}

void Integrator::groupPieces(const FemModel& model, const CpuExecutor& exec) {
  const size_t nn = size_t(model.nodeCount);
  const Fragments* fragments = m_fracture ? &m_fracture->fragments() : nullptr;
  if (fragments && fragments->nodeFragment().size() != nn) fragments = nullptr;
  const uint64_t key = fragments ? fragments->version() : kNoPieces - 1;
  if (key == m_piecesKey && m_pieceOfNode.size() == nn) return;
  m_piecesKey = key;
  int32_t count = fragments ? fragments->count() : 1;
  if (fragments) {
    const std::span<const int32_t> of = fragments->nodeFragment();
    m_pieceOfNode.assign(of.begin(), of.end());
    // The projection model's damaged tets still push fragments apart (a closed crack resists
    // compression), so fragments that share a tet are one mechanical system: their forces on
    // each other have moments, and a frame per fragment whose angular momentum ignored them
    // gave them energy (up to 1e4 E0 in the stability suite). Such fragments turn as one piece.
    if (m_fracture->damageModel() == kDamageProjection && count > 1) {
      const size_t c = size_t(count), chunks = size_t(pieceMergeChunks(count));
      for (auto* v : {&m_mergeLabel, &m_mergeNext}) v->resize(c);
      m_mergeRootId.resize(c + 1);
      m_mergeChanged.resize(c);
      m_mergeChunkSum.resize(chunks);
      m_mergeChunkOffset.resize(chunks + 1);
      const PieceMergeScratch scratch{m_mergeLabel.data(),    m_mergeNext.data(),
                                      m_mergeChanged.data(),  m_mergeRootId.data(),
                                      m_mergeChunkSum.data(), m_mergeChunkOffset.data()};
      count = mergePiecesSharingTets(exec, model.tets.data(), model.tetCount, m_pieceOfNode.data(),
                                     model.nodeCount, count, scratch);
    }
    m_pieceLists.build(exec, m_pieceOfNode.data(), model.nodeCount, count, m_pieceScan);
  } else {
    m_pieceOfNode.assign(nn, 0);
    m_pieceLists.build(exec, nullptr, model.nodeCount, count, m_pieceScan);
  }
  m_pieces.resize(size_t(count));
  constexpr size_t terms = std::max({kPieceMassTerms, kPieceSpinTerms, kPieceFrictionTerms});
  m_pieceTerms.resize(terms * nn);
  m_pieceSums.resize(terms * size_t(count));
  m_piecePartials.resize(terms * size_t(m_pieceLists.view().chunks));
}

void Integrator::sumPerPiece(const FemModel& model, const CpuExecutor& exec, int components) {
  segmentedReduce<SumOp>(exec, m_pieceLists.view(), m_pieceTerms.data(), model.nodeCount,
                         components, m_piecePartials.data(), m_pieceSums.data());
}

void Integrator::predictRigidMotion(const FemModel& model, const FemState& state,
                                    const StepContext& ctx, double fullDt, JobSystem& jobs) {
  const double dt = ctx.dt;
  const size_t n3 = state.x.size();
  const CpuExecutor exec(jobs);
  exec.run(int32_t(n3), kNodeGrain, AxpyStage{state.x.data(), state.v.data(), dt, m_y.data()});
  const bool damped = state.material.stiffnessDamping > 0;
  if (damped) m_dampRef = state.x;
  m_rigidPieces = model.solver.corotatedInertia;
  if (!m_rigidPieces) return;
  groupPieces(model, exec);
  // Per piece (a fragment, or the whole body): mass, centre, momentum, angular momentum and
  // inertia of its lumped nodes, each a per-node term summed per piece. A piece holding a
  // prescribed node moves as plain backward Euler says.
  const int32_t nn = model.nodeCount, pieces = int32_t(m_pieces.size());
  exec.run(nn, kNodeGrain,
           PieceMassTerms{state.x.data(), state.v.data(), state.nodeMass.data(),
                          state.fixedNode.data(), nn, m_pieceTerms.data()});
  sumPerPiece(model, exec, kPieceMassTerms);
  exec.run(pieces, kPieceGrain, PieceMassStage{m_pieceSums.data(), pieces, m_pieces.data()});
  exec.run(nn, kNodeGrain,
           PieceSpinTerms{state.x.data(), state.v.data(), state.nodeMass.data(), m_pieces.data(),
                          m_pieceOfNode.data(), nn, m_pieceTerms.data()});
  sumPerPiece(model, exec, kPieceSpinTerms);
  exec.run(pieces, kPieceGrain,
           PieceSpinStage{m_pieceSums.data(), pieces, dt, fullDt, m_pieces.data()});
  if (m_friction.muLambda || m_bodyFriction) frictionStart(model, state, ctx, exec);
  exec.run(
      nn, kNodeGrain,
      RigidStartStage{state.x.data(), state.v.data(), m_pieces.data(), m_pieceOfNode.data(), dt,
                      fullDt, m_x.data(), m_y.data(), damped ? m_dampRef.data() : nullptr});
  // A piece of a cracked body is rubble or holds cracked elements, so I^-1 L of its loosely
  // joined parts is no rigid spin, and its turn about the centre can press it into the
  // ground: a shattered block (one piece, its fragments sharing damaged tets) started with
  // 2.7 J of penalty energy where x_n had 6e-4 J, one Newton step only lowers the potential
  // from there, and the contact impulses spun it from 6.6 to 52.6 rad/s (+7.8 E0; stability
  // suite, Nu0p4999). Starting such a piece at x_n but keeping the turned target was no cure:
  // the end spin then read the turn the solve had not made as the deformation's and doubled
  // it every step (+8.8 E0 at 10 m/s). So a cracked body's piece that its turn, or its motion
  // over the step (PiecePressTerms), presses deeper into a collider than x_n is stepped by
  // plain backward Euler, as a thin piece is, which cannot gain energy. An intact body keeps its
  // turn: a block rocking under another needs it (BodyContact.TwoBlocksComeToRestStacked).
  if (ctx.colliderCount > 0 && m_fracture && m_fracture->brokenCount() > 0) {
    m_piecePressed.resize(size_t(pieces));
    exec.run(
        nn, kNodeGrain,
        PiecePressTerms{state.x.data(), m_x.data(), m_pieces.data(), m_pieceOfNode.data(),
                        ctx.colliders, ctx.colliderCount, m_swept, fullDt, m_pieceTerms.data()});
    segmentedReduce<MaxOp>(exec, m_pieceLists.view(), m_pieceTerms.data(), nn, 1,
                           m_piecePartials.data(), m_pieceSums.data());
    exec.run(pieces, kPieceGrain,
             PiecePressedStage{m_pieceSums.data(), m_pieces.data(), m_piecePressed.data()});
    if (exec.max(m_piecePressed.data(), pieces) > 0)
      exec.run(nn, kNodeGrain,
               PlainStepStage{state.x.data(), state.v.data(), m_pieces.data(), m_pieceOfNode.data(),
                              dt, m_x.data(), m_y.data(), damped ? m_dampRef.data() : nullptr});
  }
}

void Integrator::buildFriction(const FemModel& model, const FemState& state, const StepContext& ctx,
                               JobSystem& jobs) {
  m_friction = {};
  bool anyFriction = false;
  for (int c = 0; c < ctx.colliderCount; ++c) anyFriction |= ctx.colliders[c].friction > 0;
  if (!(model.friction > 0) || !anyFriction) return;  // the default: frictionless colliders
  const int32_t nn = model.nodeCount;
  m_frictionMuLambda.resize(size_t(ctx.colliderCount) * size_t(nn));
  m_frictionNormal.resize(m_frictionMuLambda.size());
  m_frictionTouching.resize(size_t(nn));
  const CpuExecutor exec(jobs);
  exec.run(nn, kNodeGrain,
           FrictionContactStage{m_xStart.data(), state.fixedNode.data(), state.nodeMass.data(),
                                ctx.colliders, ctx.colliderCount, model.friction, nn,
                                m_frictionMuLambda.data(), m_frictionNormal.data(),
                                m_frictionTouching.data()});
  if (exec.max(m_frictionTouching.data(), nn) > 0)
    m_friction = {m_frictionMuLambda.data(), m_frictionNormal.data(), m_xStart.data(), nn};
}

ExternalImpulse Integrator::externalImpulse(const FemState& state, const StepContext& ctx) const {
  ExternalImpulse e;
  e.externalForce = state.externalForce.data();
  e.nodeMass = state.nodeMass.data();
  e.xStart = m_xStart.data();
  e.xLin = m_xLin.data();
  e.massDamping = state.material.massDamping;
  e.drag = state.drag.empty() ? nullptr : state.drag.data();
  e.tether = tetherOf(state);
  e.dt = ctx.dt;
  e.colliders = ctx.colliders;
  e.colliderCount = ctx.colliderCount;
  e.swept = m_swept;
  e.bodies = ctx.bodyContacts;
  if (!e.bodies.joint) e.bodies.Xn = m_xStart.data();
  e.friction = m_friction;
  if (m_faceOn && m_faceAny) e.faceImpulse = m_faceNodeGrad.data();
  return e;
}

void Integrator::frictionStart(const FemModel& model, const FemState& state, const StepContext& ctx,
                               const CpuExecutor& exec) {
  // Each free piece's contact normal, friction force, gravity and point forces (the elastic
  // forces are internal) summed per piece; the pieces are fresh from predictRigidMotion.
  const int32_t nn = model.nodeCount, pieces = int32_t(m_pieces.size());
  exec.run(nn, kNodeGrain,
           PieceFrictionTerms{state.externalForce.data(), state.nodeMass.data(), ctx.gravity,
                              ctx.colliders, m_friction, ctx.colliderCount, nn, m_pieceTerms.data(),
                              ctx.bodyContacts});
  sumPerPiece(model, exec, kPieceFrictionTerms);
  exec.run(pieces, kPieceGrain,
           PieceSlideStage{m_pieceSums.data(), pieces, ctx.dt, m_pieces.data()});
}

void Integrator::rigidEndVelocities(const FemModel& model, FemState& state, const StepContext& ctx,
                                    JobSystem& jobs) {
  if (!m_rigidPieces) return;
  const CpuExecutor exec(jobs);
  const int32_t nn = model.nodeCount, pieces = int32_t(m_pieces.size());
  // The new centres, then the end spins: the angular momentum at the end is the start's plus
  // the moment of the external impulses over the step (EndSpinTerms), and the spin w' is
  // chosen to give exactly that with the deformation's own velocities, so a free body keeps
  // its angular momentum, and one that stretched turns slower, as a skater who opens her arms.
  exec.run(nn, kNodeGrain,
           EndCentreTerms{state.x.data(), state.nodeMass.data(), m_pieces.data(),
                          m_pieceOfNode.data(), nn, m_pieceTerms.data()});
  sumPerPiece(model, exec, 3);
  exec.run(pieces, kPieceGrain, PieceEndCentreStage{m_pieceSums.data(), pieces, m_pieces.data()});
  exec.run(nn, kNodeGrain,
           EndSpinTerms{state.x.data(), m_xStart.data(), state.nodeMass.data(), m_pieces.data(),
                        m_pieceOfNode.data(), externalImpulse(state, ctx), ctx.dt, nn,
                        m_pieceTerms.data()});
  sumPerPiece(model, exec, kPieceSpinTerms);
  exec.run(pieces, kPieceGrain, PieceEndSpinStage{m_pieceSums.data(), pieces, m_pieces.data()});
  exec.run(nn, kNodeGrain,
           RigidEndVelocityStage{state.x.data(), m_xStart.data(), m_pieces.data(),
                                 m_pieceOfNode.data(), ctx.dt, state.v.data()});
}

void Integrator::thetaEndState(const FemModel& model, FemState& state, const StepContext& inner,
                               double dt, double theta, JobSystem& jobs) {
  const double h = inner.dt;  // theta * dt, the step the solve took to z = m_x
  const CpuExecutor exec(jobs);
  exec.run(int32_t(state.x.size()), kNodeGrain,
           ThetaEndStage{m_x.data(), m_xStart.data(), m_vStart.data(), state.gripVelocity.data(),
                         state.fixedNode.data(), dt, h, theta, state.x.data(), state.v.data()});
  if (!m_rigidPieces) return;
  // Free pieces: the centre of z, then the extrapolated positions with the deformation
  // velocities and the end spins that give each piece its angular momentum with them
  // (rigidEndVelocities), then the spin added to the velocities.
  const int32_t nn = model.nodeCount, pieces = int32_t(m_pieces.size());
  exec.run(nn, kNodeGrain,
           EndCentreTerms{m_x.data(), state.nodeMass.data(), m_pieces.data(), m_pieceOfNode.data(),
                          nn, m_pieceTerms.data()});
  sumPerPiece(model, exec, 3);
  exec.run(pieces, kPieceGrain, PieceEndCentreStage{m_pieceSums.data(), pieces, m_pieces.data()});
  ThetaSpinTerms spin;
  spin.z = m_x.data();
  spin.xStart = m_xStart.data();
  spin.vStart = m_vStart.data();
  spin.nodeMass = state.nodeMass.data();
  spin.pieces = m_pieces.data();
  spin.pieceOfNode = m_pieceOfNode.data();
  spin.external = externalImpulse(state, inner);
  spin.h = h;
  spin.theta = theta;
  spin.nodeCount = nn;
  spin.x = state.x.data();
  spin.v = state.v.data();
  spin.out = m_pieceTerms.data();
  exec.run(nn, kNodeGrain, spin);
  sumPerPiece(model, exec, kPieceSpinTerms);
  exec.run(pieces, kPieceGrain, PieceEndSpinStage{m_pieceSums.data(), pieces, m_pieces.data()});
  exec.run(nn, kNodeGrain,
           ThetaVelocityStage{state.x.data(), m_pieces.data(), m_pieceOfNode.data(), h, theta,
                              state.v.data()});
}

EnergyBreakdown Integrator::energies(const FemModel& model, const FemState& state, const double* x,
                                     const StepContext& ctx, JobSystem& jobs) const {
  // Its own buffers, so that a diagnostic between steps never races or clobbers the step's.
  std::vector<double> energy(size_t(model.tetCount)), grad(12 * size_t(model.tetCount));
  const CpuExecutor exec(jobs);
  const ElementStage stage =
      elementStage(model, state, x, energy.data(), grad.data(), nullptr, nullptr);
  exec.runRanges(model.tetCount, kElementGrain,
                 [&stage](int32_t b, int32_t e) { evaluateElementRange(stage, b, e); });
  EnergyBreakdown out;
  out.elastic = exec.sum(energy.data(), model.tetCount);
  out.contact = exec.reduce<SumOp>(
      model.nodeCount,
      ColliderEnergyTerm{x, state.nodeMass.data(), ctx.colliders, ctx.colliderCount});
  bool any = false;
  for (int c = 0; c < ctx.colliderCount; ++c) any |= ctx.colliders[c].kind != kColliderPlane;
  if (!any || m_faceCount == 0) return out;
  // The face penalties, as the step finds and evaluates them (FacePlaneStage, FaceEnergyStage)
  // on the faces of the last step's fragments, at x alone: the nearest-face depths (no sweep,
  // nothing skipped) and no friction, which is not stored energy.
  const size_t nf = size_t(m_faceCount);
  std::vector<int32_t> collider(nf);
  std::vector<Vec3> weight(nf), point(nf), normal(nf);
  std::vector<double> k(nf), muLambda(nf), faceEnergy(nf);
  std::vector<uint8_t> seen(nf), skip(size_t(ctx.colliderCount), 0);
  const FaceContacts fc{m_faceNodes.data(), collider.data(), weight.data(), point.data(),
                        normal.data(),      k.data(),        seen.data(),   muLambda.data()};
  FacePlaneStage plane = facePlaneStage(model, state, x, ctx);
  plane.xn = x;
  plane.dt = 0;
  plane.swept = {};
  plane.bodyFriction = 0;
  plane.skip = skip.data();
  plane.fc = fc;
  if (exec.reduce<MaxOp>(m_faceCount, plane) > 0) {
    exec.run(m_faceCount, kElementGrain,
             FaceEnergyStage{x, x, ctx.colliders, ctx.dt, fc, faceEnergy.data(), nullptr, nullptr});
    out.contact += exec.sum(faceEnergy.data(), m_faceCount);
  }
  return out;
}

BodyContactBalance Integrator::bodyContactImpulses(const FemState& state, const StepContext& ctx,
                                                   bool rolledBack, double* out, JobSystem& jobs) {
  const HalfSpaceContacts& hs = ctx.bodyContacts;
  if (!hs.start) return {};
  const int32_t nn = int32_t(state.nodeMass.size());
  if (rolledBack) {
    std::fill_n(out, 3 * size_t(hs.start[nn]), 0.0);
    return {};
  }
  // As for the colliders: the force that entered the momentum balance is the penalty
  // linearised at the last Newton step's start, g + H (x - x_lin), one half-space at a time.
  BodyContactBalanceStage balance;
  balance.x = state.x.data();
  balance.xLin = m_xLin.data();
  balance.xStart = m_xStart.data();
  balance.v = state.v.data();
  balance.vStart = m_vStart.data();
  balance.nodeMass = state.nodeMass.data();
  balance.externalForce = state.externalForce.data();
  balance.fixedNode = state.fixedNode.data();
  balance.drag = state.drag.empty() ? nullptr : state.drag.data();
  balance.tether = tetherOf(state);
  balance.hs = hs;
  balance.gravity = ctx.gravity;
  balance.dt = ctx.dt;
  balance.massDamping = state.material.massDamping;
  balance.nodeCount = nn;
  balance.impulse = out;
  m_balanceTerms.resize(kBalanceTerms * size_t(nn));
  balance.terms = m_balanceTerms.data();
  const CpuExecutor exec(jobs);
  exec.run(nn, kNodeGrain, balance);
  auto total = [&](int k) { return exec.sum(m_balanceTerms.data() + size_t(k) * size_t(nn), nn); };
  // The linear model is what moved the body only when Newton's last step was taken whole and
  // solved exactly; otherwise its residual moved it too. What the body's momentum did that
  // gravity, point forces and mass damping do not explain is the contact's (eq 2.7:
  // m (v' - v) = dt f - r1 m (x' - x_n) + ... at a zero residual). A body on a grip or a
  // collider also takes momentum from outside, which cannot be told apart from the residual.
  BodyContactBalance result;
  result.external = exec.max(m_balanceTerms.data() + 6 * size_t(nn), nn) > 0;
  if (ctx.colliderImpulse)
    for (int k = 0; k < 6 * ctx.colliderCount; ++k) result.external |= ctx.colliderImpulse[k] != 0;
  if (!result.external)
    for (int k = 0; k < 3; ++k) result.unexplained[k] = total(3 + k) - total(k);
  return result;
}

void Integrator::prescribedNodeForces(const FemModel& model, const FemState& state,
                                      const StepContext& ctx, JobSystem& jobs,
                                      std::vector<double>& out) {
  // m_xStart and m_vStart still hold the last step's start, which fixes the inertia target y.
  // Below theta = 1 the step solved theta dt to z (m_x), where its forces act.
  StepContext inner = ctx;
  inner.dt = m_theta * ctx.dt;
  const double* x = m_theta == 1 ? state.x.data() : m_x.data();
  findInert(model, state, jobs);  // a restore may have come between
  (void)incrementalPotential(model, state, m_xStart.data(), x, inner, true, false, jobs);
  const double dt2 = inner.dt * inner.dt;
  out.resize(state.x.size());
  CpuExecutor(jobs).run(
      int32_t(out.size()), kNodeGrain,
      PrescribedGradientStage{m_grad.data(), state.fixedNode.data(), 1.0 / dt2, out.data()});
}

SolveReport Integrator::patternSolve(const FemModel& model, const double* b, double* x,
                                     double tolerance, double toleranceScale, JobSystem& jobs,
                                     const std::function<void()>& hostMatrixLost) {
  SolveReport sr;
  // A failed device solve leaves x as it was; the host solves again from there, with the
  // matrix the device held rebuilt where it cannot be read back.
  auto onHost = [&] {
    const bool stale = m_hostMatrixStale;
    dropDevice();
    m_matrixOnDevice = m_hostMatrixStale = false;
    if (stale) hostMatrixLost();
  };
  if (m_inert) {
    // Block diagonal: block-Jacobi PCG is exact in one iteration, where a factorisation or a
    // V-cycle of the whole pattern would cost as much as for the intact body.
    sr = m_pcg.solve(m_A, b, x, model.solver.maxLinearIterations, tolerance, jobs);
  } else if (m_cholesky) {
    sr = m_cholesky->solve(m_A, b, x);
  } else if (m_multigrid) {
    bool solved = false;
    if (m_device) {
      sr = m_multigrid->solveWith(
          m_A, x, jobs,
          [&](const CycleSettings& settings, const std::function<const MultigridMirror*()>& prepare,
              MultigridRun& run, SolveReport& report) {
            return m_device->multigridSolve(m_A, m_matrixOnDevice, settings, prepare, b, x,
                                            model.solver.maxLinearIterations, tolerance, run,
                                            report);
          },
          solved, [this] { return hostMatrix(); });
      if (!solved) onHost();
    }
    if (!solved)
      sr = m_multigrid->solve(m_A, b, x, model.solver.maxLinearIterations, tolerance, jobs);
    // A fixed number of V-cycles is a chosen cost, not a convergence target: only a
    // non-finite result is a failure there.
    if (!model.solver.multigrid.preconditionCG && std::isfinite(sr.relativeResidual))
      sr.converged = true;
  } else if (!m_device || !m_device->pcgSolve(m_A, m_matrixOnDevice, b, x,
                                              model.solver.maxLinearIterations, tolerance, sr)) {
    if (m_device) onHost();
    sr = m_pcg.solve(m_A, b, x, model.solver.maxLinearIterations, tolerance, jobs);
  }
  sr.relativeResidual /= toleranceScale;  // against the scale the tolerance was set on
  return sr;
}

bool Integrator::selfPairsAct(const FemModel& model, const StepContext& ctx, double dt2,
                              JobSystem& jobs) {
  HalfSpaceContacts h = ctx.bodyContacts.at(m_x.data());
  if (!h.start || !h.reactionStart) return false;
  h.Xn = m_xStart.data();
  const int32_t pairs = h.start[model.nodeCount];
  m_pairActive.resize(size_t(pairs));
  m_pairProjection.resize(size_t(pairs));
  m_pairNormal.resize(size_t(pairs));
  m_pairWeight.resize(size_t(pairs));
  m_pairFriction.resize(size_t(pairs));
  m_pairSlide.resize(size_t(pairs));
  const CpuExecutor exec(jobs);
  exec.run(pairs, kNodeGrain,
           SelfPairActiveStage{h, dt2, m_pairActive.data(), m_pairNormal.data(),
                               m_pairWeight.data(), m_pairFriction.data()});
  return exec.max(m_pairActive.data(), pairs) > 0 || exec.max(m_pairFriction.data(), pairs) > 0;
}

SolveReport Integrator::coupledSolve(const FemModel& model, const FemState& state,
                                     const StepContext& ctx, double tolerance,
                                     double toleranceScale, JobSystem& jobs) {
  const int32_t n3 = int32_t(m_x.size());
  const PairCoupledSystem system{ctx.bodyContacts,
                                 state.fixedNode.data(),
                                 m_pairActive.data(),
                                 m_pairNormal.data(),
                                 m_pairWeight.data(),
                                 m_pairFriction.data(),
                                 m_pairProjection.data(),
                                 m_pairSlide.data(),
                                 0,
                                 model.nodeCount,
                                 0,
                                 ctx.bodyContacts.start[model.nodeCount]};
  const PairCoupledPart part{this, &model, 0};
  m_cgWork.resize(5 * size_t(n3));
  SolveReport sr = solvePairCoupled({&part, 1}, system, m_rhs.data(), m_dx.data(), m_cgWork.data(),
                                    model.solver.maxLinearIterations, tolerance, jobs);
  sr.relativeResidual /= toleranceScale;
  return sr;
}

SolveReport Integrator::solvePairCoupled(std::span<const PairCoupledPart> parts,
                                         const PairCoupledSystem& sys, const double* rhs,
                                         double* dx, double* cgWork, int maxIterations,
                                         double tolerance, JobSystem& jobs) {
  // Flexible preconditioned CG on the whole Newton matrix: each part's pattern matrix m_A plus
  // the moving pairs' cross terms (SelfPairCouplingStage), preconditioned by each part's own
  // solver on its m_A, which holds the pairs' diagonal blocks: the direct factor once, or a
  // multigrid or block-Jacobi solve per iteration (flexible: an inexact inner solve is not a
  // fixed linear operator). The vectors are the system's run of joint vectors indexed from its
  // first node (v - at is then the joint vector the pair stages index by node).
  const CpuExecutor exec(jobs);
  const int32_t n3 = 3 * sys.nodes;
  const int64_t at = 3 * int64_t(sys.nodeBegin);
  auto product = [&](const double* v, double* y) {
    for (const PairCoupledPart& p : parts)
      p.integrator->m_A.multiply(v + (p.offset - at), y + (p.offset - at), jobs);
    exec.run(sys.pairs, kNodeGrain,
             OffsetStage<SelfPairProjectStage>{
                 {sys.contacts, sys.fixed, sys.active, sys.normal, sys.weight, sys.friction, v - at,
                  sys.projection, sys.slide},
                 sys.pairBegin});
    exec.run(sys.nodes, kNodeGrain,
             OffsetStage<SelfPairCouplingStage>{
                 {sys.contacts, sys.fixed, sys.active, sys.normal, sys.weight, sys.friction,
                  sys.projection, sys.slide, v - at, y - at},
                 sys.nodeBegin});
  };
  std::vector<uint8_t> factored(parts.size(), 0);
  for (size_t i = 0; i < parts.size(); ++i) {
    Integrator& in = *parts[i].integrator;
    factored[i] = in.m_cholesky && !in.m_inert && in.m_cholesky->factorize(in.m_A);
  }
  int innerIterations = 0;
  auto precondition = [&](const double* r, double* z) {
    exec.run(n3, kNodeGrain, FillStage{0.0, z});
    for (size_t i = 0; i < parts.size(); ++i) {
      Integrator& in = *parts[i].integrator;
      const FemModel& model = *parts[i].model;
      const double* rp = r + (parts[i].offset - at);
      double* zp = z + (parts[i].offset - at);
      if (factored[i])
        in.m_cholesky->solveFactored(rp, zp);
      else if (in.m_cholesky && !in.m_inert)
        innerIterations +=
            in.m_pcg.solve(in.m_A, rp, zp, model.solver.maxLinearIterations, tolerance, jobs)
                .iterations;
      else
        innerIterations += in.patternSolve(model, rp, zp, tolerance, 1.0, jobs).iterations;
    }
    return exec.dot(r, z, n3);
  };
  struct Operator {
    int32_t n;
    decltype(product)& apply;
  };
  struct Preconditioner {
    bool flexible;
    void (*prepare)();
    decltype(precondition)& apply;
  };
  double* w = cgWork;
  SolveReport sr =
      conjugateGradients(exec, Operator{sys.nodes, product}, rhs, dx,
                         CgBuffers{w, w + n3, w + 2 * n3, w + 3 * n3, w + 4 * n3},
                         Preconditioner{true, [] {}, precondition}, maxIterations, tolerance);
  sr.iterations += innerIterations;
  return sr;
}

void Integrator::startNewton(const FemModel& model, const FemState& state, const StepContext& ctx,
                             double fullDt, JobSystem& jobs) {
  const double dt = ctx.dt;
  // Start at x_n with the prescribed nodes already moved; they stay put from here on. Free
  // pieces start at their rigid motion over the step, and their inertia target y follows it.
  const CpuExecutor exec(jobs);
  const int32_t n3i = int32_t(state.x.size());
  // Inert: breaks only make more tets rigid or split, so it holds for the whole step.
  findInert(model, state, jobs);
  // gripVelocity is zero on free nodes, so one pass moves exactly the prescribed ones.
  exec.run(n3i, kNodeGrain, AxpyStage{state.x.data(), state.gripVelocity.data(), dt, m_x.data()});
  buildFriction(model, state, ctx, jobs);
  m_bodyFriction = bodyFriction(model, state, ctx, jobs);
  predictRigidMotion(model, state, ctx, fullDt, jobs);
  // Nodes that a face's entry clamps (FaceEntryNodeStage) are in front of their planes at x_n,
  // where the penalty has no curvature: Newton's first step is the free flight, the line search
  // stops it short of the planes, and the next linearisation sees no contact either (a box at
  // 100 m/s onto a 1 cm ball stalled at 18 m/s with no contact force). At the free flight's end
  // every such node is past its plane, so Newton starts there.
  if (!m_faceEntries.empty()) {
    exec.run(n3i, kNodeGrain,
             FreeDifferenceStage{m_y.data(), m_x.data(), state.fixedNode.data(), m_tmp.data()});
    exec.run(n3i, kNodeGrain, AxpyStage{m_x.data(), m_tmp.data(), 1.0, m_x.data()});
  }
}

bool Integrator::assemble(const FemModel& model, const FemState& state, const StepContext& ctx,
                          int it, JobSystem& jobs) {
  const double dt = ctx.dt, dt2 = dt * dt;
  const double r1 = state.material.massDamping, r2 = state.material.stiffnessDamping;
  const bool faces = m_faceOn && m_faceAny;
  const bool writeDamping = it == 0 && r2 > 0 && !m_inert;
  if (it == 0) m_dampKOnDevice = false;
  if (writeDamping) {
    if (m_dampK.n == 0) m_dampK = m_A;
    m_dampKValid = true;
  }
  const NodeBlockStage nodes{nullptr,
                             m_diagonalBlock.data(),
                             state.nodeMass.data(),
                             m_contactHess.data(),
                             1 + dt * r1,
                             dt2,
                             state.drag.empty() ? nullptr : state.drag.data(),
                             tetherOf(state)};
  m_matrixOnDevice = m_hostMatrixStale = false;
  // The device assembles from the Hessians it holds where nothing else adds element blocks:
  // face contacts gather blocks of their own, and body contact's joint solve and the direct
  // solver read the matrix on the host.
  if (m_hessOnDevice && m_device && !m_inert && !faces && !ctx.bodyContacts.start && !m_cholesky) {
    DeviceAssembly a;
    a.pattern = &m_A;
    a.gather = &m_gather;
    a.diagonalBlock = m_diagonalBlock.data();
    a.scale = dt2;
    if (writeDamping) a.sum = m_dampK.values.data();
    if (m_dampKValid) a.addScale = dt * r2;
    if (m_dampKValid && !writeDamping && !m_dampKOnDevice) a.addSum = m_dampK.values.data();
    a.nodes = nodes;
    // Per node and iteration the largest copy; zero with no collider (body contact is not here).
    if (ctx.colliderCount == 0) a.nodes.contactHess = nullptr;
    a.fixedNode = state.fixedNode.data();
    if (m_device->assemble(a)) {
      m_matrixOnDevice = m_hostMatrixStale = true;
      m_dampKOnDevice = m_dampKOnDevice || writeDamping || a.addSum != nullptr;
      return writeDamping;
    }
    dropDevice();
  }
  if (m_hessOnDevice && !(m_device && m_device->downloadHessians(m_elemHess.data()))) {
    // Lost with the device: the pass again on the host, at the linearisation point.
    if (m_device) dropDevice();
    (void)elementPass(model, state, m_x.data(), true, true, jobs);
  }
  m_hessOnDevice = false;
  // One pass over the element matrices writes A and, where this step's damping needs it,
  // K(x_n); the damping term's axpy joins the last gather into A. Each would stream the
  // matrix again; the bits are those of the separate passes.
  GatherFusion elements, faceContacts;
  elements.accumulate = false;
  if (writeDamping) elements.sum = &m_dampK;
  if (m_dampKValid) {
    GatherFusion& last = faces ? faceContacts : elements;
    last.addAfter = &m_dampK;
    last.addScale = dt * r2;
  }
  if (m_inert)
    m_A.setZero(jobs);
  else
    gatherElementBlocks(m_gather, m_elemHess.data(), dt2, m_A, jobs, elements);
  if (faces) gatherElementBlocks(m_faceGather, m_faceHess.data(), dt2, m_A, jobs, faceContacts);
  NodeBlockStage hostNodes = nodes;
  hostNodes.values = m_A.values.data();
  CpuExecutor(jobs).run(model.nodeCount, kNodeGrain, hostNodes);
  applyDirichlet(m_A, state.fixedNode.data(), jobs);
  return writeDamping;
}

bool Integrator::hostMatrix() {
  if (!m_hostMatrixStale) return true;
  if (!m_device || !m_device->downloadMatrix(m_A.values.data())) return false;
  m_hostMatrixStale = false;
  return true;
}

void Integrator::relineariseOnHost(const FemModel& model, const FemState& state,
                                   const StepContext& ctx, int it, JobSystem& jobs) {
  if (m_device) dropDevice();
  (void)elementPass(model, state, m_x.data(), true, true, jobs);
  (void)assemble(model, state, ctx, it, jobs);
}

double Integrator::linearise(const FemModel& model, const FemState& state, const StepContext& ctx,
                             int it, bool judgeFracture, JobSystem& jobs, BodyStepReport& rep,
                             double& toleranceScale) {
  const int32_t n3i = int32_t(state.x.size());
  const CpuExecutor exec(jobs);
  const double* start = m_xStart.data();  // x_n
  auto t0 = Clock::now();
  if (it == 0) m_dampKValid = false;
  // Fracture is judged on the first pass's stresses when that pass sees x_n (no grip has
  // moved the start point); if edges broke, the damaged elements change and the pass is
  // repeated once.
  const bool fusedFracture = it == 0 && judgeFracture && m_fracture && !state.movingGrips;
  if (fusedFracture) m_stressOut = m_fracture->stressBuffer();
  double E = incrementalPotential(model, state, start, m_x.data(), ctx, true, true, jobs);
  m_stressOut = nullptr;
  rep.elementsMs += msSince(t0);
  if (fusedFracture) {
    t0 = Clock::now();
    // A device pass kept its stresses there, where the criterion then runs.
    CriterionOnDevice onDevice(*this, model, state, m_x.data());
    const int32_t broke =
        m_fracture->detect(model, state, m_x.data(), jobs, true, m_svdCache.data(),
                           m_device && !m_inert ? &onDevice : nullptr);
    rep.fractureMs += msSince(t0);
    if (broke > 0) {
      t0 = Clock::now();
      E = incrementalPotential(model, state, start, m_x.data(), ctx, true, true, jobs);
      rep.elementsMs += msSince(t0);
    }
  }

  // A = M (1 + dt r1) + dt r2 K(x_n) + dt^2 (K + K_contact)
  t0 = Clock::now();
  if (assemble(model, state, ctx, it, jobs))
    E += dampingTerm(state, m_dampRef.data(), m_x.data(), ctx.dt, true, jobs);
  exec.run(n3i, kNodeGrain,
           FreeDifferenceStage{nullptr, m_grad.data(), state.fixedNode.data(), m_rhs.data()});
  rep.assemblyMs += msSince(t0);

  t0 = Clock::now();
  // Iterative solvers start the first Newton step from the constant-velocity guess dt v_n
  // (the prescribed nodes have already moved): a fixed number of V-cycles then solves for the
  // change of motion rather than the whole motion, which keeps the stresses, and so the
  // cracks, of the direct solver (tests/physics/test_multigrid_fracture.cpp).
  if (it == 0 && !m_cholesky)
    exec.run(n3i, kNodeGrain,
             FreeDifferenceStage{m_y.data(), m_x.data(), state.fixedNode.data(), m_dx.data()});
  else
    exec.run(n3i, kNodeGrain, FillStage{0.0, m_dx.data()});
  // The iterative solvers stop at a residual relative to the right-hand side. Started on the
  // turned body, that is only the deformation's share, far below what the same motion gives
  // the plain step (its rhs holds the spin's momentum), and the same relative tolerance would
  // buy a solve many times more accurate. So the first Newton step measures its residual
  // against the larger of the two.
  toleranceScale = 1;
  if (it == 0 && !m_cholesky && m_rigidPieces) {
    const double spin2 = exec.reduce<SumOp>(
        model.nodeCount, SpinShareTerm{m_xStart.data(), state.nodeMass.data(), m_pieces.data(),
                                       m_pieceOfNode.data(), ctx.dt});
    const double rhs2 = exec.dot(m_rhs.data(), m_rhs.data(), n3i);
    if (spin2 > rhs2 && rhs2 > 0) toleranceScale = std::sqrt(spin2 / rhs2);
  }
  // Cracks change the binding only when edges broke since the last solve (SPEC §5).
  if (m_multigrid && !m_inert && !m_cholesky && m_fracture &&
      m_fracture->brokenCount() != m_boundBrokenCount) {
    const EdgeGraph& g = m_fracture->graph();
    m_multigrid->rebind(g.edgeNodes.data(), m_fracture->broken().data(), g.edgeCount, jobs);
    m_boundBrokenCount = m_fracture->brokenCount();
  }
  rep.solveMs += msSince(t0);
  return E;
}

double Integrator::solve(const FemModel& model, FemState& state, const StepContext& ctx,
                         double fullDt, bool judgeFracture, JobSystem& jobs, BodyStepReport& rep) {
  const double dt2 = ctx.dt * ctx.dt;
  const int maxNewton = model.solver.newtonIterations < 1 ? 1 : model.solver.newtonIterations;
  const size_t n3 = state.x.size();
  const CpuExecutor exec(jobs);
  const int32_t n3i = int32_t(n3);
  startNewton(model, state, ctx, fullDt, jobs);

  const double* start = m_xStart.data();  // x_n
  const bool fullNewton = maxNewton > 1;
  // A moving collider that swept over x_n makes its first linearisation a poor model of the
  // contacts where the step ends (SweepStage::classify): such a step goes on to convergence
  // too, without being reported as swept.
  bool swept = !fullNewton && ((rep.flags & kStepContactSwept) || m_over);
  // Friction against another body: the drag of a node that sticks is far stiffer than its
  // inertia and a sliding one's force is constant, so one linearisation at the start can land
  // far from the step's friction (a block resting on a slab, mu 0.1, was thrown up at 4 m/s, and
  // at 861 m/s with the slab on a frictional floor). Such a step is checked against its
  // quadratic model as a cracked one is, and goes on to convergence where the two disagree
  // (going on whenever such friction acts left a resting stack more restless).
  const bool bodyFrictionActs = !fullNewton && m_bodyFriction;
  int iterationCap =
      fullNewton ? maxNewton : 1 + (swept ? kMaxSweptIterations : kMaxContactIterations);
  int stiffeningsLeft = kMaxContactStiffenings;
  // Projection damage: a crack that the linearisation saw open can close within the step, and
  // the step built on the open crack's softness then overshoots into the closed crack's
  // stiffness (on steel at dt 50 ms no trial down to kMinLineSearchStep lowered E, and taking
  // that trial gained up to 0.5 E0 per run). Such an iteration is repeated once from the same
  // point with the closed-crack Hessian, a majorant of psi's curvature. So is one whose line
  // search had to shorten the step at all: the open-crack Newton step was seen thousands of
  // metres long, and a fraction of it that Armijo accepts (its slope is steep) still threw a
  // torn steel bar's fragments at up to 5e8 J, decided by the last bits of the start (issue
  // 19, tests/physics/test_fracture.cpp, docs/validation.md).
  bool closedRetryLeft = true;
  int modelIterationsLeft = kMaxModelIterations;
  m_closedCrackHessian = false;
  bool retry = false;
  double firstStepNorm = 0;
  bool newReference = false;
  bool converged = !fullNewton;
  // Whether the elastic energy at the final positions is known (the accepted line-search
  // trial), or the final step was too small to matter (below the potential's round-off).
  bool finalPsiKnown = false, finalStepNegligible = false;
  for (int it = 0; it < iterationCap; ++it) {
    double toleranceScale = 1;
    double E = linearise(model, state, ctx, it, judgeFracture, jobs, rep, toleranceScale);
    auto t0 = Clock::now();
    const double tolerance = model.solver.linearTolerance * toleranceScale;
    auto relinearise = [&] { relineariseOnHost(model, state, ctx, it, jobs); };
    const SolveReport sr = selfPairsAct(model, ctx, dt2, jobs)
                               ? coupledSolve(model, state, ctx, tolerance, toleranceScale, jobs)
                               : patternSolve(model, m_rhs.data(), m_dx.data(), tolerance,
                                              toleranceScale, jobs, relinearise);
    rep.solveMs += msSince(t0);
    rep.linearIterations += sr.iterations;
    rep.residual = std::max(rep.residual, sr.relativeResidual);
    if (!sr.converged) rep.flags |= kStepNotConverged;
    ++rep.newtonIterations;

    const double stepNorm = std::sqrt(exec.dot(m_dx.data(), m_dx.data(), n3i));
    const double slope = exec.dot(m_grad.data(), m_dx.data(), n3i);
    if (it == 0 || std::exchange(newReference, false)) firstStepNorm = stepNorm;

    double alpha = 1.0;
    bool modelOvershot = false;
    // A predicted decrease below E's resolution cannot be judged by evaluating E: trust the
    // Newton step then (it is at round-off level anyway).
    const bool search = model.solver.lineSearch && slope < 0 && -slope > m_energyRoundOff;
    finalPsiKnown = search;
    finalStepNegligible = model.solver.lineSearch && !search && slope < 0;
    if (search) {
      // Backtracking (Armijo) on the incremental potential: the step never raises it.
      t0 = Clock::now();
      bool searchFailed = false;
      double Et = E;
      for (;;) {
        exec.run(n3i, kNodeGrain, AxpyStage{m_x.data(), m_dx.data(), alpha, m_tmp.data()});
        Et = incrementalPotential(model, state, start, m_tmp.data(), ctx, false, false, jobs);
        // Near convergence E changes below its round-off; accept a step that does not
        // raise E beyond that.
        if (std::isfinite(Et) && (Et <= E + kArmijo * alpha * slope || Et <= E + m_energyRoundOff))
          break;
        if (alpha <= kMinLineSearchStep) {
          searchFailed = true;
          break;
        }
        alpha *= 0.5;
      }
      rep.elementsMs += msSince(t0);
      const bool cracked = m_fracture && m_fracture->damageModel() == kDamageProjection &&
                           m_fracture->brokenCount() > 0;
      if ((searchFailed || alpha < 1) && cracked && closedRetryLeft) {
        // The retry of the comment above, from where this iteration started.
        alpha = 0;
        finalPsiKnown = false;
        closedRetryLeft = false;
        retry = true;
        m_closedCrackHessian = true;
        ++iterationCap;
      } else if (searchFailed) {
        rep.flags |= kStepLineSearchFailed;
      } else if ((cracked || bodyFrictionActs) && !fullNewton && !swept &&
                 modelIterationsLeft > 0) {
        // The step the search accepted whole (or the retry's) can still have closed a crack:
        // Armijo only asks for a decrease, and the inertia term makes that easy, but backward
        // Euler dissipates energy only at its minimum. A crack that closes within the step
        // stores energy its open-crack model did not count, so the decrease falls short of
        // the model's q(alpha) = -(alpha g.dx + alpha^2/2 dx.A dx); the step then goes on from
        // the accepted point, whose Hessian sees the closed crack. (Taken alone, a beam cracked
        // at its root gained up to 3.9 J in one such step: tests/stability, ProjectionBeams.)
        if (m_hostMatrixStale && !(m_device && m_device->multiply(m_dx.data(), m_adx.data())))
          relinearise();  // the device's matrix is lost with it
        if (!m_hostMatrixStale) m_A.multiply(m_dx.data(), m_adx.data(), jobs);
        const double curvature = exec.dot(m_dx.data(), m_adx.data(), n3i);
        const double predicted = -(alpha * slope + 0.5 * alpha * alpha * curvature);
        modelOvershot = E - Et < kModelAgreement * predicted;
        if (modelOvershot && !cracked) {
          // Friction against another body: from here on to convergence (a few iterations
          // more, as for a crack, left the ridge of a block tipping off another 7.4 % of a
          // cell inside it, EdgeOnEdgeMidwayBetweenNodes at 120 Hz).
          swept = true;
          iterationCap = it + 1 + kMaxSweptIterations;
          newReference = true;
          modelOvershot = false;
        } else if (modelOvershot) {
          --modelIterationsLeft;
          ++iterationCap;
        }
      }
    }
    m_shortStep = alpha < 1;
    if (ctx.colliderCount > 0 || ctx.bodyContacts.start) m_xLin = m_x;
    exec.run(n3i, kNodeGrain, AxpyStage{m_x.data(), m_dx.data(), alpha, m_x.data()});
    if (std::exchange(retry, false)) continue;
    const double relStep = firstStepNorm > 0 ? alpha * stepNorm / firstStepNorm : 0.0;
    // A pushed contact that holds a node deeper than its bound is stiffened, and the step goes
    // on as a swept one (to convergence) from where it is.
    if (stiffeningsLeft > 0 && stiffenDeepContacts(model, state, ctx, jobs)) {
      --stiffeningsLeft;
      if (!fullNewton && !swept) {
        swept = true;
        iterationCap = it + 1 + kMaxSweptIterations;
      } else {
        iterationCap = std::max(iterationCap, it + 2);
      }
      newReference = true;  // the stiffer penalty's first step is the reference
      converged = false;
      continue;
    }
    if (fullNewton || swept) {
      if (relStep <= (fullNewton ? model.solver.newtonTolerance : kSweptTolerance) ||
          alpha * stepNorm <= kNewtonRoundOff * model.lengthScale * std::sqrt(double(n3))) {
        converged = true;
        m_shortStep = false;
        break;
      }
    } else if (releasedBodyContact(model, state, ctx, jobs)) {
      // From here on to convergence: where the released half-spaces no longer act.
      swept = true;
      iterationCap =
          it + 1 + (ctx.bodyContacts.reactionStart ? kMaxSelfIterations : kMaxSweptIterations);
      newReference = true;
      converged = false;
    } else if (!modelOvershot && !enteredUnseenContact(model, state, ctx, jobs)) {
      break;
    }
  }
  if (!converged) rep.flags |= kStepNotConverged;
  double psi = 0;
  if (!finalStepNegligible)
    psi = finalPsiKnown ? m_lastPsi : elementPass(model, state, m_x.data(), false, false, jobs);
  return psi;
}

void Integrator::sweepColliders(const FemModel& model, const FemState& state,
                                const StepContext& ctx, JobSystem& jobs, BodyStepReport& rep) {
  m_swept = {};
  // Planes are half-spaces: nothing to pass through; but a moving one may need stiffening.
  bool thin = false;
  m_movingCollider = false;
  m_over = false;
  for (int c = 0; c < ctx.colliderCount; ++c) {
    thin |= ctx.colliders[c].kind != kColliderPlane;
    m_movingCollider |= dot(ctx.colliders[c].velocity, ctx.colliders[c].velocity) > 0;
  }
  if (!thin && !m_movingCollider) return;
  const size_t nn = size_t(model.nodeCount);
  m_sweptCollider.resize(nn);
  m_sweptPoint.resize(nn);
  m_sweptNormal.resize(nn);
  m_sweptCrossed.resize(nn);
  m_sweptStiffness.resize(nn);
  m_sweptBound.resize(nn);
  m_sweptScale.resize(nn);
  m_sweptPressed.resize(nn);
  m_sweptOver.resize(nn);
  SweepStage sweep;
  sweep.x = state.x.data();
  sweep.v = state.v.data();
  sweep.fixedNode = state.fixedNode.data();
  sweep.dt = ctx.dt;
  sweep.colliders = ctx.colliders;
  sweep.colliderCount = ctx.colliderCount;
  sweep.collider = m_sweptCollider.data();
  sweep.point = m_sweptPoint.data();
  sweep.normal = m_sweptNormal.data();
  sweep.stiffness = m_sweptStiffness.data();
  sweep.crossed = m_sweptCrossed.data();
  sweep.cell = m_cellSize;
  sweep.bound = m_sweptBound.data();
  sweep.scale = m_sweptScale.data();
  sweep.pressed = m_sweptPressed.data();
  sweep.over = m_sweptOver.data();
  const CpuExecutor exec(jobs);
  if (m_movingCollider) {
    // Free nodes' mean velocity: whether a moving collider closes in on the body.
    NodeMomentumTerm p{state.v.data(), state.nodeMass.data(), state.fixedNode.data(), -1};
    const double mass = exec.reduce<SumOp>(model.nodeCount, p);
    for (int k = 0; k < 3 && mass > 0; ++k) {
      p.axis = k;
      sweep.body[k] = exec.reduce<SumOp>(model.nodeCount, p) / mass;
    }
  }
  exec.run(model.nodeCount, kNodeGrain, sweep);
  m_swept = {m_sweptCollider.data(), m_sweptPoint.data(), m_sweptNormal.data(),
             m_sweptStiffness.data(), m_movingCollider ? m_sweptScale.data() : nullptr};
  if (exec.max(m_sweptCrossed.data(), model.nodeCount) > 0) rep.flags |= kStepContactSwept;
  m_over = exec.max(m_sweptOver.data(), model.nodeCount) > 0;
}

bool Integrator::stiffenDeepContacts(const FemModel& model, const FemState& state,
                                     const StepContext& ctx, JobSystem& jobs) {
  // Only against moving colliders: nothing spent, and nothing changed, on static worlds.
  if (!m_swept.collider || !m_movingCollider) return false;
  DeepContactTerm deep;
  deep.x = m_x.data();
  deep.fixedNode = state.fixedNode.data();
  deep.colliders = ctx.colliders;
  deep.swept = m_swept;
  deep.bound = m_sweptBound.data();
  deep.stiffness = m_sweptStiffness.data();
  deep.scale = m_sweptScale.data();
  deep.pressed = m_sweptPressed.data();
  deep.xn = m_xStart.data();
  deep.contactSeen = m_contactSeen.data();
  deep.dt = ctx.dt;
  deep.colliderCount = ctx.colliderCount;
  deep.cell = m_cellSize;
  deep.maxStiffness = kMaxContactStiffnessDt2 / (ctx.dt * ctx.dt);
  return CpuExecutor(jobs).reduce<MaxOp>(model.nodeCount, deep) > 0;
}

bool Integrator::nearCollider(const FemModel& model, const FemState& state, const double* x,
                              const double* v, double dt, const StepContext& ctx,
                              JobSystem& jobs) const {
  const CpuExecutor exec(jobs);
  if (v && m_swept.collider &&
      exec.reduce<MaxOp>(model.nodeCount, SweptAnyTerm{m_sweptCollider.data()}) > 0)
    return true;
  const InsideColliderTerm inside{
      x, v, dt, state.fixedNode.data(), ctx.colliders, ctx.colliderCount};
  return exec.reduce<MaxOp>(model.nodeCount, inside) > 0;
}

void Integrator::beginStep(const FemModel& model, FemState& state, const StepContext& ctx,
                           JobSystem& jobs, BodyStepReport& rep) {
  m_deviceStale = true;
  m_xStart = state.x;
  m_vStart = state.v;
  sweepColliders(model, state, ctx, jobs, rep);
  prepareFaces(model, ctx, (rep.flags & kStepContactSwept) != 0);
  sweepFaces(model, state, ctx, jobs, rep);
}

void Integrator::faceImpulses(const FemModel& model, const StepContext& inner, JobSystem& jobs) {
  const CpuExecutor exec(jobs);
  if (m_faceOn && m_faceAny) {
    // The face contacts' impulses, per node for the pieces' momentum (ExternalImpulse) and
    // per face for the colliders' (ColliderImpulseStage).
    exec.run(m_faceCount, kElementGrain,
             FaceImpulseStage{m_x.data(), m_xLin.data(), m_xStart.data(), inner.colliders,
                              faceContacts(), inner.dt, m_faceGrad.data(), m_faceTotal.data()});
    exec.run(model.nodeCount, kNodeGrain,
             GatherStage{m_faceRefStart.data(), m_faceRef.data(), m_faceGrad.data(),
                         m_faceNodeGrad.data()});
  }
}

void Integrator::endOfStep(const FemModel& model, FemState& state, const StepContext& ctx,
                           const StepContext& inner, JobSystem& jobs) {
  const CpuExecutor exec(jobs);
  const size_t n3 = state.x.size();
  exec.run(int32_t(n3), kNodeGrain,
           EndOfStepStage{m_x.data(), m_xStart.data(), state.gripVelocity.data(),
                          state.fixedNode.data(), inner.dt, state.x.data(), state.v.data()});
  // The end spin is the moment of the contact impulses as the last Newton step linearised
  // them. Against another body's lagged planes, a step the line search shortened did not
  // move the body as that model says (the planes can lie centimetres deep), and their
  // moment spun a block resting on a damped slab at 16 rad/s, then threw it at 18 m/s
  // (BodyContact.BlockRestsOnASlabBody): such a step keeps backward Euler's velocities.
  if (!(m_shortStep && ctx.bodyContacts.start)) rigidEndVelocities(model, state, inner, jobs);
}

void Integrator::finishStep(const FemModel& model, FemState& state, const StepContext& ctx,
                            double theta, double dt, double psi, JobSystem& jobs,
                            BodyStepReport& rep) {
  const CpuExecutor exec(jobs);
  const size_t n3 = state.x.size();
  m_theta = theta;
  const double blowUp = kBlowUpEnergyDensity *
                        std::max(state.material.youngsModulus, state.material.fibreStiffness) *
                        m_restVolume;
  // The divergence check reads the solved point's energy; the extrapolated state is checked for
  // finite values. A rolled-back step leaves z at the start too (prescribedNodeForces).
  if (exec.reduce<MaxOp>(int32_t(n3), NonFiniteTerm{state.x.data()}) > 0 ||
      exec.reduce<MaxOp>(int32_t(n3), NonFiniteTerm{state.v.data()}) > 0 || !std::isfinite(psi)) {
    state.x = m_xStart;
    state.v = m_vStart;
    m_x = m_xStart;
    rep.flags |= kStepNanContained;
    rep.message = "produced a non-finite state and was restored to the start of the step";
  } else if (psi > blowUp) {
    state.x = m_xStart;
    state.v = m_vStart;
    m_x = m_xStart;
    rep.flags |= kStepNanContained;
    char text[160];
    std::snprintf(text, sizeof text,
                  "diverged (elastic energy %.3g J, over 1e6 x E x V = %.3g J) and was restored to "
                  "the start of the step; use a smaller dt or substeps",
                  psi, blowUp);
    rep.message = text;
  } else if (ctx.colliderImpulse && ctx.colliderCount > 0) {
    // The last Newton step solved the linearisation at m_xLin, so the contact force that
    // entered the momentum balance is the linearised one, g + H (x - x_lin) (equal to the
    // force at x when the contact set and normals did not change). Below theta = 1 that force
    // acts over the whole step.
    const int32_t nn = model.nodeCount;
    m_impulses.resize(6 * size_t(ctx.colliderCount) * size_t(nn));
    exec.run(nn, kNodeGrain,
             ColliderImpulseStage{m_x.data(), m_xLin.data(), state.fixedNode.data(),
                                  state.nodeMass.data(), ctx.colliders, ctx.colliderCount, m_swept,
                                  -dt / theta, nn, m_impulses.data()});
    for (int k = 0; k < 6 * ctx.colliderCount; ++k)
      ctx.colliderImpulse[k] += exec.sum(m_impulses.data() + size_t(k) * size_t(nn), nn);
    if (m_faceOn && m_faceAny)
      for (int k = 0; k < 6 * ctx.colliderCount; ++k)
        ctx.colliderImpulse[k] +=
            exec.reduce<SumOp>(
                m_faceCount,
                FaceColliderImpulseTerm{m_faceCollider.data(), m_faceTotal.data(), k / 6, k % 6}) /
            theta;
    if (m_friction.muLambda) {
      exec.run(nn, kNodeGrain,
               FrictionImpulseStage{m_x.data(), m_xLin.data(), ctx.colliders, ctx.colliderCount,
                                    m_friction, dt, 1.0 / theta, nn, m_impulses.data()});
      for (int k = 0; k < 6 * ctx.colliderCount; ++k)
        ctx.colliderImpulse[k] += exec.sum(m_impulses.data() + size_t(k) * size_t(nn), nn);
    }
  }
}

void Integrator::judgeMovingGripFracture(const FemModel& model, const FemState& state,
                                         const StepContext& ctx, JobSystem& jobs,
                                         BodyStepReport& rep) {
  // Moving grips shift the start point away from x_n, so fracture is judged on x_n first. After
  // a backward-Euler step that was not rolled back, x_n is where that step's last element pass
  // looked, so its tets take their SVDs from the cache; anywhere else they miss and are computed.
  // On a device the criterion runs there, where the step's element passes ran.
  if (m_fracture && state.movingGrips && ctx.judgeFracture) {
    const auto tf = Clock::now();
    CriterionOnDevice onDevice(*this, model, state, state.x.data());
    m_fracture->detect(model, state, state.x.data(), jobs, /*stressesReady=*/false,
                       m_svdCache.data(), m_device ? &onDevice : nullptr);
    rep.fractureMs += msSince(tf);
  }
}

BodyStepReport Integrator::step(const FemModel& model, FemState& state, const StepContext& ctx,
                                JobSystem& jobs) {
  BodyStepReport rep;
  beginStep(model, state, ctx, jobs, rep);
  // theta = 1: backward Euler. Below it the solve covers theta dt (the one-leg theta method)
  // and thetaEndState extrapolates to dt. Penalty contact is one-sided: extrapolating a step
  // in which a node met a collider can put it deep inside, and the penalty energy stored there
  // comes back as an explosion (the 100 m/s impact of test_stiff.cpp blew up), so a body that
  // touches a collider, or would within the step, is stepped with backward Euler.
  double theta = 0.5 + 0.5 * model.solver.numericalDamping;
  // As for a node at a collider: the penalty is not extrapolated.
  if (theta < 1 && m_faceOn && findFaceContacts(model, state, state.x.data(), ctx, jobs)) theta = 1;
  // A pull's tether is a stiff spring whose weight is set for backward Euler over the whole
  // step; extrapolating it would overshoot the target as extrapolating penalty contact does.
  if (!state.tether.empty()) theta = 1;
  if (theta < 1 && ctx.colliderCount > 0 &&
      nearCollider(model, state, state.x.data(), state.v.data(), ctx.dt, ctx, jobs))
    theta = 1;
  // Body contact likewise, and its momentum exchange reads the backward-Euler impulses.
  if (ctx.bodyContacts.start) theta = 1;

  judgeMovingGripFracture(model, state, ctx, jobs, rep);
  StepContext inner = ctx;
  double psi = 0;
  for (bool judgeFracture = ctx.judgeFracture;; judgeFracture = false) {
    inner.dt = theta * ctx.dt;
    const uint32_t flagsBefore = rep.flags;
    psi = solve(model, state, inner, ctx.dt, judgeFracture, jobs, rep);
    faceImpulses(model, inner, jobs);
    if (theta == 1) {
      endOfStep(model, state, ctx, inner, jobs);
      break;
    }
    thetaEndState(model, state, inner, ctx.dt, theta, jobs);
    if (ctx.colliderCount == 0 ||
        !nearCollider(model, state, state.x.data(), nullptr, 0, ctx, jobs))
      break;
    // The extrapolation reached into a collider: the step again, as backward Euler from the
    // same start (fracture was judged there already).
    state.x = m_xStart;
    state.v = m_vStart;
    rep.flags = flagsBefore;
    theta = 1;
  }
  finishStep(model, state, ctx, theta, inner.dt, psi, jobs, rep);
  return rep;
}

}  // namespace gf::detail
