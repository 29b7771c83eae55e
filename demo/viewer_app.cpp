// graphfrac-viewer (viewer_app.h). Every input, from GLFW or from a --script line, goes through
// the same Viewer::on* handlers, so what CI scripts is what a user does. The simulation runs on
// a clock: the wall clock interactively, a fixed one frame = one scene dt with --script or
// --frames, so scripted runs step the same frames every time and screenshots compare.
#include "viewer_app.h"

#include <btBulletDynamicsCommon.h>
#include <graphfrac/bullet/bridge.h>

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <imgui.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <memory>
#include <numbers>
#include <sstream>

#include "cli/args.h"
#include "demo_app.h"
#include "scene/bullet_scene.h"
#include "scene_drawing.h"
#include "viewer_panel.h"

namespace gf::demo {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr const char* kUsage =
    "usage: graphfrac-viewer SCENE [options]\n"
    "\n"
    "Opens a window on a JSON scene (docs/scene_format.md) running with its Bullet rigid bodies.\n"
    "\n"
    "mouse: left-drag a body to pull it (a spring through World::applyForce); right-drag to\n"
    "       orbit; wheel to zoom; middle-drag (or X + left-drag) to draw a blade that cuts\n"
    "       every body it crosses when released\n"
    "keys:  space pause, S single step, R reset, 1-4 slow motion (1x, 2x, 4x, 8x slower),\n"
    "       O overlay, C strain colours, H panel, B throw a ball, arrows orbit, Esc quit\n"
    "\n"
    "options:\n"
    "  --script FILE              scripted input, one command a line: frame N drag X Y X2 Y2\n"
    "                             [FRAMES], frame N cut X1 Y1 X2 Y2, frame N key K, frame N\n"
    "                             screenshot PATH (the renderer's picture), frame N window\n"
    "                             PATH (the window as presented, panel included), frame N\n"
    "                             panel PATH (the panel's text), frame N scene NAME|PATH,\n"
    "                             frame N quit (pixels of the picture)\n"
    "  --frames N                 exit after N frames\n"
    "  --size WxH                 window size (default 960x540)\n"
    "  --renderer auto|vulkan|gl  back end of the off-screen renderer (default auto)\n"
    "  --present auto|vulkan|gl   how the window shows the picture: a Vulkan swapchain, or\n"
    "                             OpenGL; auto takes Vulkan where a device presents to the\n"
    "                             window, else GL (the summary says which and why)\n"
    "  --validation               Vulkan validation layers on; exit 1 if they report anything\n"
    "  --strain MAX               the strain shown red by the colour map (default 0.05)\n"
    "  -h, --help                 this text\n"
    "\n"
    "exit codes: 0 ok, 1 failure, 2 usage, 77 no display\n";

std::string parseArgs(int argc, char** argv, ViewerOptions& o, bool& help) {
  cli::ArgParser a(argc, argv);
  while (a.next()) {
    const std::string& arg = a.name();
    if (arg == "-h" || arg == "--help") {
      help = true;
    } else if (arg == "--validation") {
      o.validation = true;
    } else if (arg == "--script") {
      if (!a.nonEmptyValue(o.script)) return "--script needs a file";
    } else if (arg == "--frames") {
      int n = 0;
      if (!a.intValue(1, 100'000'000, n)) return "--frames needs an integer >= 1";
      o.frames = n;
    } else if (arg == "--size") {
      std::string value;
      const size_t x = a.value(value) ? value.find('x') : std::string::npos;
      if (x == std::string::npos ||
          !cli::parseInt(std::string_view(value).substr(0, x), 16, 8192, o.width) ||
          !cli::parseInt(std::string_view(value).substr(x + 1), 16, 8192, o.height))
        return "--size needs WxH with 16 <= W, H <= 8192 (e.g. 960x540)";
    } else if (arg == "--strain") {
      if (!a.positiveValue(o.strainMax)) return "--strain needs a number > 0 (e.g. 0.05)";
    } else if (arg == "--renderer") {
      std::string value;
      if (!a.value(value) || !parseRendererKind(value, o.renderer))
        return "--renderer needs auto, vulkan or gl";
    } else if (arg == "--present") {
      std::string value;
      if (!a.value(value) || !parsePresentKind(value, o.present))
        return "--present needs auto, vulkan or gl";
    } else if (a.isOption()) {
      return "unknown option '" + arg + "'";
    } else if (o.scene.empty()) {
      o.scene = arg;
    } else {
      return "more than one scene given ('" + o.scene + "' and '" + arg + "')";
    }
  }
  if (!help && o.scene.empty()) return "no scene given";
  return {};
}

/// Orbit camera: the eye on a sphere about the target, so dragging never rolls the picture.
struct Orbit {
  glm::dvec3 target{0};
  double distance = 1, yaw = 0, pitch = 0;
  float fov = 45, nearShare = 0.02f, farPlane = 50;

  static Orbit from(const Camera& c) {
    Orbit o;
    o.target = glm::dvec3(c.target);
    const glm::dvec3 back = glm::dvec3(c.eye) - o.target;
    o.distance = std::max(glm::length(back), 1e-3);
    o.yaw = std::atan2(back.x, back.z);
    o.pitch = std::asin(std::clamp(back.y / o.distance, -1.0, 1.0));
    o.fov = c.fovYDegrees;
    o.nearShare = c.nearPlane / float(o.distance);
    o.farPlane = c.farPlane;
    return o;
  }
  Camera camera() const {
    Camera c;
    const glm::dvec3 back(std::cos(pitch) * std::sin(yaw), std::sin(pitch),
                          std::cos(pitch) * std::cos(yaw));
    c.target = glm::vec3(target);
    c.eye = glm::vec3(target + distance * back);
    c.fovYDegrees = fov;
    // The far plane must keep what the scene camera saw once zoomed out.
    c.nearPlane = std::max(nearShare * float(distance), 1e-4f);
    c.farPlane = std::max(farPlane, float(4 * distance));
    return c;
  }
  void turn(double dYaw, double dPitch) {
    yaw += dYaw;
    pitch = std::clamp(pitch + dPitch, -1.5, 1.5);  // short of the poles, where up flips
  }
};

/// A thrown ball: a Bullet rigid sphere registered with the bridge, so it pushes the bodies
/// and they push back.
struct Ball {
  std::unique_ptr<btSphereShape> shape;
  std::unique_ptr<btRigidBody> body;
  ShapeMesh mesh;
};

class Viewer {
 public:
  explicit Viewer(const ViewerOptions& opt)
      : m_opt(opt),
        m_width(opt.width),
        m_height(opt.height),
        m_cursorX(0.5 * opt.width),
        m_cursorY(0.5 * opt.height) {}
  ~Viewer() { unload(); }

  /// Loads a scene and a fresh renderer (its slots belong to the scene it drew).
  Result<void> load(const std::string& path);
  /// The renderer that load() creates, before any scene (the window's context depends on it).
  Result<void> createRenderer();

  // Input, from GLFW and from the script alike. Coordinates are picture pixels.
  void onKey(int key);
  void onMouseButton(int button, bool pressed, double x, double y);
  void onMouseMove(double x, double y);
  void onScroll(double dy);
  bool xHeld = false;  ///< X + left button draws a blade, for mice without a middle button.

  /// Steps the scene for `wallSeconds` of the clock, or one scene dt without (the fixed
  /// clock of scripted runs), slowed down, or not at all when paused.
  Result<void> advance(std::optional<double> wallSeconds);
  Result<void> render();
  void panel();
  bool panelShown() const { return m_panelShown; }
  /// What the panel shows now (viewer_panel.h).
  PanelFigures figures() const;

  const Image& image() const { return m_image; }
  bool hasScene() const { return m_sim != nullptr; }
  /// Validation messages of this and of the renderers of earlier scenes.
  std::vector<std::string> validationMessages() const {
    std::vector<std::string> all = m_oldMessages;
    if (m_renderer)
      for (std::string& m : m_renderer->validationMessages()) all.push_back(std::move(m));
    return all;
  }
  bool usesGlRenderer() const { return m_renderer->description().rfind("OpenGL", 0) == 0; }
  std::string summary() const;
  /// A scene picked in the panel or by a script, loaded between frames.
  std::optional<std::string> pendingScene;
  /// Picks a scene as the panel's list does: `name` through resolveScene over that list.
  void pickScene(const std::string& name) { pendingScene = resolveScene(name, m_sceneFiles); }
  bool quit = false;

 private:
  void unload();
  void pick(double x, double y);
  void cutStroke();
  void throwBall();
  Result<void> stepOnce();

  ViewerOptions m_opt;
  int m_width, m_height;
  std::string m_scenePath;
  std::vector<std::string> m_sceneFiles;
  /// Why the last scene picked did not load (the running one is the one before); empty after a
  /// load that worked. Shown in the panel and the overlay until the next load.
  std::string m_loadError;
  scene::Scene m_scene;
  std::unique_ptr<scene::BulletScene> m_sim;
  std::unique_ptr<SceneDrawing> m_drawing;
  std::unique_ptr<Renderer> m_renderer;
  std::vector<std::string> m_oldMessages;
  std::vector<Ball> m_balls;
  std::vector<MeshFrame> m_meshes;
  Image m_image;
  Orbit m_orbit;

  // Clock and controls.
  bool m_paused = false, m_stepOnce = false, m_overlay = true, m_strain = false;
  bool m_panelShown = true;
  int m_slowPower = 0;  ///< Slow motion 2^power.
  double m_clock = 0;   ///< Clock time not yet stepped [s].
  StepStatus m_lastStatus;
  double m_simMs = 0;

  // Gestures.
  struct Drag {
    size_t body = 0;
    int32_t node = 0;
    glm::dvec3 planePoint{0}, planeNormal{0};
    double mass = 0;
  };
  std::optional<Drag> m_drag;
  std::optional<size_t> m_picked;  ///< Body whose material the panel shows.
  bool m_orbiting = false, m_stroking = false;
  // The cursor starts mid-picture, where a ball thrown before any mouse motion goes.
  double m_cursorX, m_cursorY, m_strokeX = 0, m_strokeY = 0;

  // Counts for the summary.
  int m_steps = 0, m_cuts = 0, m_drags = 0, m_thrown = 0;
};

Result<void> Viewer::createRenderer() {
  RendererOptions ro;
  ro.kind = m_opt.renderer;
  ro.width = m_width;
  ro.height = m_height;
  ro.validation = m_opt.validation;
  Result<std::unique_ptr<Renderer>> r = demo::createRenderer(ro);
  if (!r) return fail("graphfrac-viewer: ", r.error().message);
  m_renderer = std::move(r).value();
  return {};
}

void Viewer::unload() {
  // The balls are ours: out of the bridge and Bullet before the scene that holds them goes.
  for (Ball& b : m_balls) {
    (void)m_sim->bridge().removeCollider(b.body.get());
    m_sim->dynamics().removeRigidBody(b.body.get());
  }
  m_balls.clear();
  m_drag.reset();
  m_picked.reset();
  m_drawing.reset();
  m_sim.reset();
}

Result<void> Viewer::load(const std::string& path) {
  // Everything that can fail about the scene happens before the running one is touched.
  Result<scene::Scene> loaded = scene::loadScene(path);
  if (!loaded) {
    m_loadError = loaded.error().message;
    return loaded.error();
  }
  Result<std::unique_ptr<scene::BulletScene>> sim = scene::BulletScene::create(loaded.value());
  if (!sim) {
    m_loadError = sim.error().message;
    return sim.error();
  }
  auto drawing = std::make_unique<SceneDrawing>(loaded.value());
  if (Result<void> r = drawing->loadTextures(loaded.value()); !r) {
    m_loadError = path + ": " + r.error().message;
    return fail(m_loadError);
  }
  m_loadError.clear();
  // A renderer keeps its buffers per slot, and a new scene's slot i is another mesh whose
  // topology version may well equal the old one's: so a new renderer, not stale buffers.
  const bool reload = m_sim != nullptr;
  unload();
  if (reload) {
    for (std::string& m : m_renderer->validationMessages()) m_oldMessages.push_back(std::move(m));
    m_renderer.reset();
    if (Result<void> r = createRenderer(); !r) return r;
  }
  m_scene = std::move(loaded).value();
  m_sim = std::move(sim).value();
  m_drawing = std::move(drawing);
  if (path != m_scenePath) m_sceneFiles = siblingScenes(path);
  m_scenePath = path;
  m_orbit = Orbit::from(sceneCamera(m_scene));
  m_clock = 0;
  m_lastStatus = {};
  m_simMs = 0;
  return {};
}

void Viewer::onKey(int key) {
  switch (key) {
    case GLFW_KEY_SPACE:
      m_paused = !m_paused;
      break;
    case GLFW_KEY_S:
      m_paused = true;
      m_stepOnce = true;
      break;
    case GLFW_KEY_R:
      pendingScene = m_scenePath;
      break;
    case GLFW_KEY_1:
    case GLFW_KEY_2:
    case GLFW_KEY_3:
    case GLFW_KEY_4:
      m_slowPower = key - GLFW_KEY_1;
      break;
    case GLFW_KEY_O:
      m_overlay = !m_overlay;
      break;
    case GLFW_KEY_C:
      m_strain = !m_strain;
      break;
    case GLFW_KEY_H:
      m_panelShown = !m_panelShown;
      break;
    case GLFW_KEY_B:
      throwBall();
      break;
    case GLFW_KEY_LEFT:
      m_orbit.turn(-0.1, 0);
      break;
    case GLFW_KEY_RIGHT:
      m_orbit.turn(0.1, 0);
      break;
    case GLFW_KEY_UP:
      m_orbit.turn(0, 0.1);
      break;
    case GLFW_KEY_DOWN:
      m_orbit.turn(0, -0.1);
      break;
    case GLFW_KEY_ESCAPE:
      quit = true;
      break;
    default:
      break;
  }
}

void Viewer::onMouseButton(int button, bool pressed, double x, double y) {
  m_cursorX = x;
  m_cursorY = y;
  const bool blade =
      button == GLFW_MOUSE_BUTTON_MIDDLE || (button == GLFW_MOUSE_BUTTON_LEFT && xHeld);
  if (blade) {
    if (pressed) {
      m_stroking = true;
      m_strokeX = x;
      m_strokeY = y;
    } else if (m_stroking) {
      m_stroking = false;
      cutStroke();
    }
  } else if (button == GLFW_MOUSE_BUTTON_LEFT) {
    if (pressed)
      pick(x, y);
    else
      m_drag.reset();
  } else if (button == GLFW_MOUSE_BUTTON_RIGHT) {
    m_orbiting = pressed;
  }
}

void Viewer::onMouseMove(double x, double y) {
  if (m_orbiting) m_orbit.turn(-0.008 * (x - m_cursorX), 0.008 * (y - m_cursorY));
  m_cursorX = x;
  m_cursorY = y;
}

void Viewer::onScroll(double dy) { m_orbit.distance *= std::pow(0.9, dy); }

// The nearest surface triangle the cursor's ray hits (Moller-Trumbore), then the vertex of it
// nearest the hit: its node is what the spring pulls, which stays the same node when a
// fracture renumbers the surface.
void Viewer::pick(double x, double y) {
  const Camera cam = m_orbit.camera();
  const Ray ray = cameraRay(cam, m_width, m_height, x, y);
  double best = 1e300;
  World& world = m_sim->world();
  for (size_t b = 0; b < m_sim->bodyCount(); ++b) {
    const SurfaceView v = world.surface(m_sim->body(b));
    for (size_t t = 0; t + 2 < v.indices.size(); t += 3) {
      glm::dvec3 p[3];
      for (int k = 0; k < 3; ++k) {
        const size_t i = 3 * size_t(v.indices[t + size_t(k)]);
        p[k] = {v.positions[i], v.positions[i + 1], v.positions[i + 2]};
      }
      const glm::dvec3 e1 = p[1] - p[0], e2 = p[2] - p[0];
      const glm::dvec3 h = glm::cross(ray.direction, e2);
      const double det = glm::dot(e1, h);
      if (std::abs(det) < 1e-14) continue;
      const glm::dvec3 s = ray.origin - p[0];
      const double u = glm::dot(s, h) / det;
      const glm::dvec3 q = glm::cross(s, e1);
      const double w = glm::dot(ray.direction, q) / det;
      const double dist = glm::dot(e2, q) / det;
      if (u < 0 || w < 0 || u + w > 1 || dist <= 0 || dist >= best) continue;
      best = dist;
      const glm::dvec3 hit = ray.origin + dist * ray.direction;
      int nearest = 0;
      for (int k = 1; k < 3; ++k)
        if (glm::length(p[k] - hit) < glm::length(p[nearest] - hit)) nearest = k;
      Drag d;
      d.body = b;
      d.node = v.vertexNode[v.indices[t + size_t(nearest)]];
      d.planePoint = hit;
      d.planeNormal = glm::normalize(glm::dvec3(cam.eye) - glm::dvec3(cam.target));
      d.mass = world.stats(m_sim->body(b)).mass;
      m_drag = d;
    }
  }
  if (m_drag) {
    m_picked = m_drag->body;
    ++m_drags;
  }
}

void Viewer::cutStroke() {
  if (std::hypot(m_cursorX - m_strokeX, m_cursorY - m_strokeY) < 2) return;  // a click
  const StrokeBlade s =
      strokeBlade(m_orbit.camera(), m_width, m_height, m_strokeX, m_strokeY, m_cursorX, m_cursorY);
  Blade blade;
  blade.vertices = s.vertices;
  blade.triangles = s.triangles;
  World& world = m_sim->world();
  for (size_t b = 0; b < m_sim->bodyCount(); ++b) {
    // Bodies without fracture cannot be cut; the blade passes through them.
    if (world.fractureStats(m_sim->body(b)).edgeCount == 0) continue;
    if (world.cut(m_sim->body(b), blade)) ++m_cuts;
  }
}

void Viewer::throwBall() {
  const Camera cam = m_orbit.camera();
  const Ray ray = cameraRay(cam, m_width, m_height, m_cursorX, m_cursorY);
  // Sized and thrown relative to the view, so it reads the same on a 10 cm and a 2 m scene;
  // dense, because a rigid body much lighter than the nodes it hits bounces off too hard
  // (integration/bullet/bridge.h).
  const double radius = 0.05 * m_orbit.distance, speed = 3.0 * m_orbit.distance + 2.0;
  const double mass = 3000 * 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
  const glm::dvec3 start = ray.origin + 4 * radius * ray.direction;
  Ball ball;
  ball.shape = std::make_unique<btSphereShape>(btScalar(radius));
  btVector3 inertia(0, 0, 0);
  ball.shape->calculateLocalInertia(btScalar(mass), inertia);
  btRigidBody::btRigidBodyConstructionInfo ci(btScalar(mass), nullptr, ball.shape.get(), inertia);
  ci.m_startWorldTransform.setIdentity();
  ci.m_startWorldTransform.setOrigin(
      btVector3(btScalar(start.x), btScalar(start.y), btScalar(start.z)));
  ci.m_friction = 0.5f;
  ci.m_restitution = 0.3f;
  ball.body = std::make_unique<btRigidBody>(ci);
  const glm::dvec3 v = speed * ray.direction;
  ball.body->setLinearVelocity(btVector3(btScalar(v.x), btScalar(v.y), btScalar(v.z)));
  m_sim->dynamics().addRigidBody(ball.body.get());
  if (!m_sim->bridge().addCollider(ball.body.get())) {
    m_sim->dynamics().removeRigidBody(ball.body.get());
    return;
  }
  scene::SceneRigidBody shape;
  shape.shape = scene::SceneRigidBody::Shape::Sphere;
  shape.radius = radius;
  ball.mesh = rigidMesh(shape);
  m_balls.push_back(std::move(ball));
  ++m_thrown;
}

Result<void> Viewer::stepOnce() {
  if (m_drag) {
    // A critically damped spring from the node to the cursor's point on the plane through the
    // grab point facing the camera. Mass and damping are those of the node's piece (its share
    // of the body's nodes and their mean velocity), so a piece follows in about 1/omega
    // whatever its size; damping the node's own velocity with the piece's mass would overshoot
    // within one step. World::applyForce acts during the next World step only, one of the
    // frame's substeps, so the force is scaled up to give the frame's impulse.
    World& world = m_sim->world();
    const BodyId id = m_sim->body(m_drag->body);
    const std::span<const double> x = world.positions(id), v = world.velocities(id);
    const std::span<const int32_t> pieces = world.nodeFragments(id);
    const size_t nodes = x.size() / 3, n = size_t(m_drag->node);
    glm::dvec3 mean(0);
    size_t count = 0;
    for (size_t i = 0; i < nodes; ++i) {
      if (!pieces.empty() && pieces[i] != pieces[n]) continue;
      mean += glm::dvec3(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
      ++count;
    }
    mean /= double(std::max<size_t>(count, 1));
    const double mass = m_drag->mass * double(count) / double(std::max<size_t>(nodes, 1));
    const glm::dvec3 p(x[3 * n], x[3 * n + 1], x[3 * n + 2]);
    const Ray ray = cameraRay(m_orbit.camera(), m_width, m_height, m_cursorX, m_cursorY);
    const double denom = glm::dot(ray.direction, m_drag->planeNormal);
    glm::dvec3 target = p;
    if (std::abs(denom) > 1e-9)
      target = ray.origin + glm::dot(m_drag->planePoint - ray.origin, m_drag->planeNormal) / denom *
                                ray.direction;
    constexpr double kOmega = 12;  // [rad/s]
    const double substeps = std::max(m_scene.world.substeps, 1);
    const glm::dvec3 f = substeps * mass * (kOmega * kOmega * (target - p) - 2 * kOmega * mean);
    (void)world.applyForce(id, glm::vec3(p), glm::vec3(f));
  }
  const auto t0 = Clock::now();
  m_lastStatus = m_sim->step();
  m_simMs = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  if (m_lastStatus.has(kStepInvalidInput))
    return fail(m_scene.source, ": frame ", std::to_string(m_sim->frame()), ": ",
                m_lastStatus.message);
  ++m_steps;
  return {};
}

Result<void> Viewer::advance(std::optional<double> wallSeconds) {
  const double seconds = wallSeconds.value_or(m_scene.dt);
  if (m_stepOnce) {
    m_stepOnce = false;
    return stepOnce();
  }
  if (m_paused) return {};
  m_clock += seconds / double(1 << m_slowPower);
  // At most two steps a frame: a slow frame must not make the next one slower still.
  for (int k = 0; k < 2 && m_clock >= m_scene.dt * (1 - 1e-9); ++k) {
    m_clock -= m_scene.dt;
    if (Result<void> r = stepOnce(); !r) return r;
  }
  m_clock = std::min(m_clock, m_scene.dt);
  return {};
}

Result<void> Viewer::render() {
  m_drawing->update(*m_sim, m_strain ? m_opt.strainMax : 0);
  m_meshes.assign(m_drawing->meshes().begin(), m_drawing->meshes().end());
  for (const Ball& b : m_balls) {
    MeshFrame m;
    m.positions = b.mesh.positions;
    m.normals = b.mesh.normals;
    m.indices = b.mesh.indices;
    m.topologyVersion = 1;
    m.dirtyEnd = uint32_t(b.mesh.positions.size() / 3);  // small; a new slot needs it all
    m.colour = {0.85f, 0.2f, 0.15f};
    btScalar mat[16];
    b.body->getWorldTransform().getOpenGLMatrix(mat);
    m.model = glm::make_mat4(mat);
    m_meshes.push_back(m);
  }
  FrameOptions fo;
  fo.shadows = true;
  if (m_overlay) {
    const PanelFigures t = figures();
    char line[160];
    std::snprintf(line, sizeof line, "%s  frame %d  t %.2f s  sim %.0f ms%s", m_scene.name.c_str(),
                  m_sim->frame(), m_sim->frame() * m_scene.dt, m_simMs, m_paused ? "  paused" : "");
    fo.overlay.emplace_back(line);
    std::snprintf(line, sizeof line, "broken edges %lld  fragments %lld",
                  static_cast<long long>(t.brokenEdges), static_cast<long long>(t.fragments));
    fo.overlay.emplace_back(line);
    if (!m_loadError.empty()) fo.overlay.push_back("not loaded: " + m_loadError);
  }
  Result<FrameStats> r = m_renderer->render(m_meshes, m_orbit.camera(), fo, m_image);
  if (!r) return fail("graphfrac-viewer: ", r.error().message);
  return {};
}

void Viewer::panel() {
  ImGui::SetNextWindowPos(ImVec2(8, float(m_height) - 8), ImGuiCond_FirstUseEver, ImVec2(0, 1));
  ImGui::SetNextWindowBgAlpha(0.75f);
  ImGui::Begin("graphfrac", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
  const fs::path current(m_scenePath);
  if (ImGui::BeginCombo("scene", current.filename().string().c_str())) {
    for (const std::string& f : m_sceneFiles) {
      const bool selected = f == m_scenePath;
      if (ImGui::Selectable(fs::path(f).filename().string().c_str(), selected)) pendingScene = f;
    }
    ImGui::EndCombo();
  }
  if (!m_loadError.empty()) {
    ImGui::PushStyleColor(ImGuiCol_Text, ImVec4(1.0f, 0.45f, 0.35f, 1.0f));
    ImGui::TextWrapped("not loaded: %s", m_loadError.c_str());
    ImGui::PopStyleColor();
  }
  if (ImGui::Button(m_paused ? "run" : "pause")) onKey(GLFW_KEY_SPACE);
  ImGui::SameLine();
  if (ImGui::Button("step")) onKey(GLFW_KEY_S);
  ImGui::SameLine();
  if (ImGui::Button("reset")) onKey(GLFW_KEY_R);
  ImGui::SameLine();
  if (ImGui::Button("ball")) onKey(GLFW_KEY_B);
  ImGui::SliderInt("slow 2^n", &m_slowPower, 0, 3);
  ImGui::Checkbox("overlay", &m_overlay);
  ImGui::SameLine();
  ImGui::Checkbox("strain", &m_strain);
  ImGui::Separator();
  const PanelFigures f = figures();
  for (const std::string& line : panelLines(f)) {
    if (line.empty())
      ImGui::Separator();
    else if (line.rfind("step: ", 0) == 0)  // a solver's message can be long
      ImGui::TextWrapped("%s", line.c_str());
    else
      ImGui::TextUnformatted(line.c_str());
  }
  if (!f.picked) ImGui::TextDisabled("left-drag a body to pull it and see its material");
  ImGui::TextDisabled("%s", m_renderer->description().c_str());
  ImGui::End();
}

PanelFigures Viewer::figures() const {
  std::optional<PickedMaterial> picked;
  if (m_picked && *m_picked < m_scene.bodies.size()) {
    const scene::SceneBody& b = m_scene.bodies[*m_picked];
    picked = PickedMaterial{b.name, b.def.material, b.def.fracture};
  }
  return panelFigures(*m_sim, m_scene.dt, m_lastStatus, std::move(picked));
}

std::string Viewer::summary() const {
  if (!m_sim || !m_renderer) return "graphfrac-viewer: no scene running\n";
  const PanelFigures t = figures();
  char text[768];
  std::snprintf(text, sizeof text,
                "graphfrac-viewer: %s: %d steps, %d drags, %d cuts, %d balls\n"
                "  renderer:   %s\n"
                "  fracture:   fragments %lld, broken edges %lld of %lld\n",
                m_scene.name.c_str(), m_steps, m_drags, m_cuts, m_thrown,
                m_renderer->description().c_str(), static_cast<long long>(t.fragments),
                static_cast<long long>(t.brokenEdges), static_cast<long long>(t.edgeCount));
  std::string out = text;
  // The bodies the world holds now, so a script that switched scenes can see which ones.
  const World& world = m_sim->world();
  for (size_t i = 0; i < m_sim->bodyCount(); ++i) {
    const BodyId id = m_sim->body(i);
    const Result<TetMesh> mesh = world.currentMesh(id);
    std::snprintf(text, sizeof text, "  body %s: %lld tets, %zu nodes\n",
                  i < m_scene.bodies.size() ? m_scene.bodies[i].name.c_str() : "?",
                  mesh ? static_cast<long long>(mesh.value().tetCount()) : -1LL,
                  world.positions(id).size() / 3);
    out += text;
  }
  if (!m_loadError.empty()) out += "  not loaded: " + m_loadError + "\n";
  if (m_opt.validation) {
    std::snprintf(text, sizeof text,
                  "  validation: %zu messages from the Vulkan validation layers\n",
                  validationMessages().size());
    out += text;
  }
  return out;
}

Viewer* viewerOf(GLFWwindow* w) { return static_cast<Viewer*>(glfwGetWindowUserPointer(w)); }

/// GLFW's input to the viewer's handlers, unless the panel takes it. Installed before ImGui's
/// GLFW backend, which chains to the callbacks it finds.
void installInput(GLFWwindow* window, Viewer& viewer) {
  glfwSetWindowUserPointer(window, &viewer);
  glfwSetKeyCallback(window, [](GLFWwindow* w, int key, int, int action, int) {
    Viewer& v = *viewerOf(w);
    if (key == GLFW_KEY_X) v.xHeld = action != GLFW_RELEASE;
    if (action != GLFW_PRESS &&
        !(action == GLFW_REPEAT && key >= GLFW_KEY_RIGHT && key <= GLFW_KEY_UP))
      return;
    if (ImGui::GetCurrentContext() && ImGui::GetIO().WantCaptureKeyboard) return;
    v.onKey(key);
  });
  glfwSetMouseButtonCallback(window, [](GLFWwindow* w, int button, int action, int) {
    if (action == GLFW_PRESS && ImGui::GetCurrentContext() && ImGui::GetIO().WantCaptureMouse)
      return;
    double x = 0, y = 0;
    glfwGetCursorPos(w, &x, &y);
    viewerOf(w)->onMouseButton(button, action == GLFW_PRESS, x, y);
  });
  glfwSetCursorPosCallback(
      window, [](GLFWwindow* w, double x, double y) { viewerOf(w)->onMouseMove(x, y); });
  glfwSetScrollCallback(window, [](GLFWwindow* w, double, double dy) {
    if (ImGui::GetCurrentContext() && ImGui::GetIO().WantCaptureMouse) return;
    viewerOf(w)->onScroll(dy);
  });
}

Result<std::vector<ScriptCommand>> readScript(const std::string& path) {
  std::ifstream in(path);
  if (!in) return fail(path, ": cannot read the script");
  std::stringstream text;
  text << in.rdbuf();
  return parseScript(text.str(), path);
}

/// Runs the script's commands of `frame` that come before the step (input), through the
/// viewer's handlers; a drag spans frames, so it stays in `active` until released.
void scriptInput(std::span<const ScriptCommand> script, int frame, Viewer& viewer,
                 std::vector<const ScriptCommand*>& active) {
  for (const ScriptCommand& c : script) {
    if (c.frame != frame) continue;
    if (c.kind == ScriptCommand::Kind::Key) viewer.onKey(c.key);
    if (c.kind == ScriptCommand::Kind::Cut) {
      viewer.onMouseButton(GLFW_MOUSE_BUTTON_MIDDLE, true, c.x1, c.y1);
      viewer.onMouseMove(c.x2, c.y2);
      viewer.onMouseButton(GLFW_MOUSE_BUTTON_MIDDLE, false, c.x2, c.y2);
    }
    if (c.kind == ScriptCommand::Kind::Drag) {
      viewer.onMouseMove(c.x1, c.y1);
      viewer.onMouseButton(GLFW_MOUSE_BUTTON_LEFT, true, c.x1, c.y1);
      active.push_back(&c);
    }
  }
  for (size_t i = 0; i < active.size();) {
    const ScriptCommand& c = *active[i];
    const int held = frame - c.frame;
    if (held >= c.frames) {
      viewer.onMouseButton(GLFW_MOUSE_BUTTON_LEFT, false, c.x2, c.y2);
      active.erase(active.begin() + std::ptrdiff_t(i));
      continue;
    }
    const double s = c.frames > 1 ? double(held) / double(c.frames - 1) : 1.0;
    viewer.onMouseMove(c.x1 + s * (c.x2 - c.x1), c.y1 + s * (c.y2 - c.y1));
    ++i;
  }
}

int run(const ViewerOptions& opt) {
  std::vector<ScriptCommand> script;
  if (!opt.script.empty()) {
    Result<std::vector<ScriptCommand>> s = readScript(opt.script);
    if (!s) {
      std::fprintf(stderr, "graphfrac-viewer: %s\n", s.error().message.c_str());
      return 2;
    }
    script = std::move(s).value();
  }
  Viewer viewer(opt);
  // The renderer before the window: which context the window needs depends on it.
  if (Result<void> r = viewer.createRenderer(); !r) {
    std::fprintf(stderr, "%s\n", r.error().message.c_str());
    return 1;
  }
  if (Result<void> r = viewer.load(opt.scene); !r) {
    std::fprintf(stderr, "%s\n", r.error().message.c_str());
    return 1;
  }
  WindowOptions wo;
  wo.width = opt.width;
  wo.height = opt.height;
  wo.kind = opt.present;
  wo.validation = opt.validation;
  wo.eglContext = viewer.usesGlRenderer();
  wo.installInput = [&viewer](GLFWwindow* w) { installInput(w, viewer); };
  bool noDisplay = false;
  Result<std::unique_ptr<ViewerWindow>> opened = openViewerWindow(wo, noDisplay);
  if (noDisplay) {
    std::fprintf(stderr, "graphfrac-viewer: no display: cannot open a window (DISPLAY=%s)\n",
                 std::getenv("DISPLAY") ? std::getenv("DISPLAY") : "");
    return kViewerNoDisplay;
  }
  if (!opened) {
    std::fprintf(stderr, "graphfrac-viewer: --present %s is not available: %s\n",
                 opt.present == PresentKind::Gl ? "gl" : "vulkan", opened.error().message.c_str());
    return 1;
  }
  ViewerWindow& window = *opened.value();
  const bool fixedClock = !opt.script.empty() || opt.frames.has_value();
  std::vector<const ScriptCommand*> activeDrags;
  auto last = Clock::now();
  int status = 0;
  for (int frame = 1; !viewer.quit; ++frame) {
    glfwPollEvents();
    if (glfwWindowShouldClose(window.handle())) break;
    for (const ScriptCommand& c : script)
      if (c.frame == frame && c.kind == ScriptCommand::Kind::Scene) viewer.pickScene(c.path);
    if (viewer.pendingScene) {
      const std::string path = *viewer.pendingScene;
      viewer.pendingScene.reset();
      activeDrags.clear();
      // A scene that does not load leaves the current one running (load changes nothing
      // then but the error the panel shows), unless the renderer could not be made again.
      if (Result<void> r = viewer.load(path); !r) {
        std::fprintf(stderr, "%s\n", r.error().message.c_str());
        if (!viewer.hasScene()) {
          status = 1;
          break;
        }
      }
    }
    scriptInput(script, frame, viewer, activeDrags);
    const auto now = Clock::now();
    const double wall = std::chrono::duration<double>(now - last).count();
    last = now;
    if (Result<void> r = viewer.advance(fixedClock ? std::nullopt : std::optional<double>(wall));
        !r) {
      std::fprintf(stderr, "%s\n", r.error().message.c_str());
      status = 1;
      break;
    }
    if (Result<void> r = viewer.render(); !r) {
      std::fprintf(stderr, "%s\n", r.error().message.c_str());
      status = 1;
      break;
    }
    for (const ScriptCommand& c : script) {
      if (c.frame != frame) continue;
      if (c.kind == ScriptCommand::Kind::Screenshot) {
        if (Result<void> w = writePng(c.path, viewer.image()); !w) {
          std::fprintf(stderr, "graphfrac-viewer: %s\n", w.error().message.c_str());
          status = 1;
        }
      }
      if (c.kind == ScriptCommand::Kind::Panel) {
        std::ofstream out(c.path);
        for (const std::string& line : panelLines(viewer.figures())) out << line << '\n';
        if (!out) {
          std::fprintf(stderr, "graphfrac-viewer: %s: cannot write the panel's text\n",
                       c.path.c_str());
          status = 1;
        }
      }
      if (c.kind == ScriptCommand::Kind::Quit) viewer.quit = true;
    }
    const auto windowShot = std::find_if(script.begin(), script.end(), [&](const auto& c) {
      return c.frame == frame && c.kind == ScriptCommand::Kind::Window;
    });
    Image contents;
    if (Result<void> r = window.present(
            viewer.image(),
            [&viewer] {
              if (viewer.panelShown()) viewer.panel();
            },
            windowShot != script.end() ? &contents : nullptr);
        !r) {
      std::fprintf(stderr, "graphfrac-viewer: present: %s\n", r.error().message.c_str());
      status = 1;
      break;
    }
    for (const ScriptCommand& c : script) {
      if (c.frame != frame || c.kind != ScriptCommand::Kind::Window) continue;
      if (Result<void> w = writePng(c.path, contents); !w) {
        std::fprintf(stderr, "graphfrac-viewer: %s\n", w.error().message.c_str());
        status = 1;
      }
    }
    if (opt.frames && frame >= *opt.frames) break;
  }
  std::fputs(viewer.summary().c_str(), stdout);
  std::printf("  present:    %s\n", window.description().c_str());
  if (opt.validation) {
    std::vector<std::string> msgs = viewer.validationMessages();
    for (std::string& m : window.validationMessages()) msgs.push_back(std::move(m));
    std::printf("  validation: %zu messages from the window's Vulkan device\n",
                window.validationMessages().size());
    for (size_t i = 0; i < msgs.size() && i < 10; ++i)
      std::fprintf(stderr, "  validation: %s\n", msgs[i].c_str());
    if (!msgs.empty()) status = 1;
  }
  return status;
}

}  // namespace

int viewerMain(int argc, char** argv) {
  ViewerOptions opt;
  bool help = false;
  if (const std::string err = parseArgs(argc, argv, opt, help); !err.empty()) {
    std::fprintf(stderr, "graphfrac-viewer: %s\n(see graphfrac-viewer --help)\n", err.c_str());
    return 2;
  }
  if (help) {
    std::fputs(kUsage, stdout);
    return 0;
  }
  return run(opt);
}

}  // namespace gf::demo
