// Stress of a HapticProbe between two threads (thesis fig 7.4): a publisher writes records
// whose fields agree (force = (t, 2t, 3t), time t) as fast as it can, or at a set rate, while a
// poller reads them as fast as it can, or at a set rate, and checks every record it sees.
// Shared by the unit test and the ThreadSanitizer build (tests/tsan).
#pragma once

#include <graphfrac/sculpt.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <thread>
#include <vector>

namespace gf::test {

struct ProbeStress {
  int64_t polls = 0;
  int64_t publishes = 0;
  int64_t torn = 0;         ///< records whose fields disagree, or whose sequence went back
  int64_t fresh = 0;        ///< polls that saw a newer record than the poll before
  double pollMedianNs = 0;  ///< duration of one poll() call (two clock reads included)
  double pollP99Ns = 0;
  double pollMaxNs = 0;
  double pollRateHz = 0;  ///< polls per second of the poller's run
};

/// Runs for `seconds`; a rate of 0 runs that side flat out, otherwise it sleeps to a grid of
/// 1 / rate (absolute deadlines, so late wake-ups do not drift the rate).
inline ProbeStress stressProbe(double seconds, double pollHz, double publishHz) {
  using Clock = std::chrono::steady_clock;
  HapticProbe probe;
  std::atomic<bool> stop{false};
  std::atomic<int64_t> publishes{0};
  std::thread publisher([&] {
    int64_t n = 0;
    auto next = Clock::now();
    while (!stop.load(std::memory_order_relaxed)) {
      const double t = double(++n);
      probe.publish({t, 2 * t, 3 * t}, t);
      if (publishHz > 0) {
        next += std::chrono::nanoseconds(int64_t(1e9 / publishHz));
        std::this_thread::sleep_until(next);
      }
    }
    publishes.store(n);
  });
  ProbeStress r;
  std::vector<float> ns;
  ns.reserve(pollHz > 0 ? size_t(seconds * pollHz * 1.1 + 16) : size_t(1) << 24);
  uint64_t lastSequence = 0;
  const auto start = Clock::now();
  const auto end = start + std::chrono::nanoseconds(int64_t(seconds * 1e9));
  auto next = start;
  auto now = start;
  while ((now = Clock::now()) < end) {
    const HapticSample s = probe.poll();
    const auto after = Clock::now();
    if (ns.size() < ns.capacity()) ns.push_back(float((after - now).count()));
    ++r.polls;
    const double t = s.time;
    if (s.force.x != t || s.force.y != 2 * t || s.force.z != 3 * t || s.sequence < lastSequence ||
        double(s.sequence) != t)
      ++r.torn;
    if (s.sequence > lastSequence) ++r.fresh;
    lastSequence = s.sequence;
    if (pollHz > 0) {
      next += std::chrono::nanoseconds(int64_t(1e9 / pollHz));
      std::this_thread::sleep_until(next);
    }
  }
  const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
  stop.store(true);
  publisher.join();
  r.publishes = publishes.load();
  r.pollRateHz = double(r.polls) / elapsed;
  if (!ns.empty()) {
    std::sort(ns.begin(), ns.end());
    r.pollMedianNs = ns[ns.size() / 2];
    r.pollP99Ns = ns[std::min(ns.size() - 1, ns.size() * 99 / 100)];
    r.pollMaxNs = ns.back();
  }
  return r;
}

}  // namespace gf::test
