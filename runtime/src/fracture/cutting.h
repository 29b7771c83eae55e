// Cutting (SPEC §2): a blade, a triangle mesh moved rigidly over one step,
// breaks every unbroken edge whose CURRENT segment crosses the surface it sweeps.
//
// Design: the swept surface is approximated by triangles: the blade at the end pose, at the
// start pose and, when the poses differ, for every blade edge the quad between its start and
// end positions split into two triangles. Vertices move on straight lines, so the quad
// approximates the bilinear patch (and a rotating blade's arc) by its two triangles; a blade
// that moves less than an edge length per step, or along its own plane, is covered exactly.
// A segment crosses a triangle when its endpoints lie strictly on different sides of the
// triangle's plane, with a node ON the plane counted on the front side (n = (p1-p0)x(p2-p0)),
// and the crossing point lies inside the triangle up to a relative tolerance. So an edge that
// only touches the blade at one endpoint breaks only when its other endpoint is behind: with
// a consistently oriented blade every node is on exactly one side and the cut separates
// the body cleanly, never isolating a node that merely touches the blade.
// Acceleration: a uniform grid over the triangles (a triangle goes into the cells its plane
// crosses inside its bounding box) restricted to where the blade and the body overlap; edges
// outside are culled by their bounding box. Parallel over edges with per-edge outputs, then
// a serial pass in edge order emits the events, so results never depend on the thread count.
#pragma once

#include <cstdint>
#include <vector>

#include "fracture/fracture_model.h"
#include "graphfrac/jobs.h"
#include "graphfrac/status.h"
#include "kernels/math.h"
#include "mesh/edge_graph.h"

namespace gf::detail {

/// Pose of a blade: world = rotation * local + translation (any invertible linear part
/// works; a rotation keeps the blade rigid).
struct BladePose {
  Mat3 rotation = Mat3::identity();
  Vec3 translation;
};

/// A blade as a triangle mesh in its own frame.
struct Blade {
  std::vector<double> vertices;    ///< 3 per vertex.
  std::vector<int32_t> triangles;  ///< 3 vertex indices per triangle.
};

/// Scratch of cutEdges, reused across calls.
struct CutWorkspace {
  /// A world-space triangle of the swept surface with its unnormalised normal.
  struct Triangle {
    Vec3 p0, p1, p2, n;
    double nn = 0;  ///< |n|^2
  };
  std::vector<Triangle> triangles;
  std::vector<int32_t> cellStart, cellTriangles;
  std::vector<double> hitSplit;  ///< Per edge: crossing parameter, < 0 when none.
  std::vector<int32_t> hitTriangle;
  std::vector<int32_t> bladeEdges;
};

/// Figures of the last cut, for benchmarks and tests.
struct CutStats {
  int32_t triangles = 0;      ///< Swept-surface triangles tested (non-degenerate).
  int32_t cells = 0;          ///< Grid cells.
  int32_t edgesInRange = 0;   ///< Edges whose box overlapped the blade's box.
  int64_t triangleTests = 0;  ///< Segment-triangle tests run.
};

/// Segment (a, b) against one triangle (see the design note for the side rule). On a hit,
/// `s` is the crossing parameter from a. `tolerance` is relative to the triangle's size.
bool segmentCrossesTriangle(const Vec3& a, const Vec3& b, const CutWorkspace::Triangle& tri,
                            double& s, double tolerance = 1e-9);

/// Breaks every unbroken edge of `graph` whose segment in `positions` (3 per node) crosses
/// the surface swept by `blade` from `start` to `end` (equal poses: a static cut). Sets the
/// flags, appends events (tet -1, stress 0, split and world position of the crossing nearest
/// the edge's first node) sorted by edge id and returns how many edges broke. Fails, naming
/// the field, on a triangle index out of range or a non-finite blade vertex.
Result<int32_t> cutEdges(const EdgeGraph& graph, const double* positions, const Blade& blade,
                         const BladePose& start, const BladePose& end, std::vector<uint8_t>& broken,
                         std::vector<EdgeBreak>& events, CutWorkspace& ws, JobSystem& jobs,
                         CutStats* stats = nullptr);

}  // namespace gf::detail
