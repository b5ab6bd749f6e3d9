// Enter and exit depths of a block of shadow-map texels, reduced to integer voxel slices.
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/light_frame.h"
#include "cpvs/ray_scene.h"

namespace cpvs {

/// How the exit depth of closed geometry is found (§3.3).
enum class ExitMode : uint8_t {
  Exact = 0,   // count front (+1) and back (-1) faces from the enter hit until zero
  Approx = 1,  // first back face behind the enter hit (exact unless closed parts intersect)
};

/// Per texel, the classification of its column of R voxels, as two slice indices:
///   slice k <  lo           lit        (the voxel lies entirely in front of the surface)
///   lo <= k < hi            undefined  (inside closed geometry: no query lands there)
///   k >= hi                 shadowed
/// lo = floor(enter depth in slices); no hit gives lo = hi = R. Open geometry gives
/// hi = lo. Closed geometry gives hi = floor(exit depth), so the voxel holding the exit
/// surface stays shadowed (a receiver touching the back of a closed object must not see
/// light); hi >= lo always.
struct TexelDepths {
  std::vector<uint32_t> lo, hi;  // row-major, width * height
};

/// Renders the texels [x0, x0 + width) x [y0, y0 + height) of the grid with packets of 8
/// coherent orthographic rays, one through each texel centre, multithreaded with TBB.
/// width and height must be multiples of 8. A texel's result depends only on its global
/// index, never on the block that rendered it. Closed texels whose exit can't be found
/// (an open mesh forced closed, more than kMaxHitsPerRay crossings) fall back to hi = lo.
void renderTexelDepths(const RayScene& rays, const Grid& grid, ClosedMode closed, ExitMode exit,
                       uint64_t x0, uint64_t y0, uint32_t width, uint32_t height,
                       TexelDepths& out);

/// Crossings recorded along one ray for the exact exit depth.
constexpr int kMaxHitsPerRay = 256;

/// Puts one ray's crossings in the order the face count reads them and returns how many
/// remain: sorted by distance; within runs closer than `tieDistance`, enters first
/// (coinciding surfaces of touching parts); same-kind duplicates within it dropped (a ray
/// through a shared edge). The shared rule of renderTexelDepths, exposed for tests.
int orderCrossings(RayHit* hits, int count, double tieDistance);

/// The texel classification of one ray's hits, sorted by distance: the shared rule of
/// renderTexelDepths, exposed for tests. `t` values are world distances from the near
/// plane; `slicesPerUnit` converts them to slices.
void classifyTexel(const RayHit* hits, int count, bool exact, double slicesPerUnit, uint32_t R,
                   uint32_t& lo, uint32_t& hi);

}  // namespace cpvs
