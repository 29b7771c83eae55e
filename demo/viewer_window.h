// The viewer's window: GLFW, a Dear ImGui context and a way to put the renderer's picture on
// screen behind the panel. Two presenters share this interface: a Vulkan swapchain
// (viewer_window_vulkan.cpp) and the OpenGL fallback (viewer_window_gl.cpp), chosen by
// openViewerWindow.
#pragma once

#include <graphfrac/status.h>

#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "renderer.h"

struct GLFWwindow;

namespace gf::demo {

enum class PresentKind { Auto, Vulkan, Gl };
/// "auto", "vulkan", "gl"; false for anything else.
bool parsePresentKind(const std::string& text, PresentKind& out);

class ViewerWindow {
 public:
  virtual ~ViewerWindow() = default;
  GLFWwindow* handle() const { return m_window; }
  /// "vulkan" or "gl (why not vulkan)", for the exit summary.
  const std::string& description() const { return m_description; }
  /// Shows `image` full-window with the panel that `panel` draws (ImGui calls) over it. With
  /// `contents`, the window's pixels as presented are read back into it (RGBA, rows top down).
  virtual Result<void> present(const Image& image, const std::function<void()>& panel,
                               Image* contents) = 0;
  /// Validation messages of the presenter's own Vulkan device (none for GL).
  virtual std::vector<std::string> validationMessages() const { return {}; }

 protected:
  GLFWwindow* m_window = nullptr;
  std::string m_description;
};

struct WindowOptions {
  int width = 960, height = 540;
  PresentKind kind = PresentKind::Auto;
  bool validation = false;
  /// The GL window's context through EGL (the GL renderer's API: see viewer_window_gl.cpp).
  bool eglContext = false;
  /// Called on the new window before ImGui's GLFW backend chains to its callbacks.
  std::function<void(GLFWwindow*)> installInput;
};

/// Opens the window; Auto tries Vulkan and falls back to GL with the reason in description().
/// Errors: no display (GLFW cannot make a window: `noDisplay` set), or the forced presenter is
/// unavailable (the reason).
Result<std::unique_ptr<ViewerWindow>> openViewerWindow(const WindowOptions& options,
                                                       bool& noDisplay);

namespace detail {
/// The GL presenter; `why` says why Vulkan is not used (empty when GL was asked for).
Result<std::unique_ptr<ViewerWindow>> openGlWindow(const WindowOptions& options,
                                                   const std::string& why, bool& noDisplay);
/// The Vulkan presenter (an error when built without Vulkan).
Result<std::unique_ptr<ViewerWindow>> openVulkanWindow(const WindowOptions& options,
                                                       bool& noDisplay);
/// GLFW initialised once per process for the windows (error callback to stderr).
bool initGlfw();
}  // namespace detail

}  // namespace gf::demo
