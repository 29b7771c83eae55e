// The path of a blade (a triangle mesh, as for graph cuts) through the tets of an Is-XFEM body
// (thesis sec 3.1): which tets it crosses, the cut plane it makes in each, and whether it crosses
// each one fully.
//
// Design: a tet meets the blade when one of its faces meets a blade triangle (Moeller's
// triangle-triangle test, kernels/tri_tri.h) or a blade vertex lies in it (a triangle wholly
// inside). Within one tet the cut is a plane (the enrichment of eq 3.2 and the cells of
// cut_polytope.h need one): the area-weighted mean of the blade's pieces clipped to the tet,
// through their area centroid. For a blade that is planar across the tet this is the blade's own
// plane; for a blade folded or curved inside the tet it is the best plane in the mean, and the
// largest distance of the blade's pieces from it is reported (`deviation`) so a caller can see
// how far the cut face strays from the blade. A tet is fully crossed when the blade splits it in
// two: no blade boundary edge meets it (the blade does not end inside it), and every tet edge is
// crossed by the blade exactly as often as by the local plane (once or never), which also rejects
// a blade that folds back or closes on itself inside the tet. A tet the blade only touches (its
// pieces have no area, or the local plane leaves every node on one side) is not a crossing.
// A node within kXfemNodeSnap of its shortest edge from the blade counts as on it, and a node on
// the blade counts as the positive side (xfemHeaviside of 0): its edges towards the negative side
// are crossed at the node itself, in every tet around it, so a blade through a node (to rounding,
// as parallel cuts on a regular mesh do) gives the same node sides in all those tets. A tet
// whose only positive node lies on the blade is then crossed with an empty positive cell (its
// nodes' enriched functions stay conforming there), and one whose other nodes are all positive
// is only touched. The local plane keeps such a node exactly on its positive side.
// A swept blade (moved rigidly from `pose` to `to`, as a World Blade moves from `from` to `to`)
// cuts along the surface it sweeps: the blade at both poses and the quads its boundary edges sweep
// (bladeSurface), one closed indexed mesh oriented out of the swept volume, or, for a sweep within
// the blade's own plane, the flat region it covers with every triangle along the blade's normal.
// cutting.h's swept triangles (for segment tests) also sweep the blade's interior edges; as a cut
// surface their quads would meet along the swept vertices' paths in more than two triangles, which
// reads as the blade's boundary there (a blade ending inside every tet it crosses), so only the
// boundary edges are swept here. A tet the surface folds in (the swept volume's edges) is partial.
#pragma once

#include <graphfrac/mesh.h>
#include <graphfrac/status.h>

#include <optional>
#include <vector>

#include "fracture/cutting.h"
#include "kernels/cut_polytope.h"

namespace gf::detail {

/// A blade at rest in the body's rest frame: world = pose.rotation * local + pose.translation.
struct XfemBlade {
  Blade blade;
  BladePose pose;
  std::optional<BladePose> to =
      std::nullopt;  ///< End pose of a sweep from `pose`; unset: a static blade.
};

/// The cut surface of a blade in the body's frame (identity pose): the blade at its pose, or the
/// surface it sweeps (see the design note). Fails, naming the field, on a triangle index out of
/// range or a non-finite vertex.
Result<Blade> bladeSurface(const XfemBlade& blade);

/// Distance, relative to a node's shortest edge, below which the node counts as on a cut
/// (blade or plane): far above the rounding of a distance for coordinates up to 1e3 edges from
/// the origin, far below any volume tolerance (a cut moved onto a node by this changes the
/// volumes of the tets around it by about this fraction at most).
constexpr double kXfemNodeSnap = 1e-12;

/// Per node: kXfemNodeSnap times its shortest edge, plus 64 ulps of its largest coordinate
/// (rounding of a distance for a body far from the origin); 0 for a node in no tet.
std::vector<double> nodeSnapDistances(const TetMesh& mesh);

/// Where a blade crosses one tet.
struct BladeTetCrossing {
  int32_t tet = 0;
  CutPlane plane;         ///< The local cut plane, unit normal along the blade's orientation.
  double deviation = 0;   ///< Largest distance of the blade's pieces in the tet from `plane`.
  double area = 0;        ///< Area of the blade inside the tet.
  int32_t triangles = 0;  ///< Blade triangles that meet the tet.
  bool full = false;      ///< Fully crossed (see the design note); otherwise the blade ends here.
};

/// A blade's path: the tets it crosses, ascending.
struct BladePath {
  std::vector<BladeTetCrossing> crossings;
  int32_t fullCount = 0, partialCount = 0;
  int32_t touched = 0;        ///< Tets the blade meets without crossing.
  int64_t triangleTests = 0;  ///< Moeller tests run (after bounding-box culling).
  double maxDeviation = 0;    ///< Over the fully crossed tets.
};

/// Traces `blade` through `mesh` (positively oriented tets). Fails, naming the field, on a
/// triangle index out of range, a non-finite vertex or a degenerate (zero-area) blade.
Result<BladePath> traceBlade(const TetMesh& mesh, const XfemBlade& blade);

}  // namespace gf::detail
