// A scene: one triangle mesh in world space, flattened from whatever file it came from.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
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
  Vec3 edgeU, edgeV;  // an area light's rectangle around `position`, U x V along `direction` (zero: no size)
};

/// A participating medium the scene file declares: a material with a volume (glTF
/// KHR_materials_volume), absorbing by its attenuation colour over its distance.
struct SceneMedium {
  std::string material;
  double absorption = 0;  // per world unit, the mean of the channels' -ln(colour) / distance
};

/// "directional", "point", "spot", "area", "ambient", "unknown".
const char* lightTypeName(SceneLight::Type type);

/// One mesh of the file as placed by one node: its triangles [firstTriangle,
/// firstTriangle + triangles) of the scene and the names a light's fixture is given by
/// (Light::exclude). finalizeScene cuts a longer name to its first kMaxMeshNameBytes
/// (whole UTF-8 characters), so that the scene hashes as its mesh file stores it.
constexpr size_t kMaxMeshNameBytes = 1024;
struct SceneMesh {
  std::string node, mesh, material;
  uint32_t firstTriangle = 0, triangles = 0;
  /// The light its material lets through, per channel (RGB, each in [0, 1]): all zero for
  /// an opaque material. A translucent mesh (glass, water, leaves on cards) casts no hard
  /// shadow: its constant transmittance darkens what lies behind it (seed 003 §3.4).
  std::array<float, 3> transmittance{0, 0, 0};
};

/// The least transmittance above 0: a smaller one is 0, as devices that flush subnormal
/// floats would make it (the light through translucent casters is the same everywhere).
constexpr float kMinTransmittance = std::numeric_limits<float>::min();

/// Whether the mesh lets some light through (a channel of its transmittance above 0).
inline bool isTranslucent(const SceneMesh& m) { return m.transmittance[0] > 0 || m.transmittance[1] > 0 || m.transmittance[2] > 0; }

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
  std::vector<SceneMedium> media;    // likewise
  /// The file's meshes in triangle order, covering every triangle (hashed: a light leaves
  /// its fixture out by name); empty for generated scenes, whose triangles have no names.
  std::vector<SceneMesh> meshes;

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
/// position), gives triangles appended after the last of `meshes` an unnamed mesh, and
/// returns the counts. Every generator and importer calls it last.
SceneStats finalizeScene(Scene& scene);

/// Content hash of the geometry (positions as used, triangle indices, the closed flags)
/// and of the meshes' names and ranges (and transmittance, for translucent meshes only,
/// so that an opaque scene hashes as before they were read): two scenes with the same
/// hash bake to the same bytes.
Hash128 sceneHash(const Scene& scene);

/// Whether mesh `m` answers to `name`: its node's, its mesh's or its material's name.
bool meshIsNamed(const SceneMesh& m, const std::string& name);

/// The scene without the triangles of every mesh one of `names` names (meshIsNamed), its
/// closed parts classified again (a part cut open has an inside that can be reached):
/// what a light whose fixture those meshes are casts shadows with. InputError naming
/// `source` for a name no mesh answers to, or one that leaves no triangle.
Scene withoutMeshes(const Scene& scene, const std::vector<std::string>& names, const std::string& source);

/// Whether some mesh of the scene with a triangle is translucent (isTranslucent).
bool hasTranslucentMeshes(const Scene& scene);

/// The scene without its translucent meshes, its closed parts classified again (their
/// counts in `stats`, when given): what casts hard shadows (the CPVS is baked from it). A
/// copy of the scene when nothing is translucent; a scene of no triangle when everything is.
Scene opaquePart(const Scene& scene, SceneStats* stats = nullptr);

/// The translucent meshes' triangles alone, as given (closed flags as classified in the
/// whole scene, unused: front-face culling is off for them), and each triangle's
/// transmittance: what a TOP tree of translucent casters is built from.
struct TranslucentCasters {
  std::vector<Vec3> positions;
  std::vector<uint32_t> indices;
  std::vector<std::array<float, 3>> transmittance;  // one per triangle
  size_t meshes = 0;                                // translucent meshes they came from
  size_t triangleCount() const { return indices.size() / 3; }
};
TranslucentCasters translucentCasters(const Scene& scene);

/// Axis-aligned bounds of the vertices referenced by triangles.
void sceneBounds(const Scene& scene, Vec3& lo, Vec3& hi);

}  // namespace cpvs
