// What each texel's column of voxels must be: the enter and exit depths of the light's
// ray through it, as voxel slices.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/light/grid.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/light/perspective_grid.h"
#include "cpvs/raytrace/ray_scene.h"

namespace cpvs {

/// Per texel, the classification of its column of R voxels, as two slice indices
/// (first = firstUndefined, shadowed = firstShadowed):
///   slice k <  first             lit        (the voxel lies entirely in front of the surface)
///   first <= k < shadowed        undefined  (inside closed geometry: no query lands there)
///   k >= shadowed                shadowed
/// first = floor(enter depth in slices); no hit gives first = shadowed = R. Open geometry
/// gives shadowed = first. Closed geometry gives shadowed = floor(exit depth), so the
/// voxel holding the exit surface stays shadowed (a receiver touching the back of a closed
/// object must not see light); shadowed >= first always.
struct TexelSlices {
  std::vector<uint32_t> firstUndefined, firstShadowed;  // row-major, width * height
};

/// Renders the texels [x0, x0 + width) x [y0, y0 + height) of the grid with packets of 8
/// coherent orthographic rays, one through each texel centre, multithreaded with TBB.
/// width and height must be multiples of 8. A texel's result depends only on its global
/// index, never on the block that rendered it. Closed texels whose exit can't be found
/// (an open mesh forced closed, more than kMaxHitsPerRay crossings) fall back to firstShadowed = firstUndefined.
void renderTexelSlices(const RayScene& rays, const OrthoGrid& grid, ClosedMode closed, ExitMode exit,
                       uint64_t x0, uint64_t y0, uint32_t width, uint32_t height,
                       TexelSlices& out);

/// The same for a spot light's grid: rays from the light through each texel centre (from
/// the light, not from near: geometry nearer than near lands in slice 0 and shadows its
/// column), slices of the view depth. Texels the cone of half-angle atan(tanCone) misses
/// cast no ray and are all undefined (first = 0, shadowed = R): no light falls there.
void renderTexelSlices(const RayScene& rays, const PerspectiveGrid& grid, double tanCone, ClosedMode closed,
                       ExitMode exit, uint64_t x0, uint64_t y0, uint32_t width, uint32_t height, TexelSlices& out);

/// Puts one ray's crossings in the order the face count reads them and returns how many
/// remain: sorted by distance; within runs closer than `tieDistance`, enters first
/// (coinciding surfaces of touching parts); same-kind duplicates within it dropped (a ray
/// through a shared edge). The shared rule of renderTexelSlices, exposed for tests.
int orderCrossings(RayHit* hits, int count, double tieDistance);

/// The order of crossings before ties are resolved: by distance, then enters first, then
/// by triangle.
inline bool closerCrossing(const RayHit& a, const RayHit& b) {
  if (a.t != b.t) return a.t < b.t;
  if (a.front != b.front) return a.front;
  return a.triangle < b.triangle;
}

/// Which of one ray's ordered crossings (orderCrossings) is the exit of the interior the
/// first one enters, or -1 when the column has none (the first crossing is not a closed
/// front face; the count goes negative; it never returns to zero).
int exitCrossing(const RayHit* hits, int count, bool exact);

/// The texel classification of one ray's hits, sorted by distance: the shared rule of
/// renderTexelSlices, exposed for tests. `t` values are depths along the texel's ray
/// (LightGrid::texelRay), which the grid's texel mapping (TexelMapping, SpotTexelMapping)
/// turns into slices.
template <class Texels>
void classifyTexel(const RayHit* hits, int count, bool exact, const Texels& slices, uint32_t& lo, uint32_t& hi) {
  if (count == 0) {
    lo = hi = slices.side();
    return;
  }
  lo = hi = slices.slice(hits[0].t);
  const int exit = exitCrossing(hits, count, exact);
  if (exit >= 0) hi = std::max(lo, slices.slice(hits[exit].t));
}

}  // namespace cpvs
