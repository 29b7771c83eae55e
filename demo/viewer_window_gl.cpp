// The GL presenter (viewer_window.h): the picture as a texture drawn by ImGui's OpenGL2 backend
// in a legacy context, which is what Mesa gives under Xvfb without a Vulkan driver.
#define GLFW_INCLUDE_NONE
#include <GL/gl.h>
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <imgui_impl_glfw.h>
#include <imgui_impl_opengl2.h>

#include <cstring>

#include "viewer_window.h"

namespace gf::demo::detail {
namespace {

class GlWindow final : public ViewerWindow {
 public:
  ~GlWindow() override {
    if (m_imgui) {
      ImGui_ImplOpenGL2_Shutdown();
      ImGui_ImplGlfw_Shutdown();
      ImGui::DestroyContext();
    }
    if (m_window) {
      glfwMakeContextCurrent(m_window);
      if (m_texture) glDeleteTextures(1, &m_texture);
      glfwDestroyWindow(m_window);
    }
    if (m_glfw) glfwTerminate();
  }
  bool open(const WindowOptions& o, const std::string& why);
  Result<void> present(const Image& image, const std::function<void()>& panel,
                       Image* contents) override;

 private:
  bool m_glfw = false, m_imgui = false;
  GLuint m_texture = 0;
  int m_texWidth = 0, m_texHeight = 0;
};

bool GlWindow::open(const WindowOptions& o, const std::string& why) {
  m_description = why.empty() ? "gl" : "gl (" + why + ")";
  if (!initGlfw()) return false;
  m_glfw = true;
  glfwDefaultWindowHints();
  glfwWindowHint(GLFW_RESIZABLE, GLFW_FALSE);  // the renderer's size is fixed at creation
  // The GL renderer makes its EGL context current in each render; glvnd lets one thread switch
  // between EGL contexts but not between an EGL and a GLX one, so the window's is EGL too then.
  if (o.eglContext) glfwWindowHint(GLFW_CONTEXT_CREATION_API, GLFW_EGL_CONTEXT_API);
  m_window = glfwCreateWindow(o.width, o.height, "graphfrac-viewer", nullptr, nullptr);
  if (!m_window) return false;
  glfwMakeContextCurrent(m_window);
  glfwSwapInterval(1);
  if (o.installInput) o.installInput(m_window);
  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini next to wherever it was started
  ImGui::StyleColorsDark();
  ImGui_ImplGlfw_InitForOpenGL(m_window, true);
  ImGui_ImplOpenGL2_Init();
  m_imgui = true;
  return true;
}

Result<void> GlWindow::present(const Image& image, const std::function<void()>& panel,
                               Image* contents) {
  // The renderer may have made its own context current.
  glfwMakeContextCurrent(m_window);
  if (!m_texture) {
    glGenTextures(1, &m_texture);
    glBindTexture(GL_TEXTURE_2D, m_texture);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  }
  glBindTexture(GL_TEXTURE_2D, m_texture);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  if (image.width != m_texWidth || image.height != m_texHeight) {
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, image.width, image.height, 0, GL_RGBA,
                 GL_UNSIGNED_BYTE, image.rgba.data());
    m_texWidth = image.width;
    m_texHeight = image.height;
  } else {
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, image.width, image.height, GL_RGBA, GL_UNSIGNED_BYTE,
                    image.rgba.data());
  }
  ImGui_ImplOpenGL2_NewFrame();
  ImGui_ImplGlfw_NewFrame();
  ImGui::NewFrame();
  // The picture's rows are top to bottom, as ImGui's texture coordinates are.
  const ImVec2 size = ImGui::GetIO().DisplaySize;
  ImGui::GetBackgroundDrawList()->AddImage(
      reinterpret_cast<ImTextureID>(static_cast<uintptr_t>(m_texture)), ImVec2(0, 0), size);
  panel();
  ImGui::Render();
  int fbw = 0, fbh = 0;
  glfwGetFramebufferSize(m_window, &fbw, &fbh);
  glViewport(0, 0, fbw, fbh);
  glClearColor(0, 0, 0, 1);
  glClear(GL_COLOR_BUFFER_BIT);
  ImGui_ImplOpenGL2_RenderDrawData(ImGui::GetDrawData());
  if (contents) {
    // GL's rows are bottom up.
    contents->width = fbw;
    contents->height = fbh;
    contents->rgba.assign(size_t(fbw) * size_t(fbh) * 4, 0);
    std::vector<uint8_t> rows(contents->rgba.size());
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glReadBuffer(GL_BACK);
    glReadPixels(0, 0, fbw, fbh, GL_RGBA, GL_UNSIGNED_BYTE, rows.data());
    const size_t row = size_t(fbw) * 4;
    for (int y = 0; y < fbh; ++y)
      std::memcpy(contents->rgba.data() + size_t(y) * row, rows.data() + size_t(fbh - 1 - y) * row,
                  row);
  }
  glfwSwapBuffers(m_window);
  return {};
}

}  // namespace

Result<std::unique_ptr<ViewerWindow>> openGlWindow(const WindowOptions& options,
                                                   const std::string& why, bool& noDisplay) {
  auto w = std::make_unique<GlWindow>();
  if (!w->open(options, why)) {
    noDisplay = true;
    return fail("cannot open a window");
  }
  return std::unique_ptr<ViewerWindow>(std::move(w));
}

}  // namespace gf::demo::detail
