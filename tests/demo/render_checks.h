// Independent CPU references for the renderer tests of both back ends: the area of a convex
// outline (what a silhouette must cover) and the shading model the shaders implement
// (docs/design.md, "The demo renderer"), in double.
#pragma once

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <vector>

namespace gf::test {

/// Area of the convex hull of 2D points (monotone chain, then the shoelace formula).
inline double convexHullArea(std::vector<glm::dvec2> pts) {
  std::sort(pts.begin(), pts.end(),
            [](glm::dvec2 a, glm::dvec2 b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
  auto cross = [](glm::dvec2 o, glm::dvec2 a, glm::dvec2 b) {
    return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
  };
  std::vector<glm::dvec2> hull(2 * pts.size());
  size_t k = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], pts[i]) <= 0) --k;
    hull[k++] = pts[i];
  }
  for (size_t i = pts.size() - 1, t = k + 1; i-- > 0;) {
    while (k >= t && cross(hull[k - 2], hull[k - 1], pts[i]) <= 0) --k;
    hull[k++] = pts[i];
  }
  hull.resize(k - 1);
  double area = 0;
  for (size_t i = 0; i < hull.size(); ++i) {
    const glm::dvec2 a = hull[i], b = hull[(i + 1) % hull.size()];
    area += a.x * b.y - b.x * a.y;
  }
  return std::abs(area) / 2;
}

/// The 8-bit colour (0..255 per channel) the shaders give a surface of linear colour `base`
/// with unit world normal n facing the eye, at world point p.
inline glm::dvec3 shade(glm::dvec3 base, glm::dvec3 n, glm::dvec3 p, glm::dvec3 eye) {
  const glm::dvec3 l = glm::normalize(glm::dvec3(0.4, 1.0, 0.3));
  const glm::dvec3 h = glm::normalize(l + glm::normalize(eye - p));
  const double ambient = 0.18 + (0.38 - 0.18) * 0.5 * (n.y + 1.0);
  const double diffuse = 0.72 * std::max(glm::dot(n, l), 0.0);
  const double specular = 0.12 * std::pow(std::max(glm::dot(n, h), 0.0), 48.0);
  const glm::dvec3 linear = base * (ambient + diffuse) + glm::dvec3(specular);
  glm::dvec3 out;
  for (int c = 0; c < 3; ++c) out[c] = 255.0 * std::pow(std::clamp(linear[c], 0.0, 1.0), 1 / 2.2);
  return out;
}

}  // namespace gf::test
