// HapticContact (graphfrac/sculpt.h): continuous penalty haptics (thesis sec 7.2.3, eq
// 7.5-7.6). Each sample sweeps the proxy and the blended body surface linearly over the
// sample, keeps the contacts that are still behind their feature, finds new ones with
// continuous collision (kernels/ccd.h), and integrates each contact's depth over its
// penetration intervals. The broad phase is the sample's swept box of the proxy: body features
// whose swept boxes miss it are skipped, so the surface costs one pass of boxes per sample.
#include <algorithm>
#include <cmath>
#include <string>
#include <unordered_set>

#include "graphfrac/sculpt.h"
#include "kernels/ccd.h"

namespace gf {

namespace {

Vec3 vec(const glm::dvec3& v) { return {v.x, v.y, v.z}; }
glm::dvec3 dvec(Vec3 v) { return {v.x, v.y, v.z}; }
bool finite3(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// The unique edges of a triangle list, 2 per edge, smaller index first.
std::vector<uint32_t> edgesOf(std::span<const uint32_t> tri) {
  std::vector<uint64_t> keys;
  keys.reserve(tri.size());
  for (size_t t = 0; t + 2 < tri.size(); t += 3)
    for (int k = 0; k < 3; ++k) {
      const uint32_t i = tri[t + size_t(k)], j = tri[t + size_t((k + 1) % 3)];
      keys.push_back((uint64_t(std::min(i, j)) << 32) | std::max(i, j));
    }
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  std::vector<uint32_t> e;
  e.reserve(2 * keys.size());
  for (uint64_t k : keys) {
    e.push_back(uint32_t(k >> 32));
    e.push_back(uint32_t(k & 0xffffffffu));
  }
  return e;
}

struct Box {
  Vec3 lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  void add(Vec3 p) {
    for (int i = 0; i < 3; ++i) {
      lo[i] = std::min(lo[i], p[i]);
      hi[i] = std::max(hi[i], p[i]);
    }
  }
  bool overlaps(const Box& o) const {
    for (int i = 0; i < 3; ++i)
      if (hi[i] < o.lo[i] || o.hi[i] < lo[i]) return false;
    return true;
  }
};

// How far the felt surface has moved from the blend's start to its target after `elapsed`
// seconds. With no blend it jumps within the first sample: swept, so no contact is missed.
double blendFraction(double elapsed, double blend) {
  return blend > 0 ? std::min(1.0, elapsed / blend) : (elapsed > 0 ? 1.0 : 0.0);
}

// Barycentric tolerance for "over the triangle" and relative gap for "edges meet".
constexpr double kOverTol = 1e-9;
constexpr double kMeetTol = 1e-9;

}  // namespace

Result<HapticContact> HapticContact::create(std::span<const glm::dvec3> vertices,
                                            std::span<const uint32_t> indices,
                                            const HapticContactSettings& settings) {
  if (!(std::isfinite(settings.stiffness) && settings.stiffness > 0))
    return fail("HapticContact: settings.stiffness must be positive and finite, got ",
                std::to_string(settings.stiffness));
  if (vertices.empty() || indices.empty() || indices.size() % 3 != 0)
    return fail("HapticContact: the proxy needs vertices and 3 indices per triangle (got ",
                std::to_string(vertices.size()), " vertices, ", std::to_string(indices.size()),
                " indices)");
  for (size_t i = 0; i < vertices.size(); ++i)
    if (!finite3(vertices[i]))
      return fail("HapticContact: proxy vertex ", std::to_string(i), " is not finite");
  for (size_t i = 0; i < indices.size(); ++i)
    if (indices[i] >= vertices.size())
      return fail("HapticContact: proxy index ", std::to_string(i), " (",
                  std::to_string(indices[i]), ") is out of range [0, ",
                  std::to_string(vertices.size()), ")");
  HapticContact h;
  h.m_settings = settings;
  h.m_proxy.assign(vertices.begin(), vertices.end());
  h.m_proxyTriangles.assign(indices.begin(), indices.end());
  h.m_proxyEdges = edgesOf(indices);
  return h;
}

Result<void> HapticContact::setSurface(const SurfaceView& s, double blend) {
  if (!(std::isfinite(blend) && blend >= 0))
    return fail("HapticContact::setSurface: blend must be >= 0 s and finite, got ",
                std::to_string(blend));
  const size_t n = s.positions.size() / 3;
  if (n == 0 || s.positions.size() % 3 != 0 || s.indices.empty() || s.indices.size() % 3 != 0)
    return fail("HapticContact::setSurface: the surface has no triangles (", std::to_string(n),
                " vertices, ", std::to_string(s.indices.size()), " indices)");
  for (size_t i = 0; i < s.positions.size(); ++i)
    if (!std::isfinite(s.positions[i]))
      return fail("HapticContact::setSurface: vertex ", std::to_string(i / 3), " is not finite");
  for (size_t i = 0; i < s.indices.size(); ++i)
    if (s.indices[i] >= n)
      return fail("HapticContact::setSurface: index ", std::to_string(i), " is out of range");

  std::vector<glm::dvec3> to(n);
  for (size_t i = 0; i < n; ++i)
    to[i] = {s.positions[3 * i], s.positions[3 * i + 1], s.positions[3 * i + 2]};
  const bool sameTriangles =
      m_hasSurface && s.topologyVersion == m_topology && to.size() == m_to.size() &&
      std::equal(s.indices.begin(), s.indices.end(), m_triangles.begin(), m_triangles.end());
  if (sameTriangles) {
    // Start the new blend where the felt surface is now.
    const double f = blendFraction(m_elapsed, m_blend);
    for (size_t i = 0; i < n; ++i) m_from[i] = m_from[i] + f * (m_to[i] - m_from[i]);
    m_to = std::move(to);
  } else {
    m_from = to;
    m_to = std::move(to);
    m_triangles.assign(s.indices.begin(), s.indices.end());
    m_edges = edgesOf(m_triangles);
    // Contacts on the old features: a proxy vertex moves to the nearest new triangle it lies
    // behind (found at the next sample); the others end.
    std::vector<Contact> kept;
    for (Contact c : m_contacts)
      if (c.kind == 0) {
        c.b = -1;
        kept.push_back(c);
      }
    m_contacts = std::move(kept);
  }
  m_at0.resize(n);
  m_at1.resize(n);
  m_placed.assign(n, 0);
  m_regionValid = false;
  m_topology = s.topologyVersion;
  m_hasSurface = true;
  m_blend = blend;
  m_elapsed = 0;
  return {};
}

Result<glm::dvec3> HapticContact::sample(std::span<const glm::dvec3> vertices, double dt) {
  if (vertices.size() != m_proxy.size())
    return fail("HapticContact::sample: ", std::to_string(vertices.size()),
                " vertices given, the proxy has ", std::to_string(m_proxy.size()));
  if (!(std::isfinite(dt) && dt > 0))
    return fail("HapticContact::sample: dt must be positive and finite, got ", std::to_string(dt));
  for (size_t i = 0; i < vertices.size(); ++i)
    if (!finite3(vertices[i]))
      return fail("HapticContact::sample: vertex ", std::to_string(i), " is not finite");
  m_pushes.clear();
  if (!m_hasSurface) {
    m_proxy.assign(vertices.begin(), vertices.end());
    return glm::dvec3(0.0);
  }

  std::vector<Vec3> proxy0(m_proxy.size()), proxy1(m_proxy.size());
  Box proxyBox;
  for (size_t i = 0; i < m_proxy.size(); ++i) {
    proxy0[i] = vec(m_proxy[i]);
    proxy1[i] = vec(vertices[i]);
    proxyBox.add(proxy0[i]);
    proxyBox.add(proxy1[i]);
  }
  const bool continuous = m_settings.continuous;
  // The body features worth testing: those whose blend sweep meets a box around the proxy's
  // sweep, enlarged by its size so that the list lasts for many samples (rebuilt when the proxy
  // leaves the box's inner half or the surface changes). The discrete mode needs every
  // triangle: its nearest one may be anywhere.
  double margin = 0;
  for (int i = 0; i < 3; ++i) margin = std::max(margin, proxyBox.hi[i] - proxyBox.lo[i]);
  bool inside = m_regionValid;
  for (int i = 0; inside && i < 3; ++i)
    inside = proxyBox.lo[i] >= m_regionLo[i] + 0.5 * margin &&
             proxyBox.hi[i] <= m_regionHi[i] - 0.5 * margin;
  if (!inside || !continuous) {
    Box region = proxyBox;
    for (int i = 0; i < 3; ++i) {
      region.lo[i] -= continuous ? margin : 1e300;
      region.hi[i] += continuous ? margin : 1e300;
    }
    m_regionLo = dvec(region.lo);
    m_regionHi = dvec(region.hi);
    m_regionValid = true;
    const auto near = [&](const uint32_t* idx, int count) {
      Box b;
      for (int i = 0; i < count; ++i) {
        b.add(vec(m_from[idx[i]]));
        b.add(vec(m_to[idx[i]]));
      }
      return b.overlaps(region);
    };
    m_nearTriangles.clear();
    m_nearEdges.clear();
    m_nearVertices.clear();
    for (size_t t = 0; t < m_triangles.size() / 3; ++t)
      if (near(&m_triangles[3 * t], 3)) m_nearTriangles.push_back(int32_t(t));
    for (size_t e = 0; e < m_edges.size() / 2; ++e)
      if (near(&m_edges[2 * e], 2)) m_nearEdges.push_back(int32_t(e));
    for (size_t v = 0; v < m_to.size(); ++v) {
      const uint32_t i = uint32_t(v);
      if (near(&i, 1)) m_nearVertices.push_back(int32_t(v));
    }
  }

  // The body surface at the sample's start and end, computed for the vertices used.
  const double f0 = blendFraction(m_elapsed, m_blend), f1 = blendFraction(m_elapsed + dt, m_blend);
  if (++m_sampleId == 0) {  // after 2^32 samples the stamps start over
    std::fill(m_placed.begin(), m_placed.end(), 0u);
    m_sampleId = 1;
  }
  const auto place = [&](uint32_t i) {
    if (m_placed[i] == m_sampleId) return;
    m_placed[i] = m_sampleId;
    m_at0[i] = m_from[i] + f0 * (m_to[i] - m_from[i]);
    m_at1[i] = m_from[i] + f1 * (m_to[i] - m_from[i]);
  };
  for (int32_t v : m_nearVertices) place(uint32_t(v));
  for (int32_t t : m_nearTriangles)
    for (int c = 0; c < 3; ++c) place(m_triangles[3 * size_t(t) + size_t(c)]);
  for (int32_t e : m_nearEdges)
    for (int c = 0; c < 2; ++c) place(m_edges[2 * size_t(e) + size_t(c)]);
  const auto B0 = [&](uint32_t i) { return vec(m_at0[i]); };
  const auto B1 = [&](uint32_t i) { return vec(m_at1[i]); };
  const auto P0 = [&](uint32_t i) { return proxy0[i]; };
  const auto P1 = [&](uint32_t i) { return proxy1[i]; };

  const double k = m_settings.stiffness;
  const auto tri = [](const std::vector<uint32_t>& t, int32_t i, int c) {
    return t[3 * size_t(i) + size_t(c)];
  };
  // The quad of a contact, points moving over the sample.
  const auto quadOf = [&](const Contact& c) {
    MovingQuad q;
    if (c.kind == 0) {
      q.p0 = proxy0[size_t(c.a)], q.p1 = proxy1[size_t(c.a)];
      const uint32_t i = tri(m_triangles, c.b, 0), j = tri(m_triangles, c.b, 1),
                     l = tri(m_triangles, c.b, 2);
      place(i), place(j), place(l);
      q.a0 = B0(i), q.a1 = B1(i), q.b0 = B0(j), q.b1 = B1(j), q.c0 = B0(l), q.c1 = B1(l);
    } else if (c.kind == 1) {
      place(uint32_t(c.a));
      q.p0 = B0(uint32_t(c.a)), q.p1 = B1(uint32_t(c.a));
      const uint32_t i = tri(m_proxyTriangles, c.b, 0), j = tri(m_proxyTriangles, c.b, 1),
                     l = tri(m_proxyTriangles, c.b, 2);
      q.a0 = proxy0[i], q.a1 = proxy1[i], q.b0 = proxy0[j], q.b1 = proxy1[j];
      q.c0 = proxy0[l], q.c1 = proxy1[l];
    } else {
      const uint32_t i = m_proxyEdges[2 * size_t(c.a)], j = m_proxyEdges[2 * size_t(c.a) + 1];
      const uint32_t l = m_edges[2 * size_t(c.b)], m = m_edges[2 * size_t(c.b) + 1];
      place(l), place(m);
      q.p0 = proxy0[i], q.p1 = proxy1[i], q.a0 = proxy0[j], q.a1 = proxy1[j];
      q.b0 = B0(l), q.b1 = B1(l), q.c0 = B0(m), q.c1 = B1(m);
    }
    return q;
  };
  // The triangle among `which` (indices into `tris`, whose corners `pt` places) nearest to x,
  // with x's depth behind it (< 0 in front) and its unit normal. With `facing`, only
  // triangles behind which x lies whose normal is within 90 degrees of it: where a vertex that
  // slid off its triangle goes on (never the far side of a thin part).
  const auto nearest = [](Vec3 x, auto&& pt, const std::vector<uint32_t>& tris,
                          const std::vector<int32_t>& which, const Vec3* facing, double& depth,
                          Vec3& n) {
    int32_t best = -1;
    double bestDist = 1e300;
    for (int32_t t : which) {
      const Vec3 a = pt(tris[3 * size_t(t)]), b = pt(tris[3 * size_t(t) + 1]),
                 c = pt(tris[3 * size_t(t) + 2]);
      const Vec3 N = cross(b - a, c - a);
      const double nn = norm(N);
      if (!(nn > 0)) continue;
      const double d = -dot(N, x - a) / nn;
      if (facing && (d <= 0 || dot(N, *facing) <= 0)) continue;
      const Vec3 w = closestOnTriangle(x, a, b, c);
      const double dist = norm(x - (w.x * a + w.y * b + w.z * c));
      if (dist < bestDist) {
        bestDist = dist;
        best = t;
        depth = d;
        n = (1 / nn) * N;
      }
    }
    return best;
  };
  std::vector<int32_t> proxyTriangles(m_proxyTriangles.size() / 3);
  for (size_t t = 0; t < proxyTriangles.size(); ++t) proxyTriangles[t] = int32_t(t);

  glm::dvec3 force(0.0);
  if (!continuous) {
    // Discrete penalty at the sample's end.
    double depth = 0;
    Vec3 n;
    for (size_t v = 0; v < proxy1.size(); ++v)
      if (nearest(proxy1[v], B1, m_triangles, m_nearTriangles, nullptr, depth, n) >= 0 &&
          depth > 0) {
        const glm::dvec3 f = dvec((k * depth) * n);
        force += f;
        m_pushes.push_back({dvec(proxy1[v] + depth * n), -f});
      }
    for (int32_t v : m_nearVertices)
      if (nearest(B1(uint32_t(v)), P1, m_proxyTriangles, proxyTriangles, nullptr, depth, n) >= 0 &&
          depth > 0) {
        const glm::dvec3 f = dvec((k * depth) * n);
        force -= f;
        m_pushes.push_back({dvec(B1(uint32_t(v))), f});
      }
    m_proxy.assign(vertices.begin(), vertices.end());
    m_elapsed += dt;
    return force;
  }

  // Contacts that lost their triangle to a new surface, at the sample's start.
  for (Contact& c : m_contacts)
    if (c.kind == 0 && c.b < 0) {
      double depth = 0;
      Vec3 n;
      const Vec3 facing = vec(c.normal);
      c.b = nearest(proxy0[size_t(c.a)], B0, m_triangles, m_nearTriangles, &facing, depth, n);
    }
  std::erase_if(m_contacts, [](const Contact& c) { return c.b < 0; });

  // New contacts: features whose sweeps meet, each counted from the time it crosses in.
  std::unordered_set<uint64_t> taken;
  const auto key = [](int kind, int64_t a, int64_t b) {
    return (uint64_t(kind) << 62) | (uint64_t(a) << 31) | uint64_t(b);
  };
  for (const Contact& c : m_contacts) taken.insert(key(c.kind, c.a, c.kind == 2 ? c.b : 0));
  struct Entry {
    Contact c;
    double t;
  };
  std::vector<Entry> entries;
  // A crossing into the inside (sign * f from > 0 to < 0) with the point on the feature.
  const auto firstEntry = [&](const Contact& c, bool edgeEdge, double& when, double& sign) {
    const MovingQuad q = quadOf(c);
    double roots[3];
    const int n = quadVolumeSignChanges(q, edgeEdge, roots);
    for (int r = 0; r < n; ++r) {
      const double before = quadVolume(q, edgeEdge, r == 0 ? 0.0 : 0.5 * (roots[r - 1] + roots[r]));
      if (!edgeEdge && before <= 0) continue;  // leaving a face, not entering it
      bool on = false;
      if (edgeEdge) {
        double s = 0, u = 0;
        on = edgesMeet(q, roots[r], kMeetTol, s, u);
      } else {
        Vec3 w;
        on = pointOverTriangle(q, roots[r], kOverTol, w);
      }
      if (on) {
        when = roots[r];
        sign = before > 0 ? 1.0 : -1.0;
        return true;
      }
    }
    return false;
  };
  const auto sweepBox = [](auto&& at0, auto&& at1, const uint32_t* idx, int count) {
    Box b;
    for (int i = 0; i < count; ++i) {
      b.add(at0(idx[i]));
      b.add(at1(idx[i]));
    }
    return b;
  };
  std::vector<Box> proxyTriBox(proxyTriangles.size()), proxyEdgeBox(m_proxyEdges.size() / 2);
  for (size_t t = 0; t < proxyTriBox.size(); ++t)
    proxyTriBox[t] = sweepBox(P0, P1, &m_proxyTriangles[3 * t], 3);
  for (size_t e = 0; e < proxyEdgeBox.size(); ++e)
    proxyEdgeBox[e] = sweepBox(P0, P1, &m_proxyEdges[2 * e], 2);
  // Proxy vertices against body triangles; one contact per vertex, the earliest.
  std::vector<Box> bodyTriBox;
  std::vector<int32_t> bodyTris;
  for (int32_t t : m_nearTriangles) {
    const Box b = sweepBox(B0, B1, &m_triangles[3 * size_t(t)], 3);
    if (!b.overlaps(proxyBox)) continue;
    bodyTris.push_back(t);
    bodyTriBox.push_back(b);
  }
  for (size_t v = 0; v < proxy0.size(); ++v) {
    if (taken.count(key(0, int64_t(v), 0))) continue;
    Box pv;
    pv.add(proxy0[v]);
    pv.add(proxy1[v]);
    Entry best{{0, int32_t(v), -1, 1}, 2};
    for (size_t i = 0; i < bodyTris.size(); ++i) {
      if (!bodyTriBox[i].overlaps(pv)) continue;
      Contact c{0, int32_t(v), bodyTris[i], 1};
      double t = 0, sign = 1;
      if (firstEntry(c, false, t, sign) && t < best.t) best = {c, t};
    }
    if (best.c.b >= 0) entries.push_back(best);
  }
  // Body vertices against proxy triangles.
  for (int32_t v : m_nearVertices) {
    if (taken.count(key(1, v, 0))) continue;
    Box bv;
    bv.add(B0(uint32_t(v)));
    bv.add(B1(uint32_t(v)));
    if (!bv.overlaps(proxyBox)) continue;
    Entry best{{1, v, -1, 1}, 2};
    for (size_t t = 0; t < proxyTriBox.size(); ++t) {
      if (!proxyTriBox[t].overlaps(bv)) continue;
      Contact c{1, v, int32_t(t), 1};
      double when = 0, sign = 1;
      if (firstEntry(c, false, when, sign) && when < best.t) best = {c, when};
    }
    if (best.c.b >= 0) entries.push_back(best);
  }
  // Proxy edges against body edges.
  for (int32_t e : m_nearEdges) {
    const Box eb = sweepBox(B0, B1, &m_edges[2 * size_t(e)], 2);
    if (!eb.overlaps(proxyBox)) continue;
    for (size_t p = 0; p < proxyEdgeBox.size(); ++p) {
      if (taken.count(key(2, int64_t(p), e)) || !proxyEdgeBox[p].overlaps(eb)) continue;
      Contact c{2, int32_t(p), e, 1};
      double when = 0, sign = 1;
      if (firstEntry(c, true, when, sign)) {
        c.sign = sign;
        entries.push_back({c, when});
      }
    }
  }

  // Integrate eq 7.5-7.6 over each contact's penetration intervals in the sample.
  const auto integrate = [&](const Contact& c, double from) {
    const MovingQuad q = quadOf(c);
    const Vec3 j = (k * dt) * penetrationIntegral(q, c.kind == 2, c.sign, from, 1.0);
    // The impulse acts on the quad's point p; its owner is the proxy except for kind 1.
    const glm::dvec3 onProxy = c.kind == 1 ? -dvec(j) : dvec(j);
    force += onProxy / dt;
    Vec3 at = q.p1;
    if (c.kind == 0) {
      const Vec3 w = closestOnTriangle(q.p1, q.a1, q.b1, q.c1);
      at = w.x * q.a1 + w.y * q.b1 + w.z * q.c1;
    } else if (c.kind == 2) {
      double s = 0, u = 0;
      if (closestOnSegments(q.p1, q.a1, q.b1, q.c1, s, u)) at = lerp3(q.b1, q.c1, u);
    }
    if (onProxy != glm::dvec3(0.0)) m_pushes.push_back({dvec(at), -onProxy / dt});
  };
  for (const Contact& c : m_contacts) integrate(c, 0.0);
  for (Entry& e : entries) {
    integrate(e.c, e.t);
    const Vec3 N = quadNormal(quadOf(e.c), e.c.kind == 2, e.t);
    e.c.normal = dvec((1 / norm(N)) * N);
    m_contacts.push_back(e.c);
  }

  // Which contacts live on: still behind their feature at the end, and still over it.
  std::vector<Contact> alive;
  for (Contact c : m_contacts) {
    const MovingQuad q = quadOf(c);
    if (c.sign * quadVolume(q, c.kind == 2, 1.0) >= 0) continue;
    if (c.kind == 2) {
      double s = 0, u = 0;
      if (!closestOnSegments(q.p1, q.a1, q.b1, q.c1, s, u) || s <= 0 || s >= 1 || u <= 0 || u >= 1)
        continue;
    } else {
      Vec3 w;
      if (!pointOverTriangle(q, 1.0, kOverTol, w)) {
        double depth = 0;
        Vec3 n;
        const Vec3 facing = vec(c.normal);
        c.b = c.kind == 0 ? nearest(q.p1, B1, m_triangles, m_nearTriangles, &facing, depth, n)
                          : nearest(q.p1, P1, m_proxyTriangles, proxyTriangles, &facing, depth, n);
        if (c.b < 0) continue;
      }
      const Vec3 N = quadNormal(quadOf(c), false, 1.0);
      c.normal = dvec((1 / norm(N)) * N);
    }
    alive.push_back(c);
  }
  m_contacts = std::move(alive);
  m_proxy.assign(vertices.begin(), vertices.end());
  m_elapsed += dt;
  return force;
}

}  // namespace gf
