// Finding, creating or adopting a Vulkan device for lookups.
#include <cstdlib>
#include <cstring>

#include "gpu_device_impl.h"

namespace cpvs::runtime {

namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";
// How long a submission may take before the device counts as hung.
constexpr uint64_t kFenceTimeoutNs = 120ull * 1000 * 1000 * 1000;

std::string typeName(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return "discrete GPU";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return "integrated GPU";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return "virtual GPU";
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return "CPU";
    default: return "other";
  }
}

int preference(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return 0;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return 1;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return 2;
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return 3;
    default: return 4;
  }
}

VKAPI_ATTR VkBool32 VKAPI_CALL onValidationMessage(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                   VkDebugUtilsMessageTypeFlagsEXT,
                                                   const VkDebugUtilsMessengerCallbackDataEXT* data, void* user) {
  auto* impl = static_cast<GpuDevice::Impl*>(user);
  const char* level = severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT ? "error" : "warning";
  std::lock_guard lock(impl->messagesMutex);
  impl->messages.push_back(std::string(level) + ": " + (data && data->pMessage ? data->pMessage : "(no message)"));
  return VK_FALSE;
}

bool envFlag(const char* name) {
  const char* v = std::getenv(name);
  return v && *v && std::strcmp(v, "0") != 0;
}

// A compute queue family of the device, or -1.
int computeFamily(const InstanceApi& vki, VkPhysicalDevice d) {
  uint32_t n = 0;
  vki.vkGetPhysicalDeviceQueueFamilyProperties(d, &n, nullptr);
  std::vector<VkQueueFamilyProperties> families(n);
  vki.vkGetPhysicalDeviceQueueFamilyProperties(d, &n, families.data());
  for (uint32_t i = 0; i < n; ++i)
    if (families[i].queueFlags & VK_QUEUE_COMPUTE_BIT) return int(i);
  return -1;
}

void describe(GpuDevice::Impl& g, const DeviceOptions& options) {
  g.vki.vkGetPhysicalDeviceProperties(g.physical, &g.properties);
  g.vki.vkGetPhysicalDeviceMemoryProperties(g.physical, &g.memory);
  uint32_t n = 0;
  g.vki.vkGetPhysicalDeviceQueueFamilyProperties(g.physical, &n, nullptr);
  std::vector<VkQueueFamilyProperties> families(n);
  g.vki.vkGetPhysicalDeviceQueueFamilyProperties(g.physical, &n, families.data());
  if (g.queueFamily >= n) throw RuntimeError(Status::InvalidArgument, "queue family " + std::to_string(g.queueFamily) + " does not exist");
  g.timestampBits = families[g.queueFamily].timestampValidBits;
  // Storage bindings hold a multiple of 8 bytes (a leaf never straddles two) and a power
  // of two of words (the shader splits a word index with a shift).
  uint64_t limit = g.properties.limits.maxStorageBufferRange;
  if (options.maxBindingBytes != 0 && options.maxBindingBytes < limit) limit = options.maxBindingBytes;
  uint64_t pow2 = 8;
  while (pow2 * 2 <= limit) pow2 *= 2;
  g.bindingLimit = pow2;
  VkCommandPoolCreateInfo pool{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pool.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pool.queueFamilyIndex = g.queueFamily;
  g.check(g.vkd.vkCreateCommandPool(g.device, &pool, nullptr, &g.commandPool), "vkCreateCommandPool");
  g.vkd.vkGetDeviceQueue(g.device, g.queueFamily, 0, &g.queue);
}

}  // namespace

const char* statusName(Status s) {
  switch (s) {
    case Status::Ok: return "ok";
    case Status::InvalidArgument: return "invalid-argument";
    case Status::FileError: return "file-error";
    case Status::CorruptArtifact: return "corrupt-artifact";
    case Status::NoVulkan: return "no-vulkan";
    case Status::NoDevice: return "no-device";
    case Status::DeviceLost: return "device-lost";
    case Status::OutOfMemory: return "out-of-memory";
    case Status::FarmError: return "farm-error";
    case Status::Internal: return "internal";
  }
  return "unknown";
}

GpuDevice::Impl::~Impl() {
  if (device && vkd.vkDeviceWaitIdle && !lost) vkd.vkDeviceWaitIdle(device);
  if (commandPool) vkd.vkDestroyCommandPool(device, commandPool, nullptr);
  if (owned) {
    if (device) vkd.vkDestroyDevice(device, nullptr);
    if (messenger && vki.vkDestroyDebugUtilsMessengerEXT) vki.vkDestroyDebugUtilsMessengerEXT(instance, messenger, nullptr);
    if (instance) vki.vkDestroyInstance(instance, nullptr);
  }
}

void GpuDevice::Impl::checkNotLost() const {
  if (lost) throw RuntimeError(Status::DeviceLost, std::string("the Vulkan device ") + properties.deviceName + " was lost");
}

void GpuDevice::Impl::check(VkResult result, const char* what) {
  if (result == VK_SUCCESS) return;
  const std::string message = std::string(what) + " failed: " + vkResultName(result);
  if (result == VK_ERROR_DEVICE_LOST) {
    lost = true;
    throw RuntimeError(Status::DeviceLost, std::string("the Vulkan device ") + properties.deviceName + " was lost (" + message + ")");
  }
  if (result == VK_ERROR_OUT_OF_HOST_MEMORY || result == VK_ERROR_OUT_OF_DEVICE_MEMORY)
    throw RuntimeError(Status::OutOfMemory, message);
  throw RuntimeError(Status::Internal, message);
}

VulkanBuffer GpuDevice::Impl::createBuffer(VkDeviceSize size, VkBufferUsageFlags usage, bool hostVisible) {
  VulkanBuffer b;
  b.size = size;
  VkBufferCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  info.size = size;
  info.usage = usage;
  info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  check(vkd.vkCreateBuffer(device, &info, nullptr, &b.buffer), "vkCreateBuffer");
  VkMemoryRequirements req;
  vkd.vkGetBufferMemoryRequirements(device, b.buffer, &req);
  const VkMemoryPropertyFlags want =
      hostVisible ? VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT : VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
  uint32_t type = UINT32_MAX;
  for (uint32_t i = 0; i < memory.memoryTypeCount && type == UINT32_MAX; ++i)
    if ((req.memoryTypeBits & (1u << i)) && (memory.memoryTypes[i].propertyFlags & want) == want) type = i;
  for (uint32_t i = 0; i < memory.memoryTypeCount && type == UINT32_MAX && !hostVisible; ++i)
    if (req.memoryTypeBits & (1u << i)) type = i;  // no device-local type: any will do
  if (type == UINT32_MAX) {
    vkd.vkDestroyBuffer(device, b.buffer, nullptr);
    throw RuntimeError(Status::Internal, "the device has no memory type for a buffer of " + std::to_string(size) + " bytes");
  }
  VkMemoryAllocateInfo alloc{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  alloc.allocationSize = req.size;
  alloc.memoryTypeIndex = type;
  const VkResult r = vkd.vkAllocateMemory(device, &alloc, nullptr, &b.memory);
  if (r != VK_SUCCESS) {
    vkd.vkDestroyBuffer(device, b.buffer, nullptr);
    check(r, "vkAllocateMemory");
  }
  check(vkd.vkBindBufferMemory(device, b.buffer, b.memory, 0), "vkBindBufferMemory");
  if (hostVisible) check(vkd.vkMapMemory(device, b.memory, 0, VK_WHOLE_SIZE, 0, &b.mapped), "vkMapMemory");
  return b;
}

void GpuDevice::Impl::destroy(VulkanBuffer& b) {
  if (b.buffer) vkd.vkDestroyBuffer(device, b.buffer, nullptr);
  if (b.memory) vkd.vkFreeMemory(device, b.memory, nullptr);  // unmaps too
  b = VulkanBuffer{};
}

VkCommandBuffer GpuDevice::Impl::beginCommands() {
  checkNotLost();
  VkCommandBufferAllocateInfo alloc{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  alloc.commandPool = commandPool;
  alloc.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  alloc.commandBufferCount = 1;
  VkCommandBuffer cmd;
  check(vkd.vkAllocateCommandBuffers(device, &alloc, &cmd), "vkAllocateCommandBuffers");
  VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
  begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  check(vkd.vkBeginCommandBuffer(cmd, &begin), "vkBeginCommandBuffer");
  return cmd;
}

void GpuDevice::Impl::submitAndWaitRecorded(VkCommandBuffer cmd) {
  struct Release {  // the command buffer goes back to the pool however this ends
    Impl& g;
    VkCommandBuffer cmd;
    ~Release() {
      if (!g.lost) g.vkd.vkDeviceWaitIdle(g.device);
      g.vkd.vkResetCommandBuffer(cmd, 0);
    }
  } release{*this, cmd};
  check(vkd.vkEndCommandBuffer(cmd), "vkEndCommandBuffer");
  if (simulateLoss) check(VK_ERROR_DEVICE_LOST, "vkQueueSubmit");
  VkFenceCreateInfo fenceInfo{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  VkFence fence;
  check(vkd.vkCreateFence(device, &fenceInfo, nullptr, &fence), "vkCreateFence");
  VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  submit.commandBufferCount = 1;
  submit.pCommandBuffers = &cmd;
  VkResult r = vkd.vkQueueSubmit(queue, 1, &submit, fence);
  if (r == VK_SUCCESS) r = vkd.vkWaitForFences(device, 1, &fence, VK_TRUE, kFenceTimeoutNs);
  vkd.vkDestroyFence(device, fence, nullptr);
  if (r == VK_TIMEOUT) r = VK_ERROR_DEVICE_LOST;  // hung: no answer is coming
  check(r, "vkQueueSubmit");
}

GpuDevice::GpuDevice(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
GpuDevice::~GpuDevice() = default;

std::unique_ptr<GpuDevice> GpuDevice::create(const DeviceOptions& options) {
  auto g = std::make_unique<Impl>();
  if (std::string why = g->loader.load(options.loader); !why.empty()) throw RuntimeError(Status::NoVulkan, why);
  const bool validation = options.validation || envFlag("CPVS_VALIDATION");
  std::vector<const char*> layers, extensions;
  if (validation) {
    uint32_t n = 0;
    g->loader.vkEnumerateInstanceLayerProperties(&n, nullptr);
    std::vector<VkLayerProperties> available(n);
    g->loader.vkEnumerateInstanceLayerProperties(&n, available.data());
    bool found = false;
    for (const auto& l : available) found = found || std::strcmp(l.layerName, kValidationLayer) == 0;
    if (!found)
      throw RuntimeError(Status::NoVulkan, std::string("validation was asked for and ") + kValidationLayer +
                                               " is not installed (Debian: vulkan-validationlayers)");
    layers.push_back(kValidationLayer);
    extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
  }
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "cpvs_runtime";
  app.apiVersion = VK_API_VERSION_1_1;
  VkInstanceCreateInfo info{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  info.pApplicationInfo = &app;
  info.enabledLayerCount = uint32_t(layers.size());
  info.ppEnabledLayerNames = layers.data();
  info.enabledExtensionCount = uint32_t(extensions.size());
  info.ppEnabledExtensionNames = extensions.data();
  VkDebugUtilsMessengerCreateInfoEXT messenger{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
  messenger.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  messenger.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  messenger.pfnUserCallback = onValidationMessage;
  messenger.pUserData = g.get();
  if (validation) info.pNext = &messenger;  // also what instance creation itself reports
  const VkResult created = g->loader.vkCreateInstance(&info, nullptr, &g->instance);
  if (created == VK_ERROR_INCOMPATIBLE_DRIVER || created == VK_ERROR_INITIALIZATION_FAILED)
    throw RuntimeError(Status::NoVulkan, std::string("no Vulkan driver: vkCreateInstance failed with ") + vkResultName(created) +
                                             " (on Debian, mesa-vulkan-drivers gives a CPU device)");
  if (created != VK_SUCCESS) throw RuntimeError(Status::NoVulkan, std::string("vkCreateInstance failed: ") + vkResultName(created));
  g->owned = true;
  if (!g->vki.load(g->loader.vkGetInstanceProcAddr, g->instance))
    throw RuntimeError(Status::NoVulkan, "the Vulkan loader lacks core 1.0 instance functions");
  if (validation) {
    if (!g->vki.vkCreateDebugUtilsMessengerEXT) throw RuntimeError(Status::NoVulkan, "VK_EXT_debug_utils is missing");
    g->check(g->vki.vkCreateDebugUtilsMessengerEXT(g->instance, &messenger, nullptr, &g->messenger), "vkCreateDebugUtilsMessengerEXT");
  }

  uint32_t count = 0;
  g->vki.vkEnumeratePhysicalDevices(g->instance, &count, nullptr);
  std::vector<VkPhysicalDevice> devices(count);
  g->vki.vkEnumeratePhysicalDevices(g->instance, &count, devices.data());
  std::string select = options.select;
  if (select.empty())
    if (const char* env = std::getenv("CPVS_DEVICE")) select = env;
  int best = -1, bestPreference = 99;
  std::string seen;
  for (uint32_t i = 0; i < count; ++i) {
    VkPhysicalDeviceProperties p;
    VkPhysicalDeviceFeatures f;
    g->vki.vkGetPhysicalDeviceProperties(devices[i], &p);
    g->vki.vkGetPhysicalDeviceFeatures(devices[i], &f);
    std::string why;
    if (!select.empty() && std::string(p.deviceName).find(select) == std::string::npos) why = "not selected";
    else if (!f.shaderFloat64) why = "no 64-bit floats in shaders";
    else if (computeFamily(g->vki, devices[i]) < 0) why = "no compute queue";
    seen += std::string(seen.empty() ? "" : "; ") + p.deviceName + " (" + typeName(p.deviceType) + (why.empty() ? "" : ": " + why) + ")";
    if (why.empty() && preference(p.deviceType) < bestPreference) {
      best = int(i);
      bestPreference = preference(p.deviceType);
    }
  }
  if (best < 0)
    throw RuntimeError(Status::NoDevice, "no usable Vulkan device" + (select.empty() ? std::string() : " matching \"" + select + "\"") +
                                             (count == 0 ? std::string(": the driver reports none") : ": found " + seen));
  g->physical = devices[size_t(best)];
  g->queueFamily = uint32_t(computeFamily(g->vki, g->physical));
  const float priority = 1.0f;
  VkDeviceQueueCreateInfo queue{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
  queue.queueFamilyIndex = g->queueFamily;
  queue.queueCount = 1;
  queue.pQueuePriorities = &priority;
  VkPhysicalDeviceFeatures features{};
  features.shaderFloat64 = VK_TRUE;
  VkDeviceCreateInfo deviceInfo{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
  deviceInfo.queueCreateInfoCount = 1;
  deviceInfo.pQueueCreateInfos = &queue;
  deviceInfo.pEnabledFeatures = &features;
  const VkResult made = g->vki.vkCreateDevice(g->physical, &deviceInfo, nullptr, &g->device);
  if (made != VK_SUCCESS) throw RuntimeError(Status::NoDevice, std::string("vkCreateDevice failed: ") + vkResultName(made));
  if (!g->vkd.load(g->vki.vkGetDeviceProcAddr, g->device))
    throw RuntimeError(Status::NoVulkan, "the Vulkan driver lacks core 1.0 device functions");
  describe(*g, options);
  return std::unique_ptr<GpuDevice>(new GpuDevice(std::move(g)));
}

std::unique_ptr<GpuDevice> GpuDevice::adopt(const External& e, const DeviceOptions& options) {
  if (!e.instance || !e.physicalDevice || !e.device)
    throw RuntimeError(Status::InvalidArgument, "adopting a Vulkan device needs its instance, physical device and device");
  auto g = std::make_unique<Impl>();
  auto get = reinterpret_cast<PFN_vkGetInstanceProcAddr>(e.getInstanceProcAddr);
  if (!get) {
    if (std::string why = g->loader.load(options.loader); !why.empty()) throw RuntimeError(Status::NoVulkan, why);
    get = g->loader.vkGetInstanceProcAddr;
  }
  g->instance = e.instance;
  g->physical = e.physicalDevice;
  g->device = e.device;
  g->queueFamily = e.queueFamily;
  if (!g->vki.load(get, g->instance)) throw RuntimeError(Status::NoVulkan, "the application's Vulkan instance lacks core functions");
  VkPhysicalDeviceFeatures f;
  g->vki.vkGetPhysicalDeviceFeatures(g->physical, &f);
  if (!f.shaderFloat64) throw RuntimeError(Status::NoDevice, "the application's device has no 64-bit floats in shaders");
  if (!g->vkd.load(g->vki.vkGetDeviceProcAddr, g->device))
    throw RuntimeError(Status::NoVulkan, "the application's Vulkan device lacks core functions");
  describe(*g, options);
  return std::unique_ptr<GpuDevice>(new GpuDevice(std::move(g)));
}

std::string GpuDevice::name() const { return impl_->properties.deviceName; }
std::string GpuDevice::type() const { return typeName(impl_->properties.deviceType); }
uint64_t GpuDevice::maxStorageBufferRange() const { return impl_->properties.limits.maxStorageBufferRange; }
std::vector<std::string> GpuDevice::validationMessages() const {
  std::lock_guard lock(impl_->messagesMutex);
  return impl_->messages;
}
void GpuDevice::simulateDeviceLossForTests() { impl_->simulateLoss = true; }

}  // namespace cpvs::runtime
