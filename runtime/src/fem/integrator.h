// Implicit backward Euler for one body (eq 2.7, 3.13), written as Newton's method on the
// incremental potential
//   E(x) = 1/2 (x-y)^T M (x-y) + dt/2 (x-x_n)^T D (x-x_n) + dt^2 (Psi(x) + Psi_c(x) - f^T x),
//   y = x_n + dt v_n,  D = r1 M + r2 K(x_n)  (Rayleigh, lagged at the start of the step).
// Started at x_n, the first Newton step is exactly the linearly implicit step
//   (M + dt D + dt^2 K) dv = dt (f_ext + f_int - D v - dt K v)   (Baraff & Witkin),
// which is the default (one Newton step, plus at most two more in a step where a node hits a
// collider the linearisation did not see: otherwise that penetration would be stored as
// penalty energy and released as a bounce). More iterations converge to the fully implicit
// solution, the reference for error measurements. A backtracking line search on E keeps every
// iteration from raising the incremental potential, which bounds the energy in stiff cases.
// Free pieces (no gripped node) are stepped in the frame that turns with them: y carries their
// rigid motion exactly plus the frame's centrifugal and Coriolis accelerations, Newton starts
// from x_n turned, and the end velocity keeps their angular momentum (docs/design.md).
// SolverSettings::numericalDamping < 1 makes the step the theta method in its one-leg form:
// the step above over theta dt, extrapolated to dt (free pieces: their deformation only, with
// Coriolis split off), except for a body at a collider, which backward Euler keeps calm.
// Nodes with a prescribed velocity are placed first and then held (zero rows/columns).
// The sparse pattern, the gather plan and all work arrays are built once per body.
#pragma once

#include <functional>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "fem/body_device.h"
#include "fem/element_stage.h"
#include "fem/face_stage.h"
#include "fem/fem_body.h"
#include "fem/node_stage.h"
#include "fem/rigid_stage.h"
#include "fracture/fracture_body.h"
#include "graphfrac/jobs.h"
#include "graphfrac/status.h"
#include "kernels/contact.h"
#include "solver/block_sparse.h"
#include "solver/cholesky.h"
#include "solver/multigrid.h"
#include "solver/pcg.h"
#include "step/segments.h"

namespace gf::detail {

class CpuExecutor;
class ContactSurface;

/// What the world passes to a body step.
struct StepContext {
  double dt = 0;
  Vec3 gravity;
  const ColliderData* colliders = nullptr;
  int colliderCount = 0;
  /// Null, or 6 per collider that the step adds to: the impulse its penalty gave the free
  /// nodes (dt times the contact force of the last Newton step's linearisation at the accepted
  /// positions), then that impulse's moment about the collider's point.
  double* colliderImpulse = nullptr;
  /// This body's half-spaces of body-body and self contact (World: contact/body_contact.h).
  HalfSpaceContacts bodyContacts;
  /// False in a contact sweep after the substep's first (World::Impl::contactSweeps): the
  /// first judged the fracture at this start already, and the damage stays as it left it.
  bool judgeFracture = true;
};

/// What a body step reports.
struct BodyStepReport {
  uint32_t flags = 0;  // gf::StepFlag bits
  int newtonIterations = 0;
  int linearIterations = 0;
  double residual = 0;
  double elementsMs = 0, assemblyMs = 0, solveMs = 0, fractureMs = 0;
  std::string message;  // why the state was rolled back (kStepNanContained), else empty
};

/// Integrator::bodyContactImpulses' account of a body's momentum.
struct BodyContactBalance {
  Vec3 unexplained;       ///< momentum change beyond the half-spaces' and the external impulses
  bool external = false;  ///< a grip or a collider also acted (unexplained is then zero)
};

/// Energies of a configuration (for diagnostics).
struct EnergyBreakdown {
  double elastic = 0, contact = 0;
};

class Integrator;

/// One body of a coupled contact cluster (Integrator::coupledStep).
struct CoupledBody {
  const FemModel* model = nullptr;
  FemState* state = nullptr;
  Integrator* integrator = nullptr;
  StepContext ctx;  ///< the body's own: its half-spaces (joint), its collider impulse sums
  BodyStepReport* report = nullptr;
  int32_t jointBase = 0;  ///< its first node in the joint numbering
};

/// The coupled half-spaces (BodyContact::jointView) and one cluster's runs of them.
struct CoupledCluster {
  HalfSpaceContacts contacts;
  double* X = nullptr;                     ///< joint positions the contacts read (3 per joint node)
  double* Xn = nullptr;                    ///< x_n, the same way
  int32_t jointNodes = 0, jointPairs = 0;  ///< of all clusters
  int32_t nodeBegin = 0, nodeEnd = 0, pairBegin = 0, pairEnd = 0;
};

/// The Newton system of bodies joined by moving pairs (Integrator::solvePairCoupled): the pairs
/// and their linearisation (SelfPairActiveStage's arrays), and the runs of nodes and pairs it
/// covers, all indexed as the pairs' node indices are.
struct PairCoupledSystem {
  HalfSpaceContacts contacts;
  const uint8_t* fixed = nullptr;  ///< per node
  const double* active = nullptr;
  const Vec3* normal = nullptr;
  const Vec3* weight = nullptr;
  const double* friction = nullptr;
  double* projection = nullptr;  ///< scratch, per pair
  Vec3* slide = nullptr;
  int32_t nodeBegin = 0, nodes = 0, pairBegin = 0, pairs = 0;
};
/// One body of it: its matrix and solver, its first unknown in the joint vectors.
struct PairCoupledPart {
  Integrator* integrator = nullptr;
  const FemModel* model = nullptr;
  int64_t offset = 0;
};

/// Scratch of Integrator::coupledStep, kept between steps.
struct CoupledWork {
  std::vector<double> vectors;
  std::vector<uint8_t> fixed;
  std::vector<double> active, friction, projection;
  std::vector<Vec3> normal, weight, slide;
};

class Integrator {
 public:
  /// One step of a cluster of bodies that coupled contact joins (WorldDef::coupledContact):
  /// Newton on the sum of their incremental potentials, the pairs between them acting on both
  /// sides (fem/coupled_step.cpp). In place of step() for each body; each report as step()'s.
  static void coupledStep(std::span<CoupledBody> bodies, const CoupledCluster& cluster,
                          CoupledWork& work, JobSystem& jobs);
  explicit Integrator(const FemModel& model);
  ~Integrator();
  /// Builds what the chosen linear solver needs beyond the pattern (the multigrid hierarchy);
  /// an error names the setting that cannot be built. Call once, before the first step.
  Result<void> setupSolver(const FemModel& model, const FemState& state);
  /// After state.fixedNode changed (World::detachFragment): the multigrid binds no handle to
  /// fixed nodes, so its hierarchy is built again and re-bound to the current cracks at the
  /// next solve. If it cannot be built (e.g. no free node is left) PCG solves the body.
  void refreshFixedNodes(const FemModel& model, const FemState& state);
  /// Runs the element pass, the Newton matrix's assembly and the PCG and multigrid solves on
  /// `device` (the CUDA backend); the rest of the step, and the direct solver, stay on the host
  /// (with face or body contact, or the direct solver, the host assembles too). A device call
  /// that fails hands the body back to the CPU for good (takeDeviceFailure()).
  void useDevice(std::unique_ptr<BodyDevice> device) { m_device = std::move(device); }
  /// Why the device was dropped since the last call (empty: it was not); clears it.
  std::string takeDeviceFailure() { return std::exchange(m_deviceFailure, {}); }
  /// The multigrid solver, or null when the body uses another linear solver.
  const MultigridSolver* multigrid() const { return m_multigrid.get(); }
  /// Damage state the element pass reads (null: no fracture); it outlives the integrator's use.
  void attach(FractureBody* fracture) {
    m_fracture = fracture;
    m_piecesKey = kNoPieces;
  }
  /// Advances `state` by ctx.dt. With fracture attached (and ctx.judgeFracture), the first
  /// element pass also yields the stresses of the fracture criterion, which runs before the
  /// solve (FractureBody::detect).
  /// On a NaN/Inf the state is restored and flagged.
  BodyStepReport step(const FemModel& model, FemState& state, const StepContext& ctx,
                      JobSystem& jobs);
  /// The multigrid's state between solves (re-bindings, refresh schedule, the coarse values
  /// the next solve keeps); empty without a multigrid.
  detail::MultigridState solverState() const;
  /// Puts the solver into `solver`, a solverState() of this body (World::restore): a fresh
  /// set-up unless the current one applied a prefix of its re-bindings, the rest replayed on
  /// the broken sets of the attached fracture's break-order prefixes (its state must already
  /// be restored), then the schedule and coarse values.
  Result<void> restoreSolver(const FemModel& model, const FemState& state,
                             const detail::MultigridState& solver);
  /// The element stage of this body at x writing into the given buffers (hess and stress
  /// nullable), and the gather of its element gradients: what the step runs, for the device
  /// backend's copies and the backend tests.
  ElementStage elementStage(const FemModel& model, const FemState& state, const double* x,
                            double* energy, double* grad, double* hess, double* stress) const;
  GatherStage gatherStage(const double* elemGrad, double* nodeGrad) const {
    return {m_nodeRefStart.data(), m_nodeRef.data(), elemGrad, nodeGrad};
  }
  /// Elastic and contact energy at positions x, the contact's at nodes and, on the faces of the
  /// last step's fragments, at points on faces. Touches no scratch buffer of the step.
  EnergyBreakdown energies(const FemModel& model, const FemState& state, const double* x,
                           const StepContext& ctx, JobSystem& jobs) const;
  /// The impulse [N s] each half-space of ctx.bodyContacts gave its node over the last step, as
  /// the last Newton step linearised it (what entered the momentum balance), 3 per half-space
  /// into `out`; zero for prescribed nodes and after a rolled-back step. Returns what the
  /// body's momentum change has beyond those and gravity, point forces and mass damping (the
  /// linear model's residual, where the line search shortened the step or the solve stopped
  /// early), or that the body also took momentum from a grip or a collider. Valid while
  /// `state` is the one the last step() produced with this ctx.
  BodyContactBalance bodyContactImpulses(const FemState& state, const StepContext& ctx,
                                         bool rolledBack, double* out, JobSystem& jobs);
  /// The force [N] each prescribed node (grip or detached fragment) needs to stay on its path
  /// at the end of the last step: the gradient of that step's incremental potential at
  /// state.x over dt^2 (zero for free nodes, whose gradient the step drove to zero), 3 per node
  /// into `out`. Valid while `state` is the one the last step() produced.
  void prescribedNodeForces(const FemModel& model, const FemState& state, const StepContext& ctx,
                            JobSystem& jobs, std::vector<double>& out);

 private:
  // Sets m_inert: no tet of the body can store elastic energy now (LiveTetTerm).
  void findInert(const FemModel& model, const FemState& state, JobSystem& jobs);
  // Per-element pass: the elastic energy and, when asked, its node gradient (m_elasticGrad,
  // gathered from the element gradients in a fixed order) and the PSD element Hessians (on the
  // device where it ran the pass: m_hessOnDevice). Reads and fills m_svdCache. An inert body
  // has nothing to evaluate: 0, stresses and gradient zero.
  double elementPass(const FemModel& model, const FemState& state, const double* x,
                     bool withGradient, bool withHessian, JobSystem& jobs);
  // Incremental potential at x (scaled by 1, see header comment); fills m_grad when asked.
  double incrementalPotential(const FemModel& model, const FemState& state, const double* xn,
                              const double* x, const StepContext& ctx, bool withGradient,
                              bool withHessian, JobSystem& jobs);
  // Free pieces (fragments without a prescribed node) are stepped in the frame that turns
  // with them: fills m_y (the inertia target) and moves their start in m_x; see the .cpp.
  // fullDt is the whole step when the solve covers only ctx.dt, theta of it.
  void predictRigidMotion(const FemModel& model, const FemState& state, const StepContext& ctx,
                          double fullDt, JobSystem& jobs);
  // Groups the nodes by the pieces of the step's start when the fragments changed (stages:
  // fem/piece_merge.h, step/segments.h).
  void groupPieces(const FemModel& model, const CpuExecutor& exec);
  // m_pieceSums = the first `components` arrays of m_pieceTerms summed per piece.
  void sumPerPiece(const FemModel& model, const CpuExecutor& exec, int components);
  // The end-of-step velocities of free pieces in that frame.
  void rigidEndVelocities(const FemModel& model, FemState& state, const StepContext& ctx,
                          JobSystem& jobs);
  // What the outside gives a node over ctx.dt (ExternalImpulse) in this step.
  ExternalImpulse externalImpulse(const FemState& state, const StepContext& ctx) const;
  // The step's collider friction contacts at x_n (m_xStart) into m_friction.
  void buildFriction(const FemModel& model, const FemState& state, const StepContext& ctx,
                     JobSystem& jobs);
  // The Newton start of free pieces on frictional contacts (RigidPiece::slide).
  void frictionStart(const FemModel& model, const FemState& state, const StepContext& ctx,
                     const CpuExecutor& exec);
  // theta < 1: the end of the step extrapolated from the solved step of theta * dt (m_x).
  void thetaEndState(const FemModel& model, FemState& state, const StepContext& inner, double dt,
                     double theta, JobSystem& jobs);
  // The Newton solve of one backward-Euler step of ctx.dt (theta times the step, fullDt) into
  // m_x; fracture is judged in its first pass when asked. Returns the elastic energy at m_x.
  double solve(const FemModel& model, FemState& state, const StepContext& ctx, double fullDt,
               bool judgeFracture, JobSystem& jobs, BodyStepReport& rep);
  // With moving grips, fracture judged at x_n before the step (step()).
  void judgeMovingGripFracture(const FemModel& model, const FemState& state, const StepContext& ctx,
                               JobSystem& jobs, BodyStepReport& rep);
  // step()'s start: x_n and v_n kept, the swept colliders and the face contacts' set-up.
  void beginStep(const FemModel& model, FemState& state, const StepContext& ctx, JobSystem& jobs,
                 BodyStepReport& rep);
  // The face contacts' impulses of the solved step (inner: its part of the step).
  void faceImpulses(const FemModel& model, const StepContext& inner, JobSystem& jobs);
  // A backward-Euler step's end: x and v from m_x, the free pieces' end velocities.
  void endOfStep(const FemModel& model, FemState& state, const StepContext& ctx,
                 const StepContext& inner, JobSystem& jobs);
  // step()'s end: the divergence checks (a rolled-back state) and the collider impulses, dt the
  // solved part of the step and psi the elastic energy there.
  void finishStep(const FemModel& model, FemState& state, const StepContext& ctx, double theta,
                  double dt, double psi, JobSystem& jobs, BodyStepReport& rep);
  // solve()'s start: the inert test, the prescribed nodes moved, the step's friction, the
  // free pieces' rigid motion and the face entries' free flight, into m_x and m_y.
  void startNewton(const FemModel& model, const FemState& state, const StepContext& ctx,
                   double fullDt, JobSystem& jobs);
  // Newton iteration `it` linearised at m_x: returns the potential E and fills m_grad, m_A,
  // m_rhs and m_dx (the linear solve's start); fracture is judged in the first iteration's
  // pass when asked; toleranceScale is what the linear tolerance is measured against.
  double linearise(const FemModel& model, const FemState& state, const StepContext& ctx, int it,
                   bool judgeFracture, JobSystem& jobs, BodyStepReport& rep,
                   double& toleranceScale);
  // The Newton system with the pattern matrix m_A alone (b into x, x the start), by the body's
  // solver; the residual is reported against toleranceScale.
  // hostMatrixLost: rebuilds m_A on the host where a failed device held its only copy (never
  // called where the host assembled it).
  SolveReport patternSolve(const FemModel& model, const double* b, double* x, double tolerance,
                           double toleranceScale, JobSystem& jobs,
                           const std::function<void()>& hostMatrixLost = {});
  // linearise()'s Newton matrix into m_A (on the device where it can: m_matrixOnDevice) from
  // the last element pass's Hessians; true when it wrote this step's damping matrix K(x_n).
  bool assemble(const FemModel& model, const FemState& state, const StepContext& ctx, int it,
                JobSystem& jobs);
  // m_A's values on the host, read back from the device where it assembled them; false when
  // that failed.
  bool hostMatrix();
  // Iteration `it`'s element pass and matrix again on the host (the device dropped), at m_x.
  void relineariseOnHost(const FemModel& model, const FemState& state, const StepContext& ctx,
                         int it, JobSystem& jobs);
  // Whether a moving self pair acts at m_x (SelfPairActiveStage, into m_pairActive).
  bool selfPairsAct(const FemModel& model, const StepContext& ctx, double dt2, JobSystem& jobs);
  // Flexible CG on the parts' matrices plus the moving pairs' cross blocks, preconditioned by
  // each part's own solver (rhs and dx: the system's run of the joint vectors; cgWork: 5 of
  // them). One body's self pairs (coupledSolve) and a coupled cluster (coupledStep) alike.
  static SolveReport solvePairCoupled(std::span<const PairCoupledPart> parts,
                                      const PairCoupledSystem& system, const double* rhs,
                                      double* dx, double* cgWork, int maxIterations,
                                      double tolerance, JobSystem& jobs);
  // The Newton system with the moving self pairs' cross terms (m_rhs into m_dx).
  SolveReport coupledSolve(const FemModel& model, const FemState& state, const StepContext& ctx,
                           double tolerance, double toleranceScale, JobSystem& jobs);
  // The swept contacts of the step (SweepStage) into m_swept, from x_n over the full step;
  // flags kStepContactSwept when a node's path would have passed through a collider.
  void sweepColliders(const FemModel& model, const FemState& state, const StepContext& ctx,
                      JobSystem& jobs, BodyStepReport& rep);
  // True when a free node at x, or at x + dt v (v non-null: also when its path enters a thin
  // collider), penetrates a collider.
  bool nearCollider(const FemModel& model, const FemState& state, const double* x, const double* v,
                    double dt, const StepContext& ctx, JobSystem& jobs) const;
  // True when a free node now penetrates a collider that the last linearisation missed.
  bool enteredUnseenContact(const FemModel& model, const FemState& state, const StepContext& ctx,
                            JobSystem& jobs) const;
  // Whether a free node has friction against another body's face (BodyFrictionTerm).
  bool bodyFriction(const FemModel& model, const FemState& state, const StepContext& ctx,
                    JobSystem& jobs) const;
  // Whether a body half-space that acted at the last linearisation let go of its node
  // (ReleasedContactTerm).
  bool releasedBodyContact(const FemModel& model, const FemState& state, const StepContext& ctx,
                           JobSystem& jobs) const;
  // Stiffens the contacts that hold a pressed node at m_x deeper than its bound
  // (DeepContactTerm); true when any was.
  bool stiffenDeepContacts(const FemModel& model, const FemState& state, const StepContext& ctx,
                           JobSystem& jobs);
  // Whether this step has a box, sphere or capsule collider (m_faceOn), building the faces of
  // the body's fragments (boundary and crack faces) when one appears and again when the
  // fragments change: a world with only planes pays nothing. crossed:
  // the sweep found a node whose path would pass a collider (kStepContactSwept).
  void prepareFaces(const FemModel& model, const StepContext& ctx, bool crossed);
  // The faces' entries into colliders of the step (FaceSweepStage), after prepareFaces, as
  // swept contacts of the nodes around them (FaceEntryNodeStage, into m_swept's arrays); flags
  // kStepContactSwept when a face's path would have passed a collider. Only where a node moves,
  // relative to a collider, more than half its thinnest extent in the step.
  void sweepFaces(const FemModel& model, const FemState& state, const StepContext& ctx,
                  JobSystem& jobs, BodyStepReport& rep);
  // FacePlaneStage at x with this step's sweeps, without its output arrays (fc, skip).
  FacePlaneStage facePlaneStage(const FemModel& model, const FemState& state, const double* x,
                                const StepContext& ctx) const;
  // The face contacts at x (FacePlaneStage) into the m_face* arrays; true when any.
  bool findFaceContacts(const FemModel& model, const FemState& state, const double* x,
                        const StepContext& ctx, JobSystem& jobs);
  FaceContacts faceContacts() {
    return {m_faceNodes.data(),  m_faceCollider.data(), m_faceWeight.data(), m_facePoint.data(),
            m_faceNormal.data(), m_faceK.data(),        m_faceSeen.data(),   m_faceMuLambda.data()};
  }
  FaceContacts faceContacts() const { return const_cast<Integrator*>(this)->faceContacts(); }
  // Rayleigh stiffness-damping term dt/2 (x-x_r)^T r2 K(x_n) (x-x_r) (+ gradient into m_grad),
  // x_r = x_n, or the rigid motion of x_n for a free piece.
  double dampingTerm(const FemState& state, const double* xn, const double* x, double dt,
                     bool withGradient, JobSystem& jobs);

  BlockSparseMatrix m_A;
  ElementGather m_gather;
  std::vector<int32_t> m_nodeRefStart, m_nodeRef;  // node -> elem*4 + corner
  std::vector<double> m_elemEnergy, m_elemGrad, m_elemHess;
  // Per tet, the F of the last element pass or criterion that evaluated it and svd3 of it
  // (kSvdCacheStride, svd3.h): a pass at a state seen before (the next step's start, where
  // the criterion and the first Newton pass look; a repeated iteration) does no SVD there.
  // Keyed by F's bits, so anything that moved a node or changed Fp since simply misses.
  std::vector<double> m_svdCache;
  std::vector<double> m_elasticGrad;     // dPsi/dx per node
  std::vector<double> m_grad;            // gradient of the incremental potential
  std::vector<Mat3> m_contactHess;       // per node
  std::vector<double> m_nodeTerms;       // NodePotentialStage::terms
  std::vector<int32_t> m_diagonalBlock;  // block of each node's diagonal in m_A
  double m_energyRoundOff = 0;           // round-off of the last potential with its gradient
  double m_lastPsi = 0;                  // elastic energy of the last incrementalPotential call
  double m_restVolume = 0;               // of the whole body, for the blow-up test
  std::vector<uint8_t> m_contactSeen;    // contact was in the last linearisation
  SweptContacts m_swept;                 // this step's; null pointers when no collider is thin
  std::vector<int32_t> m_sweptCollider;
  std::vector<Vec3> m_sweptPoint, m_sweptNormal;
  std::vector<double> m_sweptCrossed, m_sweptStiffness;
  // Per node, SweepStage::bound, scale, pressed and over.
  std::vector<double> m_sweptBound, m_sweptScale, m_sweptPressed, m_sweptOver;
  bool m_movingCollider = false;           // this step has a collider with a velocity
  bool m_over = false;                     // a moving collider swept over a node's x_n (SweepStage)
  double m_cellSize = 0;                   // edge of a regular tet of the mean rest volume
  ColliderFriction m_friction;             // this step's; null muLambda when none
  bool m_bodyFriction = false;             // this step's: friction against another body's face
  std::vector<double> m_frictionMuLambda;  // FrictionContactStage's, per collider and node
  std::vector<Vec3> m_frictionNormal;
  std::vector<double> m_frictionTouching;  // per node
  BlockSparseMatrix m_dampK;               // K(x_n) for Rayleigh r2, only when r2 > 0
  bool m_dampKValid = false;               // m_dampK belongs to the current step
  // The step ended on a Newton step the line search shortened.
  bool m_shortStep = false;
  std::vector<double> m_xLin;          // the last linearisation point, for collider impulses
  std::vector<double> m_impulses;      // ColliderImpulseStage's, 6 per collider and node
  std::vector<double> m_balanceTerms;  // BodyContactBalanceStage's
  std::vector<double> m_adx;           // A dx, the Newton model's curvature along dx
  std::vector<double> m_pairActive, m_pairProjection;  // per half-space, SelfPair*Stage's
  std::vector<Vec3> m_pairNormal, m_pairWeight;
  std::vector<double> m_pairFriction;  // per half-space, SelfPair*Stage's f_k and t_k
  std::vector<Vec3> m_pairSlide;
  std::vector<double> m_cgWork;  // coupledSolve's CG vectors (CgBuffers), 5 n3
  // Boundary faces as 4-node elements (FaceContacts::faces), their gather plans and per-face
  // contacts (fem/face_stage.h); built when the first box, sphere or capsule collider appears,
  // and again when the fragments change (their version, m_facesKey): each fragment's boundary,
  // crack faces included, from body contact's surface (contact/body_contact.h).
  std::unique_ptr<ContactSurface> m_faceSurface;
  uint64_t m_facesKey = ~uint64_t(0);
  uint64_t m_faceSurfaceKey = 0;
  bool m_faceOn = false;   // this step has a box, sphere or capsule collider
  bool m_faceAny = false;  // the last linearisation has a face contact
  int32_t m_faceCount = 0;
  std::vector<int32_t> m_faceNodes, m_faceRefStart, m_faceRef, m_faceCollider;
  ElementGather m_faceGather;
  std::vector<Vec3> m_faceWeight, m_facePoint, m_faceNormal;
  std::vector<double> m_faceK, m_faceMuLambda, m_faceEnergy, m_faceGrad, m_faceHess, m_faceTotal;
  std::vector<uint8_t> m_faceSeen;
  std::vector<uint8_t> m_faceSkip;  // per collider: no face contact with it this step
  // Per face, FaceSweepStage's entries, and the step's list of them (FaceEntryNodeStage).
  std::vector<int32_t> m_faceSweptCollider;
  std::vector<Vec3> m_faceSweptPoint, m_faceSweptNormal;
  std::vector<double> m_faceSweptRadius, m_faceSweptCrossed;
  std::vector<FaceEntry> m_faceEntries;
  std::vector<double> m_faceNodeGrad;  // per node: the face gradient, then the face impulse
  std::vector<double> m_x, m_dx, m_rhs, m_tmp, m_diff, m_kdiff, m_xStart, m_vStart;
  double m_theta = 1;  // of the last step; below 1, m_x keeps the solved point the forces act at
  FractureBody* m_fracture = nullptr;
  double* m_stressOut = nullptr;      // 6 per tet: the element pass also writes Biot stresses
  bool m_closedCrackHessian = false;  // the element pass's Hessians take every crack as closed
  // Every tet is rigid or split (what is left free are chips, as when a shattered body's pieces
  // went to rigid physics): the potential is per node, so its Hessian is block diagonal.
  bool m_inert = false;
  PcgSolver m_pcg;
  // The CUDA backend's device (useDevice), and whether its copy of the body's state arrays is
  // older than this step or than the last breaks (m_deviceBroken).
  std::unique_ptr<BodyDevice> m_device;
  bool m_deviceStale = true;
  int32_t m_deviceBroken = 0;
  // The latest element Hessians are on the device only; the device assembled this iteration's
  // m_A (its values there); m_A.values on the host are not this iteration's; the device holds
  // this step's K(x_n).
  bool m_hessOnDevice = false, m_matrixOnDevice = false, m_hostMatrixStale = false;
  bool m_dampKOnDevice = false;
  std::string m_deviceFailure;
  // Hands the body back to the CPU after a failed device call.
  void dropDevice();
  class CriterionOnDevice;
  std::unique_ptr<CholeskySolver> m_cholesky;
  std::unique_ptr<MultigridSolver> m_multigrid;
  int32_t m_boundBrokenCount = 0;  // broken edges the multigrid binding has seen
  // Free pieces of this step (predictRigidMotion); m_rigidPieces false: none are stepped so.
  bool m_rigidPieces = false;
  std::vector<RigidPiece> m_pieces;
  std::vector<int32_t> m_pieceOfNode;  // the piece of each node at the step's start
  SegmentLists m_pieceLists;           // the nodes grouped by piece
  // Scratch of the piece grouping (fem/piece_merge.h, step/segments.h).
  std::vector<int32_t> m_mergeLabel, m_mergeNext, m_mergeRootId, m_mergeChunkSum,
      m_mergeChunkOffset;
  std::vector<double> m_mergeChanged;
  ScanScratch m_pieceScan;
  static constexpr uint64_t kNoPieces = ~uint64_t(0);
  uint64_t m_piecesKey = kNoPieces;  // the fragments' version m_pieceLists belongs to
  std::vector<double> m_pieceTerms;  // per-node terms of the piece sums, kPieceSpinTerms arrays
  std::vector<double> m_pieceSums, m_piecePartials;
  std::vector<double> m_piecePressed;  // per piece, 1 when stepped by plain backward Euler
  std::vector<double> m_y;             // inertia target of the step
  std::vector<double> m_dampRef;       // what stiffness damping measures the motion from
};

}  // namespace gf::detail
