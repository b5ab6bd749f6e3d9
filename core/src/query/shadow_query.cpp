#include "cpvs/query/shadow_query.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <string>

#include "cpvs/base/error.h"
#include "cpvs/query/batch_lookups.h"
#include "cpvs/query/segment_walk.h"

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

ShadowQuery::ShadowQuery(PerspectiveGrid grid, double tanCone, PackedDag dag)
    : spot_(std::move(grid)), tanCone_(tanCone), dag_(std::move(dag)), R_(int64_t(spot_->resolution())) {
  if (!(tanCone > 0) || !std::isfinite(tanCone)) throw InputError("spot light: the cone must be wider than 0 degrees");
  if (dag_.log2Resolution() != spot_->log2Resolution())
    throw InputError("a DAG of resolution 2^" + std::to_string(dag_.log2Resolution()) + " for a spot grid of 2^" +
                     std::to_string(spot_->log2Resolution()));
}

const OrthoGrid& ShadowQuery::grid() const {
  CPVS_CHECK(!spot_);
  return grid_;
}

bool ShadowQuery::dark(int64_t x, int64_t y) const {
  if (!spot_) return false;
  return x < 0 || y < 0 || x >= R_ || y >= R_ || spot_->coneMissesTexel(uint64_t(x), uint64_t(y), tanCone_);
}

bool ShadowQuery::voxelShadowed(const VoxelCoord& v) const {
  if (spot_ && (v.z >= R_ || dark(v.x, v.y))) return true;
  if (v.z < 0) return false;
  if (v.x < 0 || v.y < 0 || v.x >= R_ || v.y >= R_) return false;
  int64_t z = std::min(v.z, R_ - 1);
  return dag_.voxelShadowed(uint64_t(v.x), uint64_t(v.y), uint64_t(z));
}

VoxelCoord ShadowQuery::voxelOf(const Vec3& p, const Vec3& n, PcfWidth pcf) const {
  const double offset = normalOffsetVoxels(pcf.width());
  const Vec3 c = spot_ ? spot_->offsetVoxel(p, n, offset) : mappedLookup(mapping_, p, n, offset, grid_.depthShift());
  // Behind a spot light (no voxel coordinates): a voxel outside its frustum, where no
  // light reaches, rather than one in front of the grid.
  if (spot_ && std::isnan(c.z)) return {-1, -1, R_};
  return {floorToVoxel(c.x), floorToVoxel(c.y), floorToVoxel(c.z)};
}

Vec3 ShadowQuery::offsetPoint(const Vec3& p, const Vec3& n, PcfWidth pcf) const {
  const double offset = normalOffsetVoxels(pcf.width());
  if (spot_) return spot_->worldFromVoxel(spot_->offsetVoxel(p, n, offset));
  return grid_.worldFromVoxel(mappedLookup(mapping_, p, n, offset, grid_.depthShift()));
}

uint32_t ShadowQuery::litTexels(const Vec3& p, const Vec3& n, PcfWidth pcf) const {
  const VoxelCoord v = voxelOf(p, n, pcf);
  const int64_t r = pcf.radius(), texels = pcf.texels();
  // Texels as voxelShadowed answers them: in front of the grid lit, beyond its far end
  // its last slice for the sun and dark for a spot light (its range ends there), outside
  // it in x or y lit for the sun and dark for a spot light.
  if (spot_ && v.z >= R_) return 0;
  if (v.z < 0) {
    if (!spot_) return uint32_t(texels);
    // In front of a spot grid: lit where its frustum and cone reach.
    uint32_t lit = 0;
    for (int64_t y = v.y - r; y <= v.y + r; ++y)
      for (int64_t x = v.x - r; x <= v.x + r; ++x) lit += !dark(x, y);
    return lit;
  }
  const uint64_t z = uint64_t(std::min(v.z, R_ - 1));
  const int64_t x0 = std::max<int64_t>(v.x - r, 0), x1 = std::min<int64_t>(v.x + r, R_ - 1);
  const int64_t y0 = std::max<int64_t>(v.y - r, 0), y1 = std::min<int64_t>(v.y + r, R_ - 1);
  if (x0 > x1 || y0 > y1) return spot_ ? 0 : uint32_t(texels);
  int64_t shadowed = spot_ ? texels - (x1 - x0 + 1) * (y1 - y0 + 1) : 0;
  // A spot light's footprint reaches past its cone only when a corner does (a texel's
  // point nearest the axis is farthest from it at a corner of the rectangle).
  const bool pastCone = spot_ && (dark(x0, y0) || dark(x1, y0) || dark(x0, y1) || dark(x1, y1));
  // One walk per 8x8 leaf slice the footprint touches, counting its footprint bits.
  for (int64_t by = y0 >> 3; by <= y1 >> 3; ++by) {
    const int64_t rowLo = std::max(y0, by * 8) - by * 8, rowHi = std::min(y1, by * 8 + 7) - by * 8;
    for (int64_t bx = x0 >> 3; bx <= x1 >> 3; ++bx) {
      const int64_t colLo = std::max(x0, bx * 8) - bx * 8, colHi = std::min(x1, bx * 8 + 7) - bx * 8;
      const uint64_t row = ((uint64_t{1} << (colHi - colLo + 1)) - 1) << colLo;
      uint64_t footprint = 0;
      for (int64_t ty = rowLo; ty <= rowHi; ++ty) footprint |= row << (ty * 8);
      uint64_t mask = dag_.leafSliceMask(uint64_t(bx) * 8, uint64_t(by) * 8, z) & footprint;
      if (pastCone)
        for (uint64_t m = footprint; m; m &= m - 1) {
          const int bit = std::countr_zero(m);
          if (dark(bx * 8 + bit % 8, by * 8 + bit / 8)) mask |= uint64_t(1) << bit;
        }
      shadowed += std::popcount(mask);
    }
  }
  return uint32_t(texels - shadowed);
}

float ShadowQuery::bilinearVisibility(const Vec3& p, const Vec3& n) const {
  const double offset = kSoftOffsetVoxels;
  const Vec3 c = spot_ ? spot_->offsetVoxel(p, n, offset) : mappedLookup(mapping_, p, n, offset, grid_.depthShift());
  if (std::isnan(c.x) || std::isnan(c.y) || std::isnan(c.z)) return 0;
  const int64_t z = floorToVoxel(c.z);
  // Texel centres are at k + 1/2: the four around the point and its place between them.
  const double fx = c.x - 0.5, fy = c.y - 0.5;
  const int64_t x0 = floorToVoxel(fx), y0 = floorToVoxel(fy);
  const double wx = fx - double(x0), wy = fy - double(y0);
  double lit = 0;
  for (int dy = 0; dy < 2; ++dy)
    for (int dx = 0; dx < 2; ++dx)
      if (!voxelShadowed({x0 + dx, y0 + dy, z})) lit += (dx ? wx : 1 - wx) * (dy ? wy : 1 - wy);
  return float(std::clamp(lit, 0.0, 1.0));
}

std::vector<std::pair<double, double>> ShadowQuery::litStretches(const Vec3& a, const Vec3& b) const {
  if (spot_) throw InputError("light along a segment is answered for the sun; a spot light's voxels are not straight");
  const double distance = length(b - a);
  std::vector<std::pair<double, double>> lit;
  walkSegment(dag_, mappedVoxel(mapping_, a), mappedVoxel(mapping_, b), [&](const SegmentPiece& piece) {
    if (piece.shadowed || piece.t1 <= piece.t0) return;
    const double u0 = piece.t0 * distance, u1 = piece.t1 * distance;
    if (!lit.empty() && lit.back().second == u0) lit.back().second = u1;
    else lit.emplace_back(u0, u1);
  });
  return lit;
}

double ShadowQuery::litFraction(const Vec3& a, const Vec3& b) const {
  if (spot_) throw InputError("light along a segment is answered for the sun; a spot light's voxels are not straight");
  double lit = 0;
  walkSegment(dag_, mappedVoxel(mapping_, a), mappedVoxel(mapping_, b), [&](const SegmentPiece& piece) {
    if (!piece.shadowed) lit += piece.t1 - piece.t0;
  });
  return lit;
}

SegmentLight ShadowQuery::inScattering(const Vec3& a, const Vec3& b, const Medium& m) const {
  checkMedium(m);
  const Vec3 toEye = a - b;
  const double distance = length(toEye);
  // The angle between the sun's travel and the light scattered back along the view ray.
  const double cosTheta = distance > 0 ? dot(grid_.frame.dir, toEye) / distance : 1.0;
  return scatterAlong(litStretches(a, b), distance, m, std::clamp(cosTheta, -1.0, 1.0));
}

void ShadowQuery::batch(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
                        std::vector<float>& out) const {
  batchLookups(*this, points, normals, PcfWidth(pcf), out);
}

}  // namespace cpvs
