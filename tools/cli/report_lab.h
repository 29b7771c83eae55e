// Laboratory tests as runnable experiments (thesis sec 2.5, 4.5.5, 6.3.5): the Brazilian disc,
// the Charpy and the Izod impact tests, run from scenes/lab/ and measured only through the
// public API (grip reactions, collider impulses, fracture events), so any user of the runtime
// can take the same measurements. `graphfrac report lab` drives them; the tests call them
// directly on coarse meshes.
#pragma once

#include <graphfrac/status.h>

#include <glm/vec3.hpp>
#include <string>
#include <vector>

#include "scene/scene.h"

namespace gf::cli::lab {

/// A load-displacement record, one sample per step.
struct Curve {
  std::vector<double> displacement;  ///< [m]
  std::vector<double> load;          ///< [N]
  std::vector<double> cmod;          ///< Crack mouth opening [m] (impact tests; else empty).
};

/// Loads a lab scene with `meshPatch` (a JSON object, possibly empty "{}") merged into
/// bodies[0].mesh first, e.g. {"segments": 96, "rings": 12, "layers": 12} for a finer disc.
/// Errors name the file and the field.
Result<scene::Scene> loadLabScene(const std::string& path, const std::string& meshPatch);

/// Brazilian test: the scene's two moving grips are the jaws, squeezing along their velocity.
struct BrazilianResult {
  size_t tets = 0;
  double diameter = 0, thickness = 0;  ///< From the mesh: extent along the load, along y [m].
  double strength = 0;                 ///< sigma_th of the body [Pa].
  double jawSpeed = 0;                 ///< Speed of each jaw [m/s].
  double dt = 0;                       ///< Step before the first break [s].
  int crackRefine = 1;                 ///< Steps after it are dt / crackRefine.
  double firstBreakLoad = 0;        ///< Jaw load at the end of the step before the first break [N].
  double peakLoad = 0;              ///< The failure load P: the largest jaw load [N].
  double displacementAtPeak = 0;    ///< Jaw approach at the peak [m].
  double indirectStrength = 0;      ///< 2 P / (pi D t) [Pa] (Hondros 1959).
  glm::dvec3 firstBreak{0};         ///< Rest midpoint of the most stressed first broken edge.
  double firstBreakFromCentre = 0;  ///< Its distance from the axis, over D.
  /// Broken edges whose rest midpoint lies within 0.1 D of the loaded diametral plane, over all
  /// broken edges, and the angle [deg] of the broken edges' principal axis (in the disc's
  /// plane) from the loaded diameter.
  double onDiameter = 0, crackAngleDeg = 0;
  /// Rest midpoints of those broken edges in the disc's plane: (across the load, along it) [m]
  /// from the centre.
  std::vector<glm::dvec2> crack;
  int broken = 0, fragments = 0, steps = 0, flaggedSteps = 0;
  double seconds = 0;  ///< Wall clock of the run.
  Curve curve;         ///< Jaw approach against load.
};

/// Runs the Brazilian scene with the jaws at `rateFactor` times the scene's speed, until the
/// load has fallen below 30 % of its peak after the disc started breaking, or the scene's
/// frames (times 1 / rateFactor) are used up. From the first broken edge on, steps are
/// `crackRefine` times shorter, so the crack can run across the disc before the jaws load it
/// much further. The crack is measured when the load first falls below 90 % of its peak.
Result<BrazilianResult> runBrazilian(const scene::Scene& sc, double rateFactor = 1.0,
                                     int crackRefine = 10);

/// A bar has split in two when its second largest fragment holds this share of its nodes (the
/// two halves of a Charpy bar hold about half each; debris a few nodes).
constexpr double kSplitShare = 0.2;

/// An impact test: the scene's one moving collider is the striker, of mass `strikerMass`; each
/// step it loses the impulse it gave the bar (World::colliderImpulses), v -= J / m.
struct ImpactSetup {
  double strikerMass = 20;    ///< [kg]
  double notchX = 0.0275;     ///< Rest x of the notch tip [m].
  double notchMouthY = 0.01;  ///< Rest y of the notched face [m].
  /// Stop when the striker has moved this far past contact, or 0.5 mm past the split.
  double maxDisplacement = 4e-3;
};

struct ImpactResult {
  size_t tets = 0;
  double strikerSpeed = 0;        ///< Initial [m/s].
  double peakLoad = 0;            ///< Largest load before the fracture [N].
  double displacementAtPeak = 0;  ///< Striker travel since contact at the peak [m].
  /// Striker travel when 90 % of the ligament's edges were broken or the bar split, whichever
  /// came first (-1: never) [m].
  double displacementAtFracture = -1;
  double energyToFracture = -1;        ///< Striker kinetic energy lost by then [J] (-1: never).
  double displacementAtSplit = -1;     ///< Striker travel when the bar fell in two (-1: never) [m].
  double absorbedEnergy = 0;           ///< Striker kinetic energy lost over the whole run [J].
  double firstBreakDisplacement = -1;  ///< Striker travel at the first broken edge (-1: none).
  double firstBreakLoad = 0;  ///< Load in the step before it (the state the criterion judged) [N].
  int broken = 0, fragments = 0;
  /// Share of the nodes in the two largest fragments: split in two when the second holds a
  /// fair share of the bar.
  double largestShare = 1, secondShare = 0;
  /// Broken edges among those crossing the notch's plane (x = notchX): how much of the
  /// ligament the crack cut.
  double ligamentBroken = 0;
  double maxCmod = 0;  ///< [m]
  int steps = 0, flaggedSteps = 0;
  double seconds = 0;
  Curve curve;  ///< Striker travel since contact against the load it feels; CMOD.
  bool splitInTwo() const { return secondShare >= kSplitShare; }
};

Result<ImpactResult> runImpact(const scene::Scene& sc, const ImpactSetup& setup);

}  // namespace gf::cli::lab
