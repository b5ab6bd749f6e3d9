// An Embree BVH over a scene, built once and shared by depth rendering, verification and
// rendering. Embree's types stay behind this header: its handles are only named here
// (Embree's own opaque struct names), and the packet kernels live in src/raytrace/.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "cpvs/base/vec3.h"
#include "cpvs/bake/options.h"

struct RTCDeviceTy;
struct RTCSceneTy;

namespace cpvs {

struct Scene;

/// One ray hit: distance along the (unit) ray, the triangle, whether the ray enters the
/// surface's front side, and whether the triangle counts as closed geometry.
struct RayHit {
  double t = 0;
  uint32_t triangle = 0;
  bool front = false;
  bool closed = false;
  // Named so that the 16 bytes are copied as one (moves of 14 bytes as two overlapping
  // stores stall the loads that follow them when hits are sorted).
  uint16_t unused = 0;
};
static_assert(sizeof(RayHit) == 16);

/// Rays traced together, one per lane: coherent rays (a block of texels, a shadow map's
/// rows) along one direction, or diverging a little from one point. Origins are relative to
/// RayScene::origin(); a lane whose `active` is false is not traced.
constexpr int kPacketLanes = 8;
struct RayPacket {
  std::array<Vec3, kPacketLanes> origin;
  std::array<Vec3, kPacketLanes> dir;  // one for a directional light, diverging from a spot
  std::array<float, kPacketLanes> tNear{}, tFar{};
  std::array<bool, kPacketLanes> active{};
};

/// Crossings recorded along one ray for the exact exit depth.
constexpr int kMaxHitsPerRay = 256;

/// Every surface one ray crosses, unordered, up to kMaxHitsPerRay (overflow: more).
struct RayCrossings {
  std::array<RayHit, kMaxHitsPerRay> hits;
  int count = 0;
  bool overflow = false;
};

/// Embree scene of triangles in a local frame centred on `origin` (float vertices relative
/// to a double origin keep precision for scenes far from the world origin). Thread-safe
/// for queries after construction.
class RayScene {
 public:
  RayScene(const Scene& scene, const Vec3& origin, int threads = 0);
  ~RayScene();
  RayScene(const RayScene&) = delete;
  RayScene& operator=(const RayScene&) = delete;

  const Vec3& origin() const { return origin_; }
  size_t triangleCount() const { return closed_.size(); }
  bool triangleClosed(uint32_t tri, ClosedMode mode) const {
    return mode == ClosedMode::On || (mode == ClosedMode::Auto && closed_[tri] != 0);
  }

  /// True when anything lies on the segment from `from` along unit `dir` in (tnear, tfar).
  bool occluded(const Vec3& from, const Vec3& dir, double tnear, double tfar) const;
  /// The closest hit along the ray, or false.
  bool intersect(const Vec3& from, const Vec3& dir, double tnear, double tfar, RayHit& hit) const;

  /// How many closed solids (under `mode`) contain `from`, found by counting the closed
  /// surfaces a ray along unit `dir` leaves minus those it enters up to tfar. Surfaces
  /// that coincide (a box standing on another) are all counted, so a point in either is
  /// inside. 0 for a point outside every closed part.
  int closedNesting(const Vec3& from, const Vec3& dir, double tfar, ClosedMode mode) const;

  /// Per active lane, the closest hit in (tNear, tFar): found[l] false when none.
  /// `closed` decides RayHit::closed.
  void firstHits(const RayPacket& packet, ClosedMode closed, std::array<RayHit, kPacketLanes>& hits,
                 std::array<bool, kPacketLanes>& found) const;
  /// Per active lane, every crossing in (tNear, tFar), each surface reported once per
  /// triangle it is hit on (a ray through a shared edge reports both: orderCrossings
  /// merges them). Inactive lanes get count 0.
  void allCrossings(const RayPacket& packet, ClosedMode closed, std::array<RayCrossings, kPacketLanes>& lanes) const;
  /// Per active lane in one traversal: the closest hit (found) and, when it enters a
  /// closed front face, the closest closed back face behind it (foundBack): what
  /// firstHits then firstClosedBackFaces from the first hit give.
  void firstHitsAndClosedBackFaces(const RayPacket& packet, ClosedMode closed, std::array<RayHit, kPacketLanes>& first,
                                   std::array<bool, kPacketLanes>& found, std::array<RayHit, kPacketLanes>& back,
                                   std::array<bool, kPacketLanes>& foundBack) const;
  /// Whether any triangle counts as closed under `mode`.
  bool anyClosed(ClosedMode mode) const;
  /// Per active lane, the closest back face of closed geometry in (tNear, tFar).
  void firstClosedBackFaces(const RayPacket& packet, ClosedMode closed, std::array<RayHit, kPacketLanes>& hits,
                            std::array<bool, kPacketLanes>& found) const;

 private:
  Vec3 origin_;
  double tieDistance_ = 0;  // crossings closer than this are simultaneous (1e-6 of the scene's size)
  std::vector<uint8_t> closed_;
  RTCDeviceTy* device_ = nullptr;
  RTCSceneTy* scene_ = nullptr;
};

}  // namespace cpvs
