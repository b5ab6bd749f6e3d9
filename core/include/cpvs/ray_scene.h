// An Embree BVH over a scene, built once and shared by depth rendering, verification and
// rendering. Embree's types stay behind this header.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "cpvs/types.h"

namespace cpvs {

struct Scene;

/// How closed geometry is recognised: per part from the mesh topology (auto), every
/// triangle (on: open meshes forced closed degrade gracefully, see depth_maps.h), none (off).
enum class ClosedMode : uint8_t { Auto = 0, On = 1, Off = 2 };

/// One ray hit: distance along the (unit) ray, the triangle, whether the ray enters the
/// surface's front side, and whether the triangle counts as closed geometry.
struct RayHit {
  double t = 0;
  uint32_t triangle = 0;
  bool front = false;
  bool closed = false;
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

  /// Opaque Embree handle for the depth renderer.
  void* embreeScene() const { return scene_; }

 private:
  Vec3 origin_;
  double tieDistance_ = 0;  // crossings closer than this are simultaneous (1e-6 of the scene's size)
  std::vector<uint8_t> closed_;
  void* device_ = nullptr;
  void* scene_ = nullptr;
};

}  // namespace cpvs
