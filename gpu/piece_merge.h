// The merge of free pieces that share a tet on the device: fem/piece_merge.h's stages, run by
// the device executor (gpu/executor.h) on device copies of a body's tets, so the CPU and the
// device merge from one source. The tets are mirrored once (the topology never changes); each
// call uploads the pieces and brings the merged ones back. Built twice from one source like
// gpu/fragment_labels.h.
#pragma once

#include <cstdint>
#include <string>

#include "gpu/device.h"
#include "gpu/executor.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

class DevicePieceMerge {
 public:
  /// Copies the tets (4 node indices each); false when device memory runs out (error()).
  bool upload(const int32_t* tets, int32_t tetCount, int32_t nodeCount);
  /// pieceOf (host array, one id below `count` per node) with the pieces that share a tet
  /// merged, as detail::mergePiecesSharingTets gives on the CPU; `merged` receives the new
  /// count and `rounds` the label rounds. False on a device error (error()), pieceOf unchanged.
  bool merge(int32_t* pieceOf, int32_t count, int32_t& merged, int32_t& rounds);
  const std::string& error() const { return m_error; }

 private:
  bool fail(const char* what);

  int32_t m_tets = 0, m_nodes = 0;
  DeviceBuffer<int32_t> m_tetNodes, m_pieceOf, m_label, m_next, m_rootId, m_chunkSum, m_chunkOffset;
  DeviceBuffer<double> m_changed;
  Executor m_exec;
  std::string m_error;
};

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
