// CPU shadow queries on a baked artifact: the reference every other lookup is checked against.
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/cpvs_file.h"
#include "cpvs/packed_dag.h"

namespace cpvs {

/// Largest supported PCF filter width in texels (odd widths 1, 3, ..., 9).
constexpr int kMaxPcfWidth = 9;

/// Normal offset, in voxels, applied before a lookup with a filter of width `pcf`: the
/// offset point's voxel then lies entirely in front of a plane through the original point
/// (any normal needs more than 1.366 voxels; 1.5 is used), plus half the filter width so
/// that every texel of the footprint clears the receiver.
inline double normalOffsetVoxels(int pcf) { return 1.5 + 0.5 * (pcf - 1); }

/// InputError unless pcf is an odd filter width in [1, kMaxPcfWidth].
void checkPcfWidth(int pcf);

/// Integer voxel coordinates; may lie outside the grid.
struct VoxelCoord {
  int64_t x = 0, y = 0, z = 0;
};

/// Answers shadow queries on a complete DAG. Holds a reference to the artifact, and walks
/// a PackedDag copy of its DAG (made once, O(nodes), as many bytes again): batched binary
/// lookups on the Quake 3 house took 409 ns at 16K and 276 ns at 8K walking Dag's levels,
/// 235 ns and 206 ns walking the packed copy (same machine, same day, `cpvs accuracy`);
/// small DAGs that stay in cache gain nothing measurable.
class ShadowQuery {
 public:
  explicit ShadowQuery(const CpvsArtifact& artifact);

  const Grid& grid() const { return a_.grid; }
  const CpvsArtifact& artifact() const { return a_; }

  /// True when the voxel is shadowed. Outside the grid in x or y, or in front of it, is
  /// lit (nothing casts there); behind it answers as the last slice.
  bool voxelShadowed(const VoxelCoord& v) const;

  /// The voxel a query at world point p with normal n (need not be normalized; zero =
  /// no offset) and filter width pcf lands in: p offset by normalOffsetVoxels(pcf) along
  /// the normal measured in voxel space (scaled so its largest component moves that many
  /// voxels), then floored to integers.
  VoxelCoord lookupVoxel(const Vec3& p, const Vec3& n, int pcf) const;
  /// The world position of the offset query point (before flooring), for references.
  Vec3 offsetPoint(const Vec3& p, const Vec3& n, int pcf) const;

  /// Binary visibility: 1 = lit, 0 = shadowed.
  float visibility(const Vec3& p, const Vec3& n = {}) const { return filtered(p, n, 1); }
  /// Fraction of the pcf x pcf texels around the lookup voxel (same slice) that are lit.
  /// pcf must be odd and in [1, kMaxPcfWidth] (InputError otherwise).
  float filtered(const Vec3& p, const Vec3& n, int pcf) const;

  /// Many queries at once, multithreaded; normals may be empty (no offset).
  void batch(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
             std::vector<float>& out) const;

 private:
  const CpvsArtifact& a_;
  PackedDag packed_;
  int64_t R_;
};

}  // namespace cpvs
