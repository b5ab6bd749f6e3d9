// Depth maps by exact rasterization: for an orthographic light, "the ray through a
// texel's centre hits the triangle" is "the centre lies inside the projected triangle",
// so rasterizing at texel centres is the ray caster's computation, without a BVH walk per
// texel.
#pragma once

#include <cstdint>

#include "cpvs/bake/column_masks.h"
#include "cpvs/bake/options.h"
#include "cpvs/bake/raster_scene.h"
#include "cpvs/bake/texel_slices.h"

namespace cpvs {

/// The texels [x0, x0 + width) x [y0, y0 + height) of the scene's grid, as
/// renderTexelSlices renders them: the same classification, ordering, tie and overflow
/// rules, but every texel centre on an edge shared by two triangles is covered by exactly
/// one of them (the top-left rule on snapped vertices), so no crossing is seen twice.
/// width and height must be multiples of 8, x0 and y0 too. Multithreaded with TBB over
/// bins of 64 x 64 texels; a texel's result depends only on its global position.
void rasterTexelSlices(const RasterScene& scene, ClosedMode closed, ExitMode exit, uint64_t x0, uint64_t y0,
                       uint32_t width, uint32_t height, TexelSlices& out);

/// The same texels resolved straight into column masks while each 8x8 block's slices are
/// in cache (never stored as TexelSlices): equal to buildColumnMasks of rasterTexelSlices.
void rasterColumnMasks(const RasterScene& scene, ClosedMode closed, ExitMode exit, UndefinedRule rule,
                       uint64_t x0, uint64_t y0, uint32_t width, uint32_t height, ColumnMasks& out);

/// The SIMD instruction set the rasterizer chose on this machine ("AVX3", "AVX2", ...).
const char* rasterInstructionSet();

}  // namespace cpvs
