#include "cpvs/raytrace/visibility.h"

namespace cpvs {

double shadowRayLength(const OrthoGrid& g) { return 2.0 * (g.depthExtent + g.extent) + 1.0; }

bool exactlyLit(const RayScene& rays, const OrthoGrid& grid, const Vec3& point) {
  return !rays.occluded(point, -grid.frame.dir, 0.0, shadowRayLength(grid));
}

bool exactlyLit(const RayScene& rays, const PerspectiveGrid& grid, double tanCone, const Vec3& point) {
  if (!grid.insideCone(point, tanCone) || !(grid.depthOf(point) < grid.far())) return false;
  const ShadowRay ray = shadowRayTo(grid, point);
  return !rays.occluded(point, ray.dir, 0.0, ray.length);
}

ShadowRay shadowRayTo(const OrthoGrid& grid, const Vec3&) { return {-grid.frame.dir, shadowRayLength(grid)}; }

ShadowRay shadowRayTo(const PerspectiveGrid& grid, const Vec3& point) {
  const Vec3 d = grid.position() - point;
  const double len = length(d);
  return {len > 0 ? d / len : Vec3{}, len};
}

}  // namespace cpvs
