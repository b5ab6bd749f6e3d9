// The procedural city the project generates: a closed scene with no file behind it.
#pragma once

#include <cstdint>
#include <string>

#include "cpvs/scene/scene.h"

namespace cpvs {

/// A procedural closed city: a closed ground slab with closed box buildings of varied
/// heights (some touching, some on plinths), a few overhanging bridges between towers.
/// Deterministic for a given seed. `blocks` is the number of city blocks per side.
Scene makeProceduralCity(int blocks = 12, uint32_t seed = 1);

}  // namespace cpvs
