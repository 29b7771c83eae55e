// One backward-Euler step of a cluster of bodies whose contacts couple them (WorldDef::
// coupledContact, contact/body_contact.h): Newton's method on the sum of the bodies' incremental
// potentials, whose contact pairs act on both sides (a vertex of one body against a face of
// another, re-linearised at every iterate as a body's self pairs are), so action and reaction
// are exact and no momentum has to be evened out afterwards. Each iteration linearises every
// body (Integrator::linearise: its elements, colliders, friction and the pairs' diagonal
// blocks), solves the joint Newton system by flexible CG on the bodies' matrices plus the pairs'
// cross blocks, preconditioned by each body's own solver on its matrix, and searches the step
// on the joint potential. It iterates to convergence, as a body with moving self pairs does.
#include <algorithm>
#include <cmath>

#include "fem/integrator.h"
#include "fem/newton.h"
#include "solver/pcg_stages.h"
#include "solver/vector_stages.h"
#include "step/executor.h"
#include "step/timing.h"

namespace gf::detail {

namespace {

constexpr uint32_t kGrain = 512;
// Newton stops once its step falls below this fraction of the first. What is left of the
// gradient is a force no pair balances, so it changes the cluster's momentum: a head-on
// collision of two free bodies kept it to 2.3e-6 (relative) at 1e-3, 4.9e-7 at 1e-4 and 4e-9
// at 1e-5 (two blocks stacked at rest: 3.9 and 4.4 Newton iterations a body and step, 10.3 and
// 15.3 ms a frame at 1e-4 and 1e-5).
constexpr double kCoupledTolerance = 1e-5;
// At most this many iterations; past them a step within kSweptTolerance counts as converged.
// Friction's Hessian stand-in makes Newton contract by a fixed ratio while a vertex slides
// (0.82-0.85 an iteration for a block sliding over a slab onto a frictional floor: 1e-3 after
// about 35 iterations).
constexpr int kMaxCoupledIterations = 60;

}  // namespace

void Integrator::coupledStep(std::span<CoupledBody> bodies, const CoupledCluster& cluster,
                             CoupledWork& work, JobSystem& jobs) {
  const CpuExecutor exec(jobs);
  const HalfSpaceContacts h = cluster.contacts;
  const int32_t nodeBegin = cluster.nodeBegin, nodes = cluster.nodeEnd - cluster.nodeBegin;
  const int32_t pairBegin = cluster.pairBegin, pairs = cluster.pairEnd - cluster.pairBegin;
  const int32_t n3 = 3 * nodes;
  const int64_t at = 3 * int64_t(nodeBegin);
  // Work vectors over all joint nodes (the pair stages index them by joint node); this cluster
  // uses its run of them.
  const size_t jointScalars = 3 * size_t(cluster.jointNodes);
  // rhs, dx and CG's five vectors (CgBuffers), one after another.
  work.vectors.resize(7 * jointScalars);
  double* rhs = work.vectors.data();
  double* dx = rhs + jointScalars;
  double* cg = dx + jointScalars;
  work.fixed.resize(size_t(cluster.jointNodes));
  const size_t K = size_t(cluster.jointPairs);
  work.active.resize(K);
  work.friction.resize(K);
  work.projection.resize(K);
  work.normal.resize(K);
  work.weight.resize(K);
  work.slide.resize(K);
  // The body's part of a joint vector.
  auto part = [&](double* v, const CoupledBody& b) { return v + 3 * int64_t(b.jointBase); };
  auto put = [&](const std::vector<double>& from, double* v, const CoupledBody& b) {
    std::copy(from.begin(), from.end(), part(v, b));
  };

  int maxIterations = 0;
  double tolerance = HUGE_VAL, lengthScale = 0;
  bool lineSearch = true;
  for (CoupledBody& b : bodies) {
    Integrator& in = *b.integrator;
    const FemModel& model = *b.model;
    FemState& state = *b.state;
    in.beginStep(model, state, b.ctx, jobs, *b.report);
    in.judgeMovingGripFracture(model, state, b.ctx, jobs, *b.report);
    in.startNewton(model, state, b.ctx, b.ctx.dt, jobs);
    in.m_closedCrackHessian = false;
    put(in.m_xStart, cluster.Xn, b);
    std::copy(state.fixedNode.begin(), state.fixedNode.end(), work.fixed.begin() + b.jointBase);
    maxIterations = std::max(maxIterations, model.solver.maxLinearIterations);
    tolerance = std::min(tolerance, model.solver.linearTolerance);
    lengthScale = std::max(lengthScale, model.lengthScale);
    lineSearch = lineSearch && model.solver.lineSearch;
  }
  const double dt = bodies.front().ctx.dt, dt2 = dt * dt;
  CoupledBody& first = bodies.front();
  std::vector<PairCoupledPart> parts;
  for (CoupledBody& b : bodies) parts.push_back({b.integrator, b.model, 3 * int64_t(b.jointBase)});
  const PairCoupledSystem system{h,
                                 work.fixed.data(),
                                 work.active.data(),
                                 work.normal.data(),
                                 work.weight.data(),
                                 work.friction.data(),
                                 work.projection.data(),
                                 work.slide.data(),
                                 nodeBegin,
                                 nodes,
                                 pairBegin,
                                 pairs};

  double firstStepNorm = 0;
  bool converged = false, settled = false, finalPsiKnown = false, finalStepNegligible = false;
  for (int it = 0; it < kMaxCoupledIterations; ++it) {
    double E = 0, roundOff = 0;
    for (CoupledBody& b : bodies) put(b.integrator->m_x, cluster.X, b);
    for (CoupledBody& b : bodies) {
      Integrator& in = *b.integrator;
      double toleranceScale = 1;
      E += in.linearise(*b.model, *b.state, b.ctx, it, it == 0 && b.ctx.judgeFracture, jobs,
                        *b.report, toleranceScale);
      roundOff += in.m_energyRoundOff;
      put(in.m_rhs, rhs, b);
      put(in.m_dx, dx, b);
      ++b.report->newtonIterations;
    }

    auto t0 = Clock::now();
    // The pairs at the linearisation point (every body's iterate is in cluster.X).
    exec.run(pairs, kGrain,
             OffsetStage<SelfPairActiveStage>{{h, dt2, work.active.data(), work.normal.data(),
                                               work.weight.data(), work.friction.data()},
                                              pairBegin});
    // The joint system: each body's matrix (the pairs' diagonal blocks in it) plus the pairs'
    // cross blocks, preconditioned by each body's own solver.
    const SolveReport sr =
        solvePairCoupled(parts, system, rhs + at, dx + at, cg + at, maxIterations, tolerance, jobs);
    first.report->solveMs += msSince(t0);
    first.report->linearIterations += sr.iterations;
    // An inexact solve only costs Newton iterations: the step is judged by Newton's convergence.
    for (CoupledBody& b : bodies)
      b.report->residual = std::max(b.report->residual, sr.relativeResidual);

    double stepNorm2 = 0, slope = 0;
    for (CoupledBody& b : bodies) {
      Integrator& in = *b.integrator;
      const int32_t m3 = int32_t(in.m_dx.size());
      std::copy(part(dx, b), part(dx, b) + m3, in.m_dx.begin());
      stepNorm2 += exec.dot(in.m_dx.data(), in.m_dx.data(), m3);
      slope += exec.dot(in.m_grad.data(), in.m_dx.data(), m3);
    }
    const double stepNorm = std::sqrt(stepNorm2);
    if (it == 0) firstStepNorm = stepNorm;

    // Backtracking (Armijo) on the joint potential: every body at x + alpha dx, the pairs read
    // all of them there.
    double alpha = 1.0;
    const bool search = lineSearch && slope < 0 && -slope > roundOff;
    finalPsiKnown = search;
    finalStepNegligible = lineSearch && !search && slope < 0;
    if (search) {
      t0 = Clock::now();
      for (;;) {
        double Et = 0;
        for (CoupledBody& b : bodies) {
          Integrator& in = *b.integrator;
          const int32_t m3 = int32_t(in.m_x.size());
          exec.run(m3, kGrain, AxpyStage{in.m_x.data(), in.m_dx.data(), alpha, in.m_tmp.data()});
          put(in.m_tmp, cluster.X, b);
        }
        for (CoupledBody& b : bodies) {
          Integrator& in = *b.integrator;
          Et += in.incrementalPotential(*b.model, *b.state, in.m_xStart.data(), in.m_tmp.data(),
                                        b.ctx, false, false, jobs);
        }
        if (std::isfinite(Et) && (Et <= E + kArmijo * alpha * slope || Et <= E + roundOff)) break;
        if (alpha <= kMinLineSearchStep) {
          for (CoupledBody& b : bodies) b.report->flags |= kStepLineSearchFailed;
          break;
        }
        alpha *= 0.5;
      }
      first.report->elementsMs += msSince(t0);
    }
    for (CoupledBody& b : bodies) {
      Integrator& in = *b.integrator;
      in.m_shortStep = alpha < 1;
      in.m_xLin = in.m_x;
      const int32_t m3 = int32_t(in.m_x.size());
      exec.run(m3, kGrain, AxpyStage{in.m_x.data(), in.m_dx.data(), alpha, in.m_x.data()});
    }
    const double relStep = firstStepNorm > 0 ? alpha * stepNorm / firstStepNorm : 0.0;
    // Past the iteration cap, a step within a body's own contact tolerance is converged too.
    settled = relStep <= kSweptTolerance;
    if (relStep <= kCoupledTolerance ||
        alpha * stepNorm <= kNewtonRoundOff * lengthScale * std::sqrt(double(n3))) {
      converged = true;
      for (CoupledBody& b : bodies) b.integrator->m_shortStep = false;
      break;
    }
  }
  // The end of the step. The impulses that the free pieces' end velocities and the colliders'
  // reports read are the forces at the solved point: Newton went on to convergence, so it is
  // the backward-Euler step's, and the pairs there are exact action and reaction (at the last
  // linearisation point, the pairs' cross blocks would be missing from the linear model).
  for (CoupledBody& b : bodies) {
    b.integrator->m_xLin = b.integrator->m_x;
    put(b.integrator->m_x, cluster.X, b);
    if (!converged && !settled) b.report->flags |= kStepNotConverged;
  }
  for (CoupledBody& b : bodies) {
    Integrator& in = *b.integrator;
    const FemModel& model = *b.model;
    FemState& state = *b.state;
    double psi = 0;
    if (!finalStepNegligible)
      psi = finalPsiKnown ? in.m_lastPsi
                          : in.elementPass(model, state, in.m_x.data(), false, false, jobs);
    in.faceImpulses(model, b.ctx, jobs);
    in.endOfStep(model, state, b.ctx, b.ctx, jobs);
    in.finishStep(model, state, b.ctx, 1.0, dt, psi, jobs, *b.report);
  }
}

}  // namespace gf::detail
