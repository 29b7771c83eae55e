// What the demo and the viewer draw of a running scene: one MeshFrame slot per scene body (its
// surface stream), per rigid body and per static collider (shapes uploaded once, moved by their
// model matrix), one for a cut brush when the scene has cut strokes, and one per scripted cut
// (Scene::cuts) for its blade, drawn for a few frames around the cut. The slots stay fixed for
// the scene's lifetime, so a renderer keeps each buffer and uploads only what changed: a body's
// dirty vertex range, or everything after a fracture changed its topology.
#pragma once

#include <graphfrac/world.h>

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "renderer.h"
#include "scene/scene.h"

namespace gf::scene {
class BulletScene;
}

namespace gf::demo {

/// A rigid body's render mesh in its own frame (a plane's in world space): a UV sphere, a box
/// with flat faces, or a square of side renderSize on the plane, centred at its point nearest
/// the origin. Counter-clockwise from outside, unit normals.
struct ShapeMesh {
  std::vector<float> positions, normals;
  std::vector<uint32_t> indices;
};
ShapeMesh rigidMesh(const scene::SceneRigidBody& body);

/// A static collider of the scene ("colliders") as the shape it is drawn with.
scene::SceneRigidBody colliderShape(const Collider& collider);

/// Cell of the grid drawn on ground planes [m] (a stronger line every 5 cells).
inline constexpr float kGroundCell = 0.1f;

/// A scripted cut's blade (Scene::cuts) is drawn from this many frames before the frame whose
/// step it cuts in ...
inline constexpr int kBladeLead = 3;
/// ... to this many frames after it (at the demo's 30 frames per second, 0.1 s and 0.27 s):
/// long enough to be seen, short enough not to hide the opened cut.
inline constexpr int kBladeTrail = 8;

/// What one SceneDrawing::update changed, as the demo's summary counts it.
struct DrawingChanges {
  /// Meshes whose topology (version or size) changed since the previous update, the first
  /// update counting every mesh as changed.
  int topologyChanges = 0;
  uint64_t dirtyVertices = 0;  ///< Dirty vertices of the unchanged meshes.
};

/// Orders a surface's triangles by material (SurfaceView::materials) for MeshFrame::ranges:
/// `outIndices` and `outCrack` (empty when `crackMask` is) are the triangles material by
/// material, in their order within each, and ranges[k] is set to material k's run (its colour
/// and texture are left as they are). Crack faces (kInteriorMaterial) and ids past the ranges go
/// with material 0; their flag draws them in the crack colour whatever the range.
void groupByMaterial(std::span<const uint32_t> indices, std::span<const uint8_t> crackMask,
                     std::span<const uint16_t> materials, std::vector<uint32_t>& outIndices,
                     std::vector<uint8_t>& outCrack, std::span<DrawRange> ranges);

class SceneDrawing {
 public:
  /// The slots of `scene`'s bodies, then its rigid bodies, then its static colliders.
  explicit SceneDrawing(const scene::Scene& scene);
  SceneDrawing(const SceneDrawing&) = delete;
  SceneDrawing& operator=(const SceneDrawing&) = delete;

  /// Fills the slots from the simulation now (the BulletScene made from the same scene).
  /// strainMax > 0 colours the bodies by World::nodeStrain, saturating (red) at that strain.
  DrawingChanges update(scene::BulletScene& sim, double strainMax);

  /// Decodes the bodies' textures (SceneBody::texture); until then, and for bodies without
  /// one, the bodies are drawn in their colour. The error names the body and the file.
  Result<void> loadTextures(const scene::Scene& scene);

  /// The slots as update() left them; their spans point into the world's surfaces and this
  /// object, valid until the next step or update.
  std::span<const MeshFrame> meshes() const { return m_meshes; }
  size_t bodyCount() const { return m_bodyCount; }
  /// The slot of Scene::cuts[i]'s blade (after every other slot).
  size_t bladeSlot(size_t i) const { return m_blades[i].slot; }
  /// Whether that blade was drawn by the last update().
  bool bladeShown(size_t i) const { return m_blades[i].shown; }

 private:
  size_t m_bodyCount = 0, m_rigidCount = 0;
  std::vector<scene::SceneRigidBody> m_drawn;  ///< Rigid bodies, then colliders.
  std::vector<ShapeMesh> m_shapes;             ///< Parallel to m_drawn.
  std::vector<MeshFrame> m_meshes;
  std::vector<uint64_t> m_lastVersion, m_lastVertices, m_lastTriangles;
  std::vector<std::vector<float>> m_strain;                ///< Per body, per vertex, 0..1.
  std::vector<std::shared_ptr<const Texture>> m_textures;  ///< Per body; null: none.
  /// The cut brush (the last slot when the scene has cut strokes): a two-sided square.
  bool m_hasBrush = false;
  size_t m_brushSlot = 0;
  std::vector<float> m_brushPositions, m_brushNormals;
  std::vector<uint32_t> m_brushIndices;
  /// The scene's cuts' blades: flat-shaded two-sided triangles at the blade's start and end
  /// poses (world space), shown around the cut's frame and collapsed to a point otherwise.
  struct BladeSlot {
    int frame = 1;
    size_t slot = 0;
    bool shown = false;
    std::vector<float> from, to, normalsFrom, normalsTo;  ///< 3 per vertex
    std::vector<float> positions, normals;
    std::vector<uint32_t> indices;
  };
  std::vector<BladeSlot> m_blades;
  /// A body whose render mesh has materials (SceneBody::materials): drawn in its slot in one
  /// range per material over its triangles grouped by material, grouped again when the
  /// topology changes.
  struct MaterialDraw {
    size_t body = 0;
    std::vector<uint32_t> indices;
    std::vector<uint8_t> crackMask;
    std::vector<DrawRange> ranges;
    std::vector<std::shared_ptr<const Texture>> textures;  ///< per material; null: none
    uint64_t version = ~uint64_t(0);
    size_t triangles = 0;
  };
  std::vector<MaterialDraw> m_materialBodies;
  /// Points a material body's slot (filled from `v` already) at its grouped triangles.
  void drawMaterials(MaterialDraw& md, const SurfaceView& v);
  bool m_first = true;
};

}  // namespace gf::demo
