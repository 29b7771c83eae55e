// graphfrac-demo as a library (the executable is demo/main.cpp; the tests call runDemo without
// a subprocess): loads a scene, steps it with its Bullet rigid bodies (tools/scene/
// bullet_scene.h), renders every frame off-screen (renderer.h) into OUT/frames/frame_%04d.png,
// optionally encodes OUT/demo.mp4 with ffmpeg, and writes a summary to OUT/summary.txt.
#pragma once

#include <graphfrac/status.h>

#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "camera_rig.h"
#include "renderer.h"
#include "scene/scene.h"
#include "scene_drawing.h"

namespace gf::demo {

struct DemoOptions {
  std::string scene;               ///< Scene file (docs/scene_format.md).
  std::optional<int> frames;       ///< Default: the scene's "frames".
  std::optional<Backend> backend;  ///< Default: the scene's "backend".
  int width = 640, height = 360;
  std::string out;  ///< Default: out/<scene name>.
  bool video = false;
  RendererKind renderer = RendererKind::Auto;
  bool validation = false;
  bool quiet = false;  ///< No progress, summary or notes on stdout/stderr (summary.txt still).
  /// > 0: colour the bodies by World::nodeStrain, saturating (red) at this strain.
  double strainMax = 0;
  bool shadows = true;  ///< The key light's shadow map.
  bool overlay = true;  ///< Frame, sim ms, tets, broken edges, fragments over the picture.
  /// > 0: also write OUT/sheet.png, this many frames evenly spread (first and last included)
  /// in rows of sheetColumns, each sheetWidth pixels wide.
  int sheetFrames = 0;
  int sheetColumns = 4, sheetWidth = 200;
  /// Non-empty: a second scene, run with the same options and drawn to the right of the
  /// first, each half (width - 2) / 2 pixels wide with its scene's name over it. Each half's
  /// own frames and summary go to OUT/left and OUT/right, the composed frames (and the video
  /// and sheet) to OUT. The two scenes must have the same dt, so side by side is same time.
  std::string compare;
  bool nameInOverlay = false;  ///< The scene's name as the overlay's first line.
};

/// One rendered frame.
struct DemoFrame {
  double simMs = 0;     ///< World and Bullet (BulletScene::timings().totalMs).
  double bulletMs = 0;  ///< The Bullet part of simMs.
  double renderMs = 0;  ///< FrameStats::renderMs: upload, draw, readback.
  double pngMs = 0;     ///< Writing the PNG.
  uint64_t uploadedBytes = 0, surfaceBytes = 0;  ///< FrameStats
  /// Meshes whose topology (version or size) changed since the previous frame, the first
  /// frame counting every mesh as changed; and the dirty vertices of the unchanged ones.
  int topologyChanges = 0;
  uint64_t dirtyVertices = 0;
  int64_t brokenEdges = 0, fragments = 0;  ///< Summed over the bodies, after the step.
  size_t handedOff = 0;
  Camera camera;                   ///< The camera this frame was drawn with.
  std::vector<Bounds> bodyBounds;  ///< Per scene body: its nodes' bounds after the step.
};

struct DemoSummary {
  std::string scene;     ///< Scene name.
  std::string renderer;  ///< Renderer::description().
  std::string backend;   ///< World::backendDescription().
  std::string outDir;
  int frames = 0, width = 0, height = 0;
  double dt = 0;
  int substeps = 1;
  double simMsMean = 0, simMsMax = 0, bulletMsMean = 0, renderMsMean = 0, renderMsMax = 0,
         pngMsMean = 0;
  int64_t brokenEdges = 0, edgeCount = 0;  ///< Summed over the fracturing bodies.
  int64_t fragments = 0;  ///< Summed over the bodies (one for a body without fracture).
  size_t handedOff = 0;   ///< Fragments handed to Bullet.
  /// Per scene body at the end, so a scene's story can be checked body by body.
  struct BodyFracture {
    std::string name;
    int64_t fragments = 1, brokenEdges = 0, edgeCount = 0;
  };
  std::vector<BodyFracture> bodies;
  /// Mean over the frames after the first (the first uploads everything): bytes uploaded and
  /// bytes a full re-upload of every mesh would have cost.
  double uploadedBytesMean = 0, surfaceBytesMean = 0;
  int flaggedFrames = 0;  ///< Frames whose step reported a flag.
  std::string firstFlag;  ///< The first flagged step's message.
  double wallSeconds = 0;
  bool validation = false;  ///< The validation layers were asked for.
  std::vector<std::string> validationMessages;
  std::string video;    ///< Path of the video written, else empty.
  std::string sheet;    ///< Path of the contact sheet written, else empty.
  Camera camera;        ///< The camera of the first frame.
  bool follow = false;  ///< The camera followed the bodies (scene camera "follow").
  /// Over the frames: the smallest share of a body's projected bounds inside the picture
  /// (fractionInside), and the largest swing of the line of sight between frames.
  double minInside = 1, maxSwingDegrees = 0;
  std::vector<DemoFrame> perFrame;
  std::vector<DemoSummary> halves;  ///< With DemoOptions::compare: the left and right runs.
};

/// Runs the demo. Errors (scene, renderer, output, ffmpeg failing) come back as the message to
/// print; a missing ffmpeg is not one (the summary says so and `video` stays empty).
Result<DemoSummary> runDemo(const DemoOptions& options);

/// The summary as printed and written to summary.txt.
std::string formatSummary(const DemoSummary& summary);

/// The executable: parses argv, runs, prints. Exit codes: 0 ok, 1 failure (including
/// validation messages with --validation), 2 usage.
int demoMain(int argc, char** argv);

/// The bounds of each body's nodes now (its surface's vertices sit on them).
std::vector<Bounds> bodyBounds(const World& world, std::span<const BodyId> bodies);

/// The scene's camera, or one framing the bodies' rest bounds and the spheres and boxes of the
/// rigid bodies and colliders when the scene has none; near and far planes cover those and
/// the planes' squares (static colliders are drawn like static rigid bodies).
Camera sceneCamera(const scene::Scene& scene);

}  // namespace gf::demo
