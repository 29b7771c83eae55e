// Field output for ParaView: one VTK XML UnstructuredGrid file (.vtu, ASCII) per body and
// frame holding the tet mesh at its current positions with per-node fields, and a ParaView
// collection (.pvd) that ties those files to simulated times, one part per body. ASCII keeps
// the files readable and diffable; the runs these are for are small enough.
#pragma once

#include <graphfrac/status.h>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace gf::cli {

/// One body's state at one frame; every span has one entry (or 3 for vectors) per node.
struct VtuFrame {
  std::span<const double> positions;  ///< Current x, 3 per node: the points.
  std::span<const double> rest;       ///< Rest X, 3 per node: displacement = x - X.
  std::span<const double> velocities;
  std::span<const int32_t> tets;      ///< 4 node indices per tet.
  std::span<const double> strain;     ///< World::nodeStrain.
  std::span<const double> damage;     ///< nodeDamage.
  std::span<const int32_t> fragment;  ///< World::nodeFragments; empty = 0 everywhere.
};

/// Per node, the fraction of its fracture-graph edges that are broken (0 for a node with no
/// edge): edges holds 2 node ids per edge (World::edges), broken one flag per edge
/// (World::brokenEdges). All zeros when both are empty (a body without fracture).
std::vector<double> nodeDamage(size_t nodeCount, std::span<const int32_t> edges,
                               std::span<const uint8_t> broken);

/// Writes `frame` as a .vtu file with point data displacement, velocity (3 components),
/// strain, damage (Float64) and fragment (Int32). Fails, naming the file, on spans whose sizes
/// disagree or a write error.
Result<void> writeVtu(const std::string& path, const VtuFrame& frame);

/// Collects the files of a run and writes the .pvd collection that lists them.
class PvdWriter {
 public:
  /// Adds a file (relative to the .pvd's directory) of body `part` at time `time` [s].
  void add(double time, int part, const std::string& file);
  /// Writes the collection (all files added so far).
  Result<void> write(const std::string& path) const;

 private:
  struct Entry {
    double time;
    int part;
    std::string file;
  };
  std::vector<Entry> m_entries;
};

}  // namespace gf::cli
