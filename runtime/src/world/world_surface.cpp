// World: the render surface of a body, built and updated when asked for, and the strain field
// a renderer colours it by.
#include <vector>

#include "kernels/element.h"
#include "step/timing.h"
#include "world/world_impl.h"

namespace gf {

std::span<const double> World::nodeStrain(BodyId id) {
  BodyRecord* b = m_impl->get(id);
  if (!b || m_impl->stepping.load()) return {};
  const detail::FemModel& m = b->model;
  b->nodeStrain.assign(size_t(m.nodeCount), 0.0);
  b->nodeWeight.assign(size_t(m.nodeCount), 0.0);
  for (int32_t t = 0; t < m.tetCount; ++t) {
    Vec3 xe[4];
    for (int a = 0; a < 4; ++a) {
      const double* p = &b->state.x[3 * size_t(m.tets[4 * t + a])];
      xe[a] = {p[0], p[1], p[2]};
    }
    const double e = maxPrincipalStrain(deformationGradient(xe, m.restInverse[size_t(t)]));
    for (int a = 0; a < 4; ++a) {
      const size_t n = size_t(m.tets[4 * t + a]);
      b->nodeStrain[n] += m.restVolume[size_t(t)] * e;
      b->nodeWeight[n] += m.restVolume[size_t(t)];
    }
  }
  for (size_t n = 0; n < b->nodeStrain.size(); ++n)
    if (b->nodeWeight[n] > 0) b->nodeStrain[n] /= b->nodeWeight[n];
  return b->nodeStrain;
}

namespace {

// The topology of a requested surface for these broken edges and fragments: the render mesh
// first (it says which local maps and crack faces it takes), then the crack surface.
void rebuildSurface(SurfaceRecord& r, const uint8_t* broken, const int32_t* fragments,
                    const double* x, JobSystem* jobs) {
  if (r.embedded) {
    r.embedded->rebuild(broken, fragments);
    r.surface.setExtraFrameNodes(r.embedded->frameNodes());
    r.surface.setDrawnFragments(r.embedded->crackDrawn());
  }
  r.surface.rebuild(broken, fragments, x, jobs);
}

}  // namespace

void World::Impl::updateSurface(BodyRecord& b) {
  SurfaceRecord& r = *b.surface;
  // Partial cracks are rendered too, so every newly broken edge changes the topology.
  if (b.fracture && uint64_t(b.fracture->brokenCount()) != r.brokenCount) {
    r.brokenCount = uint64_t(b.fracture->brokenCount());
    r.surface.setSplitRatios(b.fracture->splitRatios());
    rebuildSurface(r, b.fracture->broken().data(), b.fracture->fragments().nodeFragment().data(),
                   b.state.x.data(), jobs);
  } else {
    r.surface.updatePositions(b.state.x.data(), jobs);
  }
  if (r.embedded) r.embedded->update(b.state.x.data(), r.surface, jobs);
}

SurfaceView World::surface(BodyId id) {
  BodyRecord* b = m_impl->get(id);
  if (!b || m_impl->stepping.load()) return {};
  if (b->xfem) {
    const bool moved = b->surfaceStale;
    b->surfaceStale = false;
    const auto t0 = detail::Clock::now();
    SurfaceView v = m_impl->xfemSurface(*b, moved);
    m_impl->timings.surfaceMs += detail::msSince(t0);
    return v;
  }
  // The view's dirty range covers what changed since the previous call.
  if (b->surface) b->surface->surface.clearDirty();
  bool updated = false;
  if (b->surface && b->surfaceStale) {
    const auto t0 = detail::Clock::now();
    m_impl->updateSurface(*b);
    m_impl->timings.surfaceMs += detail::msSince(t0);
    updated = true;
  }
  b->surfaceStale = false;
  if (!b->surface) {
    auto r = std::make_unique<SurfaceRecord>();
    r->rest.positions = b->model.restPositions;
    r->rest.tets = b->model.tets;
    const detail::EdgeGraph* graph = nullptr;
    if (b->fracture) {
      graph = &b->fracture->graph();
    } else {
      r->ownGraph =
          detail::EdgeGraph::build(b->model.tets.data(), b->model.tetCount, b->model.nodeCount);
      r->noBreaks.assign(r->ownGraph.edgeCount, 0);
      r->oneFragment.assign(b->model.nodeCount, 0);
      graph = &r->ownGraph;
    }
    r->surface.init(r->rest, *graph);
    const uint8_t* broken = r->noBreaks.data();
    const int32_t* fragments = r->oneFragment.data();
    if (b->fracture) {
      r->brokenCount = uint64_t(b->fracture->brokenCount());
      broken = b->fracture->broken().data();
      fragments = b->fracture->fragments().nodeFragment().data();
      r->surface.setSplitRatios(b->fracture->splitRatios());
    }
    if (b->renderBinding) {
      r->embedded = std::make_unique<detail::EmbeddedSurface>();
      r->embedded->init(*b->renderBinding, r->rest, *graph, b->model.restInverse.data());
      r->embedded->setChipsDrawnByNeighbours(b->fracture && b->model.fracture.releaseEveryBatch);
    }
    rebuildSurface(*r, broken, fragments, b->state.x.data(), m_impl->jobs);
    if (r->embedded) r->embedded->update(b->state.x.data(), r->surface, m_impl->jobs);
    b->surface = std::move(r);
    updated = true;
  }
  if (const detail::EmbeddedSurface* e = b->surface->embedded.get()) {
    // Every vertex of a render mesh moves with its tet, so an update dirties them all.
    SurfaceView v;
    v.positions = e->positions();
    v.normals = e->normals();
    v.uvs = e->uvs();
    v.indices = e->indices();
    v.crackMask = e->crackFlags();
    v.materials = e->materials();
    v.vertexFragment = e->vertexFragment();
    v.vertexNode = e->vertexNode();
    v.topologyVersion = e->topologyVersion();
    v.dirtyBegin = 0;
    v.dirtyEnd = updated ? uint32_t(e->vertexNode().size()) : 0;
    return v;
  }
  const detail::CrackSurface& s = b->surface->surface;
  SurfaceView v;
  v.positions = s.positions();
  v.normals = s.normals();
  v.indices = s.indices();
  v.crackMask = s.crackFlags();
  v.vertexFragment = s.vertexFragment();
  v.vertexNode = s.vertexNode();
  v.topologyVersion = s.topologyVersion();
  v.dirtyBegin = s.dirty().begin;
  v.dirtyEnd = s.dirty().end;
  return v;
}

}  // namespace gf
