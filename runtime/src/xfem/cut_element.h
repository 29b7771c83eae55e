// One tet of an Is-XFEM body cut by planes: its cells, their moment-fitted rules (eqs 3.8-3.12)
// and its enriched mass, load and linear-elastic stiffness (eqs 3.5-3.7).
//
// Host code over the kernels (cut_polytope.h, moment_fitting.h, xfem_enrichment.h): the element
// matrices grow with the number of cuts (4 (1 + m) shape functions), so they are Eigen matrices
// here; the per-cell geometry and rules are fixed-size and device-ready.
#pragma once

#include <Eigen/Dense>
#include <vector>

#include "kernels/moment_fitting.h"
#include "kernels/xfem_enrichment.h"

namespace gf::detail {

/// Isotropic linear elasticity (the standalone cut-body check; eq 4.29's Lame parameters).
struct LinearElastic {
  double youngs = 1e6;    ///< E [Pa].
  double poisson = 0.3;   ///< nu.
  double density = 1000;  ///< rho [kg/m^3].
  double mu() const { return youngs / (2.0 * (1.0 + poisson)); }
  double lambda() const { return youngs * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson)); }
};

/// One non-empty cell of a cut element.
struct CutCell {
  unsigned sideMask = 0;  ///< Bit j: positive side of the element's cut j.
  CutPolytope polytope;
  VolumeRule rule;       ///< Moment-fitted (eq 3.8); the standard rule in an uncut tet.
  double volume = 0;     ///< Sum of the rule's weights (exact to rounding).
  Eigen::VectorXd load;  ///< integral over the cell of rho phi_A (momentum, piece centroids).
  Eigen::MatrixXd mass;  ///< integral over the cell of rho phi_A phi_B (a piece's own moments).
  bool dropped = false;  ///< Left out of the element's sums (buildCutElement's dropCells).
};

/// An element's cells and enriched matrices. Shape functions are numbered as in
/// xfem_enrichment.h: A = a standard, A = 4 + 4j + a enriched by cut j; vector DOF 3A + i.
struct CutElement {
  CutElementSides sides;
  std::vector<CutCell> cells;
  Eigen::MatrixXd mass;       ///< Scalar: integral of rho phi_A phi_B (eq 3.5 is this x I3).
  Eigen::VectorXd load;       ///< Scalar: integral of rho phi_A (eq 3.6 is this times g).
  Eigen::MatrixXd stiffness;  ///< 3n x 3n linear-elastic stiffness of the enriched field.
};

/// Cells, rules and matrices of tet X (positively oriented) cut by `planes` (count in
/// [0, kMaxCutPlanes]; zero gives the plain linear tet, with the standard rule standardTetRule
/// instead of a fitted one). k is eq 3.2's parameter; onPlane is clipTet's: vertices that close
/// to a plane count as on it. dropCells: bit `mask` set leaves the cell of that side mask out of
/// mass, load and stiffness (a piece handed to rigid physics); the cell is still listed, with its
/// own load and mass, and `dropped` set.
CutElement buildCutElement(const Vec3 X[4], const CutPlane* planes, int count, double k,
                           const LinearElastic& material, double onPlane = 0,
                           uint32_t dropCells = 0);

}  // namespace gf::detail
