// A plain shadow map over a light grid, 16-bit or float depths: the baselines a CPVS is
// measured against.
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/light/frame.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/query/normal_offset.h"
#include "cpvs/raytrace/ray_scene.h"

namespace cpvs {

/// A conventional shadow map: per texel the enter depth (first hit along the light through
/// the texel centre), quantized to 16 bits over the grid's depth range. Its `side` x `side`
/// texels cover the same u, v extent as the grid (any side, not only a power of two), so
/// a map of side R has exactly the texels of a CPVS of resolution R.
///
/// Depths are quantized as q(d) = floor((d - d0) / depthExtent * 65536), clamped to
/// [0, 65535]; a texel whose ray hits nothing stores kEmpty (65535), behind every point.
/// A point is shadowed by a texel when its own quantized depth is beyond the stored one.
///
/// A float map (floatDepth) stores the enter depth itself as a 32-bit float (infinity where
/// the ray hits nothing) and compares the point's depth rounded to float: the full-precision
/// map a DAG-MH compresses.
class ShadowMap {
 public:
  static constexpr uint16_t kEmpty = 0xFFFF;
  static constexpr double kDepthLevels = 65536.0;

  ShadowMap() = default;
  /// An empty map (every texel kEmpty, or infinity). side must be in [1, 2^20] (InputError
  /// otherwise).
  ShadowMap(const OrthoGrid& grid, uint32_t side, bool floatDepth = false);

  const OrthoGrid& grid() const { return grid_; }
  uint32_t side() const { return side_; }
  bool floatDepth() const { return !floatDepth_.empty(); }
  /// Storage of the texels: side^2 x 2 bytes, or x 4 for a float map.
  uint64_t bytes() const { return uint64_t(depth_.size()) * sizeof(uint16_t) + uint64_t(floatDepth_.size()) * sizeof(float); }
  /// Stores the enter depth t (world units from the near plane) of texel (x, y).
  void setDepth(uint32_t x, uint32_t y, double t) {
    if (floatDepth_.empty()) at(x, y) = quantize(t, grid_.depthExtent);
    else floatDepth_[size_t(y) * side_ + x] = float(t);
  }
  /// A float map's depth of texel (x, y).
  float floatAt(uint32_t x, uint32_t y) const { return floatDepth_[size_t(y) * side_ + x]; }
  double texelSize() const { return cells_.texelSize(); }

  uint16_t& at(uint32_t x, uint32_t y) { return depth_[size_t(y) * side_ + x]; }
  uint16_t at(uint32_t x, uint32_t y) const { return depth_[size_t(y) * side_ + x]; }

  /// The 16-bit quantization of a depth along the light, measured from the grid's near
  /// plane in world units (see the class comment).
  static uint16_t quantize(double depthFromNear, double depthExtent);

  /// Continuous coordinates of a world point in this map's "voxels": x, y in texels
  /// (texel (i, j) spans [i, i+1)), z in units of depthExtent / side. The same mapping as
  /// OrthoGrid::voxelFromWorld for a map of side R.
  Vec3 toTexel(const Vec3& world) const;
  /// World position of continuous texel coordinates (inverse of toTexel).
  Vec3 toWorld(const Vec3& texel) const;

  /// The point a lookup from surface point p with normal n and filter width pcf is made
  /// at: ShadowQuery's rule (normalOffsetVoxels(pcf) along the normal, scaled so that its
  /// largest component is that many units) in this map's own texel units. For a map of
  /// side R this is exactly ShadowQuery::offsetPoint of a CPVS of resolution R.
  Vec3 offsetPoint(const Vec3& p, const Vec3& n, PcfWidth pcf) const;

  /// Fraction of the pcf x pcf texels around the texel holding the (already offset) world
  /// point q that do not shadow it (stored depth not in front of q's quantized depth).
  /// Texels outside the map are lit. pcf odd in [1, kMaxPcfWidth] (InputError otherwise).
  float filteredAt(const Vec3& q, PcfWidth pcf) const;
  /// Lookup from a surface point with its normal offset: filteredAt(offsetPoint(p, n, pcf)).
  float filtered(const Vec3& p, const Vec3& n, PcfWidth pcf) const { return filteredAt(offsetPoint(p, n, pcf), pcf); }

  /// Many lookups at once, multithreaded, as ShadowQuery::batch: normals may be empty
  /// (no offset).
  void batch(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
             std::vector<float>& out) const;

 private:
  OrthoGrid grid_;
  uint32_t side_ = 0;
  OrthoGrid cells_;  // the grid cut into side x side texels: this map's mapping
  std::vector<uint16_t> depth_;     // a 16-bit map's
  std::vector<float> floatDepth_;   // a float map's
};

/// Renders a shadow map of side x side texels over the grid's u, v extent with Embree
/// packets of 8 rays (4 x 2 texels), one ray along the light through each texel centre
/// from the grid's near plane, multithreaded. side in [1, 2^20].
ShadowMap renderShadowMap(const RayScene& rays, const OrthoGrid& grid, uint32_t side, bool floatDepth = false);

}  // namespace cpvs
