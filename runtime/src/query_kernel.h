// A compute pipeline of lookups over one packed word array on a device: the words
// uploaded as they are (one buffer, bound whole or split across up to 8 bindings), the
// sun's grid block (a light bundle's kernel leaves it zero), the read-only tables a shader needs besides (a light bundle's lights,
// grids and slice boundaries), and batches of queries in, lit texel counts out. What
// GpuShadows and GpuLights share. Private to runtime.
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/base/vec3.h"
#include "cpvs/light/gpu_grid.h"
#include "cpvs/query/medium.h"
#include "cpvs/runtime/runtime.h"
#include "gpu_device_impl.h"
#include "query_shaders.h"

namespace cpvs::runtime {

/// The uniform block CpvsSun of cpvs_shadow.glsl (std140: the sun's grid, then the log2 of
/// the words per word buffer, padded to the block's 16-byte alignment).
struct SunBlock {
  GpuGrid grid;
  uint32_t log2BufferWords;
  uint32_t pad[3];
};
static_assert(sizeof(SunBlock) == 224);

/// InvalidArgument unless pcf is a valid filter width and there are no normals or one per
/// point.
void checkQueryShape(size_t points, size_t normals, int pcf);
/// InvalidArgument unless there are as many segment ends as starts and the medium is
/// valid (checkMedium).
void checkSegmentShape(size_t starts, size_t ends, const Medium& medium);
/// InvalidArgument unless the artifact is a CPVS: segments walk its voxels.
void checkSegmentKind(const ShadowArtifact& artifact);

class QueryKernel {
 public:
  /// A read-only storage buffer uploaded once, at `binding`.
  struct Table {
    uint32_t binding;
    std::vector<uint8_t> bytes;
  };
  struct Shaders {
    SpirvCode oneBuffer, eightBuffers;
    bool queryLights;           // each query names a light (binding 11)
    uint32_t firstWordBinding;  // 1 (the sun's words), 15 (a light bundle's pool)
    uint32_t answerWords = 1;   // per query: 1 (a lit texel count), 4 (a segment's)
  };
  /// `what` names the words in errors ("the DAG", "the light bundle").
  QueryKernel(GpuDevice::Impl& device, const std::vector<uint32_t>& words, const GpuGrid& sun,
              std::vector<Table> tables, const Shaders& shaders, const char* what);
  ~QueryKernel();
  QueryKernel(const QueryKernel&) = delete;
  QueryKernel& operator=(const QueryKernel&) = delete;

  /// The answers' words for each query (point, normal, and with queryLights its light;
  /// a segment's two ends), answerWords each; pcf and the counts already checked, the
  /// medium for the segment shader. DeviceLost when the device stops answering.
  void run(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, const std::vector<uint32_t>& lights,
           int pcf, std::vector<uint32_t>& out, const float medium[3] = nullptr);
  /// Uploads new bytes for the table at `binding` (one of those given), for the runs that
  /// follow: what changes per frame (the dynamic casters' tree).
  void replaceTable(uint32_t binding, const std::vector<uint8_t>& bytes);
  /// The table at `binding` becomes a copy, on the device, of `from`'s table there (what
  /// another kernel wrote into it).
  void copyTable(uint32_t binding, const QueryKernel& from);
  double lastDeviceNanoseconds() const { return lastNs_; }
  int wordBindings() const { return int(bindings_); }

 private:
  /// Every device object, destroyed (twice is harmless).
  void release();
  void upload(const std::vector<uint32_t>& words, const GpuGrid& sun, const char* what);
  void createPipeline(const Shaders& shaders);
  void ensureCapacity(uint64_t n);
  void writeDescriptor(uint32_t binding, VkDescriptorType type, VkBuffer buffer, VkDeviceSize offset, VkDeviceSize range);
  void writeStorage(uint32_t binding, VkBuffer buffer, VkDeviceSize offset, VkDeviceSize range) {
    writeDescriptor(binding, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, buffer, offset, range);
  }
  VulkanBuffer uploadToDevice(const void* data, uint64_t bytes);
  size_t tableIndex(uint32_t binding) const;

  GpuDevice::Impl& g;
  std::vector<Table> tables_;
  std::vector<VulkanBuffer> tableBuffers_;
  bool queryLights_ = false;
  uint32_t answerWords_ = 1;
  uint32_t firstWordBinding_ = 1;
  VulkanBuffer words_, sun_, queries_, answers_, lights_, staging_;
  uint32_t bindings_ = 1;
  uint64_t wordsPerBinding_ = 0;
  VkDescriptorSetLayout setLayout_ = VK_NULL_HANDLE;
  VkPipelineLayout pipelineLayout_ = VK_NULL_HANDLE;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
  VkDescriptorPool pool_ = VK_NULL_HANDLE;
  VkDescriptorSet set_ = VK_NULL_HANDLE;
  VkQueryPool timestamps_ = VK_NULL_HANDLE;
  uint64_t capacity_ = 0;  // queries the query buffers hold
  double lastNs_ = 0;
};

}  // namespace cpvs::runtime
