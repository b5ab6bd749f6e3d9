// Scenes from files, through assimp.
#pragma once

#include <cstdint>
#include <string>

#include "cpvs/scene/scene.h"

namespace cpvs {

struct ImportOptions {
  /// Open the named file only: a reference to any other file (a glTF buffer or image
  /// `uri`, an OBJ `mtllib`) is refused, and a file that cannot import without it fails
  /// with "external references are not allowed". For files from untrusted callers (the
  /// farm): nothing outside the upload can be read through it.
  bool selfContained = false;
};

/// Loads any format assimp reads (glTF/GLB, OBJ, DAE, PLY, FBX, STL, AC, IFC, ...),
/// flattens the node hierarchy into world space, drops and counts zero-area triangles,
/// and classifies closed parts. Throws InputError naming the file (and the vertex index)
/// when the file can't be read, holds NaN/Inf positions, or holds no triangle.
Scene loadScene(const std::string& path, SceneStats* stats = nullptr, const ImportOptions& options = {});

}  // namespace cpvs
