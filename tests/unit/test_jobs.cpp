// Job systems: every index is covered exactly once, ranges respect the grain, nested and
// concurrent calls complete, and the serial system runs on the calling thread.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "graphfrac/jobs.h"

namespace {

// Runs one parallelFor and checks coverage and range sizes.
void checkCoverage(gf::JobSystem& jobs, uint32_t count, uint32_t grain) {
  std::vector<std::atomic<int>> hits(count);
  for (auto& h : hits) h.store(0);
  std::atomic<int> shortRanges{0};
  std::atomic<int> badRanges{0};
  jobs.parallelFor(count, grain, [&](uint32_t begin, uint32_t end) {
    if (begin >= end || end > count) {
      badRanges.fetch_add(1);
      return;
    }
    // Only the range that ends at count may be shorter than the grain.
    if (end - begin < grain && end != count) shortRanges.fetch_add(1);
    for (uint32_t i = begin; i < end; ++i) hits[i].fetch_add(1);
  });
  EXPECT_EQ(badRanges.load(), 0) << "count " << count << " grain " << grain;
  EXPECT_EQ(shortRanges.load(), 0) << "count " << count << " grain " << grain;
  int wrong = 0;
  for (uint32_t i = 0; i < count; ++i) wrong += hits[i].load() != 1;
  EXPECT_EQ(wrong, 0) << "count " << count << " grain " << grain;
}

TEST(Jobs, SerialCoversOnceOnCallingThread) {
  gf::SerialJobSystem jobs;
  EXPECT_EQ(jobs.threadCount(), 1);
  const std::thread::id self = std::this_thread::get_id();
  bool otherThread = false;
  int calls = 0;
  jobs.parallelFor(1000, 7, [&](uint32_t, uint32_t) {
    ++calls;
    otherThread |= std::this_thread::get_id() != self;
  });
  EXPECT_FALSE(otherThread);
  EXPECT_GE(calls, 1);
  for (uint32_t count : {0u, 1u, 5u, 1000u})
    for (uint32_t grain : {0u, 1u, 3u, 4096u}) checkCoverage(jobs, count, grain);
  EXPECT_EQ(&gf::serialJobs(), &gf::serialJobs());
  EXPECT_EQ(gf::serialJobs().threadCount(), 1);
}

TEST(Jobs, ThreadPoolCoversEveryIndexOnce) {
  for (int threads : {1, 2, 3, 4, 8}) {
    gf::ThreadPoolJobSystem jobs(threads);
    EXPECT_EQ(jobs.threadCount(), threads);
    for (uint32_t count : {0u, 1u, 2u, 3u, 7u, 64u, 100u, 1000u, 4097u, 100000u})
      for (uint32_t grain : {0u, 1u, 2u, 3u, 17u, 64u, 1000u, 1u << 20}) {
        checkCoverage(jobs, count, grain);
      }
  }
}

TEST(Jobs, ThreadPoolDefaultThreadCount) {
  gf::ThreadPoolJobSystem jobs;
  EXPECT_GE(jobs.threadCount(), 1);
  checkCoverage(jobs, 12345, 10);
}

// Many small back-to-back jobs: a worker that wakes late must never run a finished job's
// function (it would write a stale counter).
TEST(Jobs, ThreadPoolManyShortJobs) {
  gf::ThreadPoolJobSystem jobs(4);
  std::vector<int64_t> sums(64, 0);
  for (int rep = 0; rep < 3000; ++rep) {
    std::atomic<int64_t> sum{0};
    const uint32_t count = 1 + static_cast<uint32_t>(rep % 200);
    jobs.parallelFor(count, 1, [&](uint32_t begin, uint32_t end) {
      int64_t s = 0;
      for (uint32_t i = begin; i < end; ++i) s += i + 1;
      sum.fetch_add(s);
    });
    ASSERT_EQ(sum.load(), static_cast<int64_t>(count) * (count + 1) / 2) << "rep " << rep;
  }
}

TEST(Jobs, ThreadPoolNestedCallsRunInline) {
  gf::ThreadPoolJobSystem jobs(4);
  const uint32_t outer = 16, inner = 500;
  std::vector<std::atomic<int>> hits(outer * inner);
  for (auto& h : hits) h.store(0);
  jobs.parallelFor(outer, 1, [&](uint32_t b, uint32_t e) {
    for (uint32_t o = b; o < e; ++o) {
      jobs.parallelFor(inner, 8, [&](uint32_t ib, uint32_t ie) {
        for (uint32_t i = ib; i < ie; ++i) hits[o * inner + i].fetch_add(1);
      });
    }
  });
  int wrong = 0;
  for (auto& h : hits) wrong += h.load() != 1;
  EXPECT_EQ(wrong, 0);
}

TEST(Jobs, ThreadPoolConcurrentCallers) {
  gf::ThreadPoolJobSystem jobs(3);
  std::atomic<int> failures{0};
  auto caller = [&](uint32_t count) {
    for (int rep = 0; rep < 200; ++rep) {
      std::vector<std::atomic<int>> hits(count);
      for (auto& h : hits) h.store(0);
      jobs.parallelFor(count, 4, [&](uint32_t b, uint32_t e) {
        for (uint32_t i = b; i < e; ++i) hits[i].fetch_add(1);
      });
      for (auto& h : hits) failures += h.load() != 1;
    }
  };
  std::thread a(caller, 300u), b(caller, 517u);
  a.join();
  b.join();
  EXPECT_EQ(failures.load(), 0);
}

TEST(Jobs, ThreadPoolUsesWorkers) {
  // With enough ranges and some work per range, more than one thread takes part.
  gf::ThreadPoolJobSystem jobs(2);
  std::atomic<bool> otherThread{false};
  const std::thread::id self = std::this_thread::get_id();
  for (int rep = 0; rep < 50 && !otherThread.load(); ++rep) {
    jobs.parallelFor(64, 1, [&](uint32_t, uint32_t) {
      if (std::this_thread::get_id() != self) otherThread.store(true);
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    });
  }
  EXPECT_TRUE(otherThread.load());
}

// Consecutive jobs over the same data touch it from the same threads: each thread first runs
// the ranges of its own contiguous block (the caller the first half, the worker the second)
// instead of taking whichever range is next, which hands a vector's cache lines from core to
// core with every pass of a solver. Ranges long enough that the worker joins before the caller
// finishes its first one; a job the scheduler delayed is retried.
TEST(Jobs, ThreadPoolThreadsRunTheirOwnBlockOfRanges) {
  gf::ThreadPoolJobSystem jobs(2);
  const std::thread::id self = std::this_thread::get_id();
  bool split = false;
  std::string seen;
  for (int rep = 0; rep < 20 && !split; ++rep) {
    std::vector<int> byCaller(8, -1);
    jobs.parallelFor(64, 1, [&](uint32_t begin, uint32_t end) {
      EXPECT_EQ(end - begin, 8u);
      byCaller[begin / 8] = std::this_thread::get_id() == self;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    });
    split = byCaller == std::vector<int>{1, 1, 1, 1, 0, 0, 0, 0};
    seen.clear();
    for (int c : byCaller) seen += c ? 'C' : 'W';
  }
  EXPECT_TRUE(split) << "ranges by thread in the last job (C caller, W worker): " << seen;
}

}  // namespace
