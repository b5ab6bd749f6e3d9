// The runtime's GPU lookups against the CPU reference, on lavapipe in CI: bit-exact
// binary answers and identical PCF lit counts for surface points, points on leaf, tile
// and pointer-grid boundaries, outside the grid, in front of and behind it; the words
// split across several bindings; and every error through the C++ and the C API. The
// validation layer is on for every device made here and must report nothing.
#include <gtest/gtest.h>

#include <dlfcn.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <bit>
#include <random>

#include "cpvs/bake/bake.h"
#include "cpvs/bake/bake_dag_mh.h"
#include "cpvs/bake/bake_lights.h"
#include "cpvs/dagmh/dag_mh_words.h"
#include "cpvs/io/dmh_file.h"
#include "cpvs/eval/surface_sampling.h"
#include "cpvs/light/area_light.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/light/gpu_grid.h"
#include "cpvs/raytrace/ray_scene.h"
#include "cpvs/runtime/cpvs_runtime.h"
#include "cpvs/runtime/runtime.h"
#define VK_NO_PROTOTYPES
#include <vulkan/vulkan.h>
#include "cpvs/scene/boxes.h"
#include "cpvs/scene/source.h"
#include "area_testing.h"
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

Baked bake(const std::string& spec, const Vec3& sun, int log2R, uint64_t depthSlices = 0) {
  Baked b{nullptr, openScene(spec), sun,
          ::testing::TempDir() + "runtime-" + std::to_string(log2R) + "-" + std::to_string(depthSlices) + ".cpvs"};
  CpvsArtifact art;
  art.grid = makeGrid(b.scene, LightFrame::fromDirection(sun), log2R, depthSlices);
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

// Segments through the sun's grid walked on the device: the lit fraction the CPU's to
// the bit (segments inside the grid, through it from outside, beside and behind it, along
// axes and through voxel corners), the in-scattered light the CPU's within float rounding.
void expectGpuSegmentsMatchCpu(const Baked& b, GpuShadows& gpu, int count) {
  const OrthoGrid& g = b.artifact->grid();
  const double R = double(g.resolution());
  std::mt19937_64 rng(uint64_t(g.log2Resolution) * 31);
  std::uniform_real_distribution<double> unit(-0.2, 1.2);
  std::vector<Vec3> from, to;
  for (int i = 0; i < count; ++i) {
    Vec3 a{unit(rng) * R, unit(rng) * R, unit(rng) * R}, e{unit(rng) * R, unit(rng) * R, unit(rng) * R};
    if (i % 6 == 1) e.y = a.y;                                  // in a plane
    if (i % 6 == 2) e.x = a.x, e.z = a.z;                       // along an axis
    if (i % 6 == 3) a = {std::floor(a.x), std::floor(a.y), std::floor(a.z)}, e = a + Vec3{16, 16, 16};  // corners
    if (i % 6 == 4) e = a;                                      // a point
    from.push_back(g.worldFromVoxel(a));
    to.push_back(g.worldFromVoxel(e));
  }
  const Medium medium{0.01, 0.004, 0.6};
  std::vector<double> litFraction;
  std::vector<float> inScattering;
  gpu.segments(from, to, medium, litFraction, inScattering);
  ASSERT_EQ(litFraction.size(), from.size());
  const ShadowQuery& q = b.artifact->cpu();
  uint64_t differ = 0, far = 0, partly = 0;
  for (size_t i = 0; i < from.size(); ++i) {
    const double want = q.litFraction(from[i], to[i]);
    differ += litFraction[i] != want;
    partly += want > 0.01 && want < 0.99;
    const double scattered = q.inScattering(from[i], to[i], medium).inScattering;
    far += std::abs(inScattering[i] - scattered) > 1e-4 * scattered + 1e-7;
  }
  EXPECT_EQ(differ, 0u) << from.size() << " segments";
  EXPECT_EQ(far, 0u) << "in-scattering beyond float rounding";
  EXPECT_GT(partly, from.size() / 10) << "the segments must cross shadows";
}

TEST(GpuSegments, SunShaftsAnswerAsTheCpu) {
  const Baked b = bake("city", {0.4, -1, 0.25}, 12);
  GpuShadows gpu(device(), b.artifact);
  expectGpuSegmentsMatchCpu(b, gpu, 20000);
  std::vector<double> lit;
  std::vector<float> scattered;
  try {
    gpu.segments({Vec3{}}, {}, Medium{}, lit, scattered);
    ADD_FAILURE() << "one start and no end accepted";
  } catch (const RuntimeError& e) {
    EXPECT_EQ(e.status(), Status::InvalidArgument);
  }
  try {
    gpu.segments({Vec3{}}, {Vec3{}}, Medium{0.1, 0, 1.5}, lit, scattered);
    ADD_FAILURE() << "g = 1.5 accepted";
  } catch (const RuntimeError& e) {
    EXPECT_EQ(e.status(), Status::InvalidArgument);
  }
  // The front on the CPU: ShadowQuery's answers, the in-scattering in float; on the device
  // the same lit fractions.
  const std::vector<Vec3> from{{10, 30, 10}, {200, 5, 40}}, to{{300, 2, 250}, {20, 60, 300}};
  const Medium fog{0.02, 0.005, 0.6};
  ShadowLookups cpu(b.artifact, Backend::Cpu), onDevice(b.artifact, device(), Backend::Gpu);
  cpu.segments(from, to, fog, lit, scattered);
  ASSERT_EQ(lit.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(lit[i], b.artifact->cpu().litFraction(from[i], to[i]));
    EXPECT_EQ(scattered[i], float(b.artifact->cpu().inScattering(from[i], to[i], fog).inScattering));
  }
  std::vector<double> litOnDevice;
  std::vector<float> scatteredOnDevice;
  onDevice.segments(from, to, fog, litOnDevice, scatteredOnDevice);
  EXPECT_EQ(litOnDevice, lit);
  EXPECT_THROW(cpu.segments({Vec3{}}, {}, fog, lit, scattered), RuntimeError);
  expectNoValidationMessages(device());
}

// 1,500 slivers of radius r stacked `rise` apart and each turned by the golden angle about
// one vertical axis: every one crosses the others' frusta (seed 003's unavoidable case).
CasterMesh sliverFan(double r, double rise) {
  CasterMesh fan;
  for (uint32_t i = 0; i < 1500; ++i) {
    const double a = 2.399963 * i, h = rise * i;
    const Vec3 d{std::cos(a), 0, std::sin(a)}, side{-std::sin(a), 0, std::cos(a)};
    fan.positions.insert(fan.positions.end(), {d * -r + Vec3{0, h, 0}, d * r + Vec3{0, h, 0}, side * 0.02 * r + Vec3{0, h, 0}});
    fan.indices.insert(fan.indices.end(), {3 * i, 3 * i + 1, 3 * i + 2});
  }
  return fan;
}

// A box (closed), a tilted open sheet and a sliver fan over the city, placed for frame
// `t` by rotating transforms: what moves in a game. The fan (slivers stacked and turned
// about one axis, each crossing the others' frusta) is seed 003's unavoidable case, deep
// enough to overflow the shader's stack somewhere when `fan` is set.
std::vector<CasterMesh> movingCasters(const Baked& b, double t, bool fan) {
  Vec3 lo, hi;
  sceneBounds(b.scene, lo, hi);
  const Vec3 size = hi - lo;
  auto turned = [&](double angle, const Vec3& at) {
    const double c = std::cos(angle), s = std::sin(angle);
    return std::array<double, 12>{c, 0, s, at.x, 0, 1, 0, at.y, -s, 0, c, at.z};
  };
  std::vector<CasterMesh> meshes;
  Scene box;
  appendBox(box, Vec3{-0.05 * size.x, 0, -0.03 * size.z}, Vec3{0.05 * size.x, 0.08 * size.y, 0.03 * size.z});
  finalizeScene(box);
  meshes.push_back({box.positions, box.indices, box.closed,
                    turned(0.7 * t, lo + Vec3{(0.3 + 0.1 * t) * size.x, 0.6 * size.y, 0.4 * size.z})});
  CasterMesh sheet;
  sheet.positions = {Vec3{0, 0, 0}, Vec3{0.2 * size.x, 0.05 * size.y, 0}, Vec3{0.2 * size.x, 0.1 * size.y, 0.15 * size.z},
                     Vec3{0, 0.05 * size.y, 0.15 * size.z}};
  sheet.indices = {0, 1, 2, 0, 2, 3};
  sheet.transform = turned(-0.4 * t, lo + Vec3{0.55 * size.x, 0.7 * size.y, (0.5 - 0.05 * t) * size.z});
  meshes.push_back(sheet);
  if (fan) {
    CasterMesh slivers = sliverFan(0.15 * std::min(size.x, size.z), 0.001 * size.y);
    slivers.transform = turned(t, lo + Vec3{0.5 * size.x, 0.75 * size.y, 0.5 * size.z});
    meshes.push_back(slivers);
  }
  return meshes;
}

// Queries for the casters: makeQueries' points, and points on the casters and in their
// shadows (below them along the sun), where the answers change.
void casterQueries(const Baked& b, const DynamicCasters& casters, const std::vector<CasterMesh>& meshes,
                   std::vector<Vec3>& points, std::vector<Vec3>& normals) {
  makeQueries(b, 30000, points, normals);
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> unit(0, 1);
  const Vec3 dir = b.artifact->grid().frame.dir;
  for (const CasterMesh& m : meshes)
    for (int i = 0; i < 4000; ++i) {
      const size_t t = rng() % (m.indices.size() / 3);
      Vec3 c[3];
      for (int k = 0; k < 3; ++k) c[k] = m.place(m.positions[m.indices[3 * t + k]]);
      const double u = unit(rng), v = unit(rng) * (1 - u);
      const Vec3 on = c[0] + (c[1] - c[0]) * u + (c[2] - c[0]) * v;
      Vec3 n = normalize(cross(c[1] - c[0], c[2] - c[0]));
      if (dot(n, dir) > 0) n = -n;
      points.push_back(on);
      normals.push_back(n);
      points.push_back(on + dir * (unit(rng) * 200 * casters.normalOffset()));
      normals.push_back(Vec3{0, 1, 0});
    }
}

// The meshes as the C API takes them (their positions as doubles kept in `xyz`).
std::vector<CpvsCasterMesh> cMeshesOf(const std::vector<CasterMesh>& meshes, std::vector<std::vector<double>>& xyz) {
  std::vector<CpvsCasterMesh> c(meshes.size());
  xyz.assign(meshes.size(), {});
  for (size_t k = 0; k < meshes.size(); ++k) {
    for (const Vec3& v : meshes[k].positions) xyz[k].insert(xyz[k].end(), {v.x, v.y, v.z});
    c[k] = CpvsCasterMesh{xyz[k].data(), meshes[k].positions.size(), meshes[k].indices.data(), meshes[k].indices.size() / 3,
                          meshes[k].closed.empty() ? nullptr : meshes[k].closed.data(), {}};
    std::copy(meshes[k].transform.begin(), meshes[k].transform.end(), c[k].transform);
  }
  return c;
}

// An artifact's translucent casters: the CPU's transmittance is the tree's at the point
// moved one texel along its normal; the device's (cpvs_translucent_query.comp) is the
// CPU's to the bit, deep walks answered by the CPU; an artifact without glass lets all
// light through.
TEST(GpuTranslucent, TransmittanceAnswersAsTheCpu) {
  const Scene scene = testing::glassCity();
  CpvsArtifact art = testing::localArtifact(scene, makeGrid(scene, LightFrame::fromDirection({0.3, -1, 0.2}), 9), {});
  ASSERT_TRUE(art.translucent);
  const auto artifact = ShadowArtifact::fromBytes(encodeCpvs(art, true), "glass.cpvs");
  ASSERT_NE(artifact->translucent(), nullptr);
  std::vector<Vec3> points, normals;
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < 20000; ++i) {
    points.push_back({lo.x + (hi.x - lo.x) * u(rng), lo.y + (hi.y - lo.y) * u(rng), lo.z + (hi.z - lo.z) * u(rng)});
    normals.push_back(i % 2 ? Vec3{0, 1, 0} : normalize(Vec3{u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5}));
  }
  std::vector<std::array<float, 3>> onCpu, onGpu;
  cpuTransmittance(*artifact, points, normals, onCpu);
  const double d = artifact->grid().texelSize();
  size_t darkened = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    const Vec3 q{points[i].x + normals[i].x * d, points[i].y + normals[i].y * d, points[i].z + normals[i].z * d};
    ASSERT_EQ(onCpu[i], artifact->translucent()->transmittanceAt(q)) << i;
    darkened += onCpu[i][0] < 1;
  }
  EXPECT_GT(darkened, points.size() / 20) << "points under the glass";
  GpuShadows gpu(device(), artifact);
  gpu.transmittance(points, normals, onGpu);
  size_t differ = 0;
  for (size_t i = 0; i < points.size(); ++i) differ += std::memcmp(onGpu[i].data(), onCpu[i].data(), 12) != 0;
  EXPECT_EQ(differ, 0u) << gpu.lastTranslucentOverflows() << " answered by the CPU";
  expectNoValidationMessages(device());

  // The C API: the same answers on a device and on the CPU, and the buffers an engine binds.
  const std::string file = ::testing::TempDir() + "runtime-glass.cpvs";
  writeCpvs(file, art, true);
  CpvsDeviceDesc desc{};
  CpvsDevice dev = nullptr;
  ASSERT_EQ(cpvsNewDevice(&desc, &dev), CPVS_OK) << cpvsGetLastError();
  std::vector<double> p, n;
  for (size_t i = 0; i < points.size(); ++i) {
    p.insert(p.end(), {points[i].x, points[i].y, points[i].z});
    n.insert(n.end(), {normals[i].x, normals[i].y, normals[i].z});
  }
  for (CpvsDevice on : {dev, CpvsDevice(nullptr)}) {
    CpvsShadows h = nullptr;
    ASSERT_EQ(cpvsOpenShadows(file.c_str(), on, 0, &h), CPVS_OK) << cpvsGetLastError();
    EXPECT_EQ(cpvsShadowsHaveTranslucentCasters(h), 1);
    std::vector<float> rgb(3 * points.size());
    ASSERT_EQ(cpvsQueryTransmittance(h, points.size(), p.data(), n.data(), rgb.data()), CPVS_OK) << cpvsGetLastError();
    EXPECT_EQ(std::memcmp(rgb.data(), onCpu.data(), rgb.size() * 4), 0) << (on ? "device" : "CPU");
    const void* data = nullptr;
    size_t bytes = 0;
    ASSERT_EQ(cpvsGetShadowsBuffer(h, CPVS_SHADOWS_BUFFER_TRANSLUCENT, &data, &bytes), CPVS_OK);
    EXPECT_EQ(std::vector<uint8_t>(static_cast<const uint8_t*>(data), static_cast<const uint8_t*>(data) + bytes),
              artifact->translucentGpuBytes());
    ASSERT_EQ(cpvsGetShadowsBuffer(h, CPVS_SHADOWS_BUFFER_TRANSMITTANCE, &data, &bytes), CPVS_OK);
    EXPECT_EQ(bytes, 12 * artifact->translucent()->frustumCount());
    cpvsReleaseShadows(h);
  }
  cpvsReleaseDevice(dev);

  const auto opaque = ShadowArtifact::fromBytes(encodeCpvs(testing::localArtifact(opaquePart(scene), art.grid, {}), true), "o.cpvs");
  EXPECT_EQ(opaque->translucent(), nullptr);
  GpuShadows plain(device(), opaque);
  plain.transmittance(points, normals, onGpu);
  for (const auto& t : onGpu) ASSERT_EQ(t, (std::array<float, 3>{1, 1, 1}));
}

TEST(GpuDynamicCasters, MovingCastersAnswerAsTheCpu) {
  const Baked b = bake("city:4", {0.4, -1, 0.25}, 11);
  GpuShadows gpu(device(), b.artifact);
  uint64_t overflows = 0;
  for (double t : {0.0, 1.0, 2.5}) {
    const bool fan = t == 2.5;
    const std::vector<CasterMesh> meshes = movingCasters(b, t, fan);
    auto casters = std::make_shared<const DynamicCasters>(*b.artifact, meshes);
    EXPECT_EQ(casters->normalOffset(), b.artifact->grid().texelSize());
    EXPECT_GT(casters->tree().buildStats().culled, 0u) << "the box's faces towards the sun";
    std::vector<Vec3> points, normals;
    casterQueries(b, *casters, meshes, points, normals);
    // The casters' answer is the TOP tree's brute force at the offset point.
    uint64_t inShadow = 0;
    for (size_t i = 0; i < points.size(); ++i) {
      const Vec3 q = points[i] + normals[i] * casters->normalOffset();
      const bool shadowed = casters->shadowed(points[i], normals[i]);
      EXPECT_EQ(shadowed, casters->tree().inAnyFrustum(q)) << i;
      inShadow += shadowed;
    }
    EXPECT_GT(inShadow, points.size() / 20) << "frame " << t;
    gpu.setDynamicCasters(casters);
    for (int pcf : {1, 5}) {
      std::vector<uint32_t> onGpu, onCpu, baked;
      gpu.litTexels(points, normals, pcf, onGpu);
      overflows += gpu.lastCasterOverflows();
      cpuLitTexels(*b.artifact, points, normals, pcf, onCpu, casters.get());
      cpuLitTexels(*b.artifact, points, normals, pcf, baked);
      EXPECT_EQ(mismatches(onGpu, onCpu), 0u) << "frame " << t << ", pcf " << pcf;
      uint64_t changed = 0;
      for (size_t i = 0; i < points.size(); ++i) changed += onCpu[i] != baked[i];
      EXPECT_GT(changed, points.size() / 50) << "the casters must darken some of the baked light";
    }
    if (fan) {
      EXPECT_GT(overflows, 0u) << "the fan's deep walks must overflow the shader's stack somewhere";
    }
    // The tree inserted on the device instead (its shape the device's order, its frusta
    // the same): the same answers, and the CPU's own tree made when first asked.
    auto inserted = std::make_shared<const DynamicCasters>(*b.artifact, meshes, -1, DynamicCasters::Build::Device);
    EXPECT_FALSE(inserted->tree().linked());
    EXPECT_EQ(inserted->tree().frustumCount(), casters->tree().frustumCount());
    gpu.setDynamicCasters(inserted);
    EXPECT_GT(gpu.lastCasterBuildSteps(), inserted->tree().frustumCount()) << "every frustum walked down";
    EXPECT_GT(gpu.lastCasterBuildNanoseconds(), 0);
    std::vector<uint32_t> onGpu, onCpu, fromItsOwn;
    gpu.litTexels(points, normals, 1, onGpu);
    cpuLitTexels(*b.artifact, points, normals, 1, onCpu, casters.get());
    cpuLitTexels(*b.artifact, points, normals, 1, fromItsOwn, inserted.get());
    EXPECT_EQ(mismatches(onGpu, onCpu), 0u) << "frame " << t << ", the tree built on the device";
    EXPECT_EQ(mismatches(fromItsOwn, onCpu), 0u);
  }
  // No casters: the plain lookups again.
  gpu.setDynamicCasters(nullptr);
  std::vector<Vec3> points, normals;
  makeQueries(b, 5000, points, normals);
  std::vector<uint32_t> onGpu, onCpu;
  gpu.litTexels(points, normals, 3, onGpu);
  cpuLitTexels(*b.artifact, points, normals, 3, onCpu);
  EXPECT_EQ(onGpu, onCpu);
  // Bad meshes are refused.
  std::vector<CasterMesh> bad = movingCasters(b, 0, false);
  bad[1].indices.back() = 4;
  EXPECT_THROW(DynamicCasters(*b.artifact, bad), RuntimeError);
  bad = movingCasters(b, 0, false);
  bad[0].transform[5] = std::nan("");
  EXPECT_THROW(DynamicCasters(*b.artifact, bad), RuntimeError);
  bad = movingCasters(b, 0, false);
  bad[0].closed.pop_back();
  EXPECT_THROW(DynamicCasters(*b.artifact, bad), RuntimeError);
  expectNoValidationMessages(device());

  // The C API: casters set on a device handle and a CPU one answer alike, and the buffer an
  // engine binds is gpuBytes().
  const std::vector<CasterMesh> meshes = movingCasters(b, 1.0, false);
  std::vector<std::vector<double>> positions;
  std::vector<CpvsCasterMesh> c = cMeshesOf(meshes, positions);
  CpvsDeviceDesc desc{nullptr, 1, 0};
  CpvsDevice dev = nullptr;
  ASSERT_EQ(cpvsNewDevice(&desc, &dev), CPVS_OK) << cpvsGetLastError();
  CpvsShadows onDevice = nullptr, onCpuHandle = nullptr;
  ASSERT_EQ(cpvsOpenShadows(b.file.c_str(), dev, 0, &onDevice), CPVS_OK) << cpvsGetLastError();
  ASSERT_EQ(cpvsOpenShadows(b.file.c_str(), nullptr, 0, &onCpuHandle), CPVS_OK) << cpvsGetLastError();
  const DynamicCasters reference(*b.artifact, meshes);
  casterQueries(b, reference, meshes, points, normals);
  std::vector<double> p, n;
  for (size_t i = 0; i < points.size(); ++i) {
    p.insert(p.end(), {points[i].x, points[i].y, points[i].z});
    n.insert(n.end(), {normals[i].x, normals[i].y, normals[i].z});
  }
  std::vector<uint32_t> want, fromDevice(points.size()), fromCpu(points.size());
  cpuLitTexels(*b.artifact, points, normals, 3, want, &reference);
  for (CpvsShadows h : {onDevice, onCpuHandle}) {
    ASSERT_EQ(cpvsSetDynamicCasters(h, c.data(), c.size(), -1), CPVS_OK) << cpvsGetLastError();
    ASSERT_EQ(cpvsQueryShadows(h, points.size(), p.data(), n.data(), 3, (h == onDevice ? fromDevice : fromCpu).data()),
              CPVS_OK);
  }
  EXPECT_EQ(fromDevice, want);
  EXPECT_EQ(fromCpu, want);
  const void* data = nullptr;
  size_t bytes = 0;
  ASSERT_EQ(cpvsGetShadowsBuffer(onDevice, CPVS_SHADOWS_BUFFER_CASTERS, &data, &bytes), CPVS_OK);
  const std::vector<uint8_t> expected = reference.gpuBytes();
  ASSERT_EQ(bytes, expected.size());
  EXPECT_EQ(std::memcmp(data, expected.data(), bytes), 0);
  c[0].indices = nullptr;
  EXPECT_EQ(cpvsSetDynamicCasters(onDevice, c.data(), c.size(), -1), CPVS_ERROR_INVALID_ARGUMENT);
  ASSERT_EQ(cpvsSetDynamicCasters(onDevice, nullptr, 0, -1), CPVS_OK);
  ASSERT_EQ(cpvsGetShadowsBuffer(onDevice, CPVS_SHADOWS_BUFFER_CASTERS, &data, &bytes), CPVS_OK);
  EXPECT_EQ(bytes, 0u);
  cpvsReleaseShadows(onDevice);
  cpvsReleaseShadows(onCpuHandle);
  EXPECT_EQ(cpvsGetValidationMessageCount(dev), 0u);
  cpvsReleaseDevice(dev);
}

TEST(GpuLookups, ClosedCityAt16KAnswersAsTheCpu) {
  const Baked b = bake("city", {0.4, -1, 0.25}, 14);
  GpuShadows gpu(device(), b.artifact);
  EXPECT_EQ(gpu.wordBindings(), 1);
  expectGpuMatchesCpu(b, gpu, 200000);
  expectNoValidationMessages(device());
}

// Slices 4 texels deep: the device offsets across in units of 4 texels as the CPU does.
TEST(GpuLookups, FewerDepthSlicesAnswerAsTheCpu) {
  const Baked b = bake("city", {0.5, -0.4, 0.3}, 12, 1024);
  ASSERT_EQ(b.artifact->grid().depthShift(), 2);
  GpuShadows gpu(device(), b.artifact);
  expectGpuMatchesCpu(b, gpu, 100000);
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
  // Its levels name their children by 16 bits and by 32 (levels 1-4), at even and odd half-words.
  const PackedHeader& h = b.artifact->packed().header();
  ASSERT_NE(h.wideRefs, 0u);
  ASSERT_NE(~h.wideRefs & ((1u << h.internalLevels) - 1), 0u);
  GpuShadows gpu(device(), b.artifact);
  expectGpuMatchesCpu(b, gpu, 200000);
  expectNoValidationMessages(device());
}

// An array of an older layout (a version 2 file, city:3:7 at 256, words of layout 1): it
// is packed again in today's layout, which the device walks as the CPU does.
TEST(GpuLookups, AnOlderLayoutAnswersAsTheCpu) {
  const Baked b{ShadowArtifact::open(CPVS_SOURCE_DIR "/tests/io/data/city-256-v2.cpvs"), openScene("city:3:7"), {}, ""};
  ASSERT_EQ(b.artifact->packed().header().layoutVersion, kPackedLayoutVersion);
  GpuShadows gpu(device(), b.artifact);
  expectGpuMatchesCpu(b, gpu, 20000);
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
  expectGpuSegmentsMatchCpu(b, gpu, 5000);
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

// A DAG-MH of the scene for `receivers`, written as a .dmh and opened as a game opens it.
Baked bakeDagMhFile(const std::string& spec, const Vec3& sun, int log2R, ReceiverKind receivers, int pcf) {
  Baked b{nullptr, openScene(spec), sun,
          ::testing::TempDir() + "runtime-dagmh-" + std::to_string(log2R) + "-" + optionName(receivers) + ".dmh"};
  DmhArtifact art;
  art.grid = makeGrid(b.scene, LightFrame::fromDirection(sun), log2R);
  art.options.receivers = receivers;
  art.options.receiverPcf = uint8_t(pcf);
  ReceiverDeclaration d;
  d.kind = receivers;
  d.maxPcf = pcf;
  art.receiverHash = receiverHash(d);
  art.sceneHash = sceneHash(b.scene);
  art.dag = bakeDagMh(b.scene, art.grid, art.options, d);
  writeDmh(b.file, art, true);
  b.artifact = ShadowArtifact::open(b.file);
  return b;
}

// Every texel's depth as the device decodes it lies where the CPU's does: for each texel,
// the voxel centres of the two slices around its depth (the last lit, the first
// shadowed) answer alike on both.
void expectEveryTexelAsTheCpu(const Baked& b, GpuShadows& gpu) {
  const OrthoGrid& g = b.artifact->grid();
  const DagMh& dag = b.artifact->dagMh().dag();
  const uint64_t R = g.resolution();
  std::vector<Vec3> points;
  for (uint64_t y = 0; y < R; ++y)
    for (uint64_t x = 0; x < R; ++x) {
      const float depth = dag.depth(x, y);
      const double first = std::min(std::ceil(double(depth)), double(R - 1));
      for (const double k : {first - 1, first})
        points.push_back(g.worldFromVoxel({double(x) + 0.5, double(y) + 0.5, std::max(k, 0.0) + 0.5}));
    }
  std::vector<uint32_t> onGpu, onCpu;
  gpu.litTexels(points, {}, 1, onGpu);
  cpuLitTexels(*b.artifact, points, {}, 1, onCpu);
  EXPECT_EQ(mismatches(onGpu, onCpu), 0u) << points.size() << " texel probes";
  uint64_t shadowed = 0;
  for (uint32_t v : onCpu) shadowed += v == 0;
  EXPECT_GT(shadowed, points.size() / 50);
  EXPECT_LT(shadowed, points.size() * 49 / 50);
}

// A DAG-MH (`--format dagmh`) on the device: the same lit counts as DagMhQuery for
// surface, boundary and outside queries at every filter width, every texel's depth
// decoded alike, receivers on surfaces (where it compresses most) and everywhere.
TEST(GpuDagMh, AnswersAsTheCpu) {
  const Baked surfaces = bakeDagMhFile("city:6", {0.3, -1, 0.2}, 11, ReceiverKind::Surfaces, 9);
  ASSERT_EQ(surfaces.artifact->kind(), ArtifactKind::DagMh);
  EXPECT_EQ(surfaces.artifact->words(), dagMhWords(surfaces.artifact->dagMh().dag()));
  EXPECT_GT(surfaces.artifact->dagMh().dag().skipLevel, 0);
  GpuShadows gpu(device(), surfaces.artifact);
  expectGpuMatchesCpu(surfaces, gpu, 100000);
  expectEveryTexelAsTheCpu(surfaces, gpu);
  const Baked everywhere = bakeDagMhFile("city:6", {0.3, -1, 0.2}, 10, ReceiverKind::Everywhere, 9);
  GpuShadows gpu2(device(), everywhere.artifact);
  expectGpuMatchesCpu(everywhere, gpu2, 50000);
  expectEveryTexelAsTheCpu(everywhere, gpu2);
  expectNoValidationMessages(device());
}

TEST(GpuDagMh, PeersCityAnswersAsTheCpu) {
  CPVS_SHARED_SCENE_OR_SKIP(path, "loinesg-city/city.obj");
  const Baked b = bakeDagMhFile(path, {0.505259, -0.379456, 0.775066}, 12, ReceiverKind::Surfaces, 9);
  GpuShadows gpu(device(), b.artifact);
  expectGpuMatchesCpu(b, gpu, 100000);
  expectEveryTexelAsTheCpu(b, gpu);
  expectNoValidationMessages(device());
}

// Split across bindings, with dynamic casters, through ShadowLookups and the C API; what
// a DAG-MH cannot answer (segments) is refused by name.
TEST(GpuDagMh, SplitWordsCastersTheCApiAndRefusals) {
  const Baked b = bakeDagMhFile("city:4", {0.4, -1, 0.25}, 11, ReceiverKind::Surfaces, 5);
  {
    DeviceOptions options = validated();
    options.maxBindingBytes = std::bit_floor(b.artifact->words().size() * 4 / 4);
    auto small = GpuDevice::create(options);
    GpuShadows gpu(*small, b.artifact);
    EXPECT_GE(gpu.wordBindings(), 4);
    expectGpuMatchesCpu(b, gpu, 30000);
    expectNoValidationMessages(*small);
  }
  GpuShadows gpu(device(), b.artifact);
  const std::vector<CasterMesh> meshes = movingCasters(b, 1.0, false);
  auto casters = std::make_shared<const DynamicCasters>(*b.artifact, meshes);
  std::vector<Vec3> points, normals;
  casterQueries(b, *casters, meshes, points, normals);
  gpu.setDynamicCasters(casters);
  std::vector<uint32_t> onGpu, onCpu, baked;
  gpu.litTexels(points, normals, 3, onGpu);
  cpuLitTexels(*b.artifact, points, normals, 3, onCpu, casters.get());
  cpuLitTexels(*b.artifact, points, normals, 3, baked);
  EXPECT_EQ(mismatches(onGpu, onCpu), 0u);
  EXPECT_NE(onCpu, baked) << "the casters darken some of the baked light";

  // What walks a CPVS's voxels is refused.
  const Medium fog{0.01, 0.004, 0.6};
  std::vector<double> lit;
  std::vector<float> scattered;
  for (Backend backend : {Backend::Cpu, Backend::Gpu}) {
    ShadowLookups lookups(b.artifact, device(), backend);
    try {
      lookups.segments({points[0]}, {points[1]}, fog, lit, scattered);
      ADD_FAILURE() << "segments on a DAG-MH";
    } catch (const RuntimeError& e) {
      EXPECT_EQ(e.status(), Status::InvalidArgument);
      EXPECT_NE(std::string(e.what()).find("DAG-MH"), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(b.artifact->cpu(), RuntimeError);

  // The C API opens it as any artifact, says its kind and gives its words.
  CpvsDeviceDesc desc{nullptr, 1, 0};
  CpvsDevice dev = nullptr;
  ASSERT_EQ(cpvsNewDevice(&desc, &dev), CPVS_OK) << cpvsGetLastError();
  CpvsShadows onDevice = nullptr, onCpuHandle = nullptr;
  ASSERT_EQ(cpvsOpenShadows(b.file.c_str(), dev, 0, &onDevice), CPVS_OK) << cpvsGetLastError();
  ASSERT_EQ(cpvsOpenShadows(b.file.c_str(), nullptr, 0, &onCpuHandle), CPVS_OK) << cpvsGetLastError();
  EXPECT_EQ(cpvsGetShadowsKind(onDevice), CPVS_SHADOWS_DAG_MH);
  EXPECT_EQ(cpvsShadowsOnDevice(onDevice), 1);
  std::vector<double> p, n;
  for (size_t i = 0; i < points.size(); ++i) {
    p.insert(p.end(), {points[i].x, points[i].y, points[i].z});
    n.insert(n.end(), {normals[i].x, normals[i].y, normals[i].z});
  }
  std::vector<uint32_t> fromDevice(points.size()), fromCpu(points.size());
  ASSERT_EQ(cpvsQueryShadows(onDevice, points.size(), p.data(), n.data(), 3, fromDevice.data()), CPVS_OK);
  ASSERT_EQ(cpvsQueryShadows(onCpuHandle, points.size(), p.data(), n.data(), 3, fromCpu.data()), CPVS_OK);
  EXPECT_EQ(fromDevice, baked);
  EXPECT_EQ(fromCpu, baked);
  const void* data = nullptr;
  size_t bytes = 0;
  ASSERT_EQ(cpvsGetShadowsBuffer(onDevice, CPVS_SHADOWS_BUFFER_WORDS, &data, &bytes), CPVS_OK);
  ASSERT_EQ(bytes, b.artifact->words().size() * 4);
  EXPECT_EQ(std::memcmp(data, b.artifact->words().data(), bytes), 0);
  EXPECT_EQ(reinterpret_cast<const uint32_t*>(data)[0], kDagMhWordsMagic);
  cpvsReleaseShadows(onDevice);
  cpvsReleaseShadows(onCpuHandle);
  EXPECT_EQ(cpvsGetValidationMessageCount(dev), 0u);
  cpvsReleaseDevice(dev);
  expectNoValidationMessages(device());
}

// Soft shadows on the device: a spot light, then two area lights (a panel over the city
// shining down, 16 VPLs; one on a wall shining sideways, 8 VPLs; their cubes rolled), the
// soft visibility of each at surface points under the panel and at random points with
// zero, NaN and random normals, answered as BundleQuery::softVisibility to the bit.
TEST(GpuLightLookups, SoftShadowsAnswerAsTheCpu) {
  const Scene scene = openScene("city:3:5");
  std::vector<Light> lights(1);
  lights[0].position = {30, 50, 30};
  lights[0].direction = {0.1, -1, 0.2};
  lights[0].coneDeg = 40;
  lights[0].log2Resolution = 6;
  AreaLight panel;
  panel.centre = {36, 66, 36};
  panel.edgeU = {12, 0, 0};
  panel.edgeV = {0, 0, 12};
  panel.vpls = 16;
  panel.log2Resolution = 6;
  AreaLight wall = panel;
  wall.centre = {-5, 20, 36};
  wall.edgeU = {0, 6, 0};
  wall.edgeV = {0, 0, 10};  // U x V = +x: into the city
  wall.vpls = 8;
  wall.seed = 3;
  for (const Light& l : vplsOf(panel, 1)) lights.push_back(l);
  for (const Light& l : vplsOf(wall, 2)) lights.push_back(l);
  const auto artifact = std::make_shared<const LightArtifact>(bakeLights(scene, lights, 0, BakeOptions{}, sceneHash(scene)));
  ASSERT_EQ(artifact->cpu().areaCount(), 2u);

  std::vector<uint32_t> areas;
  std::vector<Vec3> points, normals;
  const RayScene rays(scene, panel.centre);
  for (const SurfaceSample& s : testing::pointsUnderArea(scene, rays, panel, 30, 1500, 2)) {
    points.push_back(s.point);
    normals.push_back(s.normal);
    areas.push_back(points.size() % 3 == 0 ? 1 : 0);
  }
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> in(-10, 80);
  std::normal_distribution<double> gauss;
  for (int i = 0; i < 3000; ++i) {
    points.push_back({in(rng), in(rng) * 0.8, in(rng)});
    const uint64_t kind = rng() % 5;
    normals.push_back(kind == 0 ? Vec3{} : kind == 1 ? Vec3{std::nan(""), 0, 1} : Vec3{gauss(rng), gauss(rng), gauss(rng)});
    areas.push_back(uint32_t(rng() % 2));
  }
  GpuLights gpu(device(), artifact);
  std::vector<float> onGpu, onCpu;
  gpu.softVisibility(areas, points, normals, onGpu);
  EXPECT_GT(gpu.lastDeviceNanoseconds(), 0) << "the device ran the lookups";
  cpuSoftVisibility(*artifact, areas, points, normals, onCpu);
  ASSERT_EQ(onGpu.size(), points.size());
  uint64_t differ = 0, lit = 0, dark = 0, partly = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    if (std::bit_cast<uint32_t>(onGpu[i]) != std::bit_cast<uint32_t>(onCpu[i]) && ++differ <= 5)
      ADD_FAILURE() << "area " << areas[i] << " at " << points[i].x << ", " << points[i].y << ", " << points[i].z
                    << ": GPU " << onGpu[i] << ", CPU " << onCpu[i];
    (onCpu[i] == 0 ? dark : onCpu[i] == 1 ? lit : partly) += 1;
    EXPECT_EQ(onCpu[i], artifact->cpu().softVisibility(areas[i], points[i], normals[i]));
  }
  EXPECT_EQ(differ, 0u) << points.size() << " soft lookups";
  EXPECT_GT(lit, points.size() / 20) << "the queries must see light";
  EXPECT_GT(dark, points.size() / 20) << "and shadow";
  EXPECT_GT(partly, points.size() / 20) << "and penumbrae";
  // One area for every point, and refusals.
  std::vector<float> one;
  gpu.softVisibility({1}, points, normals, one);
  cpuSoftVisibility(*artifact, std::vector<uint32_t>(points.size(), 1), points, normals, onCpu);
  EXPECT_EQ(0, std::memcmp(one.data(), onCpu.data(), one.size() * sizeof(float)));
  EXPECT_THROW(gpu.softVisibility({2}, points, normals, one), RuntimeError);
  EXPECT_THROW(gpu.softVisibility({0, 1}, points, normals, one), RuntimeError);
  expectNoValidationMessages(device());

  // Through the C API, on a device and on the CPU: the area lights and the same answers.
  const std::string file = ::testing::TempDir() + "gpu-soft.cpvs";
  writeBundle(file, artifact->bundle(), true);
  CpvsDeviceDesc desc{nullptr, 1, 0};
  CpvsDevice cDevice = nullptr;
  ASSERT_EQ(cpvsNewDevice(&desc, &cDevice), CPVS_OK) << cpvsGetLastError();
  CpvsLights softOnDevice = nullptr, softOnCpu = nullptr;
  ASSERT_EQ(cpvsOpenLights(file.c_str(), cDevice, 0, &softOnDevice), CPVS_OK) << cpvsGetLastError();
  ASSERT_EQ(cpvsOpenLights(file.c_str(), nullptr, 0, &softOnCpu), CPVS_OK) << cpvsGetLastError();
  ASSERT_EQ(cpvsGetAreaLightCount(softOnDevice), 2u);
  uint32_t first = 0, count = 0;
  ASSERT_EQ(cpvsGetAreaLight(softOnDevice, 1, &first, &count), CPVS_OK);
  EXPECT_EQ(first, 17u);  // after the spot light and the panel's 16
  EXPECT_EQ(count, 8u);
  EXPECT_EQ(cpvsGetAreaLight(softOnDevice, 2, &first, &count), CPVS_ERROR_INVALID_ARGUMENT);
  std::vector<double> flat, flatNormals;
  for (size_t i = 0; i < points.size(); ++i) {
    flat.insert(flat.end(), {points[i].x, points[i].y, points[i].z});
    flatNormals.insert(flatNormals.end(), {normals[i].x, normals[i].y, normals[i].z});
  }
  std::vector<float> fromDevice(points.size()), fromCpu(points.size());
  ASSERT_EQ(cpvsQuerySoftShadows(softOnDevice, points.size(), areas.data(), areas.size(), flat.data(), flatNormals.data(),
                                 fromDevice.data()), CPVS_OK) << cpvsGetLastError();
  ASSERT_EQ(cpvsQuerySoftShadows(softOnCpu, points.size(), areas.data(), areas.size(), flat.data(), flatNormals.data(),
                                 fromCpu.data()), CPVS_OK) << cpvsGetLastError();
  cpuSoftVisibility(*artifact, areas, points, normals, onCpu);
  EXPECT_EQ(0, std::memcmp(fromDevice.data(), onCpu.data(), onCpu.size() * sizeof(float)));
  EXPECT_EQ(0, std::memcmp(fromCpu.data(), onCpu.data(), onCpu.size() * sizeof(float)));
  const uint32_t tooFar = 2;
  EXPECT_EQ(cpvsQuerySoftShadows(softOnDevice, 1, &tooFar, 1, flat.data(), nullptr, fromDevice.data()), CPVS_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(cpvsGetLastError()).find("area light 2 of a bundle of 2"), std::string::npos) << cpvsGetLastError();
  EXPECT_EQ(cpvsQuerySoftShadows(softOnDevice, 3, areas.data(), 2, flat.data(), nullptr, fromDevice.data()), CPVS_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(cpvsGetValidationMessageCount(cDevice), 0u);
  cpvsReleaseLights(softOnDevice);
  cpvsReleaseLights(softOnCpu);
  cpvsReleaseDevice(cDevice);
}

// Up to `count` surface points in grid k's cone (sampleSpotSurfaces), with its light.
void appendGridSurfaces(const Scene& scene, const RayScene& rays, const LightBundle& bundle, size_t k, uint64_t count,
                        std::vector<uint32_t>& which, std::vector<Vec3>& points, std::vector<Vec3>& normals) {
  const BundleGrid& g = bundle.grids[k];
  for (const SurfaceSample& s : sampleSpotSurfaces(scene, rays, ClosedMode::Auto, g.grid, g.tanCone, count, k + 1)) {
    which.push_back(g.light);
    points.push_back(s.point);
    normals.push_back(s.normal);
  }
}

// Two spots (one with a short range) and a point light over the city's centre c, whose
// extent is e.
std::vector<Light> threeLamps(const Vec3& c, const Vec3& e) {
  std::vector<Light> lights(3);
  lights[0].name = "wide";
  lights[0].position = c + Vec3{-0.15 * e.x, 0.4 * e.y, 0.1 * e.z};
  lights[0].direction = {0.2, -1, -0.35};
  lights[0].coneDeg = 55;
  lights[0].log2Resolution = 8;
  lights[1].name = "short";
  lights[1].position = c + Vec3{0.35 * e.x, -0.2 * e.y, -0.25 * e.z};
  lights[1].direction = {-1, -0.4, 0.5};
  lights[1].coneDeg = 20;
  lights[1].range = 0.45 * length(e);
  lights[1].log2Resolution = 7;
  lights[2].name = "bulb";
  lights[2].kind = LightKind::Point;
  lights[2].position = c + Vec3{-0.05 * e.x, 0.25 * e.y, -0.1 * e.z};
  lights[2].range = 0.5 * length(e);
  lights[2].log2Resolution = 7;
  return lights;
}

// Dynamic casters under a bundle's lights: a box and a sliver fan over the city, each
// light's tree of point-light frusta answering as the brute force, the device as the CPU
// (the fan's deep walks answered on the CPU), the lights out of the casters' reach with
// no tree.
TEST(GpuLightLookups, DynamicCastersShadowEachLight) {
  const Scene scene = openScene("city:3");
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  const Vec3 c = (lo + hi) * 0.5, e = hi - lo;
  std::vector<Light> lights = threeLamps(c, e);
  lights[1].name = "far away";  // beyond the casters' reach
  lights[1].position = c + Vec3{0.45 * e.x, -0.3 * e.y, -0.45 * e.z};
  lights[1].range = 0.15 * length(e);
  const auto artifact = std::make_shared<const LightArtifact>(bakeLights(scene, lights, 0, BakeOptions{}, sceneHash(scene)));
  const LightBundle& bundle = artifact->bundle();

  // A box under the wide light, and a fan of slivers crossing each other's frusta under the bulb.
  Scene box;
  appendBox(box, Vec3{-0.04 * e.x, 0, -0.04 * e.z}, Vec3{0.04 * e.x, 0.03 * e.y, 0.04 * e.z});
  finalizeScene(box);
  std::vector<CasterMesh> meshes{{box.positions, box.indices, box.closed, {}}};
  meshes[0].transform = {1, 0, 0, lights[0].position.x, 0, 1, 0, lights[0].position.y - 0.2 * e.y, 0, 0, 1,
                         lights[0].position.z};
  CasterMesh fan = sliverFan(0.05 * std::min(e.x, e.z), 0.0002 * e.y);
  fan.transform = {1, 0, 0, lights[2].position.x, 0, 1, 0, lights[2].position.y - 0.15 * e.y, 0, 0, 1, lights[2].position.z};
  meshes.push_back(fan);
  auto casters = std::make_shared<const LightCasters>(*artifact, meshes);
  EXPECT_NE(casters->tree(0), nullptr);
  EXPECT_EQ(casters->tree(1), nullptr) << "the casters are beyond its range";
  EXPECT_NE(casters->tree(2), nullptr);

  std::vector<uint32_t> which;
  std::vector<Vec3> points, normals;
  const RayScene rays(scene, c);
  for (size_t k = 0; k < bundle.grids.size(); ++k) appendGridSurfaces(scene, rays, bundle, k, 1500, which, points, normals);
  uint64_t inShadow = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    const TopTree* t = casters->tree(which[i]);
    const bool shadowed = casters->shadowed(which[i], points[i], normals[i]);
    EXPECT_EQ(shadowed, t && t->inAnyFrustum(points[i] + normals[i] * casters->normalOffset(which[i]))) << i;
    inShadow += shadowed;
  }
  EXPECT_GT(inShadow, points.size() / 50);
  GpuLights gpu(device(), artifact);
  gpu.setDynamicCasters(casters);
  for (int pcf : {1, 3}) {
    std::vector<uint32_t> onGpu, onCpu, baked;
    gpu.litTexels(which, points, normals, pcf, onGpu);
    cpuLightLitTexels(*artifact, which, points, normals, pcf, onCpu, casters.get());
    cpuLightLitTexels(*artifact, which, points, normals, pcf, baked);
    EXPECT_EQ(mismatches(onGpu, onCpu), 0u) << "pcf " << pcf;
    uint64_t changed = 0;
    for (size_t i = 0; i < points.size(); ++i) changed += onCpu[i] != baked[i];
    EXPECT_GT(changed, points.size() / 100) << "pcf " << pcf;
  }
  EXPECT_GT(gpu.lastCasterOverflows(), 0u) << "the fan's deep walks overflow the shader's stack somewhere";

  // The C API: on a device and on the CPU alike, and the buffers an engine binds.
  const std::string file = ::testing::TempDir() + "light-casters.cpvs";
  writeBundle(file, bundle, true);
  std::vector<std::vector<double>> xyz;
  const std::vector<CpvsCasterMesh> cMeshes = cMeshesOf(meshes, xyz);
  std::vector<double> p, n;
  for (size_t i = 0; i < points.size(); ++i) {
    p.insert(p.end(), {points[i].x, points[i].y, points[i].z});
    n.insert(n.end(), {normals[i].x, normals[i].y, normals[i].z});
  }
  std::vector<uint32_t> want;
  cpuLightLitTexels(*artifact, which, points, normals, 3, want, casters.get());
  CpvsDeviceDesc desc{nullptr, 1, 0};
  CpvsDevice cDevice = nullptr;
  ASSERT_EQ(cpvsNewDevice(&desc, &cDevice), CPVS_OK) << cpvsGetLastError();
  for (CpvsDevice d : {cDevice, CpvsDevice(nullptr)}) {
    CpvsLights h = nullptr;
    ASSERT_EQ(cpvsOpenLights(file.c_str(), d, 0, &h), CPVS_OK) << cpvsGetLastError();
    ASSERT_EQ(cpvsSetLightCasters(h, cMeshes.data(), cMeshes.size(), -1), CPVS_OK) << cpvsGetLastError();
    std::vector<uint32_t> got(points.size());
    ASSERT_EQ(cpvsQueryLights(h, points.size(), which.data(), which.size(), p.data(), n.data(), 3, got.data()), CPVS_OK);
    EXPECT_EQ(got, want) << (d ? "on a device" : "on the CPU");
    const void* data = nullptr;
    size_t bytes = 0;
    ASSERT_EQ(cpvsGetLightBuffer(h, CPVS_LIGHT_BUFFER_CASTER_TREES, &data, &bytes), CPVS_OK);
    EXPECT_EQ(bytes, 64 * bundle.lights.size());
    ASSERT_EQ(cpvsGetLightBuffer(h, CPVS_LIGHT_BUFFER_CASTER_NODES, &data, &bytes), CPVS_OK);
    EXPECT_EQ(bytes, 32 * (casters->tree(0)->nodes().size() + casters->tree(2)->nodes().size()));
    ASSERT_EQ(cpvsSetLightCasters(h, nullptr, 0, -1), CPVS_OK);
    ASSERT_EQ(cpvsQueryLights(h, points.size(), which.data(), which.size(), p.data(), n.data(), 3, got.data()), CPVS_OK);
    std::vector<uint32_t> plain;
    cpuLightLitTexels(*artifact, which, points, normals, 3, plain);
    EXPECT_EQ(got, plain);
    cpvsReleaseLights(h);
  }
  EXPECT_EQ(cpvsGetValidationMessageCount(cDevice), 0u);
  cpvsReleaseDevice(cDevice);

  gpu.setDynamicCasters(nullptr);
  std::vector<uint32_t> onGpu, onCpu;
  gpu.litTexels(which, points, normals, 3, onGpu);
  cpuLightLitTexels(*artifact, which, points, normals, 3, onCpu);
  EXPECT_EQ(onGpu, onCpu);
  expectNoValidationMessages(device());
}

// A light bundle on the device: two spot lights (one with its range short of the scene)
// and a point light's cube over a small city, answered as BundleQuery answers, bit for
// bit, for every filter width: surface points in each cone with their normals; points
// spread over each grid's voxels and beyond its sides, in front of near, beyond far and
// behind the light, many exactly on a texel edge or a slice boundary (or a hair off
// one), with zero, NaN, tiny and random normals.
TEST(GpuLightLookups, ABundleAnswersAsTheCpu) {
  const Scene scene = openScene("city:3");
  Vec3 lo, hi;
  sceneBounds(scene, lo, hi);
  const Vec3 c = (lo + hi) * 0.5, e = hi - lo;
  const std::vector<Light> lights = threeLamps(c, e);
  const auto artifact = std::make_shared<const LightArtifact>(bakeLights(scene, lights, 0, BakeOptions{}, sceneHash(scene)));
  const LightBundle& bundle = artifact->bundle();
  ASSERT_EQ(bundle.grids.size(), 8u);

  std::vector<uint32_t> which;
  std::vector<Vec3> points, normals;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> gauss;
  const RayScene rays(scene, c);
  for (size_t k = 0; k < bundle.grids.size(); ++k) {
    const BundleGrid& g = bundle.grids[k];
    appendGridSurfaces(scene, rays, bundle, k, 600, which, points, normals);
    const double R = double(g.grid.resolution());
    const double hairs[] = {0, 1e-9, -1e-9};
    for (int i = 0; i < 900; ++i) {
      Vec3 v{(unit(rng) * 1.4 - 0.2) * R, (unit(rng) * 1.4 - 0.2) * R, (unit(rng) * 1.6 - 0.3) * R};
      double* axis[] = {&v.x, &v.y, &v.z};
      for (double* a : axis)
        if (rng() % 2) *a = std::floor(*a) + hairs[rng() % 3];
      Vec3 p = g.grid.worldFromVoxel(v);
      if (i % 10 == 0) p = g.grid.position() * 2 - p;  // behind the light
      which.push_back(g.light);
      points.push_back(p);
      const uint64_t kind = rng() % 6;
      normals.push_back(kind == 0   ? Vec3{}
                        : kind == 1 ? Vec3{std::nan(""), 0, 1}
                        : kind == 2 ? Vec3{1e-310, 0, 0}
                                    : Vec3{gauss(rng), gauss(rng), gauss(rng)});
    }
  }
  GpuLights gpu(device(), artifact);
  for (int pcf : {1, 3, 9}) {
    std::vector<uint32_t> onGpu, onCpu;
    gpu.litTexels(which, points, normals, pcf, onGpu);
    EXPECT_GT(gpu.lastDeviceNanoseconds(), 0) << "the device ran the lookups";
    cpuLightLitTexels(*artifact, which, points, normals, pcf, onCpu);
    ASSERT_EQ(onGpu.size(), points.size());
    uint64_t differ = 0, lit = 0, dark = 0, partly = 0;
    for (size_t i = 0; i < points.size(); ++i) {
      if (onGpu[i] != onCpu[i] && ++differ <= 5)
        ADD_FAILURE() << "pcf " << pcf << ", light " << which[i] << " at " << points[i].x << ", " << points[i].y << ", "
                      << points[i].z << ": GPU " << onGpu[i] << ", CPU " << onCpu[i];
      (onCpu[i] == 0 ? dark : onCpu[i] == uint32_t(pcf * pcf) ? lit : partly) += 1;
    }
    EXPECT_EQ(differ, 0u) << "pcf " << pcf << ", " << points.size() << " queries";
    EXPECT_GT(lit, points.size() / 20) << "pcf " << pcf << ": the queries must see light";
    EXPECT_GT(dark, points.size() / 20) << "pcf " << pcf << ": and shadow";
    if (pcf > 1) {
      EXPECT_GT(partly, points.size() / 100) << "pcf " << pcf << ": and penumbrae";
    }
  }
  // Shallower pointer grids, down to none (walks from the root): the same answers.
  for (int levels : {0, 2}) {
    const auto shallow = std::make_shared<const LightArtifact>(withPointerGrids(bundle, levels));
    GpuLights other(device(), shallow);
    std::vector<uint32_t> onOther, onCpu;
    other.litTexels(which, points, normals, 9, onOther);
    cpuLightLitTexels(*artifact, which, points, normals, 9, onCpu);
    EXPECT_EQ(onOther, onCpu) << levels << " pointer-grid levels";
  }
  // The pool split across bindings: the same answers.
  {
    DeviceOptions options = validated();
    options.maxBindingBytes = std::bit_floor(bundle.pool->size() * 4 / 4);  // 4 to 8 bindings
    auto small = GpuDevice::create(options);
    GpuLights split(*small, artifact);
    EXPECT_GE(split.wordBindings(), 4);
    EXPECT_LE(split.wordBindings(), 8);
    std::vector<uint32_t> onSplit, onOne;
    split.litTexels(which, points, normals, 9, onSplit);
    gpu.litTexels(which, points, normals, 9, onOne);
    EXPECT_EQ(onSplit, onOne);
    expectNoValidationMessages(*small);
  }
  // One light for every point, and refusals.
  std::vector<uint32_t> one, each;
  gpu.litTexels({2}, points, normals, 9, one);
  cpuLightLitTexels(*artifact, std::vector<uint32_t>(points.size(), 2), points, normals, 9, each);
  EXPECT_EQ(one, each);
  auto statusOf = [&](auto&& call) {
    try {
      call();
    } catch (const RuntimeError& e) {
      return e.status();
    }
    return Status::Ok;
  };
  EXPECT_EQ(statusOf([&] { gpu.litTexels({3}, points, normals, 1, one); }), Status::InvalidArgument);
  EXPECT_EQ(statusOf([&] { gpu.litTexels({0, 1}, points, normals, 1, one); }), Status::InvalidArgument);
  EXPECT_EQ(statusOf([&] { gpu.litTexels(which, points, normals, 4, one); }), Status::InvalidArgument);
  const Baked b = bake("city:3", {0.3, -1, 0.2}, 7);
  EXPECT_EQ(statusOf([&] { LightArtifact::open(b.file); }), Status::CorruptArtifact) << "a sun artifact is no bundle";
  EXPECT_EQ(statusOf([&] { LightArtifact::open(::testing::TempDir() + "absent-bundle.cpvs"); }), Status::FileError);
  expectNoValidationMessages(device());

  // Through the C API, on a device and on the CPU: the same answers, the light table, the
  // buffers an engine binds, and clear errors.
  const std::string file = ::testing::TempDir() + "gpu-lights.cpvs";
  writeBundle(file, bundle, true);
  CpvsDeviceDesc desc{nullptr, 1, 0};
  CpvsDevice cDevice = nullptr;
  ASSERT_EQ(cpvsNewDevice(&desc, &cDevice), CPVS_OK) << cpvsGetLastError();
  CpvsLights onDevice = nullptr, onCpu = nullptr;
  ASSERT_EQ(cpvsOpenLights(file.c_str(), cDevice, 0, &onDevice), CPVS_OK) << cpvsGetLastError();
  ASSERT_EQ(cpvsOpenLights(file.c_str(), nullptr, 0, &onCpu), CPVS_OK) << cpvsGetLastError();
  EXPECT_EQ(cpvsLightsOnDevice(onDevice), 1);
  EXPECT_EQ(cpvsLightsOnDevice(onCpu), 0);
  ASSERT_EQ(cpvsGetLightCount(onDevice), 3u);
  CpvsLightInfo info{};
  ASSERT_EQ(cpvsGetLightInfo(onDevice, 2, &info), CPVS_OK);
  EXPECT_EQ(info.kind, 1u);
  EXPECT_EQ(info.gridCount, 6u);
  EXPECT_STREQ(info.name, "bulb");
  EXPECT_EQ(info.position[1], lights[2].position.y);
  EXPECT_EQ(cpvsGetLightInfo(onDevice, 3, &info), CPVS_ERROR_INVALID_ARGUMENT);
  std::vector<double> flat, flatNormals;
  for (size_t i = 0; i < points.size(); ++i)
    for (const Vec3* v : {&points[i], &normals[i]}) (v == &points[i] ? flat : flatNormals).insert((v == &points[i] ? flat : flatNormals).end(), {v->x, v->y, v->z});
  std::vector<uint32_t> fromDevice(points.size()), fromCpu(points.size()), reference;
  ASSERT_EQ(cpvsQueryLights(onDevice, points.size(), which.data(), which.size(), flat.data(), flatNormals.data(), 9,
                            fromDevice.data()), CPVS_OK) << cpvsGetLastError();
  ASSERT_EQ(cpvsQueryLights(onCpu, points.size(), which.data(), which.size(), flat.data(), flatNormals.data(), 9,
                            fromCpu.data()), CPVS_OK) << cpvsGetLastError();
  cpuLightLitTexels(*artifact, which, points, normals, 9, reference);
  EXPECT_EQ(fromDevice, reference);
  EXPECT_EQ(fromCpu, reference);
  const uint32_t tooFar = 3;
  EXPECT_EQ(cpvsQueryLights(onDevice, 1, &tooFar, 1, flat.data(), nullptr, 1, fromDevice.data()), CPVS_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(cpvsGetLastError()).find("light 3 of a bundle of 3"), std::string::npos) << cpvsGetLastError();
  EXPECT_EQ(cpvsQueryLights(onDevice, 3, which.data(), 2, flat.data(), nullptr, 1, fromDevice.data()), CPVS_ERROR_INVALID_ARGUMENT);
  const void* data = nullptr;
  size_t bytes = 0;
  ASSERT_EQ(cpvsGetLightBuffer(onDevice, CPVS_LIGHT_BUFFER_WORDS, &data, &bytes), CPVS_OK);
  EXPECT_EQ(bytes, bundle.pool->size() * 4);
  EXPECT_EQ(std::memcmp(data, bundle.pool->data(), bytes), 0) << "the pool as the file holds it";
  ASSERT_EQ(cpvsGetLightBuffer(onDevice, CPVS_LIGHT_BUFFER_LIGHTS, &data, &bytes), CPVS_OK);
  EXPECT_EQ(bytes, 3u * 64);
  ASSERT_EQ(cpvsGetLightBuffer(onDevice, CPVS_LIGHT_BUFFER_GRIDS, &data, &bytes), CPVS_OK);
  ASSERT_EQ(bytes, 8 + 8u * sizeof(GpuGrid));
  // One record a grid, from the grid's description: what the sun's block holds too.
  for (size_t k = 0; k < 8; ++k) {
    const BundleGrid& g = bundle.grids[k];
    uint32_t first = 0;
    for (size_t j = 0; j < k; ++j) first += uint32_t(bundle.grids[j].grid.resolution() + 1);
    const GpuGrid want = gpuGridOf(gridSpecOf(g.grid, g.tanCone), "grid", bundle.dag(k).headerWord(), first, g.light);
    EXPECT_EQ(std::memcmp(static_cast<const uint8_t*>(data) + 8 + k * sizeof(GpuGrid), &want, sizeof want), 0) << "grid " << k;
  }
  ASSERT_EQ(cpvsGetLightBuffer(onDevice, CPVS_LIGHT_BUFFER_BOUNDARIES, &data, &bytes), CPVS_OK);
  EXPECT_EQ(bytes, (257u + 129u * 7) * 8);
  CpvsLights refused = nullptr;
  EXPECT_EQ(cpvsOpenLights(b.file.c_str(), cDevice, 0, &refused), CPVS_ERROR_CORRUPT_ARTIFACT);
  EXPECT_EQ(refused, nullptr);
  EXPECT_EQ(cpvsGetValidationMessageCount(cDevice), 0u);
  cpvsReleaseLights(onDevice);
  cpvsReleaseLights(onCpu);
  cpvsReleaseDevice(cDevice);
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
  // What an engine's shader binds for the sun: its grid's one record and the words.
  const void* data = nullptr;
  size_t bytes = 0;
  ASSERT_EQ(cpvsGetShadowsBuffer(onCpu, CPVS_SHADOWS_BUFFER_SUN, &data, &bytes), CPVS_OK);
  ASSERT_EQ(bytes, 224u);
  const GpuGrid sun = gpuGridOf(gridSpecOf(b.artifact->grid()), "sun");
  EXPECT_EQ(std::memcmp(data, &sun, sizeof sun), 0);
  const LookupMapping cpu = b.artifact->grid().lookupMapping();
  EXPECT_EQ(std::memcmp(&sun.mapping, &cpu, sizeof cpu), 0) << "the CPU's constants";
  ASSERT_EQ(cpvsGetShadowsBuffer(onCpu, CPVS_SHADOWS_BUFFER_WORDS, &data, &bytes), CPVS_OK);
  EXPECT_EQ(bytes, b.artifact->packed().words().size() * 4);
  EXPECT_EQ(std::memcmp(data, b.artifact->packed().words().data(), bytes), 0);
  EXPECT_EQ(cpvsGetShadowsBuffer(onCpu, CpvsShadowsBuffer(7), &data, &bytes), CPVS_ERROR_INVALID_ARGUMENT);
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
