// The fixed scene of the golden-image tests, shared by the Vulkan and the GL back end so both
// are checked against one reference image: the boundary surface of scenes/meshes/bunny_small.msh
// (World::surface before any step, so no physics is involved), triangles with a centroid right of
// the middle drawn as crack faces, seen from a fixed camera.
#pragma once

#include <graphfrac/world.h>

#include <algorithm>
#include <vector>

#include "renderer.h"

namespace gf::test {

struct GoldenScene {
  std::vector<float> positions, normals;
  std::vector<uint32_t> indices;
  std::vector<uint8_t> crackMask;
  demo::Camera camera;
  // The stage golden image: a floor square under the bunny with a grid of a tenth of its size.
  std::vector<float> floorPositions, floorNormals;
  std::vector<uint32_t> floorIndices;
  float gridSpacing = 0;

  demo::MeshFrame frame() const {
    demo::MeshFrame f;
    f.positions = positions;
    f.normals = normals;
    f.indices = indices;
    f.crackMask = crackMask;
    f.topologyVersion = 1;
    f.dirtyBegin = 0;
    f.dirtyEnd = uint32_t(positions.size() / 3);
    f.colour = {0.55f, 0.75f, 0.85f};
    f.crackColour = {0.95f, 0.55f, 0.3f};
    return f;
  }
  /// The demo's look: the bunny with glass crack faces on a gridded floor (draw with shadows).
  std::vector<demo::MeshFrame> stage() const {
    demo::MeshFrame bunny = frame();
    bunny.crackColour = {0.8f, 0.92f, 0.95f};
    bunny.crackLook = demo::crackLook("glass");
    demo::MeshFrame floor;
    floor.positions = floorPositions;
    floor.normals = floorNormals;
    floor.indices = floorIndices;
    floor.topologyVersion = 1;
    floor.dirtyEnd = uint32_t(floorPositions.size() / 3);
    floor.colour = {0.42f, 0.45f, 0.48f};
    floor.gridSpacing = gridSpacing;
    floor.castsShadow = false;
    return {bunny, floor};
  }
};

// Loads the bunny (GF_SOURCE_DIR is set by tests/CMakeLists.txt). Empty positions on failure.
inline GoldenScene goldenScene() {
  GoldenScene s;
  Result<TetMesh> mesh = TetMesh::fromFile(GF_SOURCE_DIR "/scenes/meshes/bunny_small.msh");
  if (!mesh) return s;
  BodyDef def;
  def.mesh = std::move(mesh.value());
  World world(WorldDef{});
  Result<BodyId> id = world.createBody(std::move(def));
  if (!id) return s;
  const SurfaceView v = world.surface(id.value());
  s.positions.assign(v.positions.begin(), v.positions.end());
  s.normals.assign(v.normals.begin(), v.normals.end());
  s.indices.assign(v.indices.begin(), v.indices.end());
  float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
  for (size_t i = 0; i < s.positions.size(); ++i) {
    lo[i % 3] = std::min(lo[i % 3], s.positions[i]);
    hi[i % 3] = std::max(hi[i % 3], s.positions[i]);
  }
  const float midX = 0.5f * (lo[0] + hi[0]);
  s.crackMask.resize(s.indices.size() / 3);
  for (size_t t = 0; t < s.crackMask.size(); ++t) {
    float cx = 0;
    for (int k = 0; k < 3; ++k) cx += s.positions[3 * s.indices[3 * t + k]] / 3;
    s.crackMask[t] = cx > midX ? 1 : 0;
  }
  const glm::vec3 centre(0.5f * (lo[0] + hi[0]), 0.5f * (lo[1] + hi[1]), 0.5f * (lo[2] + hi[2]));
  const float size = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  s.camera.target = centre;
  s.camera.eye = centre + glm::vec3(0.9f, 0.5f, 1.3f) * size;
  s.camera.fovYDegrees = 40;
  s.camera.nearPlane = 0.05f * size;
  s.camera.farPlane = 10 * size;
  const float h = 1.5f * size;
  const float corners[4][2] = {
      {-h, h}, {h, h}, {h, -h}, {-h, -h}};  // x, z: counter-clockwise from +y
  for (const auto& c : corners) {
    s.floorPositions.insert(s.floorPositions.end(), {centre.x + c[0], lo[1], centre.z + c[1]});
    s.floorNormals.insert(s.floorNormals.end(), {0.0f, 1.0f, 0.0f});
  }
  s.floorIndices = {0, 1, 2, 0, 2, 3};
  s.gridSpacing = 0.1f * size;
  return s;
}

}  // namespace gf::test
