#include "query_kernel.h"

#include <algorithm>
#include <bit>
#include <cstring>
#include <string>

#include "cpvs/base/error.h"
#include "cpvs/query/normal_offset.h"

namespace cpvs::runtime {

namespace {

// Bindings of the query shaders (cpvs_query.comp, cpvs_light_query.comp): the sun's grid,
// the word buffers, the queries, the answers, each query's light; tables after them.
constexpr uint32_t kSunBinding = 0, kSunWordBinding = 1, kMaxWordBindings = 8, kQueryBinding = 9,
                   kAnswerBinding = 10, kQueryLightBinding = 11;
constexpr uint32_t kGroupSize = 64;
constexpr uint32_t kQueryDoubles = 6;
// Queries per dispatch at most (48 MiB of queries): bounded by the binding limit too.
constexpr uint64_t kMaxBatch = uint64_t(1) << 20;

// The shaders' push constants; the segment shader also reads the medium.
struct BatchConstants {
  uint32_t count, pcf, groupsX;
  float medium[3];
};

}  // namespace

void checkQueryShape(size_t points, size_t normals, int pcf) {
  try {
    checkPcfWidth(pcf);
  } catch (const InputError& e) {
    throw RuntimeError(Status::InvalidArgument, e.what());
  }
  if (normals != 0 && normals != points)
    throw RuntimeError(Status::InvalidArgument, std::to_string(normals) + " normals for " + std::to_string(points) + " points");
}

void checkSegmentShape(size_t starts, size_t ends, const Medium& medium) {
  if (starts != ends)
    throw RuntimeError(Status::InvalidArgument, std::to_string(starts) + " segment starts for " + std::to_string(ends) + " ends");
  try {
    checkMedium(medium);
  } catch (const InputError& e) {
    throw RuntimeError(Status::InvalidArgument, e.what());
  }
}

QueryKernel::QueryKernel(GpuDevice::Impl& device, const std::vector<uint32_t>& words, const GpuGrid& sun,
                         std::vector<Table> tables, const Shaders& shaders, const char* what)
    : g(device),
      tables_(std::move(tables)),
      queryLights_(shaders.queryLights),
      answerWords_(shaders.answerWords),
      firstWordBinding_(shaders.firstWordBinding) {
  try {
    upload(words, sun, what);
    createPipeline(shaders);
  } catch (...) {
    release();
    throw;
  }
}

QueryKernel::~QueryKernel() { release(); }

void QueryKernel::release() {
  if (!g.lost) g.vkd.vkDeviceWaitIdle(g.device);
  for (VulkanBuffer* b : {&words_, &sun_, &queries_, &answers_, &lights_, &staging_}) g.destroy(*b);
  for (VulkanBuffer& b : tableBuffers_) g.destroy(b);
  tableBuffers_.clear();
  if (timestamps_) g.vkd.vkDestroyQueryPool(g.device, timestamps_, nullptr);
  if (pool_) g.vkd.vkDestroyDescriptorPool(g.device, pool_, nullptr);
  if (pipeline_) g.vkd.vkDestroyPipeline(g.device, pipeline_, nullptr);
  if (pipelineLayout_) g.vkd.vkDestroyPipelineLayout(g.device, pipelineLayout_, nullptr);
  if (setLayout_) g.vkd.vkDestroyDescriptorSetLayout(g.device, setLayout_, nullptr);
  timestamps_ = VK_NULL_HANDLE, pool_ = VK_NULL_HANDLE, pipeline_ = VK_NULL_HANDLE;
  pipelineLayout_ = VK_NULL_HANDLE, setLayout_ = VK_NULL_HANDLE;
}

VulkanBuffer QueryKernel::uploadToDevice(const void* data, uint64_t bytes) {
  // A source of copies too: a table another kernel wrote (copyTable).
  VulkanBuffer target = g.createBuffer(
      bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, false);
  VulkanBuffer stage{};
  try {
    stage = g.createBuffer(bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true);
    std::memcpy(stage.mapped, data, bytes);
    g.submitAndWait([&](VkCommandBuffer cmd) {
      VkBufferCopy region{0, 0, bytes};
      g.vkd.vkCmdCopyBuffer(cmd, stage.buffer, target.buffer, 1, &region);
    });
  } catch (...) {
    g.destroy(stage);
    g.destroy(target);
    throw;
  }
  g.destroy(stage);
  return target;
}

void QueryKernel::upload(const std::vector<uint32_t>& w, const GpuGrid& sun, const char* what) {
  const uint64_t bytes = uint64_t(w.size()) * 4;
  wordsPerBinding_ = g.bindingLimit / 4;
  bindings_ = uint32_t((bytes + g.bindingLimit - 1) / g.bindingLimit);
  if (bindings_ > kMaxWordBindings)
    throw RuntimeError(Status::OutOfMemory, std::string(what) + "'s " + std::to_string(bytes) + " bytes need " +
                                                std::to_string(bindings_) + " storage bindings of " +
                                                std::to_string(g.bindingLimit) + " bytes; the query shader has " +
                                                std::to_string(kMaxWordBindings));
  if (bindings_ > 1 && g.bindingLimit % g.properties.limits.minStorageBufferOffsetAlignment != 0)
    throw RuntimeError(Status::Internal, "the binding size is not a multiple of the device's storage offset alignment");
  for (const Table& t : tables_)
    if (t.bytes.size() > g.bindingLimit)
      throw RuntimeError(Status::OutOfMemory, std::string(what) + "'s table of " + std::to_string(t.bytes.size()) +
                                                  " bytes exceeds the device's storage binding limit of " +
                                                  std::to_string(g.bindingLimit));
  words_ = uploadToDevice(w.data(), bytes);
  for (Table& t : tables_) {
    tableBuffers_.push_back(uploadToDevice(t.bytes.data(), t.bytes.size()));
    t.bytes = {};  // the device holds them now
  }
  sun_ = g.createBuffer(sizeof(SunBlock), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true);
  SunBlock block{};
  block.grid = sun;
  block.log2BufferWords = uint32_t(std::countr_zero(wordsPerBinding_));
  std::memcpy(sun_.mapped, &block, sizeof block);
}

void QueryKernel::createPipeline(const Shaders& shaders) {
  std::vector<VkDescriptorSetLayoutBinding> layout;
  auto add = [&](uint32_t binding, VkDescriptorType type) {
    layout.push_back({binding, type, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
  };
  add(kSunBinding, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER);
  const uint32_t wordBindings = bindings_ == 1 ? 1 : kMaxWordBindings;  // the shader variant's
  for (uint32_t k = 0; k < wordBindings; ++k) add(firstWordBinding_ + k, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
  // A light bundle's shader declares the sun's first word buffer too (the include reads
  // either): bound to the pool's first range, never read.
  const bool bindsSunWords = firstWordBinding_ != kSunWordBinding;
  if (bindsSunWords) add(kSunWordBinding, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
  add(kQueryBinding, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
  add(kAnswerBinding, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
  if (queryLights_) add(kQueryLightBinding, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
  for (const Table& t : tables_) add(t.binding, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
  const uint32_t storage = uint32_t(layout.size()) - 1;
  VkDescriptorSetLayoutCreateInfo setInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  setInfo.bindingCount = uint32_t(layout.size());
  setInfo.pBindings = layout.data();
  g.check(g.vkd.vkCreateDescriptorSetLayout(g.device, &setInfo, nullptr, &setLayout_), "vkCreateDescriptorSetLayout");
  VkPushConstantRange push{VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(BatchConstants)};
  VkPipelineLayoutCreateInfo pipeInfo{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  pipeInfo.setLayoutCount = 1;
  pipeInfo.pSetLayouts = &setLayout_;
  pipeInfo.pushConstantRangeCount = 1;
  pipeInfo.pPushConstantRanges = &push;
  g.check(g.vkd.vkCreatePipelineLayout(g.device, &pipeInfo, nullptr, &pipelineLayout_), "vkCreatePipelineLayout");

  const SpirvCode code = bindings_ == 1 ? shaders.oneBuffer : shaders.eightBuffers;
  VkShaderModuleCreateInfo moduleInfo{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  moduleInfo.codeSize = code.words * 4;
  moduleInfo.pCode = code.data;
  VkShaderModule module;
  g.check(g.vkd.vkCreateShaderModule(g.device, &moduleInfo, nullptr, &module), "vkCreateShaderModule");
  VkComputePipelineCreateInfo info{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  info.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO, nullptr, 0, VK_SHADER_STAGE_COMPUTE_BIT, module, "main", nullptr};
  info.layout = pipelineLayout_;
  const VkResult r = g.vkd.vkCreateComputePipelines(g.device, VK_NULL_HANDLE, 1, &info, nullptr, &pipeline_);
  g.vkd.vkDestroyShaderModule(g.device, module, nullptr);
  g.check(r, "vkCreateComputePipelines");

  const VkDescriptorPoolSize sizes[] = {{VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1}, {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, storage}};
  VkDescriptorPoolCreateInfo poolInfo{VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
  poolInfo.maxSets = 1;
  poolInfo.poolSizeCount = 2;
  poolInfo.pPoolSizes = sizes;
  g.check(g.vkd.vkCreateDescriptorPool(g.device, &poolInfo, nullptr, &pool_), "vkCreateDescriptorPool");
  VkDescriptorSetAllocateInfo alloc{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
  alloc.descriptorPool = pool_;
  alloc.descriptorSetCount = 1;
  alloc.pSetLayouts = &setLayout_;
  g.check(g.vkd.vkAllocateDescriptorSets(g.device, &alloc, &set_), "vkAllocateDescriptorSets");

  writeDescriptor(kSunBinding, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, sun_.buffer, 0, sizeof(SunBlock));
  // Binding k views words [k * wordsPerBinding, ...) of the one buffer; bindings past the
  // array's end (the 8-binding variant) view its last range and are never read.
  for (uint32_t k = 0; k < wordBindings; ++k) {
    const uint64_t part = std::min(k, bindings_ - 1);
    const VkDeviceSize offset = part * wordsPerBinding_ * 4;
    writeStorage(firstWordBinding_ + k, words_.buffer, offset, std::min<VkDeviceSize>(words_.size - offset, g.bindingLimit));
  }
  if (bindsSunWords) writeStorage(kSunWordBinding, words_.buffer, 0, std::min<VkDeviceSize>(words_.size, g.bindingLimit));
  for (size_t i = 0; i < tables_.size(); ++i)
    writeStorage(tables_[i].binding, tableBuffers_[i].buffer, 0, tableBuffers_[i].size);
  if (g.timestampBits != 0) {
    VkQueryPoolCreateInfo q{VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO};
    q.queryType = VK_QUERY_TYPE_TIMESTAMP;
    q.queryCount = 2;
    g.check(g.vkd.vkCreateQueryPool(g.device, &q, nullptr, &timestamps_), "vkCreateQueryPool");
  }
}

size_t QueryKernel::tableIndex(uint32_t binding) const {
  size_t i = 0;
  while (i < tables_.size() && tables_[i].binding != binding) ++i;
  CPVS_CHECK(i < tables_.size());
  return i;
}

void QueryKernel::copyTable(uint32_t binding, const QueryKernel& from) {
  g.checkNotLost();
  const VulkanBuffer& source = from.tableBuffers_[from.tableIndex(binding)];
  const size_t i = tableIndex(binding);
  VulkanBuffer fresh = g.createBuffer(
      source.size, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, false);
  try {
    g.submitAndWait([&](VkCommandBuffer cmd) {
      VkBufferCopy region{0, 0, source.size};
      g.vkd.vkCmdCopyBuffer(cmd, source.buffer, fresh.buffer, 1, &region);
    });
  } catch (...) {
    g.destroy(fresh);
    throw;
  }
  g.destroy(tableBuffers_[i]);
  tableBuffers_[i] = fresh;
  writeStorage(binding, fresh.buffer, 0, fresh.size);
}

void QueryKernel::replaceTable(uint32_t binding, const std::vector<uint8_t>& bytes) {
  g.checkNotLost();
  const size_t i = tableIndex(binding);
  if (bytes.size() > g.bindingLimit)
    throw RuntimeError(Status::OutOfMemory, "a table of " + std::to_string(bytes.size()) +
                                                " bytes exceeds the device's storage binding limit of " +
                                                std::to_string(g.bindingLimit));
  // Every run waits for its work, so nothing reads the old buffer now.
  VulkanBuffer fresh = uploadToDevice(bytes.data(), bytes.size());
  g.destroy(tableBuffers_[i]);
  tableBuffers_[i] = fresh;
  writeStorage(binding, fresh.buffer, 0, fresh.size);
}

void QueryKernel::writeDescriptor(uint32_t binding, VkDescriptorType type, VkBuffer buffer, VkDeviceSize offset,
                                  VkDeviceSize range) {
  VkDescriptorBufferInfo info{buffer, offset, range};
  VkWriteDescriptorSet write{VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
  write.dstSet = set_;
  write.dstBinding = binding;
  write.descriptorCount = 1;
  write.descriptorType = type;
  write.pBufferInfo = &info;
  g.vkd.vkUpdateDescriptorSets(g.device, 1, &write, 0, nullptr);
}

void QueryKernel::ensureCapacity(uint64_t n) {
  if (n <= capacity_) return;
  for (VulkanBuffer* b : {&queries_, &answers_, &lights_, &staging_}) g.destroy(*b);
  capacity_ = 0;
  const VkDeviceSize queryBytes = n * kQueryDoubles * 8, answerBytes = n * 4 * answerWords_, lightBytes = queryLights_ ? n * 4 : 0;
  queries_ = g.createBuffer(queryBytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, false);
  answers_ = g.createBuffer(answerBytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT, false);
  if (queryLights_)
    lights_ = g.createBuffer(lightBytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, false);
  // Staging: the queries, the answers, then the queries' lights.
  staging_ = g.createBuffer(queryBytes + answerBytes + lightBytes,
                            VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  writeStorage(kQueryBinding, queries_.buffer, 0, queryBytes);
  writeStorage(kAnswerBinding, answers_.buffer, 0, answerBytes);
  if (queryLights_) writeStorage(kQueryLightBinding, lights_.buffer, 0, lightBytes);
  capacity_ = n;
}

void QueryKernel::run(const std::vector<Vec3>& points, const std::vector<Vec3>& normals,
                      const std::vector<uint32_t>& lights, int pcf, std::vector<uint32_t>& out,
                      const float medium[3]) {
  g.checkNotLost();
  std::vector<uint32_t> result(points.size() * answerWords_);
  const uint64_t maxBatch = std::min<uint64_t>(kMaxBatch, g.bindingLimit / (kQueryDoubles * 8));
  ensureCapacity(std::min<uint64_t>(std::max<uint64_t>(points.size(), 1), maxBatch));
  double deviceNs = 0;
  for (uint64_t first = 0; first < points.size(); first += maxBatch) {
    const uint64_t n = std::min<uint64_t>(maxBatch, points.size() - first);
    double* q = static_cast<double*>(staging_.mapped);
    for (uint64_t i = 0; i < n; ++i) {
      const Vec3& p = points[first + i];
      const Vec3 nn = normals.empty() ? Vec3{} : normals[first + i];
      double* row = q + kQueryDoubles * i;
      row[0] = p.x, row[1] = p.y, row[2] = p.z, row[3] = nn.x, row[4] = nn.y, row[5] = nn.z;
    }
    const VkDeviceSize queryBytes = n * kQueryDoubles * 8, answerOffset = capacity_ * kQueryDoubles * 8,
                       lightOffset = answerOffset + capacity_ * 4 * answerWords_;
    if (queryLights_)
      std::memcpy(static_cast<uint8_t*>(staging_.mapped) + lightOffset, lights.data() + first, n * 4);
    const uint64_t groups = (n + kGroupSize - 1) / kGroupSize;
    const uint32_t maxX = g.properties.limits.maxComputeWorkGroupCount[0];
    const BatchConstants constants{uint32_t(n), uint32_t(pcf), uint32_t(std::min<uint64_t>(groups, maxX)),
                                   {medium ? medium[0] : 0.0f, medium ? medium[1] : 0.0f, medium ? medium[2] : 0.0f}};
    const uint32_t groupsY = uint32_t((groups + constants.groupsX - 1) / constants.groupsX);
    g.submitAndWait([&](VkCommandBuffer cmd) {
      VkBufferCopy in{0, 0, queryBytes};
      g.vkd.vkCmdCopyBuffer(cmd, staging_.buffer, queries_.buffer, 1, &in);
      if (queryLights_) {
        VkBufferCopy lightsIn{lightOffset, 0, n * 4};
        g.vkd.vkCmdCopyBuffer(cmd, staging_.buffer, lights_.buffer, 1, &lightsIn);
      }
      VkMemoryBarrier barrier{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
      barrier.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
      barrier.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
      g.vkd.vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &barrier, 0,
                                 nullptr, 0, nullptr);
      if (timestamps_) {
        g.vkd.vkCmdResetQueryPool(cmd, timestamps_, 0, 2);
        g.vkd.vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, timestamps_, 0);
      }
      g.vkd.vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline_);
      g.vkd.vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipelineLayout_, 0, 1, &set_, 0, nullptr);
      g.vkd.vkCmdPushConstants(cmd, pipelineLayout_, VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof constants, &constants);
      if (groups > 0) g.vkd.vkCmdDispatch(cmd, constants.groupsX, groupsY, 1);
      if (timestamps_) g.vkd.vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, timestamps_, 1);
      barrier.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
      barrier.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
      g.vkd.vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &barrier, 0,
                                 nullptr, 0, nullptr);
      VkBufferCopy back{0, answerOffset, n * 4 * answerWords_};
      g.vkd.vkCmdCopyBuffer(cmd, answers_.buffer, staging_.buffer, 1, &back);
      barrier.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
      barrier.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
      g.vkd.vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &barrier, 0, nullptr, 0,
                                 nullptr);
    });
    std::memcpy(result.data() + first * answerWords_, static_cast<const uint8_t*>(staging_.mapped) + answerOffset,
                n * 4 * answerWords_);
    if (timestamps_) {
      uint64_t ticks[2] = {0, 0};
      if (g.vkd.vkGetQueryPoolResults(g.device, timestamps_, 0, 2, sizeof ticks, ticks, 8,
                                      VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT) == VK_SUCCESS)
        deviceNs += double((ticks[1] - ticks[0]) & (g.timestampBits >= 64 ? ~uint64_t{0} : (uint64_t{1} << g.timestampBits) - 1)) *
                    double(g.properties.limits.timestampPeriod);
    }
  }
  lastNs_ = deviceNs;
  out = std::move(result);
}

}  // namespace cpvs::runtime
