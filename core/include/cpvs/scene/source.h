// A scene by name: a generator or a file.
#pragma once

#include <cstdint>
#include <string>

#include "cpvs/scene/scene.h"

namespace cpvs {

/// Opens a scene by name: "city", "city:BLOCKS" or "city:BLOCKS:SEED" generates the
/// procedural city (12 blocks, seed 1 by default); "landscape", "landscape:SIZE" or
/// "landscape:SIZE:SEED" the fractal landscape (256 cells, seed 1); anything else is a
/// file for loadScene.
/// The command line and the farm accept the same names.
Scene openScene(const std::string& spec, SceneStats* stats = nullptr);

}  // namespace cpvs
