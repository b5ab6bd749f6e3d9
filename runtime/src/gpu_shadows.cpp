// An artifact on a device: its packed words uploaded as they are, the query pipeline.
#include <cstring>

#include "gpu_device_impl.h"
#include "query_kernel.h"

namespace cpvs::runtime {

struct GpuShadows::Impl {
  std::shared_ptr<const ShadowArtifact> artifact;
  QueryKernel kernel;
  Impl(GpuDevice::Impl& g, std::shared_ptr<const ShadowArtifact> a)
      : artifact(std::move(a)),
        kernel(g, artifact->packed().words(), gpuGridOf(gridSpecOf(artifact->grid()), "the artifact's grid"), {},
               {queryShaderOneBuffer(), queryShaderEightBuffers(), false, 1}, "the DAG") {}
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

double GpuShadows::lastDeviceNanoseconds() const { return impl_->kernel.lastDeviceNanoseconds(); }
int GpuShadows::wordBindings() const { return impl_->kernel.wordBindings(); }
const ShadowArtifact& GpuShadows::artifact() const { return *impl_->artifact; }

void GpuShadows::litTexels(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
                           std::vector<uint32_t>& out) {
  checkQueryShape(points.size(), normals.size(), pcf);
  impl_->kernel.run(points, normals, {}, pcf, out);
}

}  // namespace cpvs::runtime
