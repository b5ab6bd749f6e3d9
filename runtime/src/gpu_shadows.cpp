// An artifact on a device: its words (a CPVS's or a DAG-MH's) uploaded as they are, the
// query pipeline of its kind.
#include <cstring>

#include "cpvs/base/error.h"
#include "cpvs/query/medium.h"
#include "gpu_device_impl.h"
#include "query_kernel.h"

namespace cpvs::runtime {

struct GpuShadows::Impl {
  GpuDevice::Impl& device;
  std::shared_ptr<const ShadowArtifact> artifact;
  QueryKernel kernel;
  // Segments (sun shafts) have their own pipeline, made on first use: the words uploaded
  // a second time then, and never for a game that asks for none.
  std::unique_ptr<QueryKernel> segments;
  // Lookups with dynamic casters (cpvs_caster_query.comp), made when casters are first
  // set; their tree replaced each frame.
  std::unique_ptr<QueryKernel> withCasters;
  // Their trees inserted on the device (cpvs_caster_build.comp), made when first asked.
  std::unique_ptr<QueryKernel> casterBuild;
  std::shared_ptr<const DynamicCasters> casters;
  size_t casterOverflows = 0;
  double casterBuildNs = 0;
  uint64_t casterBuildSteps = 0;
  // The translucent casters' transmittance (cpvs_translucent_query.comp), made on first use.
  std::unique_ptr<QueryKernel> translucent;
  size_t translucentOverflows = 0;
  Impl(GpuDevice::Impl& g, std::shared_ptr<const ShadowArtifact> a)
      : device(g),
        artifact(std::move(a)),
        kernel(g, artifact->words(), sunGrid(), {}, dagMh() ? QueryKernel::Shaders{dagMhQueryShaderOneBuffer(), dagMhQueryShaderEightBuffers(), false, 1}
                                                            : QueryKernel::Shaders{queryShaderOneBuffer(), queryShaderEightBuffers(), false, 1},
               what()) {}
  bool dagMh() const { return artifact->kind() == ArtifactKind::DagMh; }
  const char* what() const { return dagMh() ? "the DAG-MH" : "the DAG"; }
  GpuGrid sunGrid() const { return gpuGridOf(gridSpecOf(artifact->grid()), "the artifact's grid"); }
};

std::vector<uint8_t> sunBlockBytes(const ShadowArtifact& artifact, uint32_t log2BufferWords) {
  SunBlock block{};
  block.grid = gpuGridOf(gridSpecOf(artifact.grid()), "the artifact's grid");
  block.log2BufferWords = log2BufferWords;
  std::vector<uint8_t> bytes(sizeof block);
  std::memcpy(bytes.data(), &block, sizeof block);
  return bytes;
}

GpuShadows::GpuShadows(GpuDevice& device, std::shared_ptr<const ShadowArtifact> artifact) {
  if (!artifact) throw RuntimeError(Status::InvalidArgument, "no artifact to upload");
  device.impl().checkNotLost();
  impl_ = std::make_unique<Impl>(device.impl(), std::move(artifact));
}

GpuShadows::~GpuShadows() = default;

double GpuShadows::lastDeviceNanoseconds() const {
  return (impl_->casters ? *impl_->withCasters : impl_->kernel).lastDeviceNanoseconds();
}
double GpuShadows::lastSegmentNanoseconds() const {
  return impl_->segments ? impl_->segments->lastDeviceNanoseconds() : 0;
}
int GpuShadows::wordBindings() const { return impl_->kernel.wordBindings(); }
const ShadowArtifact& GpuShadows::artifact() const { return *impl_->artifact; }

void GpuShadows::segments(const std::vector<Vec3>& from, const std::vector<Vec3>& to, const Medium& medium,
                          std::vector<double>& litFraction, std::vector<float>& inScattering) {
  checkSegmentShape(from.size(), to.size(), medium);
  checkSegmentKind(*impl_->artifact);
  if (!impl_->segments)
    impl_->segments = std::make_unique<QueryKernel>(impl_->device, impl_->artifact->packed().words(), impl_->sunGrid(),
                                                    std::vector<QueryKernel::Table>{},
                                                    QueryKernel::Shaders{segmentShaderOneBuffer(), segmentShaderEightBuffers(),
                                                                         false, 1, 4},
                                                    "the DAG");
  const float m[3] = {float(medium.scattering), float(medium.absorption), float(medium.g)};
  std::vector<uint32_t> words;
  impl_->segments->run(from, to, {}, 1, words, m);
  litFraction.resize(from.size());
  inScattering.resize(from.size());
  for (size_t i = 0; i < from.size(); ++i) {
    std::memcpy(&litFraction[i], &words[4 * i], 8);
    std::memcpy(&inScattering[i], &words[4 * i + 2], 4);
  }
}

// cpvs_caster_query.comp's binding of the casters' tree (CPVS_CASTER_BINDING), and
// cpvs_caster_build.comp's of the corners it classifies with.
constexpr uint32_t kCasterBinding = 12, kCornerBinding = 13;

void GpuShadows::setDynamicCasters(std::shared_ptr<const DynamicCasters> casters) {
  Impl& m = *impl_;
  m.casterBuildNs = 0;
  m.casterBuildSteps = 0;
  if (casters) {
    const std::vector<uint8_t> bytes = casters->gpuBytes();
    if (!m.withCasters)
      m.withCasters = std::make_unique<QueryKernel>(
          m.device, m.artifact->words(), m.sunGrid(), std::vector<QueryKernel::Table>{{kCasterBinding, bytes}},
          m.dagMh() ? QueryKernel::Shaders{dagMhCasterShaderOneBuffer(), dagMhCasterShaderEightBuffers(), false, 1}
                    : QueryKernel::Shaders{casterShaderOneBuffer(), casterShaderEightBuffers(), false, 1},
          m.what());
    else
      m.withCasters->replaceTable(kCasterBinding, bytes);
    const TopTree& tree = casters->tree();
    if (!tree.linked()) {
      // Insert the frusta on the device, then hand the tree to the lookups' kernel.
      const std::vector<uint8_t> corners = casters->cornerBytes();
      if (!m.casterBuild)
        m.casterBuild = std::make_unique<QueryKernel>(
            m.device, std::vector<uint32_t>{0}, m.sunGrid(),
            std::vector<QueryKernel::Table>{{kCasterBinding, bytes}, {kCornerBinding, corners}},
            QueryKernel::Shaders{casterBuildShader(), casterBuildShader(), false, 1}, "the casters' tree");
      else {
        m.casterBuild->replaceTable(kCasterBinding, bytes);
        m.casterBuild->replaceTable(kCornerBinding, corners);
      }
      // One query a frustum to insert, its rank for a point.
      std::vector<Vec3> ranks;
      for (size_t r = 1; r < tree.frustumCount(); ++r) ranks.push_back(Vec3{double(r), 0, 0});
      std::vector<uint32_t> steps;
      m.casterBuild->run(ranks, {}, {}, 1, steps);
      m.casterBuildNs = m.casterBuild->lastDeviceNanoseconds();
      for (uint32_t s : steps) m.casterBuildSteps += s;
      m.withCasters->copyTable(kCasterBinding, *m.casterBuild);
    }
  }
  m.casters = std::move(casters);
}

double GpuShadows::lastCasterBuildNanoseconds() const { return impl_->casterBuildNs; }
uint64_t GpuShadows::lastCasterBuildSteps() const { return impl_->casterBuildSteps; }

size_t GpuShadows::lastCasterOverflows() const { return impl_->casterOverflows; }
size_t GpuShadows::lastTranslucentOverflows() const { return impl_->translucentOverflows; }

// cpvs_translucent_query.comp's bindings of the tree and of its transmittance.
constexpr uint32_t kTranslucentBinding = 12, kTransmittanceBinding = 13;

void GpuShadows::transmittance(const std::vector<Vec3>& points, const std::vector<Vec3>& normals,
                               std::vector<std::array<float, 3>>& out) {
  checkQueryShape(points.size(), normals.size(), 1);
  Impl& m = *impl_;
  m.translucentOverflows = 0;
  const ShadowArtifact& a = *m.artifact;
  if (!a.translucent() || a.translucent()->root() == 0) {
    out.assign(points.size(), {1, 1, 1});
    return;
  }
  if (!m.translucent)
    m.translucent = std::make_unique<QueryKernel>(
        m.device, a.packed().words(), m.sunGrid(),
        std::vector<QueryKernel::Table>{{kTranslucentBinding, a.translucentGpuBytes()},
                                        {kTransmittanceBinding, a.transmittanceGpuBytes()}},
        QueryKernel::Shaders{translucentShaderOneBuffer(), translucentShaderEightBuffers(), false, 1, 4}, "the DAG");
  std::vector<uint32_t> words;
  m.translucent->run(points, normals, {}, 1, words);
  out.resize(points.size());
  std::vector<size_t> overflows;
  for (size_t i = 0; i < points.size(); ++i) {
    if (words[4 * i] & 0x80000000u) overflows.push_back(i);
    for (int c = 0; c < 3; ++c) std::memcpy(&out[i][c], &words[4 * i + 1 + c], 4);
  }
  // A walk deeper than the shader's stack: the CPU's answer, the same to the bit.
  m.translucentOverflows = overflows.size();
  if (overflows.empty()) return;
  std::vector<Vec3> p, n;
  for (size_t i : overflows) {
    p.push_back(points[i]);
    if (!normals.empty()) n.push_back(normals[i]);
  }
  std::vector<std::array<float, 3>> cpu;
  cpuTransmittance(a, p, n, cpu);
  for (size_t k = 0; k < overflows.size(); ++k) out[overflows[k]] = cpu[k];
}

void GpuShadows::litTexels(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
                           std::vector<uint32_t>& out) {
  checkQueryShape(points.size(), normals.size(), pcf);
  Impl& m = *impl_;
  m.casterOverflows = 0;
  if (!m.casters) {
    m.kernel.run(points, normals, {}, pcf, out);
    return;
  }
  m.withCasters->run(points, normals, {}, pcf, out);
  // Bit 31: the walk of the casters' tree needed a deeper stack than the shader's.
  for (size_t i = 0; i < out.size(); ++i)
    if (out[i] & 0x80000000u) {
      ++m.casterOverflows;
      out[i] = m.casters->shadowed(points[i], normals.empty() ? Vec3{} : normals[i]) ? 0 : out[i] & 0x7fffffffu;
    }
}

}  // namespace cpvs::runtime
