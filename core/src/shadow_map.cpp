#include "cpvs/shadow_map.h"

#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "cpvs/query.h"

#include "batch_lookup.h"
#include "embree_packet.h"

namespace cpvs {

namespace {

constexpr uint32_t kMaxSide = uint32_t(1) << 20;
// Packets of 8 coherent rays over 4 x 2 texels, as the CPVS depth renderer uses.
constexpr uint32_t kPacketW = 4, kPacketH = 2;

int64_t floorToInt(double v) { return int64_t(std::floor(std::clamp(v, -1e15, 1e15))); }

}  // namespace

ShadowMap::ShadowMap(const Grid& grid, uint32_t side) : grid_(grid), side_(side) {
  if (side < 1 || side > kMaxSide)
    throw InputError("shadow map side " + std::to_string(side) + " is outside [1, " + std::to_string(kMaxSide) + "]");
  depth_.assign(size_t(side) * side, kEmpty);
}

uint16_t ShadowMap::quantize(double depthFromNear, double depthExtent) {
  double q = std::floor(depthFromNear / depthExtent * kDepthLevels);
  if (!(q > 0)) return 0;  // also NaN
  return q >= kDepthLevels - 1 ? uint16_t(kDepthLevels - 1) : uint16_t(q);
}

Vec3 ShadowMap::toTexel(const Vec3& world) const {
  const Vec3 p = world - grid_.origin;
  const double s = double(side_);
  return {(dot(p, grid_.frame.u) - grid_.u0) / grid_.extent * s, (dot(p, grid_.frame.v) - grid_.v0) / grid_.extent * s,
          (dot(p, grid_.frame.dir) - grid_.d0) / grid_.depthExtent * s};
}

Vec3 ShadowMap::toWorld(const Vec3& t) const {
  const double s = double(side_);
  return grid_.origin + grid_.frame.u * (grid_.u0 + t.x / s * grid_.extent) +
         grid_.frame.v * (grid_.v0 + t.y / s * grid_.extent) + grid_.frame.dir * (grid_.d0 + t.z / s * grid_.depthExtent);
}

Vec3 ShadowMap::offsetPoint(const Vec3& p, const Vec3& n, int pcf) const {
  if (n == Vec3{}) return p;
  const double s = double(side_);
  const Vec3 nt{dot(n, grid_.frame.u) / grid_.extent * s, dot(n, grid_.frame.v) / grid_.extent * s,
                dot(n, grid_.frame.dir) / grid_.depthExtent * s};
  const double m = std::max({std::abs(nt.x), std::abs(nt.y), std::abs(nt.z)});
  if (!(m > 0) || !std::isfinite(m)) return p;
  return toWorld(toTexel(p) + nt * (normalOffsetVoxels(pcf) / m));
}

float ShadowMap::filteredAt(const Vec3& q, int pcf) const {
  checkPcfWidth(pcf);
  const Vec3 t = toTexel(q);
  const uint16_t qd = quantize(dot(q - grid_.origin, grid_.frame.dir) - grid_.d0, grid_.depthExtent);
  const int64_t cx = floorToInt(t.x), cy = floorToInt(t.y), s = int64_t(side_);
  const int r = pcf / 2;
  int lit = 0;
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx) {
      const int64_t x = cx + dx, y = cy + dy;
      lit += (x < 0 || y < 0 || x >= s || y >= s) || !(qd > at(uint32_t(x), uint32_t(y)));
    }
  return float(lit) / float(pcf * pcf);
}

void ShadowMap::batch(const std::vector<Vec3>& points, const std::vector<Vec3>& normals, int pcf,
                     std::vector<float>& out) const {
  checkPcfWidth(pcf);
  batchLookups(*this, points, normals, pcf, out);
}

ShadowMap renderShadowMap(const RayScene& rays, const Grid& grid, uint32_t side) {
  ShadowMap map(grid, side);
  const double ts = grid.extent / double(side);
  const Vec3 local0 = grid.origin - rays.origin();
  const Vec3 &u = grid.frame.u, &v = grid.frame.v, &d = grid.frame.dir;
  const float tfar = float(grid.depthExtent * 1.0001);
  auto* scene = static_cast<RTCScene>(rays.embreeScene());
  const uint32_t packetRows = (side + kPacketH - 1) / kPacketH;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, packetRows, 4), [&](const auto& range) {
    for (uint32_t pr = range.begin(); pr != range.end(); ++pr) {
      for (uint32_t px = 0; px < side; px += kPacketW) {
        alignas(32) int valid[8];
        alignas(32) RTCRayHit8 rh;
        for (uint32_t l = 0; l < 8; ++l) {
          const uint32_t x = px + l % kPacketW, y = pr * kPacketH + l / kPacketW;
          valid[l] = (x < side && y < side) ? -1 : 0;
          const double lu = grid.u0 + (double(std::min(x, side - 1)) + 0.5) * ts;
          const double lv = grid.v0 + (double(std::min(y, side - 1)) + 0.5) * ts;
          const Vec3 o = local0 + u * lu + v * lv + d * grid.d0;
          setPacketRay(rh, int(l), o, d, tfar);
        }
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
        rtcIntersect8(valid, scene, &ctx, &rh);
        for (uint32_t l = 0; l < 8; ++l) {
          if (!valid[l] || rh.hit.geomID[l] == RTC_INVALID_GEOMETRY_ID) continue;
          map.at(px + l % kPacketW, pr * kPacketH + l / kPacketW) =
              ShadowMap::quantize(double(rh.ray.tfar[l]), grid.depthExtent);
        }
      }
    }
  });
  return map;
}

}  // namespace cpvs
