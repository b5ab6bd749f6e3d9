// The query shaders' SPIR-V, compiled at build time by glslc from cpvs_query.comp (an
// artifact's lookups), cpvs_light_query.comp (a light bundle's), cpvs_segment_query.comp
// (segments through the sun's grid), cpvs_caster_query.comp (an artifact's lookups with
// dynamic casters) and cpvs_caster_build.comp (their tree built on the device) and embedded. Private to runtime.
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
/// A light bundle's lookups, its pool in one binding or split across up to 8.
SpirvCode lightQueryShaderOneBuffer();
SpirvCode lightQueryShaderEightBuffers();
/// Segments through the sun's grid (cpvs_segment_query.comp).
SpirvCode segmentShaderOneBuffer();
SpirvCode segmentShaderEightBuffers();
/// An artifact's lookups times its dynamic casters' shadow (cpvs_caster_query.comp).
SpirvCode casterShaderOneBuffer();
SpirvCode casterShaderEightBuffers();
/// A light bundle's lookups times its dynamic casters' shadows (cpvs_light_query.comp
/// with CPVS_QUERY_CASTERS).
SpirvCode lightCasterShaderOneBuffer();
SpirvCode lightCasterShaderEightBuffers();
/// The transmittance of an artifact's translucent casters (cpvs_translucent_query.comp).
SpirvCode translucentShaderOneBuffer();
SpirvCode translucentShaderEightBuffers();
/// An artifact's lookups, with and without dynamic casters, on a DAG-MH's words
/// (cpvs_query.comp and cpvs_caster_query.comp with CPVS_DAG_MH).
SpirvCode dagMhQueryShaderOneBuffer();
SpirvCode dagMhQueryShaderEightBuffers();
SpirvCode dagMhCasterShaderOneBuffer();
SpirvCode dagMhCasterShaderEightBuffers();
/// Dynamic casters' tree inserted on the device (cpvs_caster_build.comp); reads no words.
SpirvCode casterBuildShader();

}  // namespace cpvs::runtime
