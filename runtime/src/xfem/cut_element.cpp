#include "xfem/cut_element.h"

#include "kernels/element.h"

namespace gf::detail {

CutElement buildCutElement(const Vec3 X[4], const CutPlane* planes, int count, double k,
                           const LinearElastic& material, double onPlane, uint32_t dropCells) {
  CutElement e;
  e.sides.cutCount = count;
  for (int j = 0; j < count; ++j)
    for (int a = 0; a < 4; ++a) e.sides.side[j][a] = xfemHeaviside(planeDistance(planes[j], X[a]));
  double restVolume = 0;
  const Mat<4, 3> B = shapeGradients(restShapeInverse(X, restVolume));
  const int n = 4 * (1 + count);
  e.mass = Eigen::MatrixXd::Zero(n, n);
  e.load = Eigen::VectorXd::Zero(n);
  const double rho = material.density, mu = material.mu(), lambda = material.lambda();
  // Per cell, the rule's points as rows: phi (Q x n), gradients (Q x 3n, column 3A + i), and
  // the weights. The sums over points are then products of small dense matrices, and the
  // stiffness needs only T = sum_q w g_A g_B^T over all cells (3n x 3n).
  Eigen::MatrixXd phi, grad, weighted;
  Eigen::MatrixXd T = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  std::vector<double> value(static_cast<size_t>(n));
  std::vector<Vec3> gradient(static_cast<size_t>(n));
  for (unsigned mask = 0; mask < (1u << count); ++mask) {
    CutCell cell;
    cell.sideMask = mask;
    cell.polytope = clipTet(X, planes, count, mask, onPlane);
    if (cell.polytope.faceCount == 0) continue;
    // An uncut tet's cell is the tet: its rule is the standard one, not refitted.
    cell.rule = count == 0 ? standardTetRule(X, restVolume) : fitVolumeRule(cell.polytope);
    const int Q = cell.rule.count;
    if (Q == 0) continue;
    phi.resize(Q, n);
    grad.resize(Q, 3 * n);
    Eigen::Map<const Eigen::VectorXd> w(cell.rule.weights, Q);
    for (int q = 0; q < Q; ++q) {
      cell.volume += cell.rule.weights[q];
      enrichedShapeFunctions(X[0], B, e.sides, mask, k, cell.rule.points[q], value.data(),
                             gradient.data());
      for (int A = 0; A < n; ++A) {
        phi(q, A) = value[size_t(A)];
        for (int i = 0; i < 3; ++i) grad(q, 3 * A + i) = gradient[size_t(A)][i];
      }
    }
    cell.load = rho * (phi.transpose() * w);  // eq 3.6 per unit g
    weighted = w.asDiagonal() * phi;
    cell.mass = rho * (phi.transpose() * weighted);  // eq 3.5 over the cell
    cell.dropped = (dropCells >> mask) & 1u;
    if (cell.dropped) {
      e.cells.push_back(std::move(cell));
      continue;
    }
    e.mass.noalias() += rho * (phi.transpose() * weighted);  // as cell.mass, same rounding
    weighted = w.asDiagonal() * grad;
    T.noalias() += grad.transpose() * weighted;
    e.load += cell.load;
    e.cells.push_back(std::move(cell));
  }
  // K_AB,ij = lambda d_i phi_A d_j phi_B + mu d_j phi_A d_i phi_B + mu delta_ij gA.gB.
  e.stiffness.resize(3 * n, 3 * n);
  for (int A = 0; A < n; ++A)
    for (int Bf = 0; Bf < n; ++Bf) {
      const double gg = T(3 * A, 3 * Bf) + T(3 * A + 1, 3 * Bf + 1) + T(3 * A + 2, 3 * Bf + 2);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          e.stiffness(3 * A + i, 3 * Bf + j) = lambda * T(3 * A + i, 3 * Bf + j) +
                                               mu * T(3 * A + j, 3 * Bf + i) +
                                               (i == j ? mu * gg : 0.0);
    }
  return e;
}

}  // namespace gf::detail
