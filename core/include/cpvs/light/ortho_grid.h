// The voxel grid of a directional light: an orthographic LightGrid.
#pragma once

#include <cmath>
#include <cstdint>
#include <string>

#include "cpvs/base/limits.h"
#include "cpvs/light/frame.h"
#include "cpvs/light/grid.h"
#include "cpvs/light/lookup_mapping.h"

namespace cpvs {

struct Scene;
class OrthoGrid;

/// An ortho grid's texel rays and depth slices with everything derived (texel size,
/// slices per unit, the ray frame's origin) computed once: what a renderer's inner loop
/// calls per texel. The same arithmetic as OrthoGrid::texelRay and sliceOfDepth, which
/// are made from it; per-texel calls through LightGrid, with their divisions, made the
/// 8K bakes of bench_bake 3-12 % slower in rendering.
class TexelMapping {
 public:
  TexelMapping(const OrthoGrid& grid, const Vec3& relativeTo);

  TexelRay ray(uint64_t x, uint64_t y) const {
    const double lu = u0_ + (double(x) + 0.5) * texelSize_, lv = v0_ + (double(y) + 0.5) * texelSize_;
    return {local0_ + u_ * lu + v_ * lv + dir_ * d0_, dir_, tMax_};
  }
  uint32_t slice(double t) const {
    const double s = std::floor(t * slicesPerUnit_);
    if (!(s >= 0)) return 0;
    if (s >= cells_) return side_;
    return static_cast<uint32_t>(s);
  }
  uint32_t side() const { return side_; }
  double slicesPerUnit() const { return slicesPerUnit_; }

 private:
  Vec3 local0_, u_, v_, dir_;
  double u0_, v0_, d0_, texelSize_, slicesPerUnit_, cells_, tMax_;
  uint32_t side_;
};

/// The grid of a directional light over a scene. Every mapping is done in double
/// precision relative to `origin` (the scene's bounding-box centre), and voxel indices
/// are 64-bit. The fields are what files and messages store; the mapping is LightGrid's.
class OrthoGrid final : public LightGrid {
 public:
  LightFrame frame;
  int log2Resolution = 0;
  Vec3 origin;             // world point at light coordinates (0, 0, 0)
  double u0 = 0, v0 = 0;   // light coordinates of the grid corner, relative to origin
  double d0 = 0;           // light depth of the near plane, relative to origin
  double extent = 1;       // side of the grid in u and v (world units)
  double depthExtent = 1;  // depth range (world units)
  // The slices the scene's depth spans (makeGrid's depthSlices), a power of two below the
  // resolution; 0: all of them (a cubic grid). Lookups offset by it (depthShift).
  uint32_t depthSlices = 0;

  uint64_t resolution() const { return uint64_t(1) << log2Resolution; }
  /// log2 of resolution / depthSlices: how many texels deep a slice is, as a power of two
  /// (0 for a cubic grid and for a grid of another side).
  int depthShift() const;
  /// The depth the scene spans (world units): depthExtent, of which a grid with fewer
  /// depth slices holds the scene in the first depthSlices / R.
  double sceneDepthExtent() const;
  /// The same volume at resolution 2^log2Resolution (a plan's coarse count), its slices
  /// as deep against its texels as here (the same depthShift, down to one slice).
  OrthoGrid withResolution(int log2Resolution) const;
  /// World size of one texel and one slice of side() cells.
  double texelSize() const { return extent / cells(); }
  double sliceSize() const { return depthExtent / cells(); }

  /// The same volume cut into `side` cells a side (any side in [1, 2^20], not only a
  /// power of two): the grid of a shadow map of that side. Its side() is `side`; the
  /// stored fields and resolution() are unchanged.
  OrthoGrid withSide(uint64_t side) const;

  uint64_t side() const override { return side_ != 0 ? side_ : resolution(); }
  Vec3 voxelFromWorld(const Vec3& world) const override;
  Vec3 worldFromVoxel(const Vec3& voxel) const override;
  TexelRay texelRay(uint64_t x, uint64_t y, const Vec3& relativeTo) const override;
  uint32_t sliceOfDepth(double t) const override;
  double depthOf(const Vec3& world) const override;
  Vec3 offsetVoxel(const Vec3& world, const Vec3& normal, double voxels) const override;
  /// The constants of voxelFromWorld, directionToVoxel and offsetVoxel (lookup_mapping.h),
  /// as a GPU lookup takes them.
  LookupMapping lookupMapping() const;
  /// A world-space direction in voxel units per world unit along each axis.
  Vec3 directionToVoxel(const Vec3& worldDir) const;
  /// The texel rays and slices for an inner loop (rays relative to `relativeTo`).
  TexelMapping texelMapping(const Vec3& relativeTo) const { return TexelMapping(*this, relativeTo); }

 private:
  double cells() const { return double(side()); }
  uint64_t side_ = 0;  // 0: resolution()
};

/// Fits a grid of resolution 2^log2Resolution to the scene as seen along `frame.dir`: the
/// projected bounds, padded by a small margin, made square in u and v. The scene's depth
/// range spans `depthSlices` slices (0: all R of them). With fewer, each slice is deeper by
/// R / depthSlices and the grid reaches that much further behind the scene: the scene lies
/// in an R x R x depthSlices grid (what a shadow map of that depth precision resolves, the
/// public peer's 16K x 16K x 4096), and the slices behind it repeat its last one, so they
/// add almost nothing to the DAG; the grid keeps depthSlices for its lookups' offsets
/// (depthShift). Throws InputError for an empty scene, a resolution outside
/// [kMinLog2Resolution, kMaxLog2Resolution] or depthSlices that checkDepthSlices refuses.
OrthoGrid makeGrid(const Scene& scene, const LightFrame& frame, int log2Resolution, uint64_t depthSlices = 0);

/// InputError starting with `what` unless `depthSlices` is 0 (all) or a power of two up to
/// 2^log2Resolution.
void checkDepthSlices(uint64_t depthSlices, int log2Resolution, const std::string& what);

/// InputError naming `source` unless the grid's fields can be mapped with: a resolution
/// in range, finite values, positive extents, a unit light direction and frame.
void checkGrid(const OrthoGrid& grid, const std::string& source);

}  // namespace cpvs
