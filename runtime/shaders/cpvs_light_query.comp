// The runtime library's batch query of a light bundle: one invocation per query point,
// the lookup of cpvs_shadow.glsl's cpvsLightLitTexels. Queries are 6 doubles (point,
// normal; a zero normal: no offset) and the light's index; the answer is the lit texel
// count of the pcf x pcf footprint of that light's grid. Compiled a second time with
// CPVS_QUERY_CASTERS for dynamic casters: 0 where one shadows the point from that light
// (bit 31 set where the casters' walk needed a deeper stack: the CPU answers those). With
// pcf 0, a soft lookup: the light is an area light's first VPL and the answer the bits of
// cpvsSoftVisibility.
#version 450
#extension GL_GOOGLE_include_directive : require

#define CPVS_SET 0
#define CPVS_BINDING 0
#define CPVS_LIGHTS
#define CPVS_LIGHT_BINDING 12  // and the pool from 15
#ifdef CPVS_QUERY_CASTERS
#define CPVS_LIGHT_CASTERS
#define CPVS_LIGHT_CASTER_BINDING 23  // the trees' headers, then their nodes
#endif
#include "cpvs_shadow.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 9, std430) readonly buffer Queries { double queries[]; };
layout(set = 0, binding = 10, std430) writeonly buffer Answers { uint answers[]; };
layout(set = 0, binding = 11, std430) readonly buffer QueryLights { uint queryLights[]; };

layout(push_constant) uniform Batch {
  uint count;    // queries in this dispatch
  uint pcf;      // odd filter width; 0: soft visibility
  uint groupsX;  // workgroups per row of the 2-D dispatch (maxComputeWorkGroupCount)
};

void main() {
  const uint i = (gl_WorkGroupID.y * groupsX + gl_WorkGroupID.x) * 64u + gl_LocalInvocationID.x;
  if (i >= count) return;
  const uint q = 6u * i;
  const dvec3 p = dvec3(queries[q], queries[q + 1u], queries[q + 2u]);
  const dvec3 n = dvec3(queries[q + 3u], queries[q + 4u], queries[q + 5u]);
  const uint light = queryLights[i];
  if (pcf == 0u) {
    answers[i] = floatBitsToUint(cpvsSoftVisibility(light, p, n));
    return;
  }
#ifdef CPVS_QUERY_CASTERS
  const uint shadow = cpvsLightCasterShadow(light, p, n);
  if (shadow == CPVS_CASTER_SHADOWED) {
    answers[i] = 0u;
  } else {
    answers[i] = cpvsLightLitTexels(light, p, n, pcf) | (shadow == CPVS_CASTER_OVERFLOW ? 0x80000000u : 0u);
  }
#else
  answers[i] = cpvsLightLitTexels(light, p, n, pcf);
#endif
}
