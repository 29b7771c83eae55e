// FEM body data, MuJoCo style: a read-only model (rest data, topology, settings fixed at
// creation) and mutable data (the state and what commands set), both flat arrays that a
// device copies unchanged; a snapshot is a copy of the data.
#pragma once

#include <cstdint>
#include <vector>

#include "graphfrac/defs.h"
#include "kernels/materials.h"
#include "kernels/math.h"

namespace gf::detail {

/// Rest data of a body; fixed for its lifetime (the mesh is never remeshed, and commands
/// change FemState only).
struct FemModel {
  int32_t nodeCount = 0;
  int32_t tetCount = 0;
  std::vector<int32_t> tets;          ///< 4 per tet
  std::vector<double> restPositions;  ///< 3 per node
  std::vector<Mat3> restInverse;      ///< Dm^-1 per tet
  std::vector<double> restVolume;     ///< per tet
  double lengthScale = 1;             ///< rest bounding-box diagonal (round-off thresholds)
  SolverSettings solver;
  double friction = 0.6;  ///< BodyDef::friction
  bool contact = false;   ///< BodyDef::contact
  FractureSettings fracture;
  PlasticitySettings plasticity;
  WettingSettings wetting;
  std::vector<Vec3> fibreDir;  ///< per tet, only with a fibre field (else empty)
};

/// Mutable data of a body: its state, and the values commands set between steps.
struct FemState {
  std::vector<double> x;  ///< positions, 3 per node
  std::vector<double> v;  ///< velocities, 3 per node
  // Set by World::setMaterial (and at creation): the material, its kernel coefficients and
  // the lumped masses rho V / 4 from each incident tet (eq 2.10, row-summed).
  Material material;
  MaterialCoeffs coeffs;
  std::vector<double> nodeMass;
  // Grips (World::setGripVelocity) and nodes of fragments handed to rigid physics.
  std::vector<uint8_t> fixedNode;    ///< 1 where the velocity is prescribed
  std::vector<double> gripVelocity;  ///< 3 per node (zero where not fixed)
  bool movingGrips = false;          ///< some grip has a non-zero velocity
  /// Per tet, 1 when its nodes all lie in fragments handed to rigid physics: it moves rigidly
  /// from its rest shape (World::setFragmentTransform), so it has no strain, energy or stress
  /// and the element pass skips it. Empty until a fragment is detached.
  std::vector<uint8_t> rigidTet;
  std::vector<double> externalForce;  ///< 3 per node, constant point forces
  /// Per node, the drag w of a deform brush for the coming step (World::deform): the energy
  /// 1/2 m w |x - x_n|^2 (in the h^2-scaled units of the incremental potential), so a free node
  /// with nothing else acting leaves the step with v_n / (1 + w). Empty: none.
  std::vector<double> drag;
  /// Per node, the tether weight w of a pull for the coming step (World::pull): the energy
  /// 1/2 m w |x - t|^2 toward the node's target t (tetherTarget, 3 per node), a spring of
  /// m w / h^2 over a step of h. Empty: none.
  std::vector<double> tether, tetherTarget;
  // Plasticity (eq 2.3-2.5), only when enabled (else empty): per tet Fp, its inverse, the
  // hardening accumulator delta and the effective rest inverse Dm^-1 Fp^-1 that the element
  // pass and the fracture criterion use instead of Dm^-1.
  std::vector<Mat3> Fp, FpInv, plasticInverse;
  std::vector<double> plasticDelta;
  // Water (sculpt/wetting.h), empty until the body's first wet brush: the water mass per tet
  // and the kernel's (mu, lambda) per tet that it gives (eq 7.1-7.4), which replace
  // coeffs.mu and coeffs.lambda in every element kernel.
  std::vector<double> water;
  std::vector<double> tetLame;
  /// Per node, the normal force [N] its contact pairs (with other bodies and between the
  /// body's own pieces) pressed it with at the end of the last substep
  /// (BodyContact::recordLoads): the lagged load of their friction in the next. Empty: none.
  std::vector<double> contactLoad;
};

/// Builds the model from a validated definition (mesh already checked by the caller). Its
/// solver settings are the def's with the size rule applied (effectiveLinearSolver).
FemModel buildFemModel(const BodyDef& def);
/// The body's data at creation: at rest, at its mesh's positions, with the def's material,
/// grips and point forces, and no plastic flow yet when plasticity is enabled.
FemState buildFemState(const BodyDef& def, const FemModel& model);
/// Lumped masses of `model` at `density` into nodeMass (one per node).
void lumpMasses(const FemModel& model, double density, std::vector<double>& nodeMass);

/// The linear solver a body of `freeNodes` free nodes runs with these settings: the multigrid
/// hands bodies below MultigridSettings::directBelowNodes to the direct solver.
LinearSolverKind effectiveLinearSolver(const SolverSettings& s, int64_t freeNodes);

/// Bytes a body of this def holds once created (model, state, element buffers, the sparse
/// matrix, solver, fracture and plasticity data), from its node and tet counts: what
/// World::createBody reports when the allocation fails. Within about 25 % of the measured
/// growth of the process (tests/unit/test_world_memory.cpp).
double estimateBodyBytes(const BodyDef& def);

/// Lamé-based kernel coefficients of a public Material.
MaterialCoeffs toCoeffs(const Material& m);

}  // namespace gf::detail
