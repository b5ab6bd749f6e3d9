// The query shader's SPIR-V, compiled at build time by glslc from cpvs_query.comp and
// embedded. Private to runtime.
#pragma once

#include <cstddef>
#include <cstdint>

namespace cpvs::runtime {

struct SpirvCode {
  const uint32_t* data;
  size_t words;
};

/// The words of the DAG in one storage binding.
SpirvCode queryShaderOneBuffer();
/// Split across up to 8 bindings.
SpirvCode queryShaderEightBuffers();

}  // namespace cpvs::runtime
