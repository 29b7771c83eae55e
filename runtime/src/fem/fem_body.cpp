#include "fem/fem_body.h"

#include <algorithm>
#include <cmath>

#include "kernels/element.h"

namespace gf::detail {

MaterialCoeffs toCoeffs(const Material& m) {
  Vec3 a{m.fibreDirection.x, m.fibreDirection.y, m.fibreDirection.z};
  const double len = norm(a);
  a = len > 0 ? (1.0 / len) * a : Vec3{1, 0, 0};
  return makeMaterialCoeffs(static_cast<int>(m.model), m.youngsModulus, m.poissonRatio,
                            m.fibreStiffness, a);
}

FemModel buildFemModel(const BodyDef& def) {
  FemModel m;
  const TetMesh& mesh = def.mesh;
  m.nodeCount = static_cast<int32_t>(mesh.nodeCount());
  m.tetCount = static_cast<int32_t>(mesh.tetCount());
  m.tets = mesh.tets;
  m.restPositions = mesh.positions;
  m.solver = def.solver;
  m.friction = def.friction;
  m.contact = def.contact;
  m.restInverse.resize(m.tetCount);
  m.restVolume.resize(m.tetCount);
  for (int32_t e = 0; e < m.tetCount; ++e) {
    Vec3 X[4];
    for (int a = 0; a < 4; ++a) {
      const double* p = &mesh.positions[3 * mesh.tets[4 * e + a]];
      X[a] = {p[0], p[1], p[2]};
    }
    double vol = 0;
    m.restInverse[e] = restShapeInverse(X, vol);
    m.restVolume[e] = vol;
  }
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (int32_t n = 0; n < m.nodeCount; ++n)
    for (int i = 0; i < 3; ++i) {
      lo[i] = std::min(lo[i], mesh.positions[3 * n + i]);
      hi[i] = std::max(hi[i], mesh.positions[3 * n + i]);
    }
  m.lengthScale = std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                            (hi[2] - lo[2]) * (hi[2] - lo[2]));
  m.fracture = def.fracture;
  m.plasticity = def.plasticity;
  m.wetting = def.wetting;
  if (def.material.fibreStiffness > 0 && !def.fibreField.empty()) {
    m.fibreDir.resize(m.tetCount);
    for (int32_t t = 0; t < m.tetCount; ++t) {
      const glm::vec3 f = def.fibreField[t];
      const Vec3 a{f.x, f.y, f.z};
      m.fibreDir[t] = (1.0 / norm(a)) * a;  // validated non-zero by World::createBody
    }
  }
  std::vector<uint8_t> gripped(size_t(m.nodeCount), 0);
  for (const Grip& g : def.grips)
    for (int32_t n : g.nodes) gripped[size_t(n)] = 1;
  const int64_t fixed = std::count(gripped.begin(), gripped.end(), uint8_t(1));
  m.solver.linearSolver = effectiveLinearSolver(def.solver, m.nodeCount - fixed);
  return m;
}

void lumpMasses(const FemModel& model, double density, std::vector<double>& nodeMass) {
  nodeMass.assign(size_t(model.nodeCount), 0.0);
  // A quarter of each tet's mass to each corner (eq 2.10, row-summed), in tet order.
  for (int32_t e = 0; e < model.tetCount; ++e)
    for (int a = 0; a < 4; ++a)
      nodeMass[size_t(model.tets[4 * size_t(e) + a])] += 0.25 * density * model.restVolume[e];
}

FemState buildFemState(const BodyDef& def, const FemModel& model) {
  FemState s;
  const size_t nn = size_t(model.nodeCount);
  s.x = model.restPositions;
  s.v.assign(3 * nn, 0.0);
  s.material = def.material;
  s.coeffs = toCoeffs(def.material);
  lumpMasses(model, def.material.density, s.nodeMass);
  s.fixedNode.assign(nn, 0);
  s.gripVelocity.assign(3 * nn, 0.0);
  for (const Grip& g : def.grips)
    for (int32_t n : g.nodes) {
      s.fixedNode[size_t(n)] = 1;
      for (int i = 0; i < 3; ++i) s.gripVelocity[3 * size_t(n) + i] = g.velocity[i];
      s.movingGrips |= g.velocity != glm::vec3(0);
    }
  s.externalForce.assign(3 * nn, 0.0);
  for (const PointForce& f : def.forces)
    for (int i = 0; i < 3; ++i) s.externalForce[3 * size_t(f.node) + i] += f.force[i];
  if (def.plasticity.enabled) {
    const size_t nt = size_t(model.tetCount);
    s.Fp.assign(nt, Mat3::identity());
    s.FpInv.assign(nt, Mat3::identity());
    s.plasticDelta.assign(nt, 0.0);
    s.plasticInverse = model.restInverse;
  }
  return s;
}

LinearSolverKind effectiveLinearSolver(const SolverSettings& s, int64_t freeNodes) {
  if (s.linearSolver == LinearSolverKind::Multigrid && freeNodes < s.multigrid.directBelowNodes)
    return LinearSolverKind::Direct;
  return s.linearSolver;
}

double estimateBodyBytes(const BodyDef& def) {
  const double tets = double(def.mesh.tetCount()), nodes = double(def.mesh.nodeCount());
  // A tet mesh has about as many edges as nodes and tets together (Euler: V - E + F - T = 1
  // with F ~ 2T); the matrix holds a diagonal block per node and two blocks per edge.
  const double edges = nodes + tets;
  const double blocks = nodes + 2 * edges;
  const double d = sizeof(double);
  // Per tet: element Hessian (its upper node blocks), gradient (12), energy, rest inverse (9),
  // volume, the SVD cache, corners, node references and the gather plan's 16 block slots.
  double bytes =
      tets * (d * (kElementMatrixSize + 12 + 1 + 9 + 1 + kSvdCacheStride) + 4 * (4 + 4 + 16));
  // Per block: 9 values and a column index; the damping matrix doubles it.
  const double matrices = def.material.stiffnessDamping > 0 ? 2 : 1;
  bytes += matrices * blocks * (9 * d + 4);
  // Per node: about 16 work vectors of 3 and the contact Hessian.
  bytes += nodes * d * (16 * 3 + 9 + 4);
  int64_t gripped = 0;
  for (const Grip& g : def.grips) gripped += int64_t(g.nodes.size());
  const LinearSolverKind solver =
      effectiveLinearSolver(def.solver, int64_t(def.mesh.nodeCount()) - gripped);
  if (solver == LinearSolverKind::Multigrid) {
    // Coarse levels and their patterns; Gauss-Seidel's colour-ordered copy of the matrix
    // (values, column, source block); per node the prolongation block (3x12), about two blocks
    // of A P and their term lists. The smoothed prolongation holds about three blocks per node,
    // twice (by row, and by handle for the restriction), and ten of A P.
    bytes += 0.5 * blocks * (9 * d + 4) + blocks * (9 * d + 8);
    bytes += def.solver.multigrid.smoothedProlongation ? nodes * (16 * 36 * d + 400)
                                                       : nodes * (3 * 36 * d + 64);
  }
  if (solver == LinearSolverKind::Direct) bytes += 4 * blocks * (9 * d + 4);
  if (def.fracture.enabled) {
    // Stresses (6), rest edge directions (6), chi, mask and the tets' edges; the projection
    // model's 6x6 edge matrix and its inverse; per edge strength, flags and graph entries.
    bytes += tets * (d * 13 + 1 + 4 * 6);
    if (def.fracture.model == DamageModel::Projection) bytes += tets * 2 * 36 * d;
    bytes += edges * (d * 2 + 1 + 4 * 8);
    if (def.fracture.nonlocalLength > 0 || def.fracture.radius > 0) {
      // Non-local lists: an index and a float weight per tet within R of each tet, about the
      // tets of a ball of radius R (fewer near the surface).
      const double volume = std::abs(def.mesh.volume());  // before validate() fixes flips
      if (tets > 0 && volume > 0) {
        // A Kuhn cell of side h holds 6 tets; its unique edges average about 1.3 h.
        const double R = def.fracture.nonlocalLength > 0
                             ? def.fracture.nonlocalLength
                             : def.fracture.radius * 1.3 * std::cbrt(6.0 * volume / tets);
        const double perTet = std::min(tets, 4.18879 * R * R * R * tets / volume + 1);
        bytes += tets * perTet * (4 + 4) + 4 * tets;
      }
    }
  }
  if (def.plasticity.enabled) bytes += tets * d * (3 * 9 + 1);
  return bytes;
}

}  // namespace gf::detail
