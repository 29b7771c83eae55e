// Read-only view of a body's render surface (SPEC §3): the boundary plus the crack faces of
// broken edges, watertight per fragment. A renderer copies from it without knowing the
// internals: rebuild index buffers when topologyVersion changes, otherwise upload the dirty
// vertex range.
#pragma once

#include <cstdint>
#include <span>

namespace gf {

/// Valid until the next World::step or body creation/destruction.
struct SurfaceView {
  std::span<const float> positions;         ///< 3 per vertex, world space
  std::span<const float> normals;           ///< 3 per vertex, unit, outward
  std::span<const uint32_t> indices;        ///< 3 per triangle, counter-clockwise seen from outside
  std::span<const uint8_t> crackMask;       ///< per triangle: 1 = crack face, 0 = original boundary
  std::span<const int32_t> vertexFragment;  ///< per vertex: the fragment it belongs to
  std::span<const int32_t> vertexNode;      ///< per vertex: the node whose data it shows
  /// 2 per vertex when the body's render mesh has UVs (crack-face vertices get 0, 0), else
  /// empty.
  std::span<const float> uvs;
  /// Per triangle when the body's render mesh has materials (RenderMesh::materials): the
  /// material of the artist's triangle it was cut from, kInteriorMaterial (mesh.h) on crack
  /// faces (crackMask 1). Empty otherwise: every triangle material 0.
  std::span<const uint16_t> materials;
  uint64_t topologyVersion = 0;  ///< changes only when fractures change the triangles
  /// The vertices whose position or normal changed since the previous World::surface call for
  /// this body lie in [dirtyBegin, dirtyEnd); empty (begin == end) when none did. Every vertex
  /// is dirty when topologyVersion changed.
  uint32_t dirtyBegin = 0, dirtyEnd = 0;
};

}  // namespace gf
