// Body-body and self contact (issue 15 item 1): the boundary surfaces of all bodies that take
// part (BodyDef::contact), and those of the fragments of one body, push each other through the
// same one-sided penalty as the colliders, inside each body's implicit step.
//
// Design note.
// - Surfaces. A fragment's contact surface is the boundary of the tets whose four nodes are all
//   in it: a tet face whose three nodes are in fragment F bounds F where the tet on one side has
//   its fourth node in F and the other side has no tet or one reaching out of F. The normal
//   points away from the inner tet. An unbroken body's surface is its mesh boundary. Faces
//   between two tets of one fragment are never contact faces, so the two sides of a crack that
//   has not separated the body are left to the damage model (no double counting), and a
//   separated crack opens a layer of tets that span both fragments, whose outer faces meet.
//   The surfaces are rebuilt only when the fragments change (their version).
// - Broad phase, once per substep, serial in slot order (deterministic for any thread count):
//   the groups (one per fragment of each taking part body) are boxed over their surface
//   vertices at x_n and at x_n + dt v_n; only pairs of groups whose boxes overlap go on, so a
//   scene in which no two surfaces come near spends an O(surface vertices) box pass. Then a
//   sorted uniform grid over those groups' faces (each face's box over both positions, grown by
//   the contact thickness) gives each vertex the faces of other groups near its path.
// - Narrow phase, per (vertex, face): the point of the face nearest the vertex's predicted
//   position x~ = x_n + dt v_n, with the face also at its predicted position. The pair is kept
//   when the vertex lies over the face (its offset from the nearest point is along the normal,
//   within a tenth of the face), x~ comes within the thickness of it, the vertex was not more
//   than two thicknesses behind its plane at x_n (it came in through another face, or this is
//   the far side of the other body), and the vertex's own surface faces the face (a rim resting
//   on another body's top face is not pushed out through its side).
// - Edge-edge, per pair of feature edges (the two faces of each meet at an angle; a flat
//   face's inner edges are left out) that cross (not near parallel) with their closest points
//   inside both edges (near an end the vertex-face test holds them): two ridges crossed midway
//   between nodes meet no vertex at all (BodyContact.EdgeOnEdgeMidwayBetweenNodes; the upper
//   block fell through). The normal is the edges' cross product, turned along the other
//   body's outward edge normal and against the own one; the plane is the meeting plane of the
//   two edge points as for a vertex and a face. Each edge node gets a half-space through that
//   plane shifted by its offset from the edge point (the edge moving as a whole meets it with
//   energy k d^2 / 2, split (1 - s, s) over its nodes), so the kernel and sparse pattern are
//   unchanged. One point may carry a whole body: k is a collider's for the lighter body's
//   mass, and the pair is kept from a quarter cell away so its plane is in place a step before
//   it is met. No friction on these pairs yet.
// - Half-space. The vertex must stay in front of a plane with the face's predicted normal,
//   through the face where it will be when it comes towards the vertex (so it pushes in time)
//   and where it is when it recedes (a plane that ran ahead of a receding face let the two
//   sides push in turn, step by step). When both are predicted to overlap by D, the plane is
//   moved back to where they would meet in an inelastic impact of the vertex's node mass m_v
//   with the face's m_t = sum w_i m_i, D m_v / (m_v + m_t) (at most one thickness): each vertex
//   of either side gets its own plane, so two bodies meeting stop at one common plane instead
//   of each at the other's predicted face. The penalty is a collider's (k d^2 / 2, PSD Hessian
//   k n n^T on the node's diagonal block) with IPC friction on the sliding relative to the
//   face, so bodies still step apart and in parallel and the sparse pattern is unchanged. k is
//   a collider's 100 / dt^2 per unit mass times the vertex's surface area times the denser
//   material and the coarser cell: per unit area and equal on both sides of a pair, so that at
//   rest both sides carry the same load.
// - Momentum. A lagged plane is not an exact action-reaction pair, so after the bodies have
//   stepped, the impulse each half-space gave (as the last Newton step linearised it, what
//   entered the momentum balance) is summed over each cluster of groups that touch (directly
//   or through others), and that sum, zero for exact action and reaction, is taken off the
//   cluster as one velocity change of all its free nodes. The cluster's momentum then changes
//   only by what comes from outside it, exactly, and no relative motion changes (evening out
//   each pair of groups apart gave a block squeezed between two others, whose lagged planes
//   overlapped, a kick of 15 m/s). Where a body's last Newton step was shortened by the line
//   search or its solve stopped early, its momentum changed by more than its linear model says;
//   in a cluster that nothing outside touches (no collider, no grip: the one whose momentum
//   must be kept) that residual is counted in too, so its momentum is exact to round-off. In a
//   cluster on a collider it is not (it cannot be told apart from the collider's own residual,
//   and counting it made a resting stack jitter). A cluster holding a kinematic group (no free
//   node) is left as it is.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "fem/fem_body.h"
#include "fem/integrator.h"
#include "kernels/contact.h"

namespace gf::detail {

/// The faces of one body's mesh and the contact surface of its current fragments.
class ContactSurface {
 public:
  /// Face table of the rest mesh (once per body).
  void init(const FemModel& model);
  /// Contact faces and vertices for the fragment labels (null: one fragment), leaving out the
  /// fragments flagged in `excluded` (null: none; 1 per fragment). Rebuilds only when `key`
  /// differs from the last call's.
  void update(const FemModel& model, const int32_t* nodeFragment, const uint8_t* excluded,
              uint64_t key);
  /// 3 nodes per face, counter-clockwise seen from outside.
  std::span<const int32_t> faces() const { return m_faces; }
  /// Per contact face, per edge k (nodes k and k + 1): the contact face across it, -1 where
  /// the edge does not join exactly two faces.
  std::span<const int32_t> neighbours() const { return m_neighbours; }
  /// Nodes on some contact face, ascending.
  std::span<const int32_t> vertices() const { return m_vertices; }
  /// Edge of a regular tet of the mesh's mean volume: the contact thickness's scale.
  double cellSize() const { return m_cellSize; }

 private:
  std::vector<int32_t> m_faceNodes;     // 3 per mesh face, oriented away from m_faceOpposite[0]
  std::vector<int32_t> m_faceOpposite;  // 2 per face: the node opposite on each side, -1 none
  std::vector<int32_t> m_boundary;      // faces with one tet
  std::vector<int32_t> m_faces, m_vertices, m_neighbours;
  std::vector<std::array<int32_t, 3>> m_edgeKeys;  // (lower node, higher node, face * 3 + k)
  uint64_t m_key = ~uint64_t(0);
  double m_cellSize = 0;
};

/// What BodyContact reads of one body.
struct ContactBodyView {
  const FemModel* model = nullptr;
  const FemState* state = nullptr;
  const ContactSurface* surface = nullptr;
  std::span<const int32_t> nodeFragment;  ///< empty: one fragment
  int32_t fragmentCount = 1;
  const uint8_t* excluded = nullptr;  ///< per fragment: handed to rigid physics
};

/// The world's body-body and self contact: per substep, the half-spaces of every body's
/// nodes (find) and, after the bodies stepped, the exact exchange of momentum (exchange).
class BodyContact {
 public:
  /// Finds the contact pairs of the substep dt among `bodies` (one entry per slot; a null
  /// model: the slot takes no part) and fills each body's half-spaces; `stiffness` per unit
  /// mass [1/s^2] as a collider's, slipEps friction's smoothing length. Returns the pair count.
  int64_t find(std::span<const ContactBodyView> bodies, double dt, double stiffness,
               double slipEps);
  /// The half-spaces of slot si for StepContext::bodyContacts (start null: none).
  HalfSpaceContacts halfSpaces(size_t si) const;
  /// Buffer for slot si's half-space impulses (Integrator::bodyContactImpulses), 3 each.
  double* impulseBuffer(size_t si) { return m_bodies[si].impulse.data(); }
  /// What slot si's momentum did beyond its half-space impulses and the external impulses, and
  /// whether a grip or collider acted on it (Integrator::bodyContactImpulses).
  void setBalance(size_t si, BodyContactBalance b) { m_bodies[si].balance = b; }
  /// Takes the mismatch of action and reaction off every cluster of touching groups (design
  /// note) by changing the velocities of their free nodes in `states` (one per slot, as given
  /// to find()).
  void exchange(std::span<const ContactBodyView> bodies, std::span<FemState* const> states);

 private:
  struct Slot {
    std::vector<int32_t> start;  // nodeCount + 1
    std::vector<Vec3> point, normal;
    std::vector<int32_t> partner;    // the group on the other side, per half-space
    std::vector<double> muLambda;    // per half-space
    std::vector<double> stiffness;   // per half-space [N/m]
    std::vector<Vec3> faceMotion;    // per half-space
    std::vector<Vec3> vertexNormal;  // per node (surface vertices of near groups only)
    std::vector<double> impulse;     // 3 per half-space
    bool active = false;
    BodyContactBalance balance;
  };
  struct Pair {
    int32_t node = 0, face = 0;  // face: its index in the other body's surface
    int32_t partner = 0;         // group of the face
    Vec3 point, normal, faceMotion;
    double muLambda = 0, stiffness = 0;
  };

  // The faces of the grid (cell size h) whose cells meet box, into m_candidates.
  void gatherFaces(const double* box, double h);
  // The edge-edge half-spaces of slot si's feature edges, appended to m_pairs.
  void edgePairs(std::span<const ContactBodyView> bodies, size_t si, double dt, double stiffness,
                 double h);

  std::vector<Slot> m_bodies;
  std::vector<int32_t> m_groupBase;  // per slot: its fragment 0's group
  std::vector<int32_t> m_groupSlot;  // per group
  std::vector<double> m_box;         // 6 per group
  std::vector<double> m_groupThickness;
  std::vector<uint8_t> m_near;                           // per group: its box overlaps another's
  std::vector<std::pair<int32_t, int32_t>> m_nearLinks;  // (group, group whose box it meets)
  std::vector<std::pair<uint64_t, int32_t>> m_grid;      // (cell, global face)
  std::vector<int32_t> m_faceSlot, m_faceIndex;  // global face -> slot, index in its surface
  std::vector<double> m_faceBox;                 // 6 per global face
  std::vector<int32_t> m_hugeFaces;
  std::vector<int32_t> m_candidates;
  std::vector<Pair> m_pairs;
  std::vector<int32_t> m_cluster;  // per group: union-find parent
  std::vector<Vec3> m_clusterImpulse;
  std::vector<double> m_clusterMass;
  std::vector<uint8_t> m_clusterOk, m_clusterExternal;
  std::vector<double> m_freeMass;  // per group
  std::vector<Vec3> m_groupVelocity;
  std::vector<double> m_groupMass;  // per group, for the edge-edge penalty
  double m_slipEps = 0;
  int64_t m_pairCount = 0;
};

}  // namespace gf::detail
