// The arithmetic of a lookup from a world point to a voxel, and the constants it uses, in
// the one form that a CPU and a GPU evaluate to the same bits: additions, subtractions
// and multiplications of doubles in a fixed order (each correctly rounded, none fused),
// and a normal offset whose scale is built from integers with no rounding at all. The
// shader include (runtime/shaders) repeats these statements one for one; OrthoGrid's
// voxelFromWorld and offsetVoxel are made from them, so there is one definition.
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>

#include "cpvs/base/vec3.h"

namespace cpvs {

/// The constants of a grid's lookup: 18 doubles, the layout of the shader's uniform
/// block (std140 and std430 alike: doubles only, no vectors).
struct LookupMapping {
  double origin[3];  // world point at light coordinates (0, 0, 0)
  double u[3], v[3], dir[3];
  double offset[3];  // light coordinates of the voxel (0, 0, 0) corner: u0, v0, d0
  double scale[3];   // voxels per world unit along u, v and dir: cells / extent
};
static_assert(sizeof(LookupMapping) == 18 * 8, "the shader's uniform block is 18 doubles");

/// Light coordinates of `p` in voxels, unfloored. dot(q, axis) summed left to right.
inline Vec3 mappedVoxel(const LookupMapping& m, const Vec3& p) {
  const double qx = p.x - m.origin[0], qy = p.y - m.origin[1], qz = p.z - m.origin[2];
  const double a = qx * m.u[0] + qy * m.u[1] + qz * m.u[2];
  const double b = qx * m.v[0] + qy * m.v[1] + qz * m.v[2];
  const double c = qx * m.dir[0] + qy * m.dir[1] + qz * m.dir[2];
  return {(a - m.offset[0]) * m.scale[0], (b - m.offset[1]) * m.scale[1], (c - m.offset[2]) * m.scale[2]};
}

/// A world direction in voxel units.
inline Vec3 mappedDirection(const LookupMapping& m, const Vec3& n) {
  const double a = n.x * m.u[0] + n.y * m.u[1] + n.z * m.u[2];
  const double b = n.x * m.v[0] + n.y * m.v[1] + n.z * m.v[2];
  const double c = n.x * m.dir[0] + n.y * m.dir[1] + n.z * m.dir[2];
  return {a * m.scale[0], b * m.scale[1], c * m.scale[2]};
}

/// Bits of the mantissa that pick the reciprocal in normalOffsetScale.
constexpr int kRecipBits = 8;

/// ceil(2^24 / (256 + i)): 2^16 times an upper bound of 1 / f for every f in
/// [1 + i/256, 1 + (i+1)/256), exact in 17 bits.
constexpr uint32_t offsetReciprocal(uint32_t i) { return (uint32_t(1) << 24) / (256 + i) + ((uint32_t(1) << 24) % (256 + i) != 0); }

/// The factor s that moves a point by nv * s, so that the largest component of the
/// normal in voxels (m) moves by at least `voxels` and at most 0.4 % more: voxels times
/// a reciprocal of m rounded up, from a table indexed by m's top mantissa bits and m's
/// exponent. Every step is exact (a product of 4- and 17-bit integers, a power of two),
/// so every device gives the same bits. 0 (no offset) unless 2^-1000 <= m < 2^1000.
inline double normalOffsetScale(double m, double voxels) {
  if (!(m >= 0x1p-1000 && m < 0x1p1000)) return 0;
  const uint64_t bits = std::bit_cast<uint64_t>(m);
  const int exponent = int((bits >> 52) & 0x7FF) - 1023;
  const uint32_t index = uint32_t(bits >> (52 - kRecipBits)) & ((1u << kRecipBits) - 1);
  const double power = std::bit_cast<double>(uint64_t(1023 - 16 - exponent) << 52);  // 2^(-16 - exponent)
  return voxels * double(offsetReciprocal(index)) * power;
}

/// The largest component of `nv`, a normal in voxels, that the offset moves by its voxels:
/// x and y counted in units of 2^depthShift texels, z in slices. A grid with fewer depth
/// slices than texels (OrthoGrid::depthSlices) has slices 2^depthShift texels deep: its
/// lookups clear their own surface by as many slices as on a cubic grid of that depth,
/// and move that many times further across (0: a cubic grid, the voxels as they are).
/// Scaling by a power of two is exact, so every device picks the same component.
inline double offsetExtent(const Vec3& nv, int depthShift) {
  // The larger of two by one comparison (not fmax): a NaN takes the same branch everywhere.
  const double ax = std::ldexp(std::fabs(nv.x), -depthShift), ay = std::ldexp(std::fabs(nv.y), -depthShift);
  const double az = std::fabs(nv.z);
  const double axy = ax > ay ? ax : ay;
  return axy > az ? axy : az;
}

/// Voxel coordinates `c` moved along `nv`, a normal in voxels, so that nv's largest
/// component (offsetExtent) moves `voxels` (normalOffsetScale); `c` for a vanishing, huge
/// or NaN nv.
inline Vec3 offsetAlongNormal(const Vec3& c, const Vec3& nv, double voxels, int depthShift = 0) {
  const double s = normalOffsetScale(offsetExtent(nv, depthShift), voxels);
  if (s == 0) return c;
  return {c.x + nv.x * s, c.y + nv.y * s, c.z + nv.z * s};
}

/// The lookup point of a query at p with normal n, in voxels (unfloored): p moved along
/// n until its voxel lies `voxels` voxels further along n's largest voxel component
/// (offsetAlongNormal). A zero, non-finite or vanishing normal gives no offset.
inline Vec3 mappedLookup(const LookupMapping& m, const Vec3& p, const Vec3& n, double voxels, int depthShift = 0) {
  const Vec3 c = mappedVoxel(m, p);
  if (n == Vec3{}) return c;
  return offsetAlongNormal(c, mappedDirection(m, n), voxels, depthShift);
}

static_assert(offsetReciprocal(0) == 65536 && offsetReciprocal(255) == 32833);

}  // namespace cpvs
