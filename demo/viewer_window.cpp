// See viewer_window.h: the choice between the Vulkan and the GL presenter.
#include "viewer_window.h"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <cstdio>

namespace gf::demo {

bool parsePresentKind(const std::string& text, PresentKind& out) {
  if (text == "auto")
    out = PresentKind::Auto;
  else if (text == "vulkan")
    out = PresentKind::Vulkan;
  else if (text == "gl")
    out = PresentKind::Gl;
  else
    return false;
  return true;
}

namespace detail {
bool initGlfw() {
  glfwSetErrorCallback(
      [](int code, const char* text) { std::fprintf(stderr, "GLFW error %d: %s\n", code, text); });
  return glfwInit() == GLFW_TRUE;
}
}  // namespace detail

Result<std::unique_ptr<ViewerWindow>> openViewerWindow(const WindowOptions& options,
                                                       bool& noDisplay) {
  noDisplay = false;
  if (options.kind == PresentKind::Gl) return detail::openGlWindow(options, "", noDisplay);
  Result<std::unique_ptr<ViewerWindow>> vk = detail::openVulkanWindow(options, noDisplay);
  if (vk || noDisplay || options.kind == PresentKind::Vulkan) return vk;
  return detail::openGlWindow(options, vk.error().message, noDisplay);
}

}  // namespace gf::demo
