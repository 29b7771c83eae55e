// Body-body and self contact's per-substep work as stages (step/executor.h), over flat arrays
// that a CUDA executor can launch on: the groups' boxes and which of them meet, the faces'
// boxes in a spatial hash (cell keys per face by a count, scan and fill, then a radix sort),
// the vertex-face and edge-edge pairs (each vertex or edge queries the hash, counts its pairs,
// then after a scan writes them into its own slots, sorted by face), the per-node half-space
// lists, and the momentum exchange's clusters (label propagation over the touching groups),
// sums and velocity change. Every item writes only its own outputs, and every sum runs in a
// fixed order, so the result is the same for any thread count. The physics is described in
// contact/body_contact.h's design note.
#pragma once

#include <cstdint>

#include "kernels/contact.h"
#include "kernels/gf_hd.h"
#include "kernels/math.h"
#include "step/segments.h"

namespace gf::detail {

// Contact thickness relative to the cell size: how near a vertex's predicted position must come
// to a face for the pair to be kept, and how much the boxes of the broad phase grow.
constexpr double kContactThickness = 0.05;
// A vertex counts as over a face when its offset from the face's nearest point leaves the
// normal by at most this much of the face's longest edge (vertices over a shared edge of two
// faces get both).
constexpr double kContactLateral = 0.1;
// A vertex more than this many contact thicknesses behind a face's plane at the step's start
// went in through another face (or is on the far side of the other body): this face's plane
// would push it out sideways, so the pair is not kept.
constexpr double kContactBehind = 2.0;
// A vertex's pair with a face whose normal meets its surface's within this cosine of a right
// angle is dropped when the vertex also meets a face of the same group more head on than
// kContactHeadOn (the cosine between its surface's normal and the face's, opposed).
constexpr double kContactSide = 0.05;
constexpr double kContactHeadOn = 0.7;
// A face spanning more grid cells than this (a face moving many cells in one step) stays out
// of the hash and is tested by every vertex: it cannot be missed, only tested more often.
constexpr int64_t kContactMaxCellsPerFace = 4096;
// Edge-edge proximity (design note): only feature edges, whose two faces' normals meet at more
// than about 25 degrees (cos below this), crossing at more than about 6 degrees (the sine of
// their angle above this), closest at least this fraction of either edge away from its ends.
constexpr double kContactSharpEdge = 0.9;
constexpr double kContactEdgeCrossing = 0.1;
constexpr double kContactEdgeEnd = 0.05;
// Edge pairs are kept while the predicted edges come within this much of a cell plus the
// thickness: one point may have to stop a whole body, so its plane is set up a step before it
// is met (a plane not reached costs nothing: the penalty is one-sided).
constexpr double kContactEdgeReach = 0.25;
// A self vertex-face pair is kept while the vertex's prediction comes within this many cells
// of the face: its plane moves with the face's nodes inside the body's Newton step (design
// note), so a pair found early acts only where the two sides really meet, and the landing step,
// in which pieces that fell together first approach, already holds it.
constexpr double kContactSelfReach = 1.0;
// A self vertex-face pair's plane lies this many contact thicknesses in front of its face: the
// penalty gives under a landing piece (1.42 mm of a thrown piece's nodes in the other, bound
// 1 mm, with the plane at the face; 0.75 mm with it here).
constexpr double kContactSelfSkin = 0.5;

GF_HD Vec3 contactLoad3(const double* p, int32_t i) {
  return {p[3 * int64_t(i)], p[3 * int64_t(i) + 1], p[3 * int64_t(i) + 2]};
}
GF_HD void boxEmpty(double* box) {
  for (int i = 0; i < 3; ++i) {
    box[i] = HUGE_VAL;
    box[3 + i] = -HUGE_VAL;
  }
}
GF_HD void boxGrow(double* box, Vec3 p) {
  for (int i = 0; i < 3; ++i) {
    box[i] = p[i] < box[i] ? p[i] : box[i];
    box[3 + i] = p[i] > box[3 + i] ? p[i] : box[3 + i];
  }
}
GF_HD void boxPad(double* box, double r) {
  for (int i = 0; i < 3; ++i) {
    box[i] -= r;
    box[3 + i] += r;
  }
}
GF_HD bool boxOverlap(const double* a, const double* b) {
  for (int i = 0; i < 3; ++i)
    if (a[i] > b[3 + i] || b[i] > a[3 + i]) return false;
  return true;
}

/// Packs integer cell coordinates (21 bits each, offset) into one key.
GF_HD uint64_t contactCellKey(int64_t x, int64_t y, int64_t z) {
  constexpr int64_t kOffset = int64_t(1) << 20, kMask = (int64_t(1) << 21) - 1;
  return (uint64_t((x + kOffset) & kMask) << 42) | (uint64_t((y + kOffset) & kMask) << 21) |
         uint64_t((z + kOffset) & kMask);
}
/// The cell of coordinate v, clamped to +-1e6 cells (a NaN to the lowest: no cast of a NaN).
GF_HD int64_t contactCellOf(double v, double h) {
  const double c = floor(v / h);
  return int64_t(c > -1e6 ? (c < 1e6 ? c : 1e6) : -1e6);
}
/// The hash bucket of a cell key among 2^bits (Fibonacci hashing: the high bits of the product).
GF_HD uint64_t contactBucket(uint64_t key, int bits) {
  return (key * 0x9E3779B97F4A7C15ull) >> (64 - bits);
}

/// Last index i with base[i] <= v among `count` non-decreasing entries (base[0] <= v).
GF_HD int32_t lastAtMost(const int32_t* base, int32_t count, int32_t v) {
  int32_t lo = 0, hi = count;  // base[lo] <= v, base[hi] > v (hi = count: past the end)
  while (hi - lo > 1) {
    const int32_t mid = lo + (hi - lo) / 2;
    if (base[mid] <= v)
      lo = mid;
    else
      hi = mid;
  }
  return lo;
}
/// First index in [lo, hi) whose key is at least v (hi if none).
GF_HD int32_t lowerBound(const uint64_t* keys, int32_t lo, int32_t hi, uint64_t v) {
  while (lo < hi) {
    const int32_t mid = lo + (hi - lo) / 2;
    if (keys[mid] < v)
      lo = mid + 1;
    else
      hi = mid;
  }
  return lo;
}

/// What the stages read of one body (slot) taking part; a slot taking no part has groupBase -1
/// and no faces.
struct ContactBody {
  const double* x = nullptr;
  const double* v = nullptr;
  const double* nodeMass = nullptr;
  const uint8_t* fixed = nullptr;
  const int32_t* fragment = nullptr;    ///< per node; null: one fragment
  const int32_t* faces = nullptr;       ///< 3 per contact face
  const int32_t* neighbours = nullptr;  ///< 3 per contact face (ContactSurface::neighbours)
  const int32_t* vertices = nullptr;    ///< the surface vertices, ascending
  const int32_t* nodeVertex = nullptr;  ///< per node: its surface vertex, -1 none
  /// Per surface vertex its outward normal at x_n (ContactVertexNormalStage), set for the
  /// vertices of groups that meet another.
  const Vec3* vertexNormal = nullptr;
  /// Null, or the latest iterate of the step's end positions (World's contact sweeps): the
  /// pairs are still chosen on x_n + dt v_n, their planes are taken at the iterates.
  const double* iterate = nullptr;
  const double* rest = nullptr;  ///< the rest positions, for the self pairs' check
  double density = 0, cellSize = 0, friction = 0;
  int32_t groupBase = -1, faceBase = 0, faceCount = 0, vertexCount = 0, nodeCount = 0;
  /// Coupled contact: the body's first node in the joint numbering of the coupled bodies, whose
  /// pairs with each other are solved with both sides as self pairs are; -1: not coupled.
  int32_t jointBase = -1;

  GF_HD int32_t group(int32_t n) const { return groupBase + (fragment ? fragment[n] : 0); }
  GF_HD double thickness() const { return kContactThickness * cellSize; }
  /// Surface node n's share of its faces' area (a third of each).
  GF_HD double area(int32_t n) const { return norm(vertexNormal[nodeVertex[n]]) / 6; }
  /// Node n where the planes are taken: the iterate, else the prediction p.
  GF_HD Vec3 planeAt(int32_t n, Vec3 p) const { return iterate ? contactLoad3(iterate, n) : p; }
};

/// Mass per unit surface area [kg/m^2] that scales a pair's penalty (design note): the denser
/// material over the coarser cell, so that the penalty is at least as stiff as a collider's on
/// either side's surface nodes.
GF_HD double contactPairScale(const ContactBody& a, const ContactBody& b) {
  return (a.density > b.density ? a.density : b.density) *
         (a.cellSize > b.cellSize ? a.cellSize : b.cellSize);
}

/// One half-space of a node (HalfSpaceContacts), with the face it came from (its global
/// index; -1 for an edge-edge pair) for the order of a node's list.
struct ContactHalfSpace {
  int32_t node = 0, face = 0, partner = 0;  ///< partner: the group on the other side
  Vec3 point, normal, faceMotion;
  double muLambda = 0, stiffness = 0;
  /// A vertex-face pair's friction coefficient and its penalty's force at x_n (k times its
  /// depth there): its friction's lagged normal force, or for a self pair its share of the
  /// vertex's (ContactNodeListStage).
  double mu = 0, startForce = 0;
  /// A self pair solved with its face (HalfSpaceContacts::faceNode): the face's nodes (an
  /// edge-edge pair: the other edge's two, the second repeated with weight 0), -1 none, and the
  /// nearest point's weights; point is then the offset from sum w_i x_i. A vertex-face pair is
  /// re-linearised at each iterate (HalfSpaceContacts::pair), its weights only for a face that
  /// degenerates there.
  int32_t faceNode[3] = {-1, -1, -1};
  Vec3 weight;
  double skin = 0;  ///< a pair solved with its face: its plane's distance in front of the face
};

/// A run of half-spaces into face order, stably (equal faces keep their order): the few pairs
/// of one vertex or edge.
GF_HD void sortByFace(ContactHalfSpace* h, int32_t count) {
  for (int32_t i = 1; i < count; ++i) {
    const ContactHalfSpace t = h[i];
    int32_t j = i;
    for (; j > 0 && h[j - 1].face > t.face; --j) h[j] = h[j - 1];
    h[j] = t;
  }
}

/// Surface vertex i's path box per axis over x_n and x_n + dt v_n, as six arrays of
/// vertexCount (lower x, y, z, upper x, y, z) for the segmented min and max per group.
struct ContactPathBoxStage {
  ContactBody body;
  double dt = 0;
  double* out = nullptr;

  GF_HD void operator()(int32_t i) const {
    const int32_t n = body.vertices[i];
    const Vec3 p = contactLoad3(body.x, n), q = p + dt * contactLoad3(body.v, n);
    const int64_t V = body.vertexCount;
    for (int k = 0; k < 3; ++k) {
      out[k * V + i] = q[k] < p[k] ? q[k] : p[k];
      out[(3 + k) * V + i] = q[k] > p[k] ? q[k] : p[k];
    }
  }
};

/// The box of fragment f's group from its per-axis minima and maxima, grown by the thickness
/// and by how far gravity alone moves a node in the step.
struct ContactGroupBoxStage {
  ContactBody body;
  const double* lower = nullptr;  ///< 3 arrays of fragments
  const double* upper = nullptr;
  int32_t fragments = 0;
  double fall = 0;        ///< |g| dt^2 (ContactScene::fall)
  double* box = nullptr;  ///< 6 per group

  GF_HD void operator()(int32_t f) const {
    double* b = box + 6 * int64_t(body.groupBase + f);
    for (int k = 0; k < 3; ++k) {
      b[k] = lower[int64_t(k) * fragments + f];
      b[3 + k] = upper[int64_t(k) * fragments + f];
    }
    boxPad(b, body.thickness() + fall);
  }
};

/// Group a's links to the groups whose boxes meet its own, ascending: their number (links
/// null) or the groups themselves at links[start[a]..].
struct ContactNearStage {
  const double* box = nullptr;
  int32_t groups = 0;
  const int32_t* start = nullptr;
  int32_t* counts = nullptr;
  int32_t* links = nullptr;

  GF_HD void operator()(int32_t a) const {
    int32_t k = 0;
    const double* ba = box + 6 * int64_t(a);
    if (ba[0] <= ba[3])  // else no surface vertex
      for (int32_t b = 0; b < groups; ++b)
        if (b != a && boxOverlap(ba, box + 6 * int64_t(b))) {
          if (links) links[start[a] + k] = b;
          ++k;
        }
    if (!links) counts[a] = k;
  }
};

/// Global face gf (the faces of every slot one after another): its slot, whether its group
/// meets another, its box over both positions grown by the thickness and the fall (near faces only)
/// its largest extent, the hash's cell size's measure.
struct ContactFaceStage {
  const ContactBody* bodies = nullptr;
  const int32_t* faceBase = nullptr;  ///< per slot
  int32_t slots = 0;
  const int32_t* nearStart = nullptr;  ///< groups + 1
  double dt = 0;
  double fall = 0;  ///< |g| dt^2 (ContactScene::fall)
  int32_t* faceSlot = nullptr;
  uint8_t* near = nullptr;
  double* nearCount = nullptr;  ///< 1 or 0, summed
  double* box = nullptr;        ///< 6 per face
  double* extent = nullptr;

  GF_HD void operator()(int32_t gf) const {
    const int32_t s = lastAtMost(faceBase, slots, gf);
    const ContactBody& b = bodies[s];
    const int32_t* face = b.faces + 3 * int64_t(gf - b.faceBase);
    const int32_t g = b.group(face[0]);
    const bool isNear = nearStart[g + 1] > nearStart[g];
    faceSlot[gf] = s;
    near[gf] = isNear ? 1 : 0;
    nearCount[gf] = isNear ? 1.0 : 0.0;
    double* bx = box + 6 * int64_t(gf);
    boxEmpty(bx);
    for (int k = 0; k < 3; ++k) {
      const Vec3 p = contactLoad3(b.x, face[k]);
      boxGrow(bx, p);
      boxGrow(bx, p + dt * contactLoad3(b.v, face[k]));
    }
    boxPad(bx, b.thickness() + fall);
    double e = 0;
    for (int k = 0; k < 3; ++k) e = bx[3 + k] - bx[k] > e ? bx[3 + k] - bx[k] : e;
    extent[gf] = isNear ? e : 0.0;
  }
};

/// The hash: cells of size h; entry e (after the sort) of bucket key[e] is cell cell[value[e]]
/// of face face[value[e]]; faces too large for it are listed apart.
struct ContactGrid {
  double h = 1;
  int bits = 1;
  const int32_t* bucketStart = nullptr;  ///< 2^bits + 1: bucket b's sorted entries
  const int32_t* value = nullptr;        ///< per sorted entry: its fill index
  const uint64_t* cell = nullptr;        ///< per fill index
  const int32_t* face = nullptr;         ///< per fill index
  int32_t entries = 0;
  const int32_t* huge = nullptr;
  int32_t hugeCount = 0;
  const double* faceBox = nullptr;  ///< 6 per global face

  GF_HD void cells(const double* box, int64_t* lo, int64_t* hi) const {
    for (int i = 0; i < 3; ++i) {
      lo[i] = contactCellOf(box[i], h);
      hi[i] = contactCellOf(box[3 + i], h);
    }
  }
  /// Calls visit(face) once for every face whose cells meet the box's, and every huge face.
  /// Faces in the hash are visited at the first cell (lowest coordinates) of the intersection
  /// of the two boxes' cell ranges: once each, whatever shares their buckets.
  template <class Visit>
  GF_HD void forFaces(const double* box, Visit& visit) const {
    int64_t lo[3], hi[3];
    cells(box, lo, hi);
    for (int64_t i = lo[0]; i <= hi[0]; ++i)
      for (int64_t j = lo[1]; j <= hi[1]; ++j)
        for (int64_t k = lo[2]; k <= hi[2]; ++k) {
          const uint64_t c = contactCellKey(i, j, k), b = contactBucket(c, bits);
          for (int32_t e = bucketStart[b]; e < bucketStart[b + 1]; ++e) {
            const int32_t fill = value[e];
            if (cell[fill] != c) continue;
            const int32_t f = face[fill];
            int64_t flo[3], fhi[3];
            cells(faceBox + 6 * int64_t(f), flo, fhi);
            if (i != (lo[0] > flo[0] ? lo[0] : flo[0]) || j != (lo[1] > flo[1] ? lo[1] : flo[1]) ||
                k != (lo[2] > flo[2] ? lo[2] : flo[2]))
              continue;
            visit(f);
          }
        }
    for (int32_t u = 0; u < hugeCount; ++u) visit(huge[u]);
  }
};

/// Global face gf's cells in the hash: their number (0 for a face of a group that meets no
/// other, or a huge one, flagged), or (cell, bucket, face) at fill[start[gf]..] in x, y, z order.
struct ContactCellStage {
  const uint8_t* near = nullptr;
  const double* faceBox = nullptr;
  double h = 1;
  int bits = 1;
  const int32_t* start = nullptr;
  int32_t* counts = nullptr;
  uint8_t* huge = nullptr;
  uint64_t* bucket = nullptr;  ///< fill pass: per entry
  uint64_t* cell = nullptr;
  int32_t* face = nullptr;
  int32_t* fillIndex = nullptr;

  GF_HD void operator()(int32_t gf) const {
    int64_t lo[3], hi[3], cells = 1;
    for (int i = 0; i < 3; ++i) {
      lo[i] = contactCellOf(faceBox[6 * int64_t(gf) + i], h);
      hi[i] = contactCellOf(faceBox[6 * int64_t(gf) + 3 + i], h);
      cells *= hi[i] - lo[i] + 1;
    }
    const bool inGrid = near[gf] && cells <= kContactMaxCellsPerFace;
    if (!bucket) {
      counts[gf] = inGrid ? int32_t(cells) : 0;
      huge[gf] = near[gf] && !inGrid ? 1 : 0;
      return;
    }
    if (!inGrid) return;
    int32_t e = start[gf];
    for (int64_t i = lo[0]; i <= hi[0]; ++i)
      for (int64_t j = lo[1]; j <= hi[1]; ++j)
        for (int64_t k = lo[2]; k <= hi[2]; ++k, ++e) {
          cell[e] = contactCellKey(i, j, k);
          bucket[e] = contactBucket(cell[e], bits);
          face[e] = gf;
          fillIndex[e] = e;
        }
  }
};

/// The first entry of each bucket among the sorted bucket keys: sorted entry e (e = entries:
/// the end) starts the buckets after the previous entry's up to its own, so every bucket of
/// the 2^bits + 1 is written once (an empty one gets the start of the next).
struct ContactBucketStartStage {
  const uint64_t* keys = nullptr;
  int32_t entries = 0;
  int64_t buckets = 0;
  int32_t* start = nullptr;

  GF_HD void operator()(int32_t e) const {
    const int64_t from = e == 0 ? 0 : int64_t(keys[e - 1]) + 1;
    const int64_t to = e == entries ? buckets : int64_t(keys[e]);
    for (int64_t b = from; b <= to; ++b) start[b] = e;
  }
};

/// What the pair stages read of the broad phase.
struct ContactScene {
  const ContactBody* bodies = nullptr;
  const int32_t* faceSlot = nullptr;
  const double* groupBox = nullptr;
  const int32_t* nearStart = nullptr;
  const int32_t* nearLinks = nullptr;
  const double* groupMass = nullptr;
  ContactGrid grid;
  double dt = 0, stiffness = 0;
  /// dt^2 g: how far gravity alone moves a free node against a supported one in the step. The
  /// predictions x_n + dt v_n leave it out (a block put at rest 2 mm above a slab falls 11 mm in
  /// a step at 30 Hz, and was inside the slab before any pair was found), so a pair between
  /// bodies is also kept from |fall . n| in front of its face.
  Vec3 fall;

  GF_HD const int32_t* face(int32_t gf, const ContactBody*& owner) const {
    owner = &bodies[faceSlot[gf]];
    return owner->faces + 3 * int64_t(gf - owner->faceBase);
  }
};

/// Surface vertex i's outward normal (area-weighted; its length is twice its faces' area) at
/// x_n, its faces summed in face order, for the vertices of groups that meet another.
struct ContactVertexNormalStage {
  ContactBody body;
  const int32_t* nearStart = nullptr;
  const int32_t* vertexFaceStart = nullptr;  ///< ContactSurface's, vertexCount + 1
  const int32_t* vertexFaces = nullptr;
  Vec3* normal = nullptr;

  GF_HD void operator()(int32_t i) const {
    const int32_t g = body.group(body.vertices[i]);
    if (!(nearStart[g + 1] > nearStart[g])) return;
    Vec3 a{0, 0, 0};
    for (int32_t s = vertexFaceStart[i]; s < vertexFaceStart[i + 1]; ++s) {
      const int32_t* k = body.faces + 3 * int64_t(vertexFaces[s]);
      const Vec3 p0 = contactLoad3(body.x, k[0]);
      a += cross(contactLoad3(body.x, k[1]) - p0, contactLoad3(body.x, k[2]) - p0);
    }
    normal[i] = a;
  }
};

/// The vertex-face pairs of surface vertex i (design note, narrow phase), by face. The count
/// pass (out null) writes a bound of their number, the faces of other groups whose boxes meet
/// the vertex's (so the narrow phase runs once); the fill pass writes the pairs at
/// out[start[i]..] and their number to written[i].
struct ContactVertexPairStage {
  ContactScene scene;
  int32_t slot = 0;
  const int32_t* start = nullptr;
  int32_t* counts = nullptr;
  ContactHalfSpace* out = nullptr;
  int32_t* written = nullptr;

  GF_HD void operator()(int32_t i) const {
    const ContactBody& b = scene.bodies[slot];
    const int32_t n = b.vertices[i];
    const int32_t g = b.group(n);
    int32_t count = 0;
    if (scene.nearStart[g + 1] > scene.nearStart[g] && !b.fixed[n]) {
      const double dt = scene.dt, th = b.thickness();
      const Vec3 vn = b.vertexNormal[i];
      const double vertexArea = b.area(n);
      const Vec3 xv = contactLoad3(b.x, n), pv = xv + dt * contactLoad3(b.v, n);
      double vbox[6];
      boxEmpty(vbox);
      boxGrow(vbox, xv);
      boxGrow(vbox, pv);
      // A body of several fragments also looks for self pairs, from further away.
      const double selfReach = kContactSelfReach * b.cellSize;
      const double fallReach = th + norm(scene.fall);
      const double reach =
          (b.fragment || b.jointBase >= 0) && selfReach > fallReach ? selfReach : fallReach;
      boxPad(vbox, reach);
      auto visit = [&](int32_t cf) {
        if (!boxOverlap(vbox, scene.grid.faceBox + 6 * int64_t(cf))) return;
        const ContactBody* o = nullptr;
        const int32_t* face = scene.face(cf, o);
        const int32_t og = o->group(face[0]);
        if (og == g) return;  // never a face of the vertex's own fragment
        // Solved with its face: a self pair, or any pair between coupled bodies.
        const bool solved = o == &b || (b.jointBase >= 0 && o->jointBase >= 0);
        if (!out) {
          ++count;
          return;
        }
        Vec3 p[3], q[3];
        double L = 0;
        for (int k = 0; k < 3; ++k) {
          p[k] = contactLoad3(o->x, face[k]);
          q[k] = p[k] + dt * contactLoad3(o->v, face[k]);
        }
        for (int k = 0; k < 3; ++k) {
          const double e = norm(q[(k + 1) % 3] - q[k]);
          L = e > L ? e : L;
        }
        Vec3 nq = cross(q[1] - q[0], q[2] - q[0]), np = cross(p[1] - p[0], p[2] - p[0]);
        const double lq = norm(nq), lp = norm(np);
        if (!(lq > 0 && lp > 0)) return;
        nq = (1.0 / lq) * nq;
        np = (1.0 / lp) * np;
        const Vec3 w = closestOnTriangle(pv, q[0], q[1], q[2]);
        const Vec3 cq = w.x * q[0] + w.y * q[1] + w.z * q[2];
        const Vec3 r = pv - cq;
        const double s = dot(r, nq);
        const Vec3 cp = w.x * p[0] + w.y * p[1] + w.z * p[2];
        const double s0 = dot(xv - cp, np);
        const double keep = solved ? reach : th + fabs(dot(scene.fall, nq));
        if (s > keep || norm(r - s * nq) > kContactLateral * L) return;
        if (s0 < -kContactBehind * th) return;
        // Surfaces in contact face each other: a vertex on the rim of a face's side (a corner
        // resting on the other's top face) is not pushed out through the side.
        if (!(dot(vn, nq) < 0)) return;
        // Nor is a vertex whose surface meets another body's face at a right angle, when it was
        // behind the face's plane at x_n and is in front of it at the prediction: the face's
        // edge passes over it (a slab's top node under a sliding block's trailing face; the
        // sign above is round-off's there), and the receding face's plane, kept at its start,
        // pushed the node out along the slide (-10.6 N s in one step, the slab thrown at 0.2
        // m/s). Inside a body, behind its plane at both (a head-on collision's), it is kept.
        if (!solved && s0 < 0 && s > 0 && dot(vn, nq) > -kContactSide * norm(vn)) return;
        // The two sides of a cut layer's sliver can lie within the thickness of each other, or
        // a vertex just past a face's edge behind its plane, in the rest shape, where nothing
        // overlaps: such a self pair is the plane's error, not contact, and pushed the pieces
        // of a cut bunny apart while they fell together (BodyContactSlow.
        // PiecesOfACutBodyFallTogether). So a vertex that the test above would keep against a
        // face of its own body at rest within the thickness is not kept.
        if (o == &b && b.rest) {
          Vec3 r[3];
          double Lr = 0;
          for (int k = 0; k < 3; ++k) r[k] = contactLoad3(b.rest, face[k]);
          for (int k = 0; k < 3; ++k) {
            const double e = norm(r[(k + 1) % 3] - r[k]);
            Lr = e > Lr ? e : Lr;
          }
          const Vec3 xr = contactLoad3(b.rest, n);
          const Vec3 nr = cross(r[1] - r[0], r[2] - r[0]);
          const double lr = norm(nr);
          if (lr > 0) {
            const Vec3 wr = closestOnTriangle(xr, r[0], r[1], r[2]);
            const Vec3 rr = xr - (wr.x * r[0] + wr.y * r[1] + wr.z * r[2]);
            const double sr = dot(rr, nr) / lr;
            if (sr < th && sr > -kContactBehind * th &&
                norm(rr - (sr / lr) * nr) <= kContactLateral * Lr)
              return;
          }
        }
        // The sweeps' planes: the same pair, at the two sides' latest iterates.
        Vec3 wi = w, cqi = cq, nqi = nq, pvi = pv;
        if (b.iterate || o->iterate) {
          Vec3 qi[3];
          for (int k = 0; k < 3; ++k) qi[k] = o->planeAt(face[k], q[k]);
          pvi = b.planeAt(n, pv);
          const Vec3 ni = cross(qi[1] - qi[0], qi[2] - qi[0]);
          const double li = norm(ni);
          if (li > 0) {
            nqi = (1.0 / li) * ni;
            wi = closestOnTriangle(pvi, qi[0], qi[1], qi[2]);
            cqi = wi.x * qi[0] + wi.y * qi[1] + wi.z * qi[2];
          }
        }
        const double si = dot(pvi - cqi, nqi);
        // The plane where the two would meet in an inelastic impact (design note); a face
        // with a prescribed node does not give way.
        double mt = 0;
        bool kinematic = false;
        for (int k = 0; k < 3; ++k) {
          mt += wi[k] * o->nodeMass[face[k]];
          kinematic |= o->fixed[face[k]] && wi[k] > 0;
        }
        const double mv = b.nodeMass[n];
        const double share = kinematic || !(mv + mt > 0) ? 0.0 : mv / (mv + mt);
        const double depth = si < 0 ? -si : 0.0;
        // Between bodies, what the two sides' motion adds over the step to the overlap they
        // start with is shared as in an impact of their groups (the bodies' masses): a light
        // block falling onto a slab on the floor stops at the slab's surface, where shared by
        // node masses the slab's vertices were pushed a quarter of the block's approach into
        // the floor, pressing it with 33 times the block's own impulse, which the exchange then
        // handed back to both as a bounce. The overlap at x_n (a resting one) keeps the node
        // masses' share, so both sides of a resting stack carry the same load.
        double give = depth * share;
        if (o != &b) {
          const double start0 = s0 < 0 ? (-s0 < depth ? -s0 : depth) : 0.0;
          const double gv = scene.groupMass[g], gt = scene.groupMass[og];
          const double groupShare = kinematic || !(gv + gt > 0) ? 0.0 : gv / (gv + gt);
          give = start0 * share + (depth - start0) * groupShare;
        }
        // Not deeper than the thickness: the face gives way only through its own body's step,
        // and a vertex left deeper behind it would be dropped next step (kContactBehind).
        const double giveWay = give < o->thickness() ? give : o->thickness();
        // The face where it will be when it comes on towards the vertex (so it pushes in
        // time), where it is when it moves away (a lagged plane that ran ahead of a receding
        // face would let the two sides take turns pushing, step by step).
        const Vec3 cpi = wi.x * p[0] + wi.y * p[1] + wi.z * p[2];
        // In a self pair both seen from the vertex's own motion: pieces falling together do
        // not approach, and a face falling away ahead of its vertex left the plane at the
        // face's start, one step's fall behind the vertex's prediction (a push every step).
        // Between bodies it is not done yet: resting stacks lost up to 14 % of their ground
        // force and kept moving at 5 cm/s (BodyContactStack), not understood.
        const Vec3 own = o == &b ? pvi - xv : Vec3{0, 0, 0};
        const double onward = dot((cqi - cpi) - own, nqi);
        const Vec3 point = (onward > 0 ? cqi : cqi - onward * nqi) - giveWay * nqi;
        {
          // Friction: the penalty's normal force at the step's start, lagged (as for
          // colliders), with Box2D's mixing of the two surfaces' coefficients.
          const double startDepth = dot(point - xv, nqi);
          const double mu = sqrt(b.friction * o->friction);
          // Stiffness per unit of contact area, the same for both sides of a pair of groups: at
          // rest the two sides' penalties then carry the same load, so the exchange has nothing
          // to even out and adds no velocity. The area is the vertex's, or the other surface's
          // at the point it meets (its face nodes' areas, weighted) where that is smaller: a
          // coarse vertex under a fine face presses only on what of the fine surface is there
          // (with its own area, a slab's 10 cm vertex under a sliding block's 2.5 cm faces
          // was 16 times as stiff as the block's, and the exchange handed its spikes to both).
          double faceArea = 0;
          for (int c = 0; c < 3; ++c) faceArea += wi[c] * o->area(face[c]);
          const double area = faceArea < vertexArea ? faceArea : vertexArea;
          const double k = scene.stiffness * area * contactPairScale(b, *o);
          ContactHalfSpace& h = out[start[i] + count];
          h.node = n;
          h.face = cf;
          h.partner = og;
          h.point = point;
          h.normal = nqi;
          h.faceMotion = cqi - cpi;
          h.mu = mu;
          h.startForce = startDepth > 0 ? k * startDepth : 0.0;
          h.stiffness = k;
          if (solved) {
            // Solved with its face: the plane of the face as it moves, a skin in front in a
            // self pair. Between coupled bodies none: a block put down on another was thrown up
            // by the skin (0.16 m/s from a 10 cm-cell slab's 2.5 mm).
            const int32_t base = o->jointBase >= 0 ? o->jointBase : 0;
            for (int c = 0; c < 3; ++c) h.faceNode[c] = base + face[c];
            h.weight = wi;
            h.point = Vec3{0, 0, 0};
            h.skin = o == &b ? kContactSelfSkin * th : 0.0;
            // The pair's force at x_n from its face's plane there, not the lagged plane (the
            // face's prediction against the vertex's start), which let pairs kept from a cell
            // away rub the pieces of a falling cut body apart. Measured from the plane the
            // pair pushes from, a skin in front of the face, where a resting vertex sits
            // (from the face itself, pieces resting on each other had no friction).
            const double d0 = h.skin - s0;
            h.startForce = d0 > 0 ? k * d0 : 0.0;
          } else {
            for (int c = 0; c < 3; ++c) h.faceNode[c] = -1;
          }
        }
        ++count;
      };
      scene.grid.forFaces(vbox, visit);
      // A vertex that meets another group's face head on does not also meet that group's
      // faces at right angles: a slab's top node under a sliding block's bottom face was
      // pushed out through the block's leading face too (the facing test's sign there is
      // round-off's), which kicked the block back at every node it came over.
      if (out && count > 1) {
        ContactHalfSpace* h = out + start[i];
        const double len = norm(vn);
        int32_t kept = 0;
        for (int32_t a = 0; a < count; ++a) {
          bool headOn = false;
          if (dot(vn, h[a].normal) > -kContactSide * len)
            for (int32_t c = 0; c < count && !headOn; ++c)
              headOn = h[c].partner == h[a].partner && dot(vn, h[c].normal) < -kContactHeadOn * len;
          if (!headOn) h[kept++] = h[a];
        }
        count = kept;
      }
    }
    if (out) {
      sortByFace(out + start[i], count);
      written[i] = count;
    } else {
      counts[i] = count;
    }
  }
};

/// The edge-edge half-spaces (design note) of surface edge e = 3 f + k of the slot's faces
/// (nodes k and k + 1 of face f; each edge once, from its lower face), by the other edge's
/// face: a bound of their number (out null: two per edge of the other groups' faces whose
/// boxes meet its own), or the half-spaces at out[start[e]..] and their number in written[e].
struct ContactEdgePairStage {
  ContactScene scene;
  int32_t slot = 0;
  const int32_t* start = nullptr;
  int32_t* counts = nullptr;
  ContactHalfSpace* out = nullptr;
  int32_t* written = nullptr;

  // A surface edge at x_n: the sum of its two faces' unit normals (its outward direction) and
  // whether the faces meet at an angle (a flat face's inner edges are no features).
  GF_HD static bool edgeNormal(const ContactBody& v, int32_t f, int32_t nb, Vec3& out) {
    Vec3 n[2];
    for (int i = 0; i < 2; ++i) {
      const int32_t* k = v.faces + 3 * int64_t(i == 0 ? f : nb);
      const Vec3 p0 = contactLoad3(v.x, k[0]);
      n[i] = cross(contactLoad3(v.x, k[1]) - p0, contactLoad3(v.x, k[2]) - p0);
      const double len = norm(n[i]);
      if (!(len > 0)) return false;
      n[i] = (1.0 / len) * n[i];
    }
    out = n[0] + n[1];
    return dot(n[0], n[1]) < kContactSharpEdge;
  }

  GF_HD void operator()(int32_t e) const {
    const ContactBody& b = scene.bodies[slot];
    const int32_t f = e / 3, ke = e % 3;
    int32_t count = 0;
    const int32_t nb = b.neighbours[e];
    const int32_t a0 = b.faces[3 * int64_t(f) + ke];
    const int32_t a1 = b.faces[3 * int64_t(f) + (ke + 1) % 3];
    const int32_t g = b.group(a0);
    Vec3 nA;
    // Each edge once, from its lower face; -1: no feature.
    if (nb >= f && scene.nearStart[g + 1] > scene.nearStart[g] && !(b.fixed[a0] && b.fixed[a1]) &&
        edgeNormal(b, f, nb, nA)) {
      const double dt = scene.dt, th = b.thickness(), reach = kContactEdgeReach * b.cellSize;
      const Vec3 xa0 = contactLoad3(b.x, a0), xa1 = contactLoad3(b.x, a1);
      const Vec3 pa0 = xa0 + dt * contactLoad3(b.v, a0), pa1 = xa1 + dt * contactLoad3(b.v, a1);
      double box[6];
      boxEmpty(box);
      boxGrow(box, xa0);
      boxGrow(box, xa1);
      boxGrow(box, pa0);
      boxGrow(box, pa1);
      boxPad(box, th + reach);
      // Most feature edges of a near group are nowhere near the other group's box.
      bool reaches = false;
      for (int32_t l = scene.nearStart[g]; l < scene.nearStart[g + 1] && !reaches; ++l)
        reaches = boxOverlap(box, scene.groupBox + 6 * int64_t(scene.nearLinks[l]));
      auto visit = [&](int32_t cf) {
        if (!boxOverlap(box, scene.grid.faceBox + 6 * int64_t(cf))) return;
        const ContactBody* o = nullptr;
        const int32_t* face = scene.face(cf, o);
        const int32_t fb = cf - o->faceBase;
        const int32_t og = o->group(face[0]);
        if (og == g) return;
        for (int kb = 0; kb < 3; ++kb) {
          const int32_t nbB = o->neighbours[3 * int64_t(fb) + kb];
          if (nbB < fb) continue;
          if (!out) {
            count += 2;
            continue;
          }
          const int32_t b0 = face[kb], b1 = face[(kb + 1) % 3];
          Vec3 nB;
          if (!edgeNormal(*o, fb, nbB, nB)) continue;
          const Vec3 xb0 = contactLoad3(o->x, b0), xb1 = contactLoad3(o->x, b1);
          const Vec3 qb0 = xb0 + dt * contactLoad3(o->v, b0);
          const Vec3 qb1 = xb1 + dt * contactLoad3(o->v, b1);
          double sA = 0, tB = 0;
          if (!closestOnSegments(pa0, pa1, qb0, qb1, sA, tB)) continue;
          // Near an end the vertex-face test already holds it.
          if (sA <= kContactEdgeEnd || sA >= 1 - kContactEdgeEnd || tB <= kContactEdgeEnd ||
              tB >= 1 - kContactEdgeEnd)
            continue;
          const Vec3 ea = pa1 - pa0, eb = qb1 - qb0;
          Vec3 n = cross(ea, eb);
          const double len = norm(n);
          if (!(len > kContactEdgeCrossing * norm(ea) * norm(eb))) continue;  // nearly parallel
          n = (1.0 / len) * n;
          // Pushing A away from B: along B's outward direction, against A's.
          if (dot(n, nB - nA) < 0) n = -1.0 * n;
          if (!(dot(n, nB) > 0 && dot(n, nA) < 0)) continue;
          const Vec3 pA = (1 - sA) * pa0 + sA * pa1, pB = (1 - tB) * qb0 + tB * qb1;
          const Vec3 xA = (1 - sA) * xa0 + sA * xa1, xB = (1 - tB) * xb0 + tB * xb1;
          const double gap = dot(pA - pB, n);
          if (gap > th + reach || dot(xA - xB, n) < -kContactBehind * th) continue;
          // The sweeps' planes: the same pair, at the latest iterates.
          const Vec3 ia0 = b.planeAt(a0, pa0), ia1 = b.planeAt(a1, pa1);
          const Vec3 ib0 = o->planeAt(b0, qb0), ib1 = o->planeAt(b1, qb1);
          const Vec3 iA = (1 - sA) * ia0 + sA * ia1, iB = (1 - tB) * ib0 + tB * ib1;
          const double igap = dot(iA - iB, n);
          for (int i = 0; i < 2; ++i)
            if (!b.fixed[i == 0 ? a0 : a1]) {
              {
                // The meeting plane of the two edge points, as for a vertex and a face.
                const double mA = (1 - sA) * b.nodeMass[a0] + sA * b.nodeMass[a1];
                const double mB = (1 - tB) * o->nodeMass[b0] + tB * o->nodeMass[b1];
                const bool kinematic = o->fixed[b0] || o->fixed[b1];
                const double share = kinematic || !(mA + mB > 0) ? 0.0 : mA / (mA + mB);
                const double sink = (igap < 0 ? -igap : 0.0) * share;
                const double giveWay = sink < o->thickness() ? sink : o->thickness();
                // Relative to the edge's own motion in a self pair, as for a vertex; between
                // bodies that let an upper block's ridge sink into a lower one's by 8.6 % of
                // a cell (EdgeOnEdgeMidwayBetweenNodes), not understood yet.
                const Vec3 own = o == &b ? iA - xA : Vec3{0, 0, 0};
                const double onward = dot((iB - xB) - own, n);
                const Vec3 plane = (onward > 0 ? iB : iB - onward * n) - giveWay * n;
                // Two crossing edges may carry a whole body at one point, so the penalty is a
                // collider's for the lighter of the two bodies or fragments (stiffness is per
                // unit mass).
                const double mg = scene.groupMass[g], mo = scene.groupMass[og];
                const double k = scene.stiffness * (mg < mo ? mg : mo);
                // Each edge node keeps its offset from the edge point: the edge moved as a
                // whole meets the plane with energy k d^2 / 2 split (1 - s, s) over its nodes.
                ContactHalfSpace& h = out[start[e] + count];
                h.node = i == 0 ? a0 : a1;
                h.face = cf;
                h.partner = og;
                h.point = plane + ((i == 0 ? ia0 : ia1) - iA);
                h.normal = n;
                h.faceMotion = iB - xB;
                h.muLambda = 0;
                h.stiffness = k * (i == 0 ? 1 - sA : sA);
                for (int c = 0; c < 3; ++c) h.faceNode[c] = -1;
                if (o == &b || (b.jointBase >= 0 && o->jointBase >= 0)) {
                  // Solved with the other edge: its point (1 - t) x_b0 + t x_b1 carries the
                  // plane.
                  const int32_t base = o->jointBase >= 0 ? o->jointBase : 0;
                  h.faceNode[0] = base + b0;
                  h.faceNode[1] = h.faceNode[2] = base + b1;
                  h.weight = Vec3{1 - tB, tB, 0};
                  h.point = (i == 0 ? ia0 : ia1) - iA;
                }
              }
              ++count;
            }
        }
      };
      if (reaches) scene.grid.forFaces(box, visit);
    }
    if (out) {
      sortByFace(out + start[e], count);
      written[e] = count;
    } else {
      counts[e] = count;
    }
  }
};

/// Node n's half-spaces: its vertex-face pairs, then the edge-edge ones of its surface edges in
/// edge order. Their number (the outputs null) or the half-spaces from start[n] on.
struct ContactNodeListStage {
  const int32_t* nodeVertex = nullptr;   ///< per node: its surface vertex, -1 none
  const int32_t* vertexStart = nullptr;  ///< each vertex's slots, of which it wrote
  const int32_t* vertexWritten = nullptr;
  const ContactHalfSpace* vertexPairs = nullptr;
  const int32_t* vertexEdgeStart = nullptr;  ///< ContactSurface's, vertexCount + 1
  const int32_t* vertexEdges = nullptr;
  const int32_t* edgeStart = nullptr;
  const int32_t* edgeWritten = nullptr;
  const ContactHalfSpace* edgePairs = nullptr;
  const int32_t* start = nullptr;
  int32_t* counts = nullptr;
  Vec3* point = nullptr;
  Vec3* normal = nullptr;
  Vec3* faceMotion = nullptr;
  int32_t* partner = nullptr;
  double* muLambda = nullptr;
  double* stiffness = nullptr;
  double* impulse = nullptr;    ///< 3 per half-space, zeroed
  int32_t* faceNode = nullptr;  ///< 3 per half-space
  Vec3* weight = nullptr;
  double* skin = nullptr;  ///< per half-space; null: not kept
  /// Per node the load its half-spaces pressed it with at the end of the last substep
  /// (FemState::contactLoad; null: none).
  const double* load = nullptr;

  GF_HD void put(int32_t at, const ContactHalfSpace& h) const {
    for (int k = 0; k < 3; ++k) faceNode[3 * int64_t(at) + k] = h.faceNode[k];
    weight[at] = h.weight;
    if (skin) skin[at] = h.skin;
    point[at] = h.point;
    normal[at] = h.normal;
    faceMotion[at] = h.faceMotion;
    partner[at] = h.partner;
    muLambda[at] = h.muLambda;
    stiffness[at] = h.stiffness;
    for (int k = 0; k < 3; ++k) impulse[3 * int64_t(at) + k] = 0;
  }

  GF_HD void operator()(int32_t n) const {
    const int32_t v = nodeVertex[n];
    int32_t c = 0;
    if (v >= 0) {
      // Friction bears the vertex's load of the last substep, shared by the pairs' forces at
      // x_n, evenly where none has one (design note, contact/body_contact.h).
      double forces = 0;
      for (int32_t p = vertexStart[v]; p < vertexStart[v] + vertexWritten[v]; ++p)
        forces += vertexPairs[p].startForce;
      const double pressed = load ? load[n] : 0.0;
      const double scale = forces > 0 ? pressed / forces : 0.0;
      const double even = vertexWritten[v] > 0 ? pressed / vertexWritten[v] : 0.0;
      for (int32_t p = vertexStart[v]; p < vertexStart[v] + vertexWritten[v]; ++p, ++c)
        if (point) {
          const ContactHalfSpace& h = vertexPairs[p];
          put(start[n] + c, h);
          muLambda[start[n] + c] = h.mu * (forces > 0 ? h.startForce * scale : even);
        }
      for (int32_t s = vertexEdgeStart[v]; s < vertexEdgeStart[v + 1]; ++s) {
        const int32_t e = vertexEdges[s];
        for (int32_t p = edgeStart[e]; p < edgeStart[e] + edgeWritten[e]; ++p)
          if (edgePairs[p].node == n) {
            if (point) put(start[n] + c, edgePairs[p]);
            ++c;
          }
      }
    }
    if (!point) counts[n] = c;
  }
};

/// Per node, the normal force its half-spaces press it with at positions h.X:
/// FemState::contactLoad.
struct ContactLoadStage {
  HalfSpaceContacts h;
  double* load = nullptr;

  GF_HD void operator()(int32_t n) const {
    double sum = 0;
    for (int32_t k = h.start[n]; k < h.start[n + 1]; ++k) {
      const double d = h.depth(k, h.nodeAt(n));
      if (d > 0) sum += h.stiffness[k] * d;
    }
    load[n] = sum;
  }
};

/// For the exchange's clusters: both directions (own group, partner) of node n's half-spaces
/// as keys a G + b, from keys[2 base + 2 start[n]] on.
struct ContactLinkKeyStage {
  ContactBody body;
  const int32_t* start = nullptr;
  const int32_t* partner = nullptr;
  int64_t groups = 0;
  int64_t base = 0;
  uint64_t* keys = nullptr;
  int32_t* values = nullptr;

  GF_HD void operator()(int32_t n) const {
    const int64_t a = body.group(n);
    for (int32_t c = start[n]; c < start[n + 1]; ++c) {
      const int64_t i = 2 * (base + c), b = partner[c];
      keys[i] = uint64_t(a * groups + b);
      keys[i + 1] = uint64_t(b * groups + a);
      values[i] = int32_t(i);
      values[i + 1] = int32_t(i + 1);
    }
  }
};

/// One round of cluster labelling: group a takes the least label of itself and the groups it
/// touches (the sorted link keys a G + b); changed[a] says whether it took a new one. Repeated
/// until nothing changes, every group holds the least group of its cluster.
struct ContactLabelStage {
  const uint64_t* keys = nullptr;
  int32_t keyCount = 0;
  int64_t groups = 0;
  const int32_t* label = nullptr;
  int32_t* next = nullptr;
  double* changed = nullptr;

  GF_HD void operator()(int32_t a) const {
    int32_t m = label[a];
    const uint64_t lo = uint64_t(a * groups), hi = uint64_t((a + 1) * groups);
    for (int32_t i = lowerBound(keys, 0, keyCount, lo); i < keyCount && keys[i] < hi; ++i) {
      const int32_t l = label[int64_t(keys[i] - lo)];
      m = l < m ? l : m;
    }
    next[a] = m;
    changed[a] = m != label[a] ? 1.0 : 0.0;
  }
};

/// Fragment f's group: its mass and its free mass (nodes whose velocity is not prescribed),
/// summed over its nodes in node order (the momentum exchange's bits depend on it: see
/// BodyContact::exchange).
struct ContactGroupMassStage {
  ContactBody body;
  Segments nodes;  ///< the body's nodes by fragment
  double* mass = nullptr;
  double* freeMass = nullptr;

  GF_HD void operator()(int32_t f) const {
    double m = 0, free = 0;
    for (int32_t i = nodes.start[f]; i < nodes.start[f + 1]; ++i) {
      const int32_t n = nodes.order ? nodes.order[i] : i;
      m += body.nodeMass[n];
      if (!body.fixed[n]) free += body.nodeMass[n];
    }
    mass[body.groupBase + f] = m;
    freeMass[body.groupBase + f] = free;
  }
};

/// Whether node n has a half-space.
struct ContactHasHalfSpaceStage {
  const int32_t* start = nullptr;
  uint8_t* out = nullptr;

  GF_HD void operator()(int32_t n) const { out[n] = start[n] < start[n + 1] ? 1 : 0; }
};

/// Entry base + k (the slot's k-th node with half-spaces, in node order): its slot and its
/// cluster as the sort key, so that each cluster's nodes come out in slot and node order.
struct ContactEntryStage {
  ContactBody body;
  int32_t slot = 0;
  const int32_t* label = nullptr;
  int32_t base = 0;
  const int32_t* node = nullptr;
  int32_t* entrySlot = nullptr;
  uint64_t* keys = nullptr;
  int32_t* values = nullptr;

  GF_HD void operator()(int32_t k) const {
    const int32_t e = base + k;
    entrySlot[e] = slot;
    keys[e] = uint64_t(label[body.group(node[e])]);
    values[e] = e;
  }
};

/// What the exchange knows of one slot: the group of its first contact node (-1: none) and its
/// momentum balance (BodyContactBalance).
struct ContactSlotBalance {
  int32_t group = -1;
  bool external = false;
  Vec3 unexplained;
  const int32_t* start = nullptr;  ///< its half-spaces per node
  const double* impulse = nullptr;
  int32_t entryBase = 0, entryCount = 0;
};

/// Cluster r (a group holding its own label, with its groups at sorted[first..] by the sorted
/// labels): the velocity change that takes its summed impulse off it, if no node of it is
/// prescribed (a grip holds the cluster and takes the mismatch, design note). A body's
/// unexplained momentum belongs to the cluster of its first contact node, unless a grip or
/// collider acts on that cluster.
struct ContactClusterStage {
  const int32_t* label = nullptr;
  const uint64_t* sortedLabel = nullptr;
  const int32_t* sortedGroup = nullptr;
  int32_t groups = 0;
  const double* mass = nullptr;          ///< per group
  const double* freeMass = nullptr;      ///< per group
  const uint64_t* entryLabel = nullptr;  ///< sorted
  const int32_t* entryIndex = nullptr;   ///< per sorted entry
  const int32_t* entrySlot = nullptr;    ///< per entry
  const int32_t* entryNode = nullptr;
  int32_t entries = 0;
  const ContactSlotBalance* slots = nullptr;
  int32_t slotCount = 0;
  Vec3* velocity = nullptr;  ///< per cluster root
  uint8_t* moves = nullptr;

  GF_HD void operator()(int32_t r) const {
    moves[r] = 0;
    if (label[r] != r) return;
    double free = 0;
    bool ok = true;
    for (int32_t i = lowerBound(sortedLabel, 0, groups, uint64_t(r));
         i < groups && sortedLabel[i] == uint64_t(r); ++i) {
      const double m = freeMass[sortedGroup[i]];
      free += m;
      if (m < mass[sortedGroup[i]]) ok = false;
    }
    Vec3 j{0, 0, 0};
    for (int32_t i = lowerBound(entryLabel, 0, entries, uint64_t(r));
         i < entries && entryLabel[i] == uint64_t(r); ++i) {
      const int32_t e = entryIndex[i], n = entryNode[e];
      const ContactSlotBalance& s = slots[entrySlot[e]];
      for (int32_t c = s.start[n]; c < s.start[n + 1]; ++c)
        j += Vec3{s.impulse[3 * int64_t(c)], s.impulse[3 * int64_t(c) + 1],
                  s.impulse[3 * int64_t(c) + 2]};
    }
    bool external = false;
    for (int32_t s = 0; s < slotCount; ++s)
      if (slots[s].group >= 0 && label[slots[s].group] == r) external |= slots[s].external;
    if (!external)
      for (int32_t s = 0; s < slotCount; ++s)
        if (slots[s].group >= 0 && label[slots[s].group] == r) j += slots[s].unexplained;
    if (!ok || !(free > 0)) return;
    velocity[r] = (-1.0 / free) * j;
    moves[r] = 1;
  }
};

/// Node n's velocity change: its cluster's, unless prescribed.
struct ContactVelocityStage {
  ContactBody body;
  const int32_t* label = nullptr;
  const Vec3* velocity = nullptr;
  const uint8_t* moves = nullptr;
  double* v = nullptr;

  GF_HD void operator()(int32_t n) const {
    if (body.fixed[n]) return;
    const int32_t r = label[body.group(n)];
    if (!moves[r]) return;
    for (int k = 0; k < 3; ++k) v[3 * int64_t(n) + k] += velocity[r][k];
  }
};

/// Items 0..count-1 (the cluster labels' start), or as sort keys.
struct ContactIotaStage {
  int32_t* out = nullptr;
  GF_HD void operator()(int32_t i) const { out[i] = i; }
};
struct ContactLabelSortStage {
  const int32_t* label = nullptr;
  uint64_t* keys = nullptr;
  int32_t* values = nullptr;
  GF_HD void operator()(int32_t g) const {
    keys[g] = uint64_t(label[g]);
    values[g] = g;
  }
};

}  // namespace gf::detail
