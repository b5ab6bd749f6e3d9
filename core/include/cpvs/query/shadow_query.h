// CPU shadow queries on a complete DAG: the reference every other lookup is checked against.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "cpvs/base/vec3.h"
#include "cpvs/dag/packed_dag.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/light/perspective_grid.h"
#include "cpvs/query/medium.h"
#include "cpvs/query/normal_offset.h"

namespace cpvs {

/// Answers shadow queries on a complete DAG. Owns what it walks: the grid and the packed
/// DAG, moved in (from an artifact: ShadowQuery(art.grid, std::move(art.packed))).
/// Walking the packed form instead of Dag's levels: batched binary lookups on the Quake 3
/// house took 409 ns at 16K and 276 ns at 8K walking Dag's levels, 235 ns and 206 ns
/// walking the packed copy (same machine, same day, `cpvs accuracy`); small DAGs that stay
/// in cache gain nothing measurable. Thread-safe for lookups.
class ShadowQuery {
 public:
  /// InputError when the DAG's resolution is not the grid's.
  ShadowQuery(OrthoGrid grid, PackedDag dag);
  /// A spot light's, whose cone has half-angle atan(tanCone): no light reaches a point
  /// outside it, outside the frustum, beyond far (the light's range) or behind the light
  /// (they are shadowed), and the cone's undefined texels are never read.
  ShadowQuery(PerspectiveGrid grid, double tanCone, PackedDag dag);

  /// The directional light's grid (only for a query made with one).
  const OrthoGrid& grid() const;
  /// The spot light's grid, or null for a directional light.
  const PerspectiveGrid* spot() const { return spot_ ? &*spot_ : nullptr; }
  double tanCone() const { return tanCone_; }
  /// The grid of either light.
  const LightGrid& lightGrid() const { return spot_ ? static_cast<const LightGrid&>(*spot_) : grid_; }
  const PackedDag& dag() const { return dag_; }

  /// True when the voxel is shadowed. In front of the grid is lit (nothing casts there).
  /// Behind it answers as the last slice for a directional light; outside it in x or y is
  /// lit. For a spot light both are shadowed, as its texels the cone misses, before and
  /// beyond its depth range alike.
  bool voxelShadowed(const VoxelCoord& v) const;

  /// The voxel a query at world point p with normal n (need not be normalized; zero =
  /// no offset) and filter width pcf lands in: p offset by normalOffsetVoxels(pcf) along
  /// the normal (LightGrid::offsetVoxel), then floored to integers. Behind a spot light:
  /// (-1, -1, R), a voxel outside its frustum and beyond its far end, dark with any filter.
  VoxelCoord voxelOf(const Vec3& p, const Vec3& n, PcfWidth pcf) const;
  /// The world position of the offset query point (before flooring), for references.
  Vec3 offsetPoint(const Vec3& p, const Vec3& n, PcfWidth pcf) const;

  /// Binary visibility: 1 = lit, 0 = shadowed.
  float visibility(const Vec3& p, const Vec3& n = {}) const { return filtered(p, n, kBinary); }
  /// How many of the pcf x pcf texels around the lookup voxel (same slice) are lit, each
  /// as voxelShadowed answers it (a footprint in front of the grid is all lit). What a GPU
  /// lookup answers.
  uint32_t litTexels(const Vec3& p, const Vec3& n, PcfWidth pcf) const;
  /// Fraction of the pcf x pcf texels around the lookup voxel (same slice) that are lit.
  float filtered(const Vec3& p, const Vec3& n, PcfWidth pcf) const {
    return float(litTexels(p, n, pcf)) / float(pcf.texels());
  }

  /// Visibility interpolated across the grid, never along depth (seed 002's rule: the
  /// occluder's discontinuity lies along depth): the 2x2 texels around the lookup point
  /// (offset by kSoftOffsetVoxels) in its slice, each as voxelShadowed answers it, weighted
  /// bilinearly by where the point falls between their centres. In [0, 1]; 0 where no
  /// voxel answers (behind a spot light).
  float bilinearVisibility(const Vec3& p, const Vec3& n) const;

  /// Many queries at once, multithreaded; normals may be empty (no offset). InputError
  /// for an invalid pcf or a normal count that is neither 0 nor the point count.
  void batch(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
             std::vector<float>& out) const;

  /// The stretches of the world segment a -> b that the sun reaches, as distances from a,
  /// in order and merged: exact for the voxelization (every voxel as voxelShadowed answers
  /// it), found by walking the DAG a homogeneous block at a time (segment_walk.h). The sun
  /// only: InputError for a spot light, whose voxels a straight segment crosses on a curve.
  std::vector<std::pair<double, double>> litStretches(const Vec3& a, const Vec3& b) const;
  /// The fraction of the segment that the sun reaches: the lit pieces' (t1 - t0) summed in
  /// the walk's order, which cpvs_shadow.glsl's cpvsSunLitFraction sums alike (the same
  /// double to the bit on a device whose double division rounds correctly).
  double litFraction(const Vec3& a, const Vec3& b) const;
  /// Sun light scattered towards a by medium m along the segment from a to b (a view ray
  /// from the eye a to the surface b): medium.h's SegmentLight over litStretches.
  SegmentLight inScattering(const Vec3& a, const Vec3& b, const Medium& m) const;

  /// Whether no light reaches texel (x, y) of a spot light: outside the grid or the cone
  /// (false for the sun's grid). A lookup counts such texels dark whatever the DAG holds.
  bool dark(int64_t x, int64_t y) const;

 private:
  static inline const PcfWidth kBinary{1};

  OrthoGrid grid_;
  std::optional<PerspectiveGrid> spot_;
  double tanCone_ = 0;
  LookupMapping mapping_;  // grid_.lookupMapping(), once: the same constants every lookup uses
  PackedDag dag_;
  int64_t R_;
};

}  // namespace cpvs
