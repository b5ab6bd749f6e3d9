// An artifact on a device: the packed words uploaded as they are, the query pipeline.
#include <algorithm>
#include <bit>
#include <cstring>

#include "cpvs/query/normal_offset.h"
#include "gpu_device_impl.h"
#include "query_shaders.h"

namespace cpvs::runtime {

namespace {

// Bindings of the query shader (cpvs_query.comp): the mapping, the word buffers, then
// the queries and the answers.
constexpr uint32_t kMappingBinding = 0, kFirstWordBinding = 1, kMaxWordBindings = 8, kQueryBinding = 9,
                   kAnswerBinding = 10;
constexpr uint32_t kGroupSize = 64;
constexpr uint32_t kQueryDoubles = 6;
// Queries per dispatch at most (48 MiB of queries): bounded by the binding limit too.
constexpr uint64_t kMaxBatch = uint64_t(1) << 20;

/// The uniform block CpvsMapping of cpvs_shadow.glsl.
struct MappingBlock {
  LookupMapping mapping;
  uint32_t log2BufferWords;
  uint32_t pad[3];
};
static_assert(sizeof(MappingBlock) == 160);

struct BatchConstants {
  uint32_t count, pcf, groupsX;
};

}  // namespace

struct GpuShadows::Impl {
  GpuDevice::Impl& g;
  std::shared_ptr<const ShadowArtifact> artifact;
  VulkanBuffer words, mapping, queries, answers, staging;
  uint32_t bindings = 1;
  uint64_t wordsPerBinding = 0;
  VkDescriptorSetLayout setLayout = VK_NULL_HANDLE;
  VkPipelineLayout pipelineLayout = VK_NULL_HANDLE;
  VkPipeline pipeline = VK_NULL_HANDLE;
  VkDescriptorPool pool = VK_NULL_HANDLE;
  VkDescriptorSet set = VK_NULL_HANDLE;
  VkQueryPool timestamps = VK_NULL_HANDLE;
  uint64_t capacity = 0;  // queries the query buffers hold
  double lastNs = 0;

  Impl(GpuDevice::Impl& device, std::shared_ptr<const ShadowArtifact> a) : g(device), artifact(std::move(a)) {}
  ~Impl() {
    if (!g.lost) g.vkd.vkDeviceWaitIdle(g.device);
    for (VulkanBuffer* b : {&words, &mapping, &queries, &answers, &staging}) g.destroy(*b);
    if (timestamps) g.vkd.vkDestroyQueryPool(g.device, timestamps, nullptr);
    if (pool) g.vkd.vkDestroyDescriptorPool(g.device, pool, nullptr);
    if (pipeline) g.vkd.vkDestroyPipeline(g.device, pipeline, nullptr);
    if (pipelineLayout) g.vkd.vkDestroyPipelineLayout(g.device, pipelineLayout, nullptr);
    if (setLayout) g.vkd.vkDestroyDescriptorSetLayout(g.device, setLayout, nullptr);
  }

  void upload();
  void createPipeline();
  void ensureCapacity(uint64_t n);
  void writeDescriptor(uint32_t binding, VkDescriptorType type, VkBuffer buffer, VkDeviceSize offset, VkDeviceSize range);
  void writeStorage(uint32_t binding, VkBuffer buffer, VkDeviceSize offset, VkDeviceSize range) {
    writeDescriptor(binding, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, buffer, offset, range);
  }
};

void GpuShadows::Impl::upload() {
  const std::vector<uint32_t>& w = artifact->packed().words();
  const uint64_t bytes = uint64_t(w.size()) * 4;
  wordsPerBinding = g.bindingLimit / 4;
  bindings = uint32_t((bytes + g.bindingLimit - 1) / g.bindingLimit);
  if (bindings > kMaxWordBindings)
    throw RuntimeError(Status::OutOfMemory, "the DAG's " + std::to_string(bytes) + " bytes need " + std::to_string(bindings) +
                                                " storage bindings of " + std::to_string(g.bindingLimit) +
                                                " bytes; the query shader has " + std::to_string(kMaxWordBindings));
  if (bindings > 1 && g.bindingLimit % g.properties.limits.minStorageBufferOffsetAlignment != 0)
    throw RuntimeError(Status::Internal, "the binding size is not a multiple of the device's storage offset alignment");
  words = g.createBuffer(bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, false);
  VulkanBuffer stage = g.createBuffer(bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true);
  std::memcpy(stage.mapped, w.data(), bytes);
  try {
    g.submitAndWait([&](VkCommandBuffer cmd) {
      VkBufferCopy region{0, 0, bytes};
      g.vkd.vkCmdCopyBuffer(cmd, stage.buffer, words.buffer, 1, &region);
    });
  } catch (...) {
    g.destroy(stage);
    throw;
  }
  g.destroy(stage);
  mapping = g.createBuffer(sizeof(MappingBlock), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true);
  MappingBlock block{};
  block.mapping = artifact->grid().lookupMapping();
  block.log2BufferWords = uint32_t(std::countr_zero(wordsPerBinding));
  std::memcpy(mapping.mapped, &block, sizeof block);
}

void GpuShadows::Impl::createPipeline() {
  std::vector<VkDescriptorSetLayoutBinding> layout;
  auto add = [&](uint32_t binding, VkDescriptorType type) {
    layout.push_back({binding, type, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
  };
  add(kMappingBinding, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER);
  const uint32_t wordBindings = bindings == 1 ? 1 : kMaxWordBindings;  // the shader variant's
  for (uint32_t k = 0; k < wordBindings; ++k) add(kFirstWordBinding + k, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
  add(kQueryBinding, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
  add(kAnswerBinding, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
  VkDescriptorSetLayoutCreateInfo setInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  setInfo.bindingCount = uint32_t(layout.size());
  setInfo.pBindings = layout.data();
  g.check(g.vkd.vkCreateDescriptorSetLayout(g.device, &setInfo, nullptr, &setLayout), "vkCreateDescriptorSetLayout");
  VkPushConstantRange push{VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(BatchConstants)};
  VkPipelineLayoutCreateInfo pipeInfo{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  pipeInfo.setLayoutCount = 1;
  pipeInfo.pSetLayouts = &setLayout;
  pipeInfo.pushConstantRangeCount = 1;
  pipeInfo.pPushConstantRanges = &push;
  g.check(g.vkd.vkCreatePipelineLayout(g.device, &pipeInfo, nullptr, &pipelineLayout), "vkCreatePipelineLayout");

  const SpirvCode code = bindings == 1 ? queryShaderOneBuffer() : queryShaderEightBuffers();
  VkShaderModuleCreateInfo moduleInfo{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  moduleInfo.codeSize = code.words * 4;
  moduleInfo.pCode = code.data;
  VkShaderModule module;
  g.check(g.vkd.vkCreateShaderModule(g.device, &moduleInfo, nullptr, &module), "vkCreateShaderModule");
  VkComputePipelineCreateInfo info{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  info.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO, nullptr, 0, VK_SHADER_STAGE_COMPUTE_BIT, module, "main", nullptr};
  info.layout = pipelineLayout;
  const VkResult r = g.vkd.vkCreateComputePipelines(g.device, VK_NULL_HANDLE, 1, &info, nullptr, &pipeline);
  g.vkd.vkDestroyShaderModule(g.device, module, nullptr);
  g.check(r, "vkCreateComputePipelines");

  const VkDescriptorPoolSize sizes[] = {{VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1},
                                        {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, wordBindings + 2}};
  VkDescriptorPoolCreateInfo poolInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  poolInfo.maxSets = 1;
  poolInfo.poolSizeCount = 2;
  poolInfo.pPoolSizes = sizes;
  g.check(g.vkd.vkCreateDescriptorPool(g.device, &poolInfo, nullptr, &pool), "vkCreateDescriptorPool");
  VkDescriptorSetAllocateInfo alloc{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  alloc.descriptorPool = pool;
  alloc.descriptorSetCount = 1;
  alloc.pSetLayouts = &setLayout;
  g.check(g.vkd.vkAllocateDescriptorSets(g.device, &alloc, &set), "vkAllocateDescriptorSets");

  writeDescriptor(kMappingBinding, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, mapping.buffer, 0, sizeof(MappingBlock));
  // Binding k views words [k * wordsPerBinding, ...) of the one buffer; bindings past the
  // array's end (the 8-binding variant) view its last range and are never read.
  for (uint32_t k = 0; k < wordBindings; ++k) {
    const uint64_t part = std::min(k, bindings - 1);
    const VkDeviceSize offset = part * wordsPerBinding * 4;
    writeStorage(kFirstWordBinding + k, words.buffer, offset, std::min<VkDeviceSize>(words.size - offset, g.bindingLimit));
  }
  if (g.timestampBits != 0) {
    VkQueryPoolCreateInfo q{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    q.queryType = VK_QUERY_TYPE_TIMESTAMP;
    q.queryCount = 2;
    g.check(g.vkd.vkCreateQueryPool(g.device, &q, nullptr, &timestamps), "vkCreateQueryPool");
  }
}

void GpuShadows::Impl::writeDescriptor(uint32_t binding, VkDescriptorType type, VkBuffer buffer, VkDeviceSize offset,
                                       VkDeviceSize range) {
  VkDescriptorBufferInfo info{buffer, offset, range};
  VkWriteDescriptorSet write{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
  write.dstSet = set;
  write.dstBinding = binding;
  write.descriptorCount = 1;
  write.descriptorType = type;
  write.pBufferInfo = &info;
  g.vkd.vkUpdateDescriptorSets(g.device, 1, &write, 0, nullptr);
}

void GpuShadows::Impl::ensureCapacity(uint64_t n) {
  if (n <= capacity) return;
  for (VulkanBuffer* b : {&queries, &answers, &staging}) g.destroy(*b);
  capacity = 0;
  const VkDeviceSize queryBytes = n * kQueryDoubles * 8, answerBytes = n * 4;
  queries = g.createBuffer(queryBytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, false);
  answers = g.createBuffer(answerBytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, false);
  staging = g.createBuffer(queryBytes + answerBytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  writeStorage(kQueryBinding, queries.buffer, 0, queryBytes);
  writeStorage(kAnswerBinding, answers.buffer, 0, answerBytes);
  capacity = n;
}

GpuShadows::GpuShadows(GpuDevice& device, std::shared_ptr<const ShadowArtifact> artifact)
    : impl_(std::make_unique<Impl>(device.impl(), std::move(artifact))) {
  if (!impl_->artifact) throw RuntimeError(Status::InvalidArgument, "no artifact to upload");
  impl_->g.checkNotLost();
  impl_->upload();
  impl_->createPipeline();
}

GpuShadows::~GpuShadows() = default;

double GpuShadows::lastDeviceNanoseconds() const { return impl_->lastNs; }
int GpuShadows::wordBindings() const { return int(impl_->bindings); }
const ShadowArtifact& GpuShadows::artifact() const { return *impl_->artifact; }

void GpuShadows::litTexels(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
                           std::vector<uint32_t>& out) {
  Impl& s = *impl_;
  GpuDevice::Impl& g = s.g;
  try {
    checkPcfWidth(pcf);
  } catch (const InputError& e) {
    throw RuntimeError(Status::InvalidArgument, e.what());
  }
  if (!normals.empty() && normals.size() != points.size())
    throw RuntimeError(Status::InvalidArgument, std::to_string(normals.size()) + " normals for " + std::to_string(points.size()) + " points");
  g.checkNotLost();
  std::vector<uint32_t> result(points.size());
  const uint64_t maxBatch = std::min<uint64_t>(kMaxBatch, g.bindingLimit / (kQueryDoubles * 8));
  s.ensureCapacity(std::min<uint64_t>(std::max<uint64_t>(points.size(), 1), maxBatch));
  double deviceNs = 0;
  for (uint64_t first = 0; first < points.size(); first += maxBatch) {
    const uint64_t n = std::min<uint64_t>(maxBatch, points.size() - first);
    double* q = static_cast<double*>(s.staging.mapped);
    for (uint64_t i = 0; i < n; ++i) {
      const Vec3& p = points[first + i];
      const Vec3 nn = normals.empty() ? Vec3{} : normals[first + i];
      double* row = q + kQueryDoubles * i;
      row[0] = p.x, row[1] = p.y, row[2] = p.z, row[3] = nn.x, row[4] = nn.y, row[5] = nn.z;
    }
    const VkDeviceSize queryBytes = n * kQueryDoubles * 8, answerOffset = s.capacity * kQueryDoubles * 8;
    const uint64_t groups = (n + kGroupSize - 1) / kGroupSize;
    const uint32_t maxX = g.properties.limits.maxComputeWorkGroupCount[0];
    const BatchConstants constants{uint32_t(n), uint32_t(pcf), uint32_t(std::min<uint64_t>(groups, maxX))};
    const uint32_t groupsY = uint32_t((groups + constants.groupsX - 1) / constants.groupsX);
    g.submitAndWait([&](VkCommandBuffer cmd) {
      VkBufferCopy in{0, 0, queryBytes};
      g.vkd.vkCmdCopyBuffer(cmd, s.staging.buffer, s.queries.buffer, 1, &in);
      VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
      barrier.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
      barrier.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
      g.vkd.vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &barrier, 0,
                                 nullptr, 0, nullptr);
      if (s.timestamps) {
        g.vkd.vkCmdResetQueryPool(cmd, s.timestamps, 0, 2);
        g.vkd.vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, s.timestamps, 0);
      }
      g.vkd.vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.pipeline);
      g.vkd.vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, s.pipelineLayout, 0, 1, &s.set, 0, nullptr);
      g.vkd.vkCmdPushConstants(cmd, s.pipelineLayout, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof constants, &constants);
      if (groups > 0) g.vkd.vkCmdDispatch(cmd, constants.groupsX, groupsY, 1);
      if (s.timestamps) g.vkd.vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, s.timestamps, 1);
      barrier.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
      barrier.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
      g.vkd.vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &barrier, 0,
                                 nullptr, 0, nullptr);
      VkBufferCopy back{0, answerOffset, n * 4};
      g.vkd.vkCmdCopyBuffer(cmd, s.answers.buffer, s.staging.buffer, 1, &back);
      barrier.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
      barrier.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
      g.vkd.vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &barrier, 0, nullptr, 0,
                                 nullptr);
    });
    std::memcpy(result.data() + first, static_cast<const uint8_t*>(s.staging.mapped) + answerOffset, n * 4);
    if (s.timestamps) {
      uint64_t ticks[2] = {0, 0};
      if (g.vkd.vkGetQueryPoolResults(g.device, s.timestamps, 0, 2, sizeof ticks, ticks, 8,
                                      VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT) == VK_SUCCESS)
        deviceNs += double((ticks[1] - ticks[0]) & (g.timestampBits >= 64 ? ~uint64_t{0} : (uint64_t{1} << g.timestampBits) - 1)) *
                    double(g.properties.limits.timestampPeriod);
    }
  }
  s.lastNs = deviceNs;
  out = std::move(result);
}

}  // namespace cpvs::runtime
