// The mapping between the world and a light's voxel grid: the one interface through
// which the bake, the queries and the baselines go from one space to the other.
#pragma once

#include <cstdint>

#include "cpvs/base/vec3.h"

namespace cpvs {

/// The ray through the centre of a texel, from the grid's near end: origin (relative to
/// the point the caller names), unit direction, and the length that crosses the grid.
struct TexelRay {
  Vec3 origin, dir;
  double tMax = 0;
};

/// A light's R x R x R voxel grid (R = 2^log2Resolution, or the side a baseline map
/// chose). x, y index the texel, z the depth slice; voxel (i, j, k) spans [i, i+1) x
/// [j, j+1) x [k, k+1) in continuous voxel coordinates. Depth is the parameter of a
/// texel's ray from its origin: the distance for OrthoGrid (a directional light), the view
/// depth for PerspectiveGrid (a spot light).
class LightGrid {
 public:
  virtual ~LightGrid() = default;

  /// Texels (and slices) a side.
  virtual uint64_t side() const = 0;
  /// Continuous voxel coordinates of a world point.
  virtual Vec3 voxelFromWorld(const Vec3& world) const = 0;
  /// World position of continuous voxel coordinates.
  virtual Vec3 worldFromVoxel(const Vec3& voxel) const = 0;
  /// The ray through the centre of texel (x, y), its origin relative to `relativeTo` (a
  /// ray tracer's local frame keeps float precision far from the world origin).
  virtual TexelRay texelRay(uint64_t x, uint64_t y, const Vec3& relativeTo) const = 0;
  /// The slice holding depth `t` along a texel's ray: floor of it in slices, clamped to
  /// [0, side()] (side() = behind the grid; NaN gives 0).
  virtual uint32_t sliceOfDepth(double t) const = 0;
  /// The depth of a world point along the light (the t of texelRay's ray through it).
  virtual double depthOf(const Vec3& world) const = 0;
  /// Continuous voxel coordinates of `world` moved along `normal` (need not be
  /// normalized) by `voxels`, measured in voxel space: the normal is scaled so that its
  /// largest voxel-space component moves that many voxels (up to 0.4 % more: the scale
  /// is exact on every device, lookup_mapping.h). A zero or non-finite normal gives
  /// voxelFromWorld(world). The normal offset every lookup applies.
  virtual Vec3 offsetVoxel(const Vec3& world, const Vec3& normal, double voxels) const = 0;
};

}  // namespace cpvs
