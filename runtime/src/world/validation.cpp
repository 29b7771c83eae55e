// The checks of everything an engine hands the world: one routine per kind of input, used by the
// World, its commands and the scene loader alike. Messages name the field relative to the struct
// checked ("levels: ...") so each caller can prefix its own path.
#include "world/validation.h"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <glm/common.hpp>
#include <glm/vector_relational.hpp>
#include <string>

#include "graphfrac/defs.h"

namespace gf {

namespace {
using detail::bounded3;
using detail::finite3;
// Beyond this a collider's penalty energy k x^2 overflows: a unit mistake, not a scene.
constexpr double kMaxColliderStiffness = 1e18;
// Friction coefficients beyond this are a typo (rubber on rough concrete is about 1).
constexpr double kMaxFriction = 1e3;

bool positiveFinite(double v) { return std::isfinite(v) && v > 0; }
// Shortest readable form ("1e+06", "0.5", "inf"), not std::to_string's fixed six decimals.
std::string num(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}
}  // namespace

Result<void> Material::check() const {
  if (static_cast<unsigned>(model) > static_cast<unsigned>(MaterialModel::StableNeoHookean))
    return fail("material.model: unknown model ", std::to_string(static_cast<int>(model)));
  if (!positiveFinite(youngsModulus))
    return fail("material.youngsModulus: must be positive and finite, got ", num(youngsModulus));
  // nu -> 0.5 makes lambda (eq 4.29) infinite; nu <= -1 makes mu negative.
  if (!std::isfinite(poissonRatio) || poissonRatio <= -1.0 || poissonRatio >= 0.5)
    return fail("material.poissonRatio: must lie in (-1, 0.5), got ", num(poissonRatio));
  if (!positiveFinite(density))
    return fail("material.density: must be positive and finite, got ", num(density));
  if (!std::isfinite(fibreStiffness) || fibreStiffness < 0)
    return fail("material.fibreStiffness: must be >= 0 and finite, got ", num(fibreStiffness));
  if (fibreStiffness > 0) {
    const double len2 = double(fibreDirection.x) * fibreDirection.x +
                        double(fibreDirection.y) * fibreDirection.y +
                        double(fibreDirection.z) * fibreDirection.z;
    if (!std::isfinite(len2) || len2 < 1e-12)
      return fail("material.fibreDirection: must be a finite non-zero vector");
  }
  if (!std::isfinite(massDamping) || massDamping < 0)
    return fail("material.massDamping: must be >= 0 and finite, got ", num(massDamping));
  if (!std::isfinite(stiffnessDamping) || stiffnessDamping < 0)
    return fail("material.stiffnessDamping: must be >= 0 and finite, got ", num(stiffnessDamping));
  return {};
}

Result<void> MultigridSettings::check() const {
  for (size_t i = 0; i < levels.size(); ++i) {
    if (levels[i] < 1)
      return fail("levels[", std::to_string(i), "]: handle count ", std::to_string(levels[i]),
                  " is not positive");
    if (i > 0 && levels[i] <= levels[i - 1])
      return fail("levels[", std::to_string(i),
                  "]: handle counts must increase from coarse to fine", " (",
                  std::to_string(levels[i - 1]), " then ", std::to_string(levels[i]), ")");
  }
  if (static_cast<unsigned>(smoother) > static_cast<unsigned>(Smoother::Chebyshev))
    return fail("smoother: unknown smoother ", std::to_string(static_cast<int>(smoother)));
  if (preSweeps < 0 || postSweeps < 0 || preSweeps + postSweeps < 1)
    return fail("preSweeps, postSweeps: must be >= 0 and together >= 1 (got ",
                std::to_string(preSweeps), ", ", std::to_string(postSweeps), ")");
  if (coarsePreSweeps < -1 || coarsePostSweeps < -1)
    return fail("coarsePreSweeps, coarsePostSweeps: must be >= -1 (got ",
                std::to_string(coarsePreSweeps), ", ", std::to_string(coarsePostSweeps), ")");
  if (!(prolongationFilter >= 0 && prolongationFilter < 1))
    return fail("prolongationFilter: must be in [0, 1), got ", std::to_string(prolongationFilter));
  if (cycles < 1) return fail("cycles: must be >= 1, got ", std::to_string(cycles));
  if (coarseRefreshInterval < 0)
    return fail("coarseRefreshInterval: must be >= 0 (0: chosen), got ",
                std::to_string(coarseRefreshInterval));
  if (coarseRefreshSlack < 0)
    return fail("coarseRefreshSlack: must be >= 0, got ", std::to_string(coarseRefreshSlack));
  if (directBelowNodes < 0)
    return fail("directBelowNodes: must be >= 0, got ", std::to_string(directBelowNodes));
  return {};
}

Result<void> SolverSettings::check() const {
  if (newtonIterations < 1)
    return fail("newtonIterations: must be >= 1, got ", std::to_string(newtonIterations));
  if (!positiveFinite(newtonTolerance))
    return fail("newtonTolerance: must be positive and finite, got ", num(newtonTolerance));
  if (!(numericalDamping >= 0 && numericalDamping <= 1))
    return fail("numericalDamping: must lie in [0, 1], got ", num(numericalDamping));
  if (static_cast<unsigned>(linearSolver) > static_cast<unsigned>(LinearSolverKind::Multigrid))
    return fail("linearSolver: unknown solver ", std::to_string(static_cast<int>(linearSolver)));
  if (maxLinearIterations < 1)
    return fail("maxLinearIterations: must be >= 1, got ", std::to_string(maxLinearIterations));
  if (!positiveFinite(linearTolerance))
    return fail("linearTolerance: must be positive and finite, got ", num(linearTolerance));
  if (linearSolver == LinearSolverKind::Multigrid)
    if (Result<void> r = multigrid.check(); !r) return fail("multigrid.", r.error().message);
  return {};
}

Result<void> FractureSettings::check() const {
  if (!enabled) return {};
  if (!positiveFinite(strength))
    return fail("strength: must be a positive finite stress, got ", num(strength));
  if (!positiveFinite(fibreStrengthRatio))
    return fail("fibreStrengthRatio: must be positive and finite, got ", num(fibreStrengthRatio));
  if (!(std::isfinite(radius) && radius >= 0))
    return fail("radius: must be >= 0 and finite, got ", num(radius));
  if (!(std::isfinite(nonlocalLength) && nonlocalLength >= 0 &&
        nonlocalLength <= detail::kMaxMagnitude))
    return fail("nonlocalLength: must be >= 0 and at most 1e9 m, got ", num(nonlocalLength));
  if (nonlocalLength > 0 && radius > 0)
    return fail(
        "nonlocalLength: set either nonlocalLength (metres) or radius (edge lengths), not "
        "both (got ",
        num(nonlocalLength), " m and ", num(radius), ")");
  if (static_cast<unsigned>(model) > static_cast<unsigned>(DamageModel::Degradation))
    return fail("model: unknown damage model ", std::to_string(static_cast<int>(model)));
  if (regions < 1) return fail("regions: must be >= 1, got ", std::to_string(regions));
  if (static_cast<unsigned>(splitPoint) > static_cast<unsigned>(SplitPoint::ForceRatio))
    return fail("splitPoint: unknown split point ", std::to_string(static_cast<int>(splitPoint)));
  if (static_cast<unsigned>(impurities.noise) > static_cast<unsigned>(ImpurityNoise::Uniform))
    return fail("impurities.noise: unknown distribution ",
                std::to_string(static_cast<int>(impurities.noise)));
  if (static_cast<unsigned>(impurities.mode) > static_cast<unsigned>(ImpurityMode::Upgradation))
    return fail("impurities.mode: unknown mode ",
                std::to_string(static_cast<int>(impurities.mode)));
  if (!(std::isfinite(impurities.sigma) && impurities.sigma >= 0 && impurities.sigma <= 1e9))
    return fail("impurities.sigma: must be >= 0 and finite (at most 1e9), got ",
                num(impurities.sigma));
  for (size_t i = 0; i < impurityMaps.size(); ++i)
    if (auto r = impurityMaps[i].check(); !r)
      return fail("impurityMaps[", std::to_string(i), "].", r.error().message);
  return {};
}

Result<void> ImpurityMap::check() const {
  if (!(std::isfinite(potency) && potency >= 0 && potency <= 1))
    return fail("potency: must lie in [0, 1] (0 = a sharp pre-cut, 1 = no weakening), got ",
                num(potency));
  if (kind == Kind::Polyline) {
    if (points.size() < 2)
      return fail("points: a polyline needs at least 2 points, got ",
                  std::to_string(points.size()));
    for (size_t i = 0; i < points.size(); ++i)
      if (!(glm::all(glm::lessThanEqual(glm::abs(points[i]), glm::dvec3(detail::kMaxMagnitude)))))
        return fail("points[", std::to_string(i), "]: must be finite, at most 1e9 m");
    if (!(positiveFinite(width) && width <= detail::kMaxMagnitude))
      return fail("width: must be a positive finite length, got ", num(width));
    if (!(positiveFinite(depth) && depth <= detail::kMaxMagnitude))
      return fail("depth: must be a positive finite length, got ", num(depth));
    return {};
  }
  if (kind != Kind::Image)
    return fail("kind: unknown map kind ", std::to_string(static_cast<int>(kind)));
  if (segments.empty() || segments.size() % 2 != 0)
    return fail("segments: expected a non-empty list of end-point pairs, got ",
                std::to_string(segments.size()), " points");
  for (size_t i = 0; i < segments.size(); ++i)
    if (!(std::isfinite(segments[i].x) && std::isfinite(segments[i].y)))
      return fail("segments[", std::to_string(i), "]: must be finite");
  if (!(glm::all(glm::lessThanEqual(glm::abs(origin), glm::dvec3(detail::kMaxMagnitude)))))
    return fail("origin: must be finite, at most 1e9 m");
  const double qn = rotation.w * rotation.w + rotation.x * rotation.x + rotation.y * rotation.y +
                    rotation.z * rotation.z;
  if (!(std::isfinite(qn) && qn > 1e-12))
    return fail("rotation: must be a finite, non-zero quaternion");
  if (!(positiveFinite(scale) && scale <= detail::kMaxMagnitude))
    return fail("scale: must be a positive finite length (the image width in metres), got ",
                num(scale));
  return {};
}

Result<void> PlasticitySettings::check() const {
  if (!enabled) return {};
  if (!positiveFinite(yieldStress))
    return fail("yieldStress: must be positive and finite, got ", num(yieldStress));
  if (!(flowRate >= 0 && flowRate <= 1))
    return fail("flowRate: must lie in [0, 1], got ", num(flowRate));
  if (!(std::isfinite(hardening) && hardening >= 0))
    return fail("hardening: must be >= 0 and finite, got ", num(hardening));
  return {};
}

Result<void> WettingSettings::check() const {
  if (!(porosity > 0 && porosity <= 0.95))
    return fail("porosity: must lie in (0, 0.95], got ", num(porosity));
  if (!(positiveFinite(waterDensity) && waterDensity <= 1e6))
    return fail("waterDensity: must be positive, at most 1e6 kg/m^3, got ", num(waterDensity));
  if (!(std::isfinite(diffusivity) && diffusivity >= 0 && diffusivity <= 1e3))
    return fail("diffusivity: must lie in [0, 1e3] m^2/s, got ", num(diffusivity));
  if (!(std::isfinite(waterBulkModulus) && waterBulkModulus >= 0 && waterBulkModulus <= 1e15))
    return fail("waterBulkModulus: must lie in [0, 1e15] Pa, got ", num(waterBulkModulus));
  return {};
}

Result<void> Collider::check() const {
  if (kind != Kind::Plane && kind != Kind::Box && kind != Kind::Sphere && kind != Kind::Capsule)
    return fail("kind: ", std::to_string(static_cast<int>(kind)), " is not a Collider::Kind");
  if (!bounded3(point)) return fail("point: must be finite, within 1e9 m of the origin");
  if (!bounded3(velocity)) return fail("velocity: must be finite, at most 1e9 m/s");
  if (!bounded3(angularVelocity)) return fail("angularVelocity: must be finite, at most 1e9 rad/s");
  if (!(std::isfinite(stiffness) && stiffness >= 0 && stiffness <= kMaxColliderStiffness))
    return fail("stiffness: must lie in [0, 1e18] (0 picks one from the time step), got ",
                num(stiffness));
  if (!(std::isfinite(friction) && friction >= 0 && friction <= kMaxFriction))
    return fail("friction: must lie in [0, 1e3], got ", num(friction));
  if (kind == Kind::Plane) {
    const double len2 =
        double(normal.x) * normal.x + double(normal.y) * normal.y + double(normal.z) * normal.z;
    if (!(finite3(normal) && std::isfinite(len2) && len2 > 1e-24))
      return fail("normal: must be finite and non-zero");
  }
  if (kind == Kind::Box &&
      !(bounded3(halfExtents) && halfExtents.x > 0 && halfExtents.y > 0 && halfExtents.z > 0))
    return fail("halfExtents: must be positive and at most 1e9 m");
  if (kind == Kind::Capsule &&
      !(std::isfinite(halfLength) && halfLength >= 0 && halfLength <= detail::kMaxMagnitude))
    return fail("halfLength: must lie in [0, 1e9] m (0 is a sphere), got ", num(halfLength));
  if (kind == Kind::Box || kind == Kind::Capsule) {
    const double q2 = double(rotation.x) * rotation.x + double(rotation.y) * rotation.y +
                      double(rotation.z) * rotation.z + double(rotation.w) * rotation.w;
    if (!(std::isfinite(q2) && q2 > 1e-24))
      return fail("rotation: must be a finite non-zero quaternion");
  }
  if ((kind == Kind::Sphere || kind == Kind::Capsule) &&
      !(std::isfinite(radius) && radius > 0 && radius <= detail::kMaxMagnitude))
    return fail("radius: must be positive and at most 1e9 m, got ", num(radius));
  return {};
}

Result<void> WorldDef::check() const {
  if (substeps < 1) return fail("WorldDef.substeps: must be >= 1, got ", std::to_string(substeps));
  if (contactSweeps < 1 || contactSweeps > 64)
    return fail("WorldDef.contactSweeps: must be in [1, 64], got ", std::to_string(contactSweeps));
  if (!finite3(gravity)) return fail("WorldDef.gravity: must be finite");
  switch (backend) {
    case Backend::Auto:
    case Backend::Cpu:
    case Backend::Cuda:  // whether it can run is World's to find out (World::backend)
      break;
    default:
      return fail("WorldDef.backend: unknown backend ", std::to_string(static_cast<int>(backend)));
  }
  for (size_t i = 0; i < colliders.size(); ++i)
    if (Result<void> r = colliders[i].check(); !r)
      return fail("WorldDef.colliders[", std::to_string(i), "].", r.error().message);
  return {};
}

namespace detail {
// BodyDef::check without the mesh, for World::createBody, which validates (and repairs) the
// mesh itself.
Result<void> checkBodySettings(const BodyDef& def) {
  if (auto r = def.material.check(); !r) return r;
  if (auto r = def.solver.check(); !r) return fail("solver.", r.error().message);
  if (auto r = def.fracture.check(); !r) return fail("fracture.", r.error().message);
  if (!def.fracture.enabled &&
      (def.fracture.impurities.enabled || !def.fracture.impurityMaps.empty()))
    return fail("fracture.impurities: impurities and impurity maps need fracture.enabled");
  if (def.fracture.enabled && def.fracture.fibreStrengthRatio != 1 &&
      !(def.material.fibreStiffness > 0))
    return fail("fracture.fibreStrengthRatio: ", num(def.fracture.fibreStrengthRatio),
                " needs fibres (material.fibreStiffness > 0); use 1 for an isotropic strength");
  if (auto r = def.plasticity.check(); !r) return fail("plasticity.", r.error().message);
  if (auto r = def.wetting.check(); !r) return fail("wetting.", r.error().message);
  const int64_t nn = int64_t(def.mesh.nodeCount());
  for (size_t g = 0; g < def.grips.size(); ++g) {
    if (!bounded3(def.grips[g].velocity))
      return fail("grips[", std::to_string(g), "].velocity: must be finite, at most 1e9 m/s");
    for (int32_t n : def.grips[g].nodes)
      if (n < 0 || n >= nn)
        return fail("grips[", std::to_string(g), "].nodes: node ", std::to_string(n),
                    " out of range [0, ", std::to_string(nn), ")");
  }
  for (size_t f = 0; f < def.forces.size(); ++f) {
    if (def.forces[f].node < 0 || def.forces[f].node >= nn)
      return fail("forces[", std::to_string(f), "].node: ", std::to_string(def.forces[f].node),
                  " out of range [0, ", std::to_string(nn), ")");
    if (!finite3(def.forces[f].force))
      return fail("forces[", std::to_string(f), "].force: not finite");
  }
  if (!bounded3(def.initialVelocity))
    return fail("initialVelocity: must be finite, at most 1e9 m/s");
  if (!(std::isfinite(def.friction) && def.friction >= 0 && def.friction <= kMaxFriction))
    return fail("friction: must lie in [0, 1e3], got ", num(def.friction));
  if (!def.fibreField.empty()) {
    if (def.fibreField.size() != def.mesh.tetCount())
      return fail("fibreField: expected one direction per tet (",
                  std::to_string(def.mesh.tetCount()), "), got ",
                  std::to_string(def.fibreField.size()));
    for (size_t t = 0; t < def.fibreField.size(); ++t) {
      const glm::vec3 f = def.fibreField[t];
      if (!finite3(f) || double(f.x) * f.x + double(f.y) * f.y + double(f.z) * f.z < 1e-12)
        return fail("fibreField[", std::to_string(t), "]: must be finite and non-zero");
    }
  }
  if (def.renderMesh) {
    if (auto r = def.renderMesh->check(); !r) return fail("renderMesh.", r.error().message);
  }
  return checkCutMode(def);
}

// What a body in CutMode::Xfem cannot honour (defs.h, CutMode): each names the field.
Result<void> checkCutMode(const BodyDef& def) {
  if (def.cutMode != CutMode::Graph && def.cutMode != CutMode::Xfem)
    return fail("cutMode: unknown cut mode ", std::to_string(static_cast<int>(def.cutMode)));
  if (def.cutMode == CutMode::Graph) return {};
  const auto refuse = [](const char* field, const char* why) {
    return fail(field, ": ", why, " (cutMode Xfem: linear elasticity, cuts by World::cut only)");
  };
  if (def.fracture.enabled)
    return refuse("fracture.enabled", "an Is-XFEM body has no stress-driven fracture");
  if (def.plasticity.enabled)
    return refuse("plasticity.enabled", "an Is-XFEM body has no plasticity");
  if (def.material.fibreStiffness != 0)
    return refuse("material.fibreStiffness", "an Is-XFEM body is isotropic");
  if (!def.fibreField.empty()) return refuse("fibreField", "an Is-XFEM body is isotropic");
  if (def.material.massDamping != 0 || def.material.stiffnessDamping != 0)
    return refuse(
        def.material.massDamping != 0 ? "material.massDamping" : "material.stiffnessDamping",
        "an Is-XFEM body has no Rayleigh damping");
  if (!def.forces.empty()) return refuse("forces", "an Is-XFEM body takes no point forces");
  for (size_t g = 0; g < def.grips.size(); ++g)
    if (def.grips[g].velocity != glm::vec3(0))
      return fail("grips[", std::to_string(g),
                  "].velocity: an Is-XFEM body holds its grips still (velocity 0 only) "
                  "(cutMode Xfem)");
  if (def.contact) return refuse("contact", "an Is-XFEM body meets plane colliders only");
  if (def.renderMesh) return refuse("renderMesh", "an Is-XFEM body renders its cut surface");
  return {};
}
}  // namespace detail

Result<void> RenderMesh::check() const {
  const size_t nv = positions.size() / 3;
  if (positions.empty()) return fail("positions: empty");
  if (positions.size() % 3 != 0)
    return fail("positions: ", std::to_string(positions.size()), " values, not 3 per vertex");
  // Vertex ids become int32 in the surface's per-vertex tables.
  if (nv > size_t(INT32_MAX / 2))
    return fail("positions: ", std::to_string(nv), " vertices, more than ",
                std::to_string(INT32_MAX / 2));
  if (indices.empty()) return fail("indices: empty (no triangles)");
  if (indices.size() % 3 != 0)
    return fail("indices: ", std::to_string(indices.size()), " values, not 3 per triangle");
  if (!normals.empty() && normals.size() != positions.size())
    return fail("normals: ", std::to_string(normals.size()), " values for ", std::to_string(nv),
                " vertices (3 per vertex, or empty)");
  if (!uvs.empty() && uvs.size() != 2 * nv)
    return fail("uvs: ", std::to_string(uvs.size()), " values for ", std::to_string(nv),
                " vertices (2 per vertex, or empty)");
  if (!materials.empty() && materials.size() != indices.size() / 3)
    return fail("materials: ", std::to_string(materials.size()), " ids for ",
                std::to_string(indices.size() / 3), " triangles (1 per triangle, or empty)");
  for (size_t t = 0; t < materials.size(); ++t)
    if (materials[t] == kInteriorMaterial)
      return fail("materials[", std::to_string(t), "]: ", std::to_string(kInteriorMaterial),
                  " is reserved for crack faces");
  for (size_t i = 0; i < positions.size(); ++i)
    if (!std::isfinite(positions[i]) || std::fabs(positions[i]) > 1e9)
      return fail("positions[", std::to_string(i / 3), "]: not finite or beyond 1e9 m");
  for (size_t i = 0; i < nv && !normals.empty(); ++i) {
    const float* n = &normals[3 * i];
    if (!std::isfinite(n[0]) || !std::isfinite(n[1]) || !std::isfinite(n[2]))
      return fail("normals[", std::to_string(i), "]: not finite");
    if (double(n[0]) * n[0] + double(n[1]) * n[1] + double(n[2]) * n[2] < 1e-12)
      return fail("normals[", std::to_string(i), "]: zero length");
  }
  for (size_t i = 0; i < uvs.size(); ++i)
    if (!std::isfinite(uvs[i])) return fail("uvs[", std::to_string(i / 2), "]: not finite");
  for (size_t k = 0; k < indices.size(); ++k)
    if (indices[k] >= nv)
      return fail("indices[", std::to_string(k), "]: vertex ", std::to_string(indices[k]),
                  " out of range [0, ", std::to_string(nv), ")");
  return {};
}

Result<void> BodyDef::check() const {
  if (mesh.tetCount() == 0) return fail("mesh: has no tetrahedra");
  TetMesh copy = mesh;  // validate() repairs flipped tets; a check must not change the def
  if (auto r = validate(copy, "mesh"); !r) return r;
  return detail::checkBodySettings(*this);
}

}  // namespace gf
