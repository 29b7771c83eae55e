// Scans, compactions and sorts on the executor (step/executor.h), for the lists a step builds
// anew (the fracture criterion's candidate edges, body contact's grid and pairs). Every pass
// works on fixed chunks of items, each chunk in index order, and the chunks' totals are
// combined in chunk order on one item, so the result is the same for any thread count or
// launch shape: a list built by count, scan and fill comes out in item order, and the radix
// sort is stable.
#pragma once

#include <cstdint>
#include <vector>

#include "kernels/gf_hd.h"

namespace gf::detail {

/// Items per chunk of a compaction or a scan.
constexpr int32_t kCompactChunk = 1024;

/// The number of set flags in chunk c of a compaction.
struct CompactCountStage {
  const uint8_t* flag = nullptr;
  int32_t count = 0;
  int32_t* chunkCount = nullptr;

  GF_HD void operator()(int32_t c) const {
    const int32_t end = (c + 1) * kCompactChunk < count ? (c + 1) * kCompactChunk : count;
    int32_t n = 0;
    for (int32_t i = c * kCompactChunk; i < end; ++i) n += flag[i] ? 1 : 0;
    chunkCount[c] = n;
  }
};

/// One item: chunkOffset[c] = the set flags before chunk c (chunks + 1 entries).
struct CompactOffsetStage {
  const int32_t* chunkCount = nullptr;
  int32_t chunks = 0;
  int32_t* chunkOffset = nullptr;

  GF_HD void operator()(int32_t) const {
    chunkOffset[0] = 0;
    for (int32_t c = 0; c < chunks; ++c) chunkOffset[c + 1] = chunkOffset[c] + chunkCount[c];
  }
};

/// The indices of chunk c's set flags, in index order, at out[chunkOffset[c]..].
struct CompactScatterStage {
  const uint8_t* flag = nullptr;
  int32_t count = 0;
  const int32_t* chunkOffset = nullptr;
  int32_t* out = nullptr;

  GF_HD void operator()(int32_t c) const {
    const int32_t end = (c + 1) * kCompactChunk < count ? (c + 1) * kCompactChunk : count;
    int32_t o = chunkOffset[c];
    for (int32_t i = c * kCompactChunk; i < end; ++i)
      if (flag[i]) out[o++] = i;
  }
};

/// The sum of chunk c's counts.
struct ScanChunkStage {
  const int32_t* counts = nullptr;
  int32_t count = 0;
  int32_t* chunkSum = nullptr;

  GF_HD void operator()(int32_t c) const {
    const int32_t end = (c + 1) * kCompactChunk < count ? (c + 1) * kCompactChunk : count;
    int32_t n = 0;
    for (int32_t i = c * kCompactChunk; i < end; ++i) n += counts[i];
    chunkSum[c] = n;
  }
};

/// Chunk c's exclusive prefix sums from its offset; out may be counts (each item is read
/// before it is written). The chunk holding the last item also writes the total at out[count].
struct ScanWriteStage {
  const int32_t* counts = nullptr;
  int32_t count = 0;
  const int32_t* chunkOffset = nullptr;
  int32_t* out = nullptr;

  GF_HD void operator()(int32_t c) const {
    const int32_t end = (c + 1) * kCompactChunk < count ? (c + 1) * kCompactChunk : count;
    int32_t o = chunkOffset[c];
    for (int32_t i = c * kCompactChunk; i < end; ++i) {
      const int32_t n = counts[i];
      out[i] = o;
      o += n;
    }
    if (end == count) out[count] = o;
  }
};

/// Scratch of the scans and sorts, kept by the caller so that a step allocates nothing after
/// warm-up.
struct ScanScratch {
  std::vector<int32_t> chunkSum, chunkOffset, histogram;
  std::vector<uint64_t> keys;
  std::vector<int32_t> values;
  std::vector<uint64_t> sortKeys;  // a sort's own keys (SegmentLists)
};

/// out[i] = counts[0] + ... + counts[i - 1] for i in [0, count] (out holds count + 1; it may be
/// counts, then counts needs count + 1 entries). Returns the total.
template <class Exec>
int32_t exclusiveScan(const Exec& exec, const int32_t* counts, int32_t count, int32_t* out,
                      ScanScratch& s) {
  if (count <= 0) {
    out[0] = 0;
    return 0;
  }
  const int32_t chunks = (count + kCompactChunk - 1) / kCompactChunk;
  s.chunkSum.resize(size_t(chunks));
  s.chunkOffset.resize(size_t(chunks) + 1);
  exec.run(chunks, 4, ScanChunkStage{counts, count, s.chunkSum.data()});
  exec.run(1, 1, CompactOffsetStage{s.chunkSum.data(), chunks, s.chunkOffset.data()});
  exec.run(chunks, 4, ScanWriteStage{counts, count, s.chunkOffset.data(), out});
  return out[count];
}

/// Bits of a radix sort's digit.
constexpr int kRadixBits = 8;
constexpr int32_t kRadixDigits = 1 << kRadixBits;

/// How many items of chunk c have each digit, digit-major (histogram[d chunks + c]): its
/// exclusive scan is where chunk c's first item of digit d goes in a stable sort.
struct RadixCountStage {
  const uint64_t* keys = nullptr;
  int32_t count = 0, chunks = 0;
  int shift = 0;
  int32_t* histogram = nullptr;

  GF_HD void operator()(int32_t c) const {
    for (int32_t d = 0; d < kRadixDigits; ++d) histogram[int64_t(d) * chunks + c] = 0;
    const int32_t end = (c + 1) * kCompactChunk < count ? (c + 1) * kCompactChunk : count;
    for (int32_t i = c * kCompactChunk; i < end; ++i)
      ++histogram[int64_t((keys[i] >> shift) & uint64_t(kRadixDigits - 1)) * chunks + c];
  }
};

/// Chunk c's items to their places, in index order (stable); it moves only its own offsets.
struct RadixScatterStage {
  const uint64_t* keys = nullptr;
  const int32_t* values = nullptr;
  int32_t count = 0, chunks = 0;
  int shift = 0;
  int32_t* offset = nullptr;  ///< the scanned histogram
  uint64_t* keysOut = nullptr;
  int32_t* valuesOut = nullptr;

  GF_HD void operator()(int32_t c) const {
    const int32_t end = (c + 1) * kCompactChunk < count ? (c + 1) * kCompactChunk : count;
    for (int32_t i = c * kCompactChunk; i < end; ++i) {
      const int64_t d = int64_t((keys[i] >> shift) & uint64_t(kRadixDigits - 1));
      const int32_t to = offset[d * chunks + c]++;
      keysOut[to] = keys[i];
      valuesOut[to] = values[i];
    }
  }
};

/// Sorts (keys, values) by the low `bits` bits of the keys, stably (equal keys keep their
/// order), one least-significant-digit pass per kRadixBits.
template <class Exec>
void radixSort(const Exec& exec, std::vector<uint64_t>& keys, std::vector<int32_t>& values,
               int bits, ScanScratch& s) {
  const int32_t count = int32_t(keys.size());
  if (count < 2) return;
  const int32_t chunks = (count + kCompactChunk - 1) / kCompactChunk;
  s.histogram.resize(size_t(kRadixDigits) * size_t(chunks) + 1);
  s.keys.resize(size_t(count));
  s.values.resize(size_t(count));
  for (int shift = 0; shift < bits; shift += kRadixBits) {
    exec.run(chunks, 4, RadixCountStage{keys.data(), count, chunks, shift, s.histogram.data()});
    exclusiveScan(exec, s.histogram.data(), kRadixDigits * chunks, s.histogram.data(), s);
    exec.run(chunks, 4,
             RadixScatterStage{keys.data(), values.data(), count, chunks, shift, s.histogram.data(),
                               s.keys.data(), s.values.data()});
    keys.swap(s.keys);
    values.swap(s.values);
  }
}

}  // namespace gf::detail
