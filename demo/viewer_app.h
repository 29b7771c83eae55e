// graphfrac-viewer: a scene in a window to play with. Each frame the off-screen renderer of the
// demo (renderer.h, whichever back end createRenderer gives) draws the scene into an image that
// the window (viewer_window.h: a Vulkan swapchain, or OpenGL where Vulkan cannot present) shows
// behind a Dear ImGui panel; both work under Xvfb with Mesa, which is how CI drives the viewer
// with scripted input.
#pragma once

#include <graphfrac/status.h>

#include <glm/vec3.hpp>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "renderer.h"
#include "viewer_window.h"

namespace gf::demo {

/// One line of a --script file: `frame N drag X Y X2 Y2 [FRAMES]`, `frame N cut X1 Y1 X2 Y2`,
/// `frame N key K`, `frame N scene NAME|PATH`, `frame N screenshot PATH` (the renderer's
/// picture), `frame N window PATH` (the window's pixels as presented, panel included),
/// `frame N panel PATH` (the panel's text, viewer_panel.h, after that frame's step), `frame N quit`
/// (pixel coordinates of the picture, frames counted from 1; '#' starts a comment). A scene command
/// does what picking in the panel does: the scene is loaded before that frame's input and step;
/// NAME is a file of the panel's list (the current scene's folder), with or without `.json`.
struct ScriptCommand {
  enum class Kind { Drag, Cut, Key, Scene, Screenshot, Window, Panel, Quit };
  int frame = 1;
  Kind kind = Kind::Quit;
  double x1 = 0, y1 = 0, x2 = 0, y2 = 0;
  int frames = 10;  ///< Drag: frames the button is held, moving from (x1, y1) to (x2, y2).
  int key = 0;      ///< Key: the GLFW key code.
  std::string
      path;  ///< Screenshot, Window, Panel: the file written; Scene: the scene's name or path.
};

/// Parses a script; errors name `source`, the line and the reason. Sorted by frame (stable).
Result<std::vector<ScriptCommand>> parseScript(std::string_view text, const std::string& source);

/// The GLFW key code of a script key name: a letter or digit, "space", "left", "right", "up",
/// "down"; 0 for anything else.
int scriptKey(std::string_view name);

/// A ray from the camera's eye through the centre of pixel (x, y) of a width x height picture
/// (rows top to bottom), as the renderers project (glm::perspective of the camera).
struct Ray {
  glm::dvec3 origin{0}, direction{0, 0, -1};  ///< direction: unit
};
Ray cameraRay(const Camera& camera, int width, int height, double x, double y);

/// The planar blade of a mouse stroke: the quad between the rays through its two end points,
/// from the near to the far plane (the slice a knife drawn over the picture makes). Vertices
/// and triangles as World::cut's Blade takes them (world space, a static cut).
struct StrokeBlade {
  std::vector<glm::vec3> vertices;
  std::vector<uint32_t> triangles;
};
StrokeBlade strokeBlade(const Camera& camera, int width, int height, double x1, double y1,
                        double x2, double y2);

/// The scene picker's list: the *.json files in `scene`'s folder, sorted (empty if unreadable).
std::vector<std::string> siblingScenes(const std::string& scene);

/// The file a picked or scripted scene name stands for: a bare name (no folder) that is an
/// entry of `offered` by file name or by stem is that entry; anything else is a path as given.
std::string resolveScene(const std::string& name, std::span<const std::string> offered);

struct ViewerOptions {
  std::string scene;
  std::string script;         ///< --script FILE
  std::optional<int> frames;  ///< --frames N: exit after N frames.
  int width = 960, height = 540;
  RendererKind renderer = RendererKind::Auto;
  PresentKind present = PresentKind::Auto;  ///< --present: the window's presenter.
  bool validation = false;
  double strainMax = 0.05;  ///< The strain shown red when the colour map is on (C).
};

/// The executable: parses argv, opens the window, runs, prints a summary on exit (with the
/// presenter: `present: vulkan` or `present: gl (why not vulkan)`). Exit codes: 0 ok, 1
/// failure (including validation messages with --validation, and a --present that is not
/// available), 2 usage, 77 no display (GLFW could not open a window: the tests skip on it).
int viewerMain(int argc, char** argv);

/// viewerMain's exit code when no window can be opened.
inline constexpr int kViewerNoDisplay = 77;

}  // namespace gf::demo
