#include "scene/strokes.h"

#include <graphfrac/sculpt.h>

#include <string>
#include <vector>

namespace gf::scene {
namespace {

Collider parkedTool() {
  Collider c;
  c.kind = Collider::Kind::Sphere;
  c.point = {0, StrokePlayer::kParkedTool, 0};
  c.radius = 0.01f;
  return c;
}

}  // namespace

const char* strokeTypeName(SceneStroke::Type type) {
  switch (type) {
    case SceneStroke::Type::Wet:
      return "wet";
    case SceneStroke::Type::Dry:
      return "dry";
    case SceneStroke::Type::Push:
      break;
  }
  return "push";
}

StrokePlayer::StrokePlayer(const Scene& scene, WorldDef& def)
    : m_strokes(scene.strokes), m_dt(scene.dt) {
  if (scene.strokes.empty()) return;
  m_tool = int(def.colliders.size());
  def.colliders.push_back(parkedTool());
}

int StrokePlayer::activeStroke(int frame) const {
  for (size_t i = 0; i < m_strokes.size(); ++i) {
    const SceneStroke& s = m_strokes[i];
    if (frame >= s.fromFrame && frame <= s.toFrame) return int(i);
  }
  return -1;
}

Result<void> StrokePlayer::apply(World& world, std::span<const BodyId> bodies, int frame,
                                 int substep, int substeps) {
  if (m_tool < 0) return {};
  const int active = activeStroke(frame);
  const std::span<const Collider> now = world.colliders();
  std::vector<Collider> colliders(now.begin(), now.end());
  if (size_t(m_tool) >= colliders.size()) return fail("strokes: the tool's collider is gone");
  Collider& tool = colliders[size_t(m_tool)];
  if (active < 0) {
    // Only touch the colliders when the tool has to be put away.
    if (tool.point == parkedTool().point) return {};
    tool = parkedTool();
    return world.setColliders(colliders);
  }
  const SceneStroke& s = m_strokes[size_t(active)];
  const auto failed = [&](const Error& e) {
    return fail("strokes[", std::to_string(active), "] (", strokeTypeName(s.type), " of body \"",
                s.body, "\"): ", e.message);
  };
  if (s.bodyIndex >= bodies.size()) return fail("strokes: body index out of range");
  // The path is split evenly over the stroke's steps: from at the first one's start, to at the
  // last one's end.
  const int steps = (s.toFrame - s.fromFrame + 1) * substeps;
  const int k = (frame - s.fromFrame) * substeps + substep;
  const glm::dvec3 centre = s.from + (s.to - s.from) * (double(k) / steps);
  const BodyId body = bodies[s.bodyIndex];
  if (s.type == SceneStroke::Type::Push) {
    // The collider advances by velocity * h during each step, so it sweeps the path
    // continuously instead of jumping from sample to sample.
    tool = parkedTool();
    tool.point = glm::vec3(centre);
    tool.radius = float(s.radius);
    tool.velocity = glm::vec3((s.to - s.from) / ((s.toFrame - s.fromFrame + 1) * m_dt));
    if (Result<void> r = world.setColliders(colliders); !r) return failed(r.error());
    DeformBrush b;
    b.centre = glm::vec3(centre);
    b.radius = float(s.influence);
    b.k1 = s.k1;
    b.k2 = s.k2;
    if (Result<void> r = world.deform(body, b); !r) return failed(r.error());
    return {};
  }
  if (tool.point != parkedTool().point) {
    tool = parkedTool();
    if (Result<void> r = world.setColliders(colliders); !r) return failed(r.error());
  }
  WetBrush b;
  b.centre = glm::vec3(centre);
  b.radius = float(s.radius);
  b.rate = s.rate;
  const Result<void> r = s.type == SceneStroke::Type::Wet ? world.wet(body, b) : world.dry(body, b);
  if (!r) return failed(r.error());
  return {};
}

glm::dvec3 StrokePlayer::toolForce(const World& world, double h) const {
  const std::span<const glm::dvec3> J = world.colliderImpulses();
  if (m_tool < 0 || size_t(m_tool) >= J.size() || !(h > 0)) return glm::dvec3(0);
  return -J[size_t(m_tool)] / h;
}

}  // namespace gf::scene
