// The runtime library's batch query: one invocation per query point, the lookup of
// cpvs_shadow.glsl. Queries are 6 doubles (point, normal; a zero normal: no offset), the
// answer is the lit texel count of the pcf x pcf footprint.
#version 450
#extension GL_GOOGLE_include_directive : require

#define CPVS_SET 0
#define CPVS_BINDING 0
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
  answers[i] = cpvsLitTexels(p, n, pcf);
}
