// The Vulkan presenter (viewer_window.h): a FIFO swapchain on the window's surface. Each frame
// the renderer's picture goes through a host-visible staging buffer into the acquired swapchain
// image (a copy, the bytes reordered on the host to the swapchain's format, so no blit format
// support is needed), ImGui's Vulkan backend draws the panel over it in one render pass that
// loads the copy, and the image is presented. One frame in flight: the fence of the last
// submission is waited for before the staging buffer is written again.
#include <graphfrac/status.h>

#include "viewer_window.h"

#if defined(GF_DEMO_HAS_VULKAN)

#define GLFW_INCLUDE_NONE
#define GLFW_INCLUDE_VULKAN
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <imgui_impl_glfw.h>
#include <imgui_impl_vulkan.h>

#include <algorithm>
#include <cstring>

#include "vulkan_device.h"

namespace gf::demo::detail {
namespace {

void imguiCheck(VkResult r) {
  if (r != VK_SUCCESS && r < 0)
    std::fprintf(stderr, "graphfrac-viewer: ImGui Vulkan backend: %s\n", vkResultName(r));
}

class VulkanWindow final : public ViewerWindow {
 public:
  ~VulkanWindow() override;
  /// Everything up to the first frame; false with `noDisplay` when GLFW has no window.
  Result<void> open(const WindowOptions& o, bool& noDisplay);
  Result<void> present(const Image& image, const std::function<void()>& panel,
                       Image* contents) override;
  std::vector<std::string> validationMessages() const override { return m_vk.messages(); }

 private:
  Result<void> createSwapchain();
  void destroySwapchain();
  Result<void> createImGui();
  Result<void> record(uint32_t index, const Image& image, bool readBack);

  bool m_glfw = false, m_imguiContext = false, m_imguiGlfw = false, m_imguiVulkan = false;
  VulkanDevice m_vk;
  VkSurfaceKHR m_surface = VK_NULL_HANDLE;
  VkSurfaceFormatKHR m_format{};
  VkSwapchainKHR m_swapchain = VK_NULL_HANDLE;
  VkExtent2D m_extent{};
  std::vector<VkImage> m_images;
  std::vector<VkImageView> m_views;
  std::vector<VkFramebuffer> m_framebuffers;
  std::vector<VkSemaphore> m_rendered;  // per swapchain image: present may still hold it
  VkSemaphore m_acquired = VK_NULL_HANDLE;
  VkRenderPass m_renderPass = VK_NULL_HANDLE;
  VkDescriptorPool m_descriptors = VK_NULL_HANDLE;
  GpuBuffer m_staging, m_readback;
  bool m_inFlight = false;
  uint32_t m_minImages = 2;
};

VulkanWindow::~VulkanWindow() {
  if (m_vk.device()) (void)vkDeviceWaitIdle(m_vk.device());
  if (m_imguiVulkan) ImGui_ImplVulkan_Shutdown();
  if (m_imguiGlfw) ImGui_ImplGlfw_Shutdown();
  if (m_imguiContext) ImGui::DestroyContext();
  if (m_vk.device()) {
    destroySwapchain();
    m_vk.destroyBuffer(m_staging);
    m_vk.destroyBuffer(m_readback);
    if (m_acquired) vkDestroySemaphore(m_vk.device(), m_acquired, nullptr);
    if (m_renderPass) vkDestroyRenderPass(m_vk.device(), m_renderPass, nullptr);
    if (m_descriptors) vkDestroyDescriptorPool(m_vk.device(), m_descriptors, nullptr);
  }
  if (m_surface) vkDestroySurfaceKHR(m_vk.instance(), m_surface, nullptr);
  if (m_window) glfwDestroyWindow(m_window);
  if (m_glfw) glfwTerminate();
  // m_vk (device, then instance) goes after this body.
}

Result<void> VulkanWindow::open(const WindowOptions& o, bool& noDisplay) {
  m_description = "vulkan";
  if (!initGlfw()) {
    noDisplay = true;
    return fail("GLFW cannot start (no display)");
  }
  m_glfw = true;
  if (!glfwVulkanSupported()) return fail("GLFW finds no Vulkan loader");
  uint32_t count = 0;
  const char** surfaceExtensions = glfwGetRequiredInstanceExtensions(&count);
  if (!surfaceExtensions) return fail("Vulkan has no surface extensions for this window system");
  GF_TRY(m_vk.createInstance(o.validation, std::span(surfaceExtensions, count)));
  glfwDefaultWindowHints();
  glfwWindowHint(GLFW_CLIENT_API, GLFW_NO_API);
  glfwWindowHint(GLFW_RESIZABLE, GLFW_FALSE);  // the renderer's size is fixed at creation
  m_window = glfwCreateWindow(o.width, o.height, "graphfrac-viewer", nullptr, nullptr);
  if (!m_window) {
    noDisplay = true;
    return fail("cannot open a window");
  }
  GF_VK(glfwCreateWindowSurface, (m_vk.instance(), m_window, nullptr, &m_surface));
  const char* deviceExtensions[] = {VK_KHR_SWAPCHAIN_EXTENSION_NAME};
  GF_TRY(m_vk.createDevice(deviceExtensions, [&](VkPhysicalDevice d, uint32_t family) {
    VkBool32 ok = VK_FALSE;
    return vkGetPhysicalDeviceSurfaceSupportKHR(d, family, m_surface, &ok) == VK_SUCCESS && ok;
  }));

  // A UNORM format: the picture's bytes are already display-encoded and are copied unchanged.
  uint32_t n = 0;
  GF_VK(vkGetPhysicalDeviceSurfaceFormatsKHR, (m_vk.physicalDevice(), m_surface, &n, nullptr));
  std::vector<VkSurfaceFormatKHR> formats(n);
  GF_VK(vkGetPhysicalDeviceSurfaceFormatsKHR,
        (m_vk.physicalDevice(), m_surface, &n, formats.data()));
  auto found = std::find_if(formats.begin(), formats.end(), [](const VkSurfaceFormatKHR& f) {
    return f.format == VK_FORMAT_B8G8R8A8_UNORM || f.format == VK_FORMAT_R8G8B8A8_UNORM;
  });
  if (found == formats.end())
    return fail("the window's surface offers neither B8G8R8A8_UNORM nor R8G8B8A8_UNORM");
  m_format = *found;

  auto attachment = VkAttachmentDescription{};
  attachment.format = m_format.format;
  attachment.samples = VK_SAMPLE_COUNT_1_BIT;
  attachment.loadOp = VK_ATTACHMENT_LOAD_OP_LOAD;  // the picture copied in before
  attachment.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
  attachment.stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
  attachment.stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
  attachment.initialLayout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
  attachment.finalLayout = VK_IMAGE_LAYOUT_PRESENT_SRC_KHR;
  VkAttachmentReference ref{0, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
  VkSubpassDescription subpass{};
  subpass.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
  subpass.colorAttachmentCount = 1;
  subpass.pColorAttachments = &ref;
  // In: the copy's writes before the panel's blending. Out: the panel's writes before a
  // read-back copy (and, chained, before the present's semaphore).
  VkSubpassDependency deps[2] = {};
  deps[0].srcSubpass = VK_SUBPASS_EXTERNAL;
  deps[0].dstSubpass = 0;
  deps[0].srcStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT;
  deps[0].srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  deps[0].dstStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
  deps[0].dstAccessMask =
      VK_ACCESS_COLOR_ATTACHMENT_READ_BIT | VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
  deps[1].srcSubpass = 0;
  deps[1].dstSubpass = VK_SUBPASS_EXTERNAL;
  deps[1].srcStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
  deps[1].srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
  deps[1].dstStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT;
  deps[1].dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
  auto rp = vkInfo<VkRenderPassCreateInfo>(VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO);
  rp.attachmentCount = 1;
  rp.pAttachments = &attachment;
  rp.subpassCount = 1;
  rp.pSubpasses = &subpass;
  rp.dependencyCount = 2;
  rp.pDependencies = deps;
  GF_VK(vkCreateRenderPass, (m_vk.device(), &rp, nullptr, &m_renderPass));
  auto sem = vkInfo<VkSemaphoreCreateInfo>(VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO);
  GF_VK(vkCreateSemaphore, (m_vk.device(), &sem, nullptr, &m_acquired));
  GF_TRY(createSwapchain());

  if (o.installInput) o.installInput(m_window);
  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  m_imguiContext = true;
  ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini next to wherever it was started
  ImGui::StyleColorsDark();
  ImGui_ImplGlfw_InitForVulkan(m_window, true);
  m_imguiGlfw = true;
  return createImGui();
}

Result<void> VulkanWindow::createSwapchain() {
  VkSurfaceCapabilitiesKHR caps{};
  GF_VK(vkGetPhysicalDeviceSurfaceCapabilitiesKHR, (m_vk.physicalDevice(), m_surface, &caps));
  const VkImageUsageFlags usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT |
                                  VK_IMAGE_USAGE_TRANSFER_DST_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
  if ((caps.supportedUsageFlags & usage) != usage)
    return fail("the window's swapchain images cannot be transfer sources and destinations");
  if (caps.currentExtent.width != UINT32_MAX) {
    m_extent = caps.currentExtent;
  } else {
    int w = 0, h = 0;
    glfwGetFramebufferSize(m_window, &w, &h);
    m_extent = {std::clamp(uint32_t(w), caps.minImageExtent.width, caps.maxImageExtent.width),
                std::clamp(uint32_t(h), caps.minImageExtent.height, caps.maxImageExtent.height)};
  }
  m_minImages = std::max(caps.minImageCount + 1, 2u);
  if (caps.maxImageCount) m_minImages = std::min(m_minImages, caps.maxImageCount);
  const VkSwapchainKHR old = m_swapchain;
  auto info = vkInfo<VkSwapchainCreateInfoKHR>(VK_STRUCTURE_TYPE_SWAPCHAIN_CREATE_INFO_KHR);
  info.surface = m_surface;
  info.minImageCount = m_minImages;
  info.imageFormat = m_format.format;
  info.imageColorSpace = m_format.colorSpace;
  info.imageExtent = m_extent;
  info.imageArrayLayers = 1;
  info.imageUsage = usage;
  info.imageSharingMode = VK_SHARING_MODE_EXCLUSIVE;
  info.preTransform = caps.currentTransform;
  info.compositeAlpha = (caps.supportedCompositeAlpha & VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR)
                            ? VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR
                            : VkCompositeAlphaFlagBitsKHR(caps.supportedCompositeAlpha &
                                                          -caps.supportedCompositeAlpha);
  info.presentMode = VK_PRESENT_MODE_FIFO_KHR;  // the one mode every driver has
  info.clipped = VK_TRUE;
  info.oldSwapchain = old;
  GF_VK(vkCreateSwapchainKHR, (m_vk.device(), &info, nullptr, &m_swapchain));
  if (old) {
    const VkSwapchainKHR fresh = m_swapchain;
    m_swapchain = old;
    destroySwapchain();
    m_swapchain = fresh;
  }
  uint32_t n = 0;
  GF_VK(vkGetSwapchainImagesKHR, (m_vk.device(), m_swapchain, &n, nullptr));
  m_images.resize(n);
  GF_VK(vkGetSwapchainImagesKHR, (m_vk.device(), m_swapchain, &n, m_images.data()));
  for (VkImage image : m_images) {
    auto view = vkInfo<VkImageViewCreateInfo>(VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO);
    view.image = image;
    view.viewType = VK_IMAGE_VIEW_TYPE_2D;
    view.format = m_format.format;
    view.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    GF_VK(vkCreateImageView, (m_vk.device(), &view, nullptr, &m_views.emplace_back()));
    auto fb = vkInfo<VkFramebufferCreateInfo>(VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO);
    fb.renderPass = m_renderPass;
    fb.attachmentCount = 1;
    fb.pAttachments = &m_views.back();
    fb.width = m_extent.width;
    fb.height = m_extent.height;
    fb.layers = 1;
    GF_VK(vkCreateFramebuffer, (m_vk.device(), &fb, nullptr, &m_framebuffers.emplace_back()));
    auto sem = vkInfo<VkSemaphoreCreateInfo>(VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO);
    GF_VK(vkCreateSemaphore, (m_vk.device(), &sem, nullptr, &m_rendered.emplace_back()));
  }
  return {};
}

void VulkanWindow::destroySwapchain() {
  for (VkFramebuffer f : m_framebuffers) vkDestroyFramebuffer(m_vk.device(), f, nullptr);
  for (VkImageView v : m_views) vkDestroyImageView(m_vk.device(), v, nullptr);
  for (VkSemaphore s : m_rendered) vkDestroySemaphore(m_vk.device(), s, nullptr);
  m_framebuffers.clear();
  m_views.clear();
  m_rendered.clear();
  m_images.clear();
  if (m_swapchain) vkDestroySwapchainKHR(m_vk.device(), m_swapchain, nullptr);
  m_swapchain = VK_NULL_HANDLE;
}

Result<void> VulkanWindow::createImGui() {
  const VkDescriptorPoolSize size{VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1};
  auto pool = vkInfo<VkDescriptorPoolCreateInfo>(VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO);
  pool.flags = VK_DESCRIPTOR_POOL_CREATE_FREE_DESCRIPTOR_SET_BIT;
  pool.maxSets = 1;  // the font atlas
  pool.poolSizeCount = 1;
  pool.pPoolSizes = &size;
  GF_VK(vkCreateDescriptorPool, (m_vk.device(), &pool, nullptr, &m_descriptors));
  ImGui_ImplVulkan_InitInfo init{};
  init.Instance = m_vk.instance();
  init.PhysicalDevice = m_vk.physicalDevice();
  init.Device = m_vk.device();
  init.QueueFamily = m_vk.queueFamily();
  init.Queue = m_vk.queue();
  init.DescriptorPool = m_descriptors;
  init.MinImageCount = m_minImages;
  init.ImageCount = uint32_t(m_images.size());
  init.MSAASamples = VK_SAMPLE_COUNT_1_BIT;
  init.CheckVkResultFn = &imguiCheck;
  if (!ImGui_ImplVulkan_Init(&init, m_renderPass))
    return fail("ImGui's Vulkan backend did not start");
  m_imguiVulkan = true;
  // The font atlas, uploaded once.
  const VkCommandBuffer cmd = m_vk.commandBuffer();
  auto begin = vkInfo<VkCommandBufferBeginInfo>(VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO);
  begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  GF_VK(vkBeginCommandBuffer, (cmd, &begin));
  if (!ImGui_ImplVulkan_CreateFontsTexture(cmd)) return fail("ImGui's font atlas upload failed");
  GF_VK(vkEndCommandBuffer, (cmd));
  auto submit = vkInfo<VkSubmitInfo>(VK_STRUCTURE_TYPE_SUBMIT_INFO);
  submit.commandBufferCount = 1;
  submit.pCommandBuffers = &cmd;
  const VkFence fence = m_vk.fence();
  GF_VK(vkQueueSubmit, (m_vk.queue(), 1, &submit, fence));
  GF_VK(vkWaitForFences, (m_vk.device(), 1, &fence, VK_TRUE, UINT64_MAX));
  GF_VK(vkResetFences, (m_vk.device(), 1, &fence));
  ImGui_ImplVulkan_DestroyFontUploadObjects();
  return {};
}

Result<void> VulkanWindow::record(uint32_t index, const Image& image, bool readBack) {
  const VkCommandBuffer cmd = m_vk.commandBuffer();
  const VkImage target = m_images[index];
  auto begin = vkInfo<VkCommandBufferBeginInfo>(VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO);
  begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  GF_VK(vkBeginCommandBuffer, (cmd, &begin));
  // The acquired image's old contents are not needed: UNDEFINED. The acquire semaphore is
  // waited for at the transfer stage, which this barrier's first scope chains to.
  auto toDst = vkInfo<VkImageMemoryBarrier>(VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER);
  toDst.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  toDst.oldLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  toDst.newLayout = VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL;
  toDst.srcQueueFamilyIndex = toDst.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  toDst.image = target;
  toDst.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
  vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0,
                       nullptr, 0, nullptr, 1, &toDst);
  const uint32_t w = std::min(uint32_t(image.width), m_extent.width);
  const uint32_t h = std::min(uint32_t(image.height), m_extent.height);
  if (w < m_extent.width || h < m_extent.height) {
    // A window larger than the picture (a window manager's doing): black around it.
    const VkClearColorValue black{{0, 0, 0, 1}};
    const VkImageSubresourceRange range{VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    vkCmdClearColorImage(cmd, target, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, &black, 1, &range);
    auto again = vkInfo<VkMemoryBarrier>(VK_STRUCTURE_TYPE_MEMORY_BARRIER);
    again.srcAccessMask = again.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1,
                         &again, 0, nullptr, 0, nullptr);
  }
  VkBufferImageCopy copy{};
  copy.bufferRowLength = uint32_t(image.width);
  copy.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
  copy.imageExtent = {w, h, 1};
  if (w && h)
    vkCmdCopyBufferToImage(cmd, m_staging.buffer, target, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1,
                           &copy);

  auto pass = vkInfo<VkRenderPassBeginInfo>(VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO);
  pass.renderPass = m_renderPass;
  pass.framebuffer = m_framebuffers[index];
  pass.renderArea.extent = m_extent;
  vkCmdBeginRenderPass(cmd, &pass, VK_SUBPASS_CONTENTS_INLINE);
  ImGui_ImplVulkan_RenderDrawData(ImGui::GetDrawData(), cmd);
  vkCmdEndRenderPass(cmd);

  if (readBack) {
    // The render pass's outgoing dependency orders its writes and the move to PRESENT_SRC before
    // this transfer stage.
    auto toSrc = vkInfo<VkImageMemoryBarrier>(VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER);
    toSrc.srcAccessMask = 0;
    toSrc.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
    toSrc.oldLayout = VK_IMAGE_LAYOUT_PRESENT_SRC_KHR;
    toSrc.newLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
    toSrc.srcQueueFamilyIndex = toSrc.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    toSrc.image = target;
    toSrc.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 0,
                         nullptr, 0, nullptr, 1, &toSrc);
    VkBufferImageCopy back{};
    back.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    back.imageExtent = {m_extent.width, m_extent.height, 1};
    vkCmdCopyImageToBuffer(cmd, target, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, m_readback.buffer, 1,
                           &back);
    // Back to PRESENT_SRC; the host reads the buffer after the fence.
    auto toPresent = toSrc;
    toPresent.srcAccessMask = 0;
    toPresent.dstAccessMask = 0;
    toPresent.oldLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
    toPresent.newLayout = VK_IMAGE_LAYOUT_PRESENT_SRC_KHR;
    auto toHost = vkInfo<VkBufferMemoryBarrier>(VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER);
    toHost.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    toHost.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    toHost.srcQueueFamilyIndex = toHost.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    toHost.buffer = m_readback.buffer;
    toHost.size = VK_WHOLE_SIZE;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_HOST_BIT, 0, 0, nullptr,
                         1, &toHost, 1, &toPresent);
  }
  GF_VK(vkEndCommandBuffer, (cmd));
  return {};
}

Result<void> VulkanWindow::present(const Image& image, const std::function<void()>& panel,
                                   Image* contents) {
  const VkDevice dev = m_vk.device();
  const VkFence fence = m_vk.fence();
  if (m_inFlight) {
    GF_VK(vkWaitForFences, (dev, 1, &fence, VK_TRUE, UINT64_MAX));
    GF_VK(vkResetFences, (dev, 1, &fence));
    m_inFlight = false;
  }
  // The panel's frame is built even when the swapchain is out of date, so ImGui sees every
  // frame's input.
  ImGui_ImplVulkan_NewFrame();
  ImGui_ImplGlfw_NewFrame();
  ImGui::NewFrame();
  panel();
  ImGui::Render();

  uint32_t index = 0;
  VkResult acquired =
      vkAcquireNextImageKHR(dev, m_swapchain, UINT64_MAX, m_acquired, VK_NULL_HANDLE, &index);
  if (acquired == VK_ERROR_OUT_OF_DATE_KHR) {
    // The window changed under the swapchain: a new one, and this frame is skipped.
    GF_VK(vkDeviceWaitIdle, (dev));
    return createSwapchain();
  }
  if (acquired != VK_SUCCESS && acquired != VK_SUBOPTIMAL_KHR)
    return vkFail("vkAcquireNextImageKHR", acquired);

  const size_t bytes = size_t(image.width) * size_t(image.height) * 4;
  if (m_staging.size < bytes) {
    m_vk.destroyBuffer(m_staging);
    GF_TRY(m_vk.createBuffer(
        bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT,
        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT, 0, m_staging));
  }
  // RGBA to the swapchain's byte order.
  auto* out = static_cast<uint8_t*>(m_staging.mapped);
  const bool bgra = m_format.format == VK_FORMAT_B8G8R8A8_UNORM;
  for (size_t i = 0; i < bytes; i += 4) {
    out[i + 0] = image.rgba[i + (bgra ? 2 : 0)];
    out[i + 1] = image.rgba[i + 1];
    out[i + 2] = image.rgba[i + (bgra ? 0 : 2)];
    out[i + 3] = 255;  // the window is opaque
  }
  const size_t windowBytes = size_t(m_extent.width) * size_t(m_extent.height) * 4;
  if (contents && m_readback.size < windowBytes) {
    m_vk.destroyBuffer(m_readback);
    GF_TRY(m_vk.createBuffer(
        windowBytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT,
        VK_MEMORY_PROPERTY_HOST_CACHED_BIT, m_readback));
  }
  GF_TRY(record(index, image, contents != nullptr));

  const VkPipelineStageFlags waitStage = VK_PIPELINE_STAGE_TRANSFER_BIT;
  const VkCommandBuffer cmd = m_vk.commandBuffer();
  auto submit = vkInfo<VkSubmitInfo>(VK_STRUCTURE_TYPE_SUBMIT_INFO);
  submit.waitSemaphoreCount = 1;
  submit.pWaitSemaphores = &m_acquired;
  submit.pWaitDstStageMask = &waitStage;
  submit.commandBufferCount = 1;
  submit.pCommandBuffers = &cmd;
  submit.signalSemaphoreCount = 1;
  submit.pSignalSemaphores = &m_rendered[index];
  GF_VK(vkQueueSubmit, (m_vk.queue(), 1, &submit, fence));
  m_inFlight = true;
  if (contents) {
    GF_VK(vkWaitForFences, (dev, 1, &fence, VK_TRUE, UINT64_MAX));
    GF_VK(vkResetFences, (dev, 1, &fence));
    m_inFlight = false;
    contents->width = int(m_extent.width);
    contents->height = int(m_extent.height);
    contents->rgba.resize(windowBytes);
    const auto* in = static_cast<const uint8_t*>(m_readback.mapped);
    for (size_t i = 0; i < windowBytes; i += 4) {
      contents->rgba[i + 0] = in[i + (bgra ? 2 : 0)];
      contents->rgba[i + 1] = in[i + 1];
      contents->rgba[i + 2] = in[i + (bgra ? 0 : 2)];
      contents->rgba[i + 3] = in[i + 3];
    }
  }

  auto info = vkInfo<VkPresentInfoKHR>(VK_STRUCTURE_TYPE_PRESENT_INFO_KHR);
  info.waitSemaphoreCount = 1;
  info.pWaitSemaphores = &m_rendered[index];
  info.swapchainCount = 1;
  info.pSwapchains = &m_swapchain;
  info.pImageIndices = &index;
  const VkResult presented = vkQueuePresentKHR(m_vk.queue(), &info);
  if (presented == VK_ERROR_OUT_OF_DATE_KHR || presented == VK_SUBOPTIMAL_KHR ||
      acquired == VK_SUBOPTIMAL_KHR) {
    GF_VK(vkDeviceWaitIdle, (dev));
    m_inFlight = false;
    GF_VK(vkResetFences, (dev, 1, &fence));
    return createSwapchain();
  }
  if (presented != VK_SUCCESS) return vkFail("vkQueuePresentKHR", presented);
  return {};
}

}  // namespace

Result<std::unique_ptr<ViewerWindow>> openVulkanWindow(const WindowOptions& options,
                                                       bool& noDisplay) {
  auto w = std::make_unique<VulkanWindow>();
  if (Result<void> r = w->open(options, noDisplay); !r) return r.error();
  return std::unique_ptr<ViewerWindow>(std::move(w));
}

}  // namespace gf::demo::detail

#else

namespace gf::demo::detail {
Result<std::unique_ptr<ViewerWindow>> openVulkanWindow(const WindowOptions&, bool&) {
  return fail("built without Vulkan");
}
}  // namespace gf::demo::detail

#endif
