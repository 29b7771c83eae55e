// The laboratory experiments behind `graphfrac report lab` (report_lab_command.cpp). Everything
// measured here goes through the public API a game or a user's tool has: the jaws' load is
// World::gripForces (the residual of the implicit step on the gripped nodes, inertia included);
// the striker's is World::colliderImpulses over dt, and the same impulse slows the striker, so
// the kinetic energy it loses is exactly the work it did on the bar; crack positions come from
// the fracture events and the broken-edge flags.
#include "cli/report_lab.h"

#include <graphfrac/world.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>
#include <sstream>

namespace gf::cli::lab {
namespace {

using json = nlohmann::json;

glm::dvec3 restNode(const TetMesh& m, int32_t i) {
  const size_t k = 3 * static_cast<size_t>(i);
  return {m.positions[k], m.positions[k + 1], m.positions[k + 2]};
}

glm::dvec3 node(std::span<const double> x, int32_t i) {
  const size_t k = 3 * static_cast<size_t>(i);
  return {x[k], x[k + 1], x[k + 2]};
}

struct Bounds {
  glm::dvec3 lo{1e300}, hi{-1e300};
};

Bounds bounds(const TetMesh& m) {
  Bounds b;
  for (size_t i = 0; i < m.nodeCount(); ++i) {
    const glm::dvec3 p = restNode(m, static_cast<int32_t>(i));
    b.lo = glm::min(b.lo, p);
    b.hi = glm::max(b.hi, p);
  }
  return b;
}

double seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// Node shares of the fragments, largest first.
std::vector<double> fragmentShares(std::span<const int32_t> fragmentOfNode) {
  std::vector<double> count;
  for (int32_t f : fragmentOfNode) {
    if (f < 0) continue;
    if (static_cast<size_t>(f) >= count.size()) count.resize(static_cast<size_t>(f) + 1, 0);
    count[static_cast<size_t>(f)] += 1;
  }
  std::sort(count.rbegin(), count.rend());
  for (double& c : count) c /= static_cast<double>(std::max<size_t>(fragmentOfNode.size(), 1));
  return count;
}

}  // namespace

Result<scene::Scene> loadLabScene(const std::string& path, const std::string& meshPatch) {
  if (meshPatch.empty() || meshPatch == "{}") return scene::loadScene(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) return fail(path, ": cannot open the scene file");
  std::stringstream text;
  text << in.rdbuf();
  // A file that does not parse goes through loadScene, whose message has the line and column.
  json doc = json::parse(text.str(), nullptr, false, true);
  if (doc.is_discarded()) return scene::loadScene(path);
  const json patch = json::parse(meshPatch, nullptr, false, true);
  if (patch.is_discarded() || !patch.is_object())
    return fail(path, ": mesh resolution override: expected a JSON object, got ", meshPatch);
  if (!doc.is_object() || !doc.contains("bodies") || !doc["bodies"].is_array() ||
      doc["bodies"].empty() || !doc["bodies"][0].is_object() ||
      !doc["bodies"][0].contains("mesh") || !doc["bodies"][0]["mesh"].is_object())
    return fail(path, ": bodies[0].mesh: a lab scene needs a body with a mesh object");
  doc["bodies"][0]["mesh"].update(patch);
  const std::string dir = std::filesystem::path(path).parent_path().string();
  return scene::parseScene(doc.dump(), path + " (bodies[0].mesh with " + meshPatch + ")", dir);
}

Result<BrazilianResult> runBrazilian(const scene::Scene& sc, double rateFactor, int crackRefine) {
  if (sc.bodies.size() != 1) return fail(sc.source, ": bodies: a Brazilian test has one body");
  if (!(rateFactor > 0) || !std::isfinite(rateFactor))
    return fail("runBrazilian: rateFactor must be positive and finite");
  if (crackRefine < 1) return fail("runBrazilian: crackRefine must be at least 1");
  const scene::SceneBody& body = sc.bodies[0];
  std::vector<int> jaws;
  for (size_t g = 0; g < body.def.grips.size(); ++g)
    if (glm::length(glm::dvec3(body.def.grips[g].velocity)) > 0) jaws.push_back(int(g));
  if (jaws.size() != 2)
    return fail(sc.source, ": bodies[0].grips: a Brazilian test needs exactly two moving grips ",
                "(the jaws), found ", std::to_string(jaws.size()));
  if (!body.def.fracture.enabled)
    return fail(sc.source, ": bodies[0].fracture: a Brazilian test needs fracture");
  const glm::dvec3 v0(body.def.grips[size_t(jaws[0])].velocity);
  const glm::dvec3 axis = glm::normalize(v0);

  BrazilianResult r;
  const TetMesh& mesh = body.def.mesh;
  r.tets = mesh.tetCount();
  const Bounds b = bounds(mesh);
  const glm::dvec3 ext = b.hi - b.lo, centre = 0.5 * (b.hi + b.lo);
  // The disc's axis is its thinnest extent; the third direction lies in its plane, across the
  // load.
  int thick = 0;
  for (int k = 1; k < 3; ++k)
    if (ext[k] < ext[thick]) thick = k;
  glm::dvec3 thickAxis(0);
  thickAxis[thick] = 1;
  if (glm::length(glm::cross(axis, thickAxis)) < 0.5)
    return fail(sc.source, ": bodies[0].grips: the jaws must squeeze across the disc, not along ",
                "its thinnest extent (its axis)");
  const glm::dvec3 lateral = glm::normalize(glm::cross(axis, thickAxis));
  r.diameter = std::abs(glm::dot(ext, axis));
  r.thickness = ext[thick];
  r.strength = body.def.fracture.strength;
  r.jawSpeed = glm::length(v0) * rateFactor;
  r.dt = sc.dt;
  r.crackRefine = crackRefine;

  World world(sc.world);
  Result<BodyId> created = scene::addBody(world, body);
  if (!created.ok()) return fail(sc.source, ": bodies[0]: ", created.error().message);
  const BodyId id = created.value();
  for (int g : jaws) {
    const glm::vec3 v = body.def.grips[size_t(g)].velocity * float(rateFactor);
    if (Result<void> s = world.setGripVelocity(id, g, v); !s.ok()) return s.error();
  }

  // Where the crack ran: the rest midpoints of the broken edges, in the disc's plane.
  const std::span<const int32_t> edges = world.edges(id);
  double sa = 0, sl = 0, saa = 0, sll = 0, sal = 0;
  int near = 0;
  auto measureCrack = [&] {
    const std::span<const uint8_t> brokenFlags = world.brokenEdges(id);
    sa = sl = saa = sll = sal = 0;
    near = r.broken = 0;
    r.crack.clear();
    for (size_t e = 0; e < brokenFlags.size(); ++e) {
      if (!brokenFlags[e]) continue;
      const glm::dvec3 mid =
          0.5 * (restNode(mesh, edges[2 * e]) + restNode(mesh, edges[2 * e + 1])) - centre;
      const double a = glm::dot(mid, axis), l = glm::dot(mid, lateral);
      ++r.broken;
      r.crack.push_back({l, a});
      if (std::abs(l) < 0.1 * r.diameter) ++near;
      sa += a, sl += l, saa += a * a, sll += l * l, sal += a * l;
    }
  };

  const auto start = std::chrono::steady_clock::now();
  const double endTime = sc.frames * sc.dt / rateFactor;
  double load = 0, dt = sc.dt;
  bool broke = false, failed = false;
  int afterFailure = 0;
  while (world.time() < endTime && afterFailure < 200) {
    const StepStatus st = world.step(dt);
    ++r.steps;
    if (st.flags & ~uint32_t(kStepContactSwept)) ++r.flaggedSteps;  // swept: information
    if (!broke && !world.fractureEvents().empty()) {
      // The criterion judges the state the previous step ended in, so that step's load is the
      // one the first edge broke at.
      broke = true;
      r.firstBreakLoad = load;
      float worst = -1;
      for (const FractureEvent& e : world.fractureEvents())
        if (e.stress > worst) {
          worst = e.stress;
          r.firstBreak = 0.5 * (restNode(mesh, e.nodeA) + restNode(mesh, e.nodeB));
        }
      const glm::dvec3 d = r.firstBreak - centre;
      r.firstBreakFromCentre =
          std::hypot(glm::dot(d, axis), glm::dot(d, lateral)) / std::max(r.diameter, 1e-300);
      // An edge breaks only at the start of a step, so a crack crosses at most about one
      // averaging length per step: at dt it would run at 100 m/s while the jaws go on
      // loading the disc. Shorter steps let it run at the speed of a real one (granite's
      // Rayleigh waves: about 2.5 km/s) before the jaws have moved much.
      dt = sc.dt / crackRefine;
    }
    const std::span<const glm::dvec3> f = world.gripForces(id);
    // Each jaw's reaction along the load; their mean cancels the small inertial difference.
    load = 0.5 * (std::abs(glm::dot(f[size_t(jaws[0])], axis)) +
                  std::abs(glm::dot(f[size_t(jaws[1])], axis)));
    const double approach = 2 * r.jawSpeed * world.time();
    r.curve.displacement.push_back(approach);
    r.curve.load.push_back(load);
    if (load > r.peakLoad) {
      r.peakLoad = load;
      r.displacementAtPeak = approach;
    }
    // The crack that failed the disc is the one there when the load gave way; the jaws
    // crush the halves afterwards.
    if (broke && !failed && load < 0.9 * r.peakLoad) {
      failed = true;
      measureCrack();
    }
    if (failed && load < 0.3 * r.peakLoad) break;
    afterFailure += failed ? 1 : 0;
  }
  r.seconds = seconds(start);
  r.indirectStrength = 2 * r.peakLoad / (M_PI * r.diameter * r.thickness);
  if (!failed) measureCrack();
  r.fragments = world.fractureStats(id).fragments;
  if (r.broken > 0) {
    const double n = r.broken;
    r.onDiameter = near / n;
    const double caa = saa / n - (sa / n) * (sa / n), cll = sll / n - (sl / n) * (sl / n),
                 cal = sal / n - (sa / n) * (sl / n);
    // Principal axis of the 2x2 covariance, measured from the load axis.
    const double angle = 0.5 * std::atan2(2 * cal, caa - cll);
    r.crackAngleDeg = std::abs(angle) * 180 / M_PI;
  }
  return r;
}

Result<ImpactResult> runImpact(const scene::Scene& sc, const ImpactSetup& setup) {
  if (sc.bodies.size() != 1) return fail(sc.source, ": bodies: an impact test has one body");
  if (!(setup.strikerMass > 0)) return fail("runImpact: strikerMass must be positive");
  int striker = -1;
  for (size_t c = 0; c < sc.world.colliders.size(); ++c)
    if (glm::length(glm::dvec3(sc.world.colliders[c].velocity)) > 0) {
      if (striker >= 0)
        return fail(sc.source, ": colliders: an impact test has one moving collider (the ",
                    "striker); colliders[", std::to_string(striker), "] and [", std::to_string(c),
                    "] both move");
      striker = int(c);
    }
  if (striker < 0)
    return fail(sc.source, ": colliders: an impact test needs a moving collider (the striker)");
  const scene::SceneBody& body = sc.bodies[0];
  const TetMesh& mesh = body.def.mesh;
  const glm::dvec3 v0(sc.world.colliders[size_t(striker)].velocity);
  const glm::dvec3 axis = glm::normalize(v0);

  ImpactResult r;
  r.tets = mesh.tetCount();
  r.strikerSpeed = glm::length(v0);

  // Crack mouth: the notched face's nodes nearest the V on either side, mid-width.
  const Bounds b = bounds(mesh);
  const double midZ = 0.5 * (b.lo.z + b.hi.z), tol = 1e-9 * glm::length(b.hi - b.lo);
  int32_t mouth[2] = {-1, -1};
  for (size_t i = 0; i < mesh.nodeCount(); ++i) {
    const glm::dvec3 p = restNode(mesh, int32_t(i));
    if (std::abs(p.y - setup.notchMouthY) > tol) continue;
    const int side = p.x < setup.notchX ? 0 : 1;
    int32_t& best = mouth[side];
    if (best < 0) {
      best = int32_t(i);
      continue;
    }
    const glm::dvec3 q = restNode(mesh, best);
    const double dp = std::abs(p.x - setup.notchX), dq = std::abs(q.x - setup.notchX);
    if (dp < dq - tol || (dp < dq + tol && std::abs(p.z - midZ) < std::abs(q.z - midZ)))
      best = int32_t(i);
  }
  if (mouth[0] < 0 || mouth[1] < 0)
    return fail(sc.source, ": bodies[0].mesh: no node on the notched face y = ",
                std::to_string(setup.notchMouthY),
                " on both sides of x = ", std::to_string(setup.notchX));
  const double mouthRest = glm::length(restNode(mesh, mouth[1]) - restNode(mesh, mouth[0]));

  World world(sc.world);
  Result<BodyId> created = scene::addBody(world, body);
  if (!created.ok()) return fail(sc.source, ": bodies[0]: ", created.error().message);
  const BodyId id = created.value();

  // The ligament: the edges crossing the notch's plane. The V's tip is a node column, so no
  // edge crosses x = notchX itself: take the planes just either side of it, and the side the
  // crack ran on.
  const std::span<const int32_t> edges = world.edges(id);
  std::vector<int32_t> ligament[2];
  for (int side = 0; side < 2; ++side) {
    const double plane = setup.notchX + (side ? 1e-6 : -1e-6);
    for (size_t e = 0; 2 * e < edges.size(); ++e) {
      const double xa = restNode(mesh, edges[2 * e]).x, xb = restNode(mesh, edges[2 * e + 1]).x;
      if ((xa - plane) * (xb - plane) < 0) ligament[side].push_back(int32_t(e));
    }
  }
  auto ligamentCut = [&] {
    const std::span<const uint8_t> flags = world.brokenEdges(id);
    double most = 0;
    for (const auto& set : ligament) {
      int cut = 0;
      for (int32_t e : set) cut += flags[size_t(e)] ? 1 : 0;
      if (!set.empty()) most = std::max(most, double(cut) / double(set.size()));
    }
    return most;
  };

  const auto start = std::chrono::steady_clock::now();
  glm::dvec3 v = v0;
  const glm::dvec3 p0(world.colliders()[size_t(striker)].point);
  double contactAt = -1;  // striker travel when it first pushed
  for (int s = 0; s < sc.frames; ++s) {
    const double travelBefore =
        glm::dot(glm::dvec3(world.colliders()[size_t(striker)].point) - p0, axis);
    const StepStatus st = world.step(sc.dt);
    ++r.steps;
    if (st.flags & ~uint32_t(kStepContactSwept)) ++r.flaggedSteps;  // swept: information
    const glm::dvec3 J = world.colliderImpulses()[size_t(striker)];
    const double load = glm::dot(J, axis) / sc.dt;
    // The striker is rigid and free: the impulse it gave the bar comes off its momentum.
    v -= J / setup.strikerMass;
    std::vector<Collider> cs(world.colliders().begin(), world.colliders().end());
    cs[size_t(striker)].velocity = glm::vec3(v);
    if (Result<void> set = world.setColliders(cs); !set.ok()) return set.error();
    if (contactAt < 0 && load > 0) contactAt = travelBefore;
    if (contactAt < 0) continue;
    const double travel = glm::dot(glm::dvec3(cs[size_t(striker)].point) - p0, axis);
    const double disp = travel - contactAt;
    const std::span<const double> x = world.positions(id);
    const double cmod = glm::length(node(x, mouth[1]) - node(x, mouth[0])) - mouthRest;
    r.curve.displacement.push_back(disp);
    r.curve.load.push_back(load);
    r.curve.cmod.push_back(cmod);
    r.maxCmod = std::max(r.maxCmod, cmod);
    if (r.firstBreakDisplacement < 0 && !world.fractureEvents().empty()) {
      r.firstBreakDisplacement = disp;
      r.firstBreakLoad = r.curve.load.size() > 1 ? r.curve.load[r.curve.load.size() - 2] : 0;
    }
    // After the ligament is cut through, the striker only pushes the halves around the anvils:
    // the peak load is the bar's before that.
    if (r.displacementAtFracture < 0 && load > r.peakLoad) {
      r.peakLoad = load;
      r.displacementAtPeak = disp;
    }
    // Fragments change only when edges break.
    if (r.displacementAtSplit < 0 && !world.fractureEvents().empty()) {
      const std::vector<double> shares = fragmentShares(world.nodeFragments(id));
      if (shares.size() > 1 && shares[1] >= kSplitShare) r.displacementAtSplit = disp;
    }
    // A bar in two pieces is cut through whatever share of the two planes' edges broke: a
    // crack plane may step from one side of the notch's node column to the other.
    if (r.displacementAtFracture < 0 && !world.fractureEvents().empty() &&
        (ligamentCut() >= 0.9 || r.displacementAtSplit >= 0)) {
      r.displacementAtFracture = disp;
      r.energyToFracture = 0.5 * setup.strikerMass * (glm::dot(v0, v0) - glm::dot(v, v));
    }
    // Done: the striker went its distance or stopped, or it has thrown the halves (it is given
    // another half millimetre to do so, which the absorbed energy includes).
    if (disp >= setup.maxDisplacement || glm::dot(v, axis) <= 0 ||
        (r.displacementAtSplit >= 0 && disp >= r.displacementAtSplit + 5e-4))
      break;
  }
  r.seconds = seconds(start);
  r.absorbedEnergy = 0.5 * setup.strikerMass * (glm::dot(v0, v0) - glm::dot(v, v));

  const FractureStats fs = world.fractureStats(id);
  r.broken = fs.brokenEdges;
  r.fragments = fs.fragments;
  const std::vector<double> shares = fragmentShares(world.nodeFragments(id));
  r.largestShare = shares.empty() ? 1 : shares[0];
  r.secondShare = shares.size() > 1 ? shares[1] : 0;
  r.ligamentBroken = ligamentCut();
  return r;
}

}  // namespace gf::cli::lab
