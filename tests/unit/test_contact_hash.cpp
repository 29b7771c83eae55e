// The executor's scan and radix sort (step/scan.h) and body contact's spatial hash on them
// (contact/contact_hash.h) against plain serial truths: std::stable_sort, running sums and a
// brute-force test of every box against every other; the same bits for any thread count.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

#include "contact/contact_hash.h"
#include "graphfrac/jobs.h"
#include "step/executor.h"
#include "step/scan.h"

namespace gf::detail {
namespace {

TEST(ExecutorScan, ExclusiveScanIsTheRunningSumForAnyThreadCount) {
  for (int32_t count : {0, 1, 1023, 1024, 5 * kCompactChunk + 17}) {
    std::mt19937 rng(unsigned(count) + 3);
    std::vector<int32_t> counts(size_t(count) + 1);
    for (int32_t i = 0; i < count; ++i) counts[size_t(i)] = int32_t(rng() % 7);
    std::vector<int32_t> expect(size_t(count) + 1, 0);
    for (int32_t i = 0; i < count; ++i)
      expect[size_t(i) + 1] = expect[size_t(i)] + counts[size_t(i)];
    for (int threads : {1, 2, 4}) {
      ThreadPoolJobSystem jobs(threads);
      ScanScratch scratch;
      std::vector<int32_t> out(size_t(count) + 1, -1), inPlace = counts;
      EXPECT_EQ(exclusiveScan(CpuExecutor(jobs), counts.data(), count, out.data(), scratch),
                expect.back());
      EXPECT_EQ(out, expect) << count << " items, " << threads << " threads";
      exclusiveScan(CpuExecutor(jobs), inPlace.data(), count, inPlace.data(), scratch);
      EXPECT_EQ(inPlace, expect) << count << " items in place, " << threads << " threads";
    }
  }
}

TEST(ExecutorScan, RadixSortIsAStableSortForAnyThreadCount) {
  // Many equal keys (stability shows) over 20 bits, and keys with bits above the sorted ones
  // (they must not take part).
  const int32_t count = 7 * kCompactChunk + 100;
  std::mt19937_64 rng(5);
  std::vector<uint64_t> keys(static_cast<size_t>(count));
  for (uint64_t& k : keys) k = (rng() % 3000) | (uint64_t(rng() % 4) << 40);
  std::vector<int32_t> order(static_cast<size_t>(count));
  for (int32_t i = 0; i < count; ++i) order[size_t(i)] = i;
  const uint64_t mask = (uint64_t(1) << 20) - 1;
  std::stable_sort(order.begin(), order.end(), [&](int32_t a, int32_t b) {
    return (keys[size_t(a)] & mask) < (keys[size_t(b)] & mask);
  });
  for (int threads : {1, 2, 4}) {
    ThreadPoolJobSystem jobs(threads);
    ScanScratch scratch;
    std::vector<uint64_t> k = keys;
    std::vector<int32_t> v(static_cast<size_t>(count));
    for (int32_t i = 0; i < count; ++i) v[size_t(i)] = i;
    radixSort(CpuExecutor(jobs), k, v, 20, scratch);
    EXPECT_EQ(v, order) << threads << " threads";
    for (int32_t i = 0; i < count; ++i) ASSERT_EQ(k[size_t(i)], keys[size_t(order[size_t(i)])]);
  }
}

// Random boxes: most small; with `large`, every 97th spans many cells (more than the hash
// takes, so it is listed apart).
std::vector<double> randomBoxes(int32_t count, double size, unsigned seed, bool large) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> boxes(6 * size_t(count));
  for (int32_t b = 0; b < count; ++b) {
    const double s = large && b % 97 == 5 ? 40 * size : size * (0.2 + u(rng));
    for (int i = 0; i < 3; ++i) {
      const double lo = u(rng) - (b % 13 == 0 ? 0.6 : 0.0);  // some below zero: negative cells
      boxes[6 * size_t(b) + size_t(i)] = lo;
      boxes[6 * size_t(b) + 3 + size_t(i)] = lo + s * (0.5 + u(rng));
    }
  }
  return boxes;
}

TEST(ContactHash, EachQueryMeetsEveryOverlappingBoxOnceForAnyThreadCount) {
  const int32_t count = 3000, queries = 400;
  const double h = 0.02;
  const std::vector<double> boxes = randomBoxes(count, 0.03, 11, true);
  const std::vector<double> query = randomBoxes(queries, 0.05, 12, false);
  std::vector<uint8_t> include(static_cast<size_t>(count));
  std::mt19937 rng(13);
  for (uint8_t& f : include) f = rng() % 5 != 0 ? 1 : 0;

  std::vector<std::vector<int32_t>> first;
  int64_t met = 0, huge = 0;
  for (int threads : {1, 2, 4}) {
    ThreadPoolJobSystem jobs(threads);
    ContactHash hash;
    const ContactGrid grid = hash.build(CpuExecutor(jobs), include.data(), boxes.data(), count, h);
    huge = grid.hugeCount;
    std::vector<std::vector<int32_t>> visits(static_cast<size_t>(queries));
    for (int32_t q = 0; q < queries; ++q) {
      std::vector<int32_t>& seen = visits[size_t(q)];
      auto visit = [&](int32_t f) { seen.push_back(f); };
      grid.forFaces(&query[6 * size_t(q)], visit);
      std::vector<int32_t> sorted = seen;
      std::sort(sorted.begin(), sorted.end());
      EXPECT_TRUE(std::adjacent_find(sorted.begin(), sorted.end()) == sorted.end())
          << "query " << q << " met a box twice";
      for (int32_t f : sorted) EXPECT_TRUE(include[size_t(f)]) << "box " << f << " not hashed";
      for (int32_t f = 0; f < count; ++f)
        if (include[size_t(f)] && boxOverlap(&query[6 * size_t(q)], &boxes[6 * size_t(f)])) {
          EXPECT_TRUE(std::binary_search(sorted.begin(), sorted.end(), f))
              << "query " << q << " missed box " << f << " (" << threads << " threads)";
          ++met;
        }
    }
    if (first.empty())
      first = visits;
    else
      EXPECT_EQ(visits, first) << threads << " threads visit in another order";
  }
  // The case is not empty: boxes are met, and some are too large for the hash.
  EXPECT_GT(met, 3 * queries);
  EXPECT_GT(huge, 0);
}

}  // namespace
}  // namespace gf::detail
