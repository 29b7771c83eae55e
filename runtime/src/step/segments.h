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
#include "step/scan.h"

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

/// Item i's key widened for the radix sort, with its index as the value it carries.
struct SegmentKeyStage {
  const int32_t* key = nullptr;
  uint64_t* keys = nullptr;
  int32_t* values = nullptr;

  GF_HD void operator()(int32_t i) const {
    keys[i] = uint64_t(uint32_t(key[i]));
    values[i] = i;
  }
};

/// Boundary j in [0, items] of the items sorted by key: start[s] = j for every segment s after
/// the key before it and up to the key after it (keys -1 before the first item and `segments`
/// after the last), so each of the segments + 1 starts is written once, empty segments
/// included. sortedKeys null: every item in the last segment.
struct SegmentStartStage {
  const uint64_t* sortedKeys = nullptr;
  int32_t items = 0, segments = 0;
  int32_t* start = nullptr;  ///< segments + 1

  GF_HD int32_t keyAt(int32_t j) const {
    if (j < 0) return -1;
    if (j >= items) return segments;
    return sortedKeys ? int32_t(sortedKeys[j]) : segments - 1;
  }
  GF_HD void operator()(int32_t j) const {
    const int32_t to = keyAt(j);
    for (int32_t s = keyAt(j - 1) + 1; s <= to; ++s) start[s] = j;
  }
};

/// Segment s's chunk count, scanned into the segments' first chunks.
struct SegmentChunkCountStage {
  const int32_t* start = nullptr;
  int32_t* chunks = nullptr;
  GF_HD void operator()(int32_t s) const { chunks[s] = sumChunks(start[s + 1] - start[s]); }
};

/// Segment s's chunks mapped back to it.
struct SegmentChunkFillStage {
  const int32_t* chunkStart = nullptr;
  int32_t* chunkSegment = nullptr;
  GF_HD void operator()(int32_t s) const {
    for (int32_t c = chunkStart[s]; c < chunkStart[s + 1]; ++c) chunkSegment[c] = s;
  }
};

/// The lists behind a Segments view, built on the executor when the grouping changes (for the
/// pieces of a body: only on steps where it split): a stable radix sort of the items by key
/// (step/scan.h), the segments' starts from the sorted keys, and a scan of their chunk counts.
class SegmentLists {
 public:
  /// Items grouped by key[i] in 0..segments-1, in index order inside each; key null: one
  /// segment of every item, in index order. Every item keeps its index order inside its
  /// segment (the sort is stable), so the lists depend on the keys only. Exec is CpuExecutor;
  /// the lists are host vectors.
  template <class Exec>
  void build(const Exec& exec, const int32_t* key, int32_t items, int32_t segments,
             ScanScratch& s) {
    m_start.resize(size_t(segments) + 1);
    m_order.clear();
    const uint64_t* sortedKeys = nullptr;
    if (key) {
      s.sortKeys.resize(size_t(items));
      m_order.resize(size_t(items));
      exec.run(items, 1024, SegmentKeyStage{key, s.sortKeys.data(), m_order.data()});
      int bits = 0;
      while (bits < 31 && (int64_t(1) << bits) < int64_t(segments)) ++bits;
      radixSort(exec, s.sortKeys, m_order, bits, s);
      sortedKeys = s.sortKeys.data();
    }
    exec.run(items + 1, 1024, SegmentStartStage{sortedKeys, items, segments, m_start.data()});
    m_chunkStart.resize(size_t(segments) + 1);
    exec.run(segments, 1024, SegmentChunkCountStage{m_start.data(), m_chunkStart.data()});
    const int32_t chunks =
        exclusiveScan(exec, m_chunkStart.data(), segments, m_chunkStart.data(), s);
    m_chunkSegment.resize(size_t(chunks));
    exec.run(segments, 64, SegmentChunkFillStage{m_chunkStart.data(), m_chunkSegment.data()});
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
