// The demo's follow camera and the framing measures its tests use. The rig keeps the scene
// camera's viewing direction (so the picture never rotates) and moves its target and distance
// towards a framing of the bodies' bounds with critically damped smoothing, which reaches the
// goal without overshoot; a per-frame cap on how far the line of sight swings and how fast
// the picture zooms keeps a sudden change of the bounds (a body shattering) from becoming a
// jump. Zooming does not swing the line of sight, so its own cap is a share of the distance.
#pragma once

#include <glm/vec3.hpp>
#include <span>

#include "renderer.h"

namespace gf::demo {

/// An axis-aligned box in world space; empty when lo > hi.
struct Bounds {
  glm::dvec3 lo{1e300}, hi{-1e300};
  bool empty() const { return lo.x > hi.x; }
  void add(const glm::dvec3& p);
  void add(const Bounds& b);
};

struct FollowSettings {
  double smoothSeconds = 0.4;     ///< Time constant of the critically damped smoothing [s].
  double maxTurnDegrees = 1.0;    ///< Largest swing of the line of sight per frame.
  double maxZoomPerFrame = 0.04;  ///< Largest change of the camera's distance per frame (share).
  double fill = 0.65;             ///< Share of the half-width/height the framed bounds may span.
};

class CameraRig {
 public:
  /// Starts at `start` (its eye - target direction is kept for the whole run).
  CameraRig(const Camera& start, const FollowSettings& settings, double aspect);
  /// Places the camera on the framing of `bounds` at once (the first frame).
  Camera snap(std::span<const Bounds> bounds);
  /// One frame of dt [s] towards the framing of `bounds`; empty bounds are ignored.
  Camera update(std::span<const Bounds> bounds, double dt);
  const Camera& camera() const { return m_camera; }

 private:
  /// Target and distance that frame the union of `bounds` from the kept direction.
  bool goal(std::span<const Bounds> bounds, glm::dvec3& target, double& distance) const;
  void place();

  Camera m_camera;
  FollowSettings m_settings;
  double m_aspect = 1;
  glm::dvec3 m_back{0, 0, 1};  ///< Unit vector from the target to the eye.
  glm::dvec3 m_target{0}, m_targetVelocity{0};
  double m_distance = 1, m_distanceVelocity = 0;
};

/// Share of the box's projected bounding rectangle inside the picture, in [0, 1]: the eight
/// corners are projected and their 2D bounding rectangle clipped to the image. 0 when a corner
/// is behind the eye (the rectangle is then unbounded).
double fractionInside(const Camera& camera, double aspect, const Bounds& box);

/// Angle [degrees] by which the line of sight swings from one frame to the next: between the
/// rays from the new eye to the old and to the new target. It is how far the middle of the old
/// picture moves in the new one; it includes any rotation of the view direction.
double swingDegrees(const Camera& before, const Camera& after);

}  // namespace gf::demo
