// Back-end choice: Vulkan first (a GPU where there is one, lavapipe otherwise), then OpenGL
// through EGL.
#include "renderer.h"

namespace gf::demo {

#ifndef GF_DEMO_HAS_VULKAN
Result<std::unique_ptr<Renderer>> createVulkanRenderer(const RendererOptions&) {
  return fail("Vulkan renderer: not built (Vulkan headers or glslc were not found at configure)");
}
#endif
#ifndef GF_DEMO_HAS_GL
Result<std::unique_ptr<Renderer>> createGlRenderer(const RendererOptions&) {
  return fail("GL renderer: not built (EGL or OpenGL were not found at configure)");
}
#endif

Result<std::unique_ptr<Renderer>> createRenderer(const RendererOptions& options) {
  if (options.width <= 0 || options.height <= 0 || options.width > 8192 || options.height > 8192)
    return fail("renderer: size ", std::to_string(options.width), "x",
                std::to_string(options.height), " is outside 1x1 .. 8192x8192");
  if (options.kind == RendererKind::Vulkan) return createVulkanRenderer(options);
  if (options.kind == RendererKind::Gl) return createGlRenderer(options);
  Result<std::unique_ptr<Renderer>> vk = createVulkanRenderer(options);
  if (vk) return vk;
  Result<std::unique_ptr<Renderer>> gl = createGlRenderer(options);
  if (gl) return gl;
  return fail("no renderer: ", vk.error().message, "; ", gl.error().message);
}

}  // namespace gf::demo
