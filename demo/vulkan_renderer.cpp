// Vulkan back end of the demo renderer: headless (no surface, no swapchain), any device the loader
// finds (a GPU where there is one, lavapipe on the CPU otherwise).
//
// Design: one frame is one command buffer, submitted and waited for inside render(), so nothing
// is ever in flight between calls; buffers can be rewritten or re-created at the start of a frame
// without per-frame resource rings. Each mesh slot owns one device-local buffer holding all its
// streams (positions | normals | scalars | indices | crack flags) at aligned offsets, so a slot is
// one allocation and one descriptor set; it grows geometrically and is only re-created when a
// mesh outgrows it. All host data reaches it through one staging buffer per frame.
//
// Shadows: every frame first renders a depth-only pass from the key light into a square depth
// image (cleared only when the frame has no shadows), which the main pass samples with a
// comparison sampler; running the pass always keeps the image in the layout the frame's
// descriptor names.
#include "vulkan_renderer.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <glm/gtc/matrix_transform.hpp>
#include <map>
#include <memory>

#include "renderer.h"
#include "vulkan_device.h"

namespace gf::demo {
namespace {

using detail::GpuBuffer;
using detail::GpuImage;
using detail::vkInfo;

// SPIR-V of demo/shaders/, compiled at build time by glslc (-mfmt=c).
const uint32_t kMeshVert[] =
#include "mesh.vert.inc"
    ;
const uint32_t kMeshFrag[] =
#include "mesh.frag.inc"
    ;
const uint32_t kShadowVert[] =
#include "shadow.vert.inc"
    ;

constexpr uint32_t kShadowSize = 1024;  // texels per side of the shadow map

VkDeviceSize alignUp(VkDeviceSize x, VkDeviceSize a) { return (x + a - 1) / a * a; }

// The GPU copy of one MeshFrame slot.
struct Slot {
  GpuBuffer buffer;
  VkDescriptorSet set = VK_NULL_HANDLE;
  uint32_t vertexCapacity = 0, triangleCapacity = 0;
  VkDeviceSize normalOffset = 0, scalarOffset = 0, indexOffset = 0, crackOffset = 0, uvOffset = 0;
  // What the buffer holds; valid = false forces a full upload.
  bool valid = false;
  uint64_t topologyVersion = 0;
  uint32_t vertices = 0, triangles = 0;
  bool hasScalar = false, hasCrack = false, hasUv = false;
};

// The GPU copy of one Texture: an sRGB image with its mip levels and the descriptor set that
// samples it. `source` keeps the texture alive so its address is never reused as a key.
struct GpuTexture {
  std::shared_ptr<const Texture> source;
  GpuImage image;
  VkDescriptorSet set = VK_NULL_HANDLE;
  bool uploaded = false;  // set once a frame that copied it completed
};

// std140 layout of the Frame block of the shaders.
struct FrameUniforms {
  glm::mat4 viewProj;
  glm::vec4 eye;
  glm::mat4 lightViewProj;
  glm::vec4 shadow;  // on, texel size, normal offset
};
// The Draw push-constant block (128 bytes, the guaranteed maximum).
struct DrawConstants {
  glm::mat4 model;
  glm::vec4 colour;       // w: has scalar
  glm::vec4 crackColour;  // w: has crack flags
  glm::vec4 look;         // specular, shininess, grain, metallic
  glm::vec4 ground;       // grid cell
};

constexpr uint32_t kSetsPerPool = 64;
constexpr uint32_t kMaxTextures = 256;  // texture descriptor sets, the 1x1 white one included

class VulkanRenderer final : public Renderer {
 public:
  ~VulkanRenderer() override;
  Result<void> init(const RendererOptions& options);

  const std::string& description() const override { return m_description; }
  Result<FrameStats> render(std::span<const MeshFrame> meshes, const Camera& camera,
                            const FrameOptions& options, Image& out) override;
  std::vector<std::string> validationMessages() const override { return m_vk.messages(); }

 private:
  Result<void> createTargets();
  Result<void> createRenderPass();
  Result<void> createPipeline();
  Result<void> createShadowPass();
  Result<void> createDescriptors();
  Result<void> growSlot(Slot& slot, uint32_t vertices, uint32_t triangles);
  /// The texture's GPU copy, made (not yet filled) the first time it is seen.
  Result<GpuTexture*> textureFor(const std::shared_ptr<const Texture>& texture);
  Result<FrameStats> renderFrame(std::span<const MeshFrame> meshes, const Camera& camera,
                                 const FrameOptions& options, Image& out);

  // First member: destroyed last, after everything made on it.
  detail::VulkanDevice m_vk;
  VkDevice m_device = VK_NULL_HANDLE;  // m_vk's, for brevity
  std::string m_description;
  int m_width = 0, m_height = 0;
  VkSampleCountFlagBits m_samples = VK_SAMPLE_COUNT_1_BIT;

  GpuImage m_colourMs, m_depth, m_resolved;  // m_colourMs is unused with 1 sample
  VkRenderPass m_renderPass = VK_NULL_HANDLE;
  VkFramebuffer m_framebuffer = VK_NULL_HANDLE;
  VkDescriptorSetLayout m_frameLayout = VK_NULL_HANDLE, m_meshLayout = VK_NULL_HANDLE,
                        m_textureLayout = VK_NULL_HANDLE;
  VkPipelineLayout m_pipelineLayout = VK_NULL_HANDLE;
  VkPipeline m_pipeline = VK_NULL_HANDLE;
  GpuImage m_shadowMap;
  VkRenderPass m_shadowPass = VK_NULL_HANDLE;
  VkFramebuffer m_shadowFramebuffer = VK_NULL_HANDLE;
  VkPipeline m_shadowPipeline = VK_NULL_HANDLE;
  VkSampler m_shadowSampler = VK_NULL_HANDLE;
  VkDescriptorPool m_framePool = VK_NULL_HANDLE;
  VkDescriptorSet m_frameSet = VK_NULL_HANDLE;
  std::vector<VkDescriptorPool> m_meshPools;  // kSetsPerPool mesh sets each
  size_t m_meshSets = 0;                      // sets allocated from m_meshPools

  GpuBuffer m_uniforms, m_staging, m_readback;
  std::vector<Slot> m_slots;
  VkDescriptorPool m_texturePool = VK_NULL_HANDLE;
  VkSampler m_textureSampler = VK_NULL_HANDLE;
  std::map<const Texture*, GpuTexture> m_textures;
  // Bound for untextured meshes: the pipeline layout has the texture set either way.
  std::shared_ptr<const Texture> m_white;

  bool m_broken = false;
  std::string m_brokenReason;
};

Result<void> VulkanRenderer::init(const RendererOptions& options) {
  if (options.width <= 0 || options.height <= 0 || options.width > 8192 || options.height > 8192)
    return fail("Vulkan: size ", std::to_string(options.width), "x", std::to_string(options.height),
                " is outside 1x1 .. 8192x8192");
  m_width = options.width;
  m_height = options.height;
  GF_TRY(m_vk.create(options.validation));
  m_device = m_vk.device();

  // The largest supported power of two not above the request.
  const VkPhysicalDeviceLimits& limits = m_vk.properties().limits;
  const VkSampleCountFlags counts =
      limits.framebufferColorSampleCounts & limits.framebufferDepthSampleCounts;
  m_samples = VK_SAMPLE_COUNT_1_BIT;
  for (int s = 64; s > 1; s /= 2)
    if (s <= options.samples && (counts & VkSampleCountFlags(s))) {
      m_samples = VkSampleCountFlagBits(s);
      break;
    }

  GF_TRY(createTargets());
  GF_TRY(createRenderPass());
  GF_TRY(createShadowPass());
  GF_TRY(createDescriptors());
  GF_TRY(createPipeline());
  m_description = "Vulkan, " + m_vk.name();
  return {};
}

Result<void> VulkanRenderer::createTargets() {
  const VkFormat colour = VK_FORMAT_R8G8B8A8_UNORM;
  if (m_samples != VK_SAMPLE_COUNT_1_BIT)
    GF_TRY(m_vk.createImage(m_width, m_height, colour, VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT,
                            m_samples, VK_IMAGE_ASPECT_COLOR_BIT, m_colourMs));
  GF_TRY(m_vk.createImage(m_width, m_height, m_vk.depthFormat(),
                          VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT, m_samples,
                          VK_IMAGE_ASPECT_DEPTH_BIT, m_depth));
  GF_TRY(m_vk.createImage(m_width, m_height, colour,
                          VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
                          VK_SAMPLE_COUNT_1_BIT, VK_IMAGE_ASPECT_COLOR_BIT, m_resolved));
  // Cached memory makes the CPU's read of the frame fast where the device offers it.
  GF_TRY(m_vk.createBuffer(
      VkDeviceSize(m_width) * VkDeviceSize(m_height) * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
      VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT,
      VK_MEMORY_PROPERTY_HOST_CACHED_BIT, m_readback));
  GF_TRY(m_vk.createBuffer(
      sizeof(FrameUniforms), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT,
      VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT, 0, m_uniforms));
  return {};
}

Result<void> VulkanRenderer::createRenderPass() {
  const bool msaa = m_samples != VK_SAMPLE_COUNT_1_BIT;
  // 0: colour (multisampled when msaa), 1: depth, 2: single-sample resolve target (msaa only).
  VkAttachmentDescription att[3]{};
  att[0].format = VK_FORMAT_R8G8B8A8_UNORM;
  att[0].samples = m_samples;
  att[0].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
  att[0].storeOp = msaa ? VK_ATTACHMENT_STORE_OP_DONT_CARE : VK_ATTACHMENT_STORE_OP_STORE;
  att[0].stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
  att[0].stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
  att[0].initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  att[0].finalLayout =
      msaa ? VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL : VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
  att[1] = att[0];
  att[1].format = m_vk.depthFormat();
  att[1].storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
  att[1].finalLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
  att[2] = att[0];
  att[2].samples = VK_SAMPLE_COUNT_1_BIT;
  att[2].loadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
  att[2].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
  att[2].finalLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;

  const VkAttachmentReference colourRef{0, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
  const VkAttachmentReference depthRef{1, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
  const VkAttachmentReference resolveRef{2, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
  VkSubpassDescription subpass{};
  subpass.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
  subpass.colorAttachmentCount = 1;
  subpass.pColorAttachments = &colourRef;
  subpass.pResolveAttachments = msaa ? &resolveRef : nullptr;
  subpass.pDepthStencilAttachment = &depthRef;

  // In: the previous frame's attachment use and readback copy finish before this frame's
  // clears (write-after-read/write). Out: the resolved image is complete before the copy.
  VkSubpassDependency deps[2]{};
  deps[0].srcSubpass = VK_SUBPASS_EXTERNAL;
  deps[0].dstSubpass = 0;
  deps[0].srcStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT |
                         VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT;
  deps[0].dstStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT |
                         VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT |
                         VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
  deps[0].srcAccessMask =
      VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT;
  deps[0].dstAccessMask =
      VK_ACCESS_COLOR_ATTACHMENT_READ_BIT | VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT |
      VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT;
  deps[1].srcSubpass = 0;
  deps[1].dstSubpass = VK_SUBPASS_EXTERNAL;
  deps[1].srcStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
  deps[1].dstStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT;
  deps[1].srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
  deps[1].dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;

  auto info = vkInfo<VkRenderPassCreateInfo>(VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO);
  info.attachmentCount = msaa ? 3 : 2;
  info.pAttachments = att;
  info.subpassCount = 1;
  info.pSubpasses = &subpass;
  info.dependencyCount = 2;
  info.pDependencies = deps;
  GF_VK(vkCreateRenderPass, (m_device, &info, nullptr, &m_renderPass));

  const VkImageView views[3] = {msaa ? m_colourMs.view : m_resolved.view, m_depth.view,
                                m_resolved.view};
  auto fb = vkInfo<VkFramebufferCreateInfo>(VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO);
  fb.renderPass = m_renderPass;
  fb.attachmentCount = info.attachmentCount;
  fb.pAttachments = views;
  fb.width = uint32_t(m_width);
  fb.height = uint32_t(m_height);
  fb.layers = 1;
  GF_VK(vkCreateFramebuffer, (m_device, &fb, nullptr, &m_framebuffer));
  return {};
}

Result<void> VulkanRenderer::createShadowPass() {
  const VkFormat format = m_vk.depthFormat();
  const VkFormatFeatureFlags features = m_vk.formatFeatures(format);
  if (!(features & VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT))
    return fail("Vulkan: depth format ", std::to_string(int(format)),
                " cannot be sampled (needed for the shadow map)");
  GF_TRY(m_vk.createImage(int(kShadowSize), int(kShadowSize), format,
                          VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT,
                          VK_SAMPLE_COUNT_1_BIT, VK_IMAGE_ASPECT_DEPTH_BIT, m_shadowMap));

  VkAttachmentDescription att{};
  att.format = format;
  att.samples = VK_SAMPLE_COUNT_1_BIT;
  att.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
  att.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
  att.stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
  att.stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
  att.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  att.finalLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_READ_ONLY_OPTIMAL;
  const VkAttachmentReference depthRef{0, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
  VkSubpassDescription subpass{};
  subpass.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
  subpass.pDepthStencilAttachment = &depthRef;
  // In: the previous frame's sampling finishes before this frame's clear. Out: the depth is
  // written before the main pass samples it.
  VkSubpassDependency deps[2]{};
  deps[0].srcSubpass = VK_SUBPASS_EXTERNAL;
  deps[0].dstSubpass = 0;
  deps[0].srcStageMask = VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT;
  deps[0].dstStageMask =
      VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
  deps[0].srcAccessMask = VK_ACCESS_SHADER_READ_BIT;
  deps[0].dstAccessMask =
      VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT;
  deps[1].srcSubpass = 0;
  deps[1].dstSubpass = VK_SUBPASS_EXTERNAL;
  deps[1].srcStageMask = VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
  deps[1].dstStageMask = VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT;
  deps[1].srcAccessMask = VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT;
  deps[1].dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
  auto info = vkInfo<VkRenderPassCreateInfo>(VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO);
  info.attachmentCount = 1;
  info.pAttachments = &att;
  info.subpassCount = 1;
  info.pSubpasses = &subpass;
  info.dependencyCount = 2;
  info.pDependencies = deps;
  GF_VK(vkCreateRenderPass, (m_device, &info, nullptr, &m_shadowPass));
  auto fb = vkInfo<VkFramebufferCreateInfo>(VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO);
  fb.renderPass = m_shadowPass;
  fb.attachmentCount = 1;
  fb.pAttachments = &m_shadowMap.view;
  fb.width = kShadowSize;
  fb.height = kShadowSize;
  fb.layers = 1;
  GF_VK(vkCreateFramebuffer, (m_device, &fb, nullptr, &m_shadowFramebuffer));

  // Outside the map counts as lit (border depth 1); bilinear comparison where the format
  // allows it softens the edges a little more.
  const bool linear = features & VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT;
  auto sampler = vkInfo<VkSamplerCreateInfo>(VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO);
  sampler.magFilter = sampler.minFilter = linear ? VK_FILTER_LINEAR : VK_FILTER_NEAREST;
  sampler.mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST;
  sampler.addressModeU = sampler.addressModeV = sampler.addressModeW =
      VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_BORDER;
  sampler.borderColor = VK_BORDER_COLOR_FLOAT_OPAQUE_WHITE;
  sampler.compareEnable = VK_TRUE;
  sampler.compareOp = VK_COMPARE_OP_LESS_OR_EQUAL;
  sampler.maxLod = 0.0f;
  GF_VK(vkCreateSampler, (m_device, &sampler, nullptr, &m_shadowSampler));
  return {};
}

Result<void> VulkanRenderer::createDescriptors() {
  VkDescriptorSetLayoutBinding frame{};
  frame.binding = 0;
  frame.descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
  frame.descriptorCount = 1;
  frame.stageFlags = VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT;
  VkDescriptorSetLayoutBinding frameBindings[2] = {frame, frame};
  frameBindings[1].binding = 1;
  frameBindings[1].descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
  frameBindings[1].stageFlags = VK_SHADER_STAGE_FRAGMENT_BIT;
  auto info =
      vkInfo<VkDescriptorSetLayoutCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO);
  info.bindingCount = 2;
  info.pBindings = frameBindings;
  GF_VK(vkCreateDescriptorSetLayout, (m_device, &info, nullptr, &m_frameLayout));

  // 0: crack flags (fragment), 1: scalars (vertex), 2: texture coordinates (vertex).
  VkDescriptorSetLayoutBinding mesh[3]{};
  mesh[0].binding = 0;
  mesh[0].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  mesh[0].descriptorCount = 1;
  mesh[0].stageFlags = VK_SHADER_STAGE_FRAGMENT_BIT;
  mesh[1] = mesh[0];
  mesh[1].binding = 1;
  mesh[1].stageFlags = VK_SHADER_STAGE_VERTEX_BIT;
  mesh[2] = mesh[1];
  mesh[2].binding = 2;
  info.bindingCount = 3;
  info.pBindings = mesh;
  GF_VK(vkCreateDescriptorSetLayout, (m_device, &info, nullptr, &m_meshLayout));

  // Set 2: the mesh's colour texture.
  VkDescriptorSetLayoutBinding texture{};
  texture.binding = 0;
  texture.descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
  texture.descriptorCount = 1;
  texture.stageFlags = VK_SHADER_STAGE_FRAGMENT_BIT;
  info.bindingCount = 1;
  info.pBindings = &texture;
  GF_VK(vkCreateDescriptorSetLayout, (m_device, &info, nullptr, &m_textureLayout));
  const VkDescriptorPoolSize textureSize{VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, kMaxTextures};
  auto texturePool =
      vkInfo<VkDescriptorPoolCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO);
  texturePool.maxSets = kMaxTextures;
  texturePool.poolSizeCount = 1;
  texturePool.pPoolSizes = &textureSize;
  GF_VK(vkCreateDescriptorPool, (m_device, &texturePool, nullptr, &m_texturePool));
  // Trilinear where the format filters linearly (lavapipe and GPUs do), repeating like GL's.
  const bool linear = m_vk.formatFeatures(VK_FORMAT_R8G8B8A8_SRGB) &
                      VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT;
  auto sampler = vkInfo<VkSamplerCreateInfo>(VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO);
  sampler.magFilter = sampler.minFilter = linear ? VK_FILTER_LINEAR : VK_FILTER_NEAREST;
  sampler.mipmapMode = linear ? VK_SAMPLER_MIPMAP_MODE_LINEAR : VK_SAMPLER_MIPMAP_MODE_NEAREST;
  sampler.addressModeU = sampler.addressModeV = sampler.addressModeW =
      VK_SAMPLER_ADDRESS_MODE_REPEAT;
  sampler.maxLod = VK_LOD_CLAMP_NONE;
  GF_VK(vkCreateSampler, (m_device, &sampler, nullptr, &m_textureSampler));
  Image white;
  white.width = white.height = 1;
  white.rgba = {255, 255, 255, 255};
  Result<std::shared_ptr<const Texture>> w = makeTexture(std::move(white));
  if (!w) return w.error();
  m_white = w.value();

  const VkDescriptorPoolSize sizes[2] = {{VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1},
                                         {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1}};
  auto pool = vkInfo<VkDescriptorPoolCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO);
  pool.maxSets = 1;
  pool.poolSizeCount = 2;
  pool.pPoolSizes = sizes;
  GF_VK(vkCreateDescriptorPool, (m_device, &pool, nullptr, &m_framePool));
  auto alloc = vkInfo<VkDescriptorSetAllocateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO);
  alloc.descriptorPool = m_framePool;
  alloc.descriptorSetCount = 1;
  alloc.pSetLayouts = &m_frameLayout;
  GF_VK(vkAllocateDescriptorSets, (m_device, &alloc, &m_frameSet));
  const VkDescriptorBufferInfo buffer{m_uniforms.buffer, 0, sizeof(FrameUniforms)};
  const VkDescriptorImageInfo shadow{m_shadowSampler, m_shadowMap.view,
                                     VK_IMAGE_LAYOUT_DEPTH_STENCIL_READ_ONLY_OPTIMAL};
  VkWriteDescriptorSet writes[2];
  writes[0] = vkInfo<VkWriteDescriptorSet>(VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET);
  writes[0].dstSet = m_frameSet;
  writes[0].dstBinding = 0;
  writes[0].descriptorCount = 1;
  writes[0].descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
  writes[0].pBufferInfo = &buffer;
  writes[1] = writes[0];
  writes[1].dstBinding = 1;
  writes[1].descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
  writes[1].pBufferInfo = nullptr;
  writes[1].pImageInfo = &shadow;
  vkUpdateDescriptorSets(m_device, 2, writes, 0, nullptr);
  return {};
}

Result<void> VulkanRenderer::createPipeline() {
  const VkDescriptorSetLayout sets[3] = {m_frameLayout, m_meshLayout, m_textureLayout};
  const VkPushConstantRange push{VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0,
                                 sizeof(DrawConstants)};
  auto layout = vkInfo<VkPipelineLayoutCreateInfo>(VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO);
  layout.setLayoutCount = 3;
  layout.pSetLayouts = sets;
  layout.pushConstantRangeCount = 1;
  layout.pPushConstantRanges = &push;
  GF_VK(vkCreatePipelineLayout, (m_device, &layout, nullptr, &m_pipelineLayout));

  // Mesh vertex and fragment stages, then the shadow pass's vertex stage.
  VkShaderModule modules[3] = {VK_NULL_HANDLE, VK_NULL_HANDLE, VK_NULL_HANDLE};
  const std::pair<const uint32_t*, size_t> code[2] = {{kMeshVert, sizeof kMeshVert},
                                                      {kMeshFrag, sizeof kMeshFrag}};
  Result<void> status;
  for (int i = 0; i < 2 && status; ++i) {
    auto info = vkInfo<VkShaderModuleCreateInfo>(VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO);
    info.codeSize = code[i].second;
    info.pCode = code[i].first;
    const VkResult r = vkCreateShaderModule(m_device, &info, nullptr, &modules[i]);
    if (r != VK_SUCCESS) status = detail::vkFail("vkCreateShaderModule", r);
  }
  if (status) {
    VkPipelineShaderStageCreateInfo stages[2]{};
    for (int i = 0; i < 2; ++i) {
      stages[i].sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
      stages[i].stage = i == 0 ? VK_SHADER_STAGE_VERTEX_BIT : VK_SHADER_STAGE_FRAGMENT_BIT;
      stages[i].module = modules[i];
      stages[i].pName = "main";
    }
    // Positions and normals as two float3 streams of the slot buffer.
    const VkVertexInputBindingDescription bindings[2] = {{0, 12, VK_VERTEX_INPUT_RATE_VERTEX},
                                                         {1, 12, VK_VERTEX_INPUT_RATE_VERTEX}};
    const VkVertexInputAttributeDescription attributes[2] = {{0, 0, VK_FORMAT_R32G32B32_SFLOAT, 0},
                                                             {1, 1, VK_FORMAT_R32G32B32_SFLOAT, 0}};
    auto vertex = vkInfo<VkPipelineVertexInputStateCreateInfo>(
        VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO);
    vertex.vertexBindingDescriptionCount = 2;
    vertex.pVertexBindingDescriptions = bindings;
    vertex.vertexAttributeDescriptionCount = 2;
    vertex.pVertexAttributeDescriptions = attributes;
    auto assembly = vkInfo<VkPipelineInputAssemblyStateCreateInfo>(
        VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO);
    assembly.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
    const VkViewport viewport{0, 0, float(m_width), float(m_height), 0, 1};
    const VkRect2D scissor{{0, 0}, {uint32_t(m_width), uint32_t(m_height)}};
    auto viewportState = vkInfo<VkPipelineViewportStateCreateInfo>(
        VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO);
    viewportState.viewportCount = 1;
    viewportState.pViewports = &viewport;
    viewportState.scissorCount = 1;
    viewportState.pScissors = &scissor;
    // No culling (two-sided crack slits). The projection flips y, which keeps the on-screen
    // winding of GL: counter-clockwise is front.
    auto raster = vkInfo<VkPipelineRasterizationStateCreateInfo>(
        VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO);
    raster.polygonMode = VK_POLYGON_MODE_FILL;
    raster.cullMode = VK_CULL_MODE_NONE;
    raster.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;
    raster.lineWidth = 1.0f;
    auto multisample = vkInfo<VkPipelineMultisampleStateCreateInfo>(
        VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO);
    multisample.rasterizationSamples = m_samples;
    auto depth = vkInfo<VkPipelineDepthStencilStateCreateInfo>(
        VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO);
    depth.depthTestEnable = VK_TRUE;
    depth.depthWriteEnable = VK_TRUE;
    depth.depthCompareOp = VK_COMPARE_OP_LESS;
    VkPipelineColorBlendAttachmentState blendAttachment{};
    blendAttachment.colorWriteMask = VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT |
                                     VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;
    auto blend = vkInfo<VkPipelineColorBlendStateCreateInfo>(
        VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO);
    blend.attachmentCount = 1;
    blend.pAttachments = &blendAttachment;

    auto info =
        vkInfo<VkGraphicsPipelineCreateInfo>(VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO);
    info.stageCount = 2;
    info.pStages = stages;
    info.pVertexInputState = &vertex;
    info.pInputAssemblyState = &assembly;
    info.pViewportState = &viewportState;
    info.pRasterizationState = &raster;
    info.pMultisampleState = &multisample;
    info.pDepthStencilState = &depth;
    info.pColorBlendState = &blend;
    info.layout = m_pipelineLayout;
    info.renderPass = m_renderPass;
    info.subpass = 0;
    VkResult r =
        vkCreateGraphicsPipelines(m_device, VK_NULL_HANDLE, 1, &info, nullptr, &m_pipeline);
    if (r != VK_SUCCESS) status = detail::vkFail("vkCreateGraphicsPipelines", r);

    // The shadow pass: positions only, no fragment stage, one sample, slope-scaled depth bias
    // against self-shadowing stripes ("acne") on lit faces.
    auto module = vkInfo<VkShaderModuleCreateInfo>(VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO);
    module.codeSize = sizeof kShadowVert;
    module.pCode = kShadowVert;
    if (status) {
      r = vkCreateShaderModule(m_device, &module, nullptr, &modules[2]);
      if (r != VK_SUCCESS) {
        modules[2] = VK_NULL_HANDLE;
        status = detail::vkFail("vkCreateShaderModule", r);
      }
    }
    if (status) {
      stages[0].module = modules[2];
      vertex.vertexBindingDescriptionCount = 1;
      vertex.vertexAttributeDescriptionCount = 1;
      const VkViewport shadowViewport{0, 0, float(kShadowSize), float(kShadowSize), 0, 1};
      const VkRect2D shadowScissor{{0, 0}, {kShadowSize, kShadowSize}};
      viewportState.pViewports = &shadowViewport;
      viewportState.pScissors = &shadowScissor;
      raster.depthBiasEnable = VK_TRUE;
      raster.depthBiasConstantFactor = 2.0f;
      raster.depthBiasSlopeFactor = 2.0f;
      multisample.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
      depth.depthCompareOp = VK_COMPARE_OP_LESS_OR_EQUAL;
      info.stageCount = 1;
      info.pColorBlendState = nullptr;
      info.renderPass = m_shadowPass;
      r = vkCreateGraphicsPipelines(m_device, VK_NULL_HANDLE, 1, &info, nullptr, &m_shadowPipeline);
      if (r != VK_SUCCESS) status = detail::vkFail("vkCreateGraphicsPipelines (shadow)", r);
    }
  }
  for (VkShaderModule m : modules)
    if (m) vkDestroyShaderModule(m_device, m, nullptr);
  return status;
}

VulkanRenderer::~VulkanRenderer() {
  if (!m_device) return;
  // Nothing can be done about a failure here; destruction goes on regardless.
  (void)vkDeviceWaitIdle(m_device);
  for (Slot& s : m_slots) m_vk.destroyBuffer(s.buffer);
  for (VkDescriptorPool p : m_meshPools) vkDestroyDescriptorPool(m_device, p, nullptr);
  for (auto& [key, t] : m_textures) m_vk.destroyImage(t.image);
  if (m_texturePool) vkDestroyDescriptorPool(m_device, m_texturePool, nullptr);
  if (m_textureSampler) vkDestroySampler(m_device, m_textureSampler, nullptr);
  if (m_textureLayout) vkDestroyDescriptorSetLayout(m_device, m_textureLayout, nullptr);
  if (m_framePool) vkDestroyDescriptorPool(m_device, m_framePool, nullptr);
  m_vk.destroyBuffer(m_staging);
  m_vk.destroyBuffer(m_readback);
  m_vk.destroyBuffer(m_uniforms);
  if (m_pipeline) vkDestroyPipeline(m_device, m_pipeline, nullptr);
  if (m_shadowPipeline) vkDestroyPipeline(m_device, m_shadowPipeline, nullptr);
  if (m_shadowSampler) vkDestroySampler(m_device, m_shadowSampler, nullptr);
  if (m_shadowFramebuffer) vkDestroyFramebuffer(m_device, m_shadowFramebuffer, nullptr);
  if (m_shadowPass) vkDestroyRenderPass(m_device, m_shadowPass, nullptr);
  if (m_pipelineLayout) vkDestroyPipelineLayout(m_device, m_pipelineLayout, nullptr);
  if (m_meshLayout) vkDestroyDescriptorSetLayout(m_device, m_meshLayout, nullptr);
  if (m_frameLayout) vkDestroyDescriptorSetLayout(m_device, m_frameLayout, nullptr);
  if (m_framebuffer) vkDestroyFramebuffer(m_device, m_framebuffer, nullptr);
  if (m_renderPass) vkDestroyRenderPass(m_device, m_renderPass, nullptr);
  m_vk.destroyImage(m_colourMs);
  m_vk.destroyImage(m_depth);
  m_vk.destroyImage(m_resolved);
  m_vk.destroyImage(m_shadowMap);
}

// Makes the slot hold at least `vertices` and `triangles`: the buffer is re-created (contents
// lost) with 1.5x headroom when it is too small, and kept as is otherwise.
Result<void> VulkanRenderer::growSlot(Slot& slot, uint32_t vertices, uint32_t triangles) {
  if (slot.buffer.buffer && vertices <= slot.vertexCapacity && triangles <= slot.triangleCapacity)
    return {};
  const auto grow = [](uint32_t have, uint32_t need) {
    return need <= have ? have : std::max({need, have + have / 2, 64u});
  };
  const uint32_t vCap = grow(slot.vertexCapacity, vertices);
  const uint32_t tCap = grow(slot.triangleCapacity, triangles);
  slot.valid = false;
  slot.vertexCapacity = slot.triangleCapacity = 0;  // until the new buffer exists
  m_vk.destroyBuffer(slot.buffer);
  const VkDeviceSize align =
      std::max<VkDeviceSize>(256, m_vk.properties().limits.minStorageBufferOffsetAlignment);
  slot.normalOffset = alignUp(VkDeviceSize(vCap) * 12, align);
  slot.scalarOffset = alignUp(slot.normalOffset + VkDeviceSize(vCap) * 12, align);
  slot.indexOffset = alignUp(slot.scalarOffset + VkDeviceSize(vCap) * 4, align);
  slot.crackOffset = alignUp(slot.indexOffset + VkDeviceSize(tCap) * 12, align);
  slot.uvOffset = alignUp(slot.crackOffset + VkDeviceSize(tCap) * 4, align);
  GF_TRY(m_vk.createBuffer(slot.uvOffset + VkDeviceSize(vCap) * 8,
                           VK_BUFFER_USAGE_VERTEX_BUFFER_BIT | VK_BUFFER_USAGE_INDEX_BUFFER_BIT |
                               VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                               VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                           0, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, slot.buffer));

  if (!slot.set) {
    // Mesh sets come from pools of kSetsPerPool, added as slots are.
    if (m_meshSets == m_meshPools.size() * kSetsPerPool) {
      const VkDescriptorPoolSize size{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 3 * kSetsPerPool};
      auto pool = vkInfo<VkDescriptorPoolCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO);
      pool.maxSets = kSetsPerPool;
      pool.poolSizeCount = 1;
      pool.pPoolSizes = &size;
      VkDescriptorPool p = VK_NULL_HANDLE;
      GF_VK(vkCreateDescriptorPool, (m_device, &pool, nullptr, &p));
      m_meshPools.push_back(p);
    }
    auto alloc =
        vkInfo<VkDescriptorSetAllocateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO);
    alloc.descriptorPool = m_meshPools.back();
    alloc.descriptorSetCount = 1;
    alloc.pSetLayouts = &m_meshLayout;
    GF_VK(vkAllocateDescriptorSets, (m_device, &alloc, &slot.set));
    ++m_meshSets;
  }
  // Safe to rewrite: the previous frame finished inside its render().
  const VkDescriptorBufferInfo cracks{slot.buffer.buffer, slot.crackOffset, VkDeviceSize(tCap) * 4};
  const VkDescriptorBufferInfo scalars{slot.buffer.buffer, slot.scalarOffset,
                                       VkDeviceSize(vCap) * 4};
  const VkDescriptorBufferInfo uvs{slot.buffer.buffer, slot.uvOffset, VkDeviceSize(vCap) * 8};
  const VkDescriptorBufferInfo* infos[3] = {&cracks, &scalars, &uvs};
  VkWriteDescriptorSet writes[3]{};
  for (int i = 0; i < 3; ++i) {
    writes[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
    writes[i].dstSet = slot.set;
    writes[i].dstBinding = uint32_t(i);
    writes[i].descriptorCount = 1;
    writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    writes[i].pBufferInfo = infos[i];
  }
  vkUpdateDescriptorSets(m_device, 3, writes, 0, nullptr);
  slot.vertexCapacity = vCap;
  slot.triangleCapacity = tCap;
  return {};
}

Result<GpuTexture*> VulkanRenderer::textureFor(const std::shared_ptr<const Texture>& texture) {
  auto it = m_textures.find(texture.get());
  if (it != m_textures.end()) return &it->second;
  if (m_textures.size() >= kMaxTextures)
    return fail("Vulkan: more than ", std::to_string(kMaxTextures - 1), " textures");
  const Image& base = texture->levels.at(0);
  GpuTexture t;
  t.source = texture;
  GF_TRY(m_vk.createImage(base.width, base.height, VK_FORMAT_R8G8B8A8_SRGB,
                          VK_IMAGE_USAGE_TRANSFER_DST_BIT | VK_IMAGE_USAGE_SAMPLED_BIT,
                          VK_SAMPLE_COUNT_1_BIT, VK_IMAGE_ASPECT_COLOR_BIT, t.image,
                          uint32_t(texture->levels.size())));
  auto alloc = vkInfo<VkDescriptorSetAllocateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO);
  alloc.descriptorPool = m_texturePool;
  alloc.descriptorSetCount = 1;
  alloc.pSetLayouts = &m_textureLayout;
  if (const VkResult r = vkAllocateDescriptorSets(m_device, &alloc, &t.set); r != VK_SUCCESS) {
    m_vk.destroyImage(t.image);
    return detail::vkFail("vkAllocateDescriptorSets (texture)", r);
  }
  const VkDescriptorImageInfo image{m_textureSampler, t.image.view,
                                    VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
  auto write = vkInfo<VkWriteDescriptorSet>(VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET);
  write.dstSet = t.set;
  write.dstBinding = 0;
  write.descriptorCount = 1;
  write.descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
  write.pImageInfo = &image;
  vkUpdateDescriptorSets(m_device, 1, &write, 0, nullptr);
  return &m_textures.emplace(texture.get(), std::move(t)).first->second;
}

Result<FrameStats> VulkanRenderer::render(std::span<const MeshFrame> meshes, const Camera& camera,
                                          const FrameOptions& options, Image& out) {
  if (m_broken) return fail("Vulkan: renderer unusable after an earlier error: ", m_brokenReason);
  Result<FrameStats> r = renderFrame(meshes, camera, options, out);
  if (!r) {
    // The slots may hold partial uploads: the next frame re-uploads everything.
    for (Slot& s : m_slots) s.valid = false;
  }
  return r;
}

Result<FrameStats> VulkanRenderer::renderFrame(std::span<const MeshFrame> meshes,
                                               const Camera& camera, const FrameOptions& options,
                                               Image& out) {
  const auto start = std::chrono::steady_clock::now();
  VkCommandBuffer cmd = m_vk.commandBuffer();
  VkFence fence = m_vk.fence();
  FrameStats stats;

  // Check the inputs and plan the copies: a full upload when the topology or a size changed,
  // otherwise the dirty vertex range only.
  struct Plan {
    uint32_t vertices, triangles;
    bool hasScalar, hasCrack, hasUv, full;
    uint32_t begin, end;  // dirty vertex range of a partial upload
  };
  std::vector<Plan> plans(meshes.size());
  VkDeviceSize stagingBytes = 0;
  for (size_t i = 0; i < meshes.size(); ++i) {
    const MeshFrame& m = meshes[i];
    const std::string name = "Vulkan: mesh " + std::to_string(i) + ": ";
    if (m.positions.size() % 3 != 0 || m.indices.size() % 3 != 0)
      return fail(name, "positions (", std::to_string(m.positions.size()), ") or indices (",
                  std::to_string(m.indices.size()), ") are not a multiple of 3");
    if (m.positions.size() / 3 > UINT32_MAX / 12 || m.indices.size() / 3 > UINT32_MAX / 12)
      return fail(name, std::to_string(m.positions.size() / 3), " vertices or ",
                  std::to_string(m.indices.size() / 3), " triangles: over the 2^32 / 12 limit");
    Plan& p = plans[i];
    p.vertices = uint32_t(m.positions.size() / 3);
    p.triangles = uint32_t(m.indices.size() / 3);
    if (m.normals.size() != m.positions.size())
      return fail(name, "normals has ", std::to_string(m.normals.size()), " floats, positions ",
                  std::to_string(m.positions.size()));
    if (!m.scalar.empty() && m.scalar.size() != p.vertices)
      return fail(name, "scalar has ", std::to_string(m.scalar.size()), " values for ",
                  std::to_string(p.vertices), " vertices");
    if (!m.crackMask.empty() && m.crackMask.size() != p.triangles)
      return fail(name, "crackMask has ", std::to_string(m.crackMask.size()), " flags for ",
                  std::to_string(p.triangles), " triangles");
    if (m.dirtyBegin > m.dirtyEnd || m.dirtyEnd > p.vertices)
      return fail(name, "dirty range [", std::to_string(m.dirtyBegin), ", ",
                  std::to_string(m.dirtyEnd), ") is outside 0..", std::to_string(p.vertices));
    bool textured = m.texture != nullptr;
    for (const DrawRange& r : m.ranges) {
      if (uint64_t(r.firstTriangle) + r.triangleCount > p.triangles ||
          r.firstTriangle >= kMaxRangeStart)
        return fail(name, "range of triangles [", std::to_string(r.firstTriangle), ", ",
                    std::to_string(uint64_t(r.firstTriangle) + r.triangleCount), ") is outside 0..",
                    std::to_string(p.triangles), " (or starts past 2^24)");
      textured = textured || r.texture != nullptr;
    }
    if (textured && m.uvs.size() != 2 * size_t(p.vertices))
      return fail(name, "uvs has ", std::to_string(m.uvs.size()), " values for ",
                  std::to_string(p.vertices), " vertices (2 each, needed with a texture)");
    p.hasScalar = !m.scalar.empty();
    p.hasCrack = !m.crackMask.empty();
    p.hasUv = textured;
    const VkDeviceSize vertexBytes = p.hasScalar ? 28 : 24;
    const VkDeviceSize fullBytes = p.vertices * vertexBytes +
                                   VkDeviceSize(p.triangles) * (p.hasCrack ? 16 : 12) +
                                   (p.hasUv ? VkDeviceSize(p.vertices) * 8 : 0);
    stats.surfaceBytes += fullBytes;
    const Slot* s = i < m_slots.size() ? &m_slots[i] : nullptr;
    p.full = !s || !s->valid || s->topologyVersion != m.topologyVersion ||
             s->vertices != p.vertices || s->triangles != p.triangles ||
             s->hasScalar != p.hasScalar || s->hasCrack != p.hasCrack || s->hasUv != p.hasUv;
    if (p.full) {
      // Indices are checked once per topology: out-of-range reads are undefined on the device.
      for (uint32_t index : m.indices)
        if (index >= p.vertices)
          return fail(name, "index ", std::to_string(index), " >= vertex count ",
                      std::to_string(p.vertices));
      stagingBytes += fullBytes;
    } else {
      p.begin = m.dirtyBegin;
      p.end = m.dirtyEnd;
      stagingBytes += VkDeviceSize(p.end - p.begin) * vertexBytes;
    }
  }
  if (m_slots.size() < meshes.size()) m_slots.resize(meshes.size());
  // Everything that can fail comes before recording starts, so a failed frame never leaves the
  // command buffer half-recorded.
  for (size_t i = 0; i < meshes.size(); ++i)
    if (plans[i].full)
      GF_TRY(
          growSlot(m_slots[i], std::max(plans[i].vertices, 1u), std::max(plans[i].triangles, 1u)));

  // Each mesh's texture set (the white one without a texture); textures not yet on the device
  // are copied, every mip level, at the start of this frame's commands.
  // A mesh drawn in ranges (MeshFrame::ranges) has one per range, after the meshes' own.
  std::vector<GpuTexture*> textures(meshes.size());
  std::vector<size_t> rangeTextures(meshes.size(), 0);
  std::vector<GpuTexture*> fresh;
  auto use = [&](const std::shared_ptr<const Texture>& texture) -> Result<GpuTexture*> {
    Result<GpuTexture*> t = textureFor(texture ? texture : m_white);
    if (!t) return t.error();
    if (!t.value()->uploaded && std::find(fresh.begin(), fresh.end(), t.value()) == fresh.end()) {
      fresh.push_back(t.value());
      for (const Image& l : t.value()->source->levels) stagingBytes += l.rgba.size();
    }
    return t.value();
  };
  for (size_t i = 0; i < meshes.size(); ++i) {
    Result<GpuTexture*> t = use(plans[i].hasUv ? meshes[i].texture : nullptr);
    if (!t) return t.error();
    textures[i] = t.value();
  }
  for (size_t i = 0; i < meshes.size(); ++i) {
    rangeTextures[i] = textures.size();
    for (const DrawRange& r : meshes[i].ranges) {
      Result<GpuTexture*> t = use(r.texture);
      if (!t) return t.error();
      textures.push_back(t.value());
    }
  }

  if (stagingBytes > m_staging.size) {
    const VkDeviceSize size = std::max(stagingBytes, m_staging.size + m_staging.size / 2);
    m_vk.destroyBuffer(m_staging);
    GF_TRY(m_vk.createBuffer(
        size, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT, 0, m_staging));
  }

  auto begin = vkInfo<VkCommandBufferBeginInfo>(VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO);
  begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  GF_VK(vkBeginCommandBuffer, (cmd, &begin));

  // Fill the staging buffer and record one copy per stream.
  auto* staging = static_cast<uint8_t*>(m_staging.mapped);
  VkDeviceSize cursor = 0;
  VkDeviceSize textureBytes = 0;
  for (GpuTexture* t : fresh) {
    const uint32_t levels = uint32_t(t->source->levels.size());
    auto toLayout = [&](VkImageLayout from, VkImageLayout to, VkAccessFlags srcAccess,
                        VkAccessFlags dstAccess, VkPipelineStageFlags srcStage,
                        VkPipelineStageFlags dstStage) {
      auto barrier = vkInfo<VkImageMemoryBarrier>(VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER);
      barrier.oldLayout = from;
      barrier.newLayout = to;
      barrier.srcAccessMask = srcAccess;
      barrier.dstAccessMask = dstAccess;
      barrier.srcQueueFamilyIndex = barrier.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
      barrier.image = t->image.image;
      barrier.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, levels, 0, 1};
      vkCmdPipelineBarrier(cmd, srcStage, dstStage, 0, 0, nullptr, 0, nullptr, 1, &barrier);
    };
    toLayout(VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0,
             VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT,
             VK_PIPELINE_STAGE_TRANSFER_BIT);
    std::vector<VkBufferImageCopy> regions(levels);
    for (uint32_t l = 0; l < levels; ++l) {
      const Image& level = t->source->levels[l];
      std::memcpy(staging + cursor, level.rgba.data(), level.rgba.size());
      regions[l] = VkBufferImageCopy{};
      regions[l].bufferOffset = cursor;
      regions[l].imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, l, 0, 1};
      regions[l].imageExtent = {uint32_t(level.width), uint32_t(level.height), 1};
      cursor += level.rgba.size();
      textureBytes += level.rgba.size();
    }
    vkCmdCopyBufferToImage(cmd, m_staging.buffer, t->image.image,
                           VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, levels, regions.data());
    toLayout(VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
             VK_ACCESS_TRANSFER_WRITE_BIT, VK_ACCESS_SHADER_READ_BIT,
             VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT);
  }
  std::vector<VkBufferCopy> copies;
  for (size_t i = 0; i < meshes.size(); ++i) {
    const MeshFrame& m = meshes[i];
    const Plan& p = plans[i];
    const Slot& s = m_slots[i];
    copies.clear();
    auto stage = [&](const void* src, VkDeviceSize bytes, VkDeviceSize dst) {
      if (bytes == 0) return;
      std::memcpy(staging + cursor, src, bytes);
      copies.push_back({cursor, dst, bytes});
      cursor += bytes;
    };
    const uint32_t b = p.full ? 0 : p.begin, e = p.full ? p.vertices : p.end;
    stage(m.positions.data() + 3 * size_t(b), VkDeviceSize(e - b) * 12, VkDeviceSize(b) * 12);
    stage(m.normals.data() + 3 * size_t(b), VkDeviceSize(e - b) * 12,
          s.normalOffset + VkDeviceSize(b) * 12);
    if (p.hasScalar)
      stage(m.scalar.data() + b, VkDeviceSize(e - b) * 4, s.scalarOffset + VkDeviceSize(b) * 4);
    if (p.full) {
      stage(m.indices.data(), VkDeviceSize(p.triangles) * 12, s.indexOffset);
      if (p.hasUv) stage(m.uvs.data(), VkDeviceSize(p.vertices) * 8, s.uvOffset);
      if (p.hasCrack && p.triangles > 0) {
        // One uint per triangle: the shaders index it by gl_PrimitiveID.
        auto* flags = reinterpret_cast<uint32_t*>(staging + cursor);
        for (uint32_t t = 0; t < p.triangles; ++t) flags[t] = m.crackMask[t] ? 1u : 0u;
        copies.push_back({cursor, s.crackOffset, VkDeviceSize(p.triangles) * 4});
        cursor += VkDeviceSize(p.triangles) * 4;
      }
    }
    if (!copies.empty())
      vkCmdCopyBuffer(cmd, m_staging.buffer, s.buffer.buffer, uint32_t(copies.size()),
                      copies.data());
  }
  stats.uploadedBytes = cursor - textureBytes;  // vertices and indices, as surfaceBytes counts

  auto uploaded = vkInfo<VkMemoryBarrier>(VK_STRUCTURE_TYPE_MEMORY_BARRIER);
  uploaded.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  uploaded.dstAccessMask =
      VK_ACCESS_VERTEX_ATTRIBUTE_READ_BIT | VK_ACCESS_INDEX_READ_BIT | VK_ACCESS_SHADER_READ_BIT;
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                       VK_PIPELINE_STAGE_VERTEX_INPUT_BIT | VK_PIPELINE_STAGE_VERTEX_SHADER_BIT |
                           VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT,
                       0, 1, &uploaded, 0, nullptr, 0, nullptr);

  // glm gives GL clip space; Vulkan's has y down and depth in [0, 1].
  const glm::mat4 toVulkan(1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 0.5f, 0, 0, 0, 0.5f, 1);
  FrameUniforms frame;
  frame.viewProj =
      toVulkan *
      glm::perspective(glm::radians(camera.fovYDegrees), float(m_width) / float(m_height),
                       camera.nearPlane, camera.farPlane) *
      glm::lookAt(camera.eye, camera.target, camera.up);
  frame.eye = glm::vec4(camera.eye, 1.0f);
  const glm::mat4 light = shadowViewProj(meshes);
  frame.lightViewProj = toVulkan * light;
  // The normal offset: about two shadow-map texels in world units, so lit faces clear their
  // own depth even at grazing angles.
  const float texelWorld =
      2.0f / (glm::length(glm::vec3(light[0][0], light[1][0], light[2][0])) * float(kShadowSize));
  frame.shadow =
      glm::vec4(options.shadows ? 1.0f : 0.0f, 1.0f / float(kShadowSize), 2.0f * texelWorld, 0.0f);
  std::memcpy(m_uniforms.mapped, &frame, sizeof frame);

  auto draws = [&](bool shadowPass) {
    for (size_t i = 0; i < meshes.size(); ++i) {
      const MeshFrame& m = meshes[i];
      const Plan& p = plans[i];
      const Slot& s = m_slots[i];
      if (p.triangles == 0 || (shadowPass && !m.castsShadow)) continue;
      DrawConstants draw;
      draw.model = m.model;
      draw.colour = glm::vec4(m.colour, p.hasScalar ? 1.0f : 0.0f);
      draw.crackColour = glm::vec4(m.crackColour, p.hasCrack ? 1.0f : 0.0f);
      draw.look = glm::vec4(m.crackLook.specular, m.crackLook.shininess, m.crackLook.grain,
                            m.crackLook.metallic);
      draw.ground = glm::vec4(m.gridSpacing, p.hasUv ? 1.0f : 0.0f, 0.0f, 0.0f);
      vkCmdPushConstants(cmd, m_pipelineLayout,
                         VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof draw,
                         &draw);
      if (!shadowPass) {
        const VkDescriptorSet sets[2] = {s.set, textures[i]->set};
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, m_pipelineLayout, 1, 2, sets,
                                0, nullptr);
      }
      const VkBuffer buffers[2] = {s.buffer.buffer, s.buffer.buffer};
      const VkDeviceSize offsets[2] = {0, s.normalOffset};
      vkCmdBindVertexBuffers(cmd, 0, shadowPass ? 1 : 2, buffers, offsets);
      vkCmdBindIndexBuffer(cmd, s.buffer.buffer, s.indexOffset, VK_INDEX_TYPE_UINT32);
      if (shadowPass || m.ranges.empty()) {
        vkCmdDrawIndexed(cmd, 3 * p.triangles, 1, 0, 0, 0);
        continue;
      }
      for (size_t k = 0; k < m.ranges.size(); ++k) {
        const DrawRange& r = m.ranges[k];
        if (r.triangleCount == 0) continue;
        draw.colour = glm::vec4(r.colour, draw.colour.w);
        draw.ground =
            glm::vec4(m.gridSpacing, r.texture ? 1.0f : 0.0f, float(r.firstTriangle), 0.0f);
        vkCmdPushConstants(cmd, m_pipelineLayout,
                           VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0,
                           sizeof draw, &draw);
        const VkDescriptorSet set = textures[rangeTextures[i] + k]->set;
        vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, m_pipelineLayout, 2, 1, &set,
                                0, nullptr);
        vkCmdDrawIndexed(cmd, 3 * r.triangleCount, 1, 3 * r.firstTriangle, 0, 0);
      }
    }
  };

  VkClearValue shadowClear{};
  shadowClear.depthStencil = {1.0f, 0};
  auto shadowPass = vkInfo<VkRenderPassBeginInfo>(VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO);
  shadowPass.renderPass = m_shadowPass;
  shadowPass.framebuffer = m_shadowFramebuffer;
  shadowPass.renderArea = {{0, 0}, {kShadowSize, kShadowSize}};
  shadowPass.clearValueCount = 1;
  shadowPass.pClearValues = &shadowClear;
  vkCmdBeginRenderPass(cmd, &shadowPass, VK_SUBPASS_CONTENTS_INLINE);
  if (options.shadows) {
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, m_shadowPipeline);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, m_pipelineLayout, 0, 1,
                            &m_frameSet, 0, nullptr);
    draws(true);
  }
  vkCmdEndRenderPass(cmd);

  VkClearValue clears[3]{};
  clears[0].color = {{0.62f, 0.70f, 0.80f, 1.0f}};
  clears[1].depthStencil = {1.0f, 0};
  auto pass = vkInfo<VkRenderPassBeginInfo>(VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO);
  pass.renderPass = m_renderPass;
  pass.framebuffer = m_framebuffer;
  pass.renderArea = {{0, 0}, {uint32_t(m_width), uint32_t(m_height)}};
  pass.clearValueCount = m_samples != VK_SAMPLE_COUNT_1_BIT ? 3 : 2;
  pass.pClearValues = clears;
  vkCmdBeginRenderPass(cmd, &pass, VK_SUBPASS_CONTENTS_INLINE);
  vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, m_pipeline);
  vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, m_pipelineLayout, 0, 1, &m_frameSet,
                          0, nullptr);
  draws(false);
  vkCmdEndRenderPass(cmd);

  // Rows top to bottom: the flipped projection puts the top of the view in row 0.
  VkBufferImageCopy region{};
  region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  region.imageExtent = {uint32_t(m_width), uint32_t(m_height), 1};
  vkCmdCopyImageToBuffer(cmd, m_resolved.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                         m_readback.buffer, 1, &region);
  auto readable = vkInfo<VkMemoryBarrier>(VK_STRUCTURE_TYPE_MEMORY_BARRIER);
  readable.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  readable.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1,
                       &readable, 0, nullptr, 0, nullptr);
  GF_VK(vkEndCommandBuffer, (cmd));

  auto submit = vkInfo<VkSubmitInfo>(VK_STRUCTURE_TYPE_SUBMIT_INFO);
  submit.commandBufferCount = 1;
  submit.pCommandBuffers = &cmd;
  VkResult r = vkQueueSubmit(m_vk.queue(), 1, &submit, fence);
  if (r == VK_SUCCESS) {
    r = vkWaitForFences(m_device, 1, &fence, VK_TRUE, 60'000'000'000ull);
    if (r == VK_SUCCESS) r = vkResetFences(m_device, 1, &fence);
  }
  if (r != VK_SUCCESS) {
    // The queue's state is unknown (lost device, a frame still running): refuse further frames.
    m_broken = true;
    m_brokenReason = std::string("vkQueueSubmit/vkWaitForFences: ") + detail::vkResultName(r);
    return detail::vkFail("vkQueueSubmit/vkWaitForFences", r);
  }

  for (size_t i = 0; i < meshes.size(); ++i) {
    Slot& s = m_slots[i];
    s.valid = true;
    s.topologyVersion = meshes[i].topologyVersion;
    s.vertices = plans[i].vertices;
    s.triangles = plans[i].triangles;
    s.hasScalar = plans[i].hasScalar;
    s.hasCrack = plans[i].hasCrack;
    s.hasUv = plans[i].hasUv;
  }
  for (GpuTexture* t : fresh) t->uploaded = true;
  out.width = m_width;
  out.height = m_height;
  out.rgba.resize(size_t(m_width) * size_t(m_height) * 4);
  std::memcpy(out.rgba.data(), m_readback.mapped, out.rgba.size());
  drawOverlay(out, options.overlay);
  stats.renderMs =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

}  // namespace

Result<std::unique_ptr<Renderer>> createVulkanRenderer(const RendererOptions& options) {
  auto renderer = std::make_unique<VulkanRenderer>();
  Result<void> ok = renderer->init(options);
  if (!ok) return ok.error();
  return std::unique_ptr<Renderer>(std::move(renderer));
}

}  // namespace gf::demo
