// The slanted cut of the Is-XFEM World tests: the box [0,2] x [1,2] x [0,1] (gen::box(2, 1, 1)
// raised by 1 in y) cut by the plane x = a + b (y - 1) + c z, and the exact mass properties of
// the part below it.
#pragma once

#include <graphfrac/world.h>

#include <cmath>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>
#include <glm/vec3.hpp>

namespace gf::test {

/// a, b, c dyadic, so the blade's float vertices lie on the plane exactly, and it passes through
/// no node of the box's thirds.
struct SlantedCut {
  double a = 0.6875, b = 0.1875, c = 0.09375;
  double h(double y, double z) const { return a + b * (y - 1) + c * z; }
  /// Volume of the part with x below the plane.
  double leftVolume() const { return a + b / 2 + c / 2; }
  glm::dvec3 normal() const {
    const double len = std::sqrt(1 + b * b + c * c);
    return {1 / len, -b / len, -c / len};
  }
  double offset() const { return (a - b) / std::sqrt(1 + b * b + c * c); }  // n . x on the plane
  Blade blade() const {
    Blade bl;
    for (double y : {0.5, 2.5})
      for (double z : {-0.5, 1.5})
        bl.vertices.push_back(glm::vec3(float(h(y, z)), float(y), float(z)));
    // (y, z) = (0.5,-0.5), (0.5,1.5), (2.5,-0.5), (2.5,1.5): counter-clockwise seen from +x.
    bl.triangles = {0, 2, 3, 0, 3, 1};
    return bl;
  }
};

struct MassProperties {
  double mass = 0;
  glm::dvec3 centre{0};
  glm::dmat3 inertia{0.0};  ///< about the centre
};

/// Mass properties of the part x < h(y, z) of the box, density rho: integrals over x in closed
/// form, then over (y, z) by 4 x 4 Gauss-Legendre (exact to degree 7; the integrands are cubic).
inline MassProperties cutOffPart(const SlantedCut& cut, double rho) {
  const double g[4] = {-0.8611363115940526, -0.3399810435848563, 0.3399810435848563,
                       0.8611363115940526};
  const double w[4] = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461,
                       0.3478548451374538};
  double V = 0;
  glm::dvec3 first(0);
  glm::dmat3 second(0.0);  // integral of x x^T
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      const double y = 1.5 + 0.5 * g[i], z = 0.5 + 0.5 * g[j], wt = 0.25 * w[i] * w[j];
      const double h = cut.h(y, z);
      V += wt * h;
      first += wt * glm::dvec3(h * h / 2, y * h, z * h);
      const double xx = h * h * h / 3, xy = y * h * h / 2, xz = z * h * h / 2;
      const double m[3][3] = {{xx, xy, xz}, {xy, y * y * h, y * z * h}, {xz, y * z * h, z * z * h}};
      for (int r = 0; r < 3; ++r)
        for (int s = 0; s < 3; ++s) second[s][r] += wt * m[r][s];
    }
  MassProperties out;
  out.mass = rho * V;
  out.centre = first / V;
  const glm::dmat3 J = rho * (second - V * glm::outerProduct(out.centre, out.centre));
  out.inertia = (J[0][0] + J[1][1] + J[2][2]) * glm::dmat3(1.0) - J;
  return out;
}

}  // namespace gf::test
