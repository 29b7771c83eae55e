#include "scene/strokes.h"

#include <graphfrac/sculpt.h>

#include <glm/geometric.hpp>
#include <string>
#include <vector>

namespace gf::scene {
namespace {

// The cut brush of a stroke with its leading edge's centre at c: a square in the plane through
// the path with normal s.normal, trailing behind the edge.
std::vector<glm::dvec3> brushAt(const SceneStroke& s, glm::dvec3 c) {
  const glm::dvec3 d = glm::normalize(s.to - s.from);
  const glm::dvec3 a = 0.5 * s.size * glm::normalize(glm::cross(s.normal, d));
  return {c - a, c + a, c + a - s.size * d, c - a - s.size * d};
}
constexpr uint32_t kBrushTriangles[] = {0, 1, 2, 0, 2, 3};

// The clay kernel (eq 7.7) of a push, pull or cut stroke around `centre`.
DeformBrush clayAround(const SceneStroke& s, glm::dvec3 centre) {
  DeformBrush b;
  b.centre = glm::vec3(centre);
  b.radius = float(s.influence);
  b.k1 = s.k1;
  b.k2 = s.k2;
  return b;
}

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
    case SceneStroke::Type::Pull:
      return "pull";
    case SceneStroke::Type::Cut:
      return "cut";
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
  m_brushForce = glm::dvec3(0);
  m_brushPose.clear();
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
  if (s.type == SceneStroke::Type::Pull && m_grabbedBy != active) {
    // The stroke's first step: what the tool touches sticks to it.
    m_grabbedBy = active;
    m_pulled = body;
    m_grabbed.clear();
    m_offsets.clear();
    const std::span<const double> x = world.positions(body);
    for (size_t n = 0; 3 * n < x.size(); ++n) {
      const glm::dvec3 p(x[3 * n], x[3 * n + 1], x[3 * n + 2]);
      if (glm::length(p - centre) > s.radius + s.grab) continue;
      m_grabbed.push_back(int32_t(n));
      m_offsets.push_back(p - centre);
    }
    if (m_grabbed.empty())
      return failed(Error{"no node within radius + grab = " + std::to_string(s.radius + s.grab) +
                          " m of the tool's centre at the stroke's start"});
  }
  if (s.type == SceneStroke::Type::Cut) return cutStroke(world, body, active, centre, k, steps);
  if (s.type == SceneStroke::Type::Push || s.type == SceneStroke::Type::Pull) {
    // The collider advances by velocity * h during each step, so it sweeps the path
    // continuously instead of jumping from sample to sample.
    tool = parkedTool();
    tool.point = glm::vec3(centre);
    tool.radius = float(s.radius);
    tool.velocity = glm::vec3((s.to - s.from) / ((s.toFrame - s.fromFrame + 1) * m_dt));
    if (Result<void> r = world.setColliders(colliders); !r) return failed(r.error());
    if (Result<void> r = world.deform(body, clayAround(s, centre)); !r) return failed(r.error());
    if (s.type == SceneStroke::Type::Push) return {};
    const glm::dvec3 end = s.from + (s.to - s.from) * (double(k + 1) / steps);
    m_targets.resize(m_offsets.size());
    for (size_t i = 0; i < m_offsets.size(); ++i) m_targets[i] = end + m_offsets[i];
    PullBrush pull;
    pull.nodes = m_grabbed;
    pull.targets = m_targets;
    pull.stiffness = s.stiffness;
    if (Result<void> r = world.pull(body, pull); !r) return failed(r.error());
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

Result<void> StrokePlayer::cutStroke(World& world, BodyId body, int active, glm::dvec3 centre,
                                     int k, int steps) {
  const SceneStroke& s = m_strokes[size_t(active)];
  const auto failed = [&](const Error& e) {
    return fail("strokes[", std::to_string(active), "] (cut of body \"", s.body,
                "\"): ", e.message);
  };
  const std::span<const Collider> now = world.colliders();
  if (now[size_t(m_tool)].point != parkedTool().point) {
    std::vector<Collider> colliders(now.begin(), now.end());
    colliders[size_t(m_tool)] = parkedTool();
    if (Result<void> r = world.setColliders(colliders); !r) return failed(r.error());
  }
  const double h = m_dt * double(s.toFrame - s.fromFrame + 1) / steps;
  if (m_brushStroke != active) {
    CutBrushSettings settings;
    settings.threshold = s.threshold;
    settings.contact.stiffness = s.stiffness;
    Result<CutBrush> brush = CutBrush::create(brushAt(s, centre), kBrushTriangles, settings);
    if (!brush) return failed(brush.error());
    m_brush.emplace(std::move(brush.value()));
    m_brushStroke = active;
    if (Result<void> r = m_brush->setSurface(world.surface(body), 0); !r) return failed(r.error());
  } else if (Result<void> r = m_brush->setSurface(world.surface(body), h); !r) {
    return failed(r.error());
  }
  // The brush moves to where the path is at the end of this step.
  const glm::dvec3 end = s.from + (s.to - s.from) * (double(k + 1) / steps);
  m_brushPose = brushAt(s, end);
  const Result<glm::dvec3> f = m_brush->sample(m_brushPose, h);
  if (!f) return failed(f.error());
  m_brushForce = f.value();
  if (Result<void> r = world.deform(body, clayAround(s, end)); !r) return failed(r.error());
  if (m_brush->cutting())
    if (Result<void> r = m_brush->cut(world, body); !r) return failed(r.error());
  return {};
}

glm::dvec3 StrokePlayer::toolForce(const World& world, double h) const {
  const std::span<const glm::dvec3> J = world.colliderImpulses();
  if (m_tool < 0 || size_t(m_tool) >= J.size() || !(h > 0)) return glm::dvec3(0);
  // pullForce is zero unless the step that just ended pulled.
  return -J[size_t(m_tool)] / h - world.pullForce(m_pulled) + m_brushForce;
}

}  // namespace gf::scene
