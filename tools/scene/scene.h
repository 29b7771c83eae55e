// JSON scene files: a world (gravity, colliders, substeps), its bodies (mesh or generator,
// material, boundary conditions, solver settings, fracture, plasticity, fibre field, Bullet
// hand-off, render colours), the Bullet rigid bodies, the cuts applied during the run, a camera
// and the run length (dt, frames). This is tooling for the CLI, the tests and the demo, not
// part of the runtime's public API; the format is documented in docs/scene_format.md. Plain
// data, plus addBody, which puts a body into a World with the initial state BodyDef cannot
// hold (spin, deformed shape); tools/scene/bullet_scene.h turns the rigid bodies into Bullet
// objects.
#pragma once

#include <graphfrac/defs.h>
#include <graphfrac/status.h>
#include <graphfrac/world.h>

#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>
#include <optional>
#include <string>
#include <vector>

namespace gf::scene {

/// Which fragments of a body go to Bullet once it splits (gf::bullet::HandoffPolicy).
struct SceneHandoff {
  enum class Policy : uint8_t { Never, Every, BelowVolume };
  Policy policy = Policy::Never;
  double maxVolume = 0;  ///< [m^3], BelowVolume only.
};

/// One body of a scene: the name it is reported and written under, and its definition.
struct SceneBody {
  std::string name;  ///< Unique in the scene; letters, digits, '_', '-' and '.' only.
  BodyDef def;       ///< Mesh already generated/loaded and translated; pins and grips resolved.
  SceneHandoff handoff;
  glm::vec3 colour{0.8f};                     ///< Linear RGB of the surface (a palette default).
  glm::vec3 crackColour{0.95f, 0.55f, 0.3f};  ///< Linear RGB of crack faces.
  /// How crack faces are drawn: "plain", "glass", "crumb" or "steel" (roughness, grain).
  std::string interior = "plain";
  /// Image file drawn on the render mesh by its UVs ("render_mesh": {"texture": ...}), resolved
  /// against the scene's folder; empty for none. Checked at load; decoded by the demo.
  std::string texture;
  /// The render mesh's materials, indexed by RenderMesh::materials, when its asset names two or
  /// more and "render_mesh" gives no "texture" (docs/scene_format.md): each drawn in its own
  /// colour and texture (resolved, checked at load) instead of `colour` and `texture`.
  struct Material {
    std::string name;
    glm::vec3 colour{1.0f};  ///< Linear RGB.
    std::string texture;     ///< Image file, resolved; empty for none.
  };
  std::vector<Material> materials;
  /// The JSON entry of each def.grips, in order ("pins[0]", "grips[1]"): pins and grips
  /// share BodyDef::grips, and an entry whose nodes were all held already makes none.
  std::vector<std::string> gripNames;
  /// Initial spin [rad/s] about the centre of mass, added to def.initialVelocity by addBody.
  glm::dvec3 angularVelocity{0};
  /// Initial shape: x = c + F (X - c) about the rest centroid c, applied by addBody (identity:
  /// the rest shape). det F > 0.
  glm::dmat3 initialDeformation{1.0};
};

/// A Bullet rigid body of the scene (tools/scene/bullet_scene.h builds it).
struct SceneRigidBody {
  enum class Shape : uint8_t { Sphere, Box, Plane, Capsule };
  std::string name;  ///< Unique among the rigid bodies; "rigid<i>" by default.
  Shape shape = Shape::Sphere;
  double radius = 0;                   ///< Sphere, Capsule [m].
  double halfLength = 0;               ///< Capsule: half its segment, along its own y [m].
  glm::dvec3 halfExtents{0};           ///< Box, along its own axes [m] (half the "size").
  glm::dvec3 normal{0, 1, 0};          ///< Plane: unit normal; the plane is normal . x = offset.
  double offset = 0;                   ///< Plane [m].
  double renderSize = 4;               ///< Plane: side of the square drawn for it [m].
  double mass = 0;                     ///< [kg]; 0 = static (a plane always is).
  glm::dvec3 position{0};              ///< Centre [m] (sphere, box).
  glm::dquat orientation{1, 0, 0, 0};  ///< Body-to-world rotation, unit (box, sphere).
  glm::dvec3 velocity{0};              ///< [m/s], dynamic bodies only.
  glm::dvec3 angularVelocity{0};       ///< [rad/s], dynamic bodies only.
  double friction = 0.5;               ///< Bullet's defaults.
  double rollingFriction = 0;
  double restitution = 0;
  bool touchesBodies = true;  ///< Two-way contact with the deformable bodies (Bridge::addCollider).
  glm::vec3 colour{0.6f};     ///< Linear RGB.
};

/// Where the demo looks from.
struct SceneCamera {
  glm::dvec3 eye{1.5, 1.0, 1.5};
  glm::dvec3 target{0, 0.2, 0};
  glm::dvec3 up{0, 1, 0};
  double fovDegrees = 45;  ///< Vertical field of view.
  /// Follow the bodies' bounds (eye - target keeps its direction; target and distance move).
  bool follow = false;
  double smoothSeconds = 0.4;  ///< Follow: time constant of the critically damped smoothing.
  double maxTurnDegrees = 1;   ///< Follow: largest swing of the line of sight per frame.
};

/// A blade applied to one body before a given frame is stepped (World::cut).
struct SceneCut {
  int frame = 1;         ///< Applied before stepping this frame; 1 = before the first step.
  std::string body;      ///< Name of the body it cuts.
  size_t bodyIndex = 0;  ///< Index of that body in Scene::bodies.
  Blade blade;           ///< Triangles in the blade's frame and its start and end poses.
};

/// A sculpting stroke (thesis ch. 7): a sphere tool whose centre moves linearly from `from`
/// (at the start of frame fromFrame's step) to `to` (at the end of frame toFrame's step).
/// Push: the sphere is a collider pressed into the body plus World::deform at its centre every
/// step, so the body gives way around it and a plastic body keeps the dent. Wet / dry:
/// World::wet / dry at the centre every step. tools/scene/strokes.h plays them.
struct SceneStroke {
  enum class Type : uint8_t { Push, Wet, Dry, Pull, Cut };
  Type type = Type::Push;
  std::string body;           ///< Name of the body it sculpts.
  size_t bodyIndex = 0;       ///< Index of that body in Scene::bodies.
  int fromFrame = 1;          ///< First frame of the stroke (>= 1).
  int toFrame = 1;            ///< Last frame (>= fromFrame).
  glm::dvec3 from{0}, to{0};  ///< Tool centre's path [m], world frame.
  double radius = 0.05;       ///< Tool sphere [m].
  double influence = 0.05;    ///< Push / pull: R_D of eq 7.7 [m] (DeformBrush::radius).
  double k1 = 10, k2 = 10;    ///< Push / pull: eq 7.7's constants [1/m] (DeformBrush).
  double rate = 1;            ///< Wet / dry: saturation per second (WetBrush::rate).
  /// Pull: nodes within radius + grab of the tool's centre at the stroke's start stick to it.
  double grab = 0.005;
  double stiffness = 1e6;  ///< Pull: PullBrush::stiffness [1/s^2]; cut: the penalty [N/m].
  /// Cut: the brush is a square of side `size` in the plane through the path with this unit
  /// normal (across the path), its leading edge centred on the path.
  glm::dvec3 normal{0, 1, 0};
  double size = 0.05;
  double threshold = 20;  ///< Cut: CutBrushSettings::threshold [N].
};

/// A loaded scene. `world.jobs` is null: the caller owns the job system.
struct Scene {
  std::string name;         ///< "name" of the file, or the file's stem when absent.
  std::string description;  ///< Free text, optional.
  std::string source;       ///< The path the scene was loaded from (or the source label).
  WorldDef world;
  std::vector<SceneBody> bodies;
  std::vector<SceneCut> cuts;  ///< Sorted by frame; file order within a frame.
  /// File order; their frame ranges do not overlap (one tool at a time).
  std::vector<SceneStroke> strokes;
  std::vector<SceneRigidBody> rigidBodies;  ///< Bullet rigid bodies, file order.
  std::optional<SceneCamera> camera;        ///< Absent: the demo frames the bodies itself.
  double dt = 1.0 / 60;  ///< Time per frame [s]; World::step(dt) is called once per frame.
  int frames = 120;      ///< Frames to run.
  int threads = 1;       ///< Worker threads; 0 = hardware concurrency.
};

/// A unit vector perpendicular to the unit vector `unit` (the runtime kernels' choice, so a
/// plane blade's square and a plane collider's drawn square turn the same way everywhere).
glm::dvec3 anyPerpendicular(const glm::dvec3& unit);

/// Creates a scene body in `world` and gives it the scene's initial state beyond BodyDef: the
/// initial deformation (World::setPositions) and the spin about the centre of mass
/// (World::setVelocities, v = v0 + w x (x - c)). Every runner of scenes (graphfrac run,
/// BulletScene) creates bodies through this. On error the world is left without the body.
Result<BodyId> addBody(World& world, const SceneBody& body);

/// True when the scene needs Bullet to run as written: it has rigid bodies or a body whose
/// hand-off policy is not "never". A runner without Bullet must refuse such a scene rather
/// than run it without them.
bool needsBullet(const Scene& scene);

/// Reads, parses and checks a scene file. Relative mesh paths resolve against the directory of
/// `path`. Errors read `<path>: <json path>: <reason>` (or `<path>:<line>:<column>: ...` for a
/// JSON syntax error); nothing throws.
Result<Scene> loadScene(const std::string& path);

/// Parses scene text. `source` labels error messages; `baseDir` resolves relative mesh paths
/// (empty = the current directory).
Result<Scene> parseScene(const std::string& text, const std::string& source,
                         const std::string& baseDir);

}  // namespace gf::scene
