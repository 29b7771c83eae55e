// Penalty contact of a node against each collider kind (kernels/contact.h), checked against
// independent truths: the gradient and Hessian against central finite differences of the
// energy, the capsule's depth against the analytic point-segment distance (worked out here in
// glm from the public Collider, not through the kernel's frame), and the swept entry against a
// fine march along the path.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <random>
#include <vector>

#include "graphfrac/defs.h"
#include "kernels/contact.h"
#include "world/world_impl.h"

namespace gf {
namespace {

Collider plane() {
  Collider c;
  c.kind = Collider::Kind::Plane;
  c.point = {0.1f, -0.2f, 0.05f};
  c.normal = glm::normalize(glm::vec3(0.3f, 1, -0.2f));
  return c;
}
Collider box() {
  Collider c;
  c.kind = Collider::Kind::Box;
  c.point = {0.1f, -0.2f, 0.05f};
  c.halfExtents = {0.3f, 0.2f, 0.5f};
  c.rotation = glm::angleAxis(0.7f, glm::normalize(glm::vec3(1, 2, 3)));
  return c;
}
Collider sphere() {
  Collider c;
  c.kind = Collider::Kind::Sphere;
  c.point = {0.1f, -0.2f, 0.05f};
  c.radius = 0.4f;
  return c;
}
Collider capsule(float halfLength = 0.5f) {
  Collider c;
  c.kind = Collider::Kind::Capsule;
  c.point = {0.1f, -0.2f, 0.05f};
  c.radius = 0.3f;
  c.halfLength = halfLength;
  c.rotation = glm::angleAxis(1.1f, glm::normalize(glm::vec3(-2, 1, 0.5f)));
  return c;
}

// The capsule's segment from the public fields: the local y axis turned by the quaternion.
void segmentOf(const Collider& c, glm::dvec3& a, glm::dvec3& b) {
  const glm::dvec3 axis = glm::dquat(c.rotation) * glm::dvec3(0, 1, 0);
  a = glm::dvec3(c.point) - double(c.halfLength) * axis;
  b = glm::dvec3(c.point) + double(c.halfLength) * axis;
}

// Point-segment distance by the perpendicular (|(p - a) x u|) inside the segment's slab and
// the distance to the nearer end outside it.
double segmentDistance(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b) {
  const double len = glm::length(b - a);
  if (len == 0) return glm::length(p - a);
  const glm::dvec3 u = (b - a) / len;
  const double s = glm::dot(p - a, u);
  if (s <= 0) return glm::length(p - a);
  if (s >= len) return glm::length(p - b);
  return glm::length(glm::cross(p - a, u));
}

Vec3 v3(const glm::dvec3& v) { return {v.x, v.y, v.z}; }

double energy(const ColliderData& c, Vec3 x, double m) {
  Vec3 g;
  Mat3 h;
  return nodeContact(c, x, m, g, h);
}

// Points around the collider, inside it (depth > 0) and clear of its creases by `margin` (the
// depth is only piecewise smooth: a box's nearest face changes, a capsule's axis is singular).
std::vector<Vec3> insidePoints(const ColliderData& c, double margin, int count) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Vec3> out;
  const Vec3 centre = c.point;
  while (int(out.size()) < count) {
    const Vec3 x = centre + Vec3{u(rng), u(rng), u(rng)};
    Vec3 n;
    const double d = penetration(c, x, n);
    if (!(d > margin)) continue;
    // The same nearest feature all around: the normal turns little over the margin.
    bool smooth = true;
    for (int a = 0; a < 3 && smooth; ++a)
      for (const double s : {-margin, margin}) {
        Vec3 y = x, m;
        y[a] += s;
        (void)penetration(c, y, m);
        smooth &= norm(m - n) < 0.5;
      }
    if (smooth) out.push_back(x);
  }
  return out;
}

TEST(ColliderContact, GradientMatchesFiniteDifferencesForEveryKind) {
  const double m = 0.3;
  for (const Collider& pub : {plane(), box(), sphere(), capsule(), capsule(0)}) {
    ColliderData c = detail::toData(pub);
    c.stiffness = 1e4;
    double worst = 0;
    for (const Vec3& x : insidePoints(c, 0.02, 200)) {
      Vec3 g;
      Mat3 h;
      ASSERT_GT(nodeContact(c, x, m, g, h), 0);
      const double e = 1e-6;
      for (int a = 0; a < 3; ++a) {
        Vec3 p = x, q = x;
        p[a] += e;
        q[a] -= e;
        const double fd = (energy(c, p, m) - energy(c, q, m)) / (2 * e);
        worst = std::max(worst, fabs(fd - g[a]) / (c.stiffness * m * 0.02));
      }
    }
    EXPECT_LT(worst, 1e-6) << "collider kind " << int(pub.kind);
  }
}

// The Hessian block is the PSD part of the exact one: equal to the finite difference of the
// gradient for the flat kinds; for a sphere or capsule the finite difference also has the
// curvature term -k d / r (I - n n^T) (less the axis for a capsule's side), which the kernel
// leaves out to stay PSD, so adding it back to the finite difference must give the kernel's
// block.
TEST(ColliderContact, HessianIsThePsdPartOfTheFiniteDifferenceOne) {
  const double m = 0.3;
  for (const Collider& pub : {plane(), box(), sphere(), capsule(), capsule(0)}) {
    ColliderData c = detail::toData(pub);
    c.stiffness = 1e4;
    const double k = c.stiffness * m;
    double worst = 0, leastEigen = 1e300;
    for (const Vec3& x : insidePoints(c, 0.02, 200)) {
      Vec3 g, n;
      Mat3 h;
      nodeContact(c, x, m, g, h);
      const double d = penetration(c, x, n);
      // The exact Hessian's curvature part, from the public geometry.
      Mat3 curvature;
      if (pub.kind == Collider::Kind::Sphere || pub.kind == Collider::Kind::Capsule) {
        glm::dvec3 a = glm::dvec3(pub.point), b = a;
        if (pub.kind == Collider::Kind::Capsule) segmentOf(pub, a, b);
        const glm::dvec3 p(x.x, x.y, x.z);
        const glm::dvec3 ab = b - a;
        const double len2 = glm::dot(ab, ab);
        const double s = len2 > 0 ? glm::dot(p - a, ab) / len2 : 0;
        const bool side = s > 0 && s < 1;
        const glm::dvec3 axis = len2 > 0 ? ab / std::sqrt(len2) : glm::dvec3(0);
        const double r = double(pub.radius) - d;
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            curvature(i, j) =
                -k * d / r * ((i == j ? 1.0 : 0.0) - n[i] * n[j] - (side ? axis[i] * axis[j] : 0));
      }
      const double e = 1e-6;
      for (int col = 0; col < 3; ++col) {
        Vec3 p = x, q = x, gp, gq;
        Mat3 hp, hq;
        p[col] += e;
        q[col] -= e;
        nodeContact(c, p, m, gp, hp);
        nodeContact(c, q, m, gq, hq);
        for (int row = 0; row < 3; ++row) {
          const double fd = (gp[row] - gq[row]) / (2 * e);
          worst = std::max(worst, fabs(fd - curvature(row, col) - h(row, col)) / k);
        }
      }
      // PSD: the block is k n n^T, so its quadratic form is never negative.
      std::mt19937 rng(3);
      std::normal_distribution<double> u;
      for (int t = 0; t < 10; ++t) {
        const Vec3 v{u(rng), u(rng), u(rng)};
        leastEigen = std::min(leastEigen, dot(v, h * v) / dot(v, v));
      }
    }
    EXPECT_LT(worst, 1e-5) << "collider kind " << int(pub.kind);
    EXPECT_GE(leastEigen, -1e-9 * c.stiffness * m) << "collider kind " << int(pub.kind);
  }
}

TEST(ColliderContact, CapsuleDepthIsRadiusLessThePointSegmentDistance) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  for (const float halfLength : {0.0f, 0.01f, 0.5f, 2.0f}) {
    const Collider pub = capsule(halfLength);
    const ColliderData c = detail::toData(pub);
    glm::dvec3 a, b;
    segmentOf(pub, a, b);
    double worst = 0, worstNormal = 0;
    for (int i = 0; i < 2000; ++i) {
      const glm::dvec3 p = glm::dvec3(pub.point) + 1.5 * glm::dvec3(u(rng), u(rng), u(rng));
      Vec3 n;
      const double d = penetration(c, v3(p), n);
      const double dist = segmentDistance(p, a, b);
      worst = std::max(worst, fabs(d - (double(pub.radius) - dist)));
      // The normal points from the segment's nearest point to p: stepping along it by the
      // depth reaches the surface.
      const glm::dvec3 surface = p + d * glm::dvec3(n.x, n.y, n.z);
      worstNormal = std::max(worstNormal, fabs(segmentDistance(surface, a, b) - pub.radius));
    }
    EXPECT_LT(worst, 1e-6) << "half length " << halfLength;  // float inputs, double math
    EXPECT_LT(worstNormal, 1e-6) << "half length " << halfLength;
  }
  // On the axis itself any radial direction will do, but it must be one (unit, across the axis).
  const Collider pub = capsule();
  const ColliderData c = detail::toData(pub);
  Vec3 n;
  EXPECT_NEAR(penetration(c, c.point, n), pub.radius, 1e-7);
  EXPECT_NEAR(norm(n), 1, 1e-12);
  EXPECT_NEAR(dot(n, column(c.rotation, 1)), 0, 1e-12);
}

TEST(ColliderContact, CapsuleSweptEntryIsTheFirstPointOnItsSurface) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  const Collider pub = capsule();
  const ColliderData c = detail::toData(pub);
  glm::dvec3 sa, sb;
  segmentOf(pub, sa, sb);
  int hits = 0, misses = 0;
  for (int i = 0; i < 3000; ++i) {
    const glm::dvec3 a = glm::dvec3(pub.point) + 1.5 * glm::dvec3(u(rng), u(rng), u(rng));
    const glm::dvec3 b = glm::dvec3(pub.point) + 1.5 * glm::dvec3(u(rng), u(rng), u(rng));
    if (segmentDistance(a, sa, sb) <= pub.radius) continue;  // starts inside: no entry
    // March along the path for the first point within the radius.
    double first = -1;
    const int kSteps = 20000;
    for (int s = 0; s <= kSteps && first < 0; ++s) {
      const double t = double(s) / kSteps;
      if (segmentDistance(a + t * (b - a), sa, sb) <= pub.radius) first = t;
    }
    Vec3 point, normal;
    double thickness = 0;
    const bool hit = sweptEntry(c, v3(a), v3(b), point, normal, thickness);
    const glm::dvec3 p(point.x, point.y, point.z);
    if (first < 0) {
      // A grazing path may dip in between two marching samples; then the entry must still lie
      // on the surface.
      if (hit) {
        EXPECT_NEAR(segmentDistance(p, sa, sb), pub.radius, 1e-6);
      }
      misses += !hit;
      continue;
    }
    ASSERT_TRUE(hit) << "path " << i << " enters at t = " << first;
    ++hits;
    const double tEntry = glm::length(p - a) / glm::length(b - a);
    EXPECT_NEAR(tEntry, first, 2.0 / kSteps);
    EXPECT_NEAR(segmentDistance(p, sa, sb), pub.radius, 1e-6);
    // The normal faces back along the path, outward from the segment.
    EXPECT_LE(glm::dot(glm::dvec3(normal.x, normal.y, normal.z), b - a), 1e-12);
    EXPECT_GE(thickness, 2 * double(pub.radius) - 1e-9);
    EXPECT_LE(thickness, 2 * double(pub.radius + pub.halfLength) + 1e-9);
  }
  EXPECT_GT(hits, 300);
  EXPECT_GT(misses, 300);
}

TEST(ColliderContact, CapsuleThicknessIsItsExtentAlongTheDirection) {
  const Collider pub = capsule();
  const ColliderData c = detail::toData(pub);
  glm::dvec3 a, b;
  segmentOf(pub, a, b);
  std::mt19937 rng(2);
  std::normal_distribution<double> u;
  for (int i = 0; i < 50; ++i) {
    glm::dvec3 n(u(rng), u(rng), u(rng));
    n = glm::normalize(n);
    // Support function of a segment swept by a ball, both ways.
    const double extent = std::abs(glm::dot(b - a, n)) + 2 * double(pub.radius);
    EXPECT_NEAR(colliderThickness(c, v3(n)), extent, 1e-6);
  }
}

// Bad capsules are refused with the field named; a sphere-like capsule (no length) is fine.
TEST(ColliderContact, CapsuleCheckNamesTheField) {
  const auto message = [](const Collider& c) {
    const Result<void> r = c.check();
    return r ? std::string() : r.error().message;
  };
  EXPECT_EQ(message(capsule()), "");
  EXPECT_EQ(message(capsule(0)), "");
  Collider c = capsule();
  c.radius = 0;
  EXPECT_EQ(message(c).rfind("radius:", 0), 0u) << message(c);
  c.radius = -1;
  EXPECT_EQ(message(c).rfind("radius:", 0), 0u) << message(c);
  c.radius = NAN;
  EXPECT_EQ(message(c).rfind("radius:", 0), 0u) << message(c);
  for (const float h : {-0.1f, NAN, INFINITY, 2e9f}) {
    c = capsule(h);
    EXPECT_EQ(message(c).rfind("halfLength:", 0), 0u) << h << ": " << message(c);
  }
  c = capsule();
  c.rotation = glm::quat(0, 0, 0, 0);
  EXPECT_EQ(message(c).rfind("rotation:", 0), 0u) << message(c);
  c = capsule();
  c.point.x = NAN;
  EXPECT_EQ(message(c).rfind("point:", 0), 0u) << message(c);
}

}  // namespace
}  // namespace gf
