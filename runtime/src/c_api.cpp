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
  std::vector<uint8_t> sun;  // cpvsGetShadowsBuffer's CpvsSun block
  std::shared_ptr<const DynamicCasters> casters;  // the casters last set
  std::vector<uint8_t> casterBytes;  // cpvsGetShadowsBuffer's CpvsCasters for them, made when first asked
  std::vector<uint8_t> translucent, transmittance;  // its CpvsTranslucent and CpvsTransmittances
};

struct CpvsLights_T {
  std::shared_ptr<const LightArtifact> artifact;
  std::unique_ptr<GpuLights> gpu;  // null: the CPU answers
  bool fallback = false;
  std::vector<uint8_t> lights, grids, boundaries;  // cpvsGetLightBuffer's bytes
  std::shared_ptr<const LightCasters> casters;     // the dynamic casters last set
  std::vector<uint8_t> casterTrees, casterNodes;   // and their buffers
};

namespace {

thread_local std::string lastError;

/// `count` points of 3 doubles each (none for a null array).
std::vector<Vec3> vec3s(const double* xyz, size_t count) {
  std::vector<Vec3> out(count);
  for (size_t i = 0; i < count; ++i) out[i] = {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]};
  return out;
}

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

// A batch on the lights' device, else (none, or one lost with CPVS_FALLBACK_CPU, which
// leaves the lights on the CPU from then on) on the CPU.
template <class OnDevice, class OnCpu>
void onDeviceOrCpu(CpvsLights lights, OnDevice&& onDevice, OnCpu&& onCpu) {
  if (lights->gpu) try {
      onDevice();
    } catch (const RuntimeError& e) {
      if (!lights->fallback || e.status() != Status::DeviceLost) throw;
      lights->gpu.reset();
    }
  if (!lights->gpu) onCpu();
}

// The C meshes as the C++ API takes them.
std::vector<CasterMesh> casterMeshesOf(const CpvsCasterMesh* meshes, size_t meshCount, const std::string& function) {
  std::vector<CasterMesh> placed(meshCount);
  for (size_t k = 0; k < meshCount; ++k) {
    const CpvsCasterMesh& m = meshes[k];
    require((m.vertexCount == 0 || m.positions) && (m.triangleCount == 0 || m.indices),
            (function + ": a mesh's positions or indices are null").c_str());
    CasterMesh& c = placed[k];
    c.positions.resize(m.vertexCount);
    for (size_t v = 0; v < m.vertexCount; ++v)
      c.positions[v] = Vec3{m.positions[3 * v], m.positions[3 * v + 1], m.positions[3 * v + 2]};
    c.indices.assign(m.indices, m.indices + 3 * m.triangleCount);
    if (m.closed) c.closed.assign(m.closed, m.closed + m.triangleCount);
    std::copy(m.transform, m.transform + 12, c.transform.begin());
  }
  return placed;
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
    s->sun = sunBlockBytes(*artifact, 0);
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

CpvsShadowsKind cpvsGetShadowsKind(CpvsShadows shadows) {
  return shadows && shadows->lookups->artifact().kind() == ArtifactKind::DagMh ? CPVS_SHADOWS_DAG_MH : CPVS_SHADOWS_CPVS;
}

CpvsStatus cpvsQueryShadows(CpvsShadows shadows, size_t count, const double* points, const double* normals, int pcf,
                            uint32_t* litTexels) {
  return guarded([&] {
    require(shadows != nullptr, "cpvsQueryShadows: shadows is null");
    require(count == 0 || (points && litTexels), "cpvsQueryShadows: points or litTexels is null");
    const std::vector<Vec3> p = vec3s(points, count), n = vec3s(normals, normals ? count : 0);
    std::vector<uint32_t> out;
    shadows->lookups->litTexels(p, n, pcf, out);  // with CPVS_FALLBACK_CPU, the CPU after a loss
    if (count) std::memcpy(litTexels, out.data(), count * 4);
  });
}

int cpvsShadowsHaveTranslucentCasters(CpvsShadows shadows) {
  return shadows && shadows->lookups->artifact().translucent() ? 1 : 0;
}

CpvsStatus cpvsQueryTransmittance(CpvsShadows shadows, size_t count, const double* points, const double* normals,
                                  float* rgb) {
  return guarded([&] {
    require(shadows != nullptr, "cpvsQueryTransmittance: shadows is null");
    require(count == 0 || (points && rgb), "cpvsQueryTransmittance: points or rgb is null");
    const std::vector<Vec3> p = vec3s(points, count), n = vec3s(normals, normals ? count : 0);
    std::vector<std::array<float, 3>> out;
    shadows->lookups->transmittance(p, n, out);
    if (count) std::memcpy(rgb, out.data(), count * 12);
  });
}

CpvsStatus cpvsSetDynamicCasters(CpvsShadows shadows, const CpvsCasterMesh* meshes, size_t meshCount, double normalOffset) {
  return guarded([&] {
    require(shadows != nullptr, "cpvsSetDynamicCasters: shadows is null");
    require(meshCount == 0 || meshes != nullptr, "cpvsSetDynamicCasters: meshes is null");
    if (meshCount == 0) {
      shadows->lookups->setDynamicCasters(nullptr);
      shadows->casters.reset();
      shadows->casterBytes.clear();
      return;
    }
    const std::vector<CasterMesh> placed = casterMeshesOf(meshes, meshCount, "cpvsSetDynamicCasters");
    // On a device the frusta are inserted there (seed 003 §3.6); the CPU builds its own
    // tree only if it is asked.
    auto casters = std::make_shared<const DynamicCasters>(
        shadows->lookups->artifact(), placed, normalOffset,
        shadows->lookups->onGpu() ? DynamicCasters::Build::Device : DynamicCasters::Build::Cpu);
    shadows->lookups->setDynamicCasters(casters);
    shadows->casters = casters;
    shadows->casterBytes.clear();
  });
}

CpvsStatus cpvsGetShadowsBuffer(CpvsShadows shadows, CpvsShadowsBuffer which, const void** data, size_t* bytes) {
  return guarded([&] {
    require(shadows != nullptr && data != nullptr && bytes != nullptr, "cpvsGetShadowsBuffer: an argument is null");
    const std::vector<uint32_t>& words = shadows->lookups->artifact().words();
    switch (which) {
      case CPVS_SHADOWS_BUFFER_SUN: *data = shadows->sun.data(), *bytes = shadows->sun.size(); return;
      case CPVS_SHADOWS_BUFFER_WORDS: *data = words.data(), *bytes = words.size() * 4; return;
      case CPVS_SHADOWS_BUFFER_CASTERS:
        if (shadows->casters && shadows->casterBytes.empty()) shadows->casterBytes = shadows->casters->linkedGpuBytes();
        *data = shadows->casterBytes.data(), *bytes = shadows->casterBytes.size();
        return;
      case CPVS_SHADOWS_BUFFER_TRANSLUCENT:
        if (shadows->translucent.empty()) shadows->translucent = shadows->lookups->artifact().translucentGpuBytes();
        *data = shadows->translucent.data(), *bytes = shadows->translucent.size();
        return;
      case CPVS_SHADOWS_BUFFER_TRANSMITTANCE:
        if (shadows->transmittance.empty()) shadows->transmittance = shadows->lookups->artifact().transmittanceGpuBytes();
        *data = shadows->transmittance.data(), *bytes = shadows->transmittance.size();
        return;
    }
    require(false, "cpvsGetShadowsBuffer: no such buffer");
  });
}

CpvsStatus cpvsOpenLights(const char* path, CpvsDevice device, uint32_t flags, CpvsLights* lights) {
  return guarded([&] {
    require(lights != nullptr, "cpvsOpenLights: lights is null");
    *lights = nullptr;
    require(path != nullptr, "cpvsOpenLights: path is null");
    require((flags & ~CPVS_FALLBACK_CPU) == 0, "cpvsOpenLights: unknown flags");
    auto l = std::make_unique<CpvsLights_T>();
    l->artifact = LightArtifact::open(path);
    l->fallback = (flags & CPVS_FALLBACK_CPU) != 0;
    const LightBundle& b = l->artifact->bundle();
    l->lights = lightTableBytes(b), l->grids = gridTableBytes(b, 0), l->boundaries = sliceBoundaryBytes(b);
    if (device) try {
        l->gpu = std::make_unique<GpuLights>(*device->device, l->artifact);
      } catch (const RuntimeError&) {
        if (!l->fallback) throw;
      }
    *lights = l.release();
  });
}

void cpvsReleaseLights(CpvsLights lights) { delete lights; }

int cpvsLightsOnDevice(CpvsLights lights) { return lights && lights->gpu ? 1 : 0; }

size_t cpvsGetLightCount(CpvsLights lights) { return lights ? lights->artifact->lightCount() : 0; }

CpvsStatus cpvsGetLightInfo(CpvsLights lights, size_t light, CpvsLightInfo* info) {
  return guarded([&] {
    require(lights != nullptr && info != nullptr, "cpvsGetLightInfo: lights or info is null");
    require(light < lights->artifact->lightCount(), "cpvsGetLightInfo: no such light");
    const LightBundle& b = lights->artifact->bundle();
    const BundleLight& bl = b.lights[light];
    const Light& l = bl.light;
    const bool point = l.kind == LightKind::Point;
    const Vec3 d = point ? Vec3{} : normalize(l.direction);
    *info = CpvsLightInfo{point ? 1u : 0u, bl.gridCount, {l.position.x, l.position.y, l.position.z}, {d.x, d.y, d.z},
                          point ? 0.0 : l.coneDeg, b.grids[bl.firstGrid].grid.far(), {l.colour.x, l.colour.y, l.colour.z},
                          l.intensity, l.name.c_str()};
  });
}

CpvsStatus cpvsQueryLights(CpvsLights lights, size_t count, const uint32_t* lightOfQuery, size_t lightCount,
                           const double* points, const double* normals, int pcf, uint32_t* litTexels) {
  return guarded([&] {
    require(lights != nullptr, "cpvsQueryLights: lights is null");
    require(count == 0 || (points && litTexels && lightOfQuery), "cpvsQueryLights: lightOfQuery, points or litTexels is null");
    require(lightCount == count || lightCount == 1, "cpvsQueryLights: lightCount must be count or 1");
    const std::vector<Vec3> p = vec3s(points, count), n = vec3s(normals, normals ? count : 0);
    const std::vector<uint32_t> which(lightOfQuery, lightOfQuery + (count ? lightCount : 0));
    std::vector<uint32_t> out;
    if (count == 0) return;
    onDeviceOrCpu(lights, [&] { lights->gpu->litTexels(which, p, n, pcf, out); },
                  [&] { cpuLightLitTexels(*lights->artifact, which, p, n, pcf, out, lights->casters.get()); });
    std::memcpy(litTexels, out.data(), count * 4);
  });
}

size_t cpvsGetAreaLightCount(CpvsLights lights) { return lights ? lights->artifact->cpu().areaCount() : 0; }

CpvsStatus cpvsGetAreaLight(CpvsLights lights, size_t area, uint32_t* firstVpl, uint32_t* vplCount) {
  return guarded([&] {
    require(lights != nullptr && firstVpl != nullptr && vplCount != nullptr, "cpvsGetAreaLight: an argument is null");
    require(area < lights->artifact->cpu().areaCount(), "cpvsGetAreaLight: no such area light");
    const std::vector<uint32_t>& vpls = lights->artifact->cpu().vplsOf(area);
    *firstVpl = vpls.front();
    *vplCount = uint32_t(vpls.size());
  });
}

CpvsStatus cpvsQuerySoftShadows(CpvsLights lights, size_t count, const uint32_t* areaOfQuery, size_t areaCount,
                                const double* points, const double* normals, float* visibility) {
  return guarded([&] {
    require(lights != nullptr, "cpvsQuerySoftShadows: lights is null");
    require(count == 0 || (points && visibility && areaOfQuery), "cpvsQuerySoftShadows: areaOfQuery, points or visibility is null");
    require(areaCount == count || areaCount == 1, "cpvsQuerySoftShadows: areaCount must be count or 1");
    const std::vector<Vec3> p = vec3s(points, count), n = vec3s(normals, normals ? count : 0);
    const std::vector<uint32_t> areas(areaOfQuery, areaOfQuery + (count ? areaCount : 0));
    std::vector<float> out;
    if (count == 0) return;
    onDeviceOrCpu(lights, [&] { lights->gpu->softVisibility(areas, p, n, out); },
                  [&] { cpuSoftVisibility(*lights->artifact, areas, p, n, out); });
    std::memcpy(visibility, out.data(), count * sizeof(float));
  });
}

CpvsStatus cpvsSetLightCasters(CpvsLights lights, const CpvsCasterMesh* meshes, size_t meshCount, double normalOffset) {
  return guarded([&] {
    require(lights != nullptr, "cpvsSetLightCasters: lights is null");
    require(meshCount == 0 || meshes != nullptr, "cpvsSetLightCasters: meshes is null");
    std::shared_ptr<const LightCasters> casters;
    if (meshCount > 0)
      casters = std::make_shared<const LightCasters>(*lights->artifact,
                                                     casterMeshesOf(meshes, meshCount, "cpvsSetLightCasters"), normalOffset);
    onDeviceOrCpu(lights, [&] { lights->gpu->setDynamicCasters(casters); }, [] {});
    lights->casterTrees = casters ? casters->headerBytes() : std::vector<uint8_t>{};
    lights->casterNodes = casters ? casters->nodeBytes() : std::vector<uint8_t>{};
    lights->casters = std::move(casters);
  });
}

CpvsStatus cpvsGetLightBuffer(CpvsLights lights, CpvsLightBuffer which, const void** data, size_t* bytes) {
  return guarded([&] {
    require(lights != nullptr && data != nullptr && bytes != nullptr, "cpvsGetLightBuffer: an argument is null");
    const std::vector<uint32_t>& words = *lights->artifact->bundle().pool;
    switch (which) {
      case CPVS_LIGHT_BUFFER_WORDS: *data = words.data(), *bytes = words.size() * 4; return;
      case CPVS_LIGHT_BUFFER_LIGHTS: *data = lights->lights.data(), *bytes = lights->lights.size(); return;
      case CPVS_LIGHT_BUFFER_GRIDS: *data = lights->grids.data(), *bytes = lights->grids.size(); return;
      case CPVS_LIGHT_BUFFER_BOUNDARIES: *data = lights->boundaries.data(), *bytes = lights->boundaries.size(); return;
      case CPVS_LIGHT_BUFFER_CASTER_TREES: *data = lights->casterTrees.data(), *bytes = lights->casterTrees.size(); return;
      case CPVS_LIGHT_BUFFER_CASTER_NODES: *data = lights->casterNodes.data(), *bytes = lights->casterNodes.size(); return;
    }
    require(false, "cpvsGetLightBuffer: no such buffer");
  });
}

const char* cpvsGetLastError(void) { return lastError.c_str(); }

const char* cpvsGetStatusName(CpvsStatus status) { return statusName(Status(int(status))); }

}  // extern "C"
