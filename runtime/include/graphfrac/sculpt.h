// Sculpting (thesis ch. 7): water brushes, and the probe through which a haptic device thread
// reads the force the simulation computes.
#pragma once

#include <atomic>
#include <cstdint>
#include <glm/vec3.hpp>
#include <span>
#include <vector>

#include "graphfrac/ids.h"
#include "graphfrac/status.h"
#include "graphfrac/surface.h"

namespace gf {

/// A sphere that wets (World::wet) or dries (World::dry) the tets it touches during the next
/// step: every tet within `radius` of `centre` (at the positions before the step) gains or
/// loses rate * dt of saturation, clamped to [0, 1] (thesis sec 7.2.1).
struct WetBrush {
  glm::vec3 centre{0, 0, 0};  ///< [m], world frame.
  float radius = 0.05f;       ///< [m], > 0.
  double rate = 1;            ///< Saturation per second, > 0 (1: dry to saturated in 1 s).
};

/// Makes a body clay-like around a tool for the next step (World::deform; thesis sec 7.2.3.4):
/// every free node is held by a drag that scales its velocity over the step by G_d of eq 7.7
/// at its distance r from `centre` (at the step's start), 1 / (1 + k1 r) within `radius` and
/// 1 / (1 + k1 r + exp(k2 r)) beyond, exactly so for a node nothing else moves. The drag is
/// part of the implicit step, so the body gives way near the tool and hardly moves elsewhere.
/// G_d below 1e-6 (far from the tool) is taken as 1e-6. The push itself comes from the tool (a
/// collider, or HapticContact's pushes); a material with plasticity keeps the dent.
struct DeformBrush {
  glm::vec3 centre{0, 0, 0};  ///< The tool's position [m], world frame.
  float radius = 0.05f;       ///< R_D [m], > 0.
  double k1 = 10;             ///< [1/m], > 0 (the thesis uses 1 to 100).
  double k2 = 10;             ///< [1/m], > 0.
};

/// Draws chosen nodes of a body toward targets during the next step (World::pull): the pull of
/// the thesis's deform brush (sec 7.2.3.4), a tool that has grabbed the clay under it and moves
/// away. Each node is tied to its target by a spring of `stiffness` times its mass inside the
/// implicit step, so a stiff tether is stable at any time step; the body's elasticity, a deform
/// brush's drag and the material's plasticity decide how the clay around follows and whether
/// the shape stays. A node listed twice, or in several pulls before one step, is pulled by the
/// sum of the springs toward their stiffness-weighted mean target. Nodes held by a grip are not
/// pulled. The body feels sum m k (t - x) over the step (World::pullForce); the tool, minus it.
struct PullBrush {
  std::span<const int32_t> nodes;       ///< Node indices of the body.
  std::span<const glm::dvec3> targets;  ///< One per node [m], world frame.
  /// Spring per unit of the pulled mass [1/s^2] (N per metre of lag per kg), in (0, 1e12]. The
  /// tool's force is about the pulled mass times this times the lag.
  double stiffness = 1e6;
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

/// How HapticContact renders the proxy's contact with a body (thesis sec 7.2.3).
struct HapticContactSettings {
  /// k_vf = k_ee of eq 7.5-7.6 [N/m]: force per metre of depth and per contact, > 0.
  double stiffness = 1000;
  /// True: continuous collision and the penalty integrated over the penetration intervals
  /// (eq 7.5-7.6). False: the discrete penalty at the sample's end (each proxy vertex against
  /// the nearest surface triangle it lies behind), for comparison.
  bool continuous = true;
};

/// The body's share of one haptic sample: a force [N] to apply at a point (World::applyForce),
/// the opposite of what the proxy feels.
struct HapticPush {
  glm::dvec3 point{0, 0, 0};
  glm::dvec3 force{0, 0, 0};
};

/// The penalty force between a haptic proxy (a triangle mesh the device moves: closed for a
/// tool, or open, e.g. the flat cut brush of thesis sec 7.2.3.6, whose force tells when to cut
/// with World::cut) and a body's render surface, sampled at the device's rate (1 kHz or more)
/// between the world's steps (60 Hz; thesis fig 7.4). Contacts are proxy vertices behind body
/// triangles, body vertices behind proxy triangles, and proxy edges crossed with body edges
/// (fig 7.3), found by continuous collision over each sample's motion and kept while the point
/// stays behind the feature it entered through, so a proxy pressed deep into a thin part is pushed
/// back the way it came, never through. A vertex that slides off its triangle while behind it moves
/// to the nearest triangle it is behind; an edge contact ends when the edges no longer cross. The
/// surface the proxy feels moves from the previous world surface to the newest one over `blend`
/// seconds (one world step: the device feels the body one step late, but never jump); a surface
/// with other triangles (a crack opened) replaces it at once, and contacts on the old triangles
/// move to the nearest new triangle behind which their vertex lies. Not thread-safe: the haptic
/// thread owns it and is handed the surfaces (copies) by the application.
class HapticContact {
 public:
  /// `vertices` (world frame, the proxy's pose now) and `indices` (3 per triangle,
  /// counter-clockwise seen from outside) of the proxy. Error for an empty or non-finite
  /// proxy, an index out of range, or settings out of range (the message names the field).
  static Result<HapticContact> create(std::span<const glm::dvec3> vertices,
                                      std::span<const uint32_t> indices,
                                      const HapticContactSettings& settings = {});
  /// The body's surface after a world step, reached by the surface the proxy feels after
  /// `blend` seconds of sampling (>= 0; the world's step for a force without jumps; 0 moves
  /// to it within the next sample, still swept so no contact is missed). Error for an empty
  /// or non-finite surface or a bad blend; nothing changes then.
  Result<void> setSurface(const SurfaceView& surface, double blend);
  /// One sample: the proxy moves (linearly, vertex by vertex) from its last pose to
  /// `vertices` over `dt` seconds. Returns the force on the proxy [N]: continuous, the
  /// impulse of eq 7.5-7.6 over the sample divided by dt; discrete, the penalty at the end.
  /// Error (nothing changes) for a wrong vertex count, a non-finite vertex or dt <= 0.
  Result<glm::dvec3> sample(std::span<const glm::dvec3> vertices, double dt);
  /// The reaction on the body from the last sample (forces summing to minus its result).
  std::span<const HapticPush> pushes() const { return m_pushes; }
  /// Contacts alive after the last sample.
  int contactCount() const { return int(m_contacts.size()); }

 private:
  struct Contact {
    int kind = 0;   // 0 proxy vertex behind a body triangle, 1 body vertex behind a proxy
                    // triangle, 2 proxy edge crossed with a body edge
    int32_t a = 0;  // proxy vertex, body vertex, or proxy edge
    int32_t b = 0;  // body triangle, proxy triangle, or body edge
    double sign = 1;
    glm::dvec3 normal{0, 0, 0};  // the feature's unit normal at the last sample's end
  };
  HapticContact() = default;

  HapticContactSettings m_settings;
  std::vector<glm::dvec3> m_proxy;  // the proxy's vertices now
  std::vector<uint32_t> m_proxyTriangles;
  std::vector<uint32_t> m_proxyEdges;    // 2 per edge
  std::vector<glm::dvec3> m_from, m_to;  // the body surface: blend start and target
  double m_blend = 0, m_elapsed = 0;
  std::vector<uint32_t> m_triangles;
  std::vector<uint32_t> m_edges;  // 2 per edge
  uint64_t m_topology = 0;
  bool m_hasSurface = false;
  std::vector<Contact> m_contacts;
  std::vector<HapticPush> m_pushes;
  // The body features near the proxy (sample's broad phase), valid while the proxy stays in
  // the region, and the blended positions of the vertices a sample uses.
  glm::dvec3 m_regionLo{0, 0, 0}, m_regionHi{0, 0, 0};
  bool m_regionValid = false;
  std::vector<int32_t> m_nearTriangles, m_nearEdges, m_nearVertices;
  std::vector<glm::dvec3> m_at0, m_at1;
  std::vector<uint32_t> m_placed;  // the sample that last placed each vertex
  uint32_t m_sampleId = 0;
};

class World;

/// What a cut brush does.
struct CutBrushSettings {
  double threshold = 20;          ///< Force [N] from which the brush cuts, > 0.
  HapticContactSettings contact;  ///< The penalty that builds the force.
};

/// The cut brush of thesis sec 7.2.3.6: a flat (open) triangle mesh that the device presses into
/// a body. Its penetration builds the continuous penalty force of HapticContact (eq 7.5-7.6),
/// which the device feels; while that force is at least `threshold`, the part of the body the
/// brush overlaps is cut: cut() hands the brush at its last sampled pose to World::cut, which
/// breaks every edge the brush crosses at the world's next step. Pressed on, the brush cuts
/// deeper at each call. The thesis freezes the body while marking, since a body that gives
/// way never builds the force; a deform brush (World::deform) at the cut brush does that here.
/// Not thread-safe (the haptic thread owns it, as HapticContact).
class CutBrush {
 public:
  /// The brush (world frame, its pose now; 3 indices per triangle). Error for an empty or
  /// non-finite brush, an index out of range, or settings out of range (naming the field).
  static Result<CutBrush> create(std::span<const glm::dvec3> vertices,
                                 std::span<const uint32_t> indices,
                                 const CutBrushSettings& settings = {});
  /// As HapticContact::setSurface.
  Result<void> setSurface(const SurfaceView& surface, double blend);
  /// One haptic sample (HapticContact::sample): the force on the brush [N].
  Result<glm::dvec3> sample(std::span<const glm::dvec3> vertices, double dt);
  /// The last sample's force reached the threshold.
  bool cutting() const { return m_cutting; }
  /// Cuts `body` with the brush at its last sampled pose (World::cut). Error, nothing changed,
  /// when the last sample's force is below the threshold, or with World::cut's message. Call
  /// between steps, on the thread that steps the world.
  Result<void> cut(World& world, BodyId body) const;

 private:
  CutBrush(HapticContact contact, std::span<const glm::dvec3> vertices,
           std::span<const uint32_t> indices, double threshold);
  HapticContact m_contact;
  std::vector<glm::dvec3> m_pose;  // the last sampled pose
  std::vector<uint32_t> m_indices;
  double m_threshold = 0;
  bool m_cutting = false;
};

}  // namespace gf
