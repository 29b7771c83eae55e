// Threading interface: the engine may plug in its own scheduler. Results never depend on the
// number of threads because every loop writes disjoint outputs and reductions use fixed chunks.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>

namespace gf {

/// Runs fn(begin, end) over [0, count) split into ranges of at least `grain` items. All calls
/// return before parallelFor returns. Implementations may run ranges on any thread.
class JobSystem {
 public:
  virtual ~JobSystem() = default;
  virtual void parallelFor(uint32_t count, uint32_t grain,
                           const std::function<void(uint32_t begin, uint32_t end)>& fn) = 0;
  /// Number of threads that may run ranges at once (1 for serial).
  virtual int threadCount() const = 0;
};

/// Runs every range on the calling thread.
class SerialJobSystem final : public JobSystem {
 public:
  void parallelFor(uint32_t count, uint32_t grain,
                   const std::function<void(uint32_t, uint32_t)>& fn) override;
  int threadCount() const override { return 1; }
};

/// A small fixed pool of std::threads; threads = 0 picks the hardware concurrency.
class ThreadPoolJobSystem final : public JobSystem {
 public:
  explicit ThreadPoolJobSystem(int threads = 0);
  ~ThreadPoolJobSystem() override;
  ThreadPoolJobSystem(const ThreadPoolJobSystem&) = delete;
  ThreadPoolJobSystem& operator=(const ThreadPoolJobSystem&) = delete;
  void parallelFor(uint32_t count, uint32_t grain,
                   const std::function<void(uint32_t, uint32_t)>& fn) override;
  int threadCount() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> m_impl;
};

/// The process-wide serial job system used when a WorldDef names none.
JobSystem& serialJobs();

}  // namespace gf
