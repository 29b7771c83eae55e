// gpu/piece_merge.h: buffer management around the one merge source.
#include "fem/piece_merge.h"
#include "gpu/piece_merge.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

bool DevicePieceMerge::fail(const char* what) {
  m_error = std::string(what) + ": " + lastError();
  return false;
}

bool DevicePieceMerge::upload(const int32_t* tets, int32_t tetCount, int32_t nodeCount) {
  m_tets = tetCount;
  m_nodes = nodeCount;
  if (!m_tetNodes.upload(tets, 4 * size_t(tetCount)) || !m_pieceOf.resize(size_t(nodeCount)))
    return fail("uploading the tets");
  return true;
}

bool DevicePieceMerge::merge(int32_t* pieceOf, int32_t count, int32_t& merged, int32_t& rounds) {
  const size_t n = size_t(count), chunks = size_t(detail::pieceMergeChunks(count));
  if (!m_pieceOf.upload(pieceOf, size_t(m_nodes)) || !m_label.resize(n) || !m_next.resize(n) ||
      !m_rootId.resize(n + 1) || !m_chunkSum.resize(chunks) || !m_chunkOffset.resize(chunks + 1) ||
      !m_changed.resize(n))
    return fail("uploading the pieces");
  rounds = 0;
  merged = detail::mergePiecesSharingTets(
      m_exec, m_tetNodes.data(), m_tets, m_pieceOf.data(), m_nodes, count,
      {m_label.data(), m_next.data(), m_changed.data(), m_rootId.data(), m_chunkSum.data(),
       m_chunkOffset.data()},
      &rounds);
  if (m_exec.takeFailure() || !synchronize()) return fail("merging");
  return m_pieceOf.download(pieceOf, size_t(m_nodes)) || fail("reading the pieces");
}

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
