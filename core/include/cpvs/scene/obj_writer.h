// A scene as Wavefront OBJ text: how generated scenes reach processes that read files
// (the farm, other tools), with positions in full double precision.
#pragma once

#include <string>

#include "cpvs/scene/scene.h"

namespace cpvs {

/// "v x y z" lines with 17 significant digits (a double read back is the same double),
/// then "f a b c" lines; `comment` goes on a first "#" line when not empty.
std::string objText(const Scene& scene, const std::string& comment = "");

/// Writes objText(scene, comment) to `path` atomically (base/file.h).
void writeObj(const std::string& path, const Scene& scene, const std::string& comment = "");

}  // namespace cpvs
