// GpuDevice's state, shared with GpuShadows. Private to runtime.
#pragma once

#include <mutex>
#include <string>
#include <vector>

#include "cpvs/runtime/runtime.h"
#include "vulkan_api.h"

namespace cpvs::runtime {

/// A buffer and its memory.
struct VulkanBuffer {
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  VkDeviceSize size = 0;
  void* mapped = nullptr;  // host-visible buffers stay mapped
};

struct GpuDevice::Impl {
  VulkanLoader loader;
  InstanceApi vki;
  DeviceApi vkd;
  VkInstance instance = VK_NULL_HANDLE;
  VkPhysicalDevice physical = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;
  uint32_t queueFamily = 0;
  bool owned = false;  // instance and device are ours to destroy
  VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
  VkPhysicalDeviceProperties properties{};
  VkPhysicalDeviceMemoryProperties memory{};
  uint32_t timestampBits = 0;
  uint64_t bindingLimit = 0;  // bytes per storage binding
  VkCommandPool commandPool = VK_NULL_HANDLE;
  bool lost = false, simulateLoss = false;

  mutable std::mutex messagesMutex;
  /// Command pool and queue are used by one thread at a time (uploads of a new track
  /// version while another thread queries).
  std::mutex submitMutex;
  std::vector<std::string> messages;

  ~Impl();

  /// Throws RuntimeError for a failed call, DeviceLost for VK_ERROR_DEVICE_LOST (and
  /// remembers it: every later call fails the same way).
  void check(VkResult result, const char* what);
  void checkNotLost() const;
  VulkanBuffer createBuffer(VkDeviceSize size, VkBufferUsageFlags usage, bool hostVisible);
  void destroy(VulkanBuffer& b);
  /// Records with `record`, submits, waits (bounded), as one command buffer.
  template <class Record>
  void submitAndWait(Record&& record);
  void submitAndWaitRecorded(VkCommandBuffer cmd);
  VkCommandBuffer beginCommands();
};

template <class Record>
void GpuDevice::Impl::submitAndWait(Record&& record) {
  std::lock_guard lock(submitMutex);
  VkCommandBuffer cmd = beginCommands();
  record(cmd);
  submitAndWaitRecorded(cmd);
}

}  // namespace cpvs::runtime
