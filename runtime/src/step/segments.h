// Segmented reductions: one result per segment (per free piece of a body: its mass, momentum,
// inertia) over items grouped by segment, in one fixed order for either executor: chunks of
// kSumChunk items that never straddle a segment, each in chunkReduce's order, then each
// segment's chunks in chunk order. O(items + segments) and parallel over the chunks of all
// segments, so one large piece is not summed by one thread; a single segment of every item in
// index order gives exactly the bits of chunkedReduce.
#pragma once

#include <cstdint>
#include <vector>

#include "step/reduce.h"

namespace gf::detail {

/// Segment s holds items order[start[s]] .. order[start[s + 1] - 1] (order null: the identity)
/// and chunks chunkStart[s] .. chunkStart[s + 1] - 1; chunkSegment maps a chunk back.
struct Segments {
  const int32_t* start = nullptr;  ///< count + 1
  const int32_t* order = nullptr;
  const int32_t* chunkStart = nullptr;    ///< count + 1
  const int32_t* chunkSegment = nullptr;  ///< chunks
  int32_t count = 0, chunks = 0;
};

/// The items of one segment as a reduction term over their positions in it.
struct SegmentTerm {
  const double* values = nullptr;
  const int32_t* order = nullptr;
  int32_t base = 0;
  GF_HD double operator()(int32_t i) const { return values[order ? order[base + i] : base + i]; }
};

/// Chunk c of every component (component k of item i at values[k stride + i]) into
/// partials[k chunks + c].
template <class Op>
struct SegmentChunkStage {
  Segments seg;
  const double* values = nullptr;
  int64_t stride = 0;
  int components = 0;
  double* partials = nullptr;

  GF_HD void operator()(int32_t c) const {
    const int32_t s = seg.chunkSegment[c];
    const int32_t base = seg.start[s], length = seg.start[s + 1] - base;
    for (int k = 0; k < components; ++k)
      partials[k * int64_t(seg.chunks) + c] = chunkReduce<Op>(
          SegmentTerm{values + k * stride, seg.order, base}, length, c - seg.chunkStart[s]);
  }
};

/// Segment s of every component into out[k count + s] (Op's identity for an empty segment).
template <class Op>
struct SegmentTotalStage {
  Segments seg;
  const double* partials = nullptr;
  int components = 0;
  double* out = nullptr;

  GF_HD void operator()(int32_t s) const {
    for (int k = 0; k < components; ++k) {
      double r = Op::identity();
      for (int32_t c = seg.chunkStart[s]; c < seg.chunkStart[s + 1]; ++c)
        r = Op::apply(r, partials[k * int64_t(seg.chunks) + c]);
      out[k * int64_t(seg.count) + s] = r;
    }
  }
};

/// Op per segment of `components` arrays of `stride` items each into out (components *
/// seg.count); partials holds components * seg.chunks.
template <class Op, class Exec>
void segmentedReduce(const Exec& exec, const Segments& seg, const double* values, int64_t stride,
                     int components, double* partials, double* out) {
  exec.run(seg.chunks, 4, SegmentChunkStage<Op>{seg, values, stride, components, partials});
  exec.run(seg.count, 64, SegmentTotalStage<Op>{seg, partials, components, out});
}

/// The lists behind a Segments view, built on the host when the grouping changes (for the
/// pieces of a body: only on steps where it split).
class SegmentLists {
 public:
  /// Items grouped by key[i] in 0..segments-1, in index order inside each; key null: one
  /// segment of every item, in index order.
  void build(const int32_t* key, int32_t items, int32_t segments) {
    m_start.assign(size_t(segments) + 1, 0);
    m_order.clear();
    if (key) {
      for (int32_t i = 0; i < items; ++i) ++m_start[size_t(key[i]) + 1];
      for (int32_t s = 0; s < segments; ++s) m_start[size_t(s) + 1] += m_start[size_t(s)];
      m_order.resize(size_t(items));
      std::vector<int32_t> fill(m_start.begin(), m_start.end() - 1);
      for (int32_t i = 0; i < items; ++i) m_order[size_t(fill[size_t(key[i])]++)] = i;
    } else {
      m_start.back() = items;
    }
    m_chunkStart.assign(size_t(segments) + 1, 0);
    m_chunkSegment.clear();
    for (int32_t s = 0; s < segments; ++s) {
      const int32_t chunks = sumChunks(m_start[size_t(s) + 1] - m_start[size_t(s)]);
      m_chunkStart[size_t(s) + 1] = m_chunkStart[size_t(s)] + chunks;
      m_chunkSegment.insert(m_chunkSegment.end(), size_t(chunks), s);
    }
  }
  Segments view() const {
    return {m_start.data(),
            m_order.empty() ? nullptr : m_order.data(),
            m_chunkStart.data(),
            m_chunkSegment.data(),
            int32_t(m_start.size()) - 1,
            int32_t(m_chunkSegment.size())};
  }

 private:
  std::vector<int32_t> m_start, m_order, m_chunkStart, m_chunkSegment;
};

}  // namespace gf::detail
