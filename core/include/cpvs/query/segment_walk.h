// Walking a straight segment through a directional light's voxels, a homogeneous block at
// a time: the exact lit and shadowed stretches of the segment in the voxelization, for
// light scattered in a medium along a view ray (seed 002, NOTES §3.4 item 4).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "cpvs/base/error.h"
#include "cpvs/base/vec3.h"
#include "cpvs/dag/packed_dag.h"

namespace cpvs {

/// One stretch of a walked segment o + t (e - o), t in [t0, t1], with one value.
struct SegmentPiece {
  double t0, t1;
  bool shadowed;
  /// False for the stretches outside the grid: in front of it or beside it, lit.
  bool inGrid;
  /// The block it crosses (inGrid): its corner and size, 2^log2Side in x and y, 2^log2Depth
  /// in z, the last slice's blocks reaching on without end beyond the grid's far side.
  int64_t x, y, z;
  int log2Side, log2Depth;
};

/// The voxel that a walk along axis coordinate p + d t (d != 0) is in from time t on: k
/// with t in [tPlane(k), tPlane(k + 1)) going up, [tPlane(k + 1), tPlane(k)) going down,
/// where tPlane(k) = (k - p) / d. Every time the walk compares is one of those planes,
/// computed one way, so that two walks agree on every voxel boundary to the bit.
inline int64_t voxelOnAxisAt(double p, double d, double t) {
  auto plane = [&](int64_t k) { return (double(k) - p) / d; };
  int64_t k = int64_t(std::floor(p + d * t));
  if (d > 0) {
    while (plane(k + 1) <= t) ++k;
    while (plane(k) > t) --k;
  } else {
    while (plane(k) <= t) --k;
    while (plane(k + 1) > t) ++k;
  }
  return k;
}

/// Walks the segment from voxel coordinates o to e (a directional light's grid, where a
/// world segment stays straight) through the DAG and calls visit(SegmentPiece) for each
/// stretch in order, from t = 0 to t = 1 without gaps: a whole homogeneous block at a time
/// (a pointer-grid cell, a lit or shadowed child at any level), voxel by voxel only inside
/// a leaf slice, whose mask it reads once. The grid's rules for the outside are ShadowQuery's:
/// in front of it (z < 0) and beside it in x or y lit, beyond its far side its last slice.
/// Pieces may be empty (t0 == t1) where the segment passes an edge or a corner.
template <class Visit>
void walkSegment(const PackedDag& dag, const Vec3& o, const Vec3& e, Visit&& visit) {
  const int64_t R = int64_t(1) << dag.log2Resolution();
  const double inf = std::numeric_limits<double>::infinity();
  const double p[3] = {o.x, o.y, o.z}, d[3] = {e.x - o.x, e.y - o.y, e.z - o.z};
  // The part of the segment in x, y in [0, R) and z >= 0: the grid and what lies behind it.
  const double lo[3] = {0, 0, 0}, hi[3] = {double(R), double(R), inf};
  double tIn = 0, tOut = 1;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0) {
      if (!(p[a] >= lo[a] && p[a] < hi[a])) tOut = -1;
      continue;
    }
    double t0 = (lo[a] - p[a]) / d[a], t1 = (hi[a] - p[a]) / d[a];
    if (d[a] < 0) std::swap(t0, t1);
    tIn = std::max(tIn, t0);
    tOut = std::min(tOut, t1);
  }
  if (!(tIn < tOut)) {
    visit(SegmentPiece{0, 1, false, false, 0, 0, 0, 0, 0});
    return;
  }
  if (tIn > 0) visit(SegmentPiece{0, tIn, false, false, 0, 0, 0, 0, 0});

  int64_t v[3];
  for (int a = 0; a < 3; ++a) v[a] = d[a] == 0 ? int64_t(std::floor(p[a])) : voxelOnAxisAt(p[a], d[a], tIn);
  v[0] = std::clamp<int64_t>(v[0], 0, R - 1);
  v[1] = std::clamp<int64_t>(v[1], 0, R - 1);
  v[2] = std::max<int64_t>(v[2], 0);
  // The leaf slice last read: the walk crosses its 64 voxels without walking down again.
  int64_t leafX = -1, leafY = -1, leafZ = -1;
  uint64_t leafMask = 0;
  double t = tIn;
  // Each step leaves a block through one of its faces, and a block has a face per axis
  // and direction: no more steps than planes the segment can cross.
  const int64_t maxSteps = 3 * (R + 2);
  for (int64_t step = 0;; ++step) {
    CPVS_CHECK(step < maxSteps);
    const int64_t qz = std::min(v[2], R - 1);
    bool shadowed;
    int log2Side = 0, log2Depth = 0;
    if ((v[0] >> 3) == leafX && (v[1] >> 3) == leafY && qz == leafZ) {
      shadowed = (leafMask >> leafBit(uint64_t(v[0]), uint64_t(v[1]))) & 1;
    } else {
      const PackedDag::Block b = dag.block(uint64_t(v[0]), uint64_t(v[1]), uint64_t(qz));
      shadowed = (b.mask >> leafBit(uint64_t(v[0]), uint64_t(v[1]))) & 1;
      if (b.homogeneous) {
        log2Side = b.log2Side;
        log2Depth = b.log2Depth;
      } else {
        leafX = v[0] >> 3, leafY = v[1] >> 3, leafZ = qz, leafMask = b.mask;
      }
    }
    const int64_t side = int64_t(1) << log2Side, depth = int64_t(1) << log2Depth;
    const int64_t bx = v[0] & ~(side - 1), by = v[1] & ~(side - 1), bz = qz & ~(depth - 1);
    const double blo[3] = {double(bx), double(by), double(bz)};
    const double bhi[3] = {double(bx + side), double(by + side), bz + depth == R ? inf : double(bz + depth)};
    double tExit = tOut;
    int axis = -1;
    for (int a = 0; a < 3; ++a) {
      if (d[a] == 0 || (d[a] > 0 && bhi[a] == inf)) continue;
      const double ta = ((d[a] > 0 ? bhi[a] : blo[a]) - p[a]) / d[a];
      if (ta < tExit) tExit = ta, axis = a;
    }
    visit(SegmentPiece{t, std::max(t, tExit), shadowed, true, bx, by, bz, log2Side, log2Depth});
    if (axis < 0) break;
    t = std::max(t, tExit);
    for (int a = 0; a < 3; ++a)
      if (d[a] != 0) v[a] = voxelOnAxisAt(p[a], d[a], t);
  }
  if (tOut < 1) visit(SegmentPiece{tOut, 1, false, false, 0, 0, 0, 0, 0});
}

}  // namespace cpvs
