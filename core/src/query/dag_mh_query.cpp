#include "cpvs/query/dag_mh_query.h"

#include <algorithm>
#include <string>

#include "cpvs/base/error.h"
#include "cpvs/query/batch_lookups.h"

namespace cpvs {

DagMhQuery::DagMhQuery(OrthoGrid grid, DagMh dag)
    : grid_(std::move(grid)), mapping_(grid_.lookupMapping()), dag_(std::move(dag)), R_(int64_t(grid_.resolution())) {
  if (dag_.log2Side != grid_.log2Resolution)
    throw InputError("a DAG-MH of resolution 2^" + std::to_string(dag_.log2Side) + " for a grid of 2^" +
                     std::to_string(grid_.log2Resolution));
  if (grid_.depthSlices != 0) throw InputError("a DAG-MH's grid is cubic");
}

Vec3 DagMhQuery::lookupVoxel(const Vec3& p, const Vec3& n, PcfWidth pcf) const {
  return mappedLookup(mapping_, p, n, normalOffsetVoxels(pcf.width()));
}

bool DagMhQuery::voxelShadowed(const VoxelCoord& v) const {
  if (v.z < 0 || v.x < 0 || v.y < 0 || v.x >= R_ || v.y >= R_) return false;
  return double(std::min(v.z, R_ - 1)) >= double(dag_.depth(uint64_t(v.x), uint64_t(v.y)));
}

uint32_t DagMhQuery::litTexels(const Vec3& p, const Vec3& n, PcfWidth pcf) const {
  const Vec3 c = lookupVoxel(p, n, pcf);
  const int64_t cx = floorToVoxel(c.x), cy = floorToVoxel(c.y), cz = floorToVoxel(c.z), r = pcf.radius();
  const uint32_t all = uint32_t(pcf.texels());
  if (cz < 0) return all;  // in front of the grid
  // The footprint's texels inside the grid, read in one descent; those outside are lit.
  const int64_t x0 = std::max<int64_t>(cx - r, 0), y0 = std::max<int64_t>(cy - r, 0);
  const int64_t x1 = std::min<int64_t>(cx + r + 1, R_), y1 = std::min<int64_t>(cy + r + 1, R_);
  if (x0 >= x1 || y0 >= y1) return all;
  const uint32_t w = uint32_t(x1 - x0), h = uint32_t(y1 - y0);
  float depth[kMaxPcfWidth * kMaxPcfWidth];
  dag_.depths(uint64_t(x0), uint64_t(y0), w, h, depth);
  const double k = double(std::min(cz, R_ - 1));
  uint32_t shadowed = 0;
  for (uint32_t i = 0; i < w * h; ++i) shadowed += k >= double(depth[i]);
  return all - shadowed;
}

void DagMhQuery::batch(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
                       std::vector<float>& out) const {
  batchLookups(*this, points, normals, PcfWidth(pcf), out);
}

}  // namespace cpvs
