// Job systems: the serial default and a small persistent thread pool.
//
// Design: one job at a time. parallelFor publishes the job (function, range size, range count)
// under a mutex, bumps a generation counter and wakes the workers; every participant (the
// caller included) claims ranges, from its own block first, until none are left. A worker may join
// a job only while it is open, and the caller closes it only once every worker that joined has
// left, so no worker can touch a job whose function has gone out of scope. Results never depend
// on which thread ran a range because callers write disjoint outputs (see jobs.h).
// A solver issues jobs back to back (a CG iteration is five short passes), and waking a
// sleeping thread costs tens of microseconds, as much as a pass on a mid-size body: so a worker
// that finished a job, and a caller waiting for its workers, first spin for a few microseconds
// on an atomic hint before they sleep. The hint only decides when to take the mutex; who may
// join and when a job closes is still decided under it, as above.
#include "graphfrac/jobs.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

namespace gf {

void SerialJobSystem::parallelFor(uint32_t count, uint32_t /*grain*/,
                                  const std::function<void(uint32_t, uint32_t)>& fn) {
  if (count > 0) fn(0, count);
}

namespace {
// Set on pool workers and on a caller while it runs a job, so that a nested parallelFor (from
// inside a range) runs inline instead of waiting on a pool that is busy with its parent.
thread_local bool t_insideJob = false;

// How long a worker or a waiting caller spins before it sleeps: longer than the serial gap
// between a solver's passes, short enough that an idle pool costs nothing measurable.
constexpr auto kSpin = std::chrono::microseconds(50);

inline void cpuRelax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#elif defined(__aarch64__)
  asm volatile("yield");
#endif
}

// Spins until done() or kSpin has passed; true when done() became true.
template <class Done>
bool spinUntil(const Done& done) {
  const auto end = std::chrono::steady_clock::now() + kSpin;
  for (int i = 1;; ++i) {
    if (done()) return true;
    cpuRelax();
    if (i % 64 == 0 && std::chrono::steady_clock::now() > end) return done();
  }
}
}  // namespace

struct ThreadPoolJobSystem::Impl {
  std::vector<std::thread> workers;
  std::mutex mutex;
  std::condition_variable wake;      // workers wait here for a new generation or stop
  std::condition_variable finished;  // the caller waits here for active == 0
  std::mutex callMutex;              // serialises parallelFor calls from different threads
  uint64_t generation = 0;
  bool stop = false;
  bool open = false;  // workers may join the current job
  int active = 0;     // workers that joined the current job and have not left yet
  // Copies of generation and active for the spins, written under `mutex` with them.
  std::atomic<uint64_t> generationHint{0};
  std::atomic<int> activeHint{0};

  // The current job; written under `mutex` before `generation` is bumped.
  const std::function<void(uint32_t, uint32_t)>* fn = nullptr;
  uint32_t count = 0;
  uint32_t rangeSize = 1;

  // Each participant (the caller is 0, worker i is i) owns a contiguous block of the ranges and
  // claims from it in order before it helps with the others' blocks: when the threads keep up
  // with each other, every thread works on the same part of the data in consecutive jobs (a
  // solver's passes over one vector), so its cache lines stay in that core's cache instead of
  // moving between cores with each pass; a thread that is late or slow still gets helped.
  struct alignas(64) Block {
    std::atomic<uint32_t> next{0};
    uint32_t end = 0;
  };
  std::unique_ptr<Block[]> blocks;
  int participants = 1;

  void runRanges(const std::function<void(uint32_t, uint32_t)>& f, uint32_t n, uint32_t size,
                 int self) {
    for (int k = 0; k < participants; ++k) {
      Block& b = blocks[(self + k) % participants];
      for (;;) {
        const uint32_t r = b.next.fetch_add(1, std::memory_order_relaxed);
        if (r >= b.end) break;
        const uint32_t begin = r * size;
        f(begin, std::min(n, begin + size));
      }
    }
  }

  void workerLoop(int self) {
    t_insideJob = true;
    uint64_t seen = 0;
    for (;;) {
      const std::function<void(uint32_t, uint32_t)>* f;
      uint32_t n, size;
      spinUntil([&] { return generationHint.load(std::memory_order_acquire) != seen; });
      {
        std::unique_lock<std::mutex> lock(mutex);
        wake.wait(lock, [&] { return stop || (generation != seen && open); });
        if (stop) return;
        seen = generation;
        activeHint.store(++active, std::memory_order_relaxed);
        f = fn;
        n = count;
        size = rangeSize;
      }
      runRanges(*f, n, size, self);
      {
        std::lock_guard<std::mutex> lock(mutex);
        activeHint.store(--active, std::memory_order_release);
        if (active == 0) finished.notify_one();
      }
    }
  }
};

ThreadPoolJobSystem::ThreadPoolJobSystem(int threads) : m_impl(std::make_unique<Impl>()) {
  if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  // The calling thread works too, so the pool starts threads - 1 workers.
  m_impl->participants = threads;
  m_impl->blocks = std::make_unique<Impl::Block[]>(static_cast<size_t>(threads));
  m_impl->workers.reserve(static_cast<size_t>(threads - 1));
  for (int i = 1; i < threads; ++i)
    m_impl->workers.emplace_back([this, i] { m_impl->workerLoop(i); });
}

ThreadPoolJobSystem::~ThreadPoolJobSystem() {
  {
    std::lock_guard<std::mutex> lock(m_impl->mutex);
    m_impl->stop = true;
    m_impl->generationHint.fetch_add(1, std::memory_order_release);
  }
  m_impl->wake.notify_all();
  for (std::thread& t : m_impl->workers) t.join();
}

int ThreadPoolJobSystem::threadCount() const {
  return static_cast<int>(m_impl->workers.size()) + 1;
}

void ThreadPoolJobSystem::parallelFor(uint32_t count, uint32_t grain,
                                      const std::function<void(uint32_t, uint32_t)>& fn) {
  if (count == 0) return;
  grain = std::max(grain, 1u);
  // About four ranges per thread balances uneven rows without making ranges tiny.
  const uint64_t threads = m_impl->workers.size() + 1;
  const uint64_t target = (static_cast<uint64_t>(count) + threads * 4 - 1) / (threads * 4);
  const uint32_t size = static_cast<uint32_t>(std::max<uint64_t>(grain, target));
  const uint32_t ranges = static_cast<uint32_t>((static_cast<uint64_t>(count) + size - 1) / size);
  if (ranges <= 1 || m_impl->workers.empty() || t_insideJob) {
    fn(0, count);
    return;
  }

  std::lock_guard<std::mutex> call(m_impl->callMutex);
  Impl& p = *m_impl;
  {
    std::lock_guard<std::mutex> lock(p.mutex);
    p.fn = &fn;
    p.count = count;
    p.rangeSize = size;
    for (int k = 0; k < p.participants; ++k) {
      const uint64_t begin = ranges * static_cast<uint64_t>(k) / p.participants;
      p.blocks[k].next.store(static_cast<uint32_t>(begin), std::memory_order_relaxed);
      p.blocks[k].end =
          static_cast<uint32_t>(ranges * static_cast<uint64_t>(k + 1) / p.participants);
    }
    p.open = true;
    ++p.generation;
    p.generationHint.store(p.generation, std::memory_order_release);
  }
  p.wake.notify_all();

  const bool wasInside = t_insideJob;
  t_insideJob = true;
  p.runRanges(fn, count, size, 0);
  t_insideJob = wasInside;

  // Every range has been claimed; wait for the workers still running theirs, then close the
  // job so a late worker cannot pick up a stale function.
  spinUntil([&] { return p.activeHint.load(std::memory_order_acquire) == 0; });
  std::unique_lock<std::mutex> lock(p.mutex);
  p.finished.wait(lock, [&] { return p.active == 0; });
  p.open = false;
  p.fn = nullptr;
}

JobSystem& serialJobs() {
  static SerialJobSystem jobs;
  return jobs;
}

}  // namespace gf
