#include "cpvs/eval/shadow_map.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "cpvs/query/shadow_query.h"

#include "cpvs/query/batch_lookups.h"

namespace cpvs {

namespace {

constexpr uint32_t kMaxSide = uint32_t(1) << 20;
// Packets of 8 coherent rays over 4 x 2 texels, as the CPVS depth renderer uses.
constexpr uint32_t kPacketW = 4, kPacketH = 2;
static_assert(kPacketW * kPacketH == uint32_t(kPacketLanes));


}  // namespace

ShadowMap::ShadowMap(const OrthoGrid& grid, uint32_t side, bool floatDepth) : grid_(grid), side_(side) {
  if (side < 1 || side > kMaxSide)
    throw InputError("shadow map side " + std::to_string(side) + " is outside [1, " + std::to_string(kMaxSide) + "]");
  cells_ = grid.withSide(side);
  if (floatDepth) floatDepth_.assign(size_t(side) * side, std::numeric_limits<float>::infinity());
  else depth_.assign(size_t(side) * side, kEmpty);
}

uint16_t ShadowMap::quantize(double depthFromNear, double depthExtent) {
  double q = std::floor(depthFromNear / depthExtent * kDepthLevels);
  if (!(q > 0)) return 0;  // also NaN
  return q >= kDepthLevels - 1 ? uint16_t(kDepthLevels - 1) : uint16_t(q);
}

Vec3 ShadowMap::toTexel(const Vec3& world) const { return cells_.voxelFromWorld(world); }

Vec3 ShadowMap::toWorld(const Vec3& t) const { return cells_.worldFromVoxel(t); }

Vec3 ShadowMap::offsetPoint(const Vec3& p, const Vec3& n, PcfWidth pcf) const {
  if (n == Vec3{}) return p;
  return cells_.worldFromVoxel(cells_.offsetVoxel(p, n, normalOffsetVoxels(pcf.width())));
}

float ShadowMap::filteredAt(const Vec3& q, PcfWidth pcf) const {
  const Vec3 t = toTexel(q);
  const double depth = cells_.depthOf(q);
  const uint16_t qd = quantize(depth, grid_.depthExtent);
  const float fd = float(depth);
  const bool floats = floatDepth();
  const int64_t cx = floorToVoxel(t.x), cy = floorToVoxel(t.y), s = int64_t(side_);
  const int r = pcf.radius();
  int lit = 0;
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx) {
      const int64_t x = cx + dx, y = cy + dy;
      if (x < 0 || y < 0 || x >= s || y >= s) {
        ++lit;
        continue;
      }
      lit += floats ? !(fd > floatAt(uint32_t(x), uint32_t(y))) : !(qd > at(uint32_t(x), uint32_t(y)));
    }
  return float(lit) / float(pcf.texels());
}

void ShadowMap::batch(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
                     std::vector<float>& out) const {
  batchLookups(*this, points, normals, PcfWidth(pcf), out);
}

ShadowMap renderShadowMap(const RayScene& rays, const OrthoGrid& grid, uint32_t side, bool floatDepth) {
  ShadowMap map(grid, side, floatDepth);
  const TexelMapping texels = grid.withSide(side).texelMapping(rays.origin());
  const uint32_t packetRows = (side + kPacketH - 1) / kPacketH;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, packetRows, 4), [&](const auto& range) {
    RayPacket packet;
    std::array<RayHit, kPacketLanes> hits;
    std::array<bool, kPacketLanes> found;
    for (uint32_t pr = range.begin(); pr != range.end(); ++pr) {
      for (uint32_t px = 0; px < side; px += kPacketW) {
        for (uint32_t l = 0; l < uint32_t(kPacketLanes); ++l) {
          const uint32_t x = px + l % kPacketW, y = pr * kPacketH + l / kPacketW;
          const TexelRay ray = texels.ray(std::min(x, side - 1), std::min(y, side - 1));
          packet.origin[l] = ray.origin;
          packet.dir[l] = ray.dir;
          packet.tNear[l] = 0.0f;
          packet.tFar[l] = float(ray.tMax);
          packet.active[l] = x < side && y < side;
        }
        rays.firstHits(packet, ClosedMode::Off, hits, found);
        for (uint32_t l = 0; l < uint32_t(kPacketLanes); ++l)
          if (found[l]) map.setDepth(px + l % kPacketW, pr * kPacketH + l / kPacketW, hits[l].t);
      }
    }
  });
  return map;
}

}  // namespace cpvs
