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
  uint32_t lit = 0;
  for (int64_t y = cy - r; y <= cy + r; ++y)
    for (int64_t x = cx - r; x <= cx + r; ++x) lit += !voxelShadowed({x, y, cz});
  return lit;
}

void DagMhQuery::batch(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
                       std::vector<float>& out) const {
  batchLookups(*this, points, normals, PcfWidth(pcf), out);
}

}  // namespace cpvs
