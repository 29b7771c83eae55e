// World: the hand-off of fragments to rigid-body physics (integration/bullet). A detached
// fragment's nodes leave the FEM solve and move as the game's rigid body says.
#include <algorithm>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <string>
#include <vector>

#include "world/rigid_fragment.h"
#include "world/world_impl.h"

namespace gf {

namespace {
using detail::toGlm;
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

// Marks the tets whose nodes all lie in detached fragments (FemState::rigidTet) and whether
// the whole body is rigid now.
void markRigidTets(BodyRecord& b) {
  const std::span<const int32_t> fragmentOf = b.fracture->fragments().nodeFragment();
  std::vector<uint8_t> rigidNode(fragmentOf.size(), 0);
  for (size_t n = 0; n < fragmentOf.size(); ++n)
    rigidNode[n] = detachedCentre(b, fragmentOf[n]) != nullptr;
  const detail::FemModel& m = b.model;
  std::vector<uint8_t>& rigidTet = b.state.rigidTet;
  rigidTet.assign(size_t(m.tetCount), 0);
  for (int32_t t = 0; t < m.tetCount; ++t)
    rigidTet[size_t(t)] =
        rigidNode[size_t(m.tets[4 * t])] && rigidNode[size_t(m.tets[4 * t + 1])] &&
        rigidNode[size_t(m.tets[4 * t + 2])] && rigidNode[size_t(m.tets[4 * t + 3])];
  b.allRigid = std::all_of(rigidNode.begin(), rigidNode.end(), [](uint8_t r) { return r != 0; });
}

// Prescribes the rigid velocity field v + w x (x - c) on a detached fragment's nodes (the
// integrator moves them by it and reports it as their velocity).
void setRigidVelocities(BodyRecord& b, int32_t fragment, glm::dvec3 v, glm::dvec3 w, glm::dvec3 c) {
  detail::FemState& s = b.state;
  for (int32_t n : b.fracture->fragments().nodes(fragment)) {
    const glm::dvec3 x(s.x[3 * n], s.x[3 * n + 1], s.x[3 * n + 2]);
    const glm::dvec3 vn = v + glm::cross(w, x - c);
    for (int i = 0; i < 3; ++i) s.gripVelocity[3 * n + i] = s.v[3 * n + i] = vn[i];
    s.movingGrips |= vn != glm::dvec3(0);
  }
}
}  // namespace

Result<RigidFragmentInfo> World::fragmentInfo(BodyId id, int32_t fragment) const {
  const BodyRecord* b = m_impl->get(id);
  if (b && b->xfem) return detail::xfemFragmentInfo(*b, "fragmentInfo", fragment);
  if (std::string e = checkFragment(b, "fragmentInfo", fragment); !e.empty()) return fail(e);
  const detail::RigidProperties p = detail::rigidProperties(
      b->model, b->state, b->fracture->fragments().nodeFragment().data(), fragment);
  return toInfo(p);
}

Result<RigidFragmentInfo> World::detachFragment(BodyId id, int32_t fragment) {
  if (std::string e = m_impl->busy("detachFragment"); !e.empty()) return fail(e);
  BodyRecord* b = m_impl->get(id);
  RigidFragmentInfo info;
  if (b && b->xfem) {
    Result<RigidFragmentInfo> detached = detail::detachXfemPiece(*b, fragment);
    if (!detached) return detached.error();
    info = detached.value();
  } else {
    if (std::string e = checkFragment(b, "detachFragment", fragment); !e.empty()) return fail(e);
    if (detachedCentre(*b, fragment))
      return fail("detachFragment: fragment ", std::to_string(fragment), " is already detached");
    const detail::RigidProperties p = detail::rigidProperties(
        b->model, b->state, b->fracture->fragments().nodeFragment().data(), fragment);
    if (p.hasFixedNode)
      return fail("detachFragment: fragment ", std::to_string(fragment),
                  " holds gripped nodes (BodyDef.grips); a pinned piece cannot move rigidly");
    if (!(p.mass > 0))
      return fail("detachFragment: fragment ", std::to_string(fragment), " has no mass");
    info = toInfo(p);
    for (int32_t n : b->fracture->fragments().nodes(fragment)) b->state.fixedNode[size_t(n)] = 1;
    setRigidVelocities(*b, fragment, info.linearVelocity, info.angularVelocity, info.centreOfMass);
    b->integrator->refreshFixedNodes(b->model, b->state);
    b->rigid.emplace_back(fragment, p.restCentre);
    markRigidTets(*b);
  }

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
  if (!(b && b->xfem)) {
    if (std::string e = checkFragment(b, "setFragmentTransform", fragment); !e.empty())
      return fail(e);
    if (!detachedCentre(*b, fragment))
      return fail("setFragmentTransform: fragment ", std::to_string(fragment),
                  " is not detached (call detachFragment first)");
  }
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
  if (b->xfem) {
    Mat3 Rm;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) Rm(i, j) = R[j][i];
    return detail::setXfemPieceTransform(
        *b, fragment, Rm, Vec3{translation.x, translation.y, translation.z},
        Vec3{linearVelocity.x, linearVelocity.y, linearVelocity.z},
        Vec3{angularVelocity.x, angularVelocity.y, angularVelocity.z});
  }
  const Vec3* restCentre = detachedCentre(*b, fragment);
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

}  // namespace gf
