// World: bodies in CutMode::Xfem (issue 21 item 4). Such a body is stepped by its Is-XFEM body
// (xfem/cut_body.h: linear elasticity, the implicit step of eq 3.13 on a sparse Cholesky factor)
// instead of the integrator, and cut through its tets by World::cut.
//
// Design: the body keeps the FemModel and FemState every body has, so that positions(),
// velocities(), stateHash and the queries that read nodes see it like any other body (a snapshot
// holds them too, but restore refuses the body: its enriched DOFs and cuts are not in it): after
// each substep its nodes' x and v are the standard DOFs (rest + u, v), which is what the enriched
// field (eq 3.4) gives at the nodes wherever a node has no enriched function, and the field of the
// node's own side otherwise (an enriched function vanishes at its node, eq 3.3). A cut builds a new
// XfemBody with the blade added (the system grows, which the world's fixed block-sparse pattern
// could not) and carries the state over unchanged; its events wait for the next step, as a graph
// cut's do. The blade comes in world coordinates and is carried to the rest frame by the inverse of
// the best-fit rigid motion of the piece it meets (the identity for a body at rest, exactly), so a
// cut of a deformed piece is placed to the deformation's size. Colliders: planes only, as hard
// frictionless contact of the render surface's vertices inside the step (XfemBody::step with
// planes), so pieces land on the floor along their exact cut faces.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/matrix.hpp>
#include <map>
#include <string>
#include <vector>

#include "kernels/tet_inertia.h"
#include "step/timing.h"
#include "world/world_impl.h"

namespace gf {

namespace {
using detail::toGlm;

using detail::XfemBody;
using detail::XfemRecord;

// Nodes' x and v from the standard DOFs.
void mirrorState(BodyRecord& b) {
  const XfemBody& x = *b.xfem->body;
  const auto& rest = b.model.restPositions;
  for (size_t i = 0; i < b.state.x.size(); ++i) {
    b.state.x[i] = rest[i] + x.displacement()[Eigen::Index(i)];
    b.state.v[i] = x.velocity()[Eigen::Index(i)];
  }
}

// Rest frame = R^T (world - centre) + restCentre: a best-fit rigid motion, inverted.
struct RestFrame {
  Mat3 rotationT = Mat3::identity();
  Vec3 centre, restCentre;
  Vec3 toRest(Vec3 x) const { return rotationT * (x - centre) + restCentre; }
  Vec3 toWorld(Vec3 X) const { return transpose(rotationT) * (X - restCentre) + centre; }
};

// The rest frame of the piece the blade meets: the piece with the most surface vertices (now)
// in the blade's box over the sweep, grown by a tenth of its size (else the piece nearest to the
// box's centre), and its best-fit rigid motion (Kabsch on those vertices). The pieces of a cut
// body move apart, so one motion for the whole body would carry the blade off the piece it
// aims at.
RestFrame restFrame(const XfemBody& x, const Blade& blade) {
  RestFrame f;
  if (x.displacement().isZero(0)) return f;  // at rest: exactly the identity
  Vec3 lo{INFINITY, INFINITY, INFINITY}, hi = -lo;
  for (const glm::mat4* m : {&blade.from, &blade.to})
    for (const glm::vec3& v : blade.vertices) {
      const glm::vec4 w = *m * glm::vec4(v, 1.0f);
      for (int i = 0; i < 3; ++i)
        lo[i] = std::min(lo[i], double(w[i])), hi[i] = std::max(hi[i], double(w[i]));
    }
  const Vec3 grow = 0.1 * (hi - lo), centre = 0.5 * (lo + hi);
  lo = lo - grow;
  hi = hi + grow;
  const auto current = [&](const detail::XfemPieceSurface& s, size_t i) {
    Vec3 p = s.vertices[i].rest;
    for (int32_t w = s.weightStart[i]; w < s.weightStart[i + 1]; ++w)
      for (int d = 0; d < 3; ++d)
        p[d] += s.weightValue[size_t(w)] * x.displacement()[3 * s.weightFunction[size_t(w)] + d];
    return p;
  };
  size_t piece = 0, most = 0;
  double nearest = INFINITY;
  for (size_t k = 0; k < x.surface().size(); ++k) {
    if (x.pieces()[k].dropped) continue;  // handed to rigid physics: not where its DOFs say
    const detail::XfemPieceSurface& s = x.surface()[k];
    size_t inside = 0;
    double closest = INFINITY;
    for (size_t i = 0; i < s.vertices.size(); ++i) {
      const Vec3 p = current(s, i);
      bool in = true;
      for (int d = 0; d < 3; ++d) in = in && p[d] >= lo[d] && p[d] <= hi[d];
      inside += in;
      closest = std::min(closest, norm(p - centre));
    }
    if (inside > most || (most == 0 && closest < nearest)) piece = k;
    most = std::max(most, inside);
    nearest = std::min(nearest, closest);
  }
  const detail::XfemPieceSurface& s = x.surface()[piece];
  Vec3 restMean, mean;
  for (size_t i = 0; i < s.vertices.size(); ++i) {
    restMean += s.vertices[i].rest;
    mean += current(s, i);
  }
  restMean = (1.0 / double(s.vertices.size())) * restMean;
  mean = (1.0 / double(s.vertices.size())) * mean;
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();  // sum (X - X0)(x - x0)^T
  for (size_t i = 0; i < s.vertices.size(); ++i) {
    const Vec3 a = s.vertices[i].rest - restMean, b = current(s, i) - mean;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) H(r, c) += a[r] * b[c];
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1 : 1;
  const Eigen::Matrix3d R = svd.matrixV() * D * svd.matrixU().transpose();  // rest to current
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) f.rotationT(r, c) = R(c, r);
  f.centre = mean;
  f.restCentre = restMean;
  return f;
}

detail::BladePose restPose(const glm::mat4& m, const RestFrame& f) {
  Mat3 R;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R(i, j) = m[j][i];  // glm is column-major
  detail::BladePose p;
  p.rotation = f.rotationT * R;
  p.translation = f.toRest(Vec3{m[3][0], m[3][1], m[3][2]});
  return p;
}

Vec3 tetCentroid(const TetMesh& mesh, int32_t t) {
  Vec3 c;
  for (int a = 0; a < 4; ++a)
    for (int i = 0; i < 3; ++i)
      c[i] += 0.25 * mesh.positions[3 * size_t(mesh.tets[4 * size_t(t) + size_t(a)]) + size_t(i)];
  return c;
}

// The piece's public fragment event fields.
FragmentEvent pieceEvent(BodyId id, const XfemBody& x, int piece, int32_t fragment,
                         int32_t parent) {
  const detail::XfemPiece& p = x.pieces()[size_t(piece)];
  FragmentEvent ev;
  ev.body = id;
  ev.fragment = fragment;
  ev.parent = parent;
  for (int32_t n = 0; n < int32_t(x.def().mesh.nodeCount()); ++n) ev.nodeCount += p.load[n] > 0;
  ev.volume = p.volume;
  ev.mass = x.def().material.density * p.volume;
  const Vec3 c = x.pieceRestCentre(piece) + x.pieceMeanDisplacement(piece);
  const Vec3 v = ev.mass > 0 ? (1.0 / ev.mass) * x.momentum(piece) : Vec3{};
  ev.centreOfMass = glm::vec3(float(c.x), float(c.y), float(c.z));
  ev.velocity = glm::vec3(float(v.x), float(v.y), float(v.z));
  return ev;
}

}  // namespace

namespace detail {

Result<std::unique_ptr<XfemRecord>> buildXfem(const BodyDef& def, Vec3 gravity) {
  XfemBodyDef xd;
  xd.mesh = def.mesh;
  xd.material.youngs = def.material.youngsModulus;
  xd.material.poisson = def.material.poissonRatio;
  xd.material.density = def.material.density;
  xd.gravity = gravity;
  for (const Grip& g : def.grips)
    xd.fixedNodes.insert(xd.fixedNodes.end(), g.nodes.begin(), g.nodes.end());
  auto made = XfemBody::create(xd);
  if (!made) return fail("BodyDef.cutMode: ", made.error().message);
  auto r = std::make_unique<XfemRecord>();
  r->body = std::move(made.value());
  const Eigen::Index nodes = Eigen::Index(def.mesh.nodeCount());
  for (Eigen::Index n = 0; n < nodes; ++n)
    for (int i = 0; i < 3; ++i) r->body->velocity()[3 * n + i] = def.initialVelocity[i];
  // Gripped nodes hold still (XfemBody keeps their DOFs at rest).
  for (int32_t n : xd.fixedNodes) r->body->velocity().segment(3 * n, 3).setZero();
  r->pieceFragment.assign(r->body->pieces().size(), 0);
  for (size_t p = 0; p < r->pieceFragment.size(); ++p) r->pieceFragment[p] = int32_t(p);
  r->fragmentCount = int32_t(r->pieceFragment.size());
  return r;
}

void syncXfemState(BodyRecord& b) { mirrorState(b); }

namespace {
// The piece that is fragment `fragment` now, or -1.
int pieceOfFragment(const XfemRecord& r, int32_t fragment) {
  for (size_t p = 0; p < r.pieceFragment.size(); ++p)
    if (r.pieceFragment[p] == fragment) return int(p);
  return -1;
}
const XfemRecord::Detached* findDetached(const XfemRecord& r, int32_t fragment) {
  for (const XfemRecord::Detached& d : r.detached)
    if (d.fragment == fragment) return &d;
  return nullptr;
}
}  // namespace

Result<RigidFragmentInfo> xfemFragmentInfo(const BodyRecord& b, const char* call,
                                           int32_t fragment) {
  const XfemRecord& r = *b.xfem;
  const int piece = pieceOfFragment(r, fragment);
  if (fragment < 0 || fragment >= r.fragmentCount || piece < 0)
    return fail(call, ": fragment ", std::to_string(fragment), " out of range [0, ",
                std::to_string(r.fragmentCount), ")");
  const XfemBody& x = *r.body;
  const XfemPieceMoments m = x.pieceMoments(piece);
  if (!(m.mass > 0)) return fail(call, ": fragment ", std::to_string(fragment), " has no mass");
  // The best-fit rotation is the polar factor of the mass-weighted spread (x - c)(X - C)^T,
  // the rigid motion closest to the piece's field in the mass norm.
  Eigen::Matrix3d S;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) S(i, j) = m.spread(i, j);
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(S, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1 : 1;
  const Eigen::Matrix3d Re = svd.matrixU() * D * svd.matrixV().transpose();
  Mat3 R;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R(i, j) = Re(i, j);
  // A piece that has left the system moves as its rigid pose says.
  if (const XfemRecord::Detached* d = findDetached(r, fragment)) R = d->rotation;
  const Mat3 restInertia = inertiaFromSecondMoment(m.restSecond);
  RigidFragmentInfo info;
  for (int32_t n = 0; n < int32_t(x.def().mesh.nodeCount()); ++n)
    info.nodeCount += x.pieces()[size_t(piece)].load[n] > 0;
  info.mass = m.mass;
  info.volume = m.volume;
  info.centreOfMass = toGlm(m.centre);
  Vec3 centre = m.centre;
  if (const XfemRecord::Detached* d = findDetached(r, fragment)) {
    centre = d->rotation * d->restCentre + d->translation;
    info.centreOfMass = toGlm(centre);
  }
  const glm::dmat3 Rg = toGlm(R);
  info.inertia = Rg * toGlm(restInertia) * glm::transpose(Rg);
  info.linearVelocity = toGlm(m.momentum) / m.mass;
  info.angularVelocity = glm::inverse(info.inertia) * toGlm(m.angularMomentum);
  if (const XfemRecord::Detached* d = findDetached(r, fragment)) {
    info.linearVelocity = toGlm(d->velocity);
    info.angularVelocity = toGlm(d->angularVelocity);
  }
  info.rotation = glm::quat_cast(Rg);
  info.translation = info.centreOfMass - Rg * toGlm(m.restCentre);
  return info;
}

Result<RigidFragmentInfo> detachXfemPiece(BodyRecord& b, int32_t fragment) {
  XfemRecord& r = *b.xfem;
  auto info = xfemFragmentInfo(b, "detachFragment", fragment);
  if (!info) return info.error();
  if (findDetached(r, fragment))
    return fail("detachFragment: fragment ", std::to_string(fragment), " is already detached");
  const XfemBody& x = *r.body;
  const int piece = pieceOfFragment(r, fragment);
  size_t left = 0;
  for (const detail::XfemPiece& p : x.pieces()) left += !p.dropped;
  if (left < 2)
    return fail("detachFragment: fragment ", std::to_string(fragment),
                " is the whole body (the only piece left in its Is-XFEM system); cut it first");
  for (int32_t n : x.def().fixedNodes)
    if (x.pieces()[size_t(piece)].load[n] > 0)
      return fail("detachFragment: fragment ", std::to_string(fragment),
                  " holds gripped nodes (BodyDef.grips); a pinned piece cannot move rigidly");
  const XfemPieceMoments m = x.pieceMoments(piece);
  auto made = x.withoutPiece(piece);
  if (!made) return fail("detachFragment: ", made.error().message);
  if (auto set = made.value()->setTimeStep(x.timeStep()); !set)
    return fail("detachFragment: ", set.error().message);
  // Nothing failed: the piece leaves the system at its best-fit rigid pose.
  XfemRecord::Detached d;
  d.fragment = fragment;
  d.restCentre = m.restCentre;
  const glm::dmat3 R = glm::mat3_cast(info.value().rotation);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) d.rotation(i, j) = R[j][i];
  d.translation = m.centre - d.rotation * m.restCentre;
  const glm::dvec3 v = info.value().linearVelocity, w = info.value().angularVelocity;
  d.velocity = Vec3{v.x, v.y, v.z};
  d.angularVelocity = Vec3{w.x, w.y, w.z};
  r.body = std::move(made.value());
  r.detached.push_back(d);
  r.built = false;
  ++r.topologyVersion;
  mirrorState(b);
  b.surfaceStale = true;
  return info;
}

Result<void> setXfemPieceTransform(BodyRecord& b, int32_t fragment, const Mat3& rotation,
                                   Vec3 translation, Vec3 velocity, Vec3 angularVelocity) {
  XfemRecord& r = *b.xfem;
  for (XfemRecord::Detached& d : r.detached)
    if (d.fragment == fragment) {
      d.rotation = rotation;
      d.translation = translation;
      d.velocity = velocity;
      d.angularVelocity = angularVelocity;
      b.surfaceStale = true;
      return {};
    }
  if (fragment < 0 || fragment >= r.fragmentCount)
    return fail("setFragmentTransform: fragment ", std::to_string(fragment), " out of range [0, ",
                std::to_string(r.fragmentCount), ")");
  return fail("setFragmentTransform: fragment ", std::to_string(fragment),
              " is not detached (call detachFragment first)");
}

}  // namespace detail

std::string World::Impl::xfemColliderError(std::span<const Collider> list,
                                           const char* where) const {
  for (size_t c = 0; c < list.size(); ++c)
    if (list[c].kind != Collider::Kind::Plane)
      return std::string(where) + "[" + std::to_string(c) +
             "]: a body in CutMode::Xfem meets plane colliders only (got a " +
             (list[c].kind == Collider::Kind::Box      ? "box"
              : list[c].kind == Collider::Kind::Sphere ? "sphere"
                                                       : "capsule") +
             ")";
  return {};
}

void World::Impl::stepXfem(size_t si, const detail::StepContext& ctx) {
  BodyRecord& b = *slots[si].body;
  detail::BodyStepReport& r = reports[si];
  r = {};
  XfemBody& x = *b.xfem->body;
  const auto t0 = detail::Clock::now();
  if (auto set = x.setTimeStep(ctx.dt); !set) {
    r.flags |= kStepNanContained;
    r.message = set.error().message;
    return;
  }
  std::vector<detail::XfemContactPlane> planes(size_t(ctx.colliderCount));
  for (int c = 0; c < ctx.colliderCount; ++c) {
    planes[size_t(c)].normal = ctx.colliders[c].normal;
    planes[size_t(c)].offset = dot(ctx.colliders[c].normal, ctx.colliders[c].point);
  }
  XfemRecord& rec = *b.xfem;
  if (!x.step(planes, &rec.contact)) {
    r.flags |= kStepNanContained;
    r.message = "Is-XFEM step: the state is not finite; nothing moved";
    return;
  }
  r.solveMs = detail::msSince(t0);
  r.linearIterations = rec.contact.pivots + rec.contact.sweeps;  // the contact LCP's work
  if (!rec.contact.converged) r.flags |= kStepNotConverged;
  mirrorState(b);
  if (ctx.colliderImpulse)
    for (int c = 0; c < ctx.colliderCount; ++c) {
      const double* J = &rec.contact.impulse[6 * size_t(c)];
      const Vec3 lin{J[0], J[1], J[2]}, p = ctx.colliders[c].point;
      const Vec3 ang = Vec3{J[3], J[4], J[5]} - cross(p, lin);  // about the collider's point
      for (int i = 0; i < 3; ++i) {
        ctx.colliderImpulse[6 * c + i] += lin[i];
        ctx.colliderImpulse[6 * c + 3 + i] += ang[i];
      }
    }
  b.surfaceStale = true;
}

void World::Impl::collectXfemEvents(BodyRecord& b) {
  XfemRecord& r = *b.xfem;
  fractureEvents.insert(fractureEvents.end(), r.pendingBreaks.begin(), r.pendingBreaks.end());
  fragmentEvents.insert(fragmentEvents.end(), r.pendingSplits.begin(), r.pendingSplits.end());
  r.pendingBreaks.clear();
  r.pendingSplits.clear();
}

Result<void> World::Impl::cutXfem(BodyId id, BodyRecord& b, const Blade& blade) {
  XfemRecord& rec = *b.xfem;
  const XfemBody& old = *rec.body;
  const RestFrame frame = restFrame(old, blade);
  detail::XfemBlade xb;
  for (const glm::vec3& v : blade.vertices)
    xb.blade.vertices.insert(xb.blade.vertices.end(), {v.x, v.y, v.z});
  for (uint32_t t : blade.triangles) xb.blade.triangles.push_back(int32_t(t));
  xb.pose = restPose(blade.from, frame);
  if (blade.to != blade.from) xb.to = restPose(blade.to, frame);
  auto made = old.withBlade(xb);
  if (!made) return fail("cut: ", made.error().message);
  if (auto set = made.value()->setTimeStep(old.timeStep()); !set)
    return fail("cut: ", set.error().message);
  const XfemBody& now = *made.value();
  const int32_t cut = int32_t(now.def().planes.size() + now.def().blades.size()) - 1;

  // One event per tet carrying the new cut, at the area centroid of its cut polygons.
  std::vector<FractureEvent> breaks;
  {
    std::map<int32_t, std::pair<Vec3, double>> perTet;  // tet -> (area moment, area)
    for (const detail::XfemCutFace& f : now.cutFaces()) {
      if (f.plane != cut) continue;
      auto& [moment, area] = perTet[f.tet];
      for (int i = 1; i + 1 < f.polygon.count; ++i) {
        const Vec3 a = f.polygon.v[0], q = f.polygon.v[i], r = f.polygon.v[i + 1];
        const double triangle = 0.5 * norm(cross(q - a, r - a));
        moment += (triangle / 3.0) * (a + q + r);
        area += triangle;
      }
    }
    for (const auto& [tet, sums] : perTet) {
      const Vec3 w = frame.toWorld(sums.second > 0 ? (1.0 / sums.second) * sums.first
                                                   : tetCentroid(now.def().mesh, tet));
      FractureEvent ev;
      ev.body = id;
      ev.tet = tet;
      ev.cause = FractureEvent::Cause::Cut;
      ev.position = glm::vec3(float(w.x), float(w.y), float(w.z));
      breaks.push_back(ev);
    }
  }

  // Fragments: each new piece's parent is the old piece on the same sides of the old cuts (or,
  // failing that, the nearest at rest); the first child keeps the parent's id, the others are
  // new fragments.
  const unsigned oldBits = cut >= 32 ? ~0u : (1u << cut) - 1u;
  std::vector<int32_t> pieceFragment(now.pieces().size(), -1);
  std::vector<uint8_t> taken(old.pieces().size(), 0);
  std::vector<FragmentEvent> splits;
  int32_t count = rec.fragmentCount;
  for (size_t q = 0; q < now.pieces().size(); ++q) {
    int parent = -1;
    for (size_t p = 0; p < old.pieces().size() && parent < 0; ++p)
      if (old.pieces()[p].mask == (now.pieces()[q].mask & oldBits)) parent = int(p);
    if (parent < 0) {
      double best = INFINITY;
      for (size_t p = 0; p < old.pieces().size(); ++p) {
        const double d = norm(old.pieceRestCentre(int(p)) - now.pieceRestCentre(int(q)));
        if (d < best) best = d, parent = int(p);
      }
    }
    if (!taken[size_t(parent)]) {
      taken[size_t(parent)] = 1;
      pieceFragment[q] = rec.pieceFragment[size_t(parent)];
    } else {
      pieceFragment[q] = count++;
      splits.push_back(
          pieceEvent(id, now, int(q), pieceFragment[q], rec.pieceFragment[size_t(parent)]));
    }
  }

  // Nothing failed: the world takes the cut.
  rec.body = std::move(made.value());
  rec.pieceFragment = std::move(pieceFragment);
  rec.fragmentCount = count;
  rec.pendingBreaks.insert(rec.pendingBreaks.end(), breaks.begin(), breaks.end());
  rec.pendingSplits.insert(rec.pendingSplits.end(), splits.begin(), splits.end());
  rec.built = false;
  ++rec.topologyVersion;
  mirrorState(b);
  b.surfaceStale = true;
  return {};
}

BodyStats World::Impl::xfemStats(const BodyRecord& b) const {
  // Exact for the enriched field: with X_f the node's rest position for a standard function
  // and 0 for an enriched one, x(X) = sum_f phi_f (X_f + u_f) everywhere (the standard functions
  // interpolate X and sum to one), so every moment below is M or the loads against the DOFs.
  BodyStats s;
  const XfemBody& x = *b.xfem->body;
  const Eigen::SparseMatrix<double>& M = x.massMatrix();
  const Eigen::VectorXd& u = x.displacement();
  const Eigen::VectorXd& v = x.velocity();
  const int32_t nodes = int32_t(x.def().mesh.nodeCount());
  const glm::dvec3 g(def.gravity);
  const Eigen::VectorXd Mv = M * v;
  s.kineticEnergy = 0.5 * v.dot(Mv);
  s.elasticEnergy = 0.5 * u.dot(x.stiffnessMatrix() * u);
  const auto position = [&](Eigen::Index dof) {
    const Eigen::Index f = dof / 3;
    return (f < nodes ? b.model.restPositions[size_t(dof)] : 0.0) + u[dof];
  };
  // M is the scalar mass matrix on each axis: rows 3f + i, columns 3g + i.
  for (int k = 0; k < M.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(M, k); it; ++it) {
      const Eigen::Index row = it.row(), col = it.col();
      if (row % 3 != 0 || col % 3 != 0) continue;
      const glm::dvec3 xr(position(row), position(row + 1), position(row + 2));
      const glm::dvec3 vc(v[col], v[col + 1], v[col + 2]);
      s.angularMomentum += it.value() * glm::cross(xr, vc);
      const bool rowStandard = row / 3 < nodes, colStandard = col / 3 < nodes;
      if (rowStandard) s.linearMomentum += it.value() * vc;
      if (rowStandard && colStandard) s.mass += it.value();
      if (colStandard) s.gravityEnergy -= it.value() * glm::dot(g, xr);
    }
  return s;
}

SurfaceView World::Impl::xfemSurface(BodyRecord& b, bool moved) {
  XfemRecord& r = *b.xfem;
  XfemBody& x = *r.body;
  const bool rebuild = !r.built;
  if (moved || rebuild) x.updateSurface();
  if (rebuild) {
    r.indices.clear();
    r.crackMask.clear();
    r.vertexFragment.clear();
    r.vertexNode.clear();
    uint32_t base = 0;
    for (size_t p = 0; p < x.surface().size(); ++p) {
      const detail::XfemPieceSurface& s = x.surface()[p];
      for (size_t t = 0; t < s.triangleCut.size(); ++t) {
        for (int k = 0; k < 3; ++k) r.indices.push_back(base + uint32_t(s.triangles[3 * t + k]));
        r.crackMask.push_back(s.triangleCut[t] >= 0 ? 1 : 0);
      }
      for (const detail::XfemSurfaceVertex& v : s.vertices) {
        r.vertexFragment.push_back(r.pieceFragment[p]);
        r.vertexNode.push_back(v.simplex[0]);
      }
      base += uint32_t(s.vertices.size());
    }
    r.positions.resize(3 * size_t(base));
    r.normals.resize(3 * size_t(base));
    r.built = true;
  }
  if (moved || rebuild) {
    size_t base = 0;
    std::fill(r.normals.begin(), r.normals.end(), 0.0f);
    std::vector<Vec3> normal;
    std::vector<Vec3> position;
    for (size_t p = 0; p < x.surface().size(); ++p) {
      const detail::XfemPieceSurface& s = x.surface()[p];
      position = s.positions;
      // A detached piece shows its rest surface at the rigid pose (its DOFs are held).
      for (const XfemRecord::Detached& d : r.detached)
        if (d.fragment == r.pieceFragment[p])
          for (size_t i = 0; i < s.vertices.size(); ++i)
            position[i] = d.rotation * s.vertices[i].rest + d.translation;
      normal.assign(s.vertices.size(), Vec3{});
      for (size_t t = 0; 3 * t < s.triangles.size(); ++t) {
        const Vec3 a = position[size_t(s.triangles[3 * t])];
        const Vec3 n = cross(position[size_t(s.triangles[3 * t + 1])] - a,
                             position[size_t(s.triangles[3 * t + 2])] - a);  // area-weighted
        for (int k = 0; k < 3; ++k) normal[size_t(s.triangles[3 * t + k])] += n;
      }
      for (size_t i = 0; i < s.vertices.size(); ++i) {
        const double len = norm(normal[i]);
        for (int k = 0; k < 3; ++k) {
          r.positions[3 * (base + i) + size_t(k)] = float(position[i][k]);
          r.normals[3 * (base + i) + size_t(k)] = len > 0 ? float(normal[i][k] / len) : 0.0f;
        }
      }
      base += s.vertices.size();
    }
  }
  SurfaceView v;
  v.positions = r.positions;
  v.normals = r.normals;
  v.indices = r.indices;
  v.crackMask = r.crackMask;
  v.vertexFragment = r.vertexFragment;
  v.vertexNode = r.vertexNode;
  v.topologyVersion = r.topologyVersion;
  v.dirtyBegin = 0;
  v.dirtyEnd = (moved || rebuild) ? uint32_t(r.vertexNode.size()) : 0;
  return v;
}

}  // namespace gf
