// Vulkan without linking it: the loader (libvulkan.so.1) is opened at run time, so a
// program that links cpvs_runtime starts on a machine without one and gets a clear error
// (or the CPU path) instead of failing to load. Function pointers in one table per level,
// filled through vkGetInstanceProcAddr / vkGetDeviceProcAddr. Private to runtime.
#pragma once

#define VK_NO_PROTOTYPES
#include <vulkan/vulkan.h>

#include <string>

namespace cpvs::runtime {

#define CPVS_VK_GLOBAL(X) \
  X(vkCreateInstance)     \
  X(vkEnumerateInstanceLayerProperties) \
  X(vkEnumerateInstanceExtensionProperties)

#define CPVS_VK_INSTANCE(X)                   \
  X(vkDestroyInstance)                        \
  X(vkEnumeratePhysicalDevices)               \
  X(vkGetPhysicalDeviceProperties)            \
  X(vkGetPhysicalDeviceFeatures)              \
  X(vkGetPhysicalDeviceQueueFamilyProperties) \
  X(vkGetPhysicalDeviceMemoryProperties)      \
  X(vkCreateDevice)                           \
  X(vkGetDeviceProcAddr)

#define CPVS_VK_DEVICE(X)           \
  X(vkDestroyDevice)                \
  X(vkGetDeviceQueue)               \
  X(vkDeviceWaitIdle)               \
  X(vkCreateBuffer)                 \
  X(vkDestroyBuffer)                \
  X(vkGetBufferMemoryRequirements)  \
  X(vkAllocateMemory)               \
  X(vkFreeMemory)                   \
  X(vkBindBufferMemory)             \
  X(vkMapMemory)                    \
  X(vkUnmapMemory)                  \
  X(vkCreateShaderModule)           \
  X(vkDestroyShaderModule)          \
  X(vkCreateDescriptorSetLayout)    \
  X(vkDestroyDescriptorSetLayout)   \
  X(vkCreatePipelineLayout)         \
  X(vkDestroyPipelineLayout)        \
  X(vkCreateComputePipelines)       \
  X(vkDestroyPipeline)              \
  X(vkCreateDescriptorPool)         \
  X(vkDestroyDescriptorPool)        \
  X(vkAllocateDescriptorSets)       \
  X(vkUpdateDescriptorSets)         \
  X(vkCreateCommandPool)            \
  X(vkDestroyCommandPool)           \
  X(vkAllocateCommandBuffers)       \
  X(vkResetCommandBuffer)           \
  X(vkBeginCommandBuffer)           \
  X(vkEndCommandBuffer)             \
  X(vkCmdBindPipeline)              \
  X(vkCmdBindDescriptorSets)        \
  X(vkCmdPushConstants)             \
  X(vkCmdDispatch)                  \
  X(vkCmdPipelineBarrier)           \
  X(vkCmdCopyBuffer)                \
  X(vkCmdWriteTimestamp)            \
  X(vkCmdResetQueryPool)            \
  X(vkCreateQueryPool)              \
  X(vkDestroyQueryPool)             \
  X(vkGetQueryPoolResults)          \
  X(vkQueueSubmit)                  \
  X(vkCreateFence)                  \
  X(vkDestroyFence)                 \
  X(vkWaitForFences)                \
  X(vkResetFences)

#define CPVS_VK_MEMBER(name) PFN_##name name = nullptr;

/// The loader and its global functions. load() returns an empty string on success, else
/// why it failed (no library, no entry point).
struct VulkanLoader {
  void* library = nullptr;
  PFN_vkGetInstanceProcAddr vkGetInstanceProcAddr = nullptr;
  CPVS_VK_GLOBAL(CPVS_VK_MEMBER)

  /// Opens `path` (empty: CPVS_VULKAN_LOADER, else libvulkan.so.1). Idempotent.
  std::string load(const std::string& path);
  ~VulkanLoader();
};

struct InstanceApi {
  CPVS_VK_INSTANCE(CPVS_VK_MEMBER)
  PFN_vkCreateDebugUtilsMessengerEXT vkCreateDebugUtilsMessengerEXT = nullptr;
  PFN_vkDestroyDebugUtilsMessengerEXT vkDestroyDebugUtilsMessengerEXT = nullptr;
  /// False when a core function is missing.
  bool load(PFN_vkGetInstanceProcAddr get, VkInstance instance);
};

struct DeviceApi {
  CPVS_VK_DEVICE(CPVS_VK_MEMBER)
  bool load(PFN_vkGetDeviceProcAddr get, VkDevice device);
};

/// "VK_ERROR_DEVICE_LOST" and the like, for messages.
const char* vkResultName(VkResult r);

}  // namespace cpvs::runtime
