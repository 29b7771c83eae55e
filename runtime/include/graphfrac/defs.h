// Plain descriptions the engine fills in to create a world and its bodies. Defaults come from
// member initialisers; everything is checked when the world or body is created.
#pragma once

#include <cstdint>
#include <glm/gtc/quaternion.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <optional>
#include <vector>

#include "mesh.h"
#include "status.h"

namespace gf {

class JobSystem;

/// Hyperelastic energy of a material (SPEC §1).
enum class MaterialModel : uint8_t {
  Corotated,         ///< Co-rotational linear (Müller & Gross 2004).
  StVK,              ///< Saint Venant-Kirchhoff.
  NeoHookean,        ///< Classic Neo-Hookean; log J continued quadratically below J = 0.1.
  StableNeoHookean,  ///< Smith et al. 2018, with its Lamé reparametrisation; inversion safe.
};

/// Material parameters in SI units. Lamé parameters follow from E and nu (eq 4.29).
struct Material {
  MaterialModel model = MaterialModel::StableNeoHookean;
  double youngsModulus = 1e6;  ///< E [Pa]
  double poissonRatio = 0.3;   ///< nu, in (-1, 0.5)
  double density = 1000;       ///< rho [kg/m^3]
  /// Fibre stiffness mu_f [Pa] of the anisotropic term (eq 4.36) added to the isotropic
  /// energy; 0 = isotropic (no fibre term is evaluated).
  double fibreStiffness = 0;
  glm::vec3 fibreDirection{1, 0, 0};  ///< Rest-space fibre direction (normalised on use).
  double massDamping = 0;             ///< Rayleigh r1 [1/s]
  double stiffnessDamping = 0;        ///< Rayleigh r2 [s]

  static Material corotated(double E, double nu, double rho);
  static Material stvk(double E, double nu, double rho);
  static Material neoHookean(double E, double nu, double rho);
  static Material stableNeoHookean(double E, double nu, double rho);
  /// Empty when valid; otherwise names the field ("material.density: ...") and the reason.
  Result<void> check() const;
};

/// Linear solver of the implicit step.
enum class LinearSolverKind : uint8_t {
  PCG,        ///< Conjugate gradient, block-Jacobi preconditioned.
  Direct,     ///< Sparse Cholesky; the reference for error measurements.
  Multigrid,  ///< Galerkin multigrid (SPEC §5, thesis ch. 6), alone or preconditioning CG.
};

/// Smoother of a multigrid level.
enum class Smoother : uint8_t {
  Jacobi,       ///< Damped block Jacobi.
  GaussSeidel,  ///< Multi-colour block Gauss-Seidel (forward before, backward after: symmetric).
  Chebyshev,    ///< Chebyshev polynomial of the block-Jacobi preconditioned operator.
};

/// Galerkin multigrid of the implicit step (eq 6.1-6.8, Xian et al. 2019).
struct MultigridSettings {
  /// Handles of each coarse level, coarsest first; the mesh itself is the finest level. The
  /// scene format writes a setup "50/1000/all" as {50, 1000}. Counts must grow from coarse to
  /// fine; counts above the free node count are clamped. Fragments cut off by cracks gain
  /// handles (crackRebinding), so a level can end up with more handles than asked.
  /// Empty (the default, "auto" in scenes): chosen from the body's free node count. With the
  /// piecewise-affine prolongation about 64 nodes per handle on the finest coarse level, then
  /// 8 times fewer handles per level until at most 128 remain (a 30k-tet beam of 6k nodes gets
  /// 95/all, a 175k-tet one of 32k nodes 64/508/all); with smoothedProlongation 27 nodes per
  /// handle down to at most 96 (28/224/all and 19/150/1203/all).
  std::vector<int32_t> levels{};
  Smoother smoother = Smoother::GaussSeidel;
  int preSweeps = 2;   ///< Smoothing sweeps per level before restriction.
  int postSweeps = 2;  ///< Smoothing sweeps per level after prolongation.
  /// Sweeps before restriction / after prolongation on the coarse levels above the coarsest
  /// (which is solved exactly); -1: preSweeps / postSweeps. With smoothedProlongation level 1
  /// holds 1.33x the fine matrix's entries (30k tets: each row of P_1 has 3.4 blocks), so each
  /// of its sweeps costs about a fine one. 1+1 there, 4+4 on the fine level: 0.66-0.86x of the
  /// all-4+4 frame, 3.6x per V-cycle instead of 5.4x on the 30k steel beam (validation.md).
  int coarsePreSweeps = -1;
  int coarsePostSweeps = -1;
  /// true: the V-cycle preconditions CG (SolverSettings::maxLinearIterations and
  /// linearTolerance apply); false: `cycles` V-cycles alone (a fixed cost per step).
  bool preconditionCG = true;
  int cycles = 2;
  /// Smoothed aggregation (Vanek, Mandel and Brezina 1996): each level's piecewise-affine
  /// prolongation U takes one damped block-Jacobi step, P = (I - 4/(3 rho) D^-1 A_F) U, over
  /// unbroken edges only (A_F), and the coarse operators are P^T A P. P is smoothed with the
  /// matrix of the first solve after setup and after each crack re-binding, and kept until the
  /// next. It converges several times faster (30k-tet steel beam: 3.4x per V-cycle and 9
  /// MG-CG iterations with GS 2+2, 5.4x and 7 with 4+4, against the default's 1.7x and 16;
  /// still 7-8 iterations at 175k tets, where the default's grow to 27-30), but P^T A P costs
  /// 20-70x the piecewise-affine product (12x12 blocks of basis functions that overlap their
  /// neighbours), so on the bodies of `graphfrac bench multigrid` (30k-160k tets, one thread)
  /// a step takes 1.5-3x longer than with the default (docs/validation.md, issue 14); with
  /// coarseRefreshInterval 30, which leaves the product out of most frames, the solve stage
  /// still takes 1.6-2.2x the default's (GS 4+4: each V-cycle costs 2.5-4x). false:
  /// P = U, the thesis's prolongation (eq 6.6-6.8).
  bool smoothedProlongation = false;
  /// With smoothedProlongation, in [0, 1): bounds P's sparsity. A finer row keeps its block
  /// for a neighbouring aggregate only when at least this fraction of the row's smoothing
  /// terms (itself and its unbroken neighbours) lies in that aggregate; the other terms are
  /// lumped into the block of the row's own handle, so P maps the affine fields exactly as the
  /// unfiltered P does. Fewer blocks of P make the coarse operators sparser (cheaper sweeps and
  /// P^T A P) for a weaker V-cycle. 0: no filter.
  double prolongationFilter = 0;
  /// Recompute the coarse operators A_{l+1} = P^T A_l P (eq 6.4) and the coarsest
  /// factorisation at least every this many solves (and at the first solve after set-up).
  /// With preconditionCG the V-cycle only preconditions CG: coarse operators of an earlier
  /// matrix still give an SPD preconditioner, the fine smoother always sees the current
  /// matrix, and CG converges to the current system's solution; a stale coarse level only
  /// costs iterations (see coarseRefreshSlack). In "cycles" mode it changes what the fixed
  /// cycles reach. Above 1, crack re-binding also waits for the next refresh. Snapshots hold
  /// the schedule and the coarse levels a later solve keeps, so a restored one replays bit for
  /// bit. 0 (the default): 10 with preconditionCG, every solve in "cycles" mode. On the
  /// benchmark bodies a frame takes 0.7-0.94x its time with 1 (docs/validation.md, issue 14).
  int coarseRefreshInterval = 0;
  /// With preconditionCG and a refresh interval above 1: refresh early, at the next solve, once
  /// a solve took more MG-CG iterations than the first solve after the last refresh plus this
  /// many (the matrix has drifted from the one the coarse operators were built from). >= 0.
  int coarseRefreshSlack = 2;
  /// Re-bind vertices whose handle sits across a crack (SPEC §5) when edges break.
  bool crackRebinding = true;
  /// A body with fewer free (not gripped) nodes than this is solved by the sparse Cholesky
  /// (LinearSolverKind::Direct) instead. Its coarse level would not be coarse: a handle carries
  /// 12 unknowns and a node 3, and the default 64 handles exceed a debris box of 27 or 64 nodes
  /// several times over, so each step refactorised a coarse matrix larger than the body's own
  /// (about 1 ms a body). Below this size the exact factorisation also costs less than the
  /// multigrid's CG iterations. 0 keeps the multigrid at every size.
  int32_t directBelowNodes = 128;
  /// Empty when valid; otherwise names the field ("levels: ...") and the reason.
  Result<void> check() const;
};

/// How the implicit backward Euler step (eq 2.7, 3.13) is solved.
struct SolverSettings {
  /// Newton iterations per substep: 1 = linearly implicit (the default, game speed);
  /// more = full Newton with backtracking line search, stopping at newtonTolerance.
  int newtonIterations = 1;
  double newtonTolerance = 1e-6;  ///< Relative to the first Newton step's size.
  /// Backtracking line search on the incremental potential, also for the one-step default:
  /// it guarantees the step never increases that energy (stiff and inverted cases) for the
  /// price of one energy-only element pass per iteration.
  bool lineSearch = true;
  /// Steps free pieces (bodies and fragments that hold no gripped node) in the frame that
  /// turns with them: their rigid motion is carried exactly, so a spinning body keeps its spin
  /// and the step does not stretch it, and backward Euler acts on the deformation, with the
  /// centrifugal and Coriolis accelerations of that frame. false: backward Euler on the
  /// positions, which loses about (w dt)^2 of a spin per step and starts Newton on a stretched
  /// body.
  bool corotatedInertia = true;
  /// How strongly the time step damps vibrations, in [0, 1] (else check() fails). 1 (the
  /// default) is backward Euler, bit for bit: it removes most of a vibration within a few
  /// periods at game time steps, which keeps stiff contact calm. Below 1 the step is the theta
  /// method with theta = (1 + numericalDamping) / 2 (a backward-Euler step of theta dt,
  /// extrapolated to dt), and a mode of frequency w keeps the fraction
  /// (1 + (1-theta)^2 w^2 dt^2) / (1 + theta^2 w^2 dt^2) of its energy per step; 0 is the
  /// implicit midpoint rule, which damps no linear mode. Free pieces extrapolate only their
  /// deformation: their rigid motion is carried exactly and their angular momentum kept;
  /// gripped nodes still move exactly dt * grip velocity. A body touching a collider, or
  /// reaching one within the step, takes that step with backward Euler. With one Newton
  /// iteration the linearisation adds damping that grows with dt and amplitude; two give the
  /// theta method's figures (docs/design.md).
  double numericalDamping = 1;
  /// Multigrid (the default) solves small bodies directly; see
  /// MultigridSettings::directBelowNodes.
  LinearSolverKind linearSolver = LinearSolverKind::Multigrid;
  MultigridSettings multigrid;  ///< Used when linearSolver == Multigrid.
  int maxLinearIterations = 200;
  /// The relative residual |r|/|b| at which CG stops (PCG and multigrid-preconditioned CG).
  /// The default 1e-4 leaves the step within about 1e-5 of the exact linear solve on the
  /// benchmark bodies, far below one Newton step's own linearisation error (docs/validation.md).
  double linearTolerance = 1e-4;
  /// Empty when valid (the multigrid settings are checked when linearSolver is Multigrid);
  /// otherwise names the field ("newtonIterations: ...", "multigrid.levels: ...") and the reason.
  Result<void> check() const;
};

/// Where the render surface (World::surface) splits a broken edge (thesis sec 4.4.1, fig 4.10).
enum class SplitPoint : uint8_t {
  /// At its midpoint, as the thesis renders by default.
  Midpoint,
  /// A stress break at the force-ratio point of fig 4.10: the edge's two sections are in
  /// inverse proportion to the elastic forces on its nodes when it breaks, so the crack lies
  /// nearer the node that is pulled harder. A blade's or a brittle plane's break at the point
  /// where the blade or plane crosses the edge. Ratios are clamped to [0.1, 0.9] of the edge.
  ForceRatio,
};

/// How a damaged element's energy follows from its broken edges (SPEC §2).
enum class DamageModel : uint8_t {
  /// eq 4.25-4.27 on the material-frame (Green) strain: broken edges lose only their tensile
  /// part, so a closed crack still resists compression.
  Projection,
  /// eq 4.32-4.33: the energy scaled by chi, the ratio of summed absolute edge stresses after
  /// and before masking, lagged one step.
  Degradation,
};

/// How impurities change an edge's strength (thesis sec 5.2, eq 5.1).
enum class ImpurityMode : uint8_t {
  Degradation,  ///< Impurities weaken (damp wood, mud in asphalt).
  Upgradation,  ///< Impurities strengthen (copper in gold).
};
/// Distribution of the per-node impurity alpha_k (eq 5.2).
enum class ImpurityNoise : uint8_t {
  Gaussian,  ///< N(0, sigma^2), alpha_k != 0 (eq 5.2).
  Uniform,   ///< U(-sqrt(3) sigma, sqrt(3) sigma): the same variance.
};
/// Random-graph impurities of a fracturing body (thesis sec 5.2, SPEC §4). Each node k gets
/// alpha_k from `noise` with `seed` (a counter-based hash of (seed, k): the same on every
/// thread count and backend); an edge ij then has the break probability p_ij of eq 5.1 with
/// h of eq 5.3, computed from the nodes' CURRENT degree in the graph of unbroken edges
/// divided by their rest degree. It enters the stress criterion as an effective strength
/// (Kachanov's effective stress): the edge breaks when sigma_n >= sigma_th (1 - p_ij) /
/// (1 - p_ref), p_ref the pure, intact edge's p (0 when degrading, 1 - h(2) when upgrading).
/// So strengths fall as a neighbourhood breaks, and nothing is drawn per step: results do not
/// depend on the time step's draw count (docs/design.md "Impurities").
struct ImpuritySettings {
  bool enabled = false;
  ImpurityNoise noise = ImpurityNoise::Gaussian;
  ImpurityMode mode = ImpurityMode::Degradation;
  double sigma = 1;   ///< Standard deviation of alpha_k (>= 0, finite; 0 = only maps).
  uint64_t seed = 1;  ///< Seed of the draws.
  /// false: alpha and the degree term are ignored (no random graph): maps only scale the
  /// strengths they cover by their potency, the thesis's "without random graph" (fig 5.10).
  bool randomGraph = true;
};
/// An impurity map (thesis sec 5.4): edges it covers get strength * potency and their nodes
/// the impurity |alpha| = 1 / potency (more potent = weaker; 0 = a sharp pre-cut: the edges
/// break at the next step). Either polylines painted on the rest surface (a band `width` wide
/// and `depth` deep under each polyline), or 2D segments of an image projected through the
/// body along the image plane's normal (edges whose projection crosses a segment).
struct ImpurityMap {
  enum class Kind : uint8_t { Polyline, Image };
  Kind kind = Kind::Polyline;
  double potency = 0.5;  ///< >= 0 and finite; 0 = pre-cut, 1 = no static weakening.
  /// Polyline: points in rest coordinates, each within half a mean edge length of the rest
  /// surface. The band holds the edges whose midpoint lies within width / 2 across the line
  /// and `depth` under the surface.
  std::vector<glm::dvec3> points;
  double width = 0;  ///< Polyline: band width [m] (> 0).
  double depth = 0;  ///< Polyline: band depth under the surface [m] (> 0).
  /// Image: segment end points in image units (the image is 1 wide, centred on 0, v up), 2
  /// per segment; x = origin + scale * rotation * (u, v, 0) in rest coordinates.
  std::vector<glm::dvec2> segments;
  glm::dvec3 origin{0, 0, 0};
  glm::dquat rotation{1, 0, 0, 0};  ///< Image plane to rest frame (unit, or normalised).
  double scale = 1;                 ///< Image width in metres (> 0).
  /// Empty when valid; otherwise names the field ("potency: ...") and the reason. Whether
  /// points lie on the surface is checked against the body (World::applyImpurityMap).
  Result<void> check() const;
};
/// Graph-based fracture of a body (thesis ch. 4). Disabled by default: a body without
/// fracture computes no edge stresses.
struct FractureSettings {
  bool enabled = false;
  /// sigma_th [Pa]: an edge breaks at this tensile normal stress. With fibres and a
  /// fibreStrengthRatio != 1 it is the strength ACROSS the fibres (edges normal to them).
  double strength = 1e6;
  /// Along-fibre over across-fibre strength (> 0, finite; 1 = isotropic). An edge at angle
  /// theta to the fibre gets sigma_th r / (r sin^2 theta + cos^2 theta) (Hankinson 1921), so
  /// r > 1 makes the body split between its fibres (meat, wood); r < 1 is allowed. r != 1 needs
  /// fibres (material.fibreStiffness > 0); the direction is fibreField or material.fibreDirection.
  double fibreStrengthRatio = 1;
  /// Non-local averaging radius R_d in mean edge lengths (eq 4.10-4.12, the thesis's form);
  /// 0 = local. It shrinks with the mesh, so where stress concentrates (clamps, contact,
  /// notches) the first break still depends on the resolution; prefer nonlocalLength.
  double radius = 0;
  /// Non-local averaging radius in metres, a property of the material (about the size of
  /// its fracture process zone): each tet is judged on the mean stress of the tets within
  /// this distance, weighted by 1 - d / length and by rest volume, so the mean approximates
  /// an integral over the material and the load at which a body first breaks converges as
  /// the mesh is refined. > 0 replaces `radius` (setting both is an error); 0 = off. Cost and
  /// memory grow with (length / edge length)^3 per tet.
  double nonlocalLength = 0;
  DamageModel model = DamageModel::Degradation;
  /// Brittle mode (sec 4.5.1.2): when the criterion first fires, the `regions` most stressed
  /// regions each start a crack plane normal to the maximum principal stress.
  bool brittle = false;
  int regions = 1;
  /// Degradation model: release the severed edges (docs/design.md "Severed edges") after every
  /// batch of breaks (blade cuts, potency-0 pre-cuts, brittle planes), not only after the
  /// criterion's. Pieces that nothing holds together then come apart, so no render triangle is
  /// stretched across them, and every node whose tets are all split and that no blade cut out
  /// with others as a slice becomes a loose node (a one-node chip, FractureStats::chips): free
  /// matter that stays in the FEM world as a particle and is never handed to Bullet. Off, such
  /// pieces hang together by edges that hold nothing until the criterion breaks nearby.
  bool releaseEveryBatch = true;
  /// Where the render surface splits each broken edge; set once, when the edge breaks.
  SplitPoint splitPoint = SplitPoint::Midpoint;
  /// Random-graph impurities (thesis sec 5.2); off by default: then no work is added.
  ImpuritySettings impurities;
  /// Impurity maps applied when the body is created (World::applyImpurityMap adds more).
  /// Maps without `impurities.enabled` give only the map nodes an impurity.
  std::vector<ImpurityMap> impurityMaps;
  /// Empty when valid or disabled; otherwise names the field ("strength: ...") and the reason.
  Result<void> check() const;
};

/// Multiplicative plasticity F = Fe Fp (eq 2.3-2.5). Disabled by default: no Fp is stored.
struct PlasticitySettings {
  bool enabled = false;
  double yieldStress = 1e5;  ///< sigma_p [Pa]
  double flowRate = 1;       ///< v in eq 2.5, in [0, 1]
  double hardening = 0;      ///< K in eq 2.5 [1/s]
  /// Empty when valid or disabled; otherwise names the field ("yieldStress: ...") and the reason.
  Result<void> check() const;
};

/// Water in a porous body (thesis sec 7.2.1-7.2.2), used once a wet brush touches it
/// (World::wet): until then the body holds no water data and pays nothing. A tet's saturation
/// S_w in [0, 1] is its water mass over its capacity waterDensity * porosity * V_e; water
/// diffuses between face-neighbouring tets along the saturation gradient, and a tet's
/// elasticity is that of the body's material (the dry matrix) holding water inclusions of
/// volume fraction porosity * S_w (eq 7.1-7.4), so a wet region is smoothly softer.
struct WettingSettings {
  /// Pore volume fraction, in (0, 0.95]: the water volume fraction of a saturated tet.
  double porosity = 0.4;
  double waterDensity = 1000;  ///< rho_w [kg/m^3], > 0.
  /// Diffusivity D [m^2/s] (>= 0; 0 = water stays where the brush put it). A step of dt
  /// takes ceil(dt * D * max_e sum_f A_f / (d_f V_e)) explicit diffusion substeps over the
  /// tet's faces f (area A_f, centroid distance d_f), so fine meshes with a large D cost more.
  double diffusivity = 1e-4;
  /// Bulk modulus of the pore water [Pa] (>= 0). 0 (the default) is drained water, which
  /// flows out under load and carries no pressure: the wet material softens in bulk and
  /// shear. 2.2e9 is undrained water: shear softens, bulk stiffens.
  double waterBulkModulus = 0;
  /// Empty when valid; otherwise names the field ("porosity: ...") and the reason.
  Result<void> check() const;
};

/// Nodes whose velocity is prescribed: a pin (velocity 0) or a grip that pulls.
struct Grip {
  std::vector<int32_t> nodes;
  glm::vec3 velocity{0, 0, 0};  ///< [m/s], world frame.
};

/// A constant force on one node [N].
struct PointForce {
  int32_t node = 0;
  glm::vec3 force{0, 0, 0};
};

/// How a body is cut (World::cut).
enum class CutMode : uint8_t {
  /// Graph-based FEM (thesis ch. 4): a blade breaks the mesh edges it crosses, so the cut face
  /// follows the tets. Any setting of BodyDef applies.
  Graph,
  /// Is-XFEM (thesis ch. 3): a blade cuts through the tets and the cut face is the blade's own
  /// surface, at the price of enriched DOFs per cut (eq 3.4) and a CPU direct solve. For a few
  /// clean cuts on a small body. What such a body is:
  /// - linear (small-strain) elasticity with material.youngsModulus, poissonRatio and density
  ///   (material.model is not used: all four models share this limit at rest), stepped by the
  ///   linear implicit Euler step of eq 3.13 with the world's gravity and substep, solved by a
  ///   sparse Cholesky factor (solver settings are not used; a new substep length refactorises);
  /// - grips hold nodes still (velocity zero only; their standard and enriched DOFs stay at
  ///   rest), initialVelocity and World::setVelocity/setVelocities set the standard DOFs
  ///   (enriched ones to zero);
  /// - plane colliders only, met as hard frictionless contact of the render surface's vertices
  ///   (exact cut faces included) inside the implicit step (an LCP on the factorised system:
  ///   no penetration, no bounce); collider stiffness and friction do not apply;
  /// - World::cut adds the blade (static or swept, at most 32 per body, at most 4 through one
  ///   tet) at once, in the body's rest frame (the blade is carried back by the best-fit rigid
  ///   motion of the piece it meets); the next step reports it (FractureEvent with cause Cut and
  ///   `tet`, FragmentEvent per new piece);
  /// - pieces are its fragments (World::fractureStats, surface()'s vertexFragment);
  /// - fragment hand-off as for graph bodies (World::fragmentInfo, detachFragment,
  ///   setFragmentTransform; integration/bullet's Bridge): a piece's mass, centre, inertia and
  ///   momenta are exact moments of its own cells (its consistent mass against the DOFs); on
  ///   detach its cells leave the system (no mass, stiffness, load or contact; the enriched
  ///   functions reaching into them are held, and the velocity is the L2 projection of the old
  ///   field onto the functions left, which keeps the momentum exactly), so the rest steps on as
  ///   before, and its surface shows the rest surface at the rigid pose. Refused: a piece holding
  ///   gripped nodes, one already detached, and the last piece left in the system (the whole
  ///   body). World::positions still shows the detached piece's nodes where it left.
  /// It refuses (createBody names the field): fracture.enabled (no stress-driven fracture),
  /// plasticity.enabled, a fibre term or fibreField, Rayleigh damping, point forces, a grip with
  /// a velocity, contact (body-body), a renderMesh, and box, sphere or capsule colliders in the
  /// world (WorldDef.colliders; setColliders refuses them while such a body lives). Commands
  /// that would need what it lacks (setPositions, applyForce, applyImpulse, setMaterial, a grip
  /// velocity, sculpting brushes, snapshots) return an error.
  Xfem,
};

/// A body: its mesh, material, boundary conditions and solver settings.
struct BodyDef {
  TetMesh mesh;
  Material material;
  SolverSettings solver;
  std::vector<Grip> grips;
  std::vector<PointForce> forces;
  glm::vec3 initialVelocity{0, 0, 0};
  /// Coulomb friction coefficient of the body's surface (>= 0), mixed with a collider's as
  /// sqrt(friction * Collider::friction). Friction acts on the nodes in contact, opposite their
  /// sliding against the collider over the step, with the normal force of the step's start
  /// (lagged), smoothed below 1 mm/s of sliding so the implicit step stays smooth: a body
  /// resting on a slope steeper than its friction allows slides; on a gentler one it creeps
  /// at under (1 mm/s) tan(angle) / (2 mu).
  double friction = 0.6;
  /// Body-body and self contact (opt-in): the body's boundary (and, once it breaks, the
  /// surfaces of its fragments) pushes the other bodies that take part, and its fragments push
  /// each other, through a penalty in the implicit step (docs/design.md, "Body-body and self
  /// contact", with its limits: stacks of more than two bodies and coincident faces are not
  /// reliable yet). False, the default: the body meets only the colliders, at no cost.
  bool contact = false;
  FractureSettings fracture;
  PlasticitySettings plasticity;
  WettingSettings wetting;
  /// Optional per-tet rest-space fibre directions (one per tet) overriding
  /// material.fibreDirection; used only when material.fibreStiffness > 0.
  std::vector<glm::vec3> fibreField;
  /// Optional detailed mesh that World::surface returns instead of the tet boundary (see
  /// RenderMesh). World::createBody binds its vertices to the tets; a vertex farther from every
  /// tet than twice the longest tet edge is an error (wrong units or placement). Cost: nothing
  /// until World::surface is called, then O(render vertices) per rendered frame.
  std::optional<RenderMesh> renderMesh;
  /// How World::cut cuts the body; Graph by default (see CutMode for what Xfem supports).
  CutMode cutMode = CutMode::Graph;
  /// Everything World::createBody checks before it allocates: the mesh (validate()), the
  /// material, solver, fracture, plasticity and wetting settings, node indices of grips and
  /// forces, finite vectors, the fibre field, the render mesh's own fields (RenderMesh::check;
  /// where it lies against the tets is checked by createBody). Empty when valid; otherwise names
  /// the field ("grips[1].nodes: ...") and the reason.
  Result<void> check() const;
};

/// An obstacle; contact is a one-sided penalty whose energy enters the implicit step. A
/// collider with a velocity moves: each substep sees it at its end-of-substep pose (so it
/// pushes), and the world advances `point` by velocity * dt per step until the game replaces
/// it (World::setColliders). It is kinematic: World::colliderImpulses reports what it gave.
struct Collider {
  /// Capsule: the points within `radius` of a segment (a rounded edge: a striker, an anvil, a
  /// rod; Bullet's btCapsuleShape).
  enum class Kind : uint8_t { Plane, Box, Sphere, Capsule };
  Kind kind = Kind::Plane;
  glm::vec3 point{0, 0, 0};                 ///< Plane: a point on it; else the centre.
  glm::vec3 normal{0, 1, 0};                ///< Plane: outward normal.
  glm::vec3 halfExtents{0.5f, 0.5f, 0.5f};  ///< Box, along its own axes.
  float radius = 0.5f;                      ///< Sphere, Capsule.
  /// Capsule: half the length of its segment, which runs along the collider's own y axis
  /// (`rotation`) through `point`, as btCapsuleShape's does; 0 makes it a sphere.
  float halfLength = 0.5f;
  /// Penalty stiffness [N/m per node-mass kg]; 0 picks one from the time step so that a
  /// node is pushed out within about one step.
  double stiffness = 0;
  glm::vec3 velocity{0, 0, 0};     ///< Translation velocity [m/s].
  glm::quat rotation{1, 0, 0, 0};  ///< Box, Capsule: local-to-world rotation (normalised).
  /// Spin [rad/s] about `point`: friction measures a node's sliding against the surface's own
  /// velocity there, velocity + angularVelocity x (node - point), so a turning wheel or ball
  /// drags what it touches and rolls on it without slip. The world does not turn the pose by it
  /// (a game that turns a box or capsule sets `rotation` each step, as the Bullet bridge does).
  glm::vec3 angularVelocity{0, 0, 0};
  /// Coulomb friction coefficient of the collider's surface (>= 0). A body meets it with
  /// sqrt(friction * BodyDef::friction) (Box2D's rule). 0, the default, is frictionless.
  double friction = 0;
  /// Empty when valid; otherwise names the field ("stiffness: ...") and the reason. Finite
  /// values are also bounded (|point|, |velocity|, sizes <= 1e9 m, stiffness <= 1e18) so that
  /// the penalty energy and impulses stay finite.
  Result<void> check() const;
};

/// Which backend runs the bodies.
enum class Backend : uint8_t {
  /// The CPU in this version, also where a CUDA device is found (World::backendDescription
  /// says so): Cuda's device step is partial and not yet measured faster than the CPU.
  Auto,
  Cpu,  ///< The CPU, threaded through WorldDef::jobs.
  /// A CUDA device: each body's element pass, Newton matrix and linear solves (the rest on the
  /// CPU). Without a driver or device the world refuses to run, saying why (docs/design.md).
  Cuda,
};

/// A world: gravity, backend, threading, substeps and static colliders.
struct WorldDef {
  glm::vec3 gravity{0, -9.81f, 0};
  Backend backend = Backend::Auto;
  JobSystem* jobs = nullptr;  ///< Not owned; null = serial.
  int substeps = 1;           ///< Fixed internal substeps per step(dt).
  std::vector<Collider> colliders;
  /// Body contact (BodyDef::contact): how many times per substep, at most, the bodies that
  /// touch are stepped, each again from the substep's start against the others' latest
  /// end-of-step positions (block Jacobi), until no node moves by more than 1e-4 of a cell
  /// between two sweeps. 1: once, against the others' positions predicted at the step's start.
  /// A body's fracture is judged in the first sweep only and its plastic flow taken after the
  /// last. docs/design.md, Contact.
  int contactSweeps = 1;
  /// Body contact: each cluster of bodies that touch is stepped as one system, Newton on the
  /// sum of their potentials with every pair between them acting on both sides (exact action
  /// and reaction, re-linearised at each iterate, as the pieces of one body are), instead of
  /// each body against the others' lagged planes with their momenta evened out after. Such a
  /// step iterates to convergence. contactSweeps is not used then. docs/design.md, Contact.
  bool coupledContact = false;
  /// Empty when valid; otherwise names the field ("WorldDef.colliders[2].stiffness: ...") and
  /// the reason.
  Result<void> check() const;
};

}  // namespace gf
