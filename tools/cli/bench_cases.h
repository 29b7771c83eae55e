// The bodies `graphfrac bench multigrid` and `graphfrac bench scenes` time, as scene text: one
// list so both modes measure the same scenes.
#pragma once

#include <span>
#include <string>

namespace gf::cli {

struct BenchCase {
  const char* name;
  const char* thesisFps;  // RTX 2060, thesis table 6.2; null for a body the thesis did not run
  const char* fracture;   // the "fracture" object when fracture is on
  bool multigridBreaks;   // `bench multigrid` runs it with fracture on
  bool big;               // seconds a frame on a small CPU: `bench scenes` runs --big-frames
  const char* scene;      // SOLVER and FRACTURE are replaced by benchSceneText
};

/// The chapter-6 bodies of thesis table 6.2 at our resolution: the hinged beam (fig 6.6, 4k
/// tets), the notched Charpy bar (fig 6.9, 28k), the hanging sphere (fig 6.7, 35k) and a
/// 160k-tet sphere in place of the armadillo (fig 6.4); then a 98 x 34 x 34-cell cantilever box
/// of 679,728 tets (the size of the largest body of Xian et al.), the only `big` one.
std::span<const BenchCase> benchCases();

/// The case's scene with `solver` (a JSON object) as the body's solver and, when `fracture`,
/// the case's fracture object.
std::string benchSceneText(const BenchCase& c, const std::string& solver, bool fracture);

/// Empty when `name` is a case's name (a big one only when `withBig`), else an error that lists
/// the names, for a mode's --only.
std::string unknownBenchCase(const std::string& name, bool withBig);

}  // namespace gf::cli
