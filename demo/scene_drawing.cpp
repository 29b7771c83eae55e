// The slots' layout is fixed for the scene's lifetime (see the header); what changes per frame
// is where each span points and which vertices are dirty.
#include "scene_drawing.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <numbers>

#include "scene/bullet_scene.h"

namespace gf::demo {
namespace {

void pushVec(std::vector<float>& v, const glm::dvec3& p) {
  v.push_back(float(p.x));
  v.push_back(float(p.y));
  v.push_back(float(p.z));
}

/// A square as 4 vertices and 2 triangles: corners c +- a +- b, facing n = a x b / |a x b|.
void addQuad(ShapeMesh& m, const glm::dvec3& c, const glm::dvec3& a, const glm::dvec3& b,
             const glm::dvec3& n) {
  const auto base = uint32_t(m.positions.size() / 3);
  for (const glm::dvec3& p : {c - a - b, c + a - b, c + a + b, c - a + b}) {
    pushVec(m.positions, p);
    pushVec(m.normals, n);
  }
  for (uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) m.indices.push_back(base + i);
}

}  // namespace

void groupByMaterial(std::span<const uint32_t> indices, std::span<const uint8_t> crackMask,
                     std::span<const uint16_t> materials, std::vector<uint32_t>& outIndices,
                     std::vector<uint8_t>& outCrack, std::span<DrawRange> ranges) {
  const size_t n = materials.size(), count = ranges.size();
  auto group = [&](uint16_t m) { return m < count ? size_t(m) : size_t(0); };
  std::vector<uint32_t> next(count + 1, 0);
  for (uint16_t m : materials) ++next[group(m) + 1];
  for (size_t k = 0; k < count; ++k) {
    ranges[k].firstTriangle = next[k];
    ranges[k].triangleCount = next[k + 1];
    next[k + 1] += next[k];
  }
  outIndices.resize(3 * n);
  outCrack.resize(crackMask.empty() ? 0 : n);
  for (size_t t = 0; t < n; ++t) {
    const uint32_t at = next[group(materials[t])]++;
    std::copy_n(indices.begin() + 3 * ptrdiff_t(t), 3, outIndices.begin() + 3 * ptrdiff_t(at));
    if (!crackMask.empty()) outCrack[at] = crackMask[t];
  }
}

scene::SceneRigidBody colliderShape(const Collider& c) {
  scene::SceneRigidBody r;
  r.position = glm::dvec3(c.point);
  r.colour = glm::vec3(0.5f, 0.5f, 0.53f);
  switch (c.kind) {
    case Collider::Kind::Sphere:
      r.shape = scene::SceneRigidBody::Shape::Sphere;
      r.radius = c.radius;
      break;
    case Collider::Kind::Box:
      r.shape = scene::SceneRigidBody::Shape::Box;
      r.halfExtents = glm::dvec3(c.halfExtents);
      r.orientation = glm::normalize(glm::dquat(c.rotation));
      break;
    case Collider::Kind::Capsule:
      r.shape = scene::SceneRigidBody::Shape::Capsule;
      r.radius = c.radius;
      r.halfLength = c.halfLength;
      r.orientation = glm::normalize(glm::dquat(c.rotation));
      break;
    case Collider::Kind::Plane:
      r.shape = scene::SceneRigidBody::Shape::Plane;
      r.normal = glm::normalize(glm::dvec3(c.normal));
      r.offset = glm::dot(r.normal, r.position);
      break;
  }
  return r;
}

ShapeMesh rigidMesh(const scene::SceneRigidBody& r) {
  using Shape = scene::SceneRigidBody::Shape;
  ShapeMesh m;
  if (r.shape == Shape::Sphere || r.shape == Shape::Capsule) {
    // Latitude theta from the +y pole, longitude phi; d/dphi x d/dtheta points outwards, so
    // (a, a+1, b) and (a+1, b+1, b) are counter-clockwise seen from outside. A capsule is the
    // sphere cut at the equator, its halves moved to the segment's ends: the equator ring is
    // drawn twice, and the band between the two copies is the cylinder's side.
    constexpr uint32_t kHalfRings = 8, kSegments = 32;
    const bool capsule = r.shape == Shape::Capsule;
    const uint32_t kRings = capsule ? 2 * kHalfRings + 1 : 2 * kHalfRings;
    for (uint32_t i = 0; i <= kRings; ++i) {
      const uint32_t latitude = capsule && i > kHalfRings ? i - 1 : i;
      const double theta = std::numbers::pi * latitude / (2 * kHalfRings);
      const double shift = capsule ? (i <= kHalfRings ? r.halfLength : -r.halfLength) : 0;
      for (uint32_t j = 0; j <= kSegments; ++j) {
        const double phi = 2 * std::numbers::pi * j / kSegments;
        const glm::dvec3 n(std::sin(theta) * std::cos(phi), std::cos(theta),
                           std::sin(theta) * std::sin(phi));
        pushVec(m.positions, r.radius * n + glm::dvec3(0, shift, 0));
        pushVec(m.normals, n);
      }
    }
    for (uint32_t i = 0; i < kRings; ++i) {
      for (uint32_t j = 0; j < kSegments; ++j) {
        const uint32_t a = i * (kSegments + 1) + j, b = a + kSegments + 1;
        if (i != 0) m.indices.insert(m.indices.end(), {a, a + 1, b});  // not at the poles
        if (i + 1 != kRings) m.indices.insert(m.indices.end(), {a + 1, b + 1, b});
      }
    }
  } else if (r.shape == Shape::Box) {
    // Per face: its normal n and axes u, v with u x v = n, so the quad faces outwards.
    const glm::dvec3 h = r.halfExtents;
    const glm::dvec3 x(1, 0, 0), y(0, 1, 0), z(0, 0, 1);
    const std::array<std::array<glm::dvec3, 3>, 6> faces = {{{x, y * h.y, z * h.z},
                                                             {-x, z * h.z, y * h.y},
                                                             {y, z * h.z, x * h.x},
                                                             {-y, x * h.x, z * h.z},
                                                             {z, x * h.x, y * h.y},
                                                             {-z, y * h.y, x * h.x}}};
    for (const auto& f : faces) addQuad(m, f[0] * glm::dot(glm::abs(f[0]), h), f[1], f[2], f[0]);
  } else {
    const glm::dvec3 n = r.normal;
    const glm::dvec3 u = scene::anyPerpendicular(n), w = glm::cross(n, u);  // u x w = n
    const double half = 0.5 * r.renderSize;
    addQuad(m, r.offset * n, half * u, half * w, n);
  }
  return m;
}

SceneDrawing::SceneDrawing(const scene::Scene& sc)
    : m_bodyCount(sc.bodies.size()), m_rigidCount(sc.rigidBodies.size()), m_drawn(sc.rigidBodies) {
  for (const Collider& c : sc.world.colliders) m_drawn.push_back(colliderShape(c));
  if (!sc.strokes.empty()) {
    // The sculpting tool (scene/strokes.h) comes after the scene's colliders: a unit sphere,
    // scaled each frame to the stroke's radius.
    Collider tool;
    tool.kind = Collider::Kind::Sphere;
    tool.radius = 1;
    m_drawn.push_back(colliderShape(tool));
    m_drawn.back().colour = glm::vec3(0.85f, 0.75f, 0.3f);
  }
  for (const scene::SceneRigidBody& r : m_drawn) m_shapes.push_back(rigidMesh(r));
  const size_t slots = m_bodyCount + m_shapes.size();
  m_meshes.resize(slots);
  m_lastVersion.assign(slots, 0);
  m_lastVertices.assign(slots, 0);
  m_lastTriangles.assign(slots, 0);
  m_strain.resize(m_bodyCount);
  m_textures.resize(m_bodyCount);
  for (size_t i = 0; i < m_bodyCount; ++i) {
    m_meshes[i].colour = sc.bodies[i].colour;
    m_meshes[i].crackColour = sc.bodies[i].crackColour;
    m_meshes[i].crackLook = crackLook(sc.bodies[i].interior);
  }
  for (size_t k = 0; k < m_shapes.size(); ++k) {
    MeshFrame& m = m_meshes[m_bodyCount + k];
    m.positions = m_shapes[k].positions;
    m.normals = m_shapes[k].normals;
    m.indices = m_shapes[k].indices;
    m.topologyVersion = 1;
    m.colour = m_drawn[k].colour;
    // A plane is the ground: it shows its scale and receives shadows without casting any.
    if (m_drawn[k].shape == scene::SceneRigidBody::Shape::Plane) {
      m.gridSpacing = kGroundCell;
      m.castsShadow = false;
    }
  }
  // The parked tool waits 1e6 m away: as a caster it would stretch the shadow map over that.
  if (!sc.strokes.empty()) m_meshes.back().castsShadow = false;
  for (const scene::SceneStroke& st : sc.strokes)
    m_hasBrush |= st.type == scene::SceneStroke::Type::Cut;
  if (m_hasBrush) {
    m_brushSlot = m_meshes.size();
    // Front (0-3) and back (4-7) copies of the square, so it shows from either side.
    m_brushPositions.assign(24, 0.0f);
    m_brushNormals.assign(24, 0.0f);
    m_brushIndices = {0, 1, 2, 0, 2, 3, 4, 6, 5, 4, 7, 6};
    m_meshes.emplace_back();
    MeshFrame& m = m_meshes.back();
    m.positions = m_brushPositions;
    m.normals = m_brushNormals;
    m.indices = m_brushIndices;
    m.topologyVersion = 1;
    m.colour = glm::vec3(0.75f, 0.78f, 0.82f);
    m_lastVersion.push_back(0);
    m_lastVertices.push_back(0);
    m_lastTriangles.push_back(0);
  }
  // Scripted cuts show their blade: a thin steel sheet, seen from either side.
  for (const scene::SceneCut& c : sc.cuts) {
    BladeSlot b;
    b.frame = c.frame;
    b.slot = m_meshes.size();
    const std::vector<glm::vec3>& v = c.blade.vertices;
    const std::vector<uint32_t>& tri = c.blade.triangles;
    // One triangle of the blade at `pose`, flat: its own three vertices with its normal.
    auto addTriangle = [&](const glm::mat4& pose, const uint32_t(&idx)[3], std::vector<float>& pos,
                           std::vector<float>& nrm) {
      glm::vec3 p[3];
      for (int k = 0; k < 3; ++k) p[k] = glm::vec3(pose * glm::vec4(v[idx[k]], 1.0f));
      const glm::vec3 a = glm::cross(p[1] - p[0], p[2] - p[0]);
      const float len = glm::length(a);
      const glm::vec3 n = len > 0 ? a / len : glm::vec3(0, 1, 0);
      for (int k = 0; k < 3; ++k)
        for (int d = 0; d < 3; ++d) {
          pos.push_back(p[k][d]);
          nrm.push_back(n[d]);
        }
    };
    for (int side = 0; side < 2; ++side)
      for (size_t t = 0; t + 2 < tri.size(); t += 3) {
        const uint32_t idx[3] = {tri[t], side ? tri[t + 2] : tri[t + 1],
                                 side ? tri[t + 1] : tri[t + 2]};
        addTriangle(c.blade.from, idx, b.from, b.normalsFrom);
        addTriangle(c.blade.to, idx, b.to, b.normalsTo);
        for (int k = 0; k < 3; ++k) b.indices.push_back(uint32_t(b.indices.size()));
      }
    b.positions.assign(b.from.size(), 0.0f);
    b.normals.assign(b.from.size(), 0.0f);
    m_blades.push_back(std::move(b));
  }
  for (BladeSlot& b : m_blades) {
    m_meshes.emplace_back();
    MeshFrame& m = m_meshes.back();
    m.positions = b.positions;
    m.normals = b.normals;
    m.indices = b.indices;
    m.topologyVersion = 1;
    m.colour = glm::vec3(0.78f, 0.8f, 0.84f);
    m.crackLook.metallic = 1.0f;
    m.castsShadow = false;
    m_lastVersion.push_back(0);
    m_lastVertices.push_back(0);
    m_lastTriangles.push_back(0);
  }
  for (size_t i = 0; i < m_bodyCount; ++i) {
    const std::vector<scene::SceneBody::Material>& table = sc.bodies[i].materials;
    if (table.size() < 2) continue;
    MaterialDraw md;
    md.body = i;
    md.ranges.resize(table.size());
    md.textures.resize(table.size());
    for (size_t k = 0; k < table.size(); ++k) md.ranges[k].colour = table[k].colour;
    // Without material ids (a body whose render mesh is gone) it is drawn in the first one's.
    m_meshes[i].colour = table[0].colour;
    m_materialBodies.push_back(std::move(md));
  }
}

Result<void> SceneDrawing::loadTextures(const scene::Scene& scene) {
  for (size_t i = 0; i < m_bodyCount && i < scene.bodies.size(); ++i) {
    if (scene.bodies[i].texture.empty()) continue;
    Result<std::shared_ptr<const Texture>> t = loadTexture(scene.bodies[i].texture);
    if (!t) return fail("body '", scene.bodies[i].name, "': texture ", t.error().message);
    m_textures[i] = t.value();
  }
  for (MaterialDraw& md : m_materialBodies) {
    const scene::SceneBody& body = scene.bodies[md.body];
    for (size_t k = 0; k < md.textures.size() && k < body.materials.size(); ++k) {
      if (body.materials[k].texture.empty()) continue;
      Result<std::shared_ptr<const Texture>> t = loadTexture(body.materials[k].texture);
      if (!t)
        return fail("body '", body.name, "': material '", body.materials[k].name, "': texture ",
                    t.error().message);
      md.textures[k] = t.value();
    }
  }
  return {};
}

void SceneDrawing::drawMaterials(MaterialDraw& md, const SurfaceView& v) {
  MeshFrame& m = m_meshes[md.body];
  const size_t triangles = v.indices.size() / 3;
  if (v.materials.size() != triangles) {
    m.ranges = {};
    return;
  }
  if (md.version != v.topologyVersion || md.triangles != triangles)
    groupByMaterial(v.indices, v.crackMask, v.materials, md.indices, md.crackMask, md.ranges);
  md.version = v.topologyVersion;
  md.triangles = triangles;
  bool textured = false;
  for (size_t k = 0; k < md.ranges.size(); ++k) {
    md.ranges[k].texture = v.uvs.empty() ? nullptr : md.textures[k];
    textured = textured || md.ranges[k].texture;
  }
  m.indices = md.indices;
  m.crackMask = md.crackMask;
  m.ranges = md.ranges;
  m.texture = nullptr;
  m.uvs = textured ? v.uvs : std::span<const float>{};
}

DrawingChanges SceneDrawing::update(scene::BulletScene& sim, double strainMax) {
  World& world = sim.world();
  size_t nextMaterialBody = 0;
  for (size_t i = 0; i < m_bodyCount; ++i) {
    const SurfaceView v = world.surface(sim.body(i));
    MeshFrame& m = m_meshes[i];
    m.positions = v.positions;
    m.normals = v.normals;
    m.indices = v.indices;
    m.crackMask = v.crackMask;
    // Vertices without UVs (a body whose render mesh is gone) are drawn untextured.
    m.texture = v.uvs.empty() ? nullptr : m_textures[i];
    m.uvs = m.texture ? v.uvs : std::span<const float>{};
    m.topologyVersion = v.topologyVersion;
    m.dirtyBegin = v.dirtyBegin;
    m.dirtyEnd = v.dirtyEnd;
    if (strainMax > 0) {
      // Strain changes everywhere, so every vertex is dirty in this mode.
      const std::span<const double> e = world.nodeStrain(sim.body(i));
      m_strain[i].resize(v.vertexNode.size());
      for (size_t k = 0; k < v.vertexNode.size(); ++k)
        m_strain[i][k] = float(std::clamp(e[size_t(v.vertexNode[k])] / strainMax, 0.0, 1.0));
      m.scalar = m_strain[i];
      m.dirtyBegin = 0;
      m.dirtyEnd = uint32_t(v.vertexNode.size());
    } else {
      m.scalar = {};
    }
    if (nextMaterialBody < m_materialBodies.size() && m_materialBodies[nextMaterialBody].body == i)
      drawMaterials(m_materialBodies[nextMaterialBody++], v);
  }
  for (size_t k = 0; k < m_shapes.size(); ++k) {
    MeshFrame& m = m_meshes[m_bodyCount + k];
    if (k < m_rigidCount) {
      m.model = sim.rigidTransform(k);
    } else {
      // The scene's colliders come first in World::colliders(); a moving one has moved.
      const Collider& now = world.colliders()[k - m_rigidCount];
      const glm::vec3 start(m_drawn[k].position);
      m.model = m_drawn[k].shape == scene::SceneRigidBody::Shape::Plane
                    ? glm::translate(glm::mat4(1.0f), now.point - start)
                    : glm::translate(glm::mat4(1.0f), now.point) *
                          glm::mat4_cast(glm::normalize(now.rotation));
      // A sphere whose radius changed (the sculpting tool between strokes) is scaled to it.
      if (m_drawn[k].shape == scene::SceneRigidBody::Shape::Sphere &&
          now.radius != float(m_drawn[k].radius))
        m.model =
            m.model * glm::scale(glm::mat4(1.0f), glm::vec3(now.radius / float(m_drawn[k].radius)));
    }
    m.dirtyBegin = 0;
    m.dirtyEnd = m_first ? uint32_t(m_shapes[k].positions.size() / 3) : 0;
  }
  if (m_hasBrush) {
    // Between cut strokes the brush waits with the parked tool, casting no shadow.
    const std::span<const glm::dvec3> pose = sim.strokes().brushPose();
    const glm::vec3 n =
        pose.size() == 4
            ? glm::vec3(glm::normalize(glm::cross(pose[1] - pose[0], pose[2] - pose[0])))
            : glm::vec3(0, 1, 0);
    for (int k = 0; k < 8; ++k) {
      const glm::vec3 p = pose.size() == 4 ? glm::vec3(pose[size_t(k % 4)])
                                           : glm::vec3(0, scene::StrokePlayer::kParkedTool, 0);
      const glm::vec3 nk = k < 4 ? n : -n;
      for (int i = 0; i < 3; ++i) {
        m_brushPositions[size_t(3 * k + i)] = p[i];
        m_brushNormals[size_t(3 * k + i)] = nk[i];
      }
    }
    MeshFrame& m = m_meshes[m_brushSlot];
    m.castsShadow = pose.size() == 4;
    m.dirtyBegin = 0;
    m.dirtyEnd = 8;
  }
  for (BladeSlot& b : m_blades) {
    // Frame f's picture follows the step of frame f; the cut acts in the step of b.frame.
    const int f = sim.frame();
    const bool shown = f >= b.frame - kBladeLead && f <= b.frame + kBladeTrail;
    const bool after = f >= b.frame;
    MeshFrame& m = m_meshes[b.slot];
    m.dirtyBegin = 0;
    m.dirtyEnd = 0;
    if (shown != b.shown || (shown && after && f == b.frame) || m_first) {
      if (shown) {
        b.positions = after ? b.to : b.from;
        b.normals = after ? b.normalsTo : b.normalsFrom;
      } else {
        // Collapsed to one point: nothing is rasterised.
        std::fill(b.positions.begin(), b.positions.end(), 0.0f);
      }
      m.dirtyEnd = uint32_t(b.positions.size() / 3);
    }
    b.shown = shown;
    m.castsShadow = shown;
  }
  DrawingChanges c;
  for (size_t i = 0; i < m_meshes.size(); ++i) {
    const MeshFrame& m = m_meshes[i];
    const bool changed = m_first || m.topologyVersion != m_lastVersion[i] ||
                         m.positions.size() != m_lastVertices[i] ||
                         m.indices.size() != m_lastTriangles[i];
    if (changed)
      ++c.topologyChanges;
    else
      c.dirtyVertices += m.dirtyEnd - m.dirtyBegin;
    m_lastVersion[i] = m.topologyVersion;
    m_lastVertices[i] = m.positions.size();
    m_lastTriangles[i] = m.indices.size();
  }
  m_first = false;
  return c;
}

}  // namespace gf::demo
