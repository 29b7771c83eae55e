// The segmented reduction (step/segments.h) behind the free pieces' sums and the compaction
// behind the fracture criterion's candidate list (fracture/fracture_stages.h): same bits for
// any thread count, and each segment summed exactly as the executor sums an array.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "fracture/fracture_stages.h"
#include "graphfrac/jobs.h"
#include "step/executor.h"
#include "step/segments.h"

namespace gf::detail {
namespace {

std::vector<double> randomValues(size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> v(n);
  for (double& x : v) x = u(rng) * std::exp(8 * u(rng));  // spread exponents: order matters
  return v;
}

std::vector<double> segmentedSums(JobSystem& jobs, const SegmentLists& lists,
                                  const std::vector<double>& values, int32_t items,
                                  int components) {
  const Segments seg = lists.view();
  std::vector<double> partials(size_t(components) * size_t(seg.chunks));
  std::vector<double> out(size_t(components) * size_t(seg.count));
  segmentedReduce<SumOp>(CpuExecutor(jobs), seg, values.data(), items, components, partials.data(),
                         out.data());
  return out;
}

TEST(SegmentedReduce, EachSegmentSumsLikeTheExecutorAndBitsDoNotDependOnThreads) {
  // Five segments: one large (many chunks), one of a single item, one empty, two mid-sized,
  // their items interleaved over the index range.
  const int32_t items = 9001, segments = 5, components = 3;
  std::vector<int32_t> key(items);
  std::mt19937 rng(7);
  for (int32_t i = 0; i < items; ++i) {
    const unsigned r = rng() % 100;
    key[size_t(i)] = r < 70 ? 0 : (r < 85 ? 3 : 4);
  }
  key[4321] = 1;
  SegmentLists lists;
  lists.build(key.data(), items, segments);
  const std::vector<double> values = randomValues(size_t(components) * items, 3);

  ThreadPoolJobSystem one(1), four(4);
  const std::vector<double> s1 = segmentedSums(one, lists, values, items, components);
  const std::vector<double> s4 = segmentedSums(four, lists, values, items, components);
  ASSERT_EQ(s1.size(), s4.size());
  EXPECT_EQ(std::memcmp(s1.data(), s4.data(), 8 * s1.size()), 0);

  for (int k = 0; k < components; ++k)
    for (int32_t s = 0; s < segments; ++s) {
      std::vector<double> mine;
      for (int32_t i = 0; i < items; ++i)
        if (key[size_t(i)] == s) mine.push_back(values[size_t(k) * items + size_t(i)]);
      const double expect = chunkedReduce<SumOp>(ArrayTerm{mine.data()}, int32_t(mine.size()));
      EXPECT_EQ(s1[size_t(k) * segments + size_t(s)], expect)
          << "component " << k << " segment " << s;
    }
  EXPECT_EQ(s1[2], 0.0);  // the empty segment
}

TEST(SegmentedReduce, OneSegmentIsTheExecutorsSum) {
  const int32_t items = 5000;
  const std::vector<double> values = randomValues(items, 11);
  SegmentLists lists;
  lists.build(nullptr, items, 1);
  ThreadPoolJobSystem four(4);
  const double expect = CpuExecutor(four).sum(values.data(), items);
  EXPECT_EQ(segmentedSums(four, lists, values, items, 1)[0], expect);
}

TEST(Compaction, ListsTheFlaggedIndicesInOrder) {
  const int32_t count = 5 * kCompactChunk + 17;
  std::vector<uint8_t> flag(count);
  std::mt19937 rng(5);
  std::vector<int32_t> expect;
  for (int32_t i = 0; i < count; ++i) {
    flag[size_t(i)] = rng() % 7 == 0;
    if (flag[size_t(i)]) expect.push_back(i);
  }
  ThreadPoolJobSystem four(4);
  const CpuExecutor exec(four);
  const int32_t chunks = (count + kCompactChunk - 1) / kCompactChunk;
  std::vector<int32_t> chunkCount(chunks), chunkOffset(chunks + 1);
  exec.run(chunks, 1, CompactCountStage{flag.data(), count, chunkCount.data()});
  exec.run(1, 1, CompactOffsetStage{chunkCount.data(), chunks, chunkOffset.data()});
  std::vector<int32_t> out(static_cast<size_t>(chunkOffset[size_t(chunks)]));
  exec.run(chunks, 1, CompactScatterStage{flag.data(), count, chunkOffset.data(), out.data()});
  EXPECT_EQ(out, expect);
}

}  // namespace
}  // namespace gf::detail
