// See vulkan_device.h.
#include "vulkan_device.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>

#include "vulkan_renderer.h"

namespace gf::demo::detail {
namespace {

std::mutex g_logMutex;
std::vector<std::string> g_log;  // every validation message of the process

const char* deviceTypeName(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
      return "discrete GPU";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
      return "integrated GPU";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
      return "virtual GPU";
    case VK_PHYSICAL_DEVICE_TYPE_CPU:
      return "CPU";
    default:
      return "other";
  }
}

// Lower is better: discrete, integrated, virtual, CPU, other.
int deviceRank(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
      return 0;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
      return 1;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
      return 2;
    case VK_PHYSICAL_DEVICE_TYPE_CPU:
      return 3;
    default:
      return 4;
  }
}

}  // namespace

const char* vkResultName(VkResult r) {
  switch (r) {
#define GF_VK_NAME(x) \
  case x:             \
    return #x;
    GF_VK_NAME(VK_SUCCESS)
    GF_VK_NAME(VK_NOT_READY)
    GF_VK_NAME(VK_TIMEOUT)
    GF_VK_NAME(VK_EVENT_SET)
    GF_VK_NAME(VK_EVENT_RESET)
    GF_VK_NAME(VK_INCOMPLETE)
    GF_VK_NAME(VK_ERROR_OUT_OF_HOST_MEMORY)
    GF_VK_NAME(VK_ERROR_OUT_OF_DEVICE_MEMORY)
    GF_VK_NAME(VK_ERROR_INITIALIZATION_FAILED)
    GF_VK_NAME(VK_ERROR_DEVICE_LOST)
    GF_VK_NAME(VK_ERROR_MEMORY_MAP_FAILED)
    GF_VK_NAME(VK_ERROR_LAYER_NOT_PRESENT)
    GF_VK_NAME(VK_ERROR_EXTENSION_NOT_PRESENT)
    GF_VK_NAME(VK_ERROR_FEATURE_NOT_PRESENT)
    GF_VK_NAME(VK_ERROR_INCOMPATIBLE_DRIVER)
    GF_VK_NAME(VK_ERROR_TOO_MANY_OBJECTS)
    GF_VK_NAME(VK_ERROR_FORMAT_NOT_SUPPORTED)
    GF_VK_NAME(VK_ERROR_FRAGMENTED_POOL)
    GF_VK_NAME(VK_ERROR_UNKNOWN)
    GF_VK_NAME(VK_ERROR_OUT_OF_POOL_MEMORY)
    GF_VK_NAME(VK_ERROR_INVALID_EXTERNAL_HANDLE)
    GF_VK_NAME(VK_ERROR_FRAGMENTATION)
    GF_VK_NAME(VK_ERROR_INVALID_OPAQUE_CAPTURE_ADDRESS)
    GF_VK_NAME(VK_SUBOPTIMAL_KHR)
    GF_VK_NAME(VK_ERROR_OUT_OF_DATE_KHR)
    GF_VK_NAME(VK_ERROR_SURFACE_LOST_KHR)
    GF_VK_NAME(VK_ERROR_NATIVE_WINDOW_IN_USE_KHR)
#undef GF_VK_NAME
    default:
      return "unknown VkResult";
  }
}

Error vkFail(const char* call, VkResult r) {
  return fail("Vulkan: ", call, ": ", vkResultName(r), " (", std::to_string(int(r)), ")");
}

std::vector<std::string> vulkanValidationLog() {
  std::lock_guard<std::mutex> lock(g_logMutex);
  return g_log;
}

VKAPI_ATTR VkBool32 VKAPI_CALL VulkanDevice::onMessage(
    VkDebugUtilsMessageSeverityFlagBitsEXT severity, VkDebugUtilsMessageTypeFlagsEXT,
    const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
  std::string text =
      severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT ? "error: " : "warning: ";
  if (data && data->pMessageIdName) text += std::string(data->pMessageIdName) + ": ";
  if (data && data->pMessage) text += data->pMessage;
  auto* self = static_cast<VulkanDevice*>(user);
  {
    std::lock_guard<std::mutex> lock(self->m_messagesMutex);
    self->m_messages.push_back(text);
  }
  std::lock_guard<std::mutex> lock(g_logMutex);
  g_log.push_back(std::move(text));
  return VK_FALSE;  // never abort the call
}

Result<void> VulkanDevice::create(bool validation) {
  GF_TRY(createInstance(validation, {}));
  return createDevice({}, {});
}

Result<void> VulkanDevice::createDevice(
    std::span<const char* const> deviceExtensions,
    const std::function<bool(VkPhysicalDevice, uint32_t)>& familyOk) {
  GF_TRY(pickDevice(familyOk));
  return makeDevice(deviceExtensions);
}

std::string VulkanDevice::name() const {
  return std::string(m_properties.deviceName) + ", " + deviceTypeName(m_properties.deviceType);
}

VulkanDevice::~VulkanDevice() {
  if (m_device) {
    // Nothing can be done about a failure here; destruction goes on regardless.
    (void)vkDeviceWaitIdle(m_device);
    if (m_fence) vkDestroyFence(m_device, m_fence, nullptr);
    if (m_commandPool) vkDestroyCommandPool(m_device, m_commandPool, nullptr);
    vkDestroyDevice(m_device, nullptr);
  }
  if (m_instance) {
    if (m_messenger) m_destroyMessenger(m_instance, m_messenger, nullptr);
    vkDestroyInstance(m_instance, nullptr);
  }
}

Result<void> VulkanDevice::createInstance(bool validation, std::span<const char* const> wanted) {
  const char* kLayer = "VK_LAYER_KHRONOS_validation";
  std::vector<const char*> layers, extensions(wanted.begin(), wanted.end());
  bool syncValidation = false;
  if (validation) {
    uint32_t count = 0;
    GF_VK(vkEnumerateInstanceLayerProperties, (&count, nullptr));
    std::vector<VkLayerProperties> available(count);
    GF_VK(vkEnumerateInstanceLayerProperties, (&count, available.data()));
    const bool found = std::any_of(available.begin(), available.end(), [&](const auto& l) {
      return std::strcmp(l.layerName, kLayer) == 0;
    });
    if (!found)
      return fail("Vulkan: validation requested but the layer ", kLayer,
                  " is not installed (Debian: vulkan-validationlayers)");
    layers.push_back(kLayer);
    extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    GF_VK(vkEnumerateInstanceExtensionProperties, (kLayer, &count, nullptr));
    std::vector<VkExtensionProperties> layerExtensions(count);
    GF_VK(vkEnumerateInstanceExtensionProperties, (kLayer, &count, layerExtensions.data()));
    for (const VkExtensionProperties& e : layerExtensions)
      if (std::strcmp(e.extensionName, VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME) == 0)
        syncValidation = true;
    if (syncValidation) extensions.push_back(VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME);
  }

  auto app = vkInfo<VkApplicationInfo>(VK_STRUCTURE_TYPE_APPLICATION_INFO);
  app.pApplicationName = "graphfrac-demo";
  app.pEngineName = "graphfrac";
  app.apiVersion = VK_API_VERSION_1_1;

  // Chained into the create info as well, so vkCreateInstance and vkDestroyInstance report too.
  auto messenger = vkInfo<VkDebugUtilsMessengerCreateInfoEXT>(
      VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT);
  messenger.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT |
                              VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  messenger.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                          VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                          VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  messenger.pfnUserCallback = &VulkanDevice::onMessage;
  messenger.pUserData = this;

  // Synchronization validation too, where the layer offers it: the frame's barriers are the
  // part core validation does not check.
  const VkValidationFeatureEnableEXT enables[] = {
      VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT};
  auto features = vkInfo<VkValidationFeaturesEXT>(VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT);
  features.enabledValidationFeatureCount = 1;
  features.pEnabledValidationFeatures = enables;
  if (syncValidation) messenger.pNext = &features;

  auto info = vkInfo<VkInstanceCreateInfo>(VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO);
  info.pNext = validation ? &messenger : nullptr;
  info.pApplicationInfo = &app;
  info.enabledLayerCount = uint32_t(layers.size());
  info.ppEnabledLayerNames = layers.data();
  info.enabledExtensionCount = uint32_t(extensions.size());
  info.ppEnabledExtensionNames = extensions.data();
  GF_VK(vkCreateInstance, (&info, nullptr, &m_instance));

  if (validation) {
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(m_instance, "vkCreateDebugUtilsMessengerEXT"));
    m_destroyMessenger = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(m_instance, "vkDestroyDebugUtilsMessengerEXT"));
    if (!create || !m_destroyMessenger)
      return fail("Vulkan: vkGetInstanceProcAddr: ", VK_EXT_DEBUG_UTILS_EXTENSION_NAME,
                  " functions are missing");
    messenger.pNext = nullptr;
    GF_VK(create, (m_instance, &messenger, nullptr, &m_messenger));
  }
  return {};
}

Result<void> VulkanDevice::pickDevice(
    const std::function<bool(VkPhysicalDevice, uint32_t)>& familyOk) {
  uint32_t count = 0;
  GF_VK(vkEnumeratePhysicalDevices, (m_instance, &count, nullptr));
  std::vector<VkPhysicalDevice> devices(count);
  GF_VK(vkEnumeratePhysicalDevices, (m_instance, &count, devices.data()));
  if (count == 0) return fail("Vulkan: no physical device (no Vulkan driver found)");

  // Why each device was passed over, for the error when none fits.
  std::string rejected;
  auto suitable = [&](VkPhysicalDevice d, uint32_t& family, VkFormat& depth) {
    VkPhysicalDeviceProperties p;
    vkGetPhysicalDeviceProperties(d, &p);
    VkPhysicalDeviceFeatures f;
    vkGetPhysicalDeviceFeatures(d, &f);
    auto reject = [&](const char* why) {
      rejected += std::string("; ") + p.deviceName + ": " + why;
      return false;
    };
    // gl_PrimitiveID in the fragment stage (the crack flags) needs it.
    if (!f.geometryShader) return reject("no geometryShader feature");
    uint32_t n = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(d, &n, nullptr);
    std::vector<VkQueueFamilyProperties> families(n);
    vkGetPhysicalDeviceQueueFamilyProperties(d, &n, families.data());
    family = n;
    for (uint32_t i = 0; i < n && family == n; ++i)
      if ((families[i].queueFlags & VK_QUEUE_GRAPHICS_BIT) && (!familyOk || familyOk(d, i)))
        family = i;
    if (family == n)
      return reject(familyOk ? "no graphics queue that presents to the window"
                             : "no graphics queue");
    depth = VK_FORMAT_UNDEFINED;
    for (VkFormat c : {VK_FORMAT_D32_SFLOAT, VK_FORMAT_X8_D24_UNORM_PACK32,
                       VK_FORMAT_D24_UNORM_S8_UINT, VK_FORMAT_D32_SFLOAT_S8_UINT}) {
      VkFormatProperties fp;
      vkGetPhysicalDeviceFormatProperties(d, c, &fp);
      if (fp.optimalTilingFeatures & VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT) {
        depth = c;
        break;
      }
    }
    if (depth == VK_FORMAT_UNDEFINED) return reject("no depth attachment format");
    return true;
  };

  int chosen = -1, bestRank = 1 << 30;
  uint32_t family = 0;
  VkFormat depth = VK_FORMAT_UNDEFINED;
  if (const char* env = std::getenv("GF_VULKAN_DEVICE"); env && *env) {
    char* end = nullptr;
    const long index = std::strtol(env, &end, 10);
    if (*end != '\0' || index < 0 || index >= long(count))
      return fail("Vulkan: GF_VULKAN_DEVICE=", env, " is not a device index in 0..",
                  std::to_string(count - 1));
    if (!suitable(devices[size_t(index)], family, depth))
      return fail("Vulkan: GF_VULKAN_DEVICE=", env, " is unsuitable", rejected);
    chosen = int(index);
  } else {
    for (uint32_t i = 0; i < count; ++i) {
      uint32_t fam = 0;
      VkFormat dep = VK_FORMAT_UNDEFINED;
      if (!suitable(devices[i], fam, dep)) continue;
      VkPhysicalDeviceProperties p;
      vkGetPhysicalDeviceProperties(devices[i], &p);
      if (deviceRank(p.deviceType) < bestRank) {
        bestRank = deviceRank(p.deviceType);
        chosen = int(i);
        family = fam;
        depth = dep;
      }
    }
    if (chosen < 0) return fail("Vulkan: no suitable device", rejected);
  }
  m_physical = devices[size_t(chosen)];
  m_queueFamily = family;
  m_depthFormat = depth;
  vkGetPhysicalDeviceProperties(m_physical, &m_properties);
  vkGetPhysicalDeviceMemoryProperties(m_physical, &m_memory);
  return {};
}

Result<void> VulkanDevice::makeDevice(std::span<const char* const> deviceExtensions) {
  const float priority = 1.0f;
  auto queue = vkInfo<VkDeviceQueueCreateInfo>(VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO);
  queue.queueFamilyIndex = m_queueFamily;
  queue.queueCount = 1;
  queue.pQueuePriorities = &priority;
  VkPhysicalDeviceFeatures features{};
  features.geometryShader = VK_TRUE;
  auto info = vkInfo<VkDeviceCreateInfo>(VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO);
  info.queueCreateInfoCount = 1;
  info.pQueueCreateInfos = &queue;
  info.pEnabledFeatures = &features;
  info.enabledExtensionCount = uint32_t(deviceExtensions.size());
  info.ppEnabledExtensionNames = deviceExtensions.data();
  GF_VK(vkCreateDevice, (m_physical, &info, nullptr, &m_device));
  vkGetDeviceQueue(m_device, m_queueFamily, 0, &m_queue);

  auto pool = vkInfo<VkCommandPoolCreateInfo>(VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO);
  pool.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pool.queueFamilyIndex = m_queueFamily;
  GF_VK(vkCreateCommandPool, (m_device, &pool, nullptr, &m_commandPool));
  auto alloc = vkInfo<VkCommandBufferAllocateInfo>(VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO);
  alloc.commandPool = m_commandPool;
  alloc.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  alloc.commandBufferCount = 1;
  GF_VK(vkAllocateCommandBuffers, (m_device, &alloc, &m_cmd));
  auto fence = vkInfo<VkFenceCreateInfo>(VK_STRUCTURE_TYPE_FENCE_CREATE_INFO);
  GF_VK(vkCreateFence, (m_device, &fence, nullptr, &m_fence));
  return {};
}

Result<uint32_t> VulkanDevice::memoryType(uint32_t bits, VkMemoryPropertyFlags required,
                                          VkMemoryPropertyFlags preferred) const {
  for (VkMemoryPropertyFlags want : {required | preferred, required})
    for (uint32_t i = 0; i < m_memory.memoryTypeCount; ++i)
      if ((bits & (1u << i)) && (m_memory.memoryTypes[i].propertyFlags & want) == want) return i;
  return fail("Vulkan: no memory type with properties 0x", std::to_string(required),
              " for resource type bits ", std::to_string(bits));
}

Result<void> VulkanDevice::createBuffer(VkDeviceSize size, VkBufferUsageFlags usage,
                                        VkMemoryPropertyFlags required,
                                        VkMemoryPropertyFlags preferred, GpuBuffer& out) {
  // A half-made buffer is destroyed, so `out` is either complete or empty.
  Result<void> r = makeBuffer(size, usage, required, preferred, out);
  if (!r) destroyBuffer(out);
  return r;
}

Result<void> VulkanDevice::makeBuffer(VkDeviceSize size, VkBufferUsageFlags usage,
                                      VkMemoryPropertyFlags required,
                                      VkMemoryPropertyFlags preferred, GpuBuffer& out) {
  auto info = vkInfo<VkBufferCreateInfo>(VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO);
  info.size = size;
  info.usage = usage;
  info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  GF_VK(vkCreateBuffer, (m_device, &info, nullptr, &out.buffer));
  out.size = size;
  VkMemoryRequirements req;
  vkGetBufferMemoryRequirements(m_device, out.buffer, &req);
  Result<uint32_t> type = memoryType(req.memoryTypeBits, required, preferred);
  if (!type) return type.error();
  auto alloc = vkInfo<VkMemoryAllocateInfo>(VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO);
  alloc.allocationSize = req.size;
  alloc.memoryTypeIndex = type.value();
  GF_VK(vkAllocateMemory, (m_device, &alloc, nullptr, &out.memory));
  GF_VK(vkBindBufferMemory, (m_device, out.buffer, out.memory, 0));
  if (required & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT)
    GF_VK(vkMapMemory, (m_device, out.memory, 0, VK_WHOLE_SIZE, 0, &out.mapped));
  return {};
}

void VulkanDevice::destroyBuffer(GpuBuffer& b) {
  // Unmapped implicitly by vkFreeMemory.
  if (b.buffer) vkDestroyBuffer(m_device, b.buffer, nullptr);
  if (b.memory) vkFreeMemory(m_device, b.memory, nullptr);
  b = GpuBuffer{};
}

Result<void> VulkanDevice::createImage(int width, int height, VkFormat format,
                                       VkImageUsageFlags usage, VkSampleCountFlagBits samples,
                                       VkImageAspectFlags aspect, GpuImage& out,
                                       uint32_t mipLevels) {
  auto info = vkInfo<VkImageCreateInfo>(VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO);
  info.imageType = VK_IMAGE_TYPE_2D;
  info.format = format;
  info.extent = {uint32_t(width), uint32_t(height), 1};
  info.mipLevels = mipLevels;
  info.arrayLayers = 1;
  info.samples = samples;
  info.tiling = VK_IMAGE_TILING_OPTIMAL;
  info.usage = usage;
  info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  info.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  GF_VK(vkCreateImage, (m_device, &info, nullptr, &out.image));
  VkMemoryRequirements req;
  vkGetImageMemoryRequirements(m_device, out.image, &req);
  Result<uint32_t> type = memoryType(req.memoryTypeBits, 0, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  if (!type) return type.error();
  auto alloc = vkInfo<VkMemoryAllocateInfo>(VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO);
  alloc.allocationSize = req.size;
  alloc.memoryTypeIndex = type.value();
  GF_VK(vkAllocateMemory, (m_device, &alloc, nullptr, &out.memory));
  GF_VK(vkBindImageMemory, (m_device, out.image, out.memory, 0));
  auto view = vkInfo<VkImageViewCreateInfo>(VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO);
  view.image = out.image;
  view.viewType = VK_IMAGE_VIEW_TYPE_2D;
  view.format = format;
  view.subresourceRange = {aspect, 0, mipLevels, 0, 1};
  GF_VK(vkCreateImageView, (m_device, &view, nullptr, &out.view));
  return {};
}

void VulkanDevice::destroyImage(GpuImage& t) {
  if (t.view) vkDestroyImageView(m_device, t.view, nullptr);
  if (t.image) vkDestroyImage(m_device, t.image, nullptr);
  if (t.memory) vkFreeMemory(m_device, t.memory, nullptr);
  t = GpuImage{};
}

}  // namespace gf::demo::detail
