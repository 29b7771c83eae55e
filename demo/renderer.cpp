// Back-end choice: Vulkan first (a GPU where there is one, lavapipe otherwise), then OpenGL
// through EGL.
#include "renderer.h"

#include <algorithm>
#include <cmath>
#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/geometric.hpp>

namespace gf::demo {

CrackLook crackLook(const std::string& interior) {
  // Glass breaks into polished conchoidal faces; bread crumb is matte and porous; steel shows a
  // bright, colour-tinted fibrous face.
  if (interior == "glass") return {0.55f, 220.0f, 0.0f, 0.0f};
  if (interior == "crumb") return {0.03f, 6.0f, 0.45f, 0.0f};
  if (interior == "steel") return {0.5f, 40.0f, 0.15f, 1.0f};
  return {};
}

glm::mat4 shadowViewProj(std::span<const MeshFrame> meshes) {
  glm::vec3 lo(1e30f), hi(-1e30f);
  for (const MeshFrame& m : meshes) {
    if (!m.castsShadow) continue;
    for (size_t i = 0; i + 2 < m.positions.size(); i += 3) {
      const glm::vec3 p(m.model *
                        glm::vec4(m.positions[i], m.positions[i + 1], m.positions[i + 2], 1));
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
  }
  if (!(lo.x <= hi.x)) return glm::mat4(1.0f);
  const glm::vec3 centre = 0.5f * (lo + hi);
  const float radius = std::max(0.5f * glm::length(hi - lo), 1e-3f);
  const glm::vec3 light = glm::normalize(kKeyLight);
  // Far enough back that everything the casters can shadow (down to a floor below them) is in
  // the depth range; the shaders clamp depths beyond it to the far plane (unshadowed there).
  const glm::mat4 view = glm::lookAt(centre + 2.0f * radius * light, centre, glm::vec3(0, 0, 1));
  return glm::ortho(-radius, radius, -radius, radius, 0.5f * radius, 6.0f * radius) * view;
}

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

bool parseRendererKind(std::string_view name, RendererKind& kind) {
  if (name == "auto")
    kind = RendererKind::Auto;
  else if (name == "vulkan")
    kind = RendererKind::Vulkan;
  else if (name == "gl")
    kind = RendererKind::Gl;
  else
    return false;
  return true;
}

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
