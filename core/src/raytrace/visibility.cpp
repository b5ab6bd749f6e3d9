#include "cpvs/raytrace/visibility.h"

namespace cpvs {

double shadowRayLength(const OrthoGrid& g) { return 2.0 * (g.depthExtent + g.extent) + 1.0; }

bool exactlyLit(const RayScene& rays, const OrthoGrid& grid, const Vec3& point) {
  return !rays.occluded(point, -grid.frame.dir, 0.0, shadowRayLength(grid));
}

}  // namespace cpvs
