// The Vulkan context under the demo's Vulkan renderer: instance (with the validation messenger),
// device choice, one queue, one command buffer and fence, and buffer/image helpers. Kept apart
// from vulkan_renderer.cpp, which builds the targets, the pipeline and the frames on it.
#pragma once

#include <graphfrac/status.h>
#include <vulkan/vulkan.h>

#include <functional>
#include <mutex>
#include <span>
#include <string>
#include <vector>

namespace gf::demo::detail {

/// "VK_ERROR_DEVICE_LOST" for VK_ERROR_DEVICE_LOST.
const char* vkResultName(VkResult r);
/// The error "Vulkan: <call>: <VkResult name> (<code>)".
Error vkFail(const char* call, VkResult r);

// Calls a Vulkan function and returns its failure as an Error naming the call.
#define GF_VK(fn, args)                                                                 \
  do {                                                                                  \
    const VkResult gfVkResult_ = fn args;                                               \
    if (gfVkResult_ != VK_SUCCESS) return ::gf::demo::detail::vkFail(#fn, gfVkResult_); \
  } while (0)
// Propagates the error of a Result.
#define GF_TRY(expr)                    \
  do {                                  \
    auto gfTry_ = (expr);               \
    if (!gfTry_) return gfTry_.error(); \
  } while (0)

/// A zeroed Vulkan struct with its sType set.
template <class T>
T vkInfo(VkStructureType type) {
  T s{};
  s.sType = type;
  return s;
}

/// A buffer with its own memory; host-visible ones stay mapped.
struct GpuBuffer {
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  VkDeviceSize size = 0;
  void* mapped = nullptr;
};

/// A 2D image with its own memory and a view of it.
struct GpuImage {
  VkImage image = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  VkImageView view = VK_NULL_HANDLE;
};

/// Instance, device and queue; destroys them (after waiting for the device) on destruction, so
/// everything made on it must be destroyed first.
class VulkanDevice {
 public:
  VulkanDevice() = default;
  VulkanDevice(const VulkanDevice&) = delete;
  VulkanDevice& operator=(const VulkanDevice&) = delete;
  ~VulkanDevice();

  /// Picks a device (discrete, integrated, virtual GPU, then CPU; GF_VULKAN_DEVICE=index
  /// overrides) and creates the logical device with one graphics queue. With `validation`, the
  /// Khronos validation layer is on and its warnings and errors are collected.
  Result<void> create(bool validation);
  /// create() in two halves for a window: the instance with `extensions` too (the surface ones),
  /// then, once the caller made its surface on instance(), the device whose queue family also
  /// passes `familyOk` (presents to it), created with `deviceExtensions`.
  Result<void> createInstance(bool validation, std::span<const char* const> extensions);
  Result<void> createDevice(std::span<const char* const> deviceExtensions,
                            const std::function<bool(VkPhysicalDevice, uint32_t)>& familyOk);

  VkInstance instance() const { return m_instance; }
  VkPhysicalDevice physicalDevice() const { return m_physical; }
  uint32_t queueFamily() const { return m_queueFamily; }

  VkDevice device() const { return m_device; }
  VkQueue queue() const { return m_queue; }
  VkCommandBuffer commandBuffer() const { return m_cmd; }
  VkFence fence() const { return m_fence; }
  const VkPhysicalDeviceProperties& properties() const { return m_properties; }
  /// The first depth format of D32, X8_D24, D24_S8, D32_S8 the device can render to.
  VkFormat depthFormat() const { return m_depthFormat; }
  /// What the device can do with `format` in optimal tiling.
  VkFormatFeatureFlags formatFeatures(VkFormat format) const {
    VkFormatProperties p{};
    vkGetPhysicalDeviceFormatProperties(m_physical, format, &p);
    return p.optimalTilingFeatures;
  }
  /// e.g. "llvmpipe (LLVM 15.0.6, 256 bits), CPU".
  std::string name() const;
  std::vector<std::string> messages() const {
    std::lock_guard<std::mutex> lock(m_messagesMutex);
    return m_messages;
  }

  /// A buffer in memory with `required` properties (and `preferred` ones where possible); on
  /// failure `out` is left empty.
  Result<void> createBuffer(VkDeviceSize size, VkBufferUsageFlags usage,
                            VkMemoryPropertyFlags required, VkMemoryPropertyFlags preferred,
                            GpuBuffer& out);
  void destroyBuffer(GpuBuffer& b);
  /// A width x height 2D image in device-local memory, with a view of `aspect`.
  Result<void> createImage(int width, int height, VkFormat format, VkImageUsageFlags usage,
                           VkSampleCountFlagBits samples, VkImageAspectFlags aspect, GpuImage& out,
                           uint32_t mipLevels = 1);
  void destroyImage(GpuImage& t);

 private:
  static VKAPI_ATTR VkBool32 VKAPI_CALL onMessage(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                  VkDebugUtilsMessageTypeFlagsEXT type,
                                                  const VkDebugUtilsMessengerCallbackDataEXT* data,
                                                  void* user);
  Result<void> pickDevice(const std::function<bool(VkPhysicalDevice, uint32_t)>& familyOk);
  Result<void> makeDevice(std::span<const char* const> deviceExtensions);
  Result<uint32_t> memoryType(uint32_t bits, VkMemoryPropertyFlags required,
                              VkMemoryPropertyFlags preferred) const;
  Result<void> makeBuffer(VkDeviceSize size, VkBufferUsageFlags usage,
                          VkMemoryPropertyFlags required, VkMemoryPropertyFlags preferred,
                          GpuBuffer& out);

  VkInstance m_instance = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT m_messenger = VK_NULL_HANDLE;
  PFN_vkDestroyDebugUtilsMessengerEXT m_destroyMessenger = nullptr;
  VkPhysicalDevice m_physical = VK_NULL_HANDLE;
  VkPhysicalDeviceProperties m_properties{};
  VkPhysicalDeviceMemoryProperties m_memory{};
  VkFormat m_depthFormat = VK_FORMAT_UNDEFINED;
  uint32_t m_queueFamily = 0;
  VkDevice m_device = VK_NULL_HANDLE;
  VkQueue m_queue = VK_NULL_HANDLE;
  VkCommandPool m_commandPool = VK_NULL_HANDLE;
  VkCommandBuffer m_cmd = VK_NULL_HANDLE;
  VkFence m_fence = VK_NULL_HANDLE;
  mutable std::mutex m_messagesMutex;
  std::vector<std::string> m_messages;
};

}  // namespace gf::demo::detail
