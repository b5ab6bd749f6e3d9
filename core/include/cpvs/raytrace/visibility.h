// Exact visibility of the light by shadow rays: the ground truth that verification,
// accuracy and pictures compare the CPVS with.
#pragma once

#include "cpvs/base/vec3.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/light/perspective_grid.h"
#include "cpvs/raytrace/ray_scene.h"

namespace cpvs {

/// Exact visibility of the light from a world point: true = lit.
bool exactlyLit(const RayScene& rays, const OrthoGrid& grid, const Vec3& point);
/// Length of a shadow ray that leaves any point of the grid's volume towards the light:
/// past the grid's near plane, whatever the point.
double shadowRayLength(const OrthoGrid& grid);

/// Exact visibility of a spot light from a world point: inside its cone (half-angle
/// atan(tanCone)), nearer than its far end (its range) and nothing on the segment to the
/// light.
bool exactlyLit(const RayScene& rays, const PerspectiveGrid& grid, double tanCone, const Vec3& point);

/// The segment from a point towards a light: unit direction and length.
struct ShadowRay {
  Vec3 dir;
  double length = 0;
};
/// Towards a directional light, out of the grid's volume (shadowRayLength).
ShadowRay shadowRayTo(const OrthoGrid& grid, const Vec3& point);
/// To a spot light's position (a zero direction for the light's own position).
ShadowRay shadowRayTo(const PerspectiveGrid& grid, const Vec3& point);

}  // namespace cpvs
