// Polygons clipped to a spot light's frustum in the light's own frame, where every side
// of the frustum is a plane through the light: what the rasterizer projects and what the
// planner measures near from.
#pragma once

#include <vector>

namespace cpvs {

/// A point in a light's frame: a and b along its u and v, z along its axis (view depth).
struct LightPoint {
  double a = 0, b = 0, z = 0;
};

/// Clips the convex polygon `poly` (in place; `scratch` is working memory) to z >= zMin
/// and |a|, |b| <= tanHalf * z: the square frustum of half-angle atan(tanHalf) cut a hair
/// (zMin > 0) in front of the light. The planes are linear in (a, b, z), so the clip is
/// exact up to rounding, and an edge's crossing is computed from its endpoints in one
/// fixed order: polygons sharing the edge get the same crossing (a watertight mesh stays
/// watertight). Fewer than three points remain when nothing of it is inside.
void clipToFrustum(std::vector<LightPoint>& poly, std::vector<LightPoint>& scratch, double zMin, double tanHalf);

}  // namespace cpvs
