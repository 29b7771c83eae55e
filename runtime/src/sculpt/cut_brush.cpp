// CutBrush (graphfrac/sculpt.h): the haptic cut brush of thesis sec 7.2.3.6, HapticContact's
// penalty with a threshold in front of World::cut.
#include <cmath>
#include <glm/geometric.hpp>
#include <string>

#include "graphfrac/sculpt.h"
#include "graphfrac/world.h"

namespace gf {

CutBrush::CutBrush(HapticContact contact, std::span<const glm::dvec3> vertices,
                   std::span<const uint32_t> indices, double threshold)
    : m_contact(std::move(contact)),
      m_pose(vertices.begin(), vertices.end()),
      m_indices(indices.begin(), indices.end()),
      m_threshold(threshold) {}

Result<CutBrush> CutBrush::create(std::span<const glm::dvec3> vertices,
                                  std::span<const uint32_t> indices,
                                  const CutBrushSettings& settings) {
  if (!(std::isfinite(settings.threshold) && settings.threshold > 0))
    return fail("CutBrush: threshold must be a positive finite force [N], got ",
                std::to_string(settings.threshold));
  Result<HapticContact> contact = HapticContact::create(vertices, indices, settings.contact);
  if (!contact) return fail("CutBrush: ", contact.error().message);
  return CutBrush(std::move(contact.value()), vertices, indices, settings.threshold);
}

Result<void> CutBrush::setSurface(const SurfaceView& surface, double blend) {
  return m_contact.setSurface(surface, blend);
}

Result<glm::dvec3> CutBrush::sample(std::span<const glm::dvec3> vertices, double dt) {
  Result<glm::dvec3> f = m_contact.sample(vertices, dt);
  if (!f) return f;
  m_pose.assign(vertices.begin(), vertices.end());
  m_cutting = glm::length(f.value()) >= m_threshold;
  return f;
}

Result<void> CutBrush::cut(World& world, BodyId body) const {
  if (!m_cutting) return fail("CutBrush::cut: the last sample's force is below the threshold");
  Blade blade;
  blade.vertices.reserve(m_pose.size());
  for (const glm::dvec3& p : m_pose) blade.vertices.push_back(glm::vec3(p));
  blade.triangles = m_indices;
  return world.cut(body, blade);
}

}  // namespace gf
