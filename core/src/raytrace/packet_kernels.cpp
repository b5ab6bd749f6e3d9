// The packet queries of RayScene: Embree's 8-wide intersection with a filter that
// collects crossings. Private to the raytrace layer.
#include <embree3/rtcore.h>

#include "cpvs/raytrace/ray_scene.h"
#include "raytrace/embree_packet.h"

namespace cpvs {

namespace {

// Intersection context handed to the filter: Embree passes it back unchanged, so the
// filter can find the per-lane hit lists through it.
struct CollectContext {
  RTCIntersectContext ctx;
  const RayScene* rays;
  ClosedMode mode;
  bool acceptBackFacesOnly;                            // keep the first closed back face
  std::array<RayCrossings, kPacketLanes>* lanes;       // all-crossings pass only
  // First-and-back pass: per lane, the nearest hit that is not a closed back face.
  std::array<RayHit, kPacketLanes>* nearest = nullptr;
  std::array<bool, kPacketLanes>* foundNearest = nullptr;
};

void collectFilter(const RTCFilterFunctionNArguments* args) {
  auto* c = reinterpret_cast<const CollectContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
    const float ng = RTCHitN_Ng_x(args->hit, args->N, i) * RTCRayN_dir_x(args->ray, args->N, i) +
                     RTCHitN_Ng_y(args->hit, args->N, i) * RTCRayN_dir_y(args->ray, args->N, i) +
                     RTCHitN_Ng_z(args->hit, args->N, i) * RTCRayN_dir_z(args->ray, args->N, i);
    const bool closed = c->rays->triangleClosed(prim, c->mode);
    if (c->nearest) {
      // Closed back faces are accepted, so traversal narrows to the nearest of them; every
      // other hit is recorded and rejected. Any hit before the final tfar is reported.
      if (closed && ng > 0) continue;
      const unsigned lane = RTCRayN_id(args->ray, args->N, i);
      const float t = RTCRayN_tfar(args->ray, args->N, i);
      RayHit& best = (*c->nearest)[lane];
      if (!(*c->foundNearest)[lane] || t < best.t) {
        best = RayHit{t, prim, frontFacing(ng), closed};
        (*c->foundNearest)[lane] = true;
      }
      args->valid[i] = 0;
      continue;
    }
    if (c->acceptBackFacesOnly) {
      if (!(closed && ng > 0)) args->valid[i] = 0;
      continue;
    }
    RayCrossings& lane = (*c->lanes)[RTCRayN_id(args->ray, args->N, i)];
    if (lane.count < kMaxHitsPerRay) {
      lane.hits[lane.count++] = RayHit{RTCRayN_tfar(args->ray, args->N, i), prim, frontFacing(ng), closed};
    } else {
      lane.overflow = true;
    }
    args->valid[i] = 0;  // keep traversing: every crossing is wanted
  }
}

// Loads the packet into Embree's layout; valid[l] = -1 for active lanes.
void loadPacket(const RayPacket& p, RTCRayHit8& rh, int (&valid)[8]) {
  for (int l = 0; l < kPacketLanes; ++l) {
    setPacketRay(rh, l, p.origin[size_t(l)], p.dir[size_t(l)], p.tFar[size_t(l)]);
    rh.ray.tnear[l] = p.tNear[size_t(l)];
    valid[l] = p.active[size_t(l)] ? -1 : 0;
  }
}

void intersectPacket(RTCSceneTy* scene, CollectContext& cc, RTCFilterFunctionN filter, int (&valid)[8], RTCRayHit8& rh) {
  rtcInitIntersectContext(&cc.ctx);
  cc.ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  cc.ctx.filter = filter;
  rtcIntersect8(valid, scene, &cc.ctx, &rh);
}

}  // namespace

void RayScene::firstHits(const RayPacket& packet, ClosedMode closed, std::array<RayHit, kPacketLanes>& hits,
                         std::array<bool, kPacketLanes>& found) const {
  alignas(32) int valid[8];
  alignas(32) RTCRayHit8 rh;
  loadPacket(packet, rh, valid);
  CollectContext cc{{}, this, closed, false, nullptr};
  intersectPacket(scene_, cc, nullptr, valid, rh);
  for (int l = 0; l < kPacketLanes; ++l) {
    found[size_t(l)] = packet.active[size_t(l)] && rh.hit.geomID[l] != RTC_INVALID_GEOMETRY_ID;
    if (!found[size_t(l)]) continue;
    const unsigned prim = rh.hit.primID[l];
    const float ng = rh.hit.Ng_x[l] * rh.ray.dir_x[l] + rh.hit.Ng_y[l] * rh.ray.dir_y[l] + rh.hit.Ng_z[l] * rh.ray.dir_z[l];
    hits[size_t(l)] = RayHit{rh.ray.tfar[l], prim, frontFacing(ng), triangleClosed(prim, closed)};
  }
}

void RayScene::allCrossings(const RayPacket& packet, ClosedMode closed,
                            std::array<RayCrossings, kPacketLanes>& lanes) const {
  alignas(32) int valid[8];
  alignas(32) RTCRayHit8 rh;
  loadPacket(packet, rh, valid);
  for (auto& lane : lanes) {
    lane.count = 0;
    lane.overflow = false;
  }
  CollectContext cc{{}, this, closed, false, &lanes};
  intersectPacket(scene_, cc, collectFilter, valid, rh);
}

void RayScene::firstHitsAndClosedBackFaces(const RayPacket& packet, ClosedMode closed,
                                           std::array<RayHit, kPacketLanes>& first, std::array<bool, kPacketLanes>& found,
                                           std::array<RayHit, kPacketLanes>& back,
                                           std::array<bool, kPacketLanes>& foundBack) const {
  alignas(32) int valid[8];
  alignas(32) RTCRayHit8 rh;
  loadPacket(packet, rh, valid);
  std::array<RayHit, kPacketLanes> nearest;
  std::array<bool, kPacketLanes> foundNearest{};
  CollectContext cc{{}, this, closed, false, nullptr, &nearest, &foundNearest};
  intersectPacket(scene_, cc, collectFilter, valid, rh);
  for (size_t l = 0; l < size_t(kPacketLanes); ++l) {
    const bool hasBack = packet.active[l] && rh.hit.geomID[l] != RTC_INVALID_GEOMETRY_ID;
    const RayHit b{rh.ray.tfar[l], hasBack ? rh.hit.primID[l] : 0u, false, true};
    const bool nearestFirst = foundNearest[l] && (!hasBack || nearest[l].t < b.t || (nearest[l].t == b.t && nearest[l].front));
    found[l] = foundNearest[l] || hasBack;
    first[l] = nearestFirst ? nearest[l] : b;
    foundBack[l] = nearestFirst && hasBack && nearest[l].closed && nearest[l].front;
    if (foundBack[l]) back[l] = b;
  }
}

void RayScene::firstClosedBackFaces(const RayPacket& packet, ClosedMode closed, std::array<RayHit, kPacketLanes>& hits,
                                    std::array<bool, kPacketLanes>& found) const {
  alignas(32) int valid[8];
  alignas(32) RTCRayHit8 rh;
  loadPacket(packet, rh, valid);
  CollectContext cc{{}, this, closed, true, nullptr};
  intersectPacket(scene_, cc, collectFilter, valid, rh);
  for (int l = 0; l < kPacketLanes; ++l) {
    found[size_t(l)] = packet.active[size_t(l)] && rh.hit.geomID[l] != RTC_INVALID_GEOMETRY_ID;
    if (found[size_t(l)]) hits[size_t(l)] = RayHit{rh.ray.tfar[l], rh.hit.primID[l], false, true};
  }
}

}  // namespace cpvs
