// gpu/criterion.h: buffer management around the one criterion source.
#include "gpu/criterion.h"

namespace gf::gpu {
inline namespace GF_GPU_ABI {

int32_t DeviceCriterion::fail(const char* what) {
  m_error = std::string(what) + ": " + lastError();
  return -1;
}

int32_t DeviceCriterion::find(const detail::CriterionView& host, const double* stress,
                              double weakest) {
  const size_t T = size_t(host.tetCount), E = size_t(host.edgeCount);
  const int32_t chunks = (host.edgeCount + detail::kCompactChunk - 1) / detail::kCompactChunk;
  const detail::CriterionView& was = m_from;
  const bool model = host.tetCount != was.tetCount || host.edgeCount != was.edgeCount ||
                     host.nonLocal != was.nonLocal || host.cells != was.cells ||
                     host.edges.tetEdges != was.edges.tetEdges ||
                     host.edges.edgeDirections != was.edges.edgeDirections ||
                     host.grid.start != was.grid.start ||
                     host.average.neighbourStart != was.average.neighbourStart ||
                     host.edgeTetStart != was.edgeTetStart || host.edgeTets != was.edgeTets;
  if (model) {
    m_from = {};  // a failed copy is retried at the next call
    const size_t cells = size_t(host.cells);
    const size_t neighbours = host.nonLocal ? size_t(host.average.neighbourStart[T]) : 0;
    if (!m_tetEdges.upload(host.edges.tetEdges, 6 * T) ||
        !m_edgeDirections.upload(host.edges.edgeDirections, 18 * T) ||
        !m_gridStart.upload(host.nonLocal ? host.grid.start : nullptr, cells + 1) ||
        !m_gridItems.upload(host.nonLocal ? host.grid.items : nullptr, T) ||
        !m_gridCell.upload(host.nonLocal ? host.grid.tetCell : nullptr, T) ||
        !m_neighbourStart.upload(host.nonLocal ? host.average.neighbourStart : nullptr, T + 1) ||
        !m_neighbourIndex.upload(host.average.neighbourIndex, neighbours) ||
        !m_neighbourWeight.upload(host.average.neighbourWeight, neighbours) ||
        !m_edgeTetStart.upload(host.edgeTetStart, E + 1) ||
        !m_edgeTets.upload(host.edgeTets, size_t(host.edgeTetStart[E])) ||
        !m_candidates.resize(T) || !m_edgeFlag.resize(E) || !m_edgeStress.resize(E) ||
        !m_edgeTet.resize(E) || !m_candidateEdges.resize(E) ||
        !m_chunkCount.resize(size_t(chunks)) || !m_chunkOffset.resize(size_t(chunks) + 1) ||
        (host.nonLocal &&
         (!m_averaged.resize(6 * T) || !m_bound.resize(T) || !m_cellMax.resize(cells))))
      return fail("uploading the fracture criterion");
    m_from = host;
  }
  if (!mirrorChanged(m_strength, m_strengthCopy, host.edges.strength, E) ||
      !mirrorChanged(m_broken, m_brokenCopy, host.edges.broken, E))
    return fail("uploading the strengths");
  detail::CriterionView d = host;
  d.edges = {m_tetEdges.data(), m_edgeDirections.data(), m_strength.data(), m_broken.data()};
  if (host.nonLocal) {
    d.grid.start = m_gridStart.data();
    d.grid.items = m_gridItems.data();
    d.grid.tetCell = m_gridCell.data();
    d.average = {m_neighbourStart.data(), m_neighbourIndex.data(), m_neighbourWeight.data()};
  }
  d.edgeTetStart = m_edgeTetStart.data();
  d.edgeTets = m_edgeTets.data();
  d.averaged = m_averaged.data();
  d.candidates = m_candidates.data();
  d.bound = m_bound.data();
  d.cellMax = m_cellMax.data();
  d.edgeFlag = m_edgeFlag.data();
  d.edgeStress = m_edgeStress.data();
  d.edgeTet = m_edgeTet.data();
  d.chunkCount = m_chunkCount.data();
  d.chunkOffset = m_chunkOffset.data();
  d.candidateEdges = m_candidateEdges.data();
  bool read = true;
  const int32_t count =
      detail::findCandidateEdges(m_exec, d, stress, weakest, [&read](const int32_t* p) {
        int32_t v = 0;
        read = read && synchronize() && copyToHost(&v, p, sizeof v);
        return v;
      });
  if (!read || m_exec.takeFailure() || !synchronize()) return fail("running the criterion");
  if (count <= 0) return count;
  // Only the candidates' stresses and tets come back, into host's per-edge arrays.
  const size_t n = size_t(count);
  if (!m_compactStress.resize(n) || !m_compactTet.resize(n)) return fail("reading the candidates");
  m_exec.run(
      count, 256,
      detail::CandidateGatherStage{m_candidateEdges.data(), m_edgeStress.data(), m_edgeTet.data(),
                                   m_compactStress.data(), m_compactTet.data()});
  m_stressCopy.resize(n);
  m_tetCopy.resize(n);
  if (!synchronize() ||
      !copyToHost(host.candidateEdges, m_candidateEdges.data(), n * sizeof(int32_t)) ||
      !m_compactStress.download(m_stressCopy.data(), n) ||
      !m_compactTet.download(m_tetCopy.data(), n))
    return fail("reading the candidates");
  for (size_t i = 0; i < n; ++i) {
    host.edgeStress[host.candidateEdges[i]] = m_stressCopy[i];
    host.edgeTet[host.candidateEdges[i]] = m_tetCopy[i];
  }
  return count;
}

}  // namespace GF_GPU_ABI
}  // namespace gf::gpu
