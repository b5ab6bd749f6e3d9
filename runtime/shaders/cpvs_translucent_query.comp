// The runtime library's transmittance of an artifact's translucent casters
// (cpvs_shadow.glsl's cpvsTranslucentTransmittance): per query, a status word (bit 31 set
// where the walk needed a deeper stack: the CPU answers those) and the light let
// through, red, green and blue, as float bits.
#version 450
#extension GL_GOOGLE_include_directive : require

#define CPVS_SET 0
#define CPVS_BINDING 0
#define CPVS_TRANSLUCENT
#define CPVS_TRANSLUCENT_BINDING 12
#define CPVS_CASTER_STACK 64
#include "cpvs_shadow.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 9, std430) readonly buffer Queries { double queries[]; };
layout(set = 0, binding = 10, std430) writeonly buffer Answers { uint answers[]; };

layout(push_constant) uniform Batch {
  uint count;    // queries in this dispatch
  uint pcf;      // unused
  uint groupsX;  // workgroups per row of the 2-D dispatch (maxComputeWorkGroupCount)
};

void main() {
  const uint i = (gl_WorkGroupID.y * groupsX + gl_WorkGroupID.x) * 64u + gl_LocalInvocationID.x;
  if (i >= count) return;
  const uint q = 6u * i;
  const dvec3 p = dvec3(queries[q], queries[q + 1u], queries[q + 2u]);
  const dvec3 n = dvec3(queries[q + 3u], queries[q + 4u], queries[q + 5u]);
  vec3 light;
  const uint status = cpvsTranslucentTransmittance(p, n, light);
  answers[4u * i] = status == CPVS_CASTER_OVERFLOW ? 0x80000000u : 0u;
  answers[4u * i + 1u] = floatBitsToUint(light.r);
  answers[4u * i + 2u] = floatBitsToUint(light.g);
  answers[4u * i + 3u] = floatBitsToUint(light.b);
}
