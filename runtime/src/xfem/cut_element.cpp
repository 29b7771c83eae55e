#include "xfem/cut_element.h"

#include "kernels/element.h"

namespace gf::detail {

CutElement buildCutElement(const Vec3 X[4], const CutPlane* planes, int count, double k,
                           const LinearElastic& material, double onPlane) {
  CutElement e;
  e.sides.cutCount = count;
  for (int j = 0; j < count; ++j)
    for (int a = 0; a < 4; ++a) e.sides.side[j][a] = xfemHeaviside(planeDistance(planes[j], X[a]));
  double restVolume = 0;
  const Mat<4, 3> B = shapeGradients(restShapeInverse(X, restVolume));
  const int n = 4 * (1 + count);
  e.mass = Eigen::MatrixXd::Zero(n, n);
  e.load = Eigen::VectorXd::Zero(n);
  e.stiffness = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  const double rho = material.density, mu = material.mu(), lambda = material.lambda();
  std::vector<double> phi(n);
  std::vector<Vec3> grad(n);
  for (unsigned mask = 0; mask < (1u << count); ++mask) {
    CutCell cell;
    cell.sideMask = mask;
    cell.polytope = clipTet(X, planes, count, mask, onPlane);
    if (cell.polytope.faceCount == 0) continue;
    cell.rule = fitVolumeRule(cell.polytope);
    if (cell.rule.count == 0) continue;
    cell.load = Eigen::VectorXd::Zero(n);
    for (int q = 0; q < cell.rule.count; ++q) {
      const double w = cell.rule.weights[q];
      cell.volume += w;
      enrichedShapeFunctions(X[0], B, e.sides, mask, k, cell.rule.points[q], phi.data(),
                             grad.data());
      for (int A = 0; A < n; ++A) {
        cell.load[A] += rho * w * phi[A];
        for (int Bf = 0; Bf < n; ++Bf) e.mass(A, Bf) += rho * w * phi[A] * phi[Bf];
      }
      // K_AB,ij = lambda d_i phi_A d_j phi_B + mu d_j phi_A d_i phi_B + mu delta_ij gA.gB.
      for (int A = 0; A < n; ++A)
        for (int Bf = 0; Bf < n; ++Bf) {
          const double gg = dot(grad[A], grad[Bf]);
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
              e.stiffness(3 * A + i, 3 * Bf + j) +=
                  w * (lambda * grad[A][i] * grad[Bf][j] + mu * grad[A][j] * grad[Bf][i] +
                       (i == j ? mu * gg : 0.0));
        }
    }
    e.load += cell.load;
    e.cells.push_back(std::move(cell));
  }
  return e;
}

}  // namespace gf::detail
