#include "cpvs/depth_maps.h"

#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include "embree_packet.h"

namespace cpvs {

namespace {

// Rays travel in packets of 8 covering 4 x 2 texels; blocks are aligned to global texel
// coordinates so a texel always shares its packet with the same neighbours.
constexpr int kPacketW = 4, kPacketH = 2;

struct LaneHits {
  std::array<RayHit, kMaxHitsPerRay> hits;
  int count = 0;
  bool overflow = false;
};

// Intersection context handed to the filter: Embree passes it back unchanged, so the
// filter can find the per-lane hit lists through it.
struct CollectContext {
  RTCIntersectContext ctx;
  const RayScene* rays;
  ClosedMode mode;
  bool acceptBackFacesOnly;  // approx exit pass: keep the first closed back face
  LaneHits* lanes;           // 8 entries, exact pass only
};

void collectFilter(const RTCFilterFunctionNArguments* args) {
  auto* c = reinterpret_cast<const CollectContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    unsigned prim = RTCHitN_primID(args->hit, args->N, i);
    float ng = RTCHitN_Ng_x(args->hit, args->N, i) * RTCRayN_dir_x(args->ray, args->N, i) +
               RTCHitN_Ng_y(args->hit, args->N, i) * RTCRayN_dir_y(args->ray, args->N, i) +
               RTCHitN_Ng_z(args->hit, args->N, i) * RTCRayN_dir_z(args->ray, args->N, i);
    bool closed = c->rays->triangleClosed(prim, c->mode);
    if (c->acceptBackFacesOnly) {
      if (!(closed && ng > 0)) args->valid[i] = 0;
      continue;
    }
    LaneHits& lane = c->lanes[RTCRayN_id(args->ray, args->N, i)];
    if (lane.count < kMaxHitsPerRay) {
      lane.hits[lane.count++] = RayHit{RTCRayN_tfar(args->ray, args->N, i), prim, ng < 0, closed};
    } else {
      lane.overflow = true;
    }
    args->valid[i] = 0;  // keep traversing: every crossing is wanted
  }
}

uint32_t toSlice(double t, double slicesPerUnit, uint32_t R) {
  double s = std::floor(t * slicesPerUnit);
  if (!(s >= 0)) return 0;
  if (s >= double(R)) return R;
  return static_cast<uint32_t>(s);
}

}  // namespace

int orderCrossings(RayHit* hits, int count, double tieDistance) {
  std::sort(hits, hits + count, [](const RayHit& a, const RayHit& b) {
    if (a.t != b.t) return a.t < b.t;
    if (a.front != b.front) return a.front;
    return a.triangle < b.triangle;
  });
  // Surfaces that coincide (a box standing on another) are computed from different
  // triangles and land a few ulps apart in either order; within a run of crossings closer
  // than tieDistance, enters go first so that the count never touches zero between them.
  for (int i = 0; i < count;) {
    int j = i + 1;
    while (j < count && hits[j].t - hits[j - 1].t <= tieDistance) ++j;
    std::stable_partition(hits + i, hits + j, [](const RayHit& h) { return h.front; });
    i = j;
  }
  // A ray through a shared edge or vertex reports each triangle around it: crossings of
  // the same kind within tieDistance are one crossing.
  int n = 0;
  for (int i = 0; i < count; ++i) {
    bool dup = false;
    for (int j = n - 1; j >= 0 && std::abs(hits[i].t - hits[j].t) <= tieDistance; --j)
      if (hits[j].front == hits[i].front && hits[j].closed == hits[i].closed) {
        dup = true;
        break;
      }
    if (!dup) hits[n++] = hits[i];
  }
  return n;
}

void classifyTexel(const RayHit* hits, int count, bool exact, double slicesPerUnit, uint32_t R,
                   uint32_t& lo, uint32_t& hi) {
  if (count == 0) {
    lo = hi = R;
    return;
  }
  const RayHit& enter = hits[0];
  lo = hi = toSlice(enter.t, slicesPerUnit, R);
  // Only a closed surface entered from its front side opens an interior.
  if (!enter.closed || !enter.front) return;
  if (!exact) {
    for (int i = 1; i < count; ++i)
      if (hits[i].closed && !hits[i].front) {
        hi = std::max(lo, toSlice(hits[i].t, slicesPerUnit, R));
        return;
      }
    return;
  }
  int depth = 0;
  for (int i = 0; i < count; ++i) {
    if (!hits[i].closed) continue;
    depth += hits[i].front ? 1 : -1;
    if (depth < 0) return;  // inconsistent orientation: no interior is trusted
    if (depth == 0) {
      hi = std::max(lo, toSlice(hits[i].t, slicesPerUnit, R));
      return;
    }
  }
  // Never left the interior (open geometry forced closed): keep the column defined.
}

void renderTexelDepths(const RayScene& rays, const Grid& grid, ClosedMode closed, ExitMode exit,
                       uint64_t x0, uint64_t y0, uint32_t width, uint32_t height,
                       TexelDepths& out) {
  if (width % 8 != 0 || height % 8 != 0)
    throw std::invalid_argument("renderTexelDepths: block size must be a multiple of 8");
  const uint32_t R = static_cast<uint32_t>(grid.resolution());
  out.lo.assign(size_t(width) * height, R);
  out.hi.assign(size_t(width) * height, R);
  const double slicesPerUnit = double(R) / grid.depthExtent;
  const double ts = grid.texelSize();
  const Vec3 local0 = grid.origin - rays.origin();
  const Vec3& u = grid.frame.u;
  const Vec3& v = grid.frame.v;
  const Vec3& d = grid.frame.dir;
  // Crossings closer than this are one crossing seen twice (Embree's robust mode reports
  // a ray through a shared edge on both triangles).
  const double dedupT = grid.depthExtent * 1e-6;
  const bool exact = exit == ExitMode::Exact;
  auto* scene = static_cast<RTCScene>(rays.embreeScene());

  const uint32_t rowsOfPackets = height / kPacketH;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, rowsOfPackets, 4), [&](const auto& range) {
    std::array<LaneHits, 8> lanes;
    std::array<RayHit, kMaxHitsPerRay> sorted;
    for (uint32_t pr = range.begin(); pr != range.end(); ++pr) {
      for (uint32_t px = 0; px < width; px += kPacketW) {
        alignas(32) int valid[8];
        alignas(32) RTCRayHit8 rh;
        for (int l = 0; l < 8; ++l) {
          uint64_t gx = x0 + px + (l % kPacketW), gy = y0 + uint64_t(pr) * kPacketH + (l / kPacketW);
          double lu = grid.u0 + (double(gx) + 0.5) * ts, lv = grid.v0 + (double(gy) + 0.5) * ts;
          Vec3 o = local0 + u * lu + v * lv + d * grid.d0;
          valid[l] = -1;
          setPacketRay(rh, int(l), o, d, float(grid.depthExtent * 1.0001));
          lanes[l].count = 0;
          lanes[l].overflow = false;
        }
        CollectContext cc;
        rtcInitIntersectContext(&cc.ctx);
        cc.ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
        cc.rays = &rays;
        cc.mode = closed;
        cc.lanes = lanes.data();
        cc.acceptBackFacesOnly = false;
        cc.ctx.filter = exact ? collectFilter : nullptr;
        rtcIntersect8(valid, scene, &cc.ctx, &rh);

        if (!exact) {
          // Turn each lane's closest hit into a one-element list; lanes entering a closed
          // front face get a second pass for the first back face behind it.
          bool second = false;
          for (int l = 0; l < 8; ++l) {
            valid[l] = 0;
            if (rh.hit.geomID[l] == RTC_INVALID_GEOMETRY_ID) continue;
            unsigned prim = rh.hit.primID[l];
            float ng = rh.hit.Ng_x[l] * rh.ray.dir_x[l] + rh.hit.Ng_y[l] * rh.ray.dir_y[l] +
                       rh.hit.Ng_z[l] * rh.ray.dir_z[l];
            lanes[l].hits[0] = RayHit{rh.ray.tfar[l], prim, ng < 0, rays.triangleClosed(prim, closed)};
            lanes[l].count = 1;
            if (lanes[l].hits[0].closed && lanes[l].hits[0].front) {
              valid[l] = -1;
              second = true;
              rh.ray.tnear[l] = rh.ray.tfar[l];
              rh.ray.tfar[l] = float(grid.depthExtent * 1.0001);
              rh.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
            }
          }
          if (second) {
            cc.ctx.filter = collectFilter;
            cc.acceptBackFacesOnly = true;
            rtcIntersect8(valid, scene, &cc.ctx, &rh);
            for (int l = 0; l < 8; ++l) {
              if (valid[l] != -1 || rh.hit.geomID[l] == RTC_INVALID_GEOMETRY_ID) continue;
              lanes[l].hits[1] = RayHit{rh.ray.tfar[l], rh.hit.primID[l], false, true};
              lanes[l].count = 2;
            }
          }
        }

        for (int l = 0; l < 8; ++l) {
          LaneHits& lh = lanes[l];
          int n = 0;
          if (!lh.overflow) {
            std::copy(lh.hits.begin(), lh.hits.begin() + lh.count, sorted.begin());
            n = orderCrossings(sorted.data(), lh.count, dedupT);
          } else {
            sorted[0] = lh.hits[0];  // too many crossings: keep the enter depth only
            for (int i = 1; i < lh.count; ++i)
              if (lh.hits[i].t < sorted[0].t) sorted[0] = lh.hits[i];
            sorted[0].closed = false;
            n = 1;
          }
          uint32_t lx = px + (l % kPacketW), ly = pr * kPacketH + (l / kPacketW);
          size_t at = size_t(ly) * width + lx;
          classifyTexel(sorted.data(), n, exact, slicesPerUnit, R, out.lo[at], out.hi[at]);
        }
      }
    }
  });
}

}  // namespace cpvs
