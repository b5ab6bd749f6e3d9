// From a local light to the perspective grids that bake it (seed 000 §5): one for a spot
// light, six for a point light, each with its near, far and resolution planned.
#pragma once

#include <vector>

#include "cpvs/light/light.h"
#include "cpvs/light/perspective_grid.h"

namespace cpvs {

struct Scene;

/// far / near of a planned grid is at most this: the closest geometry is clamped to it
/// (a lamp inside its own fixture would otherwise get a near of almost nothing).
constexpr double kMaxDepthRatio = 1e4;
/// The finest resolution the planner picks for one light's grid (a light's own
/// log2Resolution may ask for more).
constexpr int kMaxPlannedLog2Resolution = 13;

/// One grid of a light, and what it was planned from.
struct LightGridPlan {
  PerspectiveGrid grid;
  double tanCone;   // the cone its texels are cut off by (a cube face: none)
  double closest;   // the view depth of the closest geometry in its frustum (infinity: none)
};

/// A spot light's grid looks along its axis with the frustum around its cone; a point
/// light's six look along its cube's faces (cubeFaceAxis) with 90-degree frusta widened
/// by a guard band (the widest filter and normal offset, so that the face cubeFace picks
/// answers a lookup whole; at least 2^5 texels a side). For each grid: far
/// is the light's range, or the farthest corner of the scene's bounding box from it; near
/// is the light's own, or the view depth of the closest geometry inside the grid's
/// frustum, clamped to [far / kMaxDepthRatio, far / 2]; the resolution is the light's own,
/// or the smallest power of two whose texels at far are at most `footprint` wide
/// (clamped to [2^kMinLog2Resolution, 2^kMaxPlannedLog2Resolution]). checkLight must have
/// accepted the light; InputError for an empty scene or a footprint that is not positive
/// when the resolution is planned.
std::vector<LightGridPlan> planLightGrids(const Scene& scene, const Light& light, double footprint);

}  // namespace cpvs
