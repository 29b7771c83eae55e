// World: the commands a game issues between steps (positions, velocities, forces, impulses,
// grips, strengths, material, cuts, colliders). Each validates first and changes nothing on an
// error.
#include <algorithm>
#include <glm/geometric.hpp>
#include <limits>
#include <string>
#include <vector>

#include "world/world_impl.h"

namespace gf {

namespace {
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

// The error of a command an Is-XFEM body cannot honour (BodyDef::cutMode), or empty.
std::string xfemRefuses(const BodyRecord* b, const char* call) {
  return b && b->xfem ? std::string(call) +
                            ": not supported for a body in CutMode::Xfem (BodyDef.cutMode); "
                            "nothing changed"
                      : std::string();
}

// An Is-XFEM body's standard velocities from its nodes' (enriched ones to zero), gripped
// nodes held.
void setXfemVelocity(BodyRecord& b) {
  Eigen::VectorXd& v = b.xfem->body->velocity();
  v.setZero();
  for (size_t i = 0; i < b.state.v.size(); ++i) v[Eigen::Index(i)] = b.state.v[i];
  for (const Grip& g : b.grips)
    for (int32_t n : g.nodes) v.segment(3 * Eigen::Index(n), 3).setZero();
  for (size_t i = 0; i < b.state.v.size(); ++i) b.state.v[i] = v[Eigen::Index(i)];
}

}  // namespace

Result<void> World::setVelocity(BodyId id, glm::dvec3 v) {
  BodyRecord* b = m_impl->get(id);
  if (std::string e = m_impl->busy("setVelocity"); !e.empty()) return fail(e);
  if (!b) return fail("setVelocity: stale or null BodyId");
  if (!bounded3(glm::vec3(v))) return fail("setVelocity: velocity must be finite, at most 1e9 m/s");
  for (size_t i = 0; i < b->state.v.size(); ++i) b->state.v[i] = v[int(i % 3)];
  if (b->xfem) setXfemVelocity(*b);
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
  if (std::string e = xfemRefuses(b, "setPositions"); !e.empty()) return fail(e);
  if (Result<void> r = overwrite(b->state.x, x, "setPositions", "m"); !r) return r;
  b->surfaceStale = true;
  b->stepEndValid = false;
  return {};
}

Result<void> World::setVelocities(BodyId id, std::span<const double> v) {
  BodyRecord* b = m_impl->get(id);
  if (std::string e = m_impl->busy("setVelocities"); !e.empty()) return fail(e);
  if (!b) return fail("setVelocities: stale or null BodyId");
  if (Result<void> r = overwrite(b->state.v, v, "setVelocities", "m/s"); !r) return r;
  if (b->xfem) setXfemVelocity(*b);
  return {};
}

Result<void> World::cut(BodyId id, const Blade& blade) {
  BodyRecord* b = m_impl->get(id);
  if (std::string e = m_impl->busy("cut"); !e.empty()) return fail(e);
  if (!b) return fail("cut: stale or null BodyId");
  if (!b->fracture && !b->xfem)
    return fail("cut: the body was created without fracture (BodyDef.fracture)");
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
  if (b->xfem) return m_impl->cutXfem(id, *b, blade);
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
  if (std::string e = xfemRefuses(b, "applyForce"); !e.empty()) return fail(e);
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
  if (std::string e = xfemRefuses(b, "applyImpulse"); !e.empty()) return fail(e);
  int32_t corner[4];
  double w[4];
  if (!pointWeights(b->model, b->state.x, glm::dvec3(point), corner, w))
    return fail("applyImpulse: the body has no tet of non-zero volume to apply the impulse to");
  for (int k = 0; k < 4; ++k) {
    const double m = b->state.nodeMass[corner[k]];
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
  if (b->xfem && velocity != glm::vec3(0))
    return fail(
        "setGripVelocity: a body in CutMode::Xfem holds its grips still (velocity 0 "
        "only); nothing changed");
  detail::FemState& s = b->state;
  for (int32_t n : b->grips[size_t(grip)].nodes)
    for (int i = 0; i < 3; ++i) s.gripVelocity[3 * n + i] = velocity[i];
  s.movingGrips =
      std::any_of(s.gripVelocity.begin(), s.gripVelocity.end(), [](double v) { return v != 0; });
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

Result<void> World::applyImpurityMap(BodyId id, const ImpurityMap& map) {
  if (std::string e = m_impl->busy("applyImpurityMap"); !e.empty()) return fail(e);
  BodyRecord* b = m_impl->get(id);
  if (!b) return fail("applyImpurityMap: stale or null BodyId");
  if (!b->fracture)
    return fail("applyImpurityMap: the body was created without fracture (BodyDef.fracture)");
  if (auto r = map.check(); !r) return fail("applyImpurityMap: map.", r.error().message);
  if (auto r = b->fracture->applyImpurityMap(b->model, map); !r)
    return fail("applyImpurityMap: map.", r.error().message);
  return {};
}

Result<void> World::setMaterial(BodyId id, const Material& material) {
  if (std::string e = m_impl->busy("setMaterial"); !e.empty()) return fail(e);
  BodyRecord* b = m_impl->get(id);
  if (!b) return fail("setMaterial: stale or null BodyId");
  if (std::string e = xfemRefuses(b, "setMaterial"); !e.empty()) return fail(e);
  if (auto r = material.check(); !r) return fail("setMaterial: ", r.error().message);
  detail::FemState& s = b->state;
  if (material.model != s.material.model)
    return fail("setMaterial: material.model must stay the body's model (",
                std::to_string(int(s.material.model)), "), got ",
                std::to_string(int(material.model)));
  if ((material.fibreStiffness > 0) != (s.material.fibreStiffness > 0))
    return fail(
        "setMaterial: material.fibreStiffness must stay zero or non-zero as at creation (the "
        "fibre field and fibre strengths are built once)");
  const bool newDensity = material.density != s.material.density;
  s.material = material;
  s.coeffs = detail::toCoeffs(material);
  if (newDensity) detail::lumpMasses(b->model, material.density, s.nodeMass);
  if (b->wetting && !s.water.empty())
    detail::refreshWetStiffness(b->model, *b->wetting, s, *m_impl->jobs);
  return {};
}

}  // namespace gf
