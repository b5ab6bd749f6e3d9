// The light's frame and the voxel grid it carries.
#pragma once

#include <cstdint>
#include <string>

#include "cpvs/types.h"

namespace cpvs {

struct Scene;

/// Orthonormal frame (u, v, dir) of a directional light; `dir` points from the light into
/// the scene. Built without a branch on the direction (Duff et al. 2017), so axis-aligned,
/// almost axis-aligned and grazing directions all get an exactly orthonormal frame.
struct LightFrame {
  Vec3 dir, u, v;

  /// `d` need not be normalized; throws InputError when it is not finite or is zero.
  static LightFrame fromDirection(const Vec3& d);
  /// Sun given by elevation above the horizon (Y is up) and azimuth (degrees, 0 = the sun
  /// stands towards +Z, 90 = towards +X). Throws InputError for an elevation below 0 or
  /// above 90, or non-finite angles.
  static LightFrame fromElevationAzimuth(double elevationDeg, double azimuthDeg);
};

/// Smallest and largest supported log2 of the grid resolution R (R = 2^k voxels a side).
constexpr int kMinLog2Resolution = 3;
constexpr int kMaxLog2Resolution = 20;

/// The R x R x R voxel grid of a light over a scene. x, y index the shadow-map texel (along
/// u, v) and z the depth slice (along dir). Every mapping is done in double precision
/// relative to `origin` (the scene's bounding-box centre), and voxel indices are 64-bit.
struct Grid {
  LightFrame frame;
  int log2Resolution = 0;
  Vec3 origin;            // world point at light coordinates (0, 0, 0)
  double u0 = 0, v0 = 0;  // light coordinates of the grid corner, relative to origin
  double d0 = 0;          // light depth of the near plane, relative to origin
  double extent = 1;      // side of the grid in u and v (world units)
  double depthExtent = 1; // depth range (world units)

  uint64_t resolution() const { return uint64_t(1) << log2Resolution; }
  double texelSize() const { return extent / double(resolution()); }
  double sliceSize() const { return depthExtent / double(resolution()); }

  /// Continuous voxel coordinates of a world point (voxel (i, j, k) spans [i, i+1) ...).
  Vec3 toVoxel(const Vec3& world) const;
  /// World position of continuous voxel coordinates.
  Vec3 toWorld(const Vec3& voxel) const;
  /// A world-space direction expressed in voxel units per world unit along each axis.
  Vec3 directionToVoxel(const Vec3& worldDir) const;
};

/// Fits a grid of resolution 2^log2Resolution to the scene as seen along `frame.dir`: the
/// projected bounds, padded by a small margin, made square in u and v. Throws InputError
/// for an empty scene or a resolution outside [kMinLog2Resolution, kMaxLog2Resolution].
Grid makeGrid(const Scene& scene, const LightFrame& frame, int log2Resolution);

/// Parses "4096", "4K", "16k", "256K" into log2 of a power of two; throws InputError for
/// anything that is not a power of two in the supported range.
int parseResolution(const std::string& text);

}  // namespace cpvs
