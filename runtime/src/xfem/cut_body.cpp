#include "xfem/cut_body.h"

#include <cmath>
#include <string>

namespace gf::detail {

namespace {

Vec3 nodePosition(const TetMesh& mesh, int32_t n) {
  return {mesh.positions[3 * size_t(n)], mesh.positions[3 * size_t(n) + 1],
          mesh.positions[3 * size_t(n) + 2]};
}

// Side of a point against every body plane, on the positive side when on a plane.
unsigned sideMask(const std::vector<CutPlane>& planes, Vec3 x) {
  unsigned mask = 0;
  for (size_t j = 0; j < planes.size(); ++j)
    if (planeDistance(planes[j], x) >= 0) mask |= 1u << j;
  return mask;
}

}  // namespace

Result<std::unique_ptr<XfemBody>> XfemBody::create(const XfemBodyDef& def) {
  const TetMesh& mesh = def.mesh;
  const int32_t nodes = int32_t(mesh.nodeCount()), tets = int32_t(mesh.tetCount());
  const int32_t planeCount = int32_t(def.planes.size());
  if (tets == 0) return fail("XfemBody: mesh: no tets");
  if (planeCount > 32) return fail("XfemBody: planes: ", std::to_string(planeCount), " > 32");
  for (int32_t j = 0; j < planeCount; ++j)
    if (std::abs(norm(def.planes[size_t(j)].normal) - 1.0) > 1e-12)
      return fail("XfemBody: planes[", std::to_string(j), "]: normal is not a unit vector");
  for (int32_t n : def.fixedNodes)
    if (n < 0 || n >= nodes)
      return fail("XfemBody: fixedNodes: node ", std::to_string(n), " out of range");

  std::unique_ptr<XfemBody> body(new XfemBody());
  XfemBody& b = *body;
  b.m_def = def;

  // A tet is cut by plane j when its nodes lie strictly on both sides; a plane that only
  // touches it (a node on the plane) leaves it whole, on the positive side.
  std::vector<std::vector<int32_t>> tetCuts(static_cast<size_t>(tets));
  std::vector<Vec3> X(4 * static_cast<size_t>(tets));
  for (int32_t t = 0; t < tets; ++t) {
    for (int a = 0; a < 4; ++a)
      X[4 * size_t(t) + a] = nodePosition(mesh, mesh.tets[4 * size_t(t) + a]);
    for (int32_t j = 0; j < planeCount; ++j) {
      bool pos = false, neg = false;
      for (int a = 0; a < 4; ++a) {
        const double d = planeDistance(def.planes[size_t(j)], X[4 * size_t(t) + a]);
        pos = pos || d > 0;
        neg = neg || d < 0;
      }
      if (pos && neg) tetCuts[size_t(t)].push_back(j);
    }
    if (tetCuts[size_t(t)].size() > size_t(kMaxCutPlanes))
      return fail("XfemBody: tet ", std::to_string(t), ": more than ",
                  std::to_string(kMaxCutPlanes), " cuts");
    if (!tetCuts[size_t(t)].empty()) ++b.m_cutTets;
  }
  // Eq 3.4: one enriched function per node of a cut tet and per cut through it.
  b.m_enriched.assign(size_t(nodes) * size_t(planeCount), -1);
  b.m_functionCount = nodes;
  for (int32_t t = 0; t < tets; ++t)
    for (int32_t j : tetCuts[size_t(t)])
      for (int a = 0; a < 4; ++a) {
        int32_t& f =
            b.m_enriched[size_t(mesh.tets[4 * size_t(t) + a]) * size_t(planeCount) + size_t(j)];
        if (f < 0) f = b.m_functionCount++;
      }
  const int32_t F = b.m_functionCount;

  // Elements, assembled; pieces and eq 3.16's volumes on the way.
  std::vector<Eigen::Triplet<double>> mass, stiffness;
  b.m_force = Eigen::VectorXd::Zero(3 * F);
  std::vector<double> support(static_cast<size_t>(nodes), 0.0);
  std::vector<double> enrichedVolume(static_cast<size_t>(F - nodes), 0.0);
  for (int32_t t = 0; t < tets; ++t) {
    const std::vector<int32_t>& cuts = tetCuts[size_t(t)];
    const int m = int(cuts.size());
    CutPlane local[kMaxCutPlanes];
    for (int j = 0; j < m; ++j) local[j] = def.planes[size_t(cuts[size_t(j)])];
    const Vec3* x = &X[4 * size_t(t)];
    const CutElement e = buildCutElement(x, local, m, def.k, def.material);
    const int n = 4 * (1 + m);
    std::vector<int32_t> map(static_cast<size_t>(n));
    for (int a = 0; a < 4; ++a) {
      const int32_t node = mesh.tets[4 * size_t(t) + a];
      map[size_t(a)] = node;
      for (int j = 0; j < m; ++j)
        map[size_t(4 + 4 * j + a)] =
            b.m_enriched[size_t(node) * size_t(planeCount) + size_t(cuts[size_t(j)])];
    }
    for (int A = 0; A < n; ++A)
      for (int B = 0; B < n; ++B) {
        for (int i = 0; i < 3; ++i) {
          if (e.mass(A, B) != 0)
            mass.emplace_back(3 * map[size_t(A)] + i, 3 * map[size_t(B)] + i, e.mass(A, B));
          for (int j = 0; j < 3; ++j)
            if (e.stiffness(3 * A + i, 3 * B + j) != 0)
              stiffness.emplace_back(3 * map[size_t(A)] + i, 3 * map[size_t(B)] + j,
                                     e.stiffness(3 * A + i, 3 * B + j));
        }
      }
    // Eq 3.6 with b = rho g.
    for (int A = 0; A < n; ++A)
      for (int i = 0; i < 3; ++i) b.m_force[3 * map[size_t(A)] + i] += e.load[A] * def.gravity[i];

    double tetVolume = 0;
    for (const CutCell& c : e.cells) tetVolume += c.volume;
    for (int a = 0; a < 4; ++a) support[size_t(mesh.tets[4 * size_t(t) + a])] += tetVolume;
    for (const CutCell& c : e.cells) {
      // Cell sides for its own cuts, and the side of every other plane from its centroid
      // (it lies wholly on one side of a plane that does not cut its tet).
      Vec3 centroid;
      for (int q = 0; q < c.rule.count; ++q) centroid += c.rule.weights[q] * c.rule.points[q];
      centroid = (1.0 / c.volume) * centroid;
      unsigned mask = sideMask(def.planes, centroid);
      for (int j = 0; j < m; ++j) {
        mask &= ~(1u << cuts[size_t(j)]);
        if ((c.sideMask >> j) & 1u) mask |= 1u << cuts[size_t(j)];
      }
      XfemPiece& piece = b.m_pieces[mask];
      if (piece.load.size() == 0) piece.load = Eigen::VectorXd::Zero(F);
      piece.volume += c.volume;
      for (int A = 0; A < n; ++A) piece.load[map[size_t(A)]] += c.load[A];
      for (int j = 0; j < m; ++j) {
        const bool cellPositive = (c.sideMask >> j) & 1u;
        // Eq 3.16's enriched support: where classic XFEM's psi_i^j is non-zero, the cells
        // on the other side of cut j from node i.
        for (int a = 0; a < 4; ++a)
          if ((e.sides.side[j][a] > 0.5) != cellPositive)
            enrichedVolume[size_t(map[size_t(4 + 4 * j + a)] - nodes)] += c.volume;
        if (cellPositive)
          for (int f = 0; f < c.polytope.faceCount; ++f)
            if (c.polytope.faces[f].label == kCutFaceLabel + j)
              b.m_cutFaces.push_back({t, cuts[size_t(j)], c.polytope.faces[f]});
      }
    }
  }
  b.m_enrichedRatio.assign(size_t(F - nodes), 0.0);
  for (int32_t n = 0; n < nodes; ++n)
    for (int32_t j = 0; j < planeCount; ++j) {
      const int32_t f = b.m_enriched[size_t(n) * size_t(planeCount) + size_t(j)];
      if (f >= 0)
        b.m_enrichedRatio[size_t(f - nodes)] =
            enrichedVolume[size_t(f - nodes)] / support[size_t(n)];
    }

  b.m_mass.resize(3 * F, 3 * F);
  b.m_mass.setFromTriplets(mass.begin(), mass.end());
  b.m_stiffness.resize(3 * F, 3 * F);
  b.m_stiffness.setFromTriplets(stiffness.begin(), stiffness.end());

  // Fixed nodes hold their standard and enriched DOFs; the step matrix is over the rest.
  std::vector<uint8_t> fixed(static_cast<size_t>(F), 0);
  for (int32_t n : def.fixedNodes) {
    fixed[size_t(n)] = 1;
    for (int32_t j = 0; j < planeCount; ++j) {
      const int32_t f = b.m_enriched[size_t(n) * size_t(planeCount) + size_t(j)];
      if (f >= 0) fixed[size_t(f)] = 1;
    }
  }
  for (int32_t f = 0; f < F; ++f)
    if (!fixed[size_t(f)])
      for (int i = 0; i < 3; ++i) b.m_freeDof.push_back(3 * f + i);
  const int32_t free = int32_t(b.m_freeDof.size());
  Eigen::SparseMatrix<double> select(3 * F, free);
  std::vector<Eigen::Triplet<double>> s;
  for (int32_t r = 0; r < free; ++r) s.emplace_back(b.m_freeDof[size_t(r)], r, 1.0);
  select.setFromTriplets(s.begin(), s.end());
  const Eigen::SparseMatrix<double> A = b.m_mass + (def.dt * def.dt) * b.m_stiffness;
  b.m_stepMatrix = select.transpose() * A * select;
  b.m_solver.compute(b.m_stepMatrix);
  if (b.m_solver.info() != Eigen::Success)
    return fail("XfemBody: step matrix: factorisation failed (singular M + dt^2 K)");
  b.m_u = Eigen::VectorXd::Zero(3 * F);
  b.m_v = Eigen::VectorXd::Zero(3 * F);
  return body;
}

void XfemBody::step() {
  const double dt = m_def.dt;
  // Eq 3.13 for linear elasticity (K x^k is the elastic force K u of the displacement).
  const Eigen::VectorXd full = m_mass * m_v - dt * (m_stiffness * m_u - m_force);
  Eigen::VectorXd rhs(Eigen::Index(m_freeDof.size()));
  for (size_t r = 0; r < m_freeDof.size(); ++r) rhs[Eigen::Index(r)] = full[m_freeDof[r]];
  const Eigen::VectorXd v = m_solver.solve(rhs);
  m_v.setZero();
  for (size_t r = 0; r < m_freeDof.size(); ++r) m_v[m_freeDof[r]] = v[Eigen::Index(r)];
  m_u += dt * m_v;
}

Vec3 XfemBody::pieceMeanDisplacement(unsigned mask) const {
  const auto it = m_pieces.find(mask);
  if (it == m_pieces.end()) return {};
  const XfemPiece& p = it->second;
  Vec3 s;
  for (int32_t f = 0; f < m_functionCount; ++f)
    for (int i = 0; i < 3; ++i) s[i] += p.load[f] * m_u[3 * f + i];
  return (1.0 / (m_def.material.density * p.volume)) * s;
}

Vec3 XfemBody::momentum(unsigned mask) const {
  Vec3 s;
  for (const auto& [key, p] : m_pieces) {
    if (mask != ~0u && key != mask) continue;
    for (int32_t f = 0; f < m_functionCount; ++f)
      for (int i = 0; i < 3; ++i) s[i] += p.load[f] * m_v[3 * f + i];
  }
  return s;
}

Eigen::VectorXd XfemBody::volumeRatioScaling() const {
  const int32_t nodes = int32_t(m_def.mesh.nodeCount());
  Eigen::VectorXd t(Eigen::Index(m_freeDof.size()));
  for (size_t r = 0; r < m_freeDof.size(); ++r) {
    const int32_t f = m_freeDof[r] / 3;
    const double v = f < nodes ? 1.0 : m_enrichedRatio[size_t(f - nodes)];
    t[Eigen::Index(r)] = v > 0 ? 1.0 / std::sqrt(v) : 1.0;  // eq 3.15
  }
  return t;
}

}  // namespace gf::detail
