// Scenes from files, through assimp.
#pragma once

#include <cstdint>
#include <string>

#include "cpvs/scene/scene.h"

namespace cpvs {

/// Loads any format assimp reads (glTF/GLB, OBJ, DAE, PLY, FBX, STL, AC, IFC, ...),
/// flattens the node hierarchy into world space, drops and counts zero-area triangles,
/// and classifies closed parts. Throws InputError naming the file (and the vertex index)
/// when the file can't be read, holds NaN/Inf positions, or holds no triangle.
Scene loadScene(const std::string& path, SceneStats* stats = nullptr);

}  // namespace cpvs
