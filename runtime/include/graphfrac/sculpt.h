// Sculpting (thesis ch. 7): water brushes, and the probe through which a haptic device thread
// reads the force the simulation computes.
#pragma once

#include <atomic>
#include <cstdint>
#include <glm/vec3.hpp>

namespace gf {

/// A sphere that wets (World::wet) or dries (World::dry) the tets it touches during the next
/// step: every tet within `radius` of `centre` (at the positions before the step) gains or
/// loses rate * dt of saturation, clamped to [0, 1] (thesis sec 7.2.1).
struct WetBrush {
  glm::vec3 centre{0, 0, 0};  ///< [m], world frame.
  float radius = 0.05f;       ///< [m], > 0.
  double rate = 1;            ///< Saturation per second, > 0 (1: dry to saturated in 1 s).
};

/// One force sample for a haptic device.
struct HapticSample {
  glm::dvec3 force{0, 0, 0};  ///< [N], what the device renders.
  double time = 0;            ///< When it was computed (the publisher's clock) [s].
  uint64_t sequence = 0;      ///< 0 before the first publish, then 1, 2, ... per publish.
};

/// The latest force, handed from the thread that steps the world (about 60 Hz) to a haptic
/// device thread that polls at 1 kHz or more (thesis fig 7.4: the device renders the last force
/// until a newer one arrives). A triple buffer: publish() and poll() are wait-free (a fixed
/// number of instructions, one atomic exchange each, no lock and no retry), a poll never sees
/// a half-written sample, and neither side ever waits for the other. One thread publishes and
/// one thread polls at a time (single producer, single consumer); either may change between
/// calls if the change is synchronised by the caller.
class HapticProbe {
 public:
  /// Makes `force` at `time` the sample the next poll() returns.
  void publish(const glm::dvec3& force, double time) noexcept {
    HapticSample& s = m_buffer[m_back];
    s.force = force;
    s.time = time;
    s.sequence = ++m_published;
    // Release: the sample's bytes are visible to the poller that takes this slot (acquire).
    m_back = m_middle.exchange(uint8_t(m_back | kFresh), std::memory_order_acq_rel) & kIndex;
  }
  /// The most recent published sample (sequence 0 and zero force before the first publish).
  HapticSample poll() noexcept {
    if (m_middle.load(std::memory_order_relaxed) & kFresh)
      m_front = m_middle.exchange(m_front, std::memory_order_acq_rel) & kIndex;
    return m_buffer[m_front];
  }

 private:
  static constexpr uint8_t kIndex = 3, kFresh = 4;
  HapticSample m_buffer[3];
  // The slot between the sides (index | kFresh when it holds a sample not yet polled), on its
  // own cache line so the two sides' private indices do not share it.
  alignas(64) std::atomic<uint8_t> m_middle{1};
  alignas(64) uint8_t m_back = 0;   // publisher only
  uint64_t m_published = 0;         // publisher only
  alignas(64) uint8_t m_front = 2;  // poller only
};

}  // namespace gf
