// The procedural city the project generates: a closed scene with no file behind it.
#pragma once

#include <cstdint>
#include <string>

#include "cpvs/scene/scene.h"

namespace cpvs {

/// A procedural closed city: a closed ground slab with closed box buildings of varied
/// heights (some touching, some on plinths), a few overhanging bridges between towers,
/// and street lamps (its lights: spot lights on the sidewalks, kLampHeight up, looking
/// down and a little towards the street; about 165 for 12 blocks, the benchmark scene of
/// seed 000 Fig. 1). Deterministic for a given seed. `blocks` is the number of city
/// blocks per side.
Scene makeProceduralCity(int blocks = 12, uint32_t seed = 1);

/// A street lamp's height above the ground, its cone's half-angle and its reach.
constexpr double kLampHeight = 7, kLampConeDeg = 60, kLampRange = 24;

}  // namespace cpvs
