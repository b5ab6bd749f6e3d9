// The voxel grid of a spot light: a perspective LightGrid whose depth slices are spaced
// logarithmically between near and far (seed 000 §5, eq. (1) as NOTES §1.2.2 repairs it).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cpvs/light/frame.h"
#include "cpvs/light/grid.h"

namespace cpvs {

class PerspectiveGrid;

/// A spot grid's texel rays and slices as a renderer's inner loop calls them (the
/// counterpart of OrthoGrid's TexelMapping): rays relative to `relativeTo`.
class SpotTexelMapping {
 public:
  SpotTexelMapping(const PerspectiveGrid& grid, const Vec3& relativeTo) : grid_(&grid), relativeTo_(relativeTo) {}
  TexelRay ray(uint64_t x, uint64_t y) const;
  uint32_t slice(double zv) const;
  uint32_t side() const;

 private:
  const PerspectiveGrid* grid_;
  Vec3 relativeTo_;
};

/// A spot light's R x R x R grid (R = 2^log2Resolution). The light sits at `position` and
/// looks along `frame.dir`; at view depth zv = dot(p - position, dir) the frustum is the
/// square [-t·zv, t·zv]² in (u, v), t = tan(fov / 2), cut into R x R texels, so texel (x, y)
/// is a pyramid from the light. Slice k holds the view depths [B[k], B[k+1]) of one table,
/// B[k] = near · (far / near)^(k / R) with B[0] = near and B[R] = far exactly: a voxel's
/// depth over its width is the same everywhere in the frustum.
///
/// Depth, for this grid, is the view depth zv. Texel rays run at unit speed along `dir`
/// (their direction is not a unit vector), so a ray's parameter is the depth the slices
/// cut. Every coordinate comes from the one table: the slice of a depth (sliceOfDepth),
/// the continuous voxel z of a point (voxelFromWorld: linear in zv within its slice) and
/// its inverse, so a surface and a lookup on it land in the same slice.
///
/// Points not in front of the light (zv <= 0, or NaN) have NaN voxel coordinates: no
/// light reaches them. Points between the light and `near` have z < 0 (in front of the
/// grid), points beyond `far` z >= R (behind it).
class PerspectiveGrid final : public LightGrid {
 public:
  /// Throws InputError naming what is wrong: a non-finite position, a frame that is not
  /// orthonormal, tanHalfFov outside (0, tan 85°], near not in (0, far), far not finite,
  /// a resolution outside [kMinLog2Resolution, kMaxLog2Resolution], or a depth range so
  /// thin that two slice boundaries coincide.
  PerspectiveGrid(const Vec3& position, const LightFrame& frame, double tanHalfFov, double near, double far,
                  int log2Resolution);

  const Vec3& position() const { return position_; }
  const LightFrame& frame() const { return frame_; }
  double tanHalfFov() const { return tanHalfFov_; }
  double near() const { return near_; }
  double far() const { return far_; }
  int log2Resolution() const { return log2Resolution_; }
  uint64_t resolution() const { return uint64_t(1) << log2Resolution_; }
  /// The view depth where slice k begins, k in [0, R] (B[R] = far).
  double sliceBoundary(uint64_t k) const { return (*boundaries_)[k]; }
  /// The whole table B[0..R], for a vectorized sliceOfDepth that estimates k by eq. (1)
  /// and lets the table decide.
  const double* sliceBoundaries() const { return boundaries_->data(); }
  /// R / ln(far / near): eq. (1)'s slices per unit of ln(zv / near).
  double slicesPerLog() const { return double(resolution()) / logRatio_; }
  /// ln(far / near).
  double logRatio() const { return logRatio_; }

  uint64_t side() const override { return resolution(); }
  Vec3 voxelFromWorld(const Vec3& world) const override;
  Vec3 worldFromVoxel(const Vec3& voxel) const override;
  /// From the light (origin `position - relativeTo`) through the texel's centre, dir with
  /// dot(dir, frame.dir) = 1, tMax a hair beyond far.
  TexelRay texelRay(uint64_t x, uint64_t y, const Vec3& relativeTo) const override;
  /// The slice of view depth `zv`: k with B[k] <= zv < B[k+1]; 0 for zv < near (geometry
  /// between the light and near shadows its whole column) and NaN; R for zv >= far.
  uint32_t sliceOfDepth(double zv) const override;
  double depthOf(const Vec3& world) const override;
  /// voxelFromWorld(world) moved along the surface's normal as voxel space sees it at
  /// `world` (normalToVoxel), so that its largest component moves `voxels` voxels (the
  /// scale OrthoGrid uses). The voxel then lies in front of the surface's plane wherever
  /// it is in the frustum.
  Vec3 offsetVoxel(const Vec3& world, const Vec3& normal, double voxels) const override;
  /// The Jacobian J of voxelFromWorld at `world` applied to `worldDir`: voxels per world
  /// unit along each voxel axis. NaN where voxelFromWorld is.
  Vec3 directionToVoxel(const Vec3& world, const Vec3& worldDir) const;
  /// The normal, in voxel space, of the plane through `world` with normal `normal`: J^-T
  /// times it. Not J times it (the image of the normal as a direction), which leans off
  /// the plane's normal when voxels are much deeper than wide (3.5 to 9 times here) and
  /// would leave a voxel offset along it behind the plane.
  Vec3 normalToVoxel(const Vec3& world, const Vec3& normal) const;
  /// Whether no point of texel (x, y) is within the cone of half-angle atan(tanCone)
  /// around the axis: no light falls on any of its voxels.
  bool coneMissesTexel(uint64_t x, uint64_t y, double tanCone) const { return coneMissesTexels(x, y, 1, 1, tanCone); }
  /// Whether the world point lies inside the cone (in front of the light, at most
  /// atan(tanCone) from its axis).
  bool insideCone(const Vec3& world, double tanCone) const;
  /// Whether it misses every texel of [x0, x0 + width) x [y0, y0 + height).
  bool coneMissesTexels(uint64_t x0, uint64_t y0, uint64_t width, uint64_t height, double tanCone) const;
  /// The texel rays and slices for an inner loop (rays relative to `relativeTo`); the grid
  /// must outlive it.
  SpotTexelMapping texelMapping(const Vec3& relativeTo) const { return SpotTexelMapping(*this, relativeTo); }

  /// The continuous voxel z of view depth zv (linear within each slice, extended
  /// linearly beyond near and far; increasing), and its inverse.
  double voxelZ(double zv) const;
  /// The same, the slice found from `hint` (a nearby depth's slice), which it updates:
  /// for many depths in order.
  double voxelZ(double zv, uint32_t& hint) const;
  double depthOfVoxelZ(double z) const;

 private:
  /// The image-plane coordinate (at unit depth) of continuous texel coordinate x. 2 / R is
  /// a power of two: exact before the one multiplication by t, for any texel of any tile.
  double planeCoordinate(double x) const { return (x * (2.0 / double(resolution())) - 1) * tanHalfFov_; }
  /// What the Jacobian at a point needs: the point from the light, its view depth, the
  /// texels and the slices per world unit there.
  struct Local {
    Vec3 q;
    double zv, texelsPerUnit, slicesPerUnit;
  };
  Local localAt(const Vec3& world) const;

  Vec3 position_;
  LightFrame frame_;
  double tanHalfFov_, near_, far_;
  int log2Resolution_;
  double logRatio_;  // ln(far / near)
  std::shared_ptr<const std::vector<double>> boundaries_;  // B[0..R], shared by copies
};

inline bool PerspectiveGrid::coneMissesTexels(uint64_t x0, uint64_t y0, uint64_t width, uint64_t height,
                                               double tanCone) const {
  // The texels' rectangle on the image plane at unit depth, and its point nearest the
  // axis (inline: the rasterizer asks per 8x8 block).
  auto nearest = [&](uint64_t i, uint64_t n) {
    const double lo = planeCoordinate(double(i)), hi = planeCoordinate(double(i + n));
    return lo > 0 ? lo : hi < 0 ? hi : 0.0;
  };
  const double a = nearest(x0, width), b = nearest(y0, height);
  return a * a + b * b > tanCone * tanCone;
}

inline TexelRay SpotTexelMapping::ray(uint64_t x, uint64_t y) const { return grid_->texelRay(x, y, relativeTo_); }
inline uint32_t SpotTexelMapping::slice(double zv) const { return grid_->sliceOfDepth(zv); }
inline uint32_t SpotTexelMapping::side() const { return uint32_t(grid_->side()); }

}  // namespace cpvs
