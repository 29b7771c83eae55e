// Fragment labelling on the device: surface/fragment_stages.h's label rounds, run by the
// device executor (gpu/executor.h) on device copies of a body's edge graph, so the CPU and the
// device label from one source. The graph is mirrored once (its topology never changes); each
// call uploads the broken flags and brings the labels back. Built twice from one source like
// gpu/pcg.h.
#pragma once

#include <cstdint>
#include <string>

#include "gpu/device.h"
#include "gpu/executor.h"
#include "mesh/edge_graph.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

class DeviceFragmentLabels {
 public:
  /// Copies the graph's node-edge lists; false when device memory runs out (error()).
  bool upload(const detail::EdgeGraph& graph);
  /// Every node's label: the lowest node of its component over the edges not set in `broken`
  /// (host array, one flag per edge; null: none broken), into the host array `label` (one per
  /// node), as detail::labelComponents gives on the CPU; `rounds` receives its round count.
  /// False on a device error (error()), `label` then unchanged.
  bool label(const uint8_t* broken, int32_t* label, int32_t& rounds);
  const std::string& error() const { return m_error; }

 private:
  bool fail(const char* what);

  int32_t m_nodes = 0, m_edges = 0;
  DeviceBuffer<int32_t> m_edgeNodes, m_nodeEdgeStart, m_nodeEdges, m_label, m_next;
  DeviceBuffer<uint8_t> m_broken;
  DeviceBuffer<double> m_changed;
  Executor m_exec;
  std::string m_error;
};

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
