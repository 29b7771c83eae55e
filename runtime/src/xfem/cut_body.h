// A standalone Is-XFEM body (thesis ch 3): a tet mesh cut through by planes, with enriched
// DOFs (eq 3.4) on every node of a cut tet, linear elasticity, and the implicit step of
// eq 3.13. It checks the enrichment and the quadrature end to end before the world integration.
//
// Design: CPU only. The system grows with every cut (the world's block-sparse pattern and its
// multigrid hierarchy are fixed for a body's lifetime), so it is an Eigen sparse matrix solved
// by a sparse Cholesky (CholeskySolver: CHOLMOD's supernodal LL^T when the build has it and the
// matrix has over 384 DOFs, else Eigen's SimplicialLLT): thousands to tens of thousands of DOFs,
// where a direct solve is both the fastest and the exact reference. The enrichment fills the factor
// much faster than it adds DOFs (every cut tet couples 4 (1 + m) functions): on 20 cuts through a
// 12000-tet box a simplicial LDL^T (AMD) spent over ten seconds, the supernodal one (CHOLMOD's
// METIS ordering, half AMD's fill) under one, analysis included. Linear elasticity keeps M and K
// constant, so the step matrix is factorised once and a step only back-substitutes. A body without
// cuts is a plain linear FEM body. The World steps its bodies in BodyDef::cutMode Xfem with this
// class (world/world_xfem.cpp): a cut there builds a new body with the blade added (withBlade) and
// carries the state over; plane colliders are met by step(planes). Bodies in graph mode never see
// it, so they pay nothing for it. Cuts are infinite planes or blades (triangle meshes,
// blade_path.h); a blade cuts each tet along its local plane. Blades that end inside the body: a
// node gets the enriched DOF of a cut only when every tet around it that the cut meets is fully
// crossed (eq 3.4 restricted so that the enriched field stays conforming across faces, since an
// enriched function then vanishes on every face its node shares with an uncut tet). A tet the blade
// ends in is not enriched; a fully crossed tet with some nodes not enriched has an opening that
// fades to zero toward them. So a crack opens only in tets whose four nodes are all enriched, and
// stops up to one ring of tets short of the blade's front; no crack-tip enrichment. Pieces are the
// connected components of the cells (cells of one tet joined unless a cut opens between them, cells
// of neighbouring tets joined when their polygons on the shared face overlap), which is also the
// check that a cut closes. Each piece has a closed render surface (cut_surface.h): its boundary
// faces clipped to its cells and the exact cut polygons, built with the cells and moved per frame
// by eq 3.4; a cut that does not open leaves a closed pocket there, not a hole. Blades may be swept
// (blade_path.h: the surface the blade sweeps). The constraint of sec 3.2.2.2 is an option
// (XfemConstraint), off by default: a tiny sliver cut off stays free of NaN and falls freely
// without it (condition number up to 2.4e11 at k = 0.1, which the direct solve absorbs); with it
// the condition number stays near 5e4 but the sliver is glued to the body (figures at
// XfemConstraint).
#pragma once

#include <graphfrac/mesh.h>
#include <graphfrac/status.h>

#include <Eigen/Sparse>
#include <memory>
#include <unordered_map>
#include <vector>

#include "solver/cholesky.h"
#include "xfem/blade_path.h"
#include "xfem/cut_element.h"
#include "xfem/cut_surface.h"

namespace gf::detail {

/// The constraint of thesis sec 3.2.2.2: (A + lambda I) v' = b on the enriched DOFs whose volume
/// ratio v (eq 3.16) is below `minRatio`, with lambda = `relative` times the DOF's own diagonal
/// A_ii (scale-free). Off by default, from the measurements of a sliver x > 2 - f h cut off a held
/// stiff bar (tests/physics/test_xfem_sliver.cpp, docs/validation.md). With k = 0.1 the step
/// matrix's condition number grows from 2.5e5 (f = 1e-3) to 2.4e11 (f = 1e-9, v = 5e-28), which
/// the direct Cholesky solve still handles: no NaN, and the cut-off sliver falls as implicit
/// Euler's free fall to 1.3e-4. The constraint (v < 1e-4, relative 1) holds the condition number
/// near 5e4 at every f, but it re-glues the sliver: A_ii holds dt^2 K, so lambda freezes the
/// enriched DOFs that let the sliver go, and the sliver stays attached to the bar (falls 0.4-0.6%
/// of free fall where the bar's mean falls 0.2%; relative 1e-2 the same for f <= 1e-5; with a
/// soft bar, E = 1e7, it is dragged: 84-87% of free fall). For classic XFEM (k = 0) a lambda
/// relative to the DOF's diagonal cannot help: that diagonal itself vanishes with the sliver
/// (3.5e10 to singular to rounding with or without it; eq 3.15's scaling is the cure there). So
/// it is for an iterative solver (the thesis's CG) at the price of glued slivers. A cut whose
/// every enriched DOF has v >= minRatio is untouched (bit-identical).
struct XfemConstraint {
  double minRatio = 0;    ///< Threshold on v of eq 3.16, in [0, 1); 0: off.
  double relative = 1.0;  ///< lambda / A_ii, >= 0.
};

/// A cell left out of the system (a piece handed to rigid physics): the cells of `tet` on side
/// `sides` of the cuts in `cutBits` (bit j: cut j), whatever later cuts do to them.
struct XfemDroppedCell {
  int32_t tet = 0;
  unsigned cutBits = 0, sides = 0;
};

/// A piece's own rigid-body moments, exact for the enriched field: with x_f = X_f + u_f (X_f the
/// node's rest position for a standard function, 0 for an enriched one) x(X) = sum_f phi_f x_f
/// on the piece, so each moment is the piece's mass matrix M^p against the DOFs.
struct XfemPieceMoments {
  double mass = 0;       ///< [kg]
  double volume = 0;     ///< Rest volume [m^3].
  Vec3 restCentre;       ///< Rest centre of mass.
  Mat3 restSecond;       ///< integral of rho (X - C)(X - C)^T at rest, about restCentre.
  Vec3 centre;           ///< Current centre of mass.
  Vec3 momentum;         ///< integral of rho v.
  Vec3 angularMomentum;  ///< integral of rho (x - c) x v, about the current centre.
  Mat3 spread;           ///< integral of rho (x - c)(X - C)^T (its polar factor: the rotation).
};

/// What an Is-XFEM body is made of.
struct XfemBodyDef {
  TetMesh mesh;                     ///< Rest shape, positively oriented tets.
  std::vector<CutPlane> planes;     ///< Cuts; unit normals (eq 3.1 is then n.x - offset).
  std::vector<XfemBlade> blades;    ///< Cuts numbered after the planes (static blades).
  double k = 0.1;                   ///< Eq 3.2: 0.1 Is-XFEM, 0 classic XFEM.
  LinearElastic material;           ///< Elasticity and density.
  std::vector<int32_t> fixedNodes;  ///< Nodes whose DOFs (standard and enriched) stay at rest.
  Vec3 gravity{0, -9.81, 0};        ///< Body force per unit mass.
  double dt = 1.0 / 60;             ///< Time step [s].
  XfemConstraint constraint;        ///< Sec 3.2.2.2 on sliver DOFs.
  /// Cells out of the system: no mass, stiffness, load or contact. Held (DOFs kept, velocity 0):
  /// every function left without support, and every enriched function that reaches into a
  /// dropped cell; on the cells left such a function is N_a (c - k gamma) (eq 3.2), nearly
  /// N_a times a constant, so it would make the step matrix all but singular (a stiff body's
  /// Cholesky failed), and its field there is frozen at the hand-off.
  std::vector<XfemDroppedCell> dropped;
};

/// A piece: a connected part of the body between opened cuts.
struct XfemPiece {
  /// Sides of the piece's first cell: bit j set on the positive side of cut j (planes first,
  /// then blades); a cut that does not separate the piece may have cells on both sides.
  unsigned mask = 0;
  double volume = 0;
  int32_t cells = 0;
  Eigen::VectorXd load;  ///< integral over the piece of rho phi_A, per scalar shape function.
  Eigen::SparseMatrix<double> mass;      ///< integral over the piece of rho phi_A phi_B (scalar).
  std::vector<XfemDroppedCell> cellIds;  ///< Its cells, as XfemBodyDef::dropped names them.
  bool dropped = false;                  ///< Its cells are out of the system (XfemBodyDef).
};

/// A cut polygon: cut j's face inside one tet (seen from the positive side's cell).
struct XfemCutFace {
  int32_t tet = 0;
  int32_t plane = 0;  ///< The cut: planes first, then blades.
  bool opens = true;  ///< All four nodes carry the cut's enrichment: the faces may separate.
  CutPolygon polygon;
};

/// How a cut crosses the body.
struct XfemCutReport {
  int32_t fullTets = 0;      ///< Fully crossed tets (blade_path.h).
  int32_t partialTets = 0;   ///< Tets the blade ends in: not enriched.
  int32_t enrichedTets = 0;  ///< Tets carrying the cut's enrichment.
  int32_t openTets = 0;      ///< Of those, tets whose four nodes are enriched.
  double maxDeviation = 0;   ///< Blade's distance from its local planes, fully crossed tets.
};

/// A half-space the body stays in (the World's plane colliders): normal . x >= offset, with a
/// unit normal.
struct XfemContactPlane {
  Vec3 normal{0, 1, 0};
  double offset = 0;
};

/// What the contact of one step did.
struct XfemContactReport {
  int32_t contacts = 0;      ///< Surface vertices in the step's LCP (active set).
  int32_t rounds = 0;        ///< Active-set rounds (each adds the vertices still penetrating).
  int32_t pivots = 0;        ///< Principal pivoting solves, summed over rounds.
  int32_t sweeps = 0;        ///< Projected Gauss-Seidel sweeps after them, summed over rounds.
  double minGap = INFINITY;  ///< Smallest end-of-step gap of the active vertices [m].
  /// The last round's LCP met its tolerance (every active vertex's complementarity residual
  /// moves it by at most 1e-9 of the body's size in the step) after pivoting and at most 5000
  /// sweeps.
  bool converged = true;
  double residual = 0;  ///< That residual [m/s].
  /// Per plane: the impulse sum lambda_k n [N s], then its moment about the origin.
  std::vector<double> impulse;
};

/// The cut body, its enriched system and its state.
class XfemBody {
 public:
  /// Builds cells, rules, element matrices and the factorised step matrix. Fails, naming the
  /// field, on an empty mesh, a plane with a non-unit normal, a bad blade (traceBlade), more
  /// than 32 cuts or more than kMaxCutPlanes through one tet (named, with its cuts), a fixed node
  /// out of range, or a singular step matrix.
  static Result<std::unique_ptr<XfemBody>> create(const XfemBodyDef& def);

  int32_t functionCount() const { return m_functionCount; }  ///< Scalar shape functions.
  int32_t enrichedCount() const { return m_functionCount - int32_t(m_def.mesh.nodeCount()); }
  int32_t dofCount() const { return 3 * m_functionCount; }
  int32_t cutTetCount() const { return m_cutTets; }

  /// One implicit Euler step (eq 3.13): (M + dt^2 K) v' = M v - dt (K u - f_ext), u' = u + dt v'.
  /// False, with u and v unchanged, when the state is not finite (a NaN set through velocity()).
  bool step();
  /// The same step with hard frictionless contact: every vertex of the render surface (cut faces
  /// included) ends the step in every plane's half-space. With impulses lambda_k >= 0 along
  /// the normals at the active vertices, A v' = b + G^T lambda, and the gaps after the step
  /// g_k + dt G_k v' >= 0 complementary to lambda (a linear complementarity problem on the
  /// Schur complement G A^-1 G^T over the existing factor, solved by principal pivoting with a
  /// projected Gauss-Seidel polish; new penetrating vertices join the active set round by round,
  /// last step's contacts start it). An inelastic contact: no bounce.
  /// False, with u and v unchanged, when the state is not finite.
  bool step(const std::vector<XfemContactPlane>& planes, XfemContactReport* report = nullptr);

  /// A new body: this one with `blade` added as its last cut, its state carried over. Every
  /// shape function this body has keeps its displacement and velocity (standard ones by node,
  /// enriched ones by node and cut); the new cut's enriched functions start at zero, so the
  /// displacement field, and so the momentum, are unchanged by the cut. Fails as create().
  Result<std::unique_ptr<XfemBody>> withBlade(const XfemBlade& blade) const;
  /// Refactorises the step matrix for a new time step (a no-op for the same one); fails, with
  /// the body unchanged, on a dt that is not positive and finite or a singular matrix.
  Result<void> setTimeStep(double dt);
  double timeStep() const { return m_def.dt; }
  const XfemBodyDef& def() const { return m_def; }
  /// Consistent mass matrix M and stiffness K over all 3 F DOFs (eq 3.5, 3.7).
  const Eigen::SparseMatrix<double>& massMatrix() const { return m_mass; }
  const Eigen::SparseMatrix<double>& stiffnessMatrix() const { return m_stiffness; }
  /// Displacement, 3 per shape function (e.g. to start from a deformed shape).
  Eigen::VectorXd& displacementMut() { return m_u; }
  /// Rest centre of mass of a piece: sum over standard functions of load_i X_i / mass (the
  /// standard functions interpolate x exactly and sum to 1).
  Vec3 pieceRestCentre(int piece) const;

  const Eigen::VectorXd& displacement() const { return m_u; }  ///< 3 per shape function.
  Eigen::VectorXd& velocity() { return m_v; }                  ///< 3 per shape function.
  const Eigen::VectorXd& velocity() const { return m_v; }

  /// Pieces ordered by mask, then by their first tet.
  const std::vector<XfemPiece>& pieces() const { return m_pieces; }
  /// The first piece with this mask, or -1.
  int pieceWithMask(unsigned mask) const;
  /// Mass-weighted mean displacement of a piece (its centre-of-mass motion).
  Vec3 pieceMeanDisplacement(int piece) const;
  /// Linear momentum of a piece, or of the whole body when piece < 0.
  Vec3 momentum(int piece = -1) const;
  /// A piece's rigid-body moments now (XfemPieceMoments); zero for a piece out of range.
  XfemPieceMoments pieceMoments(int piece) const;
  /// A new body: this one with the piece's cells dropped (XfemBodyDef::dropped), its
  /// displacement carried over and its velocity the mass-weighted (L2) projection of the old
  /// field on the cells left onto the functions still free: exact, and so momentum-preserving,
  /// for the velocity fields the free functions hold (a rigid motion always). Fails as
  /// create(), or for a piece out of range.
  Result<std::unique_ptr<XfemBody>> withoutPiece(int piece) const;
  /// Per cut (planes first, then blades): how it crosses the body.
  const std::vector<XfemCutReport>& cutReports() const { return m_cutReports; }
  /// Cut polygons (each cut's face in each tet carrying its enrichment).
  const std::vector<XfemCutFace>& cutFaces() const { return m_cutFaces; }
  /// Per piece (as pieces()), its closed render surface (cut_surface.h): boundary faces and exact
  /// cut polygons, vertices welded by name. Positions as of the last updateSurface().
  const std::vector<XfemPieceSurface>& surface() const { return m_surface; }
  /// Moves every surface vertex with the enriched field (eq 3.4) of the current displacement.
  void updateSurface();
  /// Wall time create() spent on the surface's topology and weights [ms] (benchmarks).
  double surfaceBuildMs() const { return m_surfaceBuildMs; }
  /// The enriched shape function of node for cut j (planes first, then blades), or -1.
  int32_t enrichedFunction(int32_t node, int32_t cut) const {
    const int32_t cuts = int32_t(m_def.planes.size() + m_def.blades.size());
    return m_enriched[size_t(node) * size_t(cuts) + size_t(cut)];
  }

  /// Per enriched function (function - node count): v of eq 3.16.
  const std::vector<double>& volumeRatios() const { return m_enrichedRatio; }
  /// Free DOFs under the constraint of sec 3.2.2.2 (XfemBodyDef::constraint).
  int32_t constrainedDofCount() const { return m_constrained; }
  /// The sparse step matrix A = M + dt^2 K over the free DOFs, with the constraint's lambda on
  /// the diagonal of the constrained DOFs.
  const Eigen::SparseMatrix<double>& stepMatrix() const { return m_stepMatrix; }
  /// Fill and ordering of the step matrix's Cholesky factor.
  CholeskyFactorInfo factorInfo() const { return m_solver.factorInfo(); }
  /// The volume-ratio scaling of eqs 3.15-3.16 over the free DOFs: 1 / sqrt(v_i) for enriched
  /// DOFs, 1 for standard ones, with v_i the share of node i's support on the far side of the
  /// cut (where classic XFEM's psi is non-zero). It fixes classic XFEM's sliver conditioning but
  /// over-scales Is-XFEM's enriched DOFs, whose mass does not vanish with the sliver (see
  /// tests/physics/test_xfem_cut_body.cpp for the figures).
  Eigen::VectorXd volumeRatioScaling() const;

 private:
  XfemBody() = default;
  // The step matrix over the free DOFs for m_def.dt, the constraint, and its factor.
  Result<void> buildStepMatrix();
  XfemBodyDef m_def;
  int32_t m_functionCount = 0, m_cutTets = 0, m_constrained = 0;
  std::vector<int32_t> m_enriched;      // node * cuts + j -> function, or -1
  std::vector<double> m_enrichedRatio;  // per enriched function: v of eq 3.16
  std::vector<int32_t> m_freeDof;       // free DOF -> DOF
  std::vector<uint8_t> m_held;          // per function: held by XfemBodyDef::dropped
  Eigen::SparseMatrix<double> m_mass, m_stiffness, m_stepMatrix;
  Eigen::VectorXd m_force, m_u, m_v;
  CholeskySolver m_solver;  // the step matrix's factor
  std::vector<XfemPiece> m_pieces;
  std::vector<XfemCutReport> m_cutReports;
  std::vector<XfemCutFace> m_cutFaces;
  std::vector<XfemPieceSurface> m_surface;
  // Contact impulses of the last step with planes, by (surface vertex, plane): its warm start.
  std::unordered_map<size_t, double> m_warm;
  double m_surfaceBuildMs = 0;
};

}  // namespace gf::detail
