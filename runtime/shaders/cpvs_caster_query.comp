// The runtime library's batch query with dynamic casters: cpvs_query.comp's lookup times
// the casters' shadow (cpvs_shadow.glsl's cpvsCasterShadow): 0 where a caster shadows the
// point, and bit 31 set where its walk needed a deeper stack (the CPU answers those).
#version 450
#extension GL_GOOGLE_include_directive : require

#define CPVS_SET 0
#define CPVS_BINDING 0
#define CPVS_CASTERS
#define CPVS_CASTER_BINDING 12
#include "cpvs_shadow.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 9, std430) readonly buffer Queries { double queries[]; };
layout(set = 0, binding = 10, std430) writeonly buffer Answers { uint answers[]; };

layout(push_constant) uniform Batch {
  uint count;    // queries in this dispatch
  uint pcf;      // odd filter width
  uint groupsX;  // workgroups per row of the 2-D dispatch (maxComputeWorkGroupCount)
};

void main() {
  const uint i = (gl_WorkGroupID.y * groupsX + gl_WorkGroupID.x) * 64u + gl_LocalInvocationID.x;
  if (i >= count) return;
  const uint q = 6u * i;
  const dvec3 p = dvec3(queries[q], queries[q + 1u], queries[q + 2u]);
  const dvec3 n = dvec3(queries[q + 3u], queries[q + 4u], queries[q + 5u]);
  const uint shadow = cpvsCasterShadow(p, n);
  if (shadow == CPVS_CASTER_SHADOWED) {
    answers[i] = 0u;
  } else {
    answers[i] = cpvsLitTexels(p, n, pcf) | (shadow == CPVS_CASTER_OVERFLOW ? 0x80000000u : 0u);
  }
}
