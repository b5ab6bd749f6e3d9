// The runtime library's batch of segments through the sun's grid: one invocation per
// segment, cpvs_shadow.glsl's walk. Queries are 6 doubles (from a, to b); each answer is
// 4 words: the lit fraction (a double, the CPU's to the bit), the sun light a medium
// scatters towards a (a float, per unit of sun irradiance), and a zero.
#version 450
#extension GL_GOOGLE_include_directive : require

#define CPVS_SET 0
#define CPVS_BINDING 0
#include "cpvs_shadow.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 9, std430) readonly buffer Queries { double queries[]; };
layout(set = 0, binding = 10, std430) writeonly buffer Answers { uint answers[]; };

layout(push_constant) uniform Batch {
  uint count;    // segments in this dispatch
  uint pcf;      // unused
  uint groupsX;  // workgroups per row of the 2-D dispatch (maxComputeWorkGroupCount)
  float sigmaS, sigmaA, g;  // the medium
};

void main() {
  const uint i = (gl_WorkGroupID.y * groupsX + gl_WorkGroupID.x) * 64u + gl_LocalInvocationID.x;
  if (i >= count) return;
  const uint q = 6u * i;
  const dvec3 a = dvec3(queries[q], queries[q + 1u], queries[q + 2u]);
  const dvec3 b = dvec3(queries[q + 3u], queries[q + 4u], queries[q + 5u]);
  const uvec2 lit = unpackDouble2x32(cpvsSunLitFraction(a, b));
  answers[4u * i] = lit.x;
  answers[4u * i + 1u] = lit.y;
  answers[4u * i + 2u] = floatBitsToUint(cpvsSunInScattering(a, b, sigmaS, sigmaA, g));
  answers[4u * i + 3u] = 0u;
}
