// The spatial hash of body contact's broad phase (contact/body_contact.h), built on the
// executor: each box's cells are counted by a stage, placed by an exclusive scan and written by
// a second pass of the same stage, then radix-sorted by their hash bucket (stable, so the
// entries of a bucket stay in box and cell order); boxes over too many cells are listed apart.
// The same arrays for any thread count.
#pragma once

#include <cstdint>
#include <vector>

#include "contact/contact_stages.h"
#include "step/scan.h"

namespace gf::detail {

class ContactHash {
 public:
  /// Hashes the boxes (6 each: lower x, y, z, upper x, y, z) of the `count` items flagged in
  /// `include` into cells of size h. The grid reads `boxes` and this object's arrays, valid
  /// until the next build.
  template <class Exec>
  ContactGrid build(const Exec& exec, const uint8_t* include, const double* boxes, int32_t count,
                    double h) {
    m_start.resize(size_t(count) + 1);
    m_huge.resize(size_t(count));
    ContactCellStage cells{include, boxes, h, 1, nullptr, m_start.data(), m_huge.data()};
    exec.run(count, 1024, cells);
    const int32_t entries = exclusiveScan(exec, m_start.data(), count, m_start.data(), m_scan);
    int bits = 1;
    while (bits < 31 && (int64_t(1) << bits) < entries) ++bits;
    cells.bits = bits;
    cells.start = m_start.data();
    m_key.resize(size_t(entries));
    m_cell.resize(size_t(entries));
    m_face.resize(size_t(entries));
    m_value.resize(size_t(entries));
    cells.bucket = m_key.data();
    cells.cell = m_cell.data();
    cells.face = m_face.data();
    cells.fillIndex = m_value.data();
    exec.run(count, 1024, cells);
    radixSort(exec, m_key, m_value, bits, m_scan);
    // Each bucket's run of entries, so that a query finds it in O(1).
    const int32_t buckets = int32_t(1) << bits;
    m_bucketStart.resize(size_t(buckets) + 1);
    exec.run(entries + 1, 1024,
             ContactBucketStartStage{m_key.data(), entries, buckets, m_bucketStart.data()});
    const int32_t chunks = (count + kCompactChunk - 1) / kCompactChunk;
    m_chunkCount.resize(size_t(chunks));
    m_chunkOffset.resize(size_t(chunks) + 1);
    exec.run(chunks, 4, CompactCountStage{m_huge.data(), count, m_chunkCount.data()});
    exec.run(1, 1, CompactOffsetStage{m_chunkCount.data(), chunks, m_chunkOffset.data()});
    m_hugeList.resize(size_t(m_chunkOffset[size_t(chunks)]));
    exec.run(chunks, 4,
             CompactScatterStage{m_huge.data(), count, m_chunkOffset.data(), m_hugeList.data()});
    return {h,
            bits,
            m_bucketStart.data(),
            m_value.data(),
            m_cell.data(),
            m_face.data(),
            entries,
            m_hugeList.data(),
            int32_t(m_hugeList.size()),
            boxes};
  }

 private:
  std::vector<int32_t> m_start, m_face, m_value, m_hugeList, m_chunkCount, m_chunkOffset,
      m_bucketStart;
  std::vector<uint8_t> m_huge;
  std::vector<uint64_t> m_key, m_cell;
  ScanScratch m_scan;
};

}  // namespace gf::detail
