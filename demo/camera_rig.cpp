// See camera_rig.h. The smoothing is the exact solution of a critically damped spring over the
// frame (x'' = -w^2 (x - g) - 2 w x', w = 2 / smoothSeconds), so it is stable at any frame
// length and never overshoots the goal; the caps then shorten a step that would still swing
// the view or zoom faster than allowed (and stop the spring's velocity there, so it does not
// pile up).
#include "camera_rig.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <numbers>

namespace gf::demo {
namespace {

constexpr double kDegree = std::numbers::pi / 180;

/// One exact step of the critically damped spring towards `goal`.
template <class T>
void dampTowards(T& x, T& v, const T& goal, double omega, double dt) {
  const T offset = x - goal;
  const T temp = (v + omega * offset) * dt;
  const double decay = std::exp(-omega * dt);
  x = goal + (offset + temp) * decay;
  v = (v - omega * temp) * decay;
}

}  // namespace

void Bounds::add(const glm::dvec3& p) {
  lo = glm::min(lo, p);
  hi = glm::max(hi, p);
}

void Bounds::add(const Bounds& b) {
  if (b.empty()) return;
  add(b.lo);
  add(b.hi);
}

CameraRig::CameraRig(const Camera& start, const FollowSettings& settings, double aspect)
    : m_camera(start), m_settings(settings), m_aspect(aspect) {
  m_target = glm::dvec3(start.target);
  const glm::dvec3 back = glm::dvec3(start.eye) - m_target;
  m_distance = std::max(glm::length(back), 1e-6);
  m_back = back / m_distance;
}

bool CameraRig::goal(std::span<const Bounds> bounds, glm::dvec3& target, double& distance) const {
  Bounds all;
  for (const Bounds& b : bounds) all.add(b);
  if (all.empty()) return false;
  target = 0.5 * (all.lo + all.hi);
  // Camera axes: forward looks from the eye to the target.
  const glm::dvec3 forward = -m_back;
  const glm::dvec3 right = glm::normalize(glm::cross(forward, glm::dvec3(m_camera.up)));
  const glm::dvec3 up = glm::cross(right, forward);
  const double tanV = std::tan(0.5 * double(m_camera.fovYDegrees) * kDegree) * m_settings.fill;
  const double tanH = tanV * m_aspect;
  // A corner at (x, y) across and z along the view from the target lies inside the framed
  // share when |x| <= (d + z) tanH and |y| <= (d + z) tanV.
  distance = 1e-3;
  for (int k = 0; k < 8; ++k) {
    const glm::dvec3 c(k & 1 ? all.hi.x : all.lo.x, k & 2 ? all.hi.y : all.lo.y,
                       k & 4 ? all.hi.z : all.lo.z);
    const glm::dvec3 r = c - target;
    const double z = glm::dot(r, forward);
    distance = std::max(
        {distance, std::abs(glm::dot(r, right)) / tanH - z, std::abs(glm::dot(r, up)) / tanV - z});
  }
  return true;
}

void CameraRig::place() {
  m_camera.target = glm::vec3(m_target);
  m_camera.eye = glm::vec3(m_target + m_distance * m_back);
}

Camera CameraRig::snap(std::span<const Bounds> bounds) {
  goal(bounds, m_target, m_distance);
  m_targetVelocity = glm::dvec3(0);
  m_distanceVelocity = 0;
  place();
  return m_camera;
}

Camera CameraRig::update(std::span<const Bounds> bounds, double dt) {
  glm::dvec3 target;
  double distance = 0;
  if (!goal(bounds, target, distance) || !(dt > 0)) return m_camera;
  const double omega = 2 / m_settings.smoothSeconds;
  const glm::dvec3 oldTarget = m_target;
  const double oldDistance = m_distance;
  dampTowards(m_target, m_targetVelocity, target, omega, dt);
  dampTowards(m_distance, m_distanceVelocity, distance, omega, dt);

  // Zoom: the picture's scale changes by a bounded share per frame, so a shattering body widens
  // the view over several frames instead of at once.
  const double maxScale = m_settings.maxZoomPerFrame;
  const double lo = oldDistance / (1 + maxScale), hi = oldDistance * (1 + maxScale);
  if (m_distance < lo || m_distance > hi) {
    m_distance = std::clamp(m_distance, lo, hi);
    m_distanceVelocity = (m_distance - oldDistance) / dt;
  }
  // Swing: seen from the new eye, the old target lies `across` the line of sight at a depth of
  // the distance plus the move along it; that angle is capped.
  const glm::dvec3 move = m_target - oldTarget;
  const double along = glm::dot(move, m_back);
  const glm::dvec3 across = move - along * m_back;
  const double maxAcross =
      std::max(m_distance + along, 0.0) * std::tan(m_settings.maxTurnDegrees * kDegree) * 0.999;
  if (glm::length(across) > maxAcross) {
    m_target = oldTarget + along * m_back + across * (maxAcross / glm::length(across));
    m_targetVelocity = (m_target - oldTarget) / dt;
  }
  place();
  return m_camera;
}

double fractionInside(const Camera& camera, double aspect, const Bounds& box) {
  if (box.empty()) return 0;
  const glm::dmat4 view =
      glm::lookAt(glm::dvec3(camera.eye), glm::dvec3(camera.target), glm::dvec3(camera.up));
  const double tanV = std::tan(0.5 * double(camera.fovYDegrees) * kDegree);
  const double tanH = tanV * aspect;
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (int k = 0; k < 8; ++k) {
    const glm::dvec3 c(k & 1 ? box.hi.x : box.lo.x, k & 2 ? box.hi.y : box.lo.y,
                       k & 4 ? box.hi.z : box.lo.z);
    const glm::dvec4 v = view * glm::dvec4(c, 1.0);
    if (!(-v.z > 1e-9)) return 0;  // behind the eye (view space looks down -z)
    // Normalised device coordinates: the picture is [-1, 1] on both axes.
    const double x = v.x / (-v.z * tanH), y = v.y / (-v.z * tanV);
    x0 = std::min(x0, x);
    x1 = std::max(x1, x);
    y0 = std::min(y0, y);
    y1 = std::max(y1, y);
  }
  // A box seen edge-on has no width (or height): it counts as inside along that side when its
  // line is.
  auto share = [](double a, double b) {
    if (b - a <= 1e-12) return a >= -1 && a <= 1 ? 1.0 : 0.0;
    return std::max(0.0, std::min(b, 1.0) - std::max(a, -1.0)) / (b - a);
  };
  return share(x0, x1) * share(y0, y1);
}

double swingDegrees(const Camera& before, const Camera& after) {
  const glm::dvec3 eye(after.eye);
  const glm::dvec3 a = glm::dvec3(before.target) - eye, b = glm::dvec3(after.target) - eye;
  const double c = glm::dot(a, b) / (glm::length(a) * glm::length(b));
  return std::acos(std::clamp(c, -1.0, 1.0)) / kDegree;
}

}  // namespace gf::demo
