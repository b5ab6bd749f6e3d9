// The C API over the C++ one: every call catches, stores its message per thread, and
// returns the status.
#include "cpvs/runtime/cpvs_runtime.h"

#include <cstring>
#include <new>
#include <string>

#include "cpvs/runtime/runtime.h"

using namespace cpvs;
using namespace cpvs::runtime;

struct CpvsDevice_T {
  std::unique_ptr<GpuDevice> device;
  std::string name;
};

struct CpvsShadows_T {
  std::unique_ptr<ShadowLookups> lookups;
};

namespace {

thread_local std::string lastError;

template <class F>
CpvsStatus guarded(F&& f) {
  lastError.clear();
  try {
    f();
    return CPVS_OK;
  } catch (const RuntimeError& e) {
    lastError = e.what();
    return CpvsStatus(int(e.status()));
  } catch (const std::bad_alloc&) {
    lastError = "out of memory";
    return CPVS_ERROR_OUT_OF_MEMORY;
  } catch (const std::exception& e) {
    lastError = e.what();
    return CPVS_ERROR_INTERNAL;
  }
}

void require(bool ok, const char* what) {
  if (!ok) throw RuntimeError(Status::InvalidArgument, what);
}

}  // namespace

static_assert(int(Status::Internal) == CPVS_ERROR_INTERNAL && int(Status::FarmError) == CPVS_ERROR_FARM &&
              int(Status::DeviceLost) == CPVS_ERROR_DEVICE_LOST && int(Status::CorruptArtifact) == CPVS_ERROR_CORRUPT_ARTIFACT);

extern "C" {

CpvsStatus cpvsNewDevice(const CpvsDeviceDesc* desc, CpvsDevice* device) {
  return guarded([&] {
    require(device != nullptr, "cpvsNewDevice: device is null");
    *device = nullptr;
    DeviceOptions options;
    if (desc) {
      if (desc->select) options.select = desc->select;
      options.validation = desc->validation != 0;
      options.maxBindingBytes = desc->maxBindingBytes;
    }
    auto d = std::make_unique<CpvsDevice_T>();
    d->device = GpuDevice::create(options);
    d->name = d->device->name();
    *device = d.release();
  });
}

CpvsStatus cpvsNewDeviceFromVulkan(void* instance, void* physicalDevice, void* vkDevice, uint32_t queueFamily,
                                   void* getInstanceProcAddr, CpvsDevice* device) {
  return guarded([&] {
    require(device != nullptr, "cpvsNewDeviceFromVulkan: device is null");
    *device = nullptr;
    GpuDevice::External e;
    e.instance = static_cast<VkInstance>(instance);
    e.physicalDevice = static_cast<VkPhysicalDevice>(physicalDevice);
    e.device = static_cast<VkDevice>(vkDevice);
    e.queueFamily = queueFamily;
    e.getInstanceProcAddr = getInstanceProcAddr;
    auto d = std::make_unique<CpvsDevice_T>();
    d->device = GpuDevice::adopt(e);
    d->name = d->device->name();
    *device = d.release();
  });
}

void cpvsReleaseDevice(CpvsDevice device) { delete device; }

const char* cpvsGetDeviceName(CpvsDevice device) { return device ? device->name.c_str() : ""; }

size_t cpvsGetValidationMessageCount(CpvsDevice device) {
  return device ? device->device->validationMessages().size() : 0;
}

void cpvsSimulateDeviceLossForTests(CpvsDevice device) {
  if (device) device->device->simulateDeviceLossForTests();
}

CpvsStatus cpvsOpenShadows(const char* path, CpvsDevice device, uint32_t flags, CpvsShadows* shadows) {
  return guarded([&] {
    require(shadows != nullptr, "cpvsOpenShadows: shadows is null");
    *shadows = nullptr;
    require(path != nullptr, "cpvsOpenShadows: path is null");
    require((flags & ~CPVS_FALLBACK_CPU) == 0, "cpvsOpenShadows: unknown flags");
    auto s = std::make_unique<CpvsShadows_T>();
    auto artifact = ShadowArtifact::open(path);
    const Backend backend = (flags & CPVS_FALLBACK_CPU) ? Backend::Auto : Backend::Gpu;
    s->lookups = device ? std::make_unique<ShadowLookups>(artifact, *device->device, backend)
                        : std::make_unique<ShadowLookups>(artifact, Backend::Cpu);
    *shadows = s.release();
  });
}

CpvsStatus cpvsFetchShadows(const char* address, const char* token, const char* caFile, const char* jobId,
                            const char* cacheDir, char* pathOut, size_t pathCapacity) {
  return guarded([&] {
    require(address && jobId && cacheDir && pathOut, "cpvsFetchShadows: a required argument is null");
    const std::string path = fetchArtifact({address, token ? token : "", caFile ? caFile : ""}, jobId, cacheDir);
    require(path.size() < pathCapacity, "cpvsFetchShadows: pathOut is too small for the path");
    std::memcpy(pathOut, path.c_str(), path.size() + 1);
  });
}

void cpvsReleaseShadows(CpvsShadows shadows) { delete shadows; }

int cpvsShadowsOnDevice(CpvsShadows shadows) { return shadows && shadows->lookups->onGpu() ? 1 : 0; }

CpvsStatus cpvsQueryShadows(CpvsShadows shadows, size_t count, const double* points, const double* normals, int pcf,
                            uint32_t* litTexels) {
  return guarded([&] {
    require(shadows != nullptr, "cpvsQueryShadows: shadows is null");
    require(count == 0 || (points && litTexels), "cpvsQueryShadows: points or litTexels is null");
    std::vector<Vec3> p(count), n(normals ? count : 0);
    for (size_t i = 0; i < count; ++i) p[i] = {points[3 * i], points[3 * i + 1], points[3 * i + 2]};
    for (size_t i = 0; i < n.size(); ++i) n[i] = {normals[3 * i], normals[3 * i + 1], normals[3 * i + 2]};
    std::vector<uint32_t> out;
    shadows->lookups->litTexels(p, n, pcf, out);  // with CPVS_FALLBACK_CPU, the CPU after a loss
    if (count) std::memcpy(litTexels, out.data(), count * 4);
  });
}

const char* cpvsGetLastError(void) { return lastError.c_str(); }

const char* cpvsGetStatusName(CpvsStatus status) { return statusName(Status(int(status))); }

}  // extern "C"
