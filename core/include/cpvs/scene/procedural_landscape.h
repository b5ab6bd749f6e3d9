// The procedural fractal landscape: a closed heightfield, like the paper's
// FractalLandscape (terrain with skirts and a bottom, so that it has an inside).
#pragma once

#include <cstdint>

#include "cpvs/scene/scene.h"

namespace cpvs {

/// A `size` x `size`-cell heightfield (cells 2 units wide) of fractal value noise (six
/// octaves; hills up to about 90 units), closed by four skirts and a flat bottom 10 units
/// below its lowest point: watertight and counter-clockwise seen from outside.
/// Deterministic for a seed. InputError for a size outside [2, 4096].
Scene makeFractalLandscape(int size = 256, uint32_t seed = 1);

}  // namespace cpvs
