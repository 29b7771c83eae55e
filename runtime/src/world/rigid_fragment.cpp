#include "world/rigid_fragment.h"

#include "kernels/svd3.h"
#include "kernels/tet_inertia.h"

namespace gf::detail {

namespace {
Vec3 load3(const double* p, int32_t i) { return {p[3 * i], p[3 * i + 1], p[3 * i + 2]}; }

// Corner cells of the fragment's nodes, one sub-tet at a time: fn(rest, current, mass).
template <class Fn>
void forEachCellTet(const FemModel& m, double density, const double* x, const int32_t* nodeFragment,
                    int32_t fragment, Fn&& fn) {
  for (int32_t t = 0; t < m.tetCount; ++t) {
    const int32_t* tn = &m.tets[4 * size_t(t)];
    Vec3 rest[4], cur[4];
    bool any = false;
    for (int a = 0; a < 4; ++a) any |= nodeFragment[tn[a]] == fragment;
    if (!any) continue;
    for (int a = 0; a < 4; ++a) {
      rest[a] = load3(m.restPositions.data(), tn[a]);
      cur[a] = load3(x, tn[a]);
    }
    // The lumped mass of a corner (eq 2.10, row-summed), shared by its 6 sub-tets.
    const double subMass = 0.25 * density * m.restVolume[t] / 6.0;
    for (int a = 0; a < 4; ++a) {
      if (nodeFragment[tn[a]] != fragment) continue;
      Vec3 restCell[6][4], curCell[6][4];
      cornerCellTets(rest, a, restCell);
      cornerCellTets(cur, a, curCell);
      for (int s = 0; s < 6; ++s) fn(restCell[s], curCell[s], subMass, m.restVolume[t] / 24.0);
    }
  }
}

Vec3 centroid(const Vec3 x[4]) { return 0.25 * (x[0] + x[1] + x[2] + x[3]); }
}  // namespace

RigidProperties rigidProperties(const FemModel& m, const FemState& s, const int32_t* nodeFragment,
                                int32_t fragment) {
  const double* x = s.x.data();
  const double* v = s.v.data();
  RigidProperties p;
  // Pass 1: mass, volume and both centres of mass (a uniform tet's is its vertex mean).
  Vec3 restMoment, curMoment;
  forEachCellTet(m, s.material.density, x, nodeFragment, fragment,
                 [&](const Vec3* rest, const Vec3* cur, double mass, double volume) {
                   p.mass += mass;
                   p.volume += volume;
                   restMoment += mass * centroid(rest);
                   curMoment += mass * centroid(cur);
                 });
  if (!(p.mass > 0)) return p;
  p.restCentre = (1.0 / p.mass) * restMoment;
  p.centre = (1.0 / p.mass) * curMoment;
  // Pass 2: second moment about the rest centre (relative coordinates: no cancellation).
  Mat3 second;
  forEachCellTet(m, s.material.density, x, nodeFragment, fragment,
                 [&](const Vec3* rest, const Vec3*, double mass, double) {
                   Vec3 r[4];
                   for (int a = 0; a < 4; ++a) r[a] = rest[a] - p.restCentre;
                   second = second + tetSecondMoment(mass, r);
                 });
  p.restInertia = inertiaFromSecondMoment(second);
  // Momenta with the lumped masses, and the mass-weighted cross-covariance whose polar factor
  // is the rotation that best maps the rest shape onto the current one (least squares).
  Mat3 cov;
  for (int32_t n = 0; n < m.nodeCount; ++n) {
    if (nodeFragment[n] != fragment) continue;
    ++p.nodeCount;
    p.hasFixedNode |= s.fixedNode[n] != 0;
    const double mi = s.nodeMass[n];
    const Vec3 r = load3(x, n) - p.centre, R = load3(m.restPositions.data(), n) - p.restCentre;
    const Vec3 vi = load3(v, n);
    p.momentum += mi * vi;
    p.angularMomentum += cross(r, mi * vi);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) cov(i, j) += mi * r[i] * R[j];
  }
  const Svd3 polar = svd3(cov);
  p.rotation = polar.U * transpose(polar.V);
  return p;
}

}  // namespace gf::detail
