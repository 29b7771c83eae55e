#include "contact/body_contact.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "mesh/mesh_internal.h"

namespace gf::detail {

namespace {

// Contact thickness relative to the cell size: how near a vertex's predicted position must come
// to a face for the pair to be kept, and how much the boxes of the broad phase grow.
constexpr double kThickness = 0.05;
// A vertex counts as over a face when its offset from the face's nearest point leaves the
// normal by at most this much of the face's longest edge (vertices over a shared edge of two
// faces get both).
constexpr double kLateral = 0.1;
// A vertex more than this many contact thicknesses behind a face's plane at the step's start
// went in through another face (or is on the far side of the other body): this face's plane
// would push it out sideways, so the pair is not kept.
constexpr double kBehind = 2.0;
// A face spanning more grid cells than this (a face moving many cells in one step) is put in
// the grid over a coarser box of cells only once per this many along each axis; it cannot be
// missed, only tested against more vertices.
constexpr int64_t kMaxCellsPerFace = 4096;
// Edge-edge proximity (design note): only feature edges, whose two faces' normals meet at more
// than about 25 degrees (cos below this), crossing at more than about 6 degrees (the sine of
// their angle above this), closest at least this fraction of either edge away from its ends.
constexpr double kSharpEdge = 0.9;
constexpr double kEdgeCrossing = 0.1;
constexpr double kEdgeEnd = 0.05;
// Edge pairs are kept while the predicted edges come within this much of a cell plus the
// thickness: one point may have to stop a whole body, so its plane is set up a step before it
// is met (a plane not reached costs nothing: the penalty is one-sided).
constexpr double kEdgeReach = 0.25;

Vec3 load3(const double* p, int32_t i) {
  return {p[3 * int64_t(i)], p[3 * int64_t(i) + 1], p[3 * int64_t(i) + 2]};
}

void grow(double* box, Vec3 p) {
  for (int i = 0; i < 3; ++i) {
    box[i] = std::min(box[i], p[i]);
    box[3 + i] = std::max(box[3 + i], p[i]);
  }
}

void emptyBox(double* box) {
  for (int i = 0; i < 3; ++i) {
    box[i] = HUGE_VAL;
    box[3 + i] = -HUGE_VAL;
  }
}

void pad(double* box, double r) {
  for (int i = 0; i < 3; ++i) {
    box[i] -= r;
    box[3 + i] += r;
  }
}

bool overlap(const double* a, const double* b) {
  for (int i = 0; i < 3; ++i)
    if (a[i] > b[3 + i] || b[i] > a[3 + i]) return false;
  return true;
}

// Packs integer cell coordinates (21 bits each, offset) into one key.
uint64_t cellKey(int64_t x, int64_t y, int64_t z) {
  constexpr int64_t kOffset = int64_t(1) << 20, kMask = (int64_t(1) << 21) - 1;
  return (uint64_t((x + kOffset) & kMask) << 42) | (uint64_t((y + kOffset) & kMask) << 21) |
         uint64_t((z + kOffset) & kMask);
}

int64_t cellOf(double v, double h) {
  const double c = std::floor(v / h);
  return int64_t(std::clamp(c, -1e6, 1e6));
}

// Mass per unit surface area [kg/m^2] that scales a pair's penalty (design note): the denser
// material over the coarser cell, so that the penalty is at least as stiff as a collider's on
// either side's surface nodes.
double pairScale(const ContactBodyView& a, const ContactBodyView& b) {
  return std::max(a.state->material.density, b.state->material.density) *
         std::max(a.surface->cellSize(), b.surface->cellSize());
}

}  // namespace

void ContactSurface::init(const FemModel& model) {
  // Every tet face with its opposite node (record (tet, f) is the face opposite node f);
  // equal faces are adjacent after sorting.
  const std::vector<FaceRecord> entries = sortedFaces(model.tets.data(), size_t(model.tetCount));
  double volume = 0;
  for (int32_t t = 0; t < model.tetCount; ++t) volume += model.restVolume[size_t(t)];
  auto opposite = [&](const FaceRecord& r) {
    return model.tets[4 * size_t(r.tet) + size_t(r.local)];
  };
  auto same = [](const FaceRecord& a, const FaceRecord& b) {
    return a.key[0] == b.key[0] && a.key[1] == b.key[1] && a.key[2] == b.key[2];
  };
  const double* X = model.restPositions.data();
  for (size_t i = 0; i < entries.size();) {
    size_t j = i + 1;
    while (j < entries.size() && same(entries[j], entries[i])) ++j;
    std::array<int32_t, 3> k{entries[i].key[0], entries[i].key[1], entries[i].key[2]};
    const int32_t opp0 = opposite(entries[i]), opp1 = j > i + 1 ? opposite(entries[i + 1]) : -1;
    const Vec3 p0 = load3(X, k[0]);
    // Oriented away from the tet on side 0 (its opposite node is behind the face).
    if (dot(cross(load3(X, k[1]) - p0, load3(X, k[2]) - p0), load3(X, opp0) - p0) > 0)
      std::swap(k[1], k[2]);
    if (opp1 < 0) m_boundary.push_back(int32_t(m_faceOpposite.size() / 2));
    m_faceNodes.insert(m_faceNodes.end(), k.begin(), k.end());
    m_faceOpposite.push_back(opp0);
    m_faceOpposite.push_back(opp1);
    i = j;
  }
  // Edge of a regular tet of the mean volume, V = L^3 / (6 sqrt 2).
  const double mean = model.tetCount > 0 ? volume / model.tetCount : 0;
  m_cellSize = std::cbrt(6 * std::sqrt(2.0) * mean);
}

void ContactSurface::update(const FemModel& model, const int32_t* nodeFragment,
                            const uint8_t* excluded, uint64_t key) {
  if (key == m_key) return;
  m_key = key;
  m_faces.clear();
  auto add = [&](int32_t f, bool flip) {
    const int32_t* k = &m_faceNodes[3 * size_t(f)];
    m_faces.push_back(k[0]);
    m_faces.push_back(flip ? k[2] : k[1]);
    m_faces.push_back(flip ? k[1] : k[2]);
  };
  if (!nodeFragment) {
    for (int32_t f : m_boundary) add(f, false);
  } else {
    const int32_t faceCount = int32_t(m_faceOpposite.size() / 2);
    for (int32_t f = 0; f < faceCount; ++f) {
      const int32_t* k = &m_faceNodes[3 * size_t(f)];
      const int32_t F = nodeFragment[k[0]];
      if (nodeFragment[k[1]] != F || nodeFragment[k[2]] != F || (excluded && excluded[F])) continue;
      const int32_t o0 = m_faceOpposite[2 * size_t(f)], o1 = m_faceOpposite[2 * size_t(f) + 1];
      const bool in0 = nodeFragment[o0] == F, in1 = o1 >= 0 && nodeFragment[o1] == F;
      if (in0 != in1) add(f, in1);
    }
  }
  // Face adjacency across edges, for the edges' sharpness and outward normals (edge-edge).
  const int32_t count = int32_t(m_faces.size() / 3);
  m_edgeKeys.clear();
  for (int32_t f = 0; f < count; ++f)
    for (int32_t k = 0; k < 3; ++k) {
      const int32_t a = m_faces[3 * size_t(f) + size_t(k)];
      const int32_t b = m_faces[3 * size_t(f) + size_t((k + 1) % 3)];
      m_edgeKeys.push_back({std::min(a, b), std::max(a, b), 3 * f + k});
    }
  std::sort(m_edgeKeys.begin(), m_edgeKeys.end());
  m_neighbours.assign(m_faces.size(), -1);
  for (size_t i = 0; i < m_edgeKeys.size();) {
    size_t j = i + 1;
    while (j < m_edgeKeys.size() && m_edgeKeys[j][0] == m_edgeKeys[i][0] &&
           m_edgeKeys[j][1] == m_edgeKeys[i][1])
      ++j;
    if (j == i + 2) {
      m_neighbours[size_t(m_edgeKeys[i][2])] = m_edgeKeys[i + 1][2] / 3;
      m_neighbours[size_t(m_edgeKeys[i + 1][2])] = m_edgeKeys[i][2] / 3;
    }
    i = j;
  }
  m_vertices.assign(m_faces.begin(), m_faces.end());
  std::sort(m_vertices.begin(), m_vertices.end());
  m_vertices.erase(std::unique(m_vertices.begin(), m_vertices.end()), m_vertices.end());
  (void)model;
}

int64_t BodyContact::find(std::span<const ContactBodyView> bodies, double dt, double stiffness,
                          double slipEps) {
  const size_t slots = bodies.size();
  m_bodies.resize(slots);
  for (Slot& s : m_bodies) {
    s.active = false;
    s.balance = {};
  }
  m_slipEps = slipEps;
  m_pairCount = 0;
  // Groups: one per fragment of each body that takes part.
  m_groupBase.assign(slots, -1);
  m_groupSlot.clear();
  for (size_t si = 0; si < slots; ++si) {
    if (!bodies[si].model) continue;
    m_groupBase[si] = int32_t(m_groupSlot.size());
    m_groupSlot.insert(m_groupSlot.end(), size_t(bodies[si].fragmentCount), int32_t(si));
  }
  const size_t groups = m_groupSlot.size();
  if (groups < 2) return 0;
  auto fragmentOf = [&](const ContactBodyView& b, int32_t n) {
    return b.nodeFragment.empty() ? 0 : b.nodeFragment[size_t(n)];
  };
  // Boxes of the groups over their surface vertices' paths.
  m_box.resize(6 * groups);
  m_groupThickness.assign(groups, 0.0);
  for (size_t g = 0; g < groups; ++g) emptyBox(&m_box[6 * g]);
  for (size_t si = 0; si < slots; ++si) {
    const ContactBodyView& b = bodies[si];
    if (!b.model) continue;
    const double* x = b.state->x.data();
    const double* v = b.state->v.data();
    for (int32_t n : b.surface->vertices()) {
      const size_t g = size_t(m_groupBase[si] + fragmentOf(b, n));
      const Vec3 p = load3(x, n);
      grow(&m_box[6 * g], p);
      grow(&m_box[6 * g], p + dt * load3(v, n));
    }
    for (int32_t f = 0; f < b.fragmentCount; ++f)
      m_groupThickness[size_t(m_groupBase[si] + f)] = kThickness * b.surface->cellSize();
  }
  for (size_t g = 0; g < groups; ++g) pad(&m_box[6 * g], m_groupThickness[g]);
  m_near.assign(groups, 0);
  bool anyNear = false;
  m_nearLinks.clear();
  for (size_t a = 0; a < groups; ++a) {
    if (!(m_box[6 * a] <= m_box[6 * a + 3])) continue;  // no surface vertex
    for (size_t b = a + 1; b < groups; ++b) {
      if (!overlap(&m_box[6 * a], &m_box[6 * b])) continue;
      m_near[a] = m_near[b] = 1;
      m_nearLinks.push_back({int32_t(a), int32_t(b)});
      m_nearLinks.push_back({int32_t(b), int32_t(a)});
      anyNear = true;
    }
  }
  if (!anyNear) return 0;
  std::sort(m_nearLinks.begin(), m_nearLinks.end());

  // The faces of near groups, boxed over both positions, in a sorted grid.
  m_faceSlot.clear();
  m_faceIndex.clear();
  m_faceBox.clear();
  double extent = 0;
  for (size_t si = 0; si < slots; ++si) {
    const ContactBodyView& b = bodies[si];
    if (!b.model) continue;
    const std::span<const int32_t> faces = b.surface->faces();
    const double* x = b.state->x.data();
    const double* v = b.state->v.data();
    for (size_t f = 0; f < faces.size() / 3; ++f) {
      const size_t g = size_t(m_groupBase[si] + fragmentOf(b, faces[3 * f]));
      if (!m_near[g]) continue;
      double box[6];
      emptyBox(box);
      for (int k = 0; k < 3; ++k) {
        const Vec3 p = load3(x, faces[3 * f + k]);
        grow(box, p);
        grow(box, p + dt * load3(v, faces[3 * f + k]));
      }
      pad(box, m_groupThickness[g]);
      extent += std::max({box[3] - box[0], box[4] - box[1], box[5] - box[2]});
      m_faceSlot.push_back(int32_t(si));
      m_faceIndex.push_back(int32_t(f));
      m_faceBox.insert(m_faceBox.end(), box, box + 6);
    }
  }
  const size_t faceCount = m_faceSlot.size();
  if (faceCount == 0) return 0;
  const double h = std::max(extent / double(faceCount), 1e-9);
  m_grid.clear();
  for (size_t f = 0; f < faceCount; ++f) {
    const double* box = &m_faceBox[6 * f];
    int64_t lo[3], hi[3], cells = 1;
    for (int i = 0; i < 3; ++i) {
      lo[i] = cellOf(box[i], h);
      hi[i] = cellOf(box[3 + i], h);
      cells *= hi[i] - lo[i] + 1;
    }
    if (cells > kMaxCellsPerFace) continue;  // see below: such faces are tested by every vertex
    for (int64_t i = lo[0]; i <= hi[0]; ++i)
      for (int64_t j = lo[1]; j <= hi[1]; ++j)
        for (int64_t k = lo[2]; k <= hi[2]; ++k) m_grid.push_back({cellKey(i, j, k), int32_t(f)});
  }
  // Faces too large for the grid (moving many cells in one step): every vertex tests them.
  m_hugeFaces.clear();
  for (size_t f = 0; f < faceCount; ++f) {
    const double* box = &m_faceBox[6 * f];
    int64_t cells = 1;
    for (int i = 0; i < 3; ++i) cells *= cellOf(box[3 + i], h) - cellOf(box[i], h) + 1;
    if (cells > kMaxCellsPerFace) m_hugeFaces.push_back(int32_t(f));
  }
  std::sort(m_grid.begin(), m_grid.end());

  // Masses of the groups, for the edge-edge penalty.
  m_groupMass.assign(groups, 0.0);
  for (size_t si = 0; si < slots; ++si)
    if (bodies[si].model)
      for (int32_t n = 0; n < bodies[si].model->nodeCount; ++n)
        m_groupMass[size_t(m_groupBase[si] + fragmentOf(bodies[si], n))] +=
            bodies[si].state->nodeMass[size_t(n)];
  // Outward normals of the near groups' surface vertices (area-weighted), at x_n.
  for (size_t si = 0; si < slots; ++si) {
    const ContactBodyView& b = bodies[si];
    if (!b.model) continue;
    Slot& out = m_bodies[si];
    out.vertexNormal.resize(size_t(b.model->nodeCount));
    for (int32_t n : b.surface->vertices()) out.vertexNormal[size_t(n)] = Vec3{0, 0, 0};
    const std::span<const int32_t> faces = b.surface->faces();
    const double* x = b.state->x.data();
    for (size_t f = 0; f < faces.size() / 3; ++f) {
      if (!m_near[size_t(m_groupBase[si] + fragmentOf(b, faces[3 * f]))]) continue;
      const Vec3 p0 = load3(x, faces[3 * f]);
      const Vec3 a = cross(load3(x, faces[3 * f + 1]) - p0, load3(x, faces[3 * f + 2]) - p0);
      for (int k = 0; k < 3; ++k) out.vertexNormal[size_t(faces[3 * f + k])] += a;
    }
  }

  // Narrow phase, per vertex of a near group, in slot and node order.
  for (size_t si = 0; si < slots; ++si) {
    const ContactBodyView& b = bodies[si];
    if (!b.model) continue;
    const FemState& st = *b.state;
    m_pairs.clear();
    for (int32_t n : b.surface->vertices()) {
      const int32_t g = m_groupBase[si] + fragmentOf(b, n);
      if (!m_near[size_t(g)] || st.fixedNode[size_t(n)]) continue;
      const Vec3 vertexNormal = m_bodies[si].vertexNormal[size_t(n)];
      // The summed cross products are twice the area of the vertex's faces; a third is its.
      const double vertexArea = norm(vertexNormal) / 6;
      const Vec3 xv = load3(st.x.data(), n), pv = xv + dt * load3(st.v.data(), n);
      double vbox[6];
      emptyBox(vbox);
      grow(vbox, xv);
      grow(vbox, pv);
      pad(vbox, m_groupThickness[size_t(g)]);
      gatherFaces(vbox, h);
      for (int32_t cf : m_candidates) {
        if (!overlap(vbox, &m_faceBox[6 * size_t(cf)])) continue;
        const size_t so = size_t(m_faceSlot[size_t(cf)]);
        const ContactBodyView& o = bodies[so];
        const int32_t* face = &o.surface->faces()[3 * size_t(m_faceIndex[size_t(cf)])];
        const int32_t og = m_groupBase[so] + fragmentOf(o, face[0]);
        if (og == g) continue;  // never a face of the vertex's own fragment
        const FemState& os = *o.state;
        Vec3 p[3], q[3];
        double L = 0;
        for (int k = 0; k < 3; ++k) {
          p[k] = load3(os.x.data(), face[k]);
          q[k] = p[k] + dt * load3(os.v.data(), face[k]);
        }
        for (int k = 0; k < 3; ++k) L = std::max(L, norm(q[(k + 1) % 3] - q[k]));
        Vec3 nq = cross(q[1] - q[0], q[2] - q[0]), np = cross(p[1] - p[0], p[2] - p[0]);
        const double lq = norm(nq), lp = norm(np);
        if (!(lq > 0 && lp > 0)) continue;
        nq = (1.0 / lq) * nq;
        np = (1.0 / lp) * np;
        const Vec3 w = closestOnTriangle(pv, q[0], q[1], q[2]);
        const Vec3 cq = w.x * q[0] + w.y * q[1] + w.z * q[2];
        const Vec3 r = pv - cq;
        const double s = dot(r, nq);
        const Vec3 cp = w.x * p[0] + w.y * p[1] + w.z * p[2];
        const double s0 = dot(xv - cp, np), th = m_groupThickness[size_t(g)];
        if (s > th || norm(r - s * nq) > kLateral * L) continue;
        if (s0 < -kBehind * th) continue;
        // Surfaces in contact face each other: a vertex on the rim of a face's side (a corner
        // resting on the other's top face) is not pushed out through the side.
        if (!(dot(vertexNormal, nq) < 0)) continue;
        // The plane where the two would meet in an inelastic impact (design note); a face
        // with a prescribed node does not give way.
        double mt = 0;
        bool kinematic = false;
        for (int k = 0; k < 3; ++k) {
          mt += w[k] * os.nodeMass[size_t(face[k])];
          kinematic |= os.fixedNode[size_t(face[k])] && w[k] > 0;
        }
        const double mv = st.nodeMass[size_t(n)];
        const double share = kinematic || !(mv + mt > 0) ? 0.0 : mv / (mv + mt);
        // Not deeper than the thickness: the face gives way only through its own body's step,
        // and a vertex left deeper behind it would be dropped next step (kBehind).
        const double depth = s < 0 ? -s : 0.0;
        const double giveWay = std::min(depth * share, m_groupThickness[size_t(og)]);
        // The face where it will be when it comes on towards the vertex (so it pushes in
        // time), where it is when it moves away (a lagged plane that ran ahead of a receding
        // face would let the two sides take turns pushing, step by step).
        const double onward = dot(cq - cp, nq);
        const Vec3 point = (onward > 0 ? cq : cq - onward * nq) - giveWay * nq;
        // Friction: the penalty's normal force at the step's start, lagged (as for colliders),
        // with Box2D's mixing of the two surfaces' coefficients.
        const double startDepth = dot(point - xv, nq);
        const double mu = std::sqrt(b.model->friction * o.model->friction);
        // Stiffness per unit of the vertex's surface area, the same for both sides of a pair of
        // groups: at rest the two sides' penalties then carry the same load (their contact
        // areas agree), so the exchange has nothing to even out and adds no velocity.
        const double k = stiffness * vertexArea * pairScale(b, o);
        const double muLambda = startDepth > 0 ? mu * k * startDepth : 0.0;
        m_pairs.push_back({n, cf, og, point, nq, cq - cp, muLambda, k});
      }
    }
    edgePairs(bodies, si, dt, stiffness, h);
    // Half-spaces run per node in node order; edge-edge ones came after the vertices'.
    std::stable_sort(m_pairs.begin(), m_pairs.end(),
                     [](const Pair& a, const Pair& c) { return a.node < c.node; });
    Slot& out = m_bodies[si];
    const int32_t nodeCount = b.model->nodeCount;
    if (m_pairs.empty()) continue;
    out.active = true;
    out.start.assign(size_t(nodeCount) + 1, 0);
    out.point.resize(m_pairs.size());
    out.normal.resize(m_pairs.size());
    out.partner.resize(m_pairs.size());
    out.muLambda.resize(m_pairs.size());
    out.stiffness.resize(m_pairs.size());
    out.faceMotion.resize(m_pairs.size());
    out.impulse.assign(3 * m_pairs.size(), 0.0);
    for (size_t k = 0; k < m_pairs.size(); ++k) {
      const Pair& pr = m_pairs[k];
      ++out.start[size_t(pr.node) + 1];
      out.point[k] = pr.point;
      out.normal[k] = pr.normal;
      out.partner[k] = pr.partner;
      out.muLambda[k] = pr.muLambda;
      out.stiffness[k] = pr.stiffness;
      out.faceMotion[k] = pr.faceMotion;
    }
    for (int32_t n = 0; n < nodeCount; ++n) out.start[size_t(n) + 1] += out.start[size_t(n)];
    m_pairCount += int64_t(m_pairs.size());
  }
  return m_pairCount;
}

void BodyContact::gatherFaces(const double* box, double h) {
  m_candidates.clear();
  int64_t lo[3], hi[3];
  for (int i = 0; i < 3; ++i) {
    lo[i] = cellOf(box[i], h);
    hi[i] = cellOf(box[3 + i], h);
  }
  for (int64_t i = lo[0]; i <= hi[0]; ++i)
    for (int64_t j = lo[1]; j <= hi[1]; ++j)
      for (int64_t k = lo[2]; k <= hi[2]; ++k) {
        const uint64_t key = cellKey(i, j, k);
        auto it = std::lower_bound(m_grid.begin(), m_grid.end(),
                                   std::pair<uint64_t, int32_t>{key, INT32_MIN});
        for (; it != m_grid.end() && it->first == key; ++it) m_candidates.push_back(it->second);
      }
  m_candidates.insert(m_candidates.end(), m_hugeFaces.begin(), m_hugeFaces.end());
  std::sort(m_candidates.begin(), m_candidates.end());
  m_candidates.erase(std::unique(m_candidates.begin(), m_candidates.end()), m_candidates.end());
}

void BodyContact::edgePairs(std::span<const ContactBodyView> bodies, size_t si, double dt,
                            double stiffness, double h) {
  const ContactBodyView& b = bodies[si];
  const FemState& st = *b.state;
  auto fragmentOf = [](const ContactBodyView& v, int32_t n) {
    return v.nodeFragment.empty() ? 0 : v.nodeFragment[size_t(n)];
  };
  // A surface edge at x_n: the sum of its two faces' unit normals (its outward direction) and
  // whether the faces meet at an angle (a flat face's inner edges are no features).
  auto edgeNormal = [](const ContactBodyView& v, int32_t f, int32_t nb, Vec3& out) {
    const std::span<const int32_t> faces = v.surface->faces();
    Vec3 n[2];
    for (int i = 0; i < 2; ++i) {
      const int32_t* k = &faces[3 * size_t(i == 0 ? f : nb)];
      const Vec3 p0 = load3(v.state->x.data(), k[0]);
      n[i] = cross(load3(v.state->x.data(), k[1]) - p0, load3(v.state->x.data(), k[2]) - p0);
      const double len = norm(n[i]);
      if (!(len > 0)) return false;
      n[i] = (1.0 / len) * n[i];
    }
    out = n[0] + n[1];
    return dot(n[0], n[1]) < kSharpEdge;
  };
  const std::span<const int32_t> ownFaces = b.surface->faces();
  const std::span<const int32_t> ownNb = b.surface->neighbours();
  const double* x = st.x.data();
  const double* v = st.v.data();
  for (int32_t f = 0; f < int32_t(ownFaces.size() / 3); ++f)
    for (int ke = 0; ke < 3; ++ke) {
      const int32_t nb = ownNb[3 * size_t(f) + size_t(ke)];
      if (nb < f) continue;  // each edge once, from its lower face; -1: no feature
      const int32_t a0 = ownFaces[3 * size_t(f) + size_t(ke)];
      const int32_t a1 = ownFaces[3 * size_t(f) + size_t((ke + 1) % 3)];
      const int32_t g = m_groupBase[si] + fragmentOf(b, a0);
      if (!m_near[size_t(g)] || (st.fixedNode[size_t(a0)] && st.fixedNode[size_t(a1)])) continue;
      Vec3 nA;
      if (!edgeNormal(b, f, nb, nA)) continue;
      const double th = m_groupThickness[size_t(g)];
      const Vec3 xa0 = load3(x, a0), xa1 = load3(x, a1);
      const Vec3 pa0 = xa0 + dt * load3(v, a0), pa1 = xa1 + dt * load3(v, a1);
      double box[6];
      emptyBox(box);
      for (Vec3 p : {xa0, xa1, pa0, pa1}) grow(box, p);
      pad(box, th + kEdgeReach * b.surface->cellSize());
      // Most feature edges of a near group are nowhere near the other group's box.
      bool reaches = false;
      for (auto it = std::lower_bound(m_nearLinks.begin(), m_nearLinks.end(),
                                      std::pair<int32_t, int32_t>{g, INT32_MIN});
           it != m_nearLinks.end() && it->first == g && !reaches; ++it)
        reaches = overlap(box, &m_box[6 * size_t(it->second)]);
      if (!reaches) continue;
      gatherFaces(box, h);
      for (int32_t cf : m_candidates) {
        if (!overlap(box, &m_faceBox[6 * size_t(cf)])) continue;
        const size_t so = size_t(m_faceSlot[size_t(cf)]);
        const ContactBodyView& o = bodies[so];
        const int32_t fb = m_faceIndex[size_t(cf)];
        const int32_t* face = &o.surface->faces()[3 * size_t(fb)];
        const int32_t og = m_groupBase[so] + fragmentOf(o, face[0]);
        if (og == g) continue;
        const FemState& os = *o.state;
        for (int kb = 0; kb < 3; ++kb) {
          const int32_t nbB = o.surface->neighbours()[3 * size_t(fb) + size_t(kb)];
          if (nbB < fb) continue;
          const int32_t b0 = face[kb], b1 = face[(kb + 1) % 3];
          Vec3 nB;
          if (!edgeNormal(o, fb, nbB, nB)) continue;
          const Vec3 xb0 = load3(os.x.data(), b0), xb1 = load3(os.x.data(), b1);
          const Vec3 qb0 = xb0 + dt * load3(os.v.data(), b0);
          const Vec3 qb1 = xb1 + dt * load3(os.v.data(), b1);
          double sA = 0, tB = 0;
          if (!closestOnSegments(pa0, pa1, qb0, qb1, sA, tB)) continue;
          // Near an end the vertex-face test already holds it.
          if (sA <= kEdgeEnd || sA >= 1 - kEdgeEnd || tB <= kEdgeEnd || tB >= 1 - kEdgeEnd)
            continue;
          const Vec3 ea = pa1 - pa0, eb = qb1 - qb0;
          Vec3 n = cross(ea, eb);
          const double len = norm(n);
          if (!(len > kEdgeCrossing * norm(ea) * norm(eb))) continue;  // nearly parallel
          n = (1.0 / len) * n;
          // Pushing A away from B: along B's outward direction, against A's.
          if (dot(n, nB - nA) < 0) n = -1.0 * n;
          if (!(dot(n, nB) > 0 && dot(n, nA) < 0)) continue;
          const Vec3 pA = (1 - sA) * pa0 + sA * pa1, pB = (1 - tB) * qb0 + tB * qb1;
          const Vec3 xA = (1 - sA) * xa0 + sA * xa1, xB = (1 - tB) * xb0 + tB * xb1;
          const double gap = dot(pA - pB, n);
          if (gap > th + kEdgeReach * b.surface->cellSize() || dot(xA - xB, n) < -kBehind * th)
            continue;
          // The meeting plane of the two edge points, as for a vertex and a face.
          const double mA = (1 - sA) * st.nodeMass[size_t(a0)] + sA * st.nodeMass[size_t(a1)];
          const double mB = (1 - tB) * os.nodeMass[size_t(b0)] + tB * os.nodeMass[size_t(b1)];
          const bool kinematic = os.fixedNode[size_t(b0)] || os.fixedNode[size_t(b1)];
          const double share = kinematic || !(mA + mB > 0) ? 0.0 : mA / (mA + mB);
          const double giveWay =
              std::min((gap < 0 ? -gap : 0.0) * share, m_groupThickness[size_t(og)]);
          const double onward = dot(pB - xB, n);
          const Vec3 plane = (onward > 0 ? pB : pB - onward * n) - giveWay * n;
          // Two crossing edges may carry a whole body at one point, so the penalty is a
          // collider's for the lighter of the two bodies or fragments (stiffness is per unit
          // mass).
          const double k = stiffness * std::min(m_groupMass[size_t(g)], m_groupMass[size_t(og)]);
          // Each edge node keeps its offset from the edge point: the edge moved as a whole
          // meets the plane with energy k d^2 / 2 split (1 - s, s) over its nodes.
          const int32_t nodes[2] = {a0, a1};
          const double weights[2] = {1 - sA, sA};
          const Vec3 predicted[2] = {pa0, pa1};
          for (int i = 0; i < 2; ++i) {
            if (st.fixedNode[size_t(nodes[i])]) continue;
            m_pairs.push_back(
                {nodes[i], -1, og, plane + (predicted[i] - pA), n, pB - xB, 0.0, k * weights[i]});
          }
        }
      }
    }
}

HalfSpaceContacts BodyContact::halfSpaces(size_t si) const {
  if (si >= m_bodies.size() || !m_bodies[si].active) return {};
  const Slot& s = m_bodies[si];
  HalfSpaceContacts h;
  h.start = s.start.data();
  h.point = s.point.data();
  h.normal = s.normal.data();
  h.stiffness = s.stiffness.data();
  h.muLambda = s.muLambda.data();
  h.faceMotion = s.faceMotion.data();
  h.slipEps = m_slipEps;
  return h;
}

void BodyContact::exchange(std::span<const ContactBodyView> bodies,
                           std::span<FemState* const> states) {
  if (m_pairCount == 0) return;
  const size_t groups = m_groupSlot.size();
  auto fragmentOf = [&](const ContactBodyView& b, int32_t n) {
    return b.nodeFragment.empty() ? 0 : b.nodeFragment[size_t(n)];
  };
  // Clusters: groups joined by a pair (union-find, smaller root wins: independent of order).
  m_cluster.resize(groups);
  for (size_t g = 0; g < groups; ++g) m_cluster[g] = int32_t(g);
  auto root = [&](int32_t g) {
    while (m_cluster[size_t(g)] != g)
      g = m_cluster[size_t(g)] = m_cluster[size_t(m_cluster[size_t(g)])];
    return g;
  };
  for (size_t si = 0; si < bodies.size(); ++si) {
    const Slot& s = m_bodies[si];
    if (!s.active) continue;
    for (int32_t n = 0; n < bodies[si].model->nodeCount; ++n)
      for (int32_t c = s.start[size_t(n)]; c < s.start[size_t(n) + 1]; ++c) {
        const int32_t a = root(m_groupBase[si] + fragmentOf(bodies[si], n));
        const int32_t b = root(s.partner[size_t(c)]);
        if (a != b) m_cluster[size_t(std::max(a, b))] = std::min(a, b);
      }
  }
  // Per cluster: the summed impulses of its half-spaces (zero for an exact action-reaction),
  // its free mass, and whether it can be evened out: every body's impulses known, no
  // kinematic group in it (that one, like a collider, takes momentum out of the cluster).
  m_clusterImpulse.assign(groups, Vec3{0, 0, 0});
  m_clusterMass.assign(groups, 0.0);
  m_clusterOk.assign(groups, 1);
  m_clusterExternal.assign(groups, 0);
  m_freeMass.assign(groups, 0.0);
  for (size_t si = 0; si < bodies.size(); ++si) {
    const ContactBodyView& b = bodies[si];
    if (!b.model) continue;
    for (int32_t n = 0; n < b.model->nodeCount; ++n)
      if (!b.state->fixedNode[size_t(n)])
        m_freeMass[size_t(m_groupBase[si] + fragmentOf(b, n))] += b.state->nodeMass[size_t(n)];
  }
  for (size_t g = 0; g < groups; ++g) {
    const size_t r = size_t(root(int32_t(g)));
    m_clusterMass[r] += m_freeMass[g];
    if (!(m_freeMass[g] > 0)) m_clusterOk[r] = 0;
  }
  for (size_t si = 0; si < bodies.size(); ++si) {
    const Slot& s = m_bodies[si];
    if (!s.active) continue;
    for (int32_t n = 0; n < bodies[si].model->nodeCount; ++n)
      for (int32_t c = s.start[size_t(n)]; c < s.start[size_t(n) + 1]; ++c) {
        const double* j = &s.impulse[3 * size_t(c)];
        m_clusterImpulse[size_t(root(m_groupBase[si] + fragmentOf(bodies[si], n)))] +=
            Vec3{j[0], j[1], j[2]};
      }
  }
  // Each body's unexplained momentum (the linear solve's residual) belongs to the cluster of
  // its first contact node; a cluster on a grip or a collider keeps to its own linear model
  // (design note), so it is left out there.
  auto bodyCluster = [&](size_t si) -> int32_t {
    const Slot& s = m_bodies[si];
    for (int32_t n = 0; s.active && n < bodies[si].model->nodeCount; ++n)
      if (s.start[size_t(n)] < s.start[size_t(n) + 1])
        return root(m_groupBase[si] + fragmentOf(bodies[si], n));
    return -1;
  };
  for (size_t si = 0; si < bodies.size(); ++si)
    if (const int32_t r = bodyCluster(si); r >= 0 && m_bodies[si].balance.external)
      m_clusterExternal[size_t(r)] = 1;
  for (size_t si = 0; si < bodies.size(); ++si)
    if (const int32_t r = bodyCluster(si); r >= 0 && !m_clusterExternal[size_t(r)])
      m_clusterImpulse[size_t(r)] += m_bodies[si].balance.unexplained;
  // The same velocity change for every free node of the cluster: its momentum becomes exactly
  // what it was plus the impulses from outside it, and no relative motion changes.
  bool any = false;
  for (size_t g = 0; g < groups; ++g) {
    const size_t r = size_t(root(int32_t(g)));
    m_groupVelocity.resize(groups);
    m_groupVelocity[g] = Vec3{0, 0, 0};
    if (!m_clusterOk[r] || !(m_clusterMass[r] > 0)) continue;
    m_groupVelocity[g] = (-1.0 / m_clusterMass[r]) * m_clusterImpulse[r];
    any = true;
  }
  if (!any) return;
  for (size_t si = 0; si < bodies.size(); ++si) {
    const ContactBodyView& b = bodies[si];
    if (!b.model) continue;
    FemState& st = *states[si];
    for (int32_t n = 0; n < b.model->nodeCount; ++n) {
      if (st.fixedNode[size_t(n)]) continue;
      const Vec3 dv = m_groupVelocity[size_t(m_groupBase[si] + fragmentOf(b, n))];
      for (int i = 0; i < 3; ++i) st.v[3 * size_t(n) + i] += dv[i];
    }
  }
}

}  // namespace gf::detail
