// graphfrac-viewer's scripted input and picking geometry, apart from the window so the tests
// use them without a display: the script's parser (the same handlers as the mouse and keys
// run what it says), key names, the camera ray under a pixel and the blade a stroke makes.
#include <GLFW/glfw3.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <numbers>
#include <sstream>

#include "viewer_app.h"

namespace gf::demo {

Result<std::vector<ScriptCommand>> parseScript(std::string_view text, const std::string& source) {
  std::vector<ScriptCommand> out;
  std::istringstream in{std::string(text)};
  std::string line;
  for (int lineNo = 1; std::getline(in, line); ++lineNo) {
    if (const size_t hash = line.find('#'); hash != std::string::npos) line.resize(hash);
    std::istringstream words(line);
    std::string word, verb;
    if (!(words >> word)) continue;
    auto error = [&](const std::string& why) {
      return fail(source, ":", std::to_string(lineNo), ": ", why);
    };
    ScriptCommand c;
    if (word != "frame" || !(words >> c.frame) || c.frame < 1 || !(words >> verb))
      return error("expected 'frame N COMMAND' with N >= 1");
    if (verb == "drag" || verb == "cut") {
      c.kind = verb == "drag" ? ScriptCommand::Kind::Drag : ScriptCommand::Kind::Cut;
      if (!(words >> c.x1 >> c.y1 >> c.x2 >> c.y2)) return error(verb + " needs X1 Y1 X2 Y2");
      if (c.kind == ScriptCommand::Kind::Drag && (words >> c.frames) && c.frames < 1)
        return error("drag's FRAMES must be >= 1");
    } else if (verb == "key") {
      c.kind = ScriptCommand::Kind::Key;
      std::string name;
      if (!(words >> name) || (c.key = scriptKey(name)) == 0)
        return error("key needs a letter, a digit, space, left, right, up or down");
    } else if (verb == "scene") {
      c.kind = ScriptCommand::Kind::Scene;
      if (!(words >> c.path)) return error("scene needs a scene's name or path");
    } else if (verb == "screenshot" || verb == "panel" || verb == "window") {
      c.kind = verb == "panel"    ? ScriptCommand::Kind::Panel
               : verb == "window" ? ScriptCommand::Kind::Window
                                  : ScriptCommand::Kind::Screenshot;
      if (!(words >> c.path)) return error(verb + " needs a path");
    } else if (verb == "quit") {
      c.kind = ScriptCommand::Kind::Quit;
    } else {
      return error("unknown command '" + verb +
                   "' (drag, cut, key, scene, screenshot, window, panel, quit)");
    }
    std::string extra;
    words.clear();
    if (words >> extra) return error("unexpected '" + extra + "' at the end of the line");
    out.push_back(c);
  }
  std::stable_sort(out.begin(), out.end(), [](const ScriptCommand& a, const ScriptCommand& b) {
    return a.frame < b.frame;
  });
  return out;
}

int scriptKey(std::string_view name) {
  if (name.size() == 1) {
    const char ch = name[0];
    if (ch >= 'a' && ch <= 'z') return GLFW_KEY_A + (ch - 'a');
    if (ch >= 'A' && ch <= 'Z') return GLFW_KEY_A + (ch - 'A');
    if (ch >= '0' && ch <= '9') return GLFW_KEY_0 + (ch - '0');
    return 0;
  }
  if (name == "space") return GLFW_KEY_SPACE;
  if (name == "left") return GLFW_KEY_LEFT;
  if (name == "right") return GLFW_KEY_RIGHT;
  if (name == "up") return GLFW_KEY_UP;
  if (name == "down") return GLFW_KEY_DOWN;
  return 0;
}

Ray cameraRay(const Camera& c, int width, int height, double x, double y) {
  const glm::dvec3 eye(c.eye), forward = glm::normalize(glm::dvec3(c.target) - eye);
  const glm::dvec3 right = glm::normalize(glm::cross(forward, glm::dvec3(c.up)));
  const glm::dvec3 up = glm::cross(right, forward);
  const double tanHalf = std::tan(0.5 * double(c.fovYDegrees) * std::numbers::pi / 180);
  const double aspect = double(width) / double(height);
  const double ndcX = 2 * x / width - 1, ndcY = 1 - 2 * y / height;
  Ray r;
  r.origin = eye;
  r.direction = glm::normalize(forward + ndcX * tanHalf * aspect * right + ndcY * tanHalf * up);
  return r;
}

StrokeBlade strokeBlade(const Camera& camera, int width, int height, double x1, double y1,
                        double x2, double y2) {
  const Ray a = cameraRay(camera, width, height, x1, y1);
  const Ray b = cameraRay(camera, width, height, x2, y2);
  const double nearD = camera.nearPlane, farD = camera.farPlane;
  StrokeBlade s;
  for (const glm::dvec3& p : {a.origin + nearD * a.direction, a.origin + farD * a.direction,
                              b.origin + farD * b.direction, b.origin + nearD * b.direction})
    s.vertices.emplace_back(p);
  s.triangles = {0, 1, 2, 0, 2, 3};
  return s;
}

}  // namespace gf::demo
