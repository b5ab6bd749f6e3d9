// First hits in double precision, the same bits on every machine: for what must not depend
// on where it runs, such as a camera declaration's visible surfaces, which every worker of a
// farm bake computes for itself. Embree's float hits may differ between CPUs at edges.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "cpvs/base/vec3.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

/// A bounding volume hierarchy over a scene's triangles, built and walked the same way
/// everywhere: nodes split by a binned surface area heuristic (a stable partition, ties to
/// the lowest axis and plane), hits tested by Möller–Trumbore without fused multiply-adds,
/// equal distances resolved to the lowest triangle index. A ray's hit depends only on the
/// scene and the ray, never on the thread, the CPU or the order of the walk. (The boxes,
/// widened for their own rounding, only prune; a hit that the triangle test's rounding
/// puts a hair outside its box, on a grazing ray, could in principle be missed, the same
/// way everywhere.)
class ExactCaster {
 public:
  static constexpr uint32_t kNoHit = std::numeric_limits<uint32_t>::max();
  struct Hit {
    uint32_t triangle = kNoHit;  // scene triangle index; kNoHit: none within tMax
    double t = 0;                // hit point = origin + t * direction
    bool front = false;          // the ray meets the side the triangle's winding faces
  };

  explicit ExactCaster(const Scene& scene);

  /// The nearest hit with 0 < t <= tMax (direction need not be unit length). A ray through
  /// an edge or a vertex hits every triangle there; the lowest index wins.
  Hit firstHit(const Vec3& origin, const Vec3& direction, double tMax) const;

  /// The same, by testing every triangle: the reference the hierarchy must agree with.
  Hit firstHitBruteForce(const Vec3& origin, const Vec3& direction, double tMax) const;

 private:
  struct Node {
    double lo[3], hi[3];
    uint32_t first;  // a leaf's first entry of order_; an inner node's second child
    uint32_t count;  // triangles of a leaf; 0 for an inner node (its first child follows it)
    uint32_t axis;   // an inner node's split axis
  };
  struct Triangle {
    Vec3 a, e1, e2;
  };
  uint32_t build(uint32_t begin, uint32_t end, std::vector<Vec3>& centroids, int depth);
  bool intersect(uint32_t entry, const Vec3& o, const Vec3& d, double tMax, Hit& best) const;

  std::vector<Node> nodes_;
  std::vector<uint32_t> order_;        // triangle indices; each leaf owns a range
  std::vector<Triangle> triangles_;    // per scene triangle
};

}  // namespace cpvs
