// A light bundle's lookups: the CPU path, and its upload to a device as the tables
// cpvs_shadow.glsl's CPVS_LIGHTS section reads.
#include <tbb/parallel_for.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <optional>

#include "cpvs/base/error.h"
#include "cpvs/query/normal_offset.h"
#include "cpvs/runtime/runtime.h"
#include "gpu_device_impl.h"
#include "query_kernel.h"

namespace cpvs::runtime {

namespace {

// The shader's CpvsLight (std430: floats and uints at 4); its grids are GpuGrid records.
struct GpuLight {
  uint32_t kind, firstGrid, gridCount, area;
  float position[3], range;
  float direction[3], cosCone;
  float colour[3], intensity;
};
static_assert(sizeof(GpuLight) == 64, "cpvs_shadow.glsl's CpvsLight is 64 bytes");

// cpvs_light_query.comp's pcf for a soft lookup: each query's light is an area light's
// first VPL, its answer the float bits of cpvsSoftVisibility.
constexpr int kSoftQuery = 0;

// Bindings of cpvs_light_query.comp's tables (CPVS_LIGHT_BINDING 12), then its pool, then
// the dynamic casters' trees (CPVS_LIGHT_CASTER_BINDING 23: headers, then nodes).
constexpr uint32_t kLightTableBinding = 12, kLightWordBinding = 15, kCasterTreeBinding = 23;


template <class T>
std::vector<uint8_t> bytesOf(const std::vector<T>& rows) {
  std::vector<uint8_t> b(rows.size() * sizeof(T));
  if (!rows.empty()) std::memcpy(b.data(), rows.data(), b.size());
  return b;
}

void put(float* out, const Vec3& v) { out[0] = float(v.x), out[1] = float(v.y), out[2] = float(v.z); }

void checkQueries(const LightArtifact& artifact, const std::vector<uint32_t>& lights, const std::vector<Vec3>& points,
                  const std::vector<Vec3>& normals, int pcf) {
  checkQueryShape(points.size(), normals.size(), pcf);
  if (lights.size() != points.size() && lights.size() != 1)
    throw RuntimeError(Status::InvalidArgument,
                       std::to_string(lights.size()) + " lights for " + std::to_string(points.size()) + " points (one each, or one for all)");
  for (uint32_t l : lights)
    if (l >= artifact.lightCount())
      throw RuntimeError(Status::InvalidArgument, "light " + std::to_string(l) + " of a bundle of " +
                                                      std::to_string(artifact.lightCount()) + " lights");
}

// The first VPL of each area light asked for (what cpvsSoftVisibility takes); the areas
// checked and the normals' count.
std::vector<uint32_t> firstVplsOf(const LightArtifact& artifact, const std::vector<uint32_t>& areas,
                                  const std::vector<Vec3>& points, const std::vector<Vec3>& normals) {
  checkQueryShape(points.size(), normals.size(), 1);
  if (areas.size() != points.size() && areas.size() != 1)
    throw RuntimeError(Status::InvalidArgument,
                       std::to_string(areas.size()) + " area lights for " + std::to_string(points.size()) + " points (one each, or one for all)");
  const BundleQuery& q = artifact.cpu();
  std::vector<uint32_t> first(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const uint32_t a = areas.size() == 1 ? areas[0] : areas[i];
    if (a >= q.areaCount())
      throw RuntimeError(Status::InvalidArgument,
                         "area light " + std::to_string(a) + " of a bundle of " + std::to_string(q.areaCount()) + " area lights");
    first[i] = q.vplsOf(a).front();
  }
  return first;
}

}  // namespace

void cpuSoftVisibility(const LightArtifact& artifact, const std::vector<uint32_t>& areas,
                       const std::vector<Vec3>& points, const std::vector<Vec3>& normals, std::vector<float>& out) {
  firstVplsOf(artifact, areas, points, normals);
  out.resize(points.size());
  const BundleQuery& q = artifact.cpu();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, points.size(), 256), [&](const auto& range) {
    for (size_t i = range.begin(); i != range.end(); ++i)
      out[i] = q.softVisibility(areas.size() == 1 ? areas[0] : areas[i], points[i], normals.empty() ? Vec3{} : normals[i]);
  });
}

void cpuLightLitTexels(const LightArtifact& artifact, const std::vector<uint32_t>& lights,
                       const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
                       std::vector<uint32_t>& out, const LightCasters* casters) {
  checkQueries(artifact, lights, points, normals, pcf);
  const PcfWidth width(pcf);
  out.resize(points.size());
  const BundleQuery& q = artifact.cpu();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, points.size(), 1024), [&](const auto& range) {
    for (size_t i = range.begin(); i != range.end(); ++i) {
      const uint32_t light = lights.size() == 1 ? lights[0] : lights[i];
      const Vec3 n = normals.empty() ? Vec3{} : normals[i];
      out[i] = casters && casters->shadowed(light, points[i], n) ? 0 : q.litTexels(light, points[i], n, width);
    }
  });
}

std::vector<uint8_t> lightTableBytes(const LightBundle& bundle) {
  std::vector<GpuLight> rows;
  for (const BundleLight& b : bundle.lights) {
    const Light& l = b.light;
    GpuLight r{};
    r.kind = l.kind == LightKind::Point ? 1 : 0;
    r.firstGrid = b.firstGrid, r.gridCount = b.gridCount;
    put(r.position, l.position);
    r.range = float(bundle.grids.at(b.firstGrid).grid.far());
    r.area = l.area;
    // A spot light's axis; a VPL's emitter normal (BundleQuery::emitterNormal).
    put(r.direction, l.kind == LightKind::Point && l.area == 0 ? Vec3{} : normalize(l.direction));
    r.cosCone = l.kind == LightKind::Point ? -1.0f : float(std::cos(l.coneDeg * M_PI / 180));
    put(r.colour, l.colour);
    r.intensity = float(l.intensity);
    rows.push_back(r);
  }
  return bytesOf(rows);
}

std::vector<uint8_t> gridTableBytes(const LightBundle& bundle, uint32_t log2BufferWords) {
  std::vector<GpuGrid> rows;
  uint64_t boundary = 0;
  for (size_t k = 0; k < bundle.grids.size(); ++k) {
    const BundleGrid& b = bundle.grids[k];
    rows.push_back(gpuGridOf(gridSpecOf(b.grid, b.tanCone), "grid " + std::to_string(k), bundle.dag(k).headerWord(),
                             uint32_t(boundary), b.light));
    boundary += b.grid.resolution() + 1;
  }
  // The header: log2 of the words per pool buffer, the grid count (8 bytes, so the rows
  // keep their doubles' alignment).
  std::vector<uint8_t> b(8);
  const uint32_t header[2] = {log2BufferWords, uint32_t(rows.size())};
  std::memcpy(b.data(), header, 8);
  const std::vector<uint8_t> body = bytesOf(rows);
  b.insert(b.end(), body.begin(), body.end());
  return b;
}

std::vector<uint8_t> sliceBoundaryBytes(const LightBundle& bundle) {
  std::vector<double> all;
  for (const BundleGrid& b : bundle.grids)
    all.insert(all.end(), b.grid.sliceBoundaries(), b.grid.sliceBoundaries() + b.grid.resolution() + 1);
  return bytesOf(all);
}

struct GpuLights::Impl {
  GpuDevice::Impl& device;
  std::shared_ptr<const LightArtifact> artifact;
  QueryKernel kernel;
  // Lookups with dynamic casters, made when casters are first set (the pool uploaded a
  // second time then, and never for a game that sets none); their trees replaced each frame.
  std::unique_ptr<QueryKernel> withCasters;
  std::shared_ptr<const LightCasters> casters;
  size_t casterOverflows = 0;
  Impl(GpuDevice::Impl& g, std::shared_ptr<const LightArtifact> a)
      : device(g),
        artifact(std::move(a)),
        kernel(g, *artifact->bundle().pool, GpuGrid{}, tables(), {lightQueryShaderOneBuffer(), lightQueryShaderEightBuffers(), true, kLightWordBinding},
               "the light bundle") {}
  std::vector<QueryKernel::Table> tables() const {
    return {{kLightTableBinding, lightTableBytes(artifact->bundle())},
            {kLightTableBinding + 1, gridTableBytes(artifact->bundle(), uint32_t(std::countr_zero(device.bindingLimit / 4)))},
            {kLightTableBinding + 2, sliceBoundaryBytes(artifact->bundle())}};
  }
};

GpuLights::GpuLights(GpuDevice& device, std::shared_ptr<const LightArtifact> artifact) {
  if (!artifact) throw RuntimeError(Status::InvalidArgument, "no light bundle to upload");
  device.impl().checkNotLost();
  impl_ = std::make_unique<Impl>(device.impl(), std::move(artifact));
}

GpuLights::~GpuLights() = default;

double GpuLights::lastDeviceNanoseconds() const {
  return (impl_->casters ? *impl_->withCasters : impl_->kernel).lastDeviceNanoseconds();
}
int GpuLights::wordBindings() const { return impl_->kernel.wordBindings(); }
const LightArtifact& GpuLights::artifact() const { return *impl_->artifact; }

void GpuLights::setDynamicCasters(std::shared_ptr<const LightCasters> casters) {
  Impl& m = *impl_;
  if (casters) {
    if (!m.withCasters) {
      std::vector<QueryKernel::Table> tables = m.tables();
      tables.push_back({kCasterTreeBinding, casters->headerBytes()});
      tables.push_back({kCasterTreeBinding + 1, casters->nodeBytes()});
      m.withCasters = std::make_unique<QueryKernel>(
          m.device, *m.artifact->bundle().pool, GpuGrid{}, std::move(tables),
          QueryKernel::Shaders{lightCasterShaderOneBuffer(), lightCasterShaderEightBuffers(), true, kLightWordBinding},
          "the light bundle");
    } else {
      m.withCasters->replaceTable(kCasterTreeBinding, casters->headerBytes());
      m.withCasters->replaceTable(kCasterTreeBinding + 1, casters->nodeBytes());
    }
  }
  m.casters = std::move(casters);
}

size_t GpuLights::lastCasterOverflows() const { return impl_->casterOverflows; }

void GpuLights::litTexels(const std::vector<uint32_t>& lights, const std::vector<Vec3>& points,
                          const std::vector<Vec3>& normals, int pcf, std::vector<uint32_t>& out) {
  Impl& m = *impl_;
  checkQueries(*m.artifact, lights, points, normals, pcf);
  QueryKernel& kernel = m.casters ? *m.withCasters : m.kernel;
  if (lights.size() == 1 && points.size() != 1) {
    const std::vector<uint32_t> each(points.size(), lights[0]);
    kernel.run(points, normals, each, pcf, out);
  } else {
    kernel.run(points, normals, lights, pcf, out);
  }
  // Bit 31: the walk of that light's casters' tree needed a deeper stack than the shader's.
  m.casterOverflows = 0;
  if (!m.casters) return;
  for (size_t i = 0; i < out.size(); ++i)
    if (out[i] & 0x80000000u) {
      ++m.casterOverflows;
      const uint32_t light = lights.size() == 1 ? lights[0] : lights[i];
      out[i] = m.casters->shadowed(light, points[i], normals.empty() ? Vec3{} : normals[i]) ? 0 : out[i] & 0x7fffffffu;
    }
}

void GpuLights::softVisibility(const std::vector<uint32_t>& areas, const std::vector<Vec3>& points,
                               const std::vector<Vec3>& normals, std::vector<float>& out) {
  const std::vector<uint32_t> first = firstVplsOf(*impl_->artifact, areas, points, normals);
  std::vector<uint32_t> bits;
  impl_->kernel.run(points, normals, first, kSoftQuery, bits);
  out.resize(bits.size());
  for (size_t i = 0; i < bits.size(); ++i) out[i] = std::bit_cast<float>(bits[i]);
}

}  // namespace cpvs::runtime
