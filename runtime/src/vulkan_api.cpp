#include "vulkan_api.h"

#include <dlfcn.h>

#include <cstdlib>

namespace cpvs::runtime {

std::string VulkanLoader::load(const std::string& path) {
  if (library) return {};
  std::string name = path;
  if (name.empty()) {
    const char* env = std::getenv("CPVS_VULKAN_LOADER");
    name = env && *env ? env : "libvulkan.so.1";
  }
  library = dlopen(name.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!library) {
    const char* why = dlerror();
    return "no Vulkan loader: cannot open " + name + (why ? std::string(" (") + why + ")" : std::string()) +
           "; install libvulkan1 and a driver (on Debian: mesa-vulkan-drivers for the CPU device)";
  }
  vkGetInstanceProcAddr = reinterpret_cast<PFN_vkGetInstanceProcAddr>(dlsym(library, "vkGetInstanceProcAddr"));
  if (!vkGetInstanceProcAddr) return "no Vulkan loader: " + name + " has no vkGetInstanceProcAddr";
#define CPVS_VK_LOAD_GLOBAL(fn) fn = reinterpret_cast<PFN_##fn>(vkGetInstanceProcAddr(nullptr, #fn));
  CPVS_VK_GLOBAL(CPVS_VK_LOAD_GLOBAL)
  if (!vkCreateInstance || !vkEnumerateInstanceLayerProperties || !vkEnumerateInstanceExtensionProperties)
    return "no Vulkan loader: " + name + " lacks vkCreateInstance";
  return {};
}

VulkanLoader::~VulkanLoader() {
  if (library) dlclose(library);
}

bool InstanceApi::load(PFN_vkGetInstanceProcAddr get, VkInstance instance) {
  bool ok = true;
#define CPVS_VK_LOAD_INSTANCE(fn) ok = (fn = reinterpret_cast<PFN_##fn>(get(instance, #fn))) != nullptr && ok;
  CPVS_VK_INSTANCE(CPVS_VK_LOAD_INSTANCE)
  vkCreateDebugUtilsMessengerEXT =
      reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(get(instance, "vkCreateDebugUtilsMessengerEXT"));
  vkDestroyDebugUtilsMessengerEXT =
      reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(get(instance, "vkDestroyDebugUtilsMessengerEXT"));
  return ok;
}

bool DeviceApi::load(PFN_vkGetDeviceProcAddr get, VkDevice device) {
  bool ok = true;
#define CPVS_VK_LOAD_DEVICE(fn) ok = (fn = reinterpret_cast<PFN_##fn>(get(device, #fn))) != nullptr && ok;
  CPVS_VK_DEVICE(CPVS_VK_LOAD_DEVICE)
  return ok;
}

const char* vkResultName(VkResult r) {
  switch (r) {
    case VK_SUCCESS: return "VK_SUCCESS";
    case VK_NOT_READY: return "VK_NOT_READY";
    case VK_TIMEOUT: return "VK_TIMEOUT";
    case VK_ERROR_OUT_OF_HOST_MEMORY: return "VK_ERROR_OUT_OF_HOST_MEMORY";
    case VK_ERROR_OUT_OF_DEVICE_MEMORY: return "VK_ERROR_OUT_OF_DEVICE_MEMORY";
    case VK_ERROR_INITIALIZATION_FAILED: return "VK_ERROR_INITIALIZATION_FAILED";
    case VK_ERROR_DEVICE_LOST: return "VK_ERROR_DEVICE_LOST";
    case VK_ERROR_MEMORY_MAP_FAILED: return "VK_ERROR_MEMORY_MAP_FAILED";
    case VK_ERROR_LAYER_NOT_PRESENT: return "VK_ERROR_LAYER_NOT_PRESENT";
    case VK_ERROR_EXTENSION_NOT_PRESENT: return "VK_ERROR_EXTENSION_NOT_PRESENT";
    case VK_ERROR_FEATURE_NOT_PRESENT: return "VK_ERROR_FEATURE_NOT_PRESENT";
    case VK_ERROR_INCOMPATIBLE_DRIVER: return "VK_ERROR_INCOMPATIBLE_DRIVER";
    case VK_ERROR_TOO_MANY_OBJECTS: return "VK_ERROR_TOO_MANY_OBJECTS";
    default: return "a Vulkan error";
  }
}

}  // namespace cpvs::runtime
