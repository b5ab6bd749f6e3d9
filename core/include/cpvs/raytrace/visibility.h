// Exact visibility of the light by shadow rays: the ground truth that verification,
// accuracy and pictures compare the CPVS with.
#pragma once

#include "cpvs/base/vec3.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/raytrace/ray_scene.h"

namespace cpvs {

/// Exact visibility of the light from a world point: true = lit.
bool exactlyLit(const RayScene& rays, const OrthoGrid& grid, const Vec3& point);
/// Length of a shadow ray that leaves any point of the grid's volume towards the light:
/// past the grid's near plane, whatever the point.
double shadowRayLength(const OrthoGrid& grid);

}  // namespace cpvs
