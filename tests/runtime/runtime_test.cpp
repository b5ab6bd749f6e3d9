// The runtime's GPU lookups against the CPU reference, on lavapipe in CI: bit-exact
// binary answers and identical PCF lit counts for surface points, points on leaf, tile
// and pointer-grid boundaries, outside the grid, in front of and behind it; the words
// split across several bindings; and every error through the C++ and the C API. The
// validation layer is on for every device made here and must report nothing.
#include <gtest/gtest.h>

#include <dlfcn.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <bit>
#include <random>

#include "cpvs/bake/bake.h"
#include "cpvs/eval/surface_sampling.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/runtime/cpvs_runtime.h"
#include "cpvs/runtime/runtime.h"
#define VK_NO_PROTOTYPES
#include <vulkan/vulkan.h>
#include "cpvs/scene/source.h"
#include "scene_testing.h"

namespace cpvs::runtime {
namespace {

DeviceOptions validated() {
  DeviceOptions o;
  o.validation = true;
  return o;
}

// One device for the suite (creating one with the validation layer takes a while).
GpuDevice& device() {
  static std::unique_ptr<GpuDevice> d = GpuDevice::create(validated());
  return *d;
}

void expectNoValidationMessages(const GpuDevice& d) {
  const auto messages = d.validationMessages();
  EXPECT_TRUE(messages.empty()) << messages.size() << " validation messages, the first: " << messages.front();
}

struct Baked {
  std::shared_ptr<const ShadowArtifact> artifact;
  Scene scene;
  Vec3 sun;
  std::string file;
};

Baked bake(const std::string& spec, const Vec3& sun, int log2R) {
  Baked b{nullptr, openScene(spec), sun, ::testing::TempDir() + "runtime-" + std::to_string(log2R) + ".cpvs"};
  CpvsArtifact art;
  art.grid = makeGrid(b.scene, LightFrame::fromDirection(sun), log2R);
  art.dag = testing::bakeWith(b.scene, art.grid, art.options);
  art.sceneHash = sceneHash(b.scene);
  writeCpvs(b.file, art, true);
  b.artifact = ShadowArtifact::open(b.file);  // the file's words, as a game gets them
  return b;
}

// Queries that reach every corner of the lookup: surface points with their normals;
// points exactly on (and a hair either side of) leaf, tile and pointer-grid boundaries
// with no normal, so that the voxel found is decided in the last bit; points outside the
// grid in x and y, in front of and behind it, with random, zero and degenerate normals.
// Returns how many of them, first, are surface points.
size_t makeQueries(const Baked& b, uint64_t count, std::vector<Vec3>& points, std::vector<Vec3>& normals) {
  const OrthoGrid& g = b.artifact->grid();
  const double R = double(g.resolution());
  std::mt19937_64 rng(uint64_t(g.log2Resolution) * 7919);
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> gauss;
  const RayScene rays(b.scene, g.origin);
  for (const SurfaceSample& s : sampleSurfaces(b.scene, rays, ClosedMode::Auto, g.frame.dir, count / 2, 3)) {
    points.push_back(s.point);
    normals.push_back(s.normal);
  }
  const size_t surfacePoints = points.size();
  const double cell = R / double(1 << packedGridLevels(g.log2Resolution));
  const double tile = std::min(R, 4096.0);
  const double steps[] = {8, tile, cell};
  const double hairs[] = {0, 1e-9, -1e-9, 0.5};
  while (points.size() < count * 4 / 5) {
    Vec3 v{unit(rng) * R, unit(rng) * R, unit(rng) * R};
    const double step = steps[rng() % 3];
    double* axis[] = {&v.x, &v.y, &v.z};
    for (double* a : axis)
      if (rng() % 2) *a = std::floor(*a / step) * step + hairs[rng() % 4];
    points.push_back(g.worldFromVoxel(v));
    normals.push_back({});
  }
  while (points.size() < count) {
    Vec3 v{unit(rng) * R, unit(rng) * R, unit(rng) * R};
    switch (rng() % 4) {
      case 0: v.x = rng() % 2 ? -unit(rng) * 0.2 * R : R + unit(rng) * 0.2 * R; break;
      case 1: v.y = rng() % 2 ? -unit(rng) * 0.2 * R : R + unit(rng) * 0.2 * R; break;
      case 2: v.z = -unit(rng) * 0.3 * R - 1e-9; break;
      default: v.z = R + unit(rng) * 0.3 * R; break;
    }
    points.push_back(g.worldFromVoxel(v));
    const uint64_t kind = rng() % 8;
    normals.push_back(kind == 0   ? Vec3{}
                      : kind == 1 ? Vec3{std::nan(""), 0, 1}
                      : kind == 2 ? Vec3{1e-310, 0, 0}
                                  : Vec3{gauss(rng), gauss(rng), gauss(rng)});
  }
  return surfacePoints;
}

uint64_t mismatches(const std::vector<uint32_t>& a, const std::vector<uint32_t>& b) {
  uint64_t n = a.size() == b.size() ? 0 : std::max(a.size(), b.size());
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) n += a[i] != b[i];
  return n;
}

void expectGpuMatchesCpu(const Baked& b, GpuShadows& gpu, uint64_t count) {
  std::vector<Vec3> points, normals;
  const size_t surfacePoints = makeQueries(b, count, points, normals);
  ASSERT_GE(points.size(), count);
  for (int pcf : {1, 3, 5, 7, 9}) {
    // Every point for binary and 9x9 lookups; for the widths between, every boundary,
    // outside and bad-normal point and a fifth of the surface points.
    std::vector<Vec3> p = points, n = normals;
    if (pcf != 1 && pcf != 9) {
      p.clear();
      n.clear();
      for (size_t i = 0; i < points.size(); ++i)
        if (i >= surfacePoints || i % 5 == 0) {
          p.push_back(points[i]);
          n.push_back(normals[i]);
        }
    }
    std::vector<uint32_t> onGpu, onCpu;
    gpu.litTexels(p, n, pcf, onGpu);
    EXPECT_GT(gpu.lastDeviceNanoseconds(), 0) << "the device ran the lookups";
    cpuLitTexels(*b.artifact, p, n, pcf, onCpu);
    EXPECT_EQ(mismatches(onGpu, onCpu), 0u) << "pcf " << pcf << ", " << p.size() << " queries";
    uint64_t lit = 0, shadowed = 0;
    for (uint32_t v : onCpu) (v == 0 ? shadowed : lit) += 1;
    EXPECT_GT(shadowed, p.size() / 50) << "pcf " << pcf << ": the queries must see shadow";
    EXPECT_GT(lit, p.size() / 50) << "pcf " << pcf << ": and light";
  }
}

TEST(GpuLookups, ClosedCityAt16KAnswersAsTheCpu) {
  const Baked b = bake("city", {0.4, -1, 0.25}, 14);
  GpuShadows gpu(device(), b.artifact);
  EXPECT_EQ(gpu.wordBindings(), 1);
  expectGpuMatchesCpu(b, gpu, 200000);
  expectNoValidationMessages(device());
}

TEST(GpuLookups, OpenBunnyAnswersAsTheCpu) {
  CPVS_SHARED_SCENE_OR_SKIP(path, "stanford-bunny/bunny.obj");
  const Baked b = bake(path, {0.3, -0.8, -0.5}, 11);
  GpuShadows gpu(device(), b.artifact);
  expectGpuMatchesCpu(b, gpu, 200000);
  expectNoValidationMessages(device());
}

TEST(GpuLookups, QuakeLevelAnswersAsTheCpu) {
  CPVS_SHARED_SCENE_OR_SKIP(path, "openarena/oa_shouse.obj");
  const Baked b = bake(path, {0.4, -1, 0.3}, 12);
  GpuShadows gpu(device(), b.artifact);
  expectGpuMatchesCpu(b, gpu, 200000);
  expectNoValidationMessages(device());
}

TEST(GpuLookups, PeersCityAnswersAsTheCpu) {
  CPVS_SHARED_SCENE_OR_SKIP(path, "loinesg-city/city.obj");
  const Baked b = bake(path, {-0.5, -1, 0.2}, 13);
  GpuShadows gpu(device(), b.artifact);
  expectGpuMatchesCpu(b, gpu, 200000);
  expectNoValidationMessages(device());
}

// A binding limit far below the device's forces the words across several storage
// bindings; the answers stay the same.
TEST(GpuLookups, WordsSplitAcrossBindingsAnswerTheSame) {
  const Baked b = bake("city:6:3", {0.2, -1, -0.4}, 12);
  const uint64_t bytes = b.artifact->packed().arrayBytes();
  DeviceOptions options = validated();
  options.maxBindingBytes = std::bit_floor(bytes / 4);  // 4 to 8 bindings of a power of two
  auto small = GpuDevice::create(options);
  GpuShadows gpu(*small, b.artifact);
  EXPECT_GE(gpu.wordBindings(), 4);
  EXPECT_LE(gpu.wordBindings(), 8);
  expectGpuMatchesCpu(b, gpu, 50000);
  expectNoValidationMessages(*small);
  options.maxBindingBytes = bytes / 12;  // more than 8 bindings: a clear refusal
  auto tiny = GpuDevice::create(options);
  try {
    GpuShadows refused(*tiny, b.artifact);
    ADD_FAILURE() << "accepted " << bytes << " bytes in bindings of " << options.maxBindingBytes;
  } catch (const RuntimeError& e) {
    EXPECT_EQ(e.status(), Status::OutOfMemory);
    EXPECT_NE(std::string(e.what()).find("storage bindings"), std::string::npos) << e.what();
  }
}

TEST(GpuLookups, DevicePicksAndRefusals) {
  EXPECT_FALSE(device().name().empty());
  EXPECT_GE(device().maxStorageBufferRange(), 1u << 20);
  DeviceOptions missing = validated();
  missing.select = "no device has this name";
  try {
    GpuDevice::create(missing);
    ADD_FAILURE() << "a device was found";
  } catch (const RuntimeError& e) {
    EXPECT_EQ(e.status(), Status::NoDevice);
    EXPECT_NE(std::string(e.what()).find("matching \"no device has this name\""), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(device().name()), std::string::npos) << "lists what it found: " << e.what();
  }
  // The environment picks a device the same way.
  setenv("CPVS_DEVICE", "no device has this name", 1);
  EXPECT_THROW(GpuDevice::create(), RuntimeError);
  CpvsDevice none = nullptr;
  EXPECT_EQ(cpvsNewDevice(nullptr, &none), CPVS_ERROR_NO_DEVICE);
  EXPECT_NE(std::string(cpvsGetLastError()).find("no usable Vulkan device"), std::string::npos) << cpvsGetLastError();
  unsetenv("CPVS_DEVICE");
  DeviceOptions noLoader;
  noLoader.loader = "/nonexistent/libvulkan.so.1";
  try {
    GpuDevice::create(noLoader);
    ADD_FAILURE() << "a loader was found";
  } catch (const RuntimeError& e) {
    EXPECT_EQ(e.status(), Status::NoVulkan);
    EXPECT_NE(std::string(e.what()).find("no Vulkan loader"), std::string::npos) << e.what();
  }
  // The front falls back to the CPU when asked to (Auto), and fails when not (Gpu).
  const Baked b = bake("city:3", {0.3, -1, 0.2}, 9);
  ShadowLookups automatic(b.artifact, Backend::Auto, noLoader);
  EXPECT_FALSE(automatic.onGpu());
  EXPECT_NE(automatic.fallbackReason().find("no Vulkan loader"), std::string::npos);
  std::vector<uint32_t> lit;
  automatic.litTexels({b.artifact->grid().origin}, {}, 3, lit);
  ASSERT_EQ(lit.size(), 1u);
  EXPECT_THROW(ShadowLookups(b.artifact, Backend::Gpu, noLoader), RuntimeError);
  ShadowLookups cpu(b.artifact, Backend::Cpu);
  EXPECT_FALSE(cpu.onGpu());
  EXPECT_TRUE(cpu.fallbackReason().empty());
}

// The application's own device: made here as an engine makes it (through the loader,
// with shaderFloat64 on), handed to the runtime, which answers as the CPU does and leaves
// the device to its owner.
TEST(GpuLookups, TheApplicationsOwnDeviceAnswersAsTheCpu) {
  void* loader = dlopen("libvulkan.so.1", RTLD_NOW | RTLD_LOCAL);
  ASSERT_NE(loader, nullptr);
  auto getInstance = reinterpret_cast<PFN_vkGetInstanceProcAddr>(dlsym(loader, "vkGetInstanceProcAddr"));
  auto createInstance = reinterpret_cast<PFN_vkCreateInstance>(getInstance(nullptr, "vkCreateInstance"));
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO, nullptr, "engine", 1, "engine", 1, VK_API_VERSION_1_1};
  VkInstanceCreateInfo info{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO, nullptr, 0, &app, 0, nullptr, 0, nullptr};
  VkInstance instance = VK_NULL_HANDLE;
  ASSERT_EQ(createInstance(&info, nullptr, &instance), VK_SUCCESS);
  auto enumerate = reinterpret_cast<PFN_vkEnumeratePhysicalDevices>(getInstance(instance, "vkEnumeratePhysicalDevices"));
  auto createDevice = reinterpret_cast<PFN_vkCreateDevice>(getInstance(instance, "vkCreateDevice"));
  auto destroyInstance = reinterpret_cast<PFN_vkDestroyInstance>(getInstance(instance, "vkDestroyInstance"));
  auto getDevice = reinterpret_cast<PFN_vkGetDeviceProcAddr>(getInstance(instance, "vkGetDeviceProcAddr"));
  uint32_t count = 1;
  VkPhysicalDevice physical = VK_NULL_HANDLE;
  ASSERT_NE(enumerate(instance, &count, &physical), VK_ERROR_INITIALIZATION_FAILED);
  ASSERT_EQ(count, 1u);
  const float priority = 1;
  VkDeviceQueueCreateInfo queue{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO, nullptr, 0, 0, 1, &priority};
  VkPhysicalDeviceFeatures features{};
  features.shaderFloat64 = VK_TRUE;
  VkDeviceCreateInfo deviceInfo{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO, nullptr, 0, 1, &queue, 0, nullptr, 0, nullptr, &features};
  VkDevice vkDevice = VK_NULL_HANDLE;
  ASSERT_EQ(createDevice(physical, &deviceInfo, nullptr, &vkDevice), VK_SUCCESS);
  {
    const Baked b = bake("city:5", {0.3, -1, 0.2}, 11);
    std::vector<Vec3> points, normals;
    makeQueries(b, 20000, points, normals);
    GpuDevice::External e{instance, physical, vkDevice, 0, reinterpret_cast<void*>(getInstance)};
    auto adopted = GpuDevice::adopt(e);
    GpuShadows gpu(*adopted, b.artifact);
    std::vector<uint32_t> onGpu, onCpu;
    for (int pcf : {1, 3, 5, 7, 9}) {
      gpu.litTexels(points, normals, pcf, onGpu);
      cpuLitTexels(*b.artifact, points, normals, pcf, onCpu);
      EXPECT_EQ(mismatches(onGpu, onCpu), 0u) << "pcf " << pcf;
    }
    // The same device through the C API.
    CpvsDevice dev = nullptr;
    ASSERT_EQ(cpvsNewDeviceFromVulkan(instance, physical, vkDevice, 0, reinterpret_cast<void*>(getInstance), &dev), CPVS_OK)
        << cpvsGetLastError();
    CpvsShadows shadows = nullptr;
    ASSERT_EQ(cpvsOpenShadows(b.file.c_str(), dev, 0, &shadows), CPVS_OK) << cpvsGetLastError();
    EXPECT_EQ(cpvsShadowsOnDevice(shadows), 1);
    std::vector<double> p;
    for (const Vec3& v : points) p.insert(p.end(), {v.x, v.y, v.z});
    std::vector<uint32_t> viaC(points.size());
    ASSERT_EQ(cpvsQueryShadows(shadows, points.size(), p.data(), nullptr, 3, viaC.data()), CPVS_OK);
    cpuLitTexels(*b.artifact, points, {}, 3, onCpu);
    EXPECT_EQ(viaC, onCpu);
    cpvsReleaseShadows(shadows);
    cpvsReleaseDevice(dev);
    EXPECT_EQ(cpvsNewDeviceFromVulkan(nullptr, nullptr, nullptr, 0, nullptr, &dev), CPVS_ERROR_INVALID_ARGUMENT);
  }  // the runtime's objects go; the device stays the application's
  auto destroyDevice = reinterpret_cast<PFN_vkDestroyDevice>(getDevice(vkDevice, "vkDestroyDevice"));
  destroyDevice(vkDevice, nullptr);
  destroyInstance(instance, nullptr);
  GpuDevice::External none;
  EXPECT_THROW(GpuDevice::adopt(none), RuntimeError);
}

// A lost device: a clear DeviceLost from GpuShadows, and the front that allowed a
// fallback answers on the CPU from then on, with the same answers.
TEST(GpuLookups, DeviceLossIsAnErrorOrTheCpuAnswers) {
  const Baked b = bake("city:3", {0.3, -1, 0.2}, 9);
  std::vector<Vec3> points, normals;
  makeQueries(b, 2000, points, normals);
  std::vector<uint32_t> want, got;
  cpuLitTexels(*b.artifact, points, normals, 5, want);
  {
    auto d = GpuDevice::create(validated());
    GpuShadows gpu(*d, b.artifact);
    d->simulateDeviceLossForTests();
    try {
      gpu.litTexels(points, normals, 5, got);
      ADD_FAILURE() << "no error";
    } catch (const RuntimeError& e) {
      EXPECT_EQ(e.status(), Status::DeviceLost);
      EXPECT_NE(std::string(e.what()).find("was lost"), std::string::npos) << e.what();
    }
    EXPECT_THROW(gpu.litTexels(points, normals, 5, got), RuntimeError);  // and stays lost
  }
  ShadowLookups lookups(b.artifact, Backend::Auto, validated());
  ASSERT_TRUE(lookups.onGpu()) << lookups.fallbackReason();
  lookups.device()->simulateDeviceLossForTests();
  lookups.litTexels(points, normals, 5, got);
  EXPECT_FALSE(lookups.onGpu());
  EXPECT_NE(lookups.fallbackReason().find("was lost"), std::string::npos) << lookups.fallbackReason();
  EXPECT_EQ(got, want);
}

TEST(GpuLookups, CorruptAndMissingArtifactsAreClearErrors) {
  const Baked b = bake("city:3", {0.3, -1, 0.2}, 9);
  std::vector<uint8_t> bytes = readFile(b.file);
  const std::string truncated = ::testing::TempDir() + "truncated.cpvs";
  writeFileAtomic(truncated, std::vector<uint8_t>(bytes.begin(), bytes.begin() + bytes.size() / 2));
  try {
    ShadowArtifact::open(truncated);
    ADD_FAILURE();
  } catch (const RuntimeError& e) {
    EXPECT_EQ(e.status(), Status::CorruptArtifact);
    EXPECT_NE(std::string(e.what()).find("truncated.cpvs"), std::string::npos) << e.what();
  }
  try {
    ShadowArtifact::open(::testing::TempDir() + "absent.cpvs");
    ADD_FAILURE();
  } catch (const RuntimeError& e) {
    EXPECT_EQ(e.status(), Status::FileError);
  }
  // Through the C API: the same statuses, and a message.
  CpvsShadows shadows = nullptr;
  EXPECT_EQ(cpvsOpenShadows(truncated.c_str(), nullptr, 0, &shadows), CPVS_ERROR_CORRUPT_ARTIFACT);
  EXPECT_EQ(shadows, nullptr);
  EXPECT_NE(std::string(cpvsGetLastError()).find("truncated"), std::string::npos) << cpvsGetLastError();
  EXPECT_EQ(cpvsOpenShadows((::testing::TempDir() + "absent.cpvs").c_str(), nullptr, 0, &shadows), CPVS_ERROR_FILE);
  EXPECT_EQ(cpvsOpenShadows(nullptr, nullptr, 0, &shadows), CPVS_ERROR_INVALID_ARGUMENT);
  EXPECT_STREQ(cpvsGetStatusName(CPVS_ERROR_CORRUPT_ARTIFACT), "corrupt-artifact");
}

// The C API end to end: a validated device, an artifact on it, answers as the CPU's;
// no loader; a device lost with and without the CPU fallback.
TEST(CApi, QueriesAndErrors) {
  const Baked b = bake("city:4", {0.3, -1, 0.2}, 10);
  std::vector<Vec3> points, normals;
  makeQueries(b, 20000, points, normals);
  std::vector<double> p, n;
  for (size_t i = 0; i < points.size(); ++i) {
    p.insert(p.end(), {points[i].x, points[i].y, points[i].z});
    n.insert(n.end(), {normals[i].x, normals[i].y, normals[i].z});
  }
  std::vector<uint32_t> want;
  cpuLitTexels(*b.artifact, points, normals, 9, want);

  CpvsDeviceDesc desc{nullptr, 1, 0};
  CpvsDevice dev = nullptr;
  ASSERT_EQ(cpvsNewDevice(&desc, &dev), CPVS_OK) << cpvsGetLastError();
  EXPECT_GT(std::string(cpvsGetDeviceName(dev)).size(), 0u);
  CpvsShadows shadows = nullptr;
  ASSERT_EQ(cpvsOpenShadows(b.file.c_str(), dev, 0, &shadows), CPVS_OK) << cpvsGetLastError();
  EXPECT_EQ(cpvsShadowsOnDevice(shadows), 1);
  std::vector<uint32_t> got(points.size());
  ASSERT_EQ(cpvsQueryShadows(shadows, points.size(), p.data(), n.data(), 9, got.data()), CPVS_OK) << cpvsGetLastError();
  EXPECT_EQ(got, want);
  EXPECT_EQ(cpvsQueryShadows(shadows, points.size(), p.data(), n.data(), 4, got.data()), CPVS_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(cpvsGetLastError()).find("PCF width 4"), std::string::npos) << cpvsGetLastError();
  EXPECT_EQ(cpvsGetValidationMessageCount(dev), 0u);

  // A CPU-only handle answers the same.
  CpvsShadows onCpu = nullptr;
  ASSERT_EQ(cpvsOpenShadows(b.file.c_str(), nullptr, 0, &onCpu), CPVS_OK);
  EXPECT_EQ(cpvsShadowsOnDevice(onCpu), 0);
  std::fill(got.begin(), got.end(), 0);
  ASSERT_EQ(cpvsQueryShadows(onCpu, points.size(), p.data(), n.data(), 9, got.data()), CPVS_OK);
  EXPECT_EQ(got, want);
  cpvsReleaseShadows(onCpu);

  // Lost: an error without the fallback flag; with it, the CPU answers.
  CpvsShadows withFallback = nullptr;
  ASSERT_EQ(cpvsOpenShadows(b.file.c_str(), dev, CPVS_FALLBACK_CPU, &withFallback), CPVS_OK);
  cpvsSimulateDeviceLossForTests(dev);
  EXPECT_EQ(cpvsQueryShadows(shadows, points.size(), p.data(), n.data(), 9, got.data()), CPVS_ERROR_DEVICE_LOST);
  EXPECT_NE(std::string(cpvsGetLastError()).find("was lost"), std::string::npos);
  std::fill(got.begin(), got.end(), 0);
  EXPECT_EQ(cpvsQueryShadows(withFallback, points.size(), p.data(), n.data(), 9, got.data()), CPVS_OK);
  EXPECT_EQ(cpvsShadowsOnDevice(withFallback), 0);
  EXPECT_EQ(got, want);
  cpvsReleaseShadows(withFallback);
  cpvsReleaseShadows(shadows);
  cpvsReleaseDevice(dev);

  // No loader: a clear status; the CPU path is still there.
  setenv("CPVS_VULKAN_LOADER", "/nonexistent/libvulkan.so.1", 1);
  EXPECT_EQ(cpvsNewDevice(nullptr, &dev), CPVS_ERROR_NO_VULKAN);
  EXPECT_EQ(dev, nullptr);
  EXPECT_NE(std::string(cpvsGetLastError()).find("no Vulkan loader"), std::string::npos);
  unsetenv("CPVS_VULKAN_LOADER");
}

}  // namespace
}  // namespace cpvs::runtime
