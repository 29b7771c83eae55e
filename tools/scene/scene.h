// JSON scene files: a world (gravity, colliders, substeps), its bodies (mesh or generator,
// material, boundary conditions, solver settings, fracture, plasticity, fibre field), the cuts
// applied during the run and the run length (dt, frames). This is
// tooling for the CLI, the tests and the demo, not part of the runtime's public API; the format
// is documented in docs/scene_format.md.
#pragma once

#include <graphfrac/defs.h>
#include <graphfrac/status.h>
#include <graphfrac/world.h>

#include <string>
#include <vector>

namespace gf::scene {

/// One body of a scene: the name it is reported and written under, and its definition.
struct SceneBody {
  std::string name;  ///< Unique in the scene; letters, digits, '_', '-' and '.' only.
  BodyDef def;       ///< Mesh already generated/loaded and translated; pins and grips resolved.
};

/// A blade applied to one body before a given frame is stepped (World::cut).
struct SceneCut {
  int frame = 1;         ///< Applied before stepping this frame; 1 = before the first step.
  std::string body;      ///< Name of the body it cuts.
  size_t bodyIndex = 0;  ///< Index of that body in Scene::bodies.
  Blade blade;           ///< Triangles in the blade's frame and its start and end poses.
};

/// A loaded scene. `world.jobs` is null: the caller owns the job system.
struct Scene {
  std::string name;         ///< "name" of the file, or the file's stem when absent.
  std::string description;  ///< Free text, optional.
  std::string source;       ///< The path the scene was loaded from (or the source label).
  WorldDef world;
  std::vector<SceneBody> bodies;
  std::vector<SceneCut> cuts;  ///< Sorted by frame; file order within a frame.
  double dt = 1.0 / 60;        ///< Time per frame [s]; World::step(dt) is called once per frame.
  int frames = 120;            ///< Frames to run.
  int threads = 1;             ///< Worker threads; 0 = hardware concurrency.
};

/// Reads, parses and checks a scene file. Relative mesh paths resolve against the directory of
/// `path`. Errors read `<path>: <json path>: <reason>` (or `<path>:<line>:<column>: ...` for a
/// JSON syntax error); nothing throws.
Result<Scene> loadScene(const std::string& path);

/// Parses scene text. `source` labels error messages; `baseDir` resolves relative mesh paths
/// (empty = the current directory).
Result<Scene> parseScene(const std::string& text, const std::string& source,
                         const std::string& baseDir);

}  // namespace gf::scene
