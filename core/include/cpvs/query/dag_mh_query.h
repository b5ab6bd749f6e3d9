// CPU shadow lookups on a DAG-MH: a depth compare against the texels' stored depths, with
// the CPVS's normal offset and filter footprint, so that both kinds answer the same call.
#pragma once

#include <vector>

#include "cpvs/base/vec3.h"
#include "cpvs/dagmh/dag_mh.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/query/normal_offset.h"

namespace cpvs {

/// Answers lookups on a DAG-MH over a cubic sun grid. Owns what it reads. Thread-safe.
class DagMhQuery {
 public:
  /// InputError when the DAG-MH's resolution is not the grid's or the grid is not cubic.
  DagMhQuery(OrthoGrid grid, DagMh dag);

  const OrthoGrid& grid() const { return grid_; }
  const DagMh& dag() const { return dag_; }

  /// The lookup point of a query at world point p with normal n (zero: no offset) and
  /// filter width pcf, in voxels (unfloored): ShadowQuery's offset.
  Vec3 lookupVoxel(const Vec3& p, const Vec3& n, PcfWidth pcf) const;
  /// Whether the voxel is shadowed: its slice at or beyond the texel's stored depth
  /// (bake_dag_mh.h). As ShadowQuery: in front of the grid and outside it in x or y lit,
  /// behind it as its last slice.
  bool voxelShadowed(const VoxelCoord& v) const;
  /// How many of the pcf x pcf texels around the lookup voxel (its slice) are lit.
  uint32_t litTexels(const Vec3& p, const Vec3& n, PcfWidth pcf) const;
  float filtered(const Vec3& p, const Vec3& n, PcfWidth pcf) const { return float(litTexels(p, n, pcf)) / float(pcf.texels()); }
  float visibility(const Vec3& p, const Vec3& n = {}) const { return filtered(p, n, PcfWidth(1)); }
  /// Many lookups at once, multithreaded, as ShadowQuery::batch.
  void batch(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf, std::vector<float>& out) const;

 private:
  OrthoGrid grid_;
  LookupMapping mapping_;
  DagMh dag_;
  int64_t R_;
};

}  // namespace cpvs
