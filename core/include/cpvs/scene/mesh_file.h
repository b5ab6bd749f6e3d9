// A scene as imported, in one flat file: what the coordinator keeps of an upload, so that
// no submit imports the file again, and what its sandboxed importer sends back.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "cpvs/scene/scene.h"

namespace cpvs {

/// The bytes of a scene mesh file: magic "CPVSMESH", version, counts, the import's
/// statistics and the geometry hash, the name, positions (doubles), indices, closed
/// flags, lights (with their range), the media, the meshes' names, ranges and transmittance,
/// and a content hash of everything before it. Little-endian.
std::vector<uint8_t> encodeSceneMesh(const Scene& scene, const SceneStats& stats);

/// Reads a scene mesh file. Nothing in it is trusted: FormatError naming `source` for a
/// wrong magic or version, a checksum that does not match, counts that do not fit the
/// bytes, an index past the vertices, a non-finite position, a closed flag other than
/// 0 or 1, a transmittance outside [0, 1], meshes that do not cover the triangles in order, or a geometry hash other than
/// the one stored.
Scene decodeSceneMesh(const uint8_t* data, size_t size, const std::string& source, SceneStats* stats = nullptr);

}  // namespace cpvs
