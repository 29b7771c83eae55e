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
// - Broad phase, once per substep, as executor stages (contact/contact_stages.h; the same bits
//   for any thread count): the groups (one per fragment of each taking part body) are boxed
//   over their surface vertices at x_n and at x_n + dt v_n (a segmented min and max); only
//   groups whose boxes meet another's go on, so a scene in which no two surfaces come near
//   spends an O(surface vertices) box pass. Then those groups' faces (each face's box over both
//   positions, grown by the contact thickness) go into a spatial hash: the cells of each face
//   by a count, a scan and a fill, radix-sorted by bucket; each vertex (and each feature edge)
//   queries the cells of its path, meets every face once, counts its pairs, and after a scan
//   writes them into its own slots, in face order. A node's half-spaces are its vertex-face
//   pairs, then the edge-edge ones of its edges in edge order.
// - Narrow phase, per (vertex, face): the point of the face nearest the vertex's predicted
//   position x~ = x_n + dt v_n, with the face also at its predicted position. The pair is kept
//   when the vertex lies over the face (its offset from the nearest point is along the normal,
//   within a tenth of the face), x~ comes within the thickness of it (between bodies, plus
//   |dt^2 g . n|, how far gravity alone moves a free side against a supported one, which the
//   predictions leave out), the vertex was not more
//   than two thicknesses behind its plane at x_n (it came in through another face, or this is
//   the far side of the other body), and the vertex's own surface faces the face (a rim resting
//   on another body's top face is not pushed out through its side). A self pair (both sides in
//   one body) that these tests would keep in the rest shape within the thickness is dropped: the
//   two sides of a cut layer's sliver lie that close where nothing overlaps, and their push
//   threw the pieces of a cut bunny apart in free fall.
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
//   sides push in turn, step by step); in a self pair both seen from the vertex's own motion
//   (its prediction, or iterate, less x_n): pieces moving together neither approach nor
//   recede, where a face falling ahead of its vertex kept its plane at its start, one step's
//   fall behind the vertex's prediction, and pushed every step. The same for edge-edge pairs.
//   (Between bodies that broke resting stacks; not understood yet, docs/validation.md.) When both
//   are predicted to overlap by D, the plane is moved back to where they would meet in an inelastic
//   impact (at most one thickness): each vertex of either side gets its own plane, so two bodies
//   meeting stop at one common plane instead of each at the other's predicted face. The overlap
//   at x_n, D_0, is shared by node masses, D_0 m_v / (m_v + m_t) with m_t = sum w_i m_i (both
//   sides of a resting stack then carry the same load); between bodies what the step's motion
//   adds, D - D_0, by the masses of the two groups, as in an impact of the bodies (a block
//   dropped onto a slab on the floor: by node masses the slab's vertices were pushed a quarter
//   of the block's approach into the floor, and the exchange turned that into a bounce). The
//   penalty is a collider's (k d^2 / 2, PSD Hessian k n n^T on the node's diagonal block) with IPC
//   friction on the sliding relative to the face, so bodies still step apart and in parallel and
//   the sparse pattern is unchanged. A plane at the other side's predicted face lies ahead of x_n
//   when both move together, and Newton starts near x_n: where it acts the penalty is linear, so
//   that first step solved it as a two-sided spring that pulled the node back onto the plane. A
//   step that ends with a node in front of a self pair's half-space it was behind at the
//   linearisation goes on to convergence (Integrator::releasedBodyContact); in free fall beside
//   another piece that costs Newton iterations (up to 13 where 1 did). Between bodies it is not
//   done: TwoBlocksComeToRestStacked's steps then reported not ok. k is a collider's 100 / dt^2 per
//   unit mass times the contact area times the denser material and the coarser cell: per unit area
//   and equal on both sides of a pair, so that at rest both sides carry the same load. The
//   area is the vertex's, or where smaller the other surface's at the point it meets (the face
//   nodes' areas, weighted): a coarse vertex under a finer surface presses only on that.
// - Self pairs (both sides in one body) are solved with their face inside the body's Newton
//   step, re-linearised at every iterate (HalfSpaceContacts::pair): a vertex-face pair's plane is
//   its face's as the face now is, d = n . (x_1 - x_v) + s with n the face's current unit normal
//   and s half a contact thickness (kContactSelfSkin: the penalty's give under a landing piece
//   is about a thickness), energy k d^2 / 2, gradient k d g with g = (-n, w_1 n, w_2 n, w_3 n),
//   w the barycentric weights of the vertex's projection onto the plane (exactly d's gradient;
//   a pair that kept the predicted face's normal and nearest point for the step let a vertex
//   sliding over a turning face in by 4 mm). An edge-edge pair keeps its predicted normal and
//   moves with the other edge's point. The pair acts on the vertex and, through a per-node index
//   of the pairs whose face it carries, on the face nodes (k d w_i n): an exact action and
//   reaction inside the body, so the receding rule and the give-way above are not needed and
//   the pair is left out of the momentum exchange; and such a pair acts only where the two
//   sides really meet, so it is kept from a cell in front (kContactSelfReach): the pieces of a
//   cut block approach each other only within the landing step, whose pairs chosen at the
//   thickness were none. The Newton matrix is the Gauss-Newton k g g^T per acting pair (PSD):
//   its diagonal blocks go into the sparse pattern, the cross blocks are applied matrix-free in
//   a flexible CG preconditioned by the body's own solver on the pattern
//   (Integrator::coupledSolve; with the diagonal blocks alone Newton took 12-41 iterations a
//   step). A body with no acting self pair takes the plain solve; a step in which one acts goes
//   on to convergence, up to kMaxSelfIterations.
// - Friction's lagged normal force, for self pairs and pairs between bodies alike, is the load
//   all the node's pairs pressed it with at the end of the last substep (FemState::
//   contactLoad, kept in snapshots), shared over its pairs of this one by their forces at x_n,
//   evenly where none has one (its planes all moved behind it). Each pair's own force at x_n
//   counted the load once per coplanar face the vertex lay over, which changes as it slides
//   across their edges, and gave the nodes a piece's leading edge came over a load they never
//   carried (a sliding piece braked 26-38 % too hard). Between bodies it is worse: the lagged
//   planes move with the other side's prediction, and a resting block's residual mm/s moves
//   them by several times its penalty's equilibrium depth, so that force ran from 0 to ten
//   times the block's weight from step to step (a block sliding over a slab stopped after
//   11-66 % of v^2 / (2 mu g)). The load at the step's end is what the penalty really carried,
//   and its mean over the steps is the weight.
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
//   and counting it made a resting stack jitter). A cluster holding a prescribed node (a grip,
//   a kinematic group) is left as it is: the grip holds the cluster and takes the mismatch.
//   Spread over the free nodes, it went to the slab's free top and to a block resting there
//   alike, the grip took the slab's share back, and the block was thrown at 1-10 m/s
//   (BodyContact.BlockOnAnInclinedBodyObeysCoulomb). The exchange is still needed on a
//   collider, which pushes only: without it, stacks on the ground sank into each other. The
//   clusters are found by stages too: every group takes the least label among the groups its
//   half-spaces join it to, in either direction, until none changes
//   (each group then holds its cluster's least group, the root of a union-find with the smaller
//   root winning). A cluster's impulses are summed in slot, node and half-space order, and its
//   groups' free masses (each in node order) in group order: the serial order of the loop this
//   replaced, whose bits a resting stack is sensitive to (BodyContactStack dropped_30cm_60 slid
//   off its seat with the sums in the executor's chunked order).
// - Sweeps (WorldDef::contactSweeps > 1). find() is called again with each body's substep start
//   (ContactBodyView::x, v) and its latest end-of-step iterate (iterate): the pairs are chosen
//   on the predictions as in the first pass (chosen at the iterates they toggled from sweep to
//   sweep and let a landing box through), the planes, the give-way and friction's face motion
//   are taken at the iterates, and the world steps the touching bodies again against them. A
//   body that broke in the first sweep is still seen with the labels and surface its pairs were
//   first found with (the world passes a copy), so the groups and the exchange stay those.
// - Coupled (WorldDef::coupledContact). Every pair between two bodies is solved with its face,
//   as a self pair is (no skin, kept from a cell in front), its face nodes numbered jointly over
//   all touching bodies: joinSlots renumbers the bodies cluster after cluster (the bodies that
//   pairs join, directly or through others) and lists the joint half-spaces and reactions, which
//   each body's view (halfSpaces) and the cluster's joint solve (Integrator::coupledStep) read
//   at the joint positions jointX and jointXn. Action and reaction are then exact: no exchange.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "contact/contact_hash.h"
#include "contact/contact_stages.h"
#include "fem/fem_body.h"
#include "fem/integrator.h"
#include "kernels/contact.h"
#include "step/executor.h"
#include "step/scan.h"
#include "step/segments.h"

namespace gf::detail {

/// The faces of one body's mesh and the contact surface of its current fragments, with the
/// adjacency lists the contact stages read (rebuilt with the surface: only when the fragments
/// change).
class ContactSurface {
 public:
  /// Face table of the rest mesh (once per body).
  void init(const FemModel& model);
  /// Contact faces and vertices for the fragment labels (null: one fragment; fragmentCount
  /// of them), leaving out the fragments flagged in `excluded` (null: none; 1 per fragment).
  /// Rebuilds only when `key` differs from the last call's.
  void update(const FemModel& model, const int32_t* nodeFragment, int32_t fragmentCount,
              const uint8_t* excluded, uint64_t key);
  /// 3 nodes per face, counter-clockwise seen from outside.
  std::span<const int32_t> faces() const { return m_faces; }
  /// Per contact face: the node opposite it in its tet inside the fragment (the face's inward
  /// side; collider contact at points on faces, fem/face_stage.h).
  std::span<const int32_t> inner() const { return m_inner; }
  /// Per contact face, per edge k (nodes k and k + 1): the contact face across it, -1 where
  /// the edge does not join exactly two faces.
  std::span<const int32_t> neighbours() const { return m_neighbours; }
  /// Nodes on some contact face, ascending.
  std::span<const int32_t> vertices() const { return m_vertices; }
  /// Per node: its index in vertices(), -1 for none.
  std::span<const int32_t> nodeVertex() const { return m_nodeVertex; }
  /// Per vertex (vertexCount + 1 offsets): its faces, ascending.
  std::span<const int32_t> vertexFaceStart() const { return m_vertexFaceStart; }
  std::span<const int32_t> vertexFaces() const { return m_vertexFaces; }
  /// Per vertex (vertexCount + 1 offsets): the face edges 3 f + k it ends, ascending.
  std::span<const int32_t> vertexEdgeStart() const { return m_vertexEdgeStart; }
  std::span<const int32_t> vertexEdges() const { return m_vertexEdges; }
  /// The vertices, and the nodes, grouped by fragment (step/segments.h).
  Segments vertexSegments() const { return m_vertexSegments.view(); }
  Segments nodeSegments() const { return m_nodeSegments.view(); }
  /// Edge of a regular tet of the mesh's mean volume: the contact thickness's scale.
  double cellSize() const { return m_cellSize; }

 private:
  std::vector<int32_t> m_faceNodes;     // 3 per mesh face, oriented away from m_faceOpposite[0]
  std::vector<int32_t> m_faceOpposite;  // 2 per face: the node opposite on each side, -1 none
  std::vector<int32_t> m_boundary;      // faces with one tet
  std::vector<int32_t> m_faces, m_inner, m_vertices, m_neighbours, m_nodeVertex;
  std::vector<int32_t> m_vertexFaceStart, m_vertexFaces, m_vertexEdgeStart, m_vertexEdges;
  std::vector<std::array<int32_t, 3>> m_edgeKeys;  // (lower node, higher node, face * 3 + k)
  SegmentLists m_vertexSegments, m_nodeSegments;
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
  /// Null: the state's x and v; else the substep's start (World's sweeps over the bodies that
  /// touch, whose states then hold the latest iterate of the end).
  const double* x = nullptr;
  const double* v = nullptr;
  const double* iterate = nullptr;  ///< null: none (ContactBody::iterate)
};

/// The world's body-body and self contact: per substep, the half-spaces of every body's
/// nodes (find) and, after the bodies stepped, the exact exchange of momentum (exchange), as
/// stages on the executor.
class BodyContact {
 public:
  /// Finds the contact pairs of the substep dt among `bodies` (one entry per slot; a null
  /// model: the slot takes no part) and fills each body's half-spaces; `gravity` the world's
  /// [m/s^2], `stiffness` per unit mass [1/s^2] as a collider's, slipEps friction's smoothing
  /// length. Returns the pair count.
  /// coupled: every pair between two bodies is solved with both sides, as a self pair is, in
  /// the joint numbering of the coupled bodies (WorldDef::coupledContact; clusters() below).
  int64_t find(const CpuExecutor& exec, std::span<const ContactBodyView> bodies, double dt,
               Vec3 gravity, double stiffness, double slipEps, bool coupled = false);
  /// The half-spaces of slot si for StepContext::bodyContacts (start null: none). Coupled: a
  /// view into the joint arrays, its node indices joint ones, its positions jointX / jointXn.
  HalfSpaceContacts halfSpaces(size_t si) const;

  /// Coupled contact: the bodies that pairs join (directly or through others), each cluster a
  /// run of joint nodes [nodeBegin, nodeEnd) and of half-spaces [pairBegin, pairEnd), its slots
  /// ascending. A body that touches nothing is in none.
  struct Cluster {
    std::vector<uint32_t> slots;
    int32_t nodeBegin = 0, nodeEnd = 0, pairBegin = 0, pairEnd = 0;
  };
  const std::vector<Cluster>& clusters() const { return m_clusters; }
  /// Slot si's first joint node (-1: in no cluster).
  int32_t jointBase(size_t si) const { return si < m_jointBase.size() ? m_jointBase[si] : -1; }
  /// All coupled half-spaces at once (the clusters' solves read their own ranges).
  HalfSpaceContacts jointView() const;
  /// The joint positions the views read (3 per joint node): the iterate and x_n, which the
  /// clusters' solves keep up to date.
  double* jointX() { return m_jointX.data(); }
  int32_t jointNodes() const { return int32_t(m_jointX.size() / 3); }
  int32_t jointPairs() const { return m_jointStart.empty() ? 0 : m_jointStart.back(); }
  double* jointXn() { return m_jointXn.data(); }
  /// Buffer for slot si's half-space impulses (Integrator::bodyContactImpulses), 3 each.
  double* impulseBuffer(size_t si) { return m_bodies[si].impulse.data(); }
  /// What slot si's momentum did beyond its half-space impulses and the external impulses, and
  /// whether a grip or collider acted on it (Integrator::bodyContactImpulses).
  void setBalance(size_t si, BodyContactBalance b) { m_bodies[si].balance = b; }
  /// Takes the mismatch of action and reaction off every cluster of touching groups (design
  /// note) by changing the velocities of their free nodes in `states` (one per slot, as given
  /// to find()).
  void exchange(const CpuExecutor& exec, std::span<FemState* const> states);
  /// Keeps in each state's contactLoad the normal force its nodes' half-spaces press them with at
  /// its positions, the load of their friction in the next substep (cleared for a body without
  /// pairs). Called once the substep's positions are final.
  void recordLoads(const CpuExecutor& exec, std::span<FemState* const> states);

 private:
  struct Slot {
    std::vector<int32_t> start;  // nodeCount + 1
    std::vector<Vec3> point, normal;
    std::vector<int32_t> partner;   // the group on the other side, per half-space
    std::vector<double> muLambda;   // per half-space
    std::vector<double> stiffness;  // per half-space [N/m]
    std::vector<Vec3> faceMotion;   // per half-space
    std::vector<int32_t> fragment;  // per node: the body's fragments when the pairs were found
    int32_t groupEnd = 0;           // one past the body's last group
    std::vector<double> impulse;    // 3 per half-space
    // Self pairs solved with their face (HalfSpaceContacts::faceNode): per half-space its face
    // nodes, weights and vertex node, and per node the entries it carries.
    std::vector<int32_t> faceNode, owner, reactionStart, reaction, reactionFill;
    std::vector<Vec3> weight;
    std::vector<double> skin;  // coupled contact's, per half-space
    bool moving = false;       // any self pair
    bool active = false;
    BodyContactBalance balance;
    // Scratch of the stages.
    std::vector<double> path;        // 6 per surface vertex
    std::vector<Vec3> vertexNormal;  // per surface vertex
    std::vector<int32_t> vertexStart, edgeStart, vertexWritten, edgeWritten;
    std::vector<ContactHalfSpace> vertexPairs, edgePairs;
    std::vector<uint8_t> hasContact;  // per node
  };

  std::vector<Slot> m_bodies;
  std::vector<ContactBody> m_table;  // per slot
  std::vector<int32_t> m_faceBase;   // per slot
  int32_t m_groups = 0;
  std::vector<double> m_box;  // 6 per group
  std::vector<int32_t> m_nearStart, m_nearLinks;
  std::vector<double> m_lower, m_upper, m_partials, m_groupMass, m_groupFree;
  std::vector<int32_t> m_faceSlot, m_chunkCount, m_chunkOffset;
  std::vector<uint8_t> m_faceNear;
  std::vector<double> m_faceNearCount, m_faceBox, m_faceExtent;
  ContactHash m_hash;
  ScanScratch m_scan;
  // The exchange's.
  std::vector<uint64_t> m_linkKeys, m_labelKeys;
  std::vector<int32_t> m_linkValues, m_labelValues, m_label, m_nextLabel;
  std::vector<double> m_changed;
  std::vector<uint64_t> m_entryKeys;  // per node with half-spaces: its cluster
  std::vector<int32_t> m_entryValues, m_entrySlot, m_entryNode;
  std::vector<ContactSlotBalance> m_slotBalance;
  std::vector<Vec3> m_clusterVelocity;
  std::vector<uint8_t> m_clusterMoves;
  // Coupled contact (find(..., coupled)): the half-spaces of the clusters' bodies in one
  // numbering, cluster after cluster.
  void joinSlots();
  bool m_coupled = false;
  std::vector<Cluster> m_clusters;
  std::vector<int32_t> m_jointBase;  // per slot
  std::vector<int32_t> m_jointStart, m_jointPartner, m_jointFaceNode, m_jointOwner;
  std::vector<int32_t> m_jointReactionStart, m_jointReaction;
  std::vector<Vec3> m_jointPoint, m_jointNormal, m_jointFaceMotion, m_jointWeight;
  std::vector<double> m_jointMuLambda, m_jointStiffness, m_jointSkin;
  std::vector<double> m_jointX, m_jointXn, m_jointLoad;
  double m_slipEps = 0;
  int64_t m_pairCount = 0;
};

}  // namespace gf::detail
