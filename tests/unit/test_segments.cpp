// The segmented reduction (step/segments.h) behind the free pieces' sums, the lists it runs over
// (built by stages, against a plain counting sort) and the compaction behind the fracture
// criterion's candidate list (fracture/fracture_stages.h): same bits for any thread count, and
// each segment summed exactly as the executor sums an array.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
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
  ScanScratch scratch;
  lists.build(CpuExecutor(serialJobs()), key.data(), items, segments, scratch);
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
  ScanScratch scratch;
  lists.build(CpuExecutor(serialJobs()), nullptr, items, 1, scratch);
  ThreadPoolJobSystem four(4);
  const double expect = CpuExecutor(four).sum(values.data(), items);
  EXPECT_EQ(segmentedSums(four, lists, values, items, 1)[0], expect);
}

// The lists as a plain counting sort builds them: each segment's items in index order, its
// chunks, and the chunks mapped back (the serial code the stages replaced).
struct CountingSortLists {
  std::vector<int32_t> start, order, chunkStart, chunkSegment;
};

CountingSortLists countingSort(const std::vector<int32_t>& key, int32_t segments) {
  CountingSortLists c;
  std::vector<std::vector<int32_t>> bucket(static_cast<size_t>(segments));
  for (int32_t i = 0; i < int32_t(key.size()); ++i) bucket[size_t(key[size_t(i)])].push_back(i);
  c.start.push_back(0);
  c.chunkStart.push_back(0);
  for (int32_t s = 0; s < segments; ++s) {
    const auto& b = bucket[size_t(s)];
    c.order.insert(c.order.end(), b.begin(), b.end());
    c.start.push_back(int32_t(c.order.size()));
    const int32_t chunks = (int32_t(b.size()) + kSumChunk - 1) / kSumChunk;
    c.chunkStart.push_back(c.chunkStart.back() + chunks);
    c.chunkSegment.insert(c.chunkSegment.end(), size_t(chunks), s);
  }
  return c;
}

void expectLists(const Segments& v, const CountingSortLists& c, bool identity, const char* what) {
  ASSERT_EQ(v.count + 1, int32_t(c.start.size())) << what;
  ASSERT_EQ(v.chunks, int32_t(c.chunkSegment.size())) << what;
  EXPECT_EQ(std::vector<int32_t>(v.start, v.start + v.count + 1), c.start) << what;
  EXPECT_EQ(std::vector<int32_t>(v.chunkStart, v.chunkStart + v.count + 1), c.chunkStart) << what;
  EXPECT_EQ(std::vector<int32_t>(v.chunkSegment, v.chunkSegment + v.chunks), c.chunkSegment)
      << what;
  if (identity)
    EXPECT_EQ(v.order, nullptr) << what;
  else
    EXPECT_EQ(std::vector<int32_t>(v.order, v.order + c.order.size()), c.order) << what;
}

TEST(SegmentLists, StagesGroupLikeACountingSortOnAnyThreadCount) {
  // Segment counts that take no radix pass (1), one (2, 200), two (1000) and three (70000),
  // with empty segments (more segments than items in the last cases) and skewed keys.
  struct Case {
    int32_t items, segments;
  };
  std::mt19937 rng(17);
  ThreadPoolJobSystem one(1), two(2), four(4);
  for (const Case& k : {Case{5000, 1}, Case{3000, 2}, Case{20000, 200}, Case{7001, 1000},
                        Case{40000, 70000}, Case{0, 3}, Case{1, 4}}) {
    std::vector<int32_t> key(size_t(k.items));
    for (int32_t& x : key) {
      const uint32_t r = rng();
      // Half the items in a few large segments, the rest spread over all of them.
      x = int32_t(r % 2 ? (r >> 1) % uint32_t(std::min(k.segments, 3))
                        : (r >> 1) % uint32_t(k.segments));
    }
    const CountingSortLists truth = countingSort(key, k.segments);
    const std::string what =
        std::to_string(k.items) + " items, " + std::to_string(k.segments) + " segments";
    for (JobSystem* jobs : {static_cast<JobSystem*>(&one), static_cast<JobSystem*>(&two),
                            static_cast<JobSystem*>(&four)}) {
      SegmentLists lists;
      ScanScratch scratch;
      lists.build(CpuExecutor(*jobs), key.data(), k.items, k.segments, scratch);
      expectLists(lists.view(), truth, false, what.c_str());
      // Rebuilt with the same scratch (a later split): the same lists again.
      lists.build(CpuExecutor(*jobs), key.data(), k.items, k.segments, scratch);
      expectLists(lists.view(), truth, false, what.c_str());
    }
  }
  // No keys: one segment of every item in index order.
  SegmentLists lists;
  ScanScratch scratch;
  lists.build(CpuExecutor(serialJobs()), nullptr, 3000, 1, scratch);
  expectLists(lists.view(), countingSort(std::vector<int32_t>(3000, 0), 1), true, "no keys");
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
