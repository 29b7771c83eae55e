#include "contact/body_contact.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "mesh/mesh_internal.h"

namespace gf::detail {

namespace {

Vec3 load3(const double* p, int32_t i) { return contactLoad3(p, i); }

// Radix bits that hold every value below `count`.
int bitsFor(uint64_t count) {
  int bits = 1;
  while (bits < 62 && (uint64_t(1) << bits) < count) ++bits;
  return bits;
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
                            int32_t fragmentCount, const uint8_t* excluded, uint64_t key) {
  if (key == m_key) return;
  m_key = key;
  m_faces.clear();
  m_inner.clear();
  auto add = [&](int32_t f, bool flip) {
    const int32_t* k = &m_faceNodes[3 * size_t(f)];
    m_inner.push_back(m_faceOpposite[2 * size_t(f) + (flip ? 1 : 0)]);
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
  // What the contact stages read per vertex: its index, its faces and the face edges it ends
  // (ascending, the order of the serial sums they replace), and the vertices and nodes by
  // fragment for the per-group sums.
  const int32_t V = int32_t(m_vertices.size());
  m_nodeVertex.assign(size_t(model.nodeCount), -1);
  for (int32_t i = 0; i < V; ++i) m_nodeVertex[size_t(m_vertices[size_t(i)])] = i;
  m_vertexFaceStart.assign(size_t(V) + 1, 0);
  for (int32_t n : m_faces) ++m_vertexFaceStart[size_t(m_nodeVertex[size_t(n)]) + 1];
  for (int32_t i = 0; i < V; ++i) m_vertexFaceStart[size_t(i) + 1] += m_vertexFaceStart[size_t(i)];
  m_vertexFaces.resize(m_faces.size());
  m_vertexEdges.resize(2 * m_faces.size());
  std::vector<int32_t> fill(m_vertexFaceStart.begin(), m_vertexFaceStart.end() - 1);
  for (int32_t f = 0; f < count; ++f)
    for (int32_t k = 0; k < 3; ++k) {
      const int32_t i = m_nodeVertex[size_t(m_faces[3 * size_t(f) + size_t(k)])];
      const int32_t at = fill[size_t(i)]++;
      m_vertexFaces[size_t(at)] = f;
      // The vertex is node k of face edge k and node k + 1 of face edge k - 1.
      const int32_t e0 = 3 * f + k, e1 = 3 * f + (k + 2) % 3;
      m_vertexEdges[2 * size_t(at)] = std::min(e0, e1);
      m_vertexEdges[2 * size_t(at) + 1] = std::max(e0, e1);
    }
  m_vertexEdgeStart.resize(size_t(V) + 1);
  for (int32_t i = 0; i <= V; ++i) m_vertexEdgeStart[size_t(i)] = 2 * m_vertexFaceStart[size_t(i)];
  std::vector<int32_t> vertexFragment;
  if (nodeFragment)
    for (int32_t n : m_vertices) vertexFragment.push_back(nodeFragment[n]);
  // Built when the fragments change, on the calling thread.
  const CpuExecutor serial(serialJobs());
  ScanScratch scratch;
  m_vertexSegments.build(serial, nodeFragment ? vertexFragment.data() : nullptr, V,
                         nodeFragment ? fragmentCount : 1, scratch);
  m_nodeSegments.build(serial, nodeFragment, model.nodeCount, nodeFragment ? fragmentCount : 1,
                       scratch);
}

int64_t BodyContact::find(const CpuExecutor& exec, std::span<const ContactBodyView> bodies,
                          double dt, Vec3 gravity, double stiffness, double slipEps, bool coupled) {
  const size_t slots = bodies.size();
  m_coupled = coupled;
  m_clusters.clear();
  m_jointBase.assign(slots, -1);
  const double fall = dt * dt * norm(gravity);  // the boxes' reach beyond the predictions
  m_bodies.resize(slots);
  for (Slot& s : m_bodies) {
    s.active = false;
    s.balance = {};
  }
  m_slipEps = slipEps;
  m_pairCount = 0;
  // What the stages read of each slot; groups: one per fragment of each body that takes part,
  // global faces: every slot's contact faces one after another.
  m_table.assign(slots, {});
  m_faceBase.assign(slots, 0);
  int32_t groups = 0, faces = 0, jointNodes = 0;
  for (size_t si = 0; si < slots; ++si) {
    m_faceBase[si] = faces;
    const ContactBodyView& b = bodies[si];
    ContactBody& t = m_table[si];
    t.faceBase = faces;
    if (!b.model) continue;
    t.x = b.x ? b.x : b.state->x.data();
    t.v = b.v ? b.v : b.state->v.data();
    t.iterate = b.iterate;
    t.rest = b.model->restPositions.data();
    t.nodeMass = b.state->nodeMass.data();
    t.fixed = b.state->fixedNode.data();
    // The groups as the pairs are found: a body that breaks while it steps relabels its
    // fragments before the exchange, whose clusters must still be these (it read the new
    // labels past its group count).
    Slot& slot = m_bodies[si];
    slot.fragment.assign(b.nodeFragment.begin(), b.nodeFragment.end());
    t.fragment = slot.fragment.empty() ? nullptr : slot.fragment.data();
    t.faces = b.surface->faces().data();
    t.neighbours = b.surface->neighbours().data();
    t.vertices = b.surface->vertices().data();
    t.density = b.state->material.density;
    t.cellSize = b.surface->cellSize();
    t.friction = b.model->friction;
    t.groupBase = groups;
    t.faceCount = int32_t(b.surface->faces().size() / 3);
    t.vertexCount = int32_t(b.surface->vertices().size());
    t.nodeCount = b.model->nodeCount;
    if (coupled) {
      t.jointBase = jointNodes;
      jointNodes += t.nodeCount;
    }
    groups += b.fragmentCount;
    slot.groupEnd = groups;
    faces += t.faceCount;
  }
  m_groups = groups;
  if (groups < 2) return 0;

  // Boxes of the groups over their surface vertices' paths: per-axis minima and maxima per
  // fragment.
  m_box.resize(6 * size_t(groups));
  for (size_t si = 0; si < slots; ++si) {
    if (!bodies[si].model) continue;
    const ContactBody& t = m_table[si];
    Slot& out = m_bodies[si];
    const Segments seg = bodies[si].surface->vertexSegments();
    const int32_t V = t.vertexCount;
    out.path.resize(6 * size_t(V));
    exec.run(V, 1024, ContactPathBoxStage{t, dt, out.path.data()});
    m_partials.resize(3 * size_t(seg.chunks));
    m_lower.resize(3 * size_t(seg.count));
    m_upper.resize(3 * size_t(seg.count));
    segmentedReduce<MinOp>(exec, seg, out.path.data(), V, 3, m_partials.data(), m_lower.data());
    segmentedReduce<MaxOp>(exec, seg, out.path.data() + 3 * int64_t(V), V, 3, m_partials.data(),
                           m_upper.data());
    exec.run(
        seg.count, 256,
        ContactGroupBoxStage{t, m_lower.data(), m_upper.data(), seg.count, fall, m_box.data()});
  }
  // Which groups' boxes meet, as each group's list of the others.
  m_nearStart.resize(size_t(groups) + 1);
  exec.run(groups, 64, ContactNearStage{m_box.data(), groups, nullptr, m_nearStart.data()});
  const int32_t links = exclusiveScan(exec, m_nearStart.data(), groups, m_nearStart.data(), m_scan);
  if (links == 0) return 0;
  m_nearLinks.resize(size_t(links));
  exec.run(groups, 64,
           ContactNearStage{m_box.data(), groups, m_nearStart.data(), nullptr, m_nearLinks.data()});

  // The faces of near groups, boxed over both positions, in a spatial hash whose cell is
  // their mean extent.
  m_faceSlot.resize(size_t(faces));
  m_faceNear.resize(size_t(faces));
  m_faceNearCount.resize(size_t(faces));
  m_faceBox.resize(6 * size_t(faces));
  m_faceExtent.resize(size_t(faces));
  exec.run(faces, 1024,
           ContactFaceStage{m_table.data(), m_faceBase.data(), int32_t(slots), m_nearStart.data(),
                            dt, fall, m_faceSlot.data(), m_faceNear.data(), m_faceNearCount.data(),
                            m_faceBox.data(), m_faceExtent.data()});
  const double nearFaces = exec.sum(m_faceNearCount.data(), faces);
  if (!(nearFaces > 0)) return 0;
  const double h = std::max(exec.sum(m_faceExtent.data(), faces) / nearFaces, 1e-9);
  const ContactGrid grid = m_hash.build(exec, m_faceNear.data(), m_faceBox.data(), faces, h);

  // Masses of the groups, for the edge-edge penalty and the exchange.
  m_groupMass.resize(size_t(groups));
  m_groupFree.resize(size_t(groups));
  for (size_t si = 0; si < slots; ++si) {
    if (!bodies[si].model) continue;
    const Segments seg = bodies[si].surface->nodeSegments();
    exec.run(seg.count, 1,
             ContactGroupMassStage{m_table[si], seg, m_groupMass.data(), m_groupFree.data()});
  }

  ContactScene scene;
  scene.bodies = m_table.data();
  scene.faceSlot = m_faceSlot.data();
  scene.groupBox = m_box.data();
  scene.nearStart = m_nearStart.data();
  scene.nearLinks = m_nearLinks.data();
  scene.groupMass = m_groupMass.data();
  scene.grid = grid;
  scene.dt = dt;
  scene.fall = (dt * dt) * gravity;
  scene.stiffness = stiffness;
  // Every slot's vertex normals first: a pair's stiffness reads the areas of the other side's
  // face nodes.
  for (size_t si = 0; si < slots; ++si) {
    if (!bodies[si].model) continue;
    const ContactSurface& surf = *bodies[si].surface;
    ContactBody& t = m_table[si];
    Slot& out = m_bodies[si];
    out.vertexNormal.resize(size_t(t.vertexCount));
    exec.run(t.vertexCount, 512,
             ContactVertexNormalStage{t, m_nearStart.data(), surf.vertexFaceStart().data(),
                                      surf.vertexFaces().data(), out.vertexNormal.data()});
    t.nodeVertex = surf.nodeVertex().data();
    t.vertexNormal = out.vertexNormal.data();
  }
  // Per slot: the vertex-face pairs per surface vertex and the edge-edge ones per surface edge
  // (count, scan, fill), then the half-spaces per node in node order.
  for (size_t si = 0; si < slots; ++si) {
    const ContactBodyView& b = bodies[si];
    if (!b.model) continue;
    const ContactBody& t = m_table[si];
    const ContactSurface& surf = *b.surface;
    Slot& out = m_bodies[si];
    const int32_t V = t.vertexCount, E = 3 * t.faceCount, N = t.nodeCount;
    out.vertexStart.resize(size_t(V) + 1);
    ContactVertexPairStage vp{scene, int32_t(si), nullptr, out.vertexStart.data()};
    exec.run(V, 128, vp);
    const int32_t nv =
        exclusiveScan(exec, out.vertexStart.data(), V, out.vertexStart.data(), m_scan);
    out.vertexPairs.resize(size_t(nv));
    out.vertexWritten.assign(size_t(V), 0);
    vp.start = out.vertexStart.data();
    vp.out = out.vertexPairs.data();
    vp.written = out.vertexWritten.data();
    if (nv > 0) exec.run(V, 128, vp);
    out.edgeStart.resize(size_t(E) + 1);
    ContactEdgePairStage ep{scene, int32_t(si), nullptr, out.edgeStart.data()};
    exec.run(E, 512, ep);
    const int32_t ne = exclusiveScan(exec, out.edgeStart.data(), E, out.edgeStart.data(), m_scan);
    out.edgePairs.resize(size_t(ne));
    out.edgeWritten.assign(size_t(E), 0);
    ep.start = out.edgeStart.data();
    ep.out = out.edgePairs.data();
    ep.written = out.edgeWritten.data();
    if (ne > 0) exec.run(E, 512, ep);
    if (nv + ne == 0) continue;  // bounds: the node lists may still come out empty
    out.start.resize(size_t(N) + 1);
    ContactNodeListStage nl{surf.nodeVertex().data(),
                            out.vertexStart.data(),
                            out.vertexWritten.data(),
                            out.vertexPairs.data(),
                            surf.vertexEdgeStart().data(),
                            surf.vertexEdges().data(),
                            out.edgeStart.data(),
                            out.edgeWritten.data(),
                            out.edgePairs.data(),
                            nullptr,
                            out.start.data()};
    exec.run(N, 1024, nl);
    const int32_t total = exclusiveScan(exec, out.start.data(), N, out.start.data(), m_scan);
    if (total == 0) continue;
    out.point.resize(size_t(total));
    out.normal.resize(size_t(total));
    out.faceMotion.resize(size_t(total));
    out.partner.resize(size_t(total));
    out.muLambda.resize(size_t(total));
    out.stiffness.resize(size_t(total));
    out.impulse.resize(3 * size_t(total));
    nl.start = out.start.data();
    nl.point = out.point.data();
    nl.normal = out.normal.data();
    nl.faceMotion = out.faceMotion.data();
    nl.partner = out.partner.data();
    nl.muLambda = out.muLambda.data();
    nl.stiffness = out.stiffness.data();
    nl.impulse = out.impulse.data();
    out.faceNode.resize(3 * size_t(total));
    out.weight.resize(size_t(total));
    nl.faceNode = out.faceNode.data();
    nl.weight = out.weight.data();
    if (coupled) {
      out.skin.resize(size_t(total));
      nl.skin = out.skin.data();
    }
    const std::vector<double>& load = b.state->contactLoad;
    nl.load = load.size() == size_t(N) ? load.data() : nullptr;
    exec.run(N, 1024, nl);
    out.active = true;
    // Per node, the self pairs whose face (or other edge) it carries, in half-space order (a
    // serial count, scan and fill: the lists are short, and their order is the sums').
    out.owner.resize(size_t(total));
    out.reactionStart.assign(size_t(N) + 1, 0);
    out.moving = false;
    for (int32_t n = 0; n < N; ++n)
      for (int32_t k = out.start[size_t(n)]; k < out.start[size_t(n) + 1]; ++k) {
        out.owner[size_t(k)] = n;
        if (out.faceNode[3 * size_t(k)] < 0) continue;
        out.moving = true;
        // Coupled: the face nodes are joint ones, listed over all bodies (joinSlots).
        if (!coupled)
          for (int c = 0; c < 3; ++c)
            ++out.reactionStart[size_t(out.faceNode[3 * size_t(k) + c]) + 1];
      }
    if (out.moving && !coupled) {
      for (int32_t n = 0; n < N; ++n)
        out.reactionStart[size_t(n) + 1] += out.reactionStart[size_t(n)];
      out.reaction.resize(size_t(out.reactionStart[size_t(N)]));
      out.reactionFill.assign(out.reactionStart.begin(), out.reactionStart.end() - 1);
      for (int32_t k = 0; k < total; ++k)
        if (out.faceNode[3 * size_t(k)] >= 0)
          for (int c = 0; c < 3; ++c)
            out.reaction[size_t(out.reactionFill[size_t(out.faceNode[3 * size_t(k) + c])]++)] =
                3 * k + c;
    }
    m_pairCount += total;
  }
  if (coupled && m_pairCount > 0) joinSlots();
  return m_pairCount;
}

void BodyContact::joinSlots() {
  const size_t slots = m_table.size();
  // The slot of a node in find()'s joint numbering (the slots' nodes one after another).
  std::vector<int32_t> firstNode, slotOfFirst;
  for (size_t si = 0; si < slots; ++si)
    if (m_table[si].jointBase >= 0) {
      firstNode.push_back(m_table[si].jointBase);
      slotOfFirst.push_back(int32_t(si));
    }
  auto slotOf = [&](int32_t node) {
    const auto it = std::upper_bound(firstNode.begin(), firstNode.end(), node);
    return size_t(slotOfFirst[size_t(it - firstNode.begin()) - 1]);
  };
  // Slots joined by a pair, by union-find over the pairs (serial, O(pairs), in slot order).
  std::vector<size_t> parent(slots);
  for (size_t si = 0; si < slots; ++si) parent[si] = si;
  auto root = [&](size_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  std::vector<uint8_t> touched(slots, 0);
  for (size_t si = 0; si < slots; ++si) {
    const Slot& s = m_bodies[si];
    if (!s.active) continue;
    touched[si] = 1;
    for (size_t k = 0; k < s.owner.size(); ++k)
      if (s.faceNode[3 * k] >= 0) {
        const size_t sj = slotOf(s.faceNode[3 * k]);
        touched[sj] = 1;
        const size_t a = root(si), b = root(sj);
        parent[std::max(a, b)] = std::min(a, b);
      }
  }
  // Clusters in the order of their least slot, each a run of joint nodes.
  std::vector<int32_t> clusterOf(slots, -1);
  int32_t nodes = 0;
  for (size_t si = 0; si < slots; ++si) {
    if (!touched[si]) continue;
    const size_t r = root(si);
    if (clusterOf[r] < 0) {
      clusterOf[r] = int32_t(m_clusters.size());
      m_clusters.emplace_back();
    }
    m_clusters[size_t(clusterOf[r])].slots.push_back(uint32_t(si));
  }
  for (Cluster& c : m_clusters) {
    c.nodeBegin = nodes;
    for (uint32_t si : c.slots) {
      m_jointBase[si] = nodes;
      nodes += m_table[si].nodeCount;
    }
    c.nodeEnd = nodes;
  }
  auto joint = [&](int32_t node) {
    const size_t sj = slotOf(node);
    return m_jointBase[sj] + (node - m_table[sj].jointBase);
  };
  // Each node's half-spaces in the new numbering: a cluster's bodies' lists one after another.
  m_jointStart.assign(size_t(nodes) + 1, 0);
  int32_t pairs = 0;
  for (Cluster& c : m_clusters) {
    c.pairBegin = pairs;
    for (uint32_t si : c.slots) {
      const Slot& s = m_bodies[si];
      for (int32_t n = 0; n < m_table[si].nodeCount; ++n) {
        m_jointStart[size_t(m_jointBase[si] + n)] = pairs;
        if (s.active) pairs += s.start[size_t(n) + 1] - s.start[size_t(n)];
      }
    }
    c.pairEnd = pairs;
  }
  m_jointStart[size_t(nodes)] = pairs;
  const size_t K = size_t(pairs);
  m_jointPoint.resize(K);
  m_jointNormal.resize(K);
  m_jointFaceMotion.resize(K);
  m_jointWeight.resize(K);
  m_jointPartner.resize(K);
  m_jointMuLambda.resize(K);
  m_jointStiffness.resize(K);
  m_jointSkin.resize(K);
  m_jointOwner.resize(K);
  m_jointFaceNode.resize(3 * K);
  for (const Cluster& c : m_clusters)
    for (uint32_t si : c.slots) {
      const Slot& s = m_bodies[si];
      if (!s.active) continue;
      const size_t base = size_t(m_jointStart[size_t(m_jointBase[si])]);
      for (size_t k = 0; k < s.owner.size(); ++k) {
        const size_t j = base + k;
        m_jointPoint[j] = s.point[k];
        m_jointNormal[j] = s.normal[k];
        m_jointFaceMotion[j] = s.faceMotion[k];
        m_jointWeight[j] = s.weight[k];
        m_jointPartner[j] = s.partner[k];
        m_jointMuLambda[j] = s.muLambda[k];
        m_jointStiffness[j] = s.stiffness[k];
        m_jointSkin[j] = s.skin[k];
        m_jointOwner[j] = m_jointBase[si] + s.owner[k];
        for (size_t c3 = 0; c3 < 3; ++c3) {
          const int32_t f = s.faceNode[3 * k + c3];
          m_jointFaceNode[3 * j + c3] = f >= 0 ? joint(f) : -1;
        }
      }
    }
  // Per joint node, the half-spaces whose face (or other edge) it carries, in half-space order.
  m_jointReactionStart.assign(size_t(nodes) + 1, 0);
  for (size_t k = 0; k < K; ++k)
    if (m_jointFaceNode[3 * k] >= 0)
      for (size_t c3 = 0; c3 < 3; ++c3)
        ++m_jointReactionStart[size_t(m_jointFaceNode[3 * k + c3]) + 1];
  for (int32_t n = 0; n < nodes; ++n)
    m_jointReactionStart[size_t(n) + 1] += m_jointReactionStart[size_t(n)];
  m_jointReaction.resize(size_t(m_jointReactionStart[size_t(nodes)]));
  std::vector<int32_t> fill(m_jointReactionStart.begin(), m_jointReactionStart.end() - 1);
  for (size_t k = 0; k < K; ++k)
    if (m_jointFaceNode[3 * k] >= 0)
      for (size_t c3 = 0; c3 < 3; ++c3)
        m_jointReaction[size_t(fill[size_t(m_jointFaceNode[3 * k + c3])]++)] = int32_t(3 * k + c3);
  m_jointX.resize(3 * size_t(nodes));
  m_jointXn.resize(3 * size_t(nodes));
}

HalfSpaceContacts BodyContact::jointView() const {
  HalfSpaceContacts h;
  if (m_clusters.empty()) return h;
  h.start = m_jointStart.data();
  h.point = m_jointPoint.data();
  h.normal = m_jointNormal.data();
  h.stiffness = m_jointStiffness.data();
  h.muLambda = m_jointMuLambda.data();
  h.faceMotion = m_jointFaceMotion.data();
  h.slipEps = m_slipEps;
  h.partner = m_jointPartner.data();
  h.faceNode = m_jointFaceNode.data();
  h.weight = m_jointWeight.data();
  h.owner = m_jointOwner.data();
  h.reactionStart = m_jointReactionStart.data();
  h.reaction = m_jointReaction.data();
  h.skin = m_jointSkin.data();
  h.X = m_jointX.data();
  h.Xn = m_jointXn.data();
  h.joint = true;
  return h;
}

HalfSpaceContacts BodyContact::halfSpaces(size_t si) const {
  if (m_coupled) {
    const int32_t base = jointBase(si);
    if (base < 0) return {};
    HalfSpaceContacts h = jointView();
    h.start += base;
    h.reactionStart += base;
    h.ownFirst = m_table[si].groupBase;
    h.ownEnd = m_bodies[si].groupEnd;
    return h;
  }
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
  h.partner = s.partner.data();
  h.ownFirst = m_table[si].groupBase;
  h.ownEnd = s.groupEnd;
  if (s.moving) {
    h.selfSkin = kContactSelfSkin * m_table[si].thickness();
    h.faceNode = s.faceNode.data();
    h.weight = s.weight.data();
    h.owner = s.owner.data();
    h.reactionStart = s.reactionStart.data();
    h.reaction = s.reaction.data();
  }
  return h;
}

void BodyContact::recordLoads(const CpuExecutor& exec, std::span<FemState* const> states) {
  if (m_coupled) {
    // The joint view reads the other bodies' faces: every coupled body's end positions first.
    for (size_t si = 0; si < states.size(); ++si)
      if (states[si] && jointBase(si) >= 0)
        std::copy(states[si]->x.begin(), states[si]->x.end(),
                  m_jointX.begin() + 3 * std::ptrdiff_t(jointBase(si)));
    m_jointLoad.resize(m_jointX.size() / 3);
    for (const Cluster& c : m_clusters)
      exec.run(c.nodeEnd - c.nodeBegin, 1024,
               OffsetStage<ContactLoadStage>{{jointView(), m_jointLoad.data()}, c.nodeBegin});
    for (size_t si = 0; si < states.size(); ++si) {
      if (!states[si]) continue;
      if (jointBase(si) < 0) {
        states[si]->contactLoad.clear();
        continue;
      }
      const auto first = m_jointLoad.begin() + jointBase(si);
      states[si]->contactLoad.assign(first, first + m_table[si].nodeCount);
    }
    return;
  }
  for (size_t si = 0; si < states.size(); ++si) {
    FemState* state = states[si];
    if (!state) continue;
    if (si >= m_bodies.size() || !m_bodies[si].active) {
      state->contactLoad.clear();
      continue;
    }
    const int32_t N = m_table[si].nodeCount;
    state->contactLoad.resize(size_t(N));
    exec.run(N, 1024,
             ContactLoadStage{halfSpaces(si).at(state->x.data()), state->contactLoad.data()});
  }
}

void BodyContact::exchange(const CpuExecutor& exec, std::span<FemState* const> states) {
  // Coupled pairs are exact action and reaction: nothing to even out.
  if (m_pairCount == 0 || m_coupled) return;
  const int32_t groups = m_groups;
  const size_t slots = m_table.size();
  // Clusters: groups joined by a half-space, in either direction; each group's label becomes
  // the least group of its cluster (the root a union-find with the smaller root winning gives).
  int64_t halfSpaces = 0;
  for (size_t si = 0; si < slots; ++si)
    if (m_bodies[si].active) halfSpaces += m_bodies[si].start.back();
  m_linkKeys.resize(2 * size_t(halfSpaces));
  m_linkValues.resize(2 * size_t(halfSpaces));
  int64_t base = 0;
  for (size_t si = 0; si < slots; ++si) {
    const Slot& s = m_bodies[si];
    if (!s.active) continue;
    exec.run(m_table[si].nodeCount, 1024,
             ContactLinkKeyStage{m_table[si], s.start.data(), s.partner.data(), groups, base,
                                 m_linkKeys.data(), m_linkValues.data()});
    base += s.start.back();
  }
  radixSort(exec, m_linkKeys, m_linkValues, bitsFor(uint64_t(groups) * uint64_t(groups)), m_scan);
  m_label.resize(size_t(groups));
  m_nextLabel.resize(size_t(groups));
  m_changed.resize(size_t(groups));
  exec.run(groups, 1024, ContactIotaStage{m_label.data()});
  for (;;) {
    exec.run(groups, 256,
             ContactLabelStage{m_linkKeys.data(), int32_t(m_linkKeys.size()), groups,
                               m_label.data(), m_nextLabel.data(), m_changed.data()});
    m_label.swap(m_nextLabel);
    if (!(exec.max(m_changed.data(), groups) > 0)) break;
  }
  // Per cluster the nodes with half-spaces in slot and node order, the order their impulses
  // are summed in (zero for an exact action-reaction; design note).
  m_slotBalance.assign(slots, {});
  int32_t entries = 0;
  for (size_t si = 0; si < slots; ++si) {
    const ContactBody& t = m_table[si];
    Slot& s = m_bodies[si];
    const int32_t N = t.nodeCount;
    if (!s.active) continue;
    s.hasContact.resize(size_t(N));
    exec.run(N, 1024, ContactHasHalfSpaceStage{s.start.data(), s.hasContact.data()});
    const int32_t chunks = (N + kCompactChunk - 1) / kCompactChunk;
    m_chunkCount.resize(size_t(chunks));
    m_chunkOffset.resize(size_t(chunks) + 1);
    exec.run(chunks, 4, CompactCountStage{s.hasContact.data(), N, m_chunkCount.data()});
    exec.run(1, 1, CompactOffsetStage{m_chunkCount.data(), chunks, m_chunkOffset.data()});
    const int32_t count = m_chunkOffset[size_t(chunks)];
    m_entryNode.resize(size_t(entries + count));
    m_entrySlot.resize(size_t(entries + count));
    exec.run(chunks, 4,
             CompactScatterStage{s.hasContact.data(), N, m_chunkOffset.data(),
                                 m_entryNode.data() + entries});
    // Each body's unexplained momentum (the linear solve's residual) belongs to the cluster of
    // its first contact node; a cluster on a grip or a collider keeps to its own linear model
    // (design note), so it is left out there.
    ContactSlotBalance& sb = m_slotBalance[si];
    sb.group = t.group(m_entryNode[size_t(entries)]);
    sb.external = s.balance.external;
    sb.unexplained = s.balance.unexplained;
    sb.start = s.start.data();
    sb.impulse = s.impulse.data();
    sb.entryBase = entries;
    sb.entryCount = count;
    entries += count;
  }
  m_entryKeys.resize(size_t(entries));
  m_entryValues.resize(size_t(entries));
  for (size_t si = 0; si < slots; ++si)
    if (m_bodies[si].active) {
      const ContactSlotBalance& sb = m_slotBalance[si];
      exec.run(sb.entryCount, 1024,
               ContactEntryStage{m_table[si], int32_t(si), m_label.data(), sb.entryBase,
                                 m_entryNode.data(), m_entrySlot.data(), m_entryKeys.data(),
                                 m_entryValues.data()});
    }
  radixSort(exec, m_entryKeys, m_entryValues, bitsFor(uint64_t(groups)), m_scan);
  // The groups by cluster, then the same velocity change for every free node of a cluster:
  // its momentum becomes exactly what it was plus the impulses from outside it, and no
  // relative motion changes.
  m_labelKeys.resize(size_t(groups));
  m_labelValues.resize(size_t(groups));
  exec.run(groups, 1024,
           ContactLabelSortStage{m_label.data(), m_labelKeys.data(), m_labelValues.data()});
  radixSort(exec, m_labelKeys, m_labelValues, bitsFor(uint64_t(groups)), m_scan);
  m_clusterVelocity.resize(size_t(groups));
  m_clusterMoves.resize(size_t(groups));
  exec.run(groups, 64,
           ContactClusterStage{m_label.data(), m_labelKeys.data(), m_labelValues.data(), groups,
                               m_groupMass.data(), m_groupFree.data(), m_entryKeys.data(),
                               m_entryValues.data(), m_entrySlot.data(), m_entryNode.data(),
                               entries, m_slotBalance.data(), int32_t(slots),
                               m_clusterVelocity.data(), m_clusterMoves.data()});
  for (size_t si = 0; si < slots; ++si)
    if (m_table[si].groupBase >= 0)
      exec.run(m_table[si].nodeCount, 1024,
               ContactVelocityStage{m_table[si], m_label.data(), m_clusterVelocity.data(),
                                    m_clusterMoves.data(), states[si]->v.data()});
}

}  // namespace gf::detail
