// gpu/fragment_labels.h: buffer management around the one labelling source.
#include "gpu/fragment_labels.h"
#include "surface/fragment_stages.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

bool DeviceFragmentLabels::fail(const char* what) {
  m_error = std::string(what) + ": " + lastError();
  return false;
}

bool DeviceFragmentLabels::upload(const detail::EdgeGraph& graph) {
  const size_t n = size_t(graph.nodeCount);
  m_nodes = graph.nodeCount;
  m_edges = graph.edgeCount;
  if (!m_edgeNodes.upload(graph.edgeNodes.data(), graph.edgeNodes.size()) ||
      !m_nodeEdgeStart.upload(graph.nodeEdgeStart.data(), graph.nodeEdgeStart.size()) ||
      !m_nodeEdges.upload(graph.nodeEdges.data(), graph.nodeEdges.size()) || !m_label.resize(n) ||
      !m_next.resize(n) || !m_changed.resize(n))
    return fail("uploading the edge graph");
  return true;
}

bool DeviceFragmentLabels::label(const uint8_t* broken, int32_t* label, int32_t& rounds) {
  if (!m_broken.upload(broken, size_t(m_edges))) return fail("uploading the broken flags");
  const detail::FragmentGraphView graph{m_nodes, m_edgeNodes.data(), m_nodeEdgeStart.data(),
                                        m_nodeEdges.data(), broken ? m_broken.data() : nullptr};
  rounds = detail::labelComponents(m_exec, graph, nullptr, m_nodes, m_label.data(), m_next.data(),
                                   m_changed.data());
  if (m_exec.takeFailure() || !synchronize()) return fail("labelling");
  return m_label.download(label, size_t(m_nodes)) || fail("reading the labels");
}

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
