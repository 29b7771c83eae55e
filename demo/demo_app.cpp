// graphfrac-demo: one World/bridge frame per scene frame (BulletScene), then one render of what
// SceneDrawing makes of it (every body's surface stream and every rigid body), written as a PNG.
#include "demo_app.h"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <memory>
#include <numbers>
#include <string_view>

#include "cli/args.h"
#include "cli/progress.h"
#include "scene/bullet_scene.h"

extern char** environ;

namespace gf::demo {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr const char* kUsage =
    "usage: graphfrac-demo SCENE [options]\n"
    "\n"
    "Simulates a JSON scene (docs/scene_format.md) with its Bullet rigid bodies and renders\n"
    "every frame off-screen to OUT/frames/frame_NNNN.png; prints and writes OUT/summary.txt\n"
    "(ms per frame in simulation and rendering, fragments, broken edges, bodies handed to\n"
    "Bullet, bytes streamed to the renderer per frame).\n"
    "\n"
    "options:\n"
    "  --frames N                 frames to run (default: the scene's \"frames\")\n"
    "  --size WxH                 image size (default 640x360)\n"
    "  --out DIR                  output directory (default: out/<scene name>)\n"
    "  --video                    also encode OUT/demo.mp4 with ffmpeg (H.264, yuv420p, the\n"
    "                             scene's real-time rate), if installed\n"
    "  --sheet                    also write OUT/sheet.png, a contact sheet: 12 frames\n"
    "                             (--sheet-frames N) evenly spread, first and last included,\n"
    "                             in rows of 4 (--sheet-columns C), each 200 pixels wide\n"
    "                             (--sheet-width W)\n"
    "  --compare SCENE2           draw SCENE2 beside SCENE (same options, same dt), each\n"
    "                             half named in its overlay; the halves' own frames and\n"
    "                             summaries in OUT/left and OUT/right\n"
    "  --no-overlay               no text (frame, sim ms, tets, broken edges, fragments)\n"
    "  --no-shadows               no shadow map from the key light\n"
    "  --renderer auto|vulkan|gl  back end (default auto: Vulkan, else OpenGL through EGL)\n"
    "  --backend auto|cpu|cuda    simulation backend (default: the scene's \"backend\")\n"
    "  --validation               Vulkan validation layers on; exit 1 if they report anything\n"
    "  --strain MAX               colour the bodies by their largest principal strain, blue\n"
    "                             at 0 to red at MAX (the thesis's strain profiles, figs 4.2,\n"
    "                             5.14); crack faces keep their colour\n"
    "  --quiet                    no progress and no summary on the terminal\n"
    "  -h, --help                 this text\n"
    "\n"
    "exit codes: 0 ok, 1 failure, 2 usage\n";

/// Parses argv (argv[0] = the program); returns an error message or empty.
std::string parseArgs(int argc, char** argv, DemoOptions& o, bool& help) {
  cli::ArgParser a(argc, argv);
  while (a.next()) {
    const std::string& arg = a.name();
    if (arg == "-h" || arg == "--help") {
      help = true;
    } else if (arg == "--quiet" || arg == "-q") {
      o.quiet = true;
    } else if (arg == "--video") {
      o.video = true;
    } else if (arg == "--validation") {
      o.validation = true;
    } else if (arg == "--no-overlay") {
      o.overlay = false;
    } else if (arg == "--no-shadows") {
      o.shadows = false;
    } else if (arg == "--sheet") {
      if (o.sheetFrames == 0) o.sheetFrames = 12;
    } else if (arg == "--sheet-frames") {
      if (!a.intValue(1, 1000, o.sheetFrames)) return "--sheet-frames needs an integer in 1..1000";
    } else if (arg == "--sheet-columns") {
      if (!a.intValue(1, 100, o.sheetColumns)) return "--sheet-columns needs an integer in 1..100";
    } else if (arg == "--sheet-width") {
      if (!a.intValue(16, 4096, o.sheetWidth)) return "--sheet-width needs an integer in 16..4096";
    } else if (arg == "--frames") {
      int n = 0;
      if (!a.intValue(1, 100'000'000, n)) return "--frames needs an integer >= 1";
      o.frames = n;
    } else if (arg == "--backend") {
      std::string value;
      Backend b{};
      if (!a.value(value) || !cli::parseBackend(value, b))
        return "--backend needs auto, cpu or cuda";
      o.backend = b;
    } else if (arg == "--size") {
      std::string value;
      const size_t x = a.value(value) ? value.find('x') : std::string::npos;
      if (x == std::string::npos ||
          !cli::parseInt(std::string_view(value).substr(0, x), 1, 8192, o.width) ||
          !cli::parseInt(std::string_view(value).substr(x + 1), 1, 8192, o.height))
        return "--size needs WxH with 1 <= W, H <= 8192 (e.g. 640x360)";
    } else if (arg == "--out") {
      if (!a.nonEmptyValue(o.out)) return "--out needs a directory";
    } else if (arg == "--compare") {
      if (!a.nonEmptyValue(o.compare)) return "--compare needs a second scene";
    } else if (arg == "--strain") {
      if (!a.positiveValue(o.strainMax))
        return "--strain needs the strain shown as red, a number > 0 (e.g. 0.05)";
    } else if (arg == "--renderer") {
      std::string value;
      if (!a.value(value) || !parseRendererKind(value, o.renderer))
        return "--renderer needs auto, vulkan or gl";
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

/// Every point the camera should see of a rigid body (its bounding box corners; the square of
/// a plane) in world space.
std::vector<glm::dvec3> rigidBoundPoints(const scene::SceneRigidBody& r) {
  std::vector<glm::dvec3> pts;
  if (r.shape == scene::SceneRigidBody::Shape::Plane) {
    const ShapeMesh m = rigidMesh(r);
    for (size_t i = 0; i < m.positions.size(); i += 3)
      pts.emplace_back(m.positions[i], m.positions[i + 1], m.positions[i + 2]);
    return pts;
  }
  const double extent = r.shape == scene::SceneRigidBody::Shape::Sphere ? r.radius
                        : r.shape == scene::SceneRigidBody::Shape::Capsule
                            ? r.radius + r.halfLength
                            : glm::length(r.halfExtents);  // any orientation
  for (int k = 0; k < 8; ++k) {
    pts.push_back(r.position + extent * glm::dvec3(k & 1 ? 1 : -1, k & 2 ? 1 : -1, k & 4 ? 1 : -1));
  }
  return pts;
}

/// Near and far planes for everything in `pts` (and the target) seen from the eye.
void fitPlanes(Camera& c, std::span<const glm::dvec3> pts) {
  const glm::dvec3 eye(c.eye);
  const double view = glm::length(glm::dvec3(c.target) - eye);
  double farthest = 2 * view;
  for (const glm::dvec3& p : pts) farthest = std::max(farthest, glm::length(p - eye));
  c.nearPlane = float(0.02 * view);
  c.farPlane = float(1.5 * farthest);
}

/// The corners of every scene body's rest bounds and of the rigid shapes (a plane's square).
std::vector<glm::dvec3> staticPoints(const scene::Scene& sc) {
  std::vector<glm::dvec3> pts;
  for (const scene::SceneBody& b : sc.bodies) {
    const std::vector<double>& x = b.def.mesh.positions;
    for (size_t i = 0; i + 2 < x.size(); i += 3) pts.emplace_back(x[i], x[i + 1], x[i + 2]);
  }
  std::vector<scene::SceneRigidBody> shapes = sc.rigidBodies;
  for (const Collider& c : sc.world.colliders) shapes.push_back(colliderShape(c));
  for (const scene::SceneRigidBody& r : shapes)
    for (const glm::dvec3& p : rigidBoundPoints(r)) pts.push_back(p);
  return pts;
}

/// The frames of a contact sheet of `count` frames out of `frames`: evenly spread, the first
/// and the last included.
std::vector<int> sheetFrames(int count, int frames) {
  count = std::min(count, frames);
  std::vector<int> out;
  for (int k = 0; k < count; ++k)
    out.push_back(count == 1 ? frames
                             : 1 + int(std::lround(double(k) * (frames - 1) / (count - 1))));
  return out;
}

/// Fracture totals over the bodies, as `graphfrac run` counts them.
struct Totals {
  int64_t brokenEdges = 0, edgeCount = 0, fragments = 0;
};
Totals totals(const World& world, const scene::BulletScene& sim) {
  Totals t;
  for (size_t i = 0; i < sim.bodyCount(); ++i) {
    const FractureStats f = world.fractureStats(sim.body(i));
    if (f.edgeCount > 0) {
      t.brokenEdges += f.brokenEdges;
      t.edgeCount += f.edgeCount;
    }
    t.fragments += f.fragments;  // 1 for a body that cannot break; pieces of an Is-XFEM body
  }
  return t;
}

/// The first executable named `name` on PATH, or empty.
std::string findOnPath(const std::string& name) {
  const char* path = std::getenv("PATH");
  if (path == nullptr) return {};
  std::string_view rest(path);
  while (true) {
    const size_t colon = rest.find(':');
    const std::string dir(rest.substr(0, colon));
    const std::string candidate = (dir.empty() ? std::string(".") : dir) + "/" + name;
    if (access(candidate.c_str(), X_OK) == 0) return candidate;
    if (colon == std::string_view::npos) return {};
    rest.remove_prefix(colon + 1);
  }
}

/// Runs a program without a shell (paths need no quoting); returns its exit status or an error.
Result<int> runProgram(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = 0;
  if (const int e = posix_spawn(&pid, args[0].c_str(), nullptr, nullptr, argv.data(), environ);
      e != 0)
    return fail("cannot start ", args[0], ": ", std::strerror(e));
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return fail("waiting for ", args[0], ": ", std::strerror(errno));
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::string formatBytes(double b) {
  char buf[32];
  if (b >= 1024.0 * 1024.0)
    std::snprintf(buf, sizeof buf, "%.2f MB", b / (1024.0 * 1024.0));
  else
    std::snprintf(buf, sizeof buf, "%.1f kB", b / 1024.0);
  return buf;
}

// Encodes frameDir/frame_%04d.png into outDir/demo.mp4 at the scene's rate; returns the
// video's description, or "" with a note when ffmpeg is missing (not an error).
Result<std::string> encodeVideo(const fs::path& frameDir, const fs::path& outDir, double dt,
                                std::string& note) {
  const std::string ffmpeg = findOnPath("ffmpeg");
  if (ffmpeg.empty()) {
    note += "  video:      skipped: ffmpeg is not on PATH (install it for --video)\n";
    return std::string();
  }
  // The scene's own rate, as an exact fraction where 1/dt is not a whole number (a frame
  // of 1/24 s plays at 24 fps, one of 0.03 s at 100000/3000).
  const double fps = 1.0 / dt;
  const std::string rate = std::abs(fps - std::round(fps)) < 1e-6 * fps
                               ? std::to_string(std::lround(fps))
                               : "1000000/" + std::to_string(std::lround(dt * 1e6));
  const std::string video = (outDir / "demo.mp4").string();
  // What plays everywhere (browsers, phones, QuickTime): H.264 High profile, yuv420p,
  // even sizes (odd ones padded by a pixel), the index at the front of the file.
  Result<int> r = runProgram({ffmpeg,
                              "-y",
                              "-loglevel",
                              "error",
                              "-framerate",
                              rate,
                              "-start_number",
                              "1",
                              "-i",
                              (frameDir / "frame_%04d.png").string(),
                              "-vf",
                              "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                              "-c:v",
                              "libx264",
                              "-profile:v",
                              "high",
                              "-crf",
                              "20",
                              "-pix_fmt",
                              "yuv420p",
                              "-movflags",
                              "+faststart",
                              video});
  if (!r) return fail("graphfrac-demo: ", r.error().message);
  if (r.value() != 0)
    return fail("graphfrac-demo: ffmpeg failed (exit status ", std::to_string(r.value()),
                ") making ", video);
  char rateNote[64];
  std::snprintf(rateNote, sizeof rateNote, " (H.264, yuv420p, %.6g fps)", fps);
  return video + rateNote;
}

// Writes outDir/sheet.png from the chosen frames; returns its path.
Result<std::string> writeSheet(std::span<const Image> images, const DemoOptions& opt,
                               const fs::path& outDir) {
  Result<Image> sheet = contactSheet(images, opt.sheetColumns, opt.sheetWidth);
  if (!sheet) return fail("graphfrac-demo: ", sheet.error().message);
  const std::string path = (outDir / "sheet.png").string();
  if (Result<void> w = writePng(path, sheet.value()); !w)
    return fail("graphfrac-demo: ", w.error().message);
  return path;
}

// Writes `text` to outDir/summary.txt and, unless quiet, to stdout.
Result<void> writeSummary(const fs::path& outDir, const std::string& text, bool quiet) {
  const fs::path path = outDir / "summary.txt";
  std::ofstream file(path);
  file << text;
  file.close();
  if (!file) return fail("graphfrac-demo: cannot write ", path.string());
  if (!quiet) std::fputs(text.c_str(), stdout);
  return {};
}

// Clears the frames of an earlier run from frameDir (they would continue this run's sequence
// in the video).
Result<void> prepareFrameDir(const fs::path& frameDir) {
  std::error_code ec;
  fs::create_directories(frameDir, ec);
  if (ec) return fail("graphfrac-demo: cannot create ", frameDir.string(), ": ", ec.message());
  for (const fs::directory_entry& e : fs::directory_iterator(frameDir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.size() == 14 && name.rfind("frame_", 0) == 0 && e.path().extension() == ".png")
      fs::remove(e.path(), ec);
  }
  return {};
}

std::string frameName(int frame) {
  char name[32];
  std::snprintf(name, sizeof name, "frame_%04d.png", frame);
  return name;
}

}  // namespace

std::vector<Bounds> bodyBounds(const World& world, std::span<const BodyId> bodies) {
  std::vector<Bounds> out(bodies.size());
  for (size_t i = 0; i < bodies.size(); ++i) {
    const std::span<const double> x = world.positions(bodies[i]);
    for (size_t k = 0; k + 2 < x.size(); k += 3) out[i].add({x[k], x[k + 1], x[k + 2]});
  }
  return out;
}

Camera sceneCamera(const scene::Scene& sc) {
  std::vector<glm::dvec3> pts;
  glm::dvec3 lo(1e300), hi(-1e300);
  auto add = [&](const glm::dvec3& p, bool frame) {
    pts.push_back(p);
    if (!frame) return;
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  };
  for (const scene::SceneBody& b : sc.bodies) {
    const std::vector<double>& x = b.def.mesh.positions;
    for (size_t i = 0; i + 2 < x.size(); i += 3) add({x[i], x[i + 1], x[i + 2]}, true);
  }
  std::vector<scene::SceneRigidBody> shapes = sc.rigidBodies;
  for (const Collider& c : sc.world.colliders) shapes.push_back(colliderShape(c));
  for (const scene::SceneRigidBody& r : shapes) {
    const bool plane = r.shape == scene::SceneRigidBody::Shape::Plane;
    for (const glm::dvec3& p : rigidBoundPoints(r)) add(p, !plane);
  }
  Camera c;
  if (sc.camera) {
    c.eye = glm::vec3(sc.camera->eye);
    c.target = glm::vec3(sc.camera->target);
    c.up = glm::vec3(sc.camera->up);
    c.fovYDegrees = float(sc.camera->fovDegrees);
  } else if (lo.x <= hi.x) {
    // Looking at the bounds' centre from the front right, far enough to hold their sphere.
    const glm::dvec3 centre = 0.5 * (lo + hi);
    const double radius = std::max(0.5 * glm::length(hi - lo), 1e-3);
    const double fov = double(c.fovYDegrees) * std::numbers::pi / 180;
    const double dist = 1.15 * radius / std::sin(0.5 * fov);
    c.target = glm::vec3(centre);
    c.eye = glm::vec3(centre + dist * glm::normalize(glm::dvec3(0.8, 0.55, 1.3)));
  }
  fitPlanes(c, pts);
  return c;
}

std::string formatSummary(const DemoSummary& s) {
  std::string out;
  char line[512];
  auto add = [&](const char* fmt, auto... args) {
    std::snprintf(line, sizeof line, fmt, args...);
    out += line;
  };
  add("graphfrac-demo: %s: %d frames of %.6g s (%d substep%s), %dx%d\n", s.scene.c_str(), s.frames,
      s.dt, s.substeps, s.substeps == 1 ? "" : "s", s.width, s.height);
  add("  renderer:   %s\n", s.renderer.c_str());
  add("  backend:    %s\n", s.backend.c_str());
  add("  simulation: %.2f ms/frame mean, %.2f max (Bullet %.2f ms/frame mean)\n", s.simMsMean,
      s.simMsMax, s.bulletMsMean);
  add("  rendering:  %.2f ms/frame mean, %.2f max (upload, draw, readback; PNG writing %.2f "
      "ms/frame more)\n",
      s.renderMsMean, s.renderMsMax, s.pngMsMean);
  add("  fracture:   %lld fragments, %lld broken edges of %lld, %zu fragment%s handed to Bullet\n",
      static_cast<long long>(s.fragments), static_cast<long long>(s.brokenEdges),
      static_cast<long long>(s.edgeCount), s.handedOff, s.handedOff == 1 ? "" : "s");
  for (const DemoSummary::BodyFracture& b : s.bodies)
    add("    %-10s %lld fragment%s, %lld broken edges of %lld\n", b.name.c_str(),
        static_cast<long long>(b.fragments), b.fragments == 1 ? "" : "s",
        static_cast<long long>(b.brokenEdges), static_cast<long long>(b.edgeCount));
  if (s.frames > 1) {
    add("  streaming:  %s uploaded per frame vs %s for full surfaces (%.1f %%), mean after the "
        "first frame\n",
        formatBytes(s.uploadedBytesMean).c_str(), formatBytes(s.surfaceBytesMean).c_str(),
        s.surfaceBytesMean > 0 ? 100 * s.uploadedBytesMean / s.surfaceBytesMean : 0.0);
  }
  if (s.flaggedFrames > 0)
    add("  flagged:    %d frame%s; first: %s\n", s.flaggedFrames, s.flaggedFrames == 1 ? "" : "s",
        s.firstFlag.c_str());
  add("  wall time:  %s\n", cli::formatDuration(s.wallSeconds).c_str());
  add("  frames:     %s/frames/frame_0001.png .. frame_%04d.png\n", s.outDir.c_str(), s.frames);
  if (!s.video.empty()) add("  video:      %s\n", s.video.c_str());
  if (!s.sheet.empty()) add("  sheet:      %s\n", s.sheet.c_str());
  add("  camera:     %s; each body's projected box at least %.1f %% in the picture, line of "
      "sight swings at most %.3f deg/frame\n",
      s.follow ? "following the bodies" : "fixed", 100 * s.minInside, s.maxSwingDegrees);
  if (s.validation)
    add("  validation: %zu message%s from the Vulkan validation layers\n",
        s.validationMessages.size(), s.validationMessages.size() == 1 ? "" : "s");
  return out;
}

namespace {

// Between the halves of --compare, as between the cells of a contact sheet.
constexpr int kSideGap = 2;
constexpr uint8_t kGapGrey = 24;

// --compare: each scene through runDemo at half the width, then each pair of frames composed.
Result<DemoSummary> runSideBySide(const DemoOptions& opt) {
  const auto wallStart = Clock::now();
  const int half = (opt.width - kSideGap) / 2;
  if (half < 1)
    return fail("graphfrac-demo: --compare needs a width of at least ",
                std::to_string(kSideGap + 2), " pixels, got ", std::to_string(opt.width));
  Result<scene::Scene> left = scene::loadScene(opt.scene);
  if (!left) return left.error();
  Result<scene::Scene> right = scene::loadScene(opt.compare);
  if (!right) return right.error();
  if (left.value().dt != right.value().dt) {
    char msg[160];
    std::snprintf(msg, sizeof msg, "dt %.6g differs from the first scene's %.6g", right.value().dt,
                  left.value().dt);
    return fail(opt.compare, ": ", msg, ": side by side, the halves would show different times");
  }
  const fs::path outDir = opt.out.empty()
                              ? fs::path("out") / (left.value().name + "_vs_" + right.value().name)
                              : fs::path(opt.out);
  DemoSummary s;
  for (const std::string* sceneFile : {&opt.scene, &opt.compare}) {
    DemoOptions h = opt;
    h.scene = *sceneFile;
    h.compare.clear();
    h.width = half;
    h.out = (outDir / (s.halves.empty() ? "left" : "right")).string();
    h.video = false;
    h.sheetFrames = 0;
    h.nameInOverlay = true;
    Result<DemoSummary> r = runDemo(h);
    if (!r) return r.error();
    s.halves.push_back(std::move(r).value());
  }

  const fs::path frameDir = outDir / "frames";
  if (Result<void> r = prepareFrameDir(frameDir); !r) return r.error();
  s.scene = s.halves[0].scene + " | " + s.halves[1].scene;
  s.renderer = s.halves[0].renderer;
  s.backend = s.halves[0].backend;
  s.outDir = outDir.string();
  s.frames = std::min(s.halves[0].frames, s.halves[1].frames);
  s.width = 2 * half + kSideGap;
  s.height = opt.height;
  s.dt = left.value().dt;
  const std::vector<int> sheetAt = sheetFrames(opt.sheetFrames, s.frames);
  std::vector<Image> sheetImages;
  Image both;
  both.width = s.width;
  both.height = s.height;
  both.rgba.assign(4 * size_t(both.width) * size_t(both.height), kGapGrey);
  for (int frame = 1; frame <= s.frames; ++frame) {
    for (size_t k = 0; k < 2; ++k) {
      Result<Image> img =
          readPng((fs::path(s.halves[k].outDir) / "frames" / frameName(frame)).string());
      if (!img) return fail("graphfrac-demo: ", img.error().message);
      const size_t x0 = k * size_t(half + kSideGap);
      for (int y = 0; y < both.height; ++y)
        std::memcpy(&both.rgba[4 * (size_t(y) * size_t(both.width) + x0)],
                    &img.value().rgba[4 * size_t(y) * size_t(half)], 4 * size_t(half));
    }
    if (Result<void> w = writePng((frameDir / frameName(frame)).string(), both); !w)
      return fail("graphfrac-demo: ", w.error().message);
    if (std::find(sheetAt.begin(), sheetAt.end(), frame) != sheetAt.end())
      sheetImages.push_back(both);
  }
  std::string text = "graphfrac-demo: side by side, " + s.scene + "\n";
  char line[256];
  std::snprintf(line, sizeof line, "  frames:     %s .. %s (%dx%d)\n",
                (frameDir / frameName(1)).c_str(), frameName(s.frames).c_str(), s.width, s.height);
  text += line;
  text += "  halves:     " + s.halves[0].outDir + "/summary.txt, " + s.halves[1].outDir +
          "/summary.txt\n";
  if (opt.video) {
    Result<std::string> v = encodeVideo(frameDir, outDir, s.dt, text);
    if (!v) return v.error();
    s.video = v.value();
    if (!s.video.empty()) text += "  video:      " + s.video + "\n";
  }
  if (!sheetImages.empty()) {
    Result<std::string> sheet = writeSheet(sheetImages, opt, outDir);
    if (!sheet) return sheet.error();
    s.sheet = sheet.value();
    text += "  sheet:      " + s.sheet + "\n";
  }
  s.wallSeconds = std::chrono::duration<double>(Clock::now() - wallStart).count();
  if (Result<void> w = writeSummary(outDir, text, opt.quiet); !w) return w.error();
  return s;
}

}  // namespace

Result<DemoSummary> runDemo(const DemoOptions& opt) {
  if (!opt.compare.empty()) return runSideBySide(opt);
  const auto wallStart = Clock::now();
  Result<scene::Scene> loaded = scene::loadScene(opt.scene);
  if (!loaded) return loaded.error();
  scene::Scene sc = std::move(loaded).value();
  if (opt.backend) sc.world.backend = *opt.backend;
  const int frames = opt.frames.value_or(sc.frames);
  if (frames < 1) return fail("graphfrac-demo: frames must be >= 1, got ", std::to_string(frames));

  Result<std::unique_ptr<scene::BulletScene>> created = scene::BulletScene::create(sc);
  if (!created) return created.error();
  scene::BulletScene& sim = *created.value();
  World& world = sim.world();

  RendererOptions ro;
  ro.kind = opt.renderer;
  ro.width = opt.width;
  ro.height = opt.height;
  ro.validation = opt.validation;
  Result<std::unique_ptr<Renderer>> madeRenderer = createRenderer(ro);
  if (!madeRenderer) return fail("graphfrac-demo: ", madeRenderer.error().message);
  Renderer& renderer = *madeRenderer.value();

  DemoSummary s;
  s.backend = world.backendDescription();
  s.scene = sc.name;
  s.renderer = renderer.description();
  s.frames = frames;
  s.width = opt.width;
  s.height = opt.height;
  s.dt = sc.dt;
  s.substeps = std::max(sc.world.substeps, 1);
  s.camera = sceneCamera(sc);
  std::vector<BodyId> ids;
  int64_t tets = 0;
  for (size_t i = 0; i < sim.bodyCount(); ++i) {
    ids.push_back(sim.body(i));
    tets += int64_t(sc.bodies[i].def.mesh.tetCount());
  }
  // A follow camera starts framing the bodies as they stand; every later frame moves it by
  // the rig's smoothing towards the bounds after that frame's step.
  const double aspect = double(opt.width) / double(opt.height);
  const std::vector<glm::dvec3> fixedPoints = staticPoints(sc);
  std::optional<CameraRig> rig;
  s.follow = sc.camera && sc.camera->follow;
  if (s.follow) {
    FollowSettings follow;
    follow.smoothSeconds = sc.camera->smoothSeconds;
    follow.maxTurnDegrees = sc.camera->maxTurnDegrees;
    rig.emplace(s.camera, follow, aspect);
    s.camera = rig->snap(bodyBounds(world, ids));
    fitPlanes(s.camera, fixedPoints);
  }
  Camera previousCamera = s.camera;
  const std::vector<int> sheetAt = sheetFrames(opt.sheetFrames, frames);
  std::vector<Image> sheetImages;
  const fs::path outDir = opt.out.empty() ? fs::path("out") / sc.name : fs::path(opt.out);
  s.outDir = outDir.string();
  const fs::path frameDir = outDir / "frames";
  if (Result<void> r = prepareFrameDir(frameDir); !r) return r.error();

  if (!opt.quiet) {
    std::printf("graphfrac-demo: %s: %zu bod%s, %zu rigid bod%s; %d frames of %.6g s; %dx%d\n",
                sc.name.c_str(), sc.bodies.size(), sc.bodies.size() == 1 ? "y" : "ies",
                sc.rigidBodies.size(), sc.rigidBodies.size() == 1 ? "y" : "ies", frames, sc.dt,
                opt.width, opt.height);
    std::printf("  renderer: %s\n  output:   %s\n", s.renderer.c_str(), s.outDir.c_str());
    std::fflush(stdout);
  }

  SceneDrawing drawing(sc);
  if (Result<void> r = drawing.loadTextures(sc); !r)
    return fail(opt.scene, ": ", r.error().message);
  cli::Progress progress(frames, cli::Progress::detect(stderr, opt.quiet));
  Image image;
  double simSum = 0, bulletSum = 0, renderSum = 0, pngSum = 0, upSum = 0, fullSum = 0;
  for (int frame = 1; frame <= frames; ++frame) {
    const StepStatus st = sim.step();
    if (st.has(kStepInvalidInput))
      return fail(opt.scene, ": frame ", std::to_string(frame), ": ", st.message);
    if (!st.ok() && s.flaggedFrames++ == 0)
      s.firstFlag = "frame " + std::to_string(frame) + ": " + st.message;
    DemoFrame f;
    f.simMs = sim.timings().totalMs;
    f.bulletMs = sim.timings().bulletMs;

    const DrawingChanges changes = drawing.update(sim, opt.strainMax);
    f.topologyChanges = changes.topologyChanges;
    f.dirtyVertices = changes.dirtyVertices;

    f.bodyBounds = bodyBounds(world, ids);
    if (rig) {
      f.camera = rig->update(f.bodyBounds, sc.dt);
      std::vector<glm::dvec3> pts = fixedPoints;
      for (const Bounds& b : f.bodyBounds)
        if (!b.empty()) pts.insert(pts.end(), {b.lo, b.hi});
      fitPlanes(f.camera, pts);
    } else {
      f.camera = s.camera;
    }
    if (frame > 1)
      s.maxSwingDegrees = std::max(s.maxSwingDegrees, swingDegrees(previousCamera, f.camera));
    previousCamera = f.camera;
    for (const Bounds& b : f.bodyBounds)
      s.minInside = std::min(s.minInside, fractionInside(f.camera, aspect, b));

    const Totals t = totals(world, sim);
    FrameOptions fo;
    fo.shadows = opt.shadows;
    if (opt.overlay) {
      if (opt.nameInOverlay) fo.overlay.push_back(sc.name);
      char line[160];
      std::snprintf(line, sizeof line, "frame %d/%d  t %.2f s  sim %.0f ms", frame, frames,
                    frame * sc.dt, f.simMs);
      fo.overlay.emplace_back(line);
      std::snprintf(line, sizeof line, "tets %lld  broken edges %lld  fragments %lld",
                    static_cast<long long>(tets), static_cast<long long>(t.brokenEdges),
                    static_cast<long long>(t.fragments));
      fo.overlay.emplace_back(line);
    }
    Result<FrameStats> rs = renderer.render(drawing.meshes(), f.camera, fo, image);
    if (!rs) return fail("graphfrac-demo: frame ", std::to_string(frame), ": ", rs.error().message);
    f.renderMs = rs.value().renderMs;
    f.uploadedBytes = rs.value().uploadedBytes;
    f.surfaceBytes = rs.value().surfaceBytes;
    const auto tp = Clock::now();
    if (Result<void> w = writePng((frameDir / frameName(frame)).string(), image); !w)
      return fail("graphfrac-demo: ", w.error().message);
    f.pngMs = cli::msSince(tp);
    if (std::find(sheetAt.begin(), sheetAt.end(), frame) != sheetAt.end())
      sheetImages.push_back(image);

    f.brokenEdges = t.brokenEdges;
    f.fragments = t.fragments;
    f.handedOff = sim.handedOff();
    simSum += f.simMs;
    bulletSum += f.bulletMs;
    renderSum += f.renderMs;
    pngSum += f.pngMs;
    s.simMsMax = std::max(s.simMsMax, f.simMs);
    s.renderMsMax = std::max(s.renderMsMax, f.renderMs);
    if (frame > 1) {
      upSum += double(f.uploadedBytes);
      fullSum += double(f.surfaceBytes);
    }
    s.perFrame.push_back(f);
    char note[96];
    std::snprintf(note, sizeof note, "sim %.0f ms, render %.0f ms, %lld fragments", f.simMs,
                  f.renderMs, static_cast<long long>(f.fragments));
    progress.update(frame, note);
  }
  progress.finish();

  const Totals t = totals(world, sim);
  for (size_t i = 0; i < sim.bodyCount(); ++i) {
    const FractureStats fs = world.fractureStats(sim.body(i));
    DemoSummary::BodyFracture bf;
    bf.name = sc.bodies[i].name;
    if (fs.edgeCount > 0) {
      bf.fragments = fs.fragments;
      bf.brokenEdges = fs.brokenEdges;
      bf.edgeCount = fs.edgeCount;
    }
    s.bodies.push_back(bf);
  }
  s.brokenEdges = t.brokenEdges;
  s.edgeCount = t.edgeCount;
  s.fragments = t.fragments;
  s.handedOff = sim.handedOff();
  s.simMsMean = simSum / frames;
  s.bulletMsMean = bulletSum / frames;
  s.renderMsMean = renderSum / frames;
  s.pngMsMean = pngSum / frames;
  if (frames > 1) {
    s.uploadedBytesMean = upSum / (frames - 1);
    s.surfaceBytesMean = fullSum / (frames - 1);
  }
  s.validation = opt.validation;
  s.validationMessages = renderer.validationMessages();

  std::string videoNote;
  if (opt.video) {
    Result<std::string> v = encodeVideo(frameDir, outDir, sc.dt, videoNote);
    if (!v) return v.error();
    s.video = v.value();
  }
  if (!sheetImages.empty()) {
    Result<std::string> sheet = writeSheet(sheetImages, opt, outDir);
    if (!sheet) return sheet.error();
    s.sheet = sheet.value();
  }
  if (opt.overlay && !overlayAvailable())
    videoNote += "  overlay:    skipped: built without stb_easy_font (libstb-dev)\n";
  s.wallSeconds = std::chrono::duration<double>(Clock::now() - wallStart).count();
  if (Result<void> w = writeSummary(outDir, formatSummary(s) + videoNote, opt.quiet); !w)
    return w.error();
  return s;
}

int demoMain(int argc, char** argv) {
  DemoOptions opt;
  bool help = false;
  if (const std::string err = parseArgs(argc, argv, opt, help); !err.empty()) {
    std::fprintf(stderr, "graphfrac-demo: %s\n(see graphfrac-demo --help)\n", err.c_str());
    return 2;
  }
  if (help) {
    std::fputs(kUsage, stdout);
    return 0;
  }
  Result<DemoSummary> r = runDemo(opt);
  if (!r) {
    std::fprintf(stderr, "%s\n", r.error().message.c_str());
    return 1;
  }
  if (opt.validation) {
    const std::vector<std::string>& msgs = r.value().validationMessages;
    for (size_t i = 0; i < msgs.size() && i < 10; ++i)
      std::fprintf(stderr, "  validation: %s\n", msgs[i].c_str());
    if (!msgs.empty()) return 1;
  }
  return 0;
}

}  // namespace gf::demo
