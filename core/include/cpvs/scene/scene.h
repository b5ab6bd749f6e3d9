// A scene: one triangle mesh in world space, flattened from whatever file it came from.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cpvs/base/hash.h"
#include "cpvs/base/vec3.h"

namespace cpvs {

/// A light the scene file holds (glTF KHR_lights_punctual, COLLADA, FBX, ... through
/// assimp), in world space: what `cpvs plan` reports. Not part of the geometry.
struct SceneLight {
  enum class Type : uint8_t { Directional, Point, Spot, Area, Ambient, Unknown };
  std::string name;
  Type type = Type::Unknown;
  Vec3 position, direction;  // direction: where it shines (unit; zero when it has none)
  Vec3 color;
  double innerConeDeg = 0, outerConeDeg = 0;  // spot lights
  double range = 0;                           // how far it reaches; 0: not given
};

/// "directional", "point", "spot", "area", "ambient", "unknown".
const char* lightTypeName(SceneLight::Type type);

/// One flattened triangle mesh in world space (all node transforms applied).
/// Positions stay in double precision; every triangle indexes `positions`.
/// `closed[i]` tells whether triangle i belongs to a closed, consistently oriented,
/// outward-facing part (a watertight edge-connected component): only such parts have an
/// interior that no shadow query can reach.
struct Scene {
  std::vector<Vec3> positions;
  std::vector<uint32_t> indices;     // 3 per triangle
  std::vector<uint8_t> closed;       // 1 per triangle, see above
  std::string name;                  // file name or generator name, for logs
  std::vector<SceneLight> lights;    // as the file holds them (not hashed: they cast no shadow)

  size_t triangleCount() const { return indices.size() / 3; }
  Vec3 vertex(size_t tri, int corner) const { return positions[indices[3 * tri + corner]]; }
};

/// The area of triangle `tri` of the scene.
inline double triangleArea(const Scene& scene, size_t tri) {
  const Vec3 a = scene.vertex(tri, 0);
  return 0.5 * length(cross(scene.vertex(tri, 1) - a, scene.vertex(tri, 2) - a));
}

/// What the importer did, for logs and the bake summary.
struct SceneStats {
  size_t triangles = 0;            // kept
  size_t degenerateDropped = 0;    // zero-area triangles removed
  size_t closedTriangles = 0;      // triangles in closed parts
  size_t parts = 0;                // edge-connected components
  size_t closedParts = 0;
};

/// Removes zero-area triangles, fills `closed` from the mesh topology (welded by exact
/// position), and returns the counts. Every generator and importer calls it last.
SceneStats finalizeScene(Scene& scene);

/// Content hash of the geometry (positions as used, triangle indices, the closed flags):
/// two scenes with the same hash bake to the same bytes.
Hash128 sceneHash(const Scene& scene);

/// Axis-aligned bounds of the vertices referenced by triangles.
void sceneBounds(const Scene& scene, Vec3& lo, Vec3& hi);

}  // namespace cpvs
