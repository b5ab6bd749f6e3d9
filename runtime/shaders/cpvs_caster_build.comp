// Dynamic casters' TOP tree inserted on the device (seed 003 §3.6): one invocation per
// frustum of rank 1 .. n-1, its rank the query's first double (rank 0, node 1, is the root), each walking down from the root
// as TopTree::link classifies (its triangle's corners against a node's plane, in double,
// with the build's tolerance) until a child is free, which it takes with an atomic
// compare-and-swap; a shadow plane's wedge grows by an atomic max of its float bits. The
// frusta's planes and chains come from the host (TopTree::frusta), so the tree answers as
// the CPU's (the same frusta), though its shape depends on the order the device ran in.
// The sun's frusta only. Answers: the planes each invocation was classified against.
#version 450

layout(local_size_x = 64) in;

struct CpvsBuildNode {
  vec4 plane;
  uint pos, inter, neg;
  uint wedgeBits;  // a non-negative float's bits: ordered as the float
};
layout(set = 0, binding = 12, std430) coherent buffer CpvsCasters {
  dvec4 origin;
  vec4 light;
  float margin, relativeMargin;
  uint pad, root;
  CpvsBuildNode nodes[];
};
// The build's tolerance, a reserved double, then 10 doubles a frustum in rank order: its
// triangle's corners relative to the origin and its distance from a point light (unused).
layout(set = 0, binding = 13, std430) readonly buffer CpvsCorners { double corners[]; };
// Each query's first double is its frustum's rank (the batches of a large tree each start
// their invocations at 0).
layout(set = 0, binding = 9, std430) readonly buffer Queries { double queries[]; };
layout(set = 0, binding = 10, std430) writeonly buffer Answers { uint answers[]; };

layout(push_constant) uniform Batch {
  uint count;  // frusta to insert in this batch
  uint unused;
  uint groupsX;
};

void main() {
  const uint i = (gl_WorkGroupID.y * groupsX + gl_WorkGroupID.x) * 64u + gl_LocalInvocationID.x;
  if (i >= count) return;
  const uint rank = uint(queries[6u * i]), mine = 4u * rank + 1u;
  const double tolerance = corners[0];
  dvec3 v[3];
  for (uint k = 0u; k < 3u; ++k) {
    const uint c = 2u + 10u * rank + 3u * k;
    v[k] = dvec3(corners[c], corners[c + 1u], corners[c + 2u]);
  }
  uint node = 1u, steps = 0u;
  while (true) {
    ++steps;
    const vec4 p = nodes[node].plane;
    bool above = false, below = false;
    double farthest = 0.0lf;
    for (uint k = 0u; k < 3u; ++k) {
      precise double s = double(p.x) * v[k].x + double(p.y) * v[k].y + double(p.z) * v[k].z + double(p.w);
      above = above || s > tolerance;
      below = below || s < -tolerance;
      farthest = max(farthest, abs(s));
    }
    const bool capping = node % 4u == 0u;
    uint taken;
    if (above && !below) {
      taken = atomicCompSwap(nodes[node].pos, 0u, mine);
    } else if (below && !above) {
      if (!capping) {  // on along the frustum's chain: its next plane
        node = node + 1u;
        continue;
      }
      taken = atomicCompSwap(nodes[node].neg, 0u, mine);
    } else {
      if (!capping) atomicMax(nodes[node].wedgeBits, floatBitsToUint(float(farthest)) + 1u);
      taken = atomicCompSwap(nodes[node].inter, 0u, mine);
    }
    if (taken == 0u) break;
    node = taken;
  }
  answers[i] = steps;
}
