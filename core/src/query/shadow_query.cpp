#include "cpvs/query/shadow_query.h"

#include <algorithm>
#include <bit>
#include <string>

#include "cpvs/base/error.h"
#include "cpvs/query/batch_lookups.h"

namespace cpvs {

void checkPcfWidth(int pcf) {
  if (pcf < 1 || pcf > kMaxPcfWidth || pcf % 2 == 0)
    throw InputError("PCF width " + std::to_string(pcf) + " must be odd and between 1 and " +
                     std::to_string(kMaxPcfWidth));
}

ShadowQuery::ShadowQuery(OrthoGrid grid, PackedDag dag)
    : grid_(std::move(grid)), mapping_(grid_.lookupMapping()), dag_(std::move(dag)), R_(int64_t(grid_.resolution())) {
  if (dag_.log2Resolution() != grid_.log2Resolution)
    throw InputError("a DAG of resolution 2^" + std::to_string(dag_.log2Resolution()) + " for a grid of 2^" +
                     std::to_string(grid_.log2Resolution));
}

bool ShadowQuery::voxelShadowed(const VoxelCoord& v) const {
  if (v.x < 0 || v.y < 0 || v.x >= R_ || v.y >= R_ || v.z < 0) return false;
  int64_t z = std::min(v.z, R_ - 1);
  return dag_.voxelShadowed(uint64_t(v.x), uint64_t(v.y), uint64_t(z));
}

VoxelCoord ShadowQuery::voxelOf(const Vec3& p, const Vec3& n, PcfWidth pcf) const {
  const Vec3 c = mappedLookup(mapping_, p, n, normalOffsetVoxels(pcf.width()));
  return {floorToVoxel(c.x), floorToVoxel(c.y), floorToVoxel(c.z)};
}

Vec3 ShadowQuery::offsetPoint(const Vec3& p, const Vec3& n, PcfWidth pcf) const {
  return grid_.worldFromVoxel(mappedLookup(mapping_, p, n, normalOffsetVoxels(pcf.width())));
}

uint32_t ShadowQuery::litTexels(const Vec3& p, const Vec3& n, PcfWidth pcf) const {
  const VoxelCoord v = voxelOf(p, n, pcf);
  const int64_t r = pcf.radius(), texels = pcf.texels();
  // Outside the grid is lit (as in voxelShadowed); beyond its far end is its last slice.
  if (v.z < 0) return uint32_t(texels);
  const uint64_t z = uint64_t(std::min(v.z, R_ - 1));
  const int64_t x0 = std::max<int64_t>(v.x - r, 0), x1 = std::min<int64_t>(v.x + r, R_ - 1);
  const int64_t y0 = std::max<int64_t>(v.y - r, 0), y1 = std::min<int64_t>(v.y + r, R_ - 1);
  int64_t shadowed = 0;
  // One walk per 8x8 leaf slice the footprint touches, counting its footprint bits.
  for (int64_t by = y0 >> 3; by <= y1 >> 3; ++by) {
    const int64_t rowLo = std::max(y0, by * 8) - by * 8, rowHi = std::min(y1, by * 8 + 7) - by * 8;
    for (int64_t bx = x0 >> 3; bx <= x1 >> 3; ++bx) {
      const int64_t colLo = std::max(x0, bx * 8) - bx * 8, colHi = std::min(x1, bx * 8 + 7) - bx * 8;
      const uint64_t row = ((uint64_t{1} << (colHi - colLo + 1)) - 1) << colLo;
      uint64_t footprint = 0;
      for (int64_t ty = rowLo; ty <= rowHi; ++ty) footprint |= row << (ty * 8);
      shadowed += std::popcount(dag_.leafSliceMask(uint64_t(bx) * 8, uint64_t(by) * 8, z) & footprint);
    }
  }
  return uint32_t(texels - shadowed);
}

void ShadowQuery::batch(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
                        std::vector<float>& out) const {
  batchLookups(*this, points, normals, PcfWidth(pcf), out);
}

}  // namespace cpvs
