// Brittle mode (thesis sec 4.5.1.2, fig 4.19): when the criterion first fires in a brittle
// body, the `regions` most stressed regions each start one planar crack normal to their
// maximum principal stress, and the plane runs to the boundary, breaking every edge it
// crosses.
//
// Design: everything happens in REST space. The stress is material-frame (rotation
// invariant), so its principal direction is a rest-space direction, and rest positions make
// the planes independent of the current pose and of round-off in it. Seeds: tets sorted by
// maximum principal stress (ties by id), taken greedily when farther than 2 R_seed from every
// seed already taken. Propagation: a flood fill over face-adjacent tets that the plane cuts
// (nodes on both sides, a node on the plane counting as the positive side), breaking the
// edges whose endpoints lie on opposite sides; the fill stops where the plane leaves the body,
// so on a non-convex body a plane only cuts the sheet that contains its seed. Strength: a plane
// carries its seed's maximum principal stress or the body's strength (settings.strength),
// whichever is larger, so it runs to the boundary through the body's own material (the
// thesis's rule) even from a region stressed below the strength; an edge whose strength (per
// edge, as World::setEdgeStrengths sets it) exceeds that holds, and the fill does not go on
// from a tet in which an edge held, so the crack front stops there (a strong inclusion or a
// reinforced seam arrests it). Planes do not stop at earlier cracks. A node the planes leave
// with no whole tet goes to a piece (brittle.cpp, keepNodesInPieces), not out as a loose node.
// Serial apart from the principal stresses; events sorted by edge id.
#pragma once

#include <cstdint>
#include <vector>

#include "fracture/fracture_model.h"
#include "graphfrac/jobs.h"
#include "graphfrac/status.h"
#include "kernels/math.h"
#include "mesh/edge_graph.h"

namespace gf::detail {

/// Tuning of the seed choice.
struct BrittleOptions {
  /// Radius of a seed region in mean edge lengths (at least R_d is used); seeds are more than
  /// twice this apart.
  double seedRadius = 2;
  /// Give a node that the planes left with no whole tet to a piece (keeping some of the plane
  /// edges at it) instead of leaving it a loose node (brittle.cpp, keepNodesInPieces). Off
  /// only to measure what it changes.
  bool keepNodesWhole = true;
};

/// One crack plane started by startBrittleCracks.
struct BrittleSeed {
  int32_t tet = -1;          ///< Seed tet.
  double principal = 0;      ///< Its maximum principal stress [Pa].
  double carried = 0;        ///< max(principal, settings.strength): edges above it hold [Pa].
  Vec3 point;                ///< Rest centroid of the seed tet: a point of the plane.
  Vec3 normal;               ///< Unit rest-space normal (maximum principal direction).
  int32_t tetsCut = 0;       ///< Tets the plane crossed.
  int32_t edgesBroken = 0;   ///< Edges this plane broke that were not broken before.
  int32_t tetsArrested = 0;  ///< Cut tets where an edge stronger than `carried` held.
  int32_t edgesKept = 0;     ///< Edges it crossed, left unbroken so a node keeps a whole tet.
  /// Severed edges broken with its planes' batch (keepNodesInPieces: only split tets, and they
  /// could join two pieces); their events follow all the planes' breaks.
  int32_t edgesReleased = 0;
};

/// Starts up to model.settings.regions crack planes from the tets of highest maximum
/// principal stress of `tetStress` (6 per tet, Voigt, material frame; pass the criterion's
/// averaged stress when R_d > 0); `strength` holds the current per-edge strengths. Only tensile
/// tets (principal > 0) seed. Sets broken flags, appends events sorted by edge id (position from
/// `positions` when given, else rest) and after them, also sorted, the severed edges released
/// with the planes (BrittleSeed::edgesReleased in all), and returns the seeds in the order
/// chosen. Fails when the
/// model has no face adjacency (build it with settings.brittle or
/// FractureModel::buildFaceAdjacency) or the sizes disagree.
Result<std::vector<BrittleSeed>> startBrittleCracks(
    const FractureModel& model, const EdgeGraph& graph, const RestMeshView& rest,
    const double* strength, const double* tetStress, std::vector<uint8_t>& broken,
    std::vector<EdgeBreak>& events, JobSystem& jobs, const double* positions = nullptr,
    const BrittleOptions& options = {});

}  // namespace gf::detail
