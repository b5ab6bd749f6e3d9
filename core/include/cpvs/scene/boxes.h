// Closed boxes: the building block of the procedural city and of test scenes.
#pragma once

#include "cpvs/base/vec3.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

/// Appends the axis-aligned box [lo, hi] as 12 triangles, counter-clockwise seen from
/// outside (a closed, outward-facing part). Call finalizeScene when the scene is complete.
void appendBox(Scene& scene, const Vec3& lo, const Vec3& hi);

}  // namespace cpvs
